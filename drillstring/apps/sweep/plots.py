"""Maps of sweep metrics: a heat map over the swept plane (2-D) or a line plot (1-D), with the
reference point (the base set's value of each swept parameter) marked. Failed points are grey.
The controllers' panels can carry contour overlays (the linearised stability boundary: the 0
contour of a spectral abscissa computed on its own, finer grid)."""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Overlay", "cell_edges", "sweep_figure"]


@dataclass(frozen=True)
class Overlay:
    """A field drawn as its 0 contour on a map: ``z`` of shape ``(x.size, y.size)`` over the
    grid values ``x``, ``y``; ``label`` for the legend, ``style`` the line's ``color``, ``ls``,
    ``lw`` and a ``hatch`` for the side where ``z`` > 0 (none: not hatched); ``subject`` names
    the field in a panel's note when it has one sign on the whole map (default ``label``)."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    label: str
    style: Mapping[str, Any]
    subject: str = ""


def _draw_overlay(ax: Any, overlay: Overlay) -> tuple[Any, str]:
    """The 0 contour of ``overlay`` on ``ax``: (a legend handle, "") when the field changes
    sign on the map, else (None, a note saying on which side the whole map lies)."""
    from matplotlib.lines import Line2D

    z = np.asarray(overlay.z, dtype=float)
    finite = z[np.isfinite(z)]
    subject = overlay.subject or overlay.label
    if finite.size == 0:
        return None, f"{subject}: none"
    style = {"color": "k", "ls": "-", "lw": 1.2, **dict(overlay.style)}
    if finite.min() < 0.0 < finite.max():
        ax.contour(overlay.x, overlay.y, z.T, levels=[0.0], colors=style["color"],
                   linestyles=style["ls"], linewidths=style["lw"])  # fmt: skip
        if style.get("hatch"):  # the unstable side
            ax.contourf(overlay.x, overlay.y, z.T, levels=[0.0, np.inf], colors="none",
                        hatches=[style["hatch"]])  # fmt: skip
        handle = Line2D([], [], color=style["color"], ls=style["ls"], lw=style["lw"],
                        label=overlay.label)  # fmt: skip
        return handle, ""
    side = "unstable" if finite.min() >= 0.0 else "stable"
    return None, f"{subject}: {side} on the whole map"


def _label(name: str, labels: Mapping[str, str] | None) -> str:
    return (labels or {}).get(name, name)


def _figure(figsize: tuple[float, float]) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=120)
    FigureCanvasAgg(fig)
    return fig


def cell_edges(values: np.ndarray, scale: str) -> np.ndarray:
    """Edges of the cells centred on the grid values (geometric midpoints on a log scale).

    Parameters
    ----------
    values : ndarray
        Monotone grid values of one axis, at least two (positive for ``"log"``).
    scale : str
        ``"log"`` for midpoints in log space; anything else is linear.

    Returns
    -------
    ndarray
        ``len(values) + 1`` edges; the outer two mirror the first and last midpoints.

    Raises
    ------
    IndexError
        ``values`` has fewer than two entries.
    """
    v = np.log(values) if scale == "log" else np.asarray(values, dtype=float)
    mid = 0.5 * (v[1:] + v[:-1])
    edges = np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]])
    return np.exp(edges) if scale == "log" else edges


def _encode(
    values: Sequence[Any], kind: str, categories: Sequence[str] | None = None
) -> tuple[np.ndarray, list[str] | None]:
    """Numbers for the plot; strings become category codes, with their labels (``categories``
    first, in their order, then any other value found, sorted)."""
    if kind != "str":
        return np.array([math.nan if v is None else float(v) for v in values]), None
    found = {v for v in values if v}
    first = [c for c in (categories or ()) if c in found]
    labels = first + sorted(found - set(first))
    codes = {s: k for k, s in enumerate(labels)}
    return np.array([codes[v] if v else math.nan for v in values], dtype=float), labels


def _categorical(labels: Sequence[str], palette: Mapping[str, str] | None) -> Any:
    """A colour map with one colour per label: ``palette``'s where given, else tab10's."""
    import matplotlib as mpl
    from matplotlib.colors import ListedColormap

    base = list(mpl.colormaps["tab10"].colors)
    spare = [c for c in base if c not in (palette or {}).values()]
    colours = []
    for k, label in enumerate(labels):
        colours.append((palette or {}).get(label, spare[k % len(spare)]))
    return ListedColormap(colours or base[:1])


def sweep_figure(
    metric: str,
    kind: str,
    panels: Mapping[str, Sequence[Any]],
    axes: Sequence[Any],
    reference: dict[str, float],
    title: str,
    *,
    log: bool = False,
    categories: Sequence[str] | None = None,
    palette: Mapping[str, str] | None = None,
    axis_labels: Mapping[str, str] | None = None,
    note: str = "",
    overlays: Mapping[str, Sequence[Overlay]] | None = None,
) -> Any:
    """Figure of one sweep metric for one or several runs: a line per run over one axis, or a
    heat map per run (side by side) over two, on one shared colour scale.

    The reference point is marked; failed points are grey in a heat map.

    Parameters
    ----------
    metric : str
        The metric's name (axis or colour-bar label).
    kind : str
        Its type in :data:`~drillstring.apps.sweep.metrics.METRICS`; ``"str"`` is drawn as
        categories shared by all panels (a colour means one label), any other as numbers.
    panels : mapping of str to sequence
        Each run's label (the panel's title; ``""`` for a single unnamed panel) -> its values in
        point-index order (row-major over ``axes``); None for a failed point of a numeric
        metric, ``""`` for one of a string metric.
    axes : sequence of Axis
        The spec's one or two :class:`~drillstring.apps.sweep.spec.Axis` objects.
    reference : dict of str to float
        The reference value of each swept parameter (:meth:`SweepSpec.reference_values`).
    title : str
        Figure title.
    log : bool
        Logarithmic colour scale in 2-D (values <= 0 shown grey, as failed), logarithmic y
        axis in 1-D.
    categories : sequence of str, optional
        Order of a string metric's labels (others found follow, sorted).
    palette : mapping of str to colour, optional
        Colours of a string metric's labels (tab10 for the others).
    axis_labels : mapping of str to str, optional
        The axes' labels by parameter name (default: the name).
    note : str
        A line under the title (e.g. how the model is fed).
    overlays : mapping of str to sequence of Overlay, optional
        Per panel, the fields drawn as their 0 contour (2-D only), with a legend.

    Returns
    -------
    matplotlib.figure.Figure
        The figure, on an Agg canvas, not saved.
    """
    import matplotlib as mpl
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    names = list(panels)
    if kind == "str":
        everything = [v for name in names for v in panels[name]]
        _, labels = _encode(everything, kind, categories)
        order = list(labels or [])
        # every panel on the labels of all panels, so that a colour means one thing
        encoded = {
            n: np.array([order.index(v) if v else math.nan for v in panels[n]], dtype=float)
            for n in names
        }
    else:
        order = None
        encoded = {n: _encode(panels[n], kind)[0] for n in names}
    heading = f"{title}\n{note}" if note else title
    x_axis = axes[0]
    x = x_axis.values()
    if len(axes) == 1:
        fig = _figure((6.4, 4.8))
        ax = fig.add_subplot(1, 1, 1)
        for name in names:
            ax.plot(x, encoded[name], "o-", ms=3, label=name or metric)
        ax.axvline(reference[x_axis.param], color="k", ls="--", lw=1, label="reference")
        ax.set_xscale("log" if x_axis.scale == "log" else "linear")
        if log:
            ax.set_yscale("log")
        ax.set_xlabel(_label(x_axis.param, axis_labels))
        ax.set_ylabel(metric)
        if order is not None:
            ax.set_yticks(range(len(order)), order)
        ax.legend(loc="best", fontsize="small")
        ax.set_title(heading, fontsize="medium")
        fig.tight_layout()
        return fig
    y_axis = axes[1]
    y = y_axis.values()
    width = 3.4 * len(names) + 1.2 if len(names) > 1 else 6.4
    fig = _figure((width, 4.2 if len(names) > 1 else 4.8))
    grid_axes = fig.subplots(1, len(names), sharex=True, sharey=True, squeeze=False)[0]
    if order is not None:
        cmap = _categorical(order, palette)
        norm: Any = Normalize(-0.5, max(len(order), 1) - 0.5)
    else:
        finite = np.concatenate([v[np.isfinite(v)] for v in encoded.values()] or [np.zeros(0)])
        if log:
            finite = finite[finite > 0.0]
        lo = float(np.min(finite)) if finite.size else (1.0 if log else 0.0)
        hi = float(np.max(finite)) if finite.size else lo + 1.0
        if hi <= lo:
            hi = lo * 10.0 if log else lo + 1.0
        norm = LogNorm(lo, hi) if log else Normalize(lo, hi)
        cmap = mpl.colormaps["viridis"]
    cmap = cmap.with_extremes(bad="lightgrey")
    mesh = None
    star = {"marker": "*", "mfc": "white", "mec": "black", "ls": ""}
    legend: dict[str, Any] = {"reference": Line2D([], [], ms=12, label="reference", **star)}
    for ax, name in zip(grid_axes, names, strict=True):
        z = encoded[name]
        if log and order is None:
            z = np.where(z > 0.0, z, math.nan)
        grid = np.ma.masked_invalid(z.reshape(x.size, y.size).T)
        mesh = ax.pcolormesh(cell_edges(x, x_axis.scale), cell_edges(y, y_axis.scale), grid,
                             cmap=cmap, norm=norm, shading="flat")  # fmt: skip
        if np.ma.count_masked(grid):
            legend["failed"] = Patch(facecolor="lightgrey", label="failed / no value")
        ax.plot([reference[x_axis.param]], [reference[y_axis.param]], ms=12, **star)
        notes = []
        for overlay in (overlays or {}).get(name, ()):
            handle, text = _draw_overlay(ax, overlay)
            if handle is not None and handle.get_label() not in legend:
                legend[handle.get_label()] = handle
            if text:
                notes.append(text)
        if notes:
            ax.text(0.02, 0.02, "\n".join(notes), transform=ax.transAxes, fontsize="x-small",
                    va="bottom", bbox={"fc": "white", "alpha": 0.8, "lw": 0})  # fmt: skip
        ax.set_xscale("log" if x_axis.scale == "log" else "linear")
        ax.set_yscale("log" if y_axis.scale == "log" else "linear")
        ax.set_title(name, fontsize="medium")
        ax.set_xlabel(_label(x_axis.param, axis_labels))
    grid_axes[0].set_ylabel(_label(y_axis.param, axis_labels))
    # margins in inches, so that one panel and six keep the same room for labels and legend;
    # the legend in one row when its labels fit the width (about 12 characters an inch)
    chars = [len(h.get_label()) + 6 for h in legend.values()]
    ncol = len(chars) if sum(chars) < 12.0 * width else 1
    bottom = (0.63 + 0.2 * math.ceil(len(chars) / ncol)) / fig.get_figheight()
    heading = "\n".join(textwrap.fill(line, int(13.0 * width)) for line in heading.split("\n"))
    # room for the title's and the note's lines (about 0.19 in each)
    lines = 2 + heading.count("\n")
    top = min(0.8, 0.97 - 0.19 * lines / fig.get_figheight())
    left, right = 0.6 / width, 1.0 - 1.03 / width
    fig.subplots_adjust(top=top, bottom=bottom, left=left, right=right, wspace=0.12)
    cax = fig.add_axes((1.0 - 0.91 / width, bottom, 0.08 / width, top - bottom))
    cbar = fig.colorbar(mesh, cax=cax, label=metric)
    if order is not None:
        cbar.set_ticks(range(len(order)), labels=order)
    fig.suptitle(heading, fontsize="medium")
    fig.legend(handles=list(legend.values()), loc="lower center", ncol=ncol, fontsize="small",
               frameon=False)  # fmt: skip
    return fig
