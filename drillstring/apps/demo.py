"""``drillstring demo``: the main job.

1. Section III: Fig. 2 (stability diagram of (21)), Fig. 3 (axial limit cycle), Fig. 4
   (averaged contact force, slope A).
2. The gains file (LMI synthesis (33) with A from step 1) is read from ``--gains``.
3. Figs. 5 and 6 by co-simulation of the plant and controller FMUs (``--fmus``) on the fmpy
   master, each with the monolithic solver of the same closed loop overlaid, and the measured
   agreement printed.

``make demo`` runs the design and ``build_fmus.py`` first, then this command; all results go
into ``--out`` (CSV/JSON data, PNG figures) and ``summary.json`` lists them with the key numbers.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from drillstring.fileio import write_json


def _step(title: str) -> float:
    print(f"\n== {title}", flush=True)
    return time.perf_counter()


def demo_main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="drillstring demo", description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out"))
    ap.add_argument("--gains", type=Path, default=Path("out/gains.json"), help="gains file")
    ap.add_argument("--fmus", type=Path, default=Path("build"), help="folder with the two FMUs")
    ap.add_argument("--H", type=float, default=1e-3, help="macro step of the co-simulation")
    ap.add_argument("--quick", action="store_true", help="fewer Fig. 4 points")
    args = ap.parse_args(argv)

    from drillstring.analysis.axial_stability import write_stability_diagram
    from drillstring.analysis.figures import write_average_figure, write_limit_cycle_figure
    from drillstring.controller.gains import GainsFileError, read_gains

    try:
        gains = read_gains(args.gains)
    except (GainsFileError, OSError) as exc:
        print(
            f"drillstring demo: {exc} (run `drillstring design --out {args.gains}`)",
            file=sys.stderr,
        )
        return 2
    fmus = sorted(args.fmus.glob("*.fmu")) if args.fmus.is_dir() else []
    if len(fmus) < 2:
        print(
            f"drillstring demo: no FMUs in {args.fmus} (run `python build_fmus.py --gains "
            f"{args.gains} --out {args.fmus}`)",
            file=sys.stderr,
        )
        return 2
    out: Path = args.out
    summary: dict[str, Any] = {"gains": str(args.gains), "fmus": [str(f) for f in fmus]}

    t0 = _step("Section III: axial stability (Fig. 2), limit cycle (Fig. 3), averaging (Fig. 4)")
    ax = out / "axial"
    summary["fig2"] = {k: str(v) for k, v in write_stability_diagram(ax).items()}
    summary["fig3"] = {k: str(v) for k, v in write_limit_cycle_figure(ax).items()}
    summary["fig4"] = {
        k: str(v) for k, v in write_average_figure(ax, n_points=8 if args.quick else 25).items()
    }
    print(f"   written to {ax} ({time.perf_counter() - t0:.1f} s)")
    print(
        f"   gains: A = {gains.A:.5f}, taubar_crit = {gains.taubar_crit:.5f}, "
        f"F = [{', '.join(f'{v:.2f}' for v in gains.F)}], K0 = {gains.K0:.5f}"
    )
    summary["design"] = {"A": gains.A, "taubar_crit": gains.taubar_crit, "F": list(gains.F)}

    from drillstring.orchestration.figures import write_fig5, write_fig6

    t0 = _step(f"Fig. 5 by co-simulation (fmpy master, H = {args.H:g}) vs monolithic solver")
    fig5 = write_fig5(out / "fig5", args.fmus, H=args.H)
    _report(fig5)
    summary["fig5"] = _jsonable(fig5)
    print(f"   ({time.perf_counter() - t0:.1f} s)")

    t0 = _step("Fig. 6: torsional stick-slip, controller switched on at tau = 25")
    fig6 = write_fig6(out / "fig6", args.fmus, H=args.H)
    _report(fig6)
    summary["fig6"] = _jsonable(fig6)
    print(f"   ({time.perf_counter() - t0:.1f} s)")

    path = write_json(out / "summary.json", summary)
    print(f"\nSummary: {path}")
    return 0


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    if hasattr(obj, "item"):
        return obj.item()
    return obj


def _report(result: Any) -> None:
    if isinstance(result, dict):
        for k, v in result.items():
            if isinstance(v, dict):
                continue
            print(f"   {k}: {v}")
