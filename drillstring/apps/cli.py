"""The ``drillstring`` command: simulate, axial analysis, controller design, co-simulation
cross-check, parameter sweeps and the demo pipeline.

Every subcommand writes CSV/JSON/PNG files into an output folder and exits with 0 on success,
2 on bad input (with a message naming the bad value).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from drillstring.model.params import ParameterError, params_from_spec


def _simulate_main(argv: Sequence[str]) -> int:
    from drillstring.fileio import write_json
    from drillstring.model.control import AffineFeedback
    from drillstring.model.engine import EngineOptions
    from drillstring.model.simulate import simulate
    from drillstring.plotting import plot_velocities

    ap = argparse.ArgumentParser(prog="drillstring simulate", description=simulate.__doc__)
    ap.add_argument("--params", default="reference", help="parameter set name or file")
    ap.add_argument("--tau-end", type=float, default=60.0)
    ap.add_argument("--dphi0", type=float, default=-2.5, help="initial dphi/dtau perturbation")
    ap.add_argument("--du0", type=float, default=0.0, help="initial du/dtau perturbation")
    ap.add_argument(
        "--control",
        choices=("none", "feedforward", "gains"),
        default="none",
        help="R - R0 = 0, R_ff only, or R_ff + F x from --gains",
    )
    ap.add_argument("--gains", type=Path, default=None, help="gains file (controller design)")
    ap.add_argument("--t-on", type=float, default=0.0, help="controller switch-on time")
    ap.add_argument("--h", type=float, default=5e-4, help="integration step")
    ap.add_argument("--dt-out", type=float, default=1e-2, help="output sampling step")
    ap.add_argument("--torsional-stick", action="store_true", help="model torsional stick")
    ap.add_argument("--out", type=Path, default=Path("out/simulate"))
    args = ap.parse_args(argv)
    try:
        params = params_from_spec(args.params)
        control = None
        if args.control != "none":
            from drillstring.controller.gains import DEFAULT_GAINS_PATH, read_gains

            g = read_gains(args.gains or DEFAULT_GAINS_PATH)
            if args.control == "feedforward":
                control = g.R_ff
            else:
                latch = "angle" if args.t_on > 0 else "none"
                control = AffineFeedback(g.F, g.K0, g.R_ff, t_on=args.t_on, latch=latch)
        opts = EngineOptions(h=args.h, torsional_stick=args.torsional_stick)
        r = simulate(
            params,
            args.tau_end,
            control=control,
            initial={"dphi": args.dphi0, "du": args.du0},
            dt_out=args.dt_out,
            options=opts,
        )
    except (ParameterError, ValueError, OSError) as exc:
        print(f"drillstring simulate: {exc}", file=sys.stderr)
        return 2
    out = args.out
    r.to_csv(out / "simulation.csv")
    write_json(
        out / "simulation.json",
        {
            "status": r.status.code,
            "message": r.status.message,
            "counters": r.counters,
            "flags": r.flags,
            "params": params.to_dict(),
        },
    )
    plot_velocities(out / "simulation.png", [("monolithic", r)], title="drillstring simulate")
    print(f"{r.status.code}: tau = {r.tau[-1]:.4g}, {r.counters}; wrote {out}")
    return 0 if r.status.ok else 1


def _axial_main(argv: Sequence[str]) -> int:
    ap = argparse.ArgumentParser(
        prog="drillstring axial", description="Axial analysis of Section III (Figs. 2-4)."
    )
    ap.add_argument("what", choices=("stability", "limit-cycle", "average", "all"))
    ap.add_argument("--out", type=Path, default=Path("out/axial"))
    ap.add_argument("--quick", action="store_true", help="fewer sweep points (Fig. 4: 8 a line)")
    ap.add_argument("--gammabar", type=float, default=0.2, help="limit-cycle gammabar")
    ap.add_argument("--etabar2", type=float, default=0.1, help="limit-cycle etabar^2")
    ap.add_argument("--taubar", type=float, default=10.0, help="limit-cycle delay taubar_n")
    args = ap.parse_args(argv)
    from drillstring.analysis.axial_stability import write_stability_diagram
    from drillstring.analysis.figures import write_average_figure, write_limit_cycle_figure

    try:
        written = {}
        if args.what in ("stability", "all"):
            written["fig2"] = write_stability_diagram(args.out)
        if args.what in ("limit-cycle", "all"):
            written["fig3"] = write_limit_cycle_figure(
                args.out, args.gammabar, args.etabar2, args.taubar
            )
        if args.what in ("average", "all"):
            written["fig4"] = write_average_figure(args.out, n_points=8 if args.quick else 25)
    except (ValueError, RuntimeError) as exc:
        print(f"drillstring axial: {exc}", file=sys.stderr)
        return 2
    for name, paths in written.items():
        print(f"{name}: " + ", ".join(str(p) for p in paths.values()))
    if "fig4" in written:
        import csv

        with open(written["fig4"]["fits"]) as fh:
            for row in csv.DictReader(fh):
                a, zero, crit = (float(row[k]) for k in ("A", "taubar_zero", "taubar_crit"))
                print(
                    f"  gammabar = {row['gammabar']}: A = {a:.5f}, zero at {zero:.4f}, "
                    f"taubar_crit = {crit:.4f}"
                )
    return 0


def _lazy(module: str, func: str):
    def run(argv: Sequence[str]) -> int:
        import importlib

        return int(getattr(importlib.import_module(module), func)(list(argv)))

    return run


COMMANDS = {
    "simulate": _simulate_main,
    "axial": _axial_main,
    "design": _lazy("drillstring.apps.design", "design_main"),
    "crosscheck": _lazy("drillstring.apps.crosscheck", "crosscheck_main"),
    "sweep": _lazy("drillstring.apps.sweep.runner", "sweep_main"),
    "demo": _lazy("drillstring.apps.demo", "demo_main"),
}


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``drillstring`` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help") or argv[0] not in COMMANDS:
        print("usage: drillstring {" + ",".join(COMMANDS) + "} [options]   (-h for help)")
        if argv and argv[0] not in ("-h", "--help"):
            print(f"drillstring: unknown command {argv[0]!r}", file=sys.stderr)
            return 2
        return 0
    np.seterr(all="ignore")
    return COMMANDS[argv[0]](argv[1:])


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
