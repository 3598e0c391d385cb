"""Figures 3 and 4 of the paper (axial limit cycle, averaged contact force) as PNG + CSV."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from tqdm import tqdm

from drillstring.analysis.limit_cycles import (
    FIG4_ETABAR2,
    FIG4_GAMMABARS,
    LimitCycle,
    default_fit_delays,
    fit_slope,
)
from drillstring.analysis.limit_cycles import limit_cycle as find_limit_cycle
from drillstring.fileio import save_figure, write_csv, write_json


def _figure(figsize: tuple[float, float]):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=150)
    FigureCanvasAgg(fig)
    return fig


def write_limit_cycle_figure(
    out_dir: str | os.PathLike[str],
    gammabar: float = 0.2,
    etabar2: float = FIG4_ETABAR2,
    taubar_n: float = 10.0,
    periods: int = 2,
) -> dict[str, Path]:
    """Fig. 3: ubar and gbar over ``periods`` periods of the axial stick-slip limit cycle."""
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
    fig = _figure((7.0, 4.6))
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


def write_average_figure(
    out_dir: str | os.PathLike[str],
    gammabars: Sequence[float] = FIG4_GAMMABARS,
    etabar2: float = FIG4_ETABAR2,
    n_points: int = 25,
    *,
    progress: bool = True,
) -> dict[str, Path]:
    """Fig. 4: (lambda/vbar0)<gbar>_a against taubar_n, linear fits (22), taubar_crit marked.

    The points CSV is rewritten after every point, so an interrupted sweep keeps its results.
    """
    out = Path(out_dir)
    header = ("gammabar", "etabar2", "taubar_n", "kind", "average", "period", "stick_fraction")
    rows: list[tuple] = []
    curves: dict[float, list[LimitCycle]] = {}
    jobs = [(g, float(tb)) for g in gammabars for tb in default_fit_delays(g, etabar2, n_points)]
    for g, tb in tqdm(jobs, desc="Fig. 4 limit cycles", disable=not progress):
        lc = find_limit_cycle(g, etabar2, tb, n_samples=0)
        curves.setdefault(g, []).append(lc)
        rows.append((g, etabar2, tb, lc.kind, lc.average, lc.period, lc.stick_fraction))
        write_csv(out / "fig4_average.csv", header, rows)
    fits = {
        g: fit_slope(g, etabar2, [c.taubar_n for c in cs], [c.average for c in cs])
        for g, cs in curves.items()
    }
    fits_csv = write_csv(
        out / "fig4_fits.csv",
        ("gammabar", "etabar2", "A", "taubar_zero", "taubar_crit", "residual_rms"),
        [(g, etabar2, f.A, f.taubar_zero, f.taubar_crit, f.residual_rms) for g, f in fits.items()],
    )
    fig = _figure((7.0, 4.6))
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
    return {"png": png, "csv": out / "fig4_average.csv", "fits": fits_csv}
