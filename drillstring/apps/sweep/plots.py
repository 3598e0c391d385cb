"""Maps of sweep metrics: a heat map over the swept plane (2-D) or a line plot (1-D), with the
reference point (the base set's value of each swept parameter) marked. Failed points are grey."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["cell_edges", "metric_figure", "panel_figure"]


def _figure(figsize: tuple[float, float]) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=120)
    FigureCanvasAgg(fig)
    return fig


def cell_edges(values: np.ndarray, scale: str) -> np.ndarray:
    """Edges of the cells centred on the grid values (geometric midpoints on a log scale)."""
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


def metric_figure(
    metric: str,
    kind: str,
    values: Sequence[Any],
    axes: Sequence[Any],
    reference: dict[str, float],
    title: str,
    categories: Sequence[str] | None = None,
    palette: Mapping[str, str] | None = None,
) -> Any:
    """Figure of one metric; ``values`` in point-index order (row-major over ``axes``; None or ''
    for a failed point), ``axes`` the spec's :class:`~drillstring.apps.sweep.spec.Axis` objects;
    ``categories`` orders the labels of a string metric, ``palette`` colours them."""
    z, labels = _encode(values, kind, categories)
    fig = _figure((6.4, 4.8))
    ax = fig.add_subplot(1, 1, 1)
    x_axis = axes[0]
    x = x_axis.values()
    if len(axes) == 1:
        ax.plot(x, z, "o-", ms=3)
        ax.axvline(reference[x_axis.param], color="k", ls="--", lw=1, label="reference")
        ax.set_xscale("log" if x_axis.scale == "log" else "linear")
        ax.set_xlabel(x_axis.param)
        ax.set_ylabel(metric)
        if labels is not None:
            ax.set_yticks(range(len(labels)), labels)
        ax.legend(loc="best")
    else:
        import matplotlib as mpl

        y_axis = axes[1]
        y = y_axis.values()
        grid = np.ma.masked_invalid(z.reshape(x.size, y.size).T)
        if labels is not None:
            cmap = _categorical(labels, palette)
            vmin, vmax = -0.5, max(len(labels), 1) - 0.5
        else:
            cmap = mpl.colormaps["viridis"].copy()
            vmin = vmax = None
        cmap = cmap.with_extremes(bad="lightgrey")
        mesh = ax.pcolormesh(
            cell_edges(x, x_axis.scale),
            cell_edges(y, y_axis.scale),
            grid,
            cmap=cmap,
            vmin=vmin,
            vmax=vmax,
            shading="flat",
        )
        cbar = fig.colorbar(mesh, ax=ax, label=metric)
        if labels is not None:
            cbar.set_ticks(range(len(labels)), labels=labels)
        ax.set_xscale("log" if x_axis.scale == "log" else "linear")
        ax.set_yscale("log" if y_axis.scale == "log" else "linear")
        rx, ry = reference[x_axis.param], reference[y_axis.param]
        ax.plot([rx], [ry], marker="*", ms=14, mfc="white", mec="black", ls="", label="reference")
        handles, _ = ax.get_legend_handles_labels()
        if np.ma.count_masked(grid):
            from matplotlib.patches import Patch

            handles.append(Patch(facecolor="lightgrey", label="failed / no value"))
        ax.legend(handles=handles, loc="best", fontsize="small")
        ax.set_xlabel(x_axis.param)
        ax.set_ylabel(y_axis.param)
    ax.set_title(title, fontsize="medium")
    fig.tight_layout()
    return fig


def panel_figure(
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
) -> Any:
    """One metric for several runs side by side (one panel each) on one shared colour scale.

    ``panels`` maps each panel's label to its values in point-index order (as
    :func:`metric_figure`); a 2-D sweep gives heat maps with one colour bar, a 1-D sweep one
    line per panel on shared axes. ``log``: logarithmic colour scale (positive values);
    ``categories`` orders the labels of a string metric, shared by the panels, and ``palette``
    colours them.
    """
    import matplotlib as mpl
    from matplotlib.colors import LogNorm, Normalize

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
    x_axis = axes[0]
    x = x_axis.values()
    if len(axes) == 1:
        fig = _figure((6.4, 4.8))
        ax = fig.add_subplot(1, 1, 1)
        for name in names:
            ax.plot(x, encoded[name], "o-", ms=3, label=name)
        ax.axvline(reference[x_axis.param], color="k", ls="--", lw=1)
        ax.set_xscale("log" if x_axis.scale == "log" else "linear")
        if log:
            ax.set_yscale("log")
        ax.set_xlabel(x_axis.param)
        ax.set_ylabel(metric)
        if order is not None:
            ax.set_yticks(range(len(order)), order)
        ax.legend(loc="best", fontsize="small")
        ax.set_title(title, fontsize="medium")
        fig.tight_layout()
        return fig
    y_axis = axes[1]
    y = y_axis.values()
    fig = _figure((3.4 * len(names) + 1.2, 3.8))
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
    for ax, name in zip(grid_axes, names, strict=True):
        z = encoded[name]
        if log and order is None:
            z = np.where(z > 0.0, z, math.nan)
        grid = np.ma.masked_invalid(z.reshape(x.size, y.size).T)
        mesh = ax.pcolormesh(
            cell_edges(x, x_axis.scale),
            cell_edges(y, y_axis.scale),
            grid,
            cmap=cmap,
            norm=norm,
            shading="flat",
        )
        ax.plot(
            [reference[x_axis.param]],
            [reference[y_axis.param]],
            marker="*",
            ms=12,
            mfc="white",
            mec="black",
            ls="",
        )
        ax.set_xscale("log" if x_axis.scale == "log" else "linear")
        ax.set_yscale("log" if y_axis.scale == "log" else "linear")
        ax.set_title(name, fontsize="medium")
        ax.set_xlabel(x_axis.param)
    grid_axes[0].set_ylabel(y_axis.param)
    cbar = fig.colorbar(mesh, ax=list(grid_axes), label=metric, fraction=0.03, pad=0.02)
    if order is not None:
        cbar.set_ticks(range(len(order)), labels=order)
    fig.suptitle(title, fontsize="medium")
    return fig
