"""``drillstring crosscheck``: co-simulation against the monolithic solver, convergence in H.

The closed loop of Fig. 5 (reference set of the gains file, dphi/dtau(0) = -2.5, controller
(29)-(31) on from tau = 0, paper's law without latch) is co-simulated by the fmpy master
(:mod:`.master`) for a list of macro steps ``H`` and schemes, and compared with the monolithic
solver (:func:`~drillstring.orchestration.monolithic.run_monolithic`: the same engine with the
law evaluated continuously) at every communication point. Both use the engine step ``h``; every
``H`` is a multiple of ``h`` and of the reference's output step ``min(H)``, so the plant FMU's RK4
steps fall on the monolithic run's and the difference is the coupling error alone (sample and
hold of the torque over a macro step), not a discretization difference.

Expected orders (max error over the run against H): 1 for zero-order hold (the torque lags by
H/2 on average), 2 for linear extrapolation (the master gives the mean of the extrapolated line
over the step). For this loop Gauss-Seidel equals Jacobi: the controller has no state and its
output is exchanged at every communication point after the plant's outputs, so the plant
always receives ``R(x(t_n))`` either way.

Writes ``crosscheck.csv`` (scheme, extrapolation, H, steps, max error du, max error dphi, wall
time, status) and ``crosscheck.png`` (log-log errors against H with the fitted orders) and
prints the table. :func:`adaptive_vs_fixed` compares the step-size-controlled master with the
fixed-step one at equal accuracy.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from drillstring.controller.gains import GainsFile
from drillstring.orchestration.closed_loop import (
    LoopSetup,
    build_fmus_into,
    closed_loop_master,
    errors_on_grid,
    fmu_paths,
    load_gains,
    reference_at,
    run_cosim,
    run_reference,
)
from drillstring.orchestration.master import StepControl

__all__ = [
    "DEFAULT_STEPS",
    "DEFAULT_SCHEMES",
    "CrosscheckRow",
    "CrosscheckResult",
    "fit_order",
    "run_crosscheck",
    "write_table",
    "plot_errors",
    "format_table",
    "adaptive_vs_fixed",
    "crosscheck_main",
]

DEFAULT_STEPS: tuple[float, ...] = (0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001)
DEFAULT_SCHEMES: tuple[tuple[str, str], ...] = (
    ("jacobi", "zoh"),
    ("gauss-seidel", "zoh"),
    ("jacobi", "linear"),
)
#: fitted orders use the macro steps up to this one ("the smaller steps")
FIT_MAX_H = 0.01
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
    rows: tuple[CrosscheckRow, ...]
    #: (scheme, extrapolation) -> {"du": order, "dphi": order} fitted over H <= fit_max
    orders: dict[tuple[str, str], dict[str, float]]
    tau_end: float
    setup: LoopSetup
    fit_max: float
    reference_wall_time: float
    reference_dt: float
    extra: dict[str, Any] = field(default_factory=dict)

    def select(self, scheme: str, extrapolation: str) -> list[CrosscheckRow]:
        return [r for r in self.rows if (r.scheme, r.extrapolation) == (scheme, extrapolation)]


def fit_order(H: Sequence[float], err: Sequence[float]) -> float:
    """Least-squares slope of log(err) against log(H) over the finite, positive errors
    (NaN with fewer than two)."""
    h, e = np.asarray(H, dtype=float), np.asarray(err, dtype=float)
    ok = np.isfinite(e) & (e > 0) & (h > 0)
    if ok.sum() < 2:
        return math.nan
    return float(np.polyfit(np.log(h[ok]), np.log(e[ok]), 1)[0])


def _is_multiple(a: float, b: float) -> bool:
    k = round(a / b)
    return k >= 1 and abs(k * b - a) <= 1e-9 * a


def _check_steps(steps: Sequence[float], h: float, tau_end: float) -> float:
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
    gains: GainsFile | str | os.PathLike[str],
    fmus_dir: str | os.PathLike[str],
    *,
    tau_end: float = 10.0,
    steps: Sequence[float] = DEFAULT_STEPS,
    schemes: Sequence[tuple[str, str]] = DEFAULT_SCHEMES,
    setup: LoopSetup | None = None,
    fit_max: float = FIT_MAX_H,
    verbose: bool = False,
) -> CrosscheckResult:
    """Co-simulate for every scheme and H, compare with one monolithic run (module doc)."""
    g = load_gains(gains)
    setup = setup or LoopSetup()
    steps = sorted({float(H) for H in steps}, reverse=True)
    dt = _check_steps(steps, setup.h, tau_end)
    for scheme, ex in schemes:
        if scheme not in ("jacobi", "gauss-seidel") or ex not in ("zoh", "linear"):
            raise ValueError(f"unknown scheme/extrapolation {scheme!r}/{ex!r}")
    w0 = time.perf_counter()
    ref = run_reference(g, setup, tau_end, dt)
    ref_wall = time.perf_counter() - w0
    if not ref.status.ok:
        raise RuntimeError(f"the monolithic reference stopped early: {ref.status.message}")
    if verbose:
        print(f"monolithic reference, dt_out = {dt:g}, h = {setup.h:g}: {ref_wall:.2f} s")
        print(_HEADER_LINE, flush=True)
    rows = []
    with closed_loop_master(fmus_dir, g, setup) as master:
        for scheme, ex in schemes:
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
                if verbose:
                    print(_format_row(row), flush=True)
    orders = {}
    for key in schemes:
        sel = [r for r in rows if (r.scheme, r.extrapolation) == key and r.H <= fit_max * 1.000001]
        Hs = [r.H for r in sel]
        orders[key] = {
            "du": fit_order(Hs, [r.err_du for r in sel]),
            "dphi": fit_order(Hs, [r.err_dphi for r in sel]),
        }
    return CrosscheckResult(tuple(rows), orders, tau_end, setup, fit_max, ref_wall, dt)


def write_table(result: CrosscheckResult, path: str | os.PathLike[str]) -> Path:
    """``crosscheck.csv``: one row per (scheme, extrapolation, H)."""
    from drillstring.fileio import write_csv

    rows = [
        (r.scheme, r.extrapolation, r.H, r.steps, r.err_du, r.err_dphi, r.wall_time, r.status)
        for r in result.rows
    ]
    return write_csv(path, TABLE_HEADER, rows)


def _format_row(r: CrosscheckRow) -> str:
    line = (
        f"{r.scheme:>12} {r.extrapolation:>6} {r.H:8.4g} {r.steps:7d} {r.err_du:11.3e} "
        f"{r.err_dphi:11.3e} {r.wall_time:8.2f}"
    )
    return line if r.status == "ok" else f"{line}  {r.status}"


_HEADER_LINE = (
    f"{'scheme':>12} {'extrap':>6} {'H':>8} {'steps':>7} {'err du':>11} {'err dphi':>11} "
    f"{'wall s':>8}"
)


def format_table(result: CrosscheckResult, rows: bool = True) -> str:
    """The table (``rows``) and the fitted orders as text."""
    lines = [_HEADER_LINE, *(_format_row(r) for r in result.rows)] if rows else []
    lines.append(f"fitted orders over H <= {result.fit_max:g}:")
    for (scheme, ex), o in result.orders.items():
        lines.append(f"  {scheme}/{ex}: dphi {o['dphi']:.3f}, du {o['du']:.3f}")
    return "\n".join(lines)


def plot_errors(result: CrosscheckResult, path: str | os.PathLike[str]) -> Path:
    """Log-log PNG of the max errors in dphi/dtau and du/dtau against H, fitted orders."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from drillstring.fileio import save_figure

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
    gains: GainsFile | str | os.PathLike[str],
    fmus_dir: str | os.PathLike[str],
    *,
    tau_end: float = 10.0,
    setup: LoopSetup | None = None,
    control: StepControl | None = None,
    extrapolation: str = "zoh",
    max_doublings: int = 6,
) -> dict[str, Any]:
    """Steps of the adaptive master against the fixed-step master for the same error.

    The adaptive run (``control``, default absolute tolerance 1e-2 on the input-error
    impulse) reaches a max error ``E`` in dphi/dtau against the monolithic loop evaluated at
    its own communication points (:func:`reference_at`) with ``N_a`` attempted steps
    (accepted + rejected). Fixed-step runs then start at ``N_a`` steps and double the count
    until their error is at most ``E``: ``fixed_steps_needed`` is that count (None if
    ``max_doublings`` did not suffice).

    The default tolerance is absolute (``rtol=0``): the exchanged torque is thousands during
    the initial transient, where the coupling error is made, and tens later, so a relative
    tolerance would allow the largest input errors exactly where they matter most (with
    ``rtol=1e-3`` the adaptive run needs more steps than the fixed-step one).
    """
    g = load_gains(gains)
    setup = setup or LoopSetup()
    control = control or StepControl(rtol=0.0, atol=1e-2, h_min=1e-5, h_max=0.1)
    with closed_loop_master(fmus_dir, g, setup) as master:
        ad = run_cosim(master, tau_end, None, step_control=control, extrapolation=extrapolation)
        if not ad.completed:
            raise RuntimeError(f"adaptive co-simulation failed: {ad.failure}")
        ref = reference_at(g, setup, ad.time, ("dphi",))
        e_ad = float(np.max(np.abs(ad["plant.dphi"] - ref["dphi"])))
        n_ad = ad.stats.attempted
        fixed: list[tuple[int, float]] = []
        needed = None
        n = n_ad
        for _ in range(max_doublings + 1):
            res = run_cosim(master, tau_end, tau_end / n, extrapolation=extrapolation)
            if not res.completed:
                e = math.inf
            else:
                ref_f = reference_at(g, setup, res.time, ("dphi",))
                e = float(np.max(np.abs(res["plant.dphi"] - ref_f["dphi"])))
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


def crosscheck_main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``drillstring crosscheck``; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="drillstring crosscheck",
        description="Co-simulation of the Fig. 5 closed loop against the monolithic solver "
        "for a list of macro steps: table, log-log plot and fitted convergence orders.",
    )
    ap.add_argument(
        "--gains",
        type=Path,
        default=None,
        help="gains file (default: the synthesis' default path, controller/gains.json)",
    )
    ap.add_argument(
        "--fmus",
        type=Path,
        default=None,
        help="folder with prebuilt FMUs (default: build into a temporary folder)",
    )
    ap.add_argument("--out", type=Path, default=Path("out/crosscheck"), help="output folder")
    ap.add_argument("--tau-end", type=float, default=10.0, help="end of the run (default 10)")
    ap.add_argument(
        "--steps", type=float, nargs="+", default=list(DEFAULT_STEPS), help="macro steps H"
    )
    ap.add_argument("--h", type=float, default=5e-4, help="engine RK4 step (default 5e-4)")
    ap.add_argument(
        "--fit-max",
        type=float,
        default=FIT_MAX_H,
        help=f"fit the orders over H <= this (default {FIT_MAX_H})",
    )
    ap.add_argument(
        "--adaptive-atol",
        type=float,
        default=1e-2,
        help="also compare the adaptive master (absolute tolerance; 0: skip)",
    )
    args = ap.parse_args(argv)

    from drillstring.controller.gains import DEFAULT_GAINS_PATH, GainsFileError

    gains_path = args.gains if args.gains is not None else DEFAULT_GAINS_PATH
    try:
        setup = LoopSetup(dphi0=-2.5, h=args.h)
        _check_steps(args.steps, setup.h, args.tau_end)
        if args.fmus is not None:
            fmu_paths(args.fmus)
            gains = load_gains(gains_path)
    except (ValueError, GainsFileError, OSError) as exc:
        print(f"drillstring crosscheck: {exc}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="crosscheck_fmus_") as tmp:
        fmus = args.fmus
        try:
            if fmus is None:
                print(f"building the FMUs with {gains_path} into a temporary folder ...")
                fmus = build_fmus_into(tmp, gains_path)
            gains = load_gains(gains_path)
            result = run_crosscheck(
                gains,
                fmus,
                tau_end=args.tau_end,
                steps=args.steps,
                setup=setup,
                fit_max=args.fit_max,
                verbose=True,
            )
            adaptive = None
            if args.adaptive_atol > 0:
                control = StepControl(rtol=0.0, atol=args.adaptive_atol, h_min=1e-5, h_max=0.1)
                adaptive = adaptive_vs_fixed(
                    gains, fmus, tau_end=args.tau_end, setup=setup, control=control
                )
        except (ValueError, RuntimeError, GainsFileError, OSError) as exc:
            print(f"drillstring crosscheck: {exc}", file=sys.stderr)
            return 2
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    csv = write_table(result, out / "crosscheck.csv")
    png = plot_errors(result, out / "crosscheck.png")
    print(format_table(result, rows=False))
    small = [r for r in result.rows if math.isclose(r.H, min(args.steps))]
    for r in small:
        rel = r.err_dphi / abs(setup.dphi0)
        print(
            f"H = {r.H:g}, {r.scheme}/{r.extrapolation}: max |error dphi| = {r.err_dphi:.3e} "
            f"= {rel:.2e} of |dphi(0)|"
        )
    if adaptive is not None:
        fixed = adaptive["fixed"]
        needed = adaptive["fixed_steps_needed"]
        if needed is None:
            verdict = f"more than {fixed[-1][0]}"
        elif len(fixed) > 1:
            verdict = f"more than {fixed[-2][0]} ({needed} suffice)"
        else:
            verdict = f"at most {needed}"
        print(
            f"adaptive master ({adaptive['extrapolation']}, atol {args.adaptive_atol:g}): "
            f"max |error dphi| = {adaptive['adaptive_error']:.3e} with "
            f"{adaptive['adaptive_attempted']} steps ({adaptive['adaptive_rejected']} rejected); "
            f"the fixed-step master needs {verdict} steps for that error "
            f"({', '.join(f'{n} steps: {e:.3e}' for n, e in fixed)})"
        )
    print(f"wrote {csv} and {png}")
    return 0
