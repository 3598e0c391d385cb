"""Time-series figures in the style of the paper's Figs. 5 and 6 (du/dtau and dphi/dtau)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from drillstring.fileio import save_figure


def plot_velocities(
    path: str | os.PathLike[str],
    runs: Sequence[tuple[str, Any]],
    *,
    title: str = "",
    t_on: float | None = None,
) -> Path:
    """du/dtau and dphi/dtau against tau for one or more runs (objects with tau, du, dphi)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.0, 5.0), dpi=150)
    FigureCanvasAgg(fig)
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
        ax1.set_title(title)
    fig.tight_layout()
    return save_figure(fig, path)
