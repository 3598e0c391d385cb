"""``drillstring crosscheck``: the co-simulation of the Fig. 5 loop against its monolithic twin.

Runs :func:`~drillstring.orchestration.crosscheck.run_crosscheck` for a list of macro steps
(and, unless ``--adaptive-atol 0``,
:func:`~drillstring.orchestration.crosscheck.adaptive_vs_fixed`), writes ``crosscheck.csv``
and ``crosscheck.png`` into ``--out`` and prints the table and the fitted convergence orders.
The FMUs and the loop's SSP package come from ``--fmus`` (``build_fmus.py``'s output), or are
built from ``--gains`` into a temporary folder; their own gains and parameter set are what both
runs use.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from drillstring.apps.export import build_fmus_into
from drillstring.controller.gains import DEFAULT_GAINS_PATH, GainsFileError, read_gains
from drillstring.orchestration.closed_loop import loop_package
from drillstring.orchestration.crosscheck import (
    CROSSCHECK,
    DEFAULT_CONTROL,
    DEFAULT_STEPS,
    FIT_MAX_H,
    HEADER_LINE,
    CrosscheckRow,
    adaptive_vs_fixed,
    check_steps,
    format_row,
    format_table,
    plot_errors,
    run_crosscheck,
    write_table,
)

__all__ = ["crosscheck_main"]


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="drillstring crosscheck",
        description="Co-simulation of the Fig. 5 closed loop against the monolithic solver "
        "for a list of macro steps: table, log-log plot and fitted convergence orders.",
    )
    ap.add_argument(
        "--gains",
        type=Path,
        default=None,
        help="gains file to build the FMUs with when --fmus is not given (default: "
        "out/design/gains.json)",
    )
    ap.add_argument(
        "--fmus",
        type=Path,
        default=None,
        help="folder with prebuilt FMUs and packages, build_fmus.py's output (default: build "
        "into a temporary folder)",
    )
    ap.add_argument("--out", type=Path, default=Path("out/crosscheck"), help="output folder")
    ap.add_argument(
        "--tau-end",
        type=float,
        default=CROSSCHECK.tau_end,
        help=f"end of the run (default {CROSSCHECK.tau_end:g})",
    )
    ap.add_argument(
        "--steps", type=float, nargs="+", default=list(DEFAULT_STEPS), help="macro steps H"
    )
    ap.add_argument(
        "--h",
        type=float,
        default=CROSSCHECK.h,
        help=f"engine RK4 step (default {CROSSCHECK.h:g})",
    )
    ap.add_argument(
        "--fit-max",
        type=float,
        default=FIT_MAX_H,
        help=f"fit the orders over H <= this (default {FIT_MAX_H})",
    )
    ap.add_argument(
        "--adaptive-atol",
        type=float,
        default=DEFAULT_CONTROL.atol,
        help="also compare the adaptive master (absolute tolerance; 0: skip)",
    )
    return ap


def _adaptive_line(adaptive: dict[str, Any], atol: float) -> str:
    fixed = adaptive["fixed"]
    needed = adaptive["fixed_steps_needed"]
    if needed is None:
        verdict = f"more than {fixed[-1][0]}"
    elif len(fixed) > 1:
        verdict = f"more than {fixed[-2][0]} ({needed} suffice)"
    else:
        verdict = f"at most {needed}"
    return (
        f"adaptive master ({adaptive['extrapolation']}, atol {atol:g}): "
        f"max |error dphi| = {adaptive['adaptive_error']:.3e} with "
        f"{adaptive['adaptive_attempted']} steps ({adaptive['adaptive_rejected']} rejected); "
        f"the fixed-step master needs {verdict} steps for that error "
        f"({', '.join(f'{n} steps: {e:.3e}' for n, e in fixed)})"
    )


def crosscheck_main(argv: Sequence[str] | None = None) -> int:
    """Run ``drillstring crosscheck``; exit code 0 (ok) or 2 (bad input, a message naming it)."""
    args = _parser().parse_args(argv)
    gains_path = args.gains if args.gains is not None else DEFAULT_GAINS_PATH
    try:
        experiment = replace(CROSSCHECK, tau_end=args.tau_end, h=args.h)
        check_steps(args.steps, experiment.h, experiment.tau_end)
        control = None
        if args.adaptive_atol > 0:
            control = replace(DEFAULT_CONTROL, atol=args.adaptive_atol)
        if args.fmus is not None:
            loop_package(args.fmus)
        else:
            read_gains(gains_path)
    except (ValueError, GainsFileError, OSError) as exc:
        print(f"drillstring crosscheck: {exc}", file=sys.stderr)
        return 2

    def show(row: CrosscheckRow) -> None:
        print(format_row(row), flush=True)

    with tempfile.TemporaryDirectory(prefix="crosscheck_fmus_") as tmp:
        fmus = args.fmus
        try:
            if fmus is None:
                print(f"building the FMUs with {gains_path} into a temporary folder ...")
                fmus = build_fmus_into(tmp, gains_path)
            print(HEADER_LINE, flush=True)
            result = run_crosscheck(
                fmus, experiment, steps=args.steps, fit_max=args.fit_max, on_row=show
            )
            adaptive = None
            if control is not None:
                adaptive = adaptive_vs_fixed(fmus, experiment, control=control)
        except (ValueError, RuntimeError, OSError) as exc:
            print(f"drillstring crosscheck: {exc}", file=sys.stderr)
            return 2
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    csv = write_table(result, out / "crosscheck.csv")
    png = plot_errors(result, out / "crosscheck.png")
    print(
        f"monolithic reference, dt_out = {result.reference_dt:g}, h = {experiment.h:g}: "
        f"{result.reference_wall_time:.2f} s"
    )
    print(format_table(result, rows=False))
    for r in (r for r in result.rows if math.isclose(r.H, min(args.steps))):
        rel = r.err_dphi / abs(experiment.dphi0)
        print(
            f"H = {r.H:g}, {r.scheme}/{r.extrapolation}: max |error dphi| = {r.err_dphi:.3e} "
            f"= {rel:.2e} of |dphi(0)|"
        )
    if adaptive is not None:
        print(_adaptive_line(adaptive, args.adaptive_atol))
    print(f"wrote {csv} and {png}")
    return 0
