"""Figures: one helper that makes a figure without pyplot state, and the Fig. 5/6 style plot.

Every PNG of the project is drawn on :func:`new_figure` (an Agg canvas, no global pyplot state,
safe in worker processes and FMUs) and written with :func:`drillstring.fileio.save_figure`
(atomically).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from drillstring.fileio import save_figure

__all__ = ["new_figure", "plot_velocities"]


def new_figure(figsize: tuple[float, float] = (7.0, 4.6), dpi: int = 150) -> Figure:
    """A matplotlib figure on its own Agg canvas (no pyplot).

    Parameters
    ----------
    figsize : (float, float)
        Width and height in inches.
    dpi : int
        Resolution.

    Returns
    -------
    Figure
        A figure attached to a fresh :class:`FigureCanvasAgg`.
    """
    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def plot_velocities(
    path: str | os.PathLike[str],
    runs: Sequence[tuple[str, Any]],
    *,
    title: str = "",
    t_on: float | None = None,
) -> Path:
    """du/dtau and dphi/dtau against tau for one or more runs, in the style of Figs. 5 and 6.

    Parameters
    ----------
    path : path-like
        The PNG to write (atomically).
    runs : sequence of (label, run)
        Each run has arrays ``tau``, ``du`` and ``dphi``.
    title : str
        Figure title.
    t_on : float, optional
        Switch-on time of the controller, drawn as a dotted line.

    Returns
    -------
    Path
        The written PNG.
    """
    fig = new_figure((8.0, 5.0))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    styles = ["-", "--", ":", "-."]
    for i, (label, r) in enumerate(runs):
        ls = styles[i % len(styles)]
        lw = 1.0 if i == 0 else 1.2
        ax1.plot(r.tau, r.du, ls, lw=lw, label=label)
        ax2.plot(r.tau, r.dphi, ls, lw=lw, label=label)
    ax1.set_ylabel(r"$\dot u(\tau)$")
    ax2.set_ylabel(r"$\dot\varphi(\tau)$")
    ax2.set_xlabel(r"$\tau$")
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
        if t_on is not None:
            ax.axvline(t_on, color="k", ls=":", lw=1)
    if len(runs) > 1:
        ax2.legend(fontsize=8)
    if title:
        ax1.set_title(title, fontsize="small" if "\n" in title else None)
    fig.tight_layout()
    return save_figure(fig, path)
