"""Maps of sweep metrics: a heat map over the swept plane (2-D) or a line plot (1-D), with the
reference point (the base set's value of each swept parameter) marked. Failed points are grey."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["cell_edges", "metric_figure"]


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


def _encode(values: Sequence[Any], kind: str) -> tuple[np.ndarray, list[str] | None]:
    """Numbers for the plot; strings become category codes (sorted), with their labels."""
    if kind != "str":
        return np.array([math.nan if v is None else float(v) for v in values]), None
    labels = sorted({v for v in values if v})
    codes = {s: k for k, s in enumerate(labels)}
    return np.array([codes[v] if v else math.nan for v in values], dtype=float), labels


def metric_figure(
    metric: str,
    kind: str,
    values: Sequence[Any],
    axes: Sequence[Any],
    reference: dict[str, float],
    title: str,
) -> Any:
    """Figure of one metric; ``values`` in point-index order (row-major over ``axes``; None or ''
    for a failed point), ``axes`` the spec's :class:`~drillstring.apps.sweep.spec.Axis` objects."""
    z, labels = _encode(values, kind)
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
            cmap = mpl.colormaps["tab10"].resampled(max(len(labels), 1))
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
