"""Figures 2, 3 and 4 of the paper (stability diagram of (21), axial limit cycle, averaged
contact force) as PNG + CSV."""

from __future__ import annotations

import csv
import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np
from matplotlib.patches import Patch
from tqdm import tqdm

from drillstring.analysis.axial_stability import (
    StabilityDiagram,
    stability_diagram,
)
from drillstring.analysis.limit_cycles import (
    FIG4_ETABAR2,
    FIG4_GAMMABARS,
    FIT_POINTS,
    LimitCycle,
    default_fit_delays,
    fit_slope,
)
from drillstring.analysis.limit_cycles import limit_cycle as find_limit_cycle
from drillstring.fileio import save_figure, write_csv, write_json
from drillstring.plotting import new_figure


def write_limit_cycle_figure(
    out_dir: str | os.PathLike[str],
    gammabar: float = 0.2,
    etabar2: float = FIG4_ETABAR2,
    taubar_n: float = 10.0,
    periods: int = 2,
) -> dict[str, Path]:
    """Fig. 3: ubar and gbar over ``periods`` periods of the axial stick-slip limit cycle.

    Parameters
    ----------
    out_dir : path-like
        Folder of ``fig3_limit_cycle.png``, ``.csv`` (the repeated samples) and ``.json`` (period,
        stick fraction, both estimates of the average).
    gammabar, etabar2, taubar_n : float
        The point of (18).
    periods : int
        Number of periods drawn.

    Returns
    -------
    dict
        Paths ``png``, ``csv`` and ``json``.

    Raises
    ------
    RuntimeError
        The motion at this point does not settle on a periodic limit cycle.
    """
    out = Path(out_dir)
    lc = find_limit_cycle(gammabar, etabar2, taubar_n, n_samples=2000)
    if lc.kind != "periodic":
        raise RuntimeError(
            f"no axial limit cycle at gammabar={gammabar}, etabar2={etabar2}, "
            f"taubar_n={taubar_n}: {lc.kind}"
        )
    s = lc.samples
    t = np.concatenate([s["taubar"][:-1] + k * lc.period for k in range(periods)])
    reps = {k: np.concatenate([s[k][:-1]] * periods) for k in ("ubar", "dubar", "gbar")}
    csv = write_csv(
        out / "fig3_limit_cycle.csv",
        ("taubar", "ubar", "dubar", "gbar"),
        zip(t, reps["ubar"], reps["dubar"], reps["gbar"], strict=True),
    )
    summary = write_json(
        out / "fig3_limit_cycle.json",
        {
            "gammabar": gammabar,
            "etabar2": etabar2,
            "taubar_n": taubar_n,
            "period": lc.period,
            "stick_fraction": lc.stick_fraction,
            "stick_phases_per_period": lc.stick_phases,
            "average_contact_force": lc.average,
            "average_check_etabar2_mean_ubar": lc.average_check,
            "period_drift": lc.period_drift,
        },
    )
    fig = new_figure()
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(t, reps["ubar"], "k-", lw=1.2)
    ax1.set_ylabel(r"$\bar u$")
    ax1.set_title(
        rf"Axial stick-slip limit cycle, $\bar\gamma$={gammabar:g}, $\bar\eta^2$={etabar2:g}, "
        rf"$\bar\tau_n$={taubar_n:g} (period {lc.period:.4g}, stick {100 * lc.stick_fraction:.0f}%)"
    )
    ax2.plot(t, reps["gbar"], "tab:red", lw=1.2)
    ax2.set_ylabel(r"$\bar g$")
    ax2.set_xlabel(r"$\bar\tau$")
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    png = save_figure(fig, out / "fig3_limit_cycle.png")
    return {"png": png, "csv": csv, "json": summary}


#: Columns of a Fig. 4 points file (one limit cycle per row).
POINT_COLUMNS = ("gammabar", "etabar2", "taubar_n", "kind", "average", "period", "stick_fraction")


def write_average_points(path: str | os.PathLike[str], curves: Iterable[LimitCycle]) -> Path:
    """Write limit cycles as a Fig. 4 points file (CSV, :data:`POINT_COLUMNS`), atomically.

    Parameters
    ----------
    path : path-like
        The CSV file.
    curves : iterable of LimitCycle
        One row each (samples are not written).

    Returns
    -------
    Path
        ``path``.
    """
    rows = (
        (lc.gammabar, lc.etabar2, lc.taubar_n, lc.kind, lc.average, lc.period, lc.stick_fraction)
        for lc in curves
    )
    return write_csv(path, POINT_COLUMNS, rows)


def read_average_points(path: str | os.PathLike[str]) -> list[LimitCycle]:
    """Read a Fig. 4 points file written by :func:`write_average_points`.

    Parameters
    ----------
    path : path-like
        The CSV file.

    Returns
    -------
    list of LimitCycle
        The rows, without samples and with the unwritten fields at their defaults.

    Raises
    ------
    ValueError
        When the file is missing, has other columns or a value that is not a number.
    """
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            if tuple(reader.fieldnames or ()) != POINT_COLUMNS:
                raise ValueError(
                    f"{path}: columns {reader.fieldnames} are not those of a points file "
                    f"{POINT_COLUMNS}"
                )
            out = []
            for i, row in enumerate(reader, start=2):
                try:
                    out.append(
                        LimitCycle(
                            gammabar=float(row["gammabar"]),
                            etabar2=float(row["etabar2"]),
                            taubar_n=float(row["taubar_n"]),
                            kind=row["kind"],
                            average=float(row["average"]),
                            period=float(row["period"]),
                            stick_fraction=float(row["stick_fraction"]),
                        )
                    )
                except ValueError as exc:
                    raise ValueError(f"{path}, line {i}: {exc}") from None
    except OSError as exc:
        raise ValueError(f"cannot read the points file {path}: {exc}") from None
    return out


def average_curves(
    gammabars: Sequence[float] = FIG4_GAMMABARS,
    etabar2: float = FIG4_ETABAR2,
    n_points: int = FIT_POINTS,
    *,
    known: Iterable[LimitCycle] = (),
    progress: bool = True,
    on_point: Callable[[list[LimitCycle]], None] | None = None,
) -> dict[float, list[LimitCycle]]:
    """The limit cycles of the Fig. 4 lines (gammabar -> points along :func:`default_fit_delays`).

    Points already in ``known`` (same gammabar, etabar^2 and delay, e.g. the design's own line)
    are taken from there, not computed again.

    Parameters
    ----------
    gammabars : sequence of float
        One line per damping value.
    etabar2 : float
        Stiffness of all lines.
    n_points : int
        Delays per line.
    known : iterable of LimitCycle
        Points computed before; matched exactly on (gammabar, etabar2, taubar_n).
    progress : bool
        Show a progress bar over the points to compute.
    on_point : callable, optional
        Called as ``on_point(points_so_far)`` after every point, reused or computed (to keep
        partial results).

    Returns
    -------
    dict
        gammabar -> the limit cycles of its line, in order of delay.
    """
    have = {(lc.gammabar, lc.etabar2, lc.taubar_n): lc for lc in known}
    jobs = [(g, float(tb)) for g in gammabars for tb in default_fit_delays(g, etabar2, n_points)]
    curves: dict[float, list[LimitCycle]] = {g: [] for g in gammabars}
    done: list[LimitCycle] = []
    todo = [job for job in jobs if (job[0], etabar2, job[1]) not in have]
    bar = tqdm(total=len(todo), desc="Fig. 4 limit cycles", disable=not progress)
    for g, tb in jobs:
        lc = have.get((g, etabar2, tb))
        if lc is None:
            lc = find_limit_cycle(g, etabar2, tb, n_samples=0)
            bar.update(1)
        curves[g].append(lc)
        done.append(lc)
        if on_point is not None:
            on_point(done)
    bar.close()
    return curves


def write_average_figure(
    out_dir: str | os.PathLike[str],
    gammabars: Sequence[float] = FIG4_GAMMABARS,
    etabar2: float = FIG4_ETABAR2,
    n_points: int = FIT_POINTS,
    *,
    known: Iterable[LimitCycle] = (),
    progress: bool = True,
) -> dict[str, Path]:
    """Fig. 4: (lambda/vbar0)<gbar>_a against taubar_n, linear fits (22), taubar_crit marked.

    Parameters
    ----------
    out_dir : path-like
        Folder of ``fig4_average.png``, ``fig4_average.csv`` (points) and ``fig4_fits.csv``.
    gammabars, etabar2, n_points : sequence of float, float, int
        The lines of the figure (as for :func:`average_curves`).
    known : iterable of LimitCycle
        Points computed before (the design's line, :func:`read_average_points`), reused.
    progress : bool
        Show a progress bar.

    Returns
    -------
    dict
        Paths ``png``, ``csv`` and ``fits``. The points file is rewritten after every point, so
        an interrupted run keeps its results.

    Raises
    ------
    ValueError
        A line with fewer than two periodic points (no fit).
    """
    out = Path(out_dir)
    points = out / "fig4_average.csv"
    curves = average_curves(
        gammabars,
        etabar2,
        n_points,
        known=known,
        progress=progress,
        on_point=lambda done: write_average_points(points, done),
    )
    fits = {
        g: fit_slope(g, etabar2, [c.taubar_n for c in cs], [c.average for c in cs])
        for g, cs in curves.items()
    }
    fits_csv = write_csv(
        out / "fig4_fits.csv",
        ("gammabar", "etabar2", "A", "taubar_zero", "taubar_crit", "residual_rms"),
        [(g, etabar2, f.A, f.taubar_zero, f.taubar_crit, f.residual_rms) for g, f in fits.items()],
    )
    fig = new_figure()
    ax = fig.add_subplot()
    colors = ["tab:blue", "tab:red", "tab:green", "tab:purple"]
    for i, (g, f) in enumerate(fits.items()):
        c = colors[i % len(colors)]
        ax.plot(f.taubar, f.average, "o", color=c, ms=4, label=rf"$\bar\gamma$={g:g}")
        tt = np.linspace(f.taubar_zero, f.taubar.max(), 50)
        ax.plot(tt, f.A * (tt - f.taubar_zero), "-", color=c, lw=1, label=f"fit, A={f.A:.4f}")
        ax.axvline(f.taubar_crit, color=c, ls=":", lw=1)
    ax.set_xlabel(r"$\bar\tau_n$")
    ax.set_ylabel(r"$\frac{\lambda}{\bar v_0}\langle\bar g\rangle_a$")
    ax.set_title(
        rf"Averaged contact force, $\bar\eta^2$={etabar2:g} (dotted: $\bar\tau_n^{{crit}}$)"
    )
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    png = save_figure(fig, out / "fig4_average.png")
    return {"png": png, "csv": points, "fits": fits_csv}


def write_stability_diagram(
    out_dir: str | os.PathLike[str], *, diagram: StabilityDiagram | None = None
) -> dict[str, Path]:
    """Write Fig. 2 (``fig2_stability.png``, ``fig2_boundaries.csv``) atomically into ``out_dir``.

    CSV columns: gammabar, segment (polyline id per gammabar), taubar_n, etabar2.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created).
    diagram : StabilityDiagram, optional
        A diagram computed before (default: that of
        :func:`~drillstring.analysis.axial_stability.stability_diagram`, Fig. 2).

    Returns
    -------
    dict
        Paths ``png`` and ``csv``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    d = diagram or stability_diagram()

    csv_path = write_csv(
        out / "fig2_boundaries.csv",
        ("gammabar", "segment", "taubar_n", "etabar2"),
        (
            (g, i, float(t), float(e))
            for g in d.gammabars
            for i, seg in enumerate(d.boundaries[g])
            for t, e in seg
        ),
    )
    fig = new_figure()
    ax = fig.add_subplot()
    ax.contourf(
        d.taubar_grid, d.etabar2_grid, d.stable.astype(float), levels=[0.5, 1.5], colors=["0.82"]
    )
    styles = ["-", "--", "-.", ":"]
    colors = ["k", "tab:blue", "tab:red", "tab:green", "tab:purple", "tab:orange"]
    handles = [
        Patch(
            facecolor="0.82",
            edgecolor="none",
            label=rf"stable, $\bar\gamma$ = {d.shade_gammabar:g}",
        )
    ]
    for i, g in enumerate(d.gammabars):
        style = dict(color=colors[i % len(colors)], ls=styles[i % len(styles)], lw=1.3)
        for seg in d.boundaries[g]:
            ax.plot(seg[:, 0], seg[:, 1], **style)
        (h,) = ax.plot([], [], label=rf"boundary, $\bar\gamma$ = {g:g}", **style)
        handles.append(h)
    ax.set_xlim(*d.taubar_range)
    ax.set_ylim(*d.etabar2_range)
    ax.set_xlabel(r"delay $\bar\tau_n$")
    ax.set_ylabel(r"stiffness $\bar\eta^2$")
    ax.set_title(r"Axial stability, eq. (21): $s^2+\bar\gamma s+\bar\eta^2+1-e^{-s\bar\tau_n}=0$")
    ax.legend(handles=handles, loc="lower right", fontsize=8, framealpha=0.9)
    fig.tight_layout()
    png_path = save_figure(fig, out / "fig2_stability.png")
    return {"png": png_path, "csv": csv_path}
