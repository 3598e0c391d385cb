"""Co-simulation against the monolithic twin: convergence in the macro step H.

The closed loop of Fig. 5 (:data:`CROSSCHECK`: :data:`~drillstring.model.experiments.FIG5`
over tau in [0, 10], where the initial transient makes the largest coupling errors) is
co-simulated by the fmpy master (:mod:`.master`) for a list of macro steps ``H`` and schemes,
and compared with the monolithic twin (:mod:`.monolithic`: the same engine with the law
evaluated continuously, read from the same FMUs) at every communication point. Both use the
engine step ``h``; every ``H`` is a multiple of ``h`` and of the reference's output step
``min(H)``, so the plant FMU's RK4 steps fall on the monolithic run's and the difference is the
coupling error alone (sample and hold of the torque over a macro step), not a discretization
difference.

Expected orders (max error over the run against H): 1 for zero-order hold (the torque lags by
H/2 on average), 2 for linear extrapolation (the master gives the mean of the extrapolated line
over the step). For this loop Gauss-Seidel equals Jacobi: the controller has no state and its
output is exchanged at every communication point after the plant's outputs, so the plant
always receives ``R(x(t_n))`` either way.

:func:`run_crosscheck` returns the table (:func:`write_table`: ``crosscheck.csv``;
:func:`plot_errors`: ``crosscheck.png``, log-log errors against H with the fitted orders;
:func:`format_table`: text). :func:`adaptive_vs_fixed` compares the step-size-controlled master
with the fixed-step one at equal accuracy. The command line is ``drillstring crosscheck``
(:mod:`drillstring.apps.crosscheck`).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from drillstring.fileio import save_figure, write_csv
from drillstring.model.experiments import FIG5, Experiment
from drillstring.orchestration.closed_loop import (
    closed_loop_master,
    errors_on_grid,
    loop_model_of,
    run_cosim,
)
from drillstring.orchestration.monolithic import run_monolithic
from drillstring.orchestration.results import CosimResult
from drillstring.orchestration.step_control import StepControl

__all__ = [
    "CROSSCHECK",
    "DEFAULT_STEPS",
    "DEFAULT_SCHEMES",
    "FIT_MAX_H",
    "DEFAULT_CONTROL",
    "CrosscheckRow",
    "CrosscheckResult",
    "check_steps",
    "fit_order",
    "run_crosscheck",
    "write_table",
    "plot_errors",
    "format_row",
    "format_table",
    "HEADER_LINE",
    "adaptive_vs_fixed",
]

#: The cross-check's experiment: Fig. 5 over tau in [0, 10] (the initial transient).
CROSSCHECK = replace(FIG5, name="crosscheck", tau_end=10.0)
DEFAULT_STEPS: tuple[float, ...] = (0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001)
DEFAULT_SCHEMES: tuple[tuple[str, str], ...] = (
    ("jacobi", "zoh"),
    ("gauss-seidel", "zoh"),
    ("jacobi", "linear"),
)
#: fitted orders use the macro steps up to this one ("the smaller steps")
FIT_MAX_H = 0.01
#: step control of :func:`adaptive_vs_fixed` (absolute tolerance: see there)
DEFAULT_CONTROL = StepControl(rtol=0.0, atol=1e-2, h_min=1e-5, h_max=0.1)
TABLE_HEADER = (
    "scheme",
    "extrapolation",
    "H",
    "steps",
    "max_err_du",
    "max_err_dphi",
    "wall_time_s",
    "status",
)


@dataclass(frozen=True)
class CrosscheckRow:
    """One co-simulation against the reference; errors are NaN when the run failed."""

    scheme: str
    extrapolation: str
    H: float
    steps: int
    err_du: float
    err_dphi: float
    wall_time: float
    status: str = "ok"


@dataclass(frozen=True)
class CrosscheckResult:
    """The rows of a cross-check, the fitted orders and how the reference was computed.

    Attributes
    ----------
    rows : tuple of CrosscheckRow
        One per (scheme, extrapolation, H).
    orders : dict
        (scheme, extrapolation) -> {"du": order, "dphi": order} fitted over ``H <= fit_max``.
    experiment : Experiment
        The experiment run.
    fit_max : float
        Largest H in the fits.
    reference_wall_time, reference_dt : float
        Wall time and output step of the monolithic reference.
    """

    rows: tuple[CrosscheckRow, ...]
    orders: dict[tuple[str, str], dict[str, float]]
    experiment: Experiment
    fit_max: float
    reference_wall_time: float
    reference_dt: float
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def tau_end(self) -> float:
        """End of the runs."""
        return self.experiment.tau_end

    def select(self, scheme: str, extrapolation: str) -> list[CrosscheckRow]:
        """The rows of one coupling.

        Parameters
        ----------
        scheme, extrapolation : str
            The coupling.

        Returns
        -------
        list of CrosscheckRow
            Its rows, in the order of the steps.
        """
        return [r for r in self.rows if (r.scheme, r.extrapolation) == (scheme, extrapolation)]


def fit_order(H: Sequence[float], err: Sequence[float]) -> float:
    """Least-squares slope of log(err) against log(H).

    Parameters
    ----------
    H, err : sequence of float
        Macro steps and errors; only finite, positive errors count.

    Returns
    -------
    float
        The slope (NaN with fewer than two usable points).
    """
    h, e = np.asarray(H, dtype=float), np.asarray(err, dtype=float)
    ok = np.isfinite(e) & (e > 0) & (h > 0)
    if ok.sum() < 2:
        return math.nan
    return float(np.polyfit(np.log(h[ok]), np.log(e[ok]), 1)[0])


def _is_multiple(a: float, b: float) -> bool:
    k = round(a / b)
    return k >= 1 and abs(k * b - a) <= 1e-9 * a


def check_steps(steps: Sequence[float], h: float, tau_end: float) -> float:
    """Check the macro steps of a cross-check; returns the reference's output step ``min(H)``.

    Parameters
    ----------
    steps : sequence of float
        The macro steps H.
    h : float
        The engine step.
    tau_end : float
        End of the runs.

    Returns
    -------
    float
        The smallest H.

    Raises
    ------
    ValueError
        Naming an H that is not positive, not a multiple of ``h`` or of the smallest H, or a
        ``tau_end`` that is not positive or not a multiple of the smallest H.
    """
    if not steps:
        raise ValueError("need at least one macro step H")
    for H in steps:
        if not (isinstance(H, int | float) and math.isfinite(H) and H > 0):
            raise ValueError(f"macro step H must be a positive finite number, got {H!r}")
    if not (math.isfinite(tau_end) and tau_end > 0):
        raise ValueError(f"tau_end must be a positive finite time, got {tau_end!r}")
    dt = min(steps)
    for H in steps:
        if not _is_multiple(H, h):
            raise ValueError(f"macro step H = {H!r} is not a multiple of the engine step h = {h!r}")
    for H in steps:
        if not _is_multiple(H, dt):
            raise ValueError(
                f"macro step H = {H!r} is not a multiple of the smallest one, {dt!r}: the "
                "communication points must lie on the reference's grid"
            )
    if not _is_multiple(tau_end, dt):
        raise ValueError(f"tau_end = {tau_end!r} is not a multiple of the smallest H = {dt!r}")
    return dt


def run_crosscheck(
    fmus_dir: str | os.PathLike[str],
    experiment: Experiment = CROSSCHECK,
    *,
    steps: Sequence[float] = DEFAULT_STEPS,
    fit_max: float = FIT_MAX_H,
    on_row: Callable[[CrosscheckRow], None] | None = None,
) -> CrosscheckResult:
    """Co-simulate for every scheme of :data:`DEFAULT_SCHEMES` and H, compare with one monolithic
    run (module docstring).

    Parameters
    ----------
    fmus_dir : path
        Folder of the built FMUs.
    experiment : Experiment
        The set-up, run over ``[0, experiment.tau_end]`` (default :data:`CROSSCHECK`).
    steps : sequence of float
        Macro steps H (see :func:`check_steps`).
    fit_max : float
        Orders are fitted over ``H <= fit_max``.
    on_row : callable, optional
        Called with every row as soon as it is computed.

    Returns
    -------
    CrosscheckResult
        Rows and fitted orders.

    Raises
    ------
    ValueError
        For bad steps.
    RuntimeError
        If the monolithic reference stops early.
    """
    tau_end = experiment.tau_end
    steps = sorted({float(H) for H in steps}, reverse=True)
    rows = []
    with closed_loop_master(fmus_dir, experiment) as master:
        model = loop_model_of(master)
        dt = check_steps(steps, model.options.h, tau_end)
        w0 = time.perf_counter()
        ref = run_monolithic(model, tau_end, dt_out=dt)
        ref_wall = time.perf_counter() - w0
        if not ref.status.ok:
            raise RuntimeError(f"the monolithic reference stopped early: {ref.status.message}")
        for scheme, ex in DEFAULT_SCHEMES:
            for H in steps:
                res = run_cosim(master, tau_end, H, scheme=scheme, extrapolation=ex)
                if res.completed:
                    err = errors_on_grid(res, ref, dt)
                    status = "ok"
                else:
                    err = {"du": math.nan, "dphi": math.nan}
                    f = res.failure
                    status = f"failed at tau = {f.time:.6g}: {f.unit} {f.function} {f.status}"
                row = CrosscheckRow(
                    scheme,
                    ex,
                    H,
                    res.stats.accepted,
                    err["du"],
                    err["dphi"],
                    res.stats.wall_time,
                    status,
                )
                rows.append(row)
                if on_row is not None:
                    on_row(row)
    orders = {}
    for key in DEFAULT_SCHEMES:
        sel = [r for r in rows if (r.scheme, r.extrapolation) == key and r.H <= fit_max * 1.000001]
        Hs = [r.H for r in sel]
        orders[key] = {
            "du": fit_order(Hs, [r.err_du for r in sel]),
            "dphi": fit_order(Hs, [r.err_dphi for r in sel]),
        }
    return CrosscheckResult(tuple(rows), orders, experiment, fit_max, ref_wall, dt)


def write_table(result: CrosscheckResult, path: str | os.PathLike[str]) -> Path:
    """Write ``crosscheck.csv``: one row per (scheme, extrapolation, H).

    Parameters
    ----------
    result : CrosscheckResult
        The cross-check.
    path : path
        The CSV file (written atomically).

    Returns
    -------
    Path
        ``path``.
    """
    rows = [
        (r.scheme, r.extrapolation, r.H, r.steps, r.err_du, r.err_dphi, r.wall_time, r.status)
        for r in result.rows
    ]
    return write_csv(path, TABLE_HEADER, rows)


def format_row(r: CrosscheckRow) -> str:
    """One row of the table as text.

    Parameters
    ----------
    r : CrosscheckRow
        The row.

    Returns
    -------
    str
        The row in the columns of :data:`HEADER_LINE`, with its status if it failed.
    """
    line = (
        f"{r.scheme:>12} {r.extrapolation:>6} {r.H:8.4g} {r.steps:7d} {r.err_du:11.3e} "
        f"{r.err_dphi:11.3e} {r.wall_time:8.2f}"
    )
    return line if r.status == "ok" else f"{line}  {r.status}"


HEADER_LINE = (
    f"{'scheme':>12} {'extrap':>6} {'H':>8} {'steps':>7} {'err du':>11} {'err dphi':>11} "
    f"{'wall s':>8}"
)


def format_table(result: CrosscheckResult, rows: bool = True) -> str:
    """The cross-check as text.

    Parameters
    ----------
    result : CrosscheckResult
        The cross-check.
    rows : bool
        Include the table of rows (else only the fitted orders).

    Returns
    -------
    str
        The text.
    """
    lines = [HEADER_LINE, *(format_row(r) for r in result.rows)] if rows else []
    lines.append(f"fitted orders over H <= {result.fit_max:g}:")
    for (scheme, ex), o in result.orders.items():
        lines.append(f"  {scheme}/{ex}: dphi {o['dphi']:.3f}, du {o['du']:.3f}")
    return "\n".join(lines)


def plot_errors(result: CrosscheckResult, path: str | os.PathLike[str]) -> Path:
    """Write a log-log PNG of the max errors in dphi/dtau and du/dtau against H.

    Parameters
    ----------
    result : CrosscheckResult
        The cross-check (the legend gives the fitted orders).
    path : path
        The PNG file (written atomically).

    Returns
    -------
    Path
        ``path``.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 4.2), dpi=150)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 2)
    markers = ["o", "s", "^", "D", "v"]
    for ax, name, label in zip(axes, ("dphi", "du"), (r"$\dot\varphi$", r"$\dot u$"), strict=True):
        for i, key in enumerate(result.orders):
            rows = result.select(*key)
            H = np.array([r.H for r in rows])
            e = np.array([getattr(r, f"err_{name}") for r in rows])
            order = result.orders[key][name]
            failed = [f"{r.H:g}" for r in rows if r.status != "ok"]
            note = f" (failed: H = {', '.join(failed)})" if failed else ""
            ls = "--" if key[0] == "gauss-seidel" else "-"
            ax.loglog(
                H,
                e,
                ls,
                marker=markers[i % len(markers)],
                mfc="none" if key[0] == "gauss-seidel" else None,
                label=f"{key[0]}/{key[1]}: order {order:.2f}{note}",
            )
        ax.axvspan(min(r.H for r in result.rows), result.fit_max, color="0.9", zorder=0)
        ax.set_xlabel("macro step H")
        ax.set_ylabel(f"max |error| in {label}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(
        rf"co-simulation vs monolithic, Fig. 5 loop, $\tau \in [0, {result.tau_end:g}]$ "
        f"(orders fitted over the shaded H <= {result.fit_max:g})",
        fontsize=10,
    )
    fig.tight_layout()
    return save_figure(fig, path)


def adaptive_vs_fixed(
    fmus_dir: str | os.PathLike[str],
    experiment: Experiment = CROSSCHECK,
    *,
    control: StepControl = DEFAULT_CONTROL,
    extrapolation: str = "zoh",
    max_doublings: int = 6,
) -> dict[str, Any]:
    """Steps of the adaptive master against the fixed-step master for the same error.

    The adaptive run reaches a max error ``E`` in dphi/dtau against the monolithic twin
    evaluated at its own communication points with ``N_a`` attempted steps (accepted +
    rejected). Fixed-step runs then start at ``N_a`` steps and double the count until their
    error is at most ``E``.

    The default tolerance is absolute (``rtol=0``): the exchanged torque is thousands during
    the initial transient, where the coupling error is made, and tens later, so a relative
    tolerance would allow the largest input errors exactly where they matter most (with
    ``rtol=1e-3`` the adaptive run needs more steps than the fixed-step one).

    Parameters
    ----------
    fmus_dir : path
        Folder of the built FMUs.
    experiment : Experiment
        The set-up (default :data:`CROSSCHECK`).
    control : StepControl
        Step control of the adaptive run (default absolute tolerance 1e-2 on the input-error
        impulse).
    extrapolation : str
        ``"zoh"`` or ``"linear"``, for all runs.
    max_doublings : int
        Doublings of the fixed step count tried.

    Returns
    -------
    dict
        ``adaptive_error``, ``adaptive_attempted``/``accepted``/``rejected``,
        ``adaptive_h_range``, ``fixed`` (list of (steps, error)) and ``fixed_steps_needed``
        (None if ``max_doublings`` did not suffice).

    Raises
    ------
    RuntimeError
        If the adaptive co-simulation fails.
    """
    tau_end = experiment.tau_end

    def error(res: CosimResult) -> float:
        """Max |dphi| error at the run's own communication points."""
        ref = run_monolithic(model, float(res.time[-1]), times=res.time)
        if not ref.status.ok:
            raise RuntimeError(f"the monolithic reference stopped early: {ref.status.message}")
        return float(np.max(np.abs(res["plant.dphi"] - ref.dphi)))

    with closed_loop_master(fmus_dir, experiment) as master:
        model = loop_model_of(master)
        ad = run_cosim(master, tau_end, None, step_control=control, extrapolation=extrapolation)
        if not ad.completed:
            raise RuntimeError(f"adaptive co-simulation failed: {ad.failure}")
        e_ad = error(ad)
        n_ad = ad.stats.attempted
        fixed: list[tuple[int, float]] = []
        needed = None
        n = n_ad
        for _ in range(max_doublings + 1):
            res = run_cosim(master, tau_end, tau_end / n, extrapolation=extrapolation)
            e = error(res) if res.completed else math.inf
            fixed.append((n, e))
            if e <= e_ad:
                needed = n
                break
            n *= 2
    return {
        "extrapolation": extrapolation,
        "control": control,
        "adaptive_error": e_ad,
        "adaptive_attempted": n_ad,
        "adaptive_accepted": ad.stats.accepted,
        "adaptive_rejected": ad.stats.rejected,
        "adaptive_h_range": (ad.stats.h_min, ad.stats.h_max),
        "fixed": fixed,
        "fixed_steps_needed": needed,
    }
