"""``drillstring axial``: the axial analysis of Section III (Figs. 2-4) as CSV and PNG."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from drillstring.analysis.figures import (
    read_average_points,
    write_average_figure,
    write_limit_cycle_figure,
    write_stability_diagram,
)
from drillstring.analysis.limit_cycles import FIG4_ETABAR2, FIT_POINTS

__all__ = ["axial_main"]


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of the ``axial`` subcommand.

    Returns
    -------
    argparse.ArgumentParser
        ``what`` (stability, limit-cycle, average, all) and the options ``--out``,
        ``--points``, ``--fit``, ``--gammabar``, ``--etabar2``, ``--taubar``.
    """
    ap = argparse.ArgumentParser(
        prog="drillstring axial", description="Axial analysis of Section III (Figs. 2-4)."
    )
    ap.add_argument("what", choices=("stability", "limit-cycle", "average", "all"))
    ap.add_argument("--out", type=Path, default=Path("out/axial"))
    ap.add_argument("--points", type=int, default=FIT_POINTS, help="Fig. 4: limit cycles per line")
    ap.add_argument(
        "--fit",
        type=Path,
        default=None,
        help="Fig. 4: points already computed (the design's axial_fit.csv), reused",
    )
    ap.add_argument("--gammabar", type=float, default=0.2, help="limit-cycle gammabar")
    ap.add_argument("--etabar2", type=float, default=FIG4_ETABAR2, help="limit-cycle etabar^2")
    ap.add_argument("--taubar", type=float, default=10.0, help="limit-cycle delay taubar_n")
    return ap


def axial_main(argv: Sequence[str] | None = None) -> int:
    """Run the ``axial`` subcommand; exit code 0 (ok) or 2 (bad input or no limit cycle).

    Writes Fig. 2, Fig. 3 and/or Fig. 4 (PNG and CSV) into ``--out`` and prints the paths.
    """
    args = build_parser().parse_args(argv)
    try:
        written = {}
        if args.what in ("stability", "all"):
            written["fig2"] = write_stability_diagram(args.out)
        if args.what in ("limit-cycle", "all"):
            written["fig3"] = write_limit_cycle_figure(
                args.out, args.gammabar, args.etabar2, args.taubar
            )
        if args.what in ("average", "all"):
            known = read_average_points(args.fit) if args.fit else ()
            written["fig4"] = write_average_figure(args.out, n_points=args.points, known=known)
    except (ValueError, RuntimeError) as exc:
        print(f"drillstring axial: {exc}", file=sys.stderr)
        return 2
    for name, paths in written.items():
        print(f"{name}: " + ", ".join(str(p) for p in paths.values()))
    return 0
