"""``drillstring simulate``: one monolithic run of the full model, written as CSV, JSON and PNG.

Examples::

    drillstring simulate --tau-end 60 --dphi0 -2.5 --out out/simulate            # open loop
    drillstring simulate --experiment fig5 --gains out/design/gains.json         # Fig. 5
    drillstring simulate --experiment fig6 --gains out/design/gains.json         # Fig. 6
    drillstring simulate --tau-end 30 --dphi0 -4.9 --torsional-stick --elements 16  # string
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from drillstring.controller.gains import GainsFileError, read_gains
from drillstring.fileio import write_json
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import Control, EngineOptions
from drillstring.model.experiments import DEFAULT_DT_OUT, DEFAULT_H, EXPERIMENTS, FIG5
from drillstring.model.params import ParameterError, params_from_spec, rig_from_spec
from drillstring.model.pipe import string_of_rig
from drillstring.model.simulate import simulate
from drillstring.plotting import plot_velocities
from drillstring.validation import check_out_folder, check_real

__all__ = ["simulate_main"]


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of the ``simulate`` subcommand.

    Returns
    -------
    argparse.ArgumentParser
        The parser (``prog="drillstring simulate"``); its options are listed by ``--help``.
    """
    ap = argparse.ArgumentParser(
        prog="drillstring simulate", description="One run of the full model (11)-(14), (17)."
    )
    ap.add_argument("--params", default="reference", help="parameter set name or file")
    ap.add_argument(
        "--experiment",
        choices=sorted(EXPERIMENTS),
        default=None,
        help="the paper's closed-loop experiment (needs --gains); sets dphi0, tau-end, t-on, "
        "the latch and the torsional-stick model",
    )
    ap.add_argument("--tau-end", type=float, default=None, help=f"default {FIG5.tau_end:g}")
    ap.add_argument("--dphi0", type=float, default=None, help=f"default {FIG5.dphi0:g}")
    ap.add_argument("--du0", type=float, default=0.0, help="initial du/dtau perturbation")
    ap.add_argument(
        "--control",
        choices=("none", "feedforward", "gains"),
        default=None,
        help="R - R0 = 0, R_ff only, or R_ff + F x from --gains (default: gains with "
        "--experiment, else none)",
    )
    ap.add_argument("--gains", type=Path, default=None, help="gains file of the design")
    ap.add_argument(
        "--h",
        type=float,
        default=DEFAULT_H,
        help=f"integration step (default {DEFAULT_H:g}; at most a tenth of the model's shortest "
        "time scale: the axial period, the nominal delay, the torsional period)",
    )
    ap.add_argument("--dt-out", type=float, default=DEFAULT_DT_OUT, help="output sampling step")
    ap.add_argument("--torsional-stick", action="store_true", help="model torsional stick")
    ap.add_argument(
        "--elements",
        type=int,
        default=1,
        help="elements of the distributed string (default 1: the paper's one-mode model; "
        "docs/model.md, 'The distributed string')",
    )
    ap.add_argument("--out", type=Path, default=Path("out/simulate"))
    return ap


def simulate_main(argv: Sequence[str] | None = None) -> int:
    """Run the ``simulate`` subcommand; exit code 0 (ok), 1 (the run stopped), 2 (bad input).

    Writes ``simulation.csv``, ``simulation.json`` (status, counters, flags, parameters, the
    string), ``simulation.png`` and the string along its length (``string_nodes.csv``,
    ``string_elements.csv``: :meth:`SimulationResult.profiles_to_csv`) into ``--out``; a run
    that stops early is written up to the stop.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after the subcommand (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit code.
    """
    args = build_parser().parse_args(argv)
    exp = EXPERIMENTS[args.experiment] if args.experiment else None
    mode = args.control or ("gains" if exp is not None else "none")
    try:
        check_out_folder("--out", args.out)
        params = params_from_spec(args.params)
        # a step beyond the model's time scales is no step of this model (and the engine would
        # silently take --dt-out instead)
        check_real("--h", args.h, lower=0.0, upper=params.h_max)
        control: Control = None
        if mode != "none":
            if args.gains is None:
                raise ValueError(f"--control {mode} needs --gains FILE (drillstring design)")
            g = read_gains(args.gains)
            if mode == "feedforward" or (exp is not None and not exp.enabled):
                control = g.R_ff
            else:
                t_on, latch = (exp.t_on, exp.latch) if exp is not None else (0.0, "none")
                control = AffineFeedback(g.F, g.K0, g.R_ff, t_on=t_on, latch=latch)
        # the pipe of the rig --params names, by the one rule for a rig's pipe
        string = string_of_rig(rig_from_spec(args.params), args.elements)
        stick = args.torsional_stick or (exp is not None and exp.torsional_stick)
        dphi0 = args.dphi0 if args.dphi0 is not None else (exp or FIG5).dphi0
        tau_end = args.tau_end if args.tau_end is not None else (exp or FIG5).tau_end
        r = simulate(
            params,
            tau_end,
            control=control,
            initial={"dphi": dphi0, "du": args.du0},
            dt_out=args.dt_out,
            options=EngineOptions(h=args.h, torsional_stick=stick),
            string=string,
        )
    except (ParameterError, GainsFileError, ValueError, OSError) as exc:
        print(f"drillstring simulate: {exc}", file=sys.stderr)
        return 2
    out = args.out
    r.to_csv(out / "simulation.csv")
    r.profiles_to_csv(out / "string_nodes.csv", out / "string_elements.csv")
    write_json(
        out / "simulation.json",
        {
            "status": r.status.code,
            "message": r.status.message,
            "counters": r.counters,
            "flags": r.flags,
            "params": params.to_dict(),
            "string": {
                "elements": r.string.elements,
                "kappa": r.string.kappa,
                "axial_mass_ratio": r.string.axial_mass_ratio,
                "lumping": r.string.lumping,
            },
        },
    )
    t_on = exp.t_on if exp is not None and exp.t_on > 0 else None
    title = f"drillstring simulate{f' ({exp.name})' if exp else ''}"
    plot_velocities(out / "simulation.png", [("monolithic", r)], title=title, t_on=t_on)
    print(f"{r.status.code}: tau = {r.tau[-1]:.4g}, {r.counters}; wrote {out}")
    return 0 if r.status.ok else 1
