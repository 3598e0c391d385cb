"""``drillstring demo``: the main job, a chain of artifacts each computed once.

``make demo`` runs, in this order (each step reads only what the one before wrote):

1. ``drillstring design --out out/design --torque-limit tds-11sa``: the slope A of (22) from the
   axial limit cycles (the Fig. 4 line at the reference set's gammabar, etabar^2:
   ``axial_fit.csv``), the LMI design (33) and its certificate (``gains.json``), the
   input-constrained design for the reference rig's top drive (``gains_constrained.json``);
2. ``python build_fmus.py --gains out/design/gains.json --out build``: the plant, LMI and
   top-drive controller FMUs (scaled and SI) and the SSP packages, the gains baked into the LMI
   controller FMUs;
3. ``drillstring demo --design out/design --fmus build --out out`` (:func:`run_demo`):
   Section III (Fig. 2, Fig. 3, Fig. 4 with the design's own line reused), then Figs. 5 and 6
   by co-simulation of the FMUs on the fmpy master with the monolithic solver of the same loop
   overlaid, and their measured agreement; Fig. 6 on the one-mode model and on the distributed
   string with the string's modes (``out/string/``); then Fig. 5 in SI units from the SSP
   package in Ecos
   and in the project's master, against the monolithic solver in SI; then the controllers on the
   reference rig's top drive, with and without braking: every one switched on from the Fig. 6
   state on the converged string (``out/controllers/string/``) beside the one-mode model
   (``out/controllers/one-mode/``), the outcomes that change printed, and a small map of their
   outcomes over surface speed and weight on bit on the string (Dask). ``summary.json`` lists
   every file and number.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from drillstring.analysis.figures import (
    read_average_points,
    write_average_figure,
    write_limit_cycle_figure,
    write_stability_diagram,
)
from drillstring.analysis.string_figures import write_string_fig6
from drillstring.apps.controllers import (
    STRING_ELEMENTS,
    format_comparison,
    write_controller_comparison,
    write_controller_map,
)
from drillstring.apps.cosim import run_si_demo, si_demo_lines
from drillstring.apps.modes import modes_main
from drillstring.controller.design import CONSTRAINED_FILE, FIT_FILE, GAINS_FILE
from drillstring.controller.gains import GainsFile, GainsFileError, read_gains
from drillstring.fileio import json_types, replace_dir, write_json
from drillstring.model.control import AffineFeedback
from drillstring.model.params import known_rig
from drillstring.model.pipe import string_of_rig
from drillstring.orchestration.closed_loop import read_loop_model
from drillstring.orchestration.figures import write_fig5, write_fig6

__all__ = ["DemoSummary", "demo_main", "run_demo"]

#: The demo's summary in its output folder.
SUMMARY_FILE = "summary.json"


#: Points per axis of the demo's controller map: on the 16-element string a point costs about
#: 2.5 s (9 points of the default map, serial, warm: 22.6 s), so 7 x 7 keeps the demo's map
#: near a minute on two workers (``drillstring controllers map`` defaults to 25 x 25).
DEMO_MAP_POINTS = 7


@dataclass
class DemoSummary:
    """What the demo wrote and measured.

    ``figures`` maps each figure to its files; ``files`` lists every file the run wrote
    (relative to the output folder, ``summary.json`` included); ``design`` holds A, taubar_crit
    and F of the gains the FMUs were built with; ``fig5``/``fig6`` the co-simulation's agreement
    with the monolithic solver and the checks of the paper's claims; ``seconds`` the wall time of
    each step.
    """

    design: dict[str, Any]
    figures: dict[str, dict[str, str]] = field(default_factory=dict)
    fig5: dict[str, Any] = field(default_factory=dict)
    fig6: dict[str, Any] = field(default_factory=dict)
    si: dict[str, Any] = field(default_factory=dict)
    string: dict[str, Any] = field(default_factory=dict)
    controllers: list[dict[str, Any]] = field(default_factory=list)
    controllers_one_mode: list[dict[str, Any]] = field(default_factory=list)
    controller_changes: list[str] = field(default_factory=list)
    controller_elements: int = STRING_ELEMENTS
    controller_map: list[dict[str, Any]] = field(default_factory=list)
    map_points: int = 0
    seconds: dict[str, float] = field(default_factory=dict)
    files: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        """The summary as plain JSON types.

        Returns
        -------
        dict
            The fields (:func:`dataclasses.asdict`) with paths as strings, numpy scalars as
            Python numbers, tuples as lists and keys as strings, ready for :func:`json.dumps`.
        """
        return json_types(asdict(self))


def run_demo(
    design_dir: str | Path,
    fmus_dir: str | Path,
    out_dir: str | Path,
    *,
    H: float = 1e-3,
    workers: int | None = 2,
    map_points: int = DEMO_MAP_POINTS,
    progress: bool = False,
    log: Any = print,
) -> DemoSummary:
    """Run the demo (module docstring) and write ``summary.json`` into ``out_dir``: every number
    and every file the run wrote (valid JSON: a number without a value is null).

    Parameters
    ----------
    design_dir : path
        Folder written by ``drillstring design`` (``gains.json``, ``axial_fit.csv``).
    fmus_dir : path
        Folder with the FMUs built from that gains file.
    out_dir : path
        Where the figures, data and ``summary.json`` go.
    H : float
        Macro step of the co-simulations.
    workers : int, optional
        Dask workers of the controller map (0: serially in this process).
    map_points : int
        Points per axis of the controller map (surface speed x weight on bit).
    progress : bool
        Show the map's progress bar.
    log : callable
        Receives one line of progress text per step.

    Returns
    -------
    DemoSummary
        The files written and the numbers measured.

    Raises
    ------
    drillstring.controller.gains.GainsFileError, ValueError
        When the design folder or the FMUs are missing or do not match.
    """
    design_dir, out = Path(design_dir), Path(out_dir)
    before = _file_states(out)  # what is there already is not this run's (out/design, ...)
    gains = read_gains(design_dir / GAINS_FILE)
    fit = read_average_points(design_dir / FIT_FILE)
    _check_fmus_carry(gains, fmus_dir, design_dir)
    summary = DemoSummary(design=_design_numbers(gains))

    t0 = time.perf_counter()
    log("Section III: axial stability (Fig. 2), limit cycle (Fig. 3), averaging (Fig. 4)")
    axial = out / "axial"
    summary.figures["fig2"] = _paths(write_stability_diagram(axial))
    summary.figures["fig3"] = _paths(write_limit_cycle_figure(axial))
    summary.figures["fig4"] = _paths(write_average_figure(axial, known=fit))
    summary.seconds["section_3"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    log(f"Fig. 5 by co-simulation (fmpy master, H = {H:g}) vs monolithic solver")
    summary.fig5 = dict(write_fig5(out / "fig5", fmus_dir, H=H))
    summary.figures["fig5"] = {k: str(summary.fig5.pop(k)) for k in ("png", "csv")}
    summary.seconds["fig5"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    log("Fig. 6: torsional stick-slip, controller switched on at tau = 25")
    summary.fig6 = dict(write_fig6(out / "fig6", fmus_dir, H=H))
    summary.figures["fig6"] = {k: str(summary.fig6.pop(k)) for k in ("png", "csv")}
    summary.seconds["fig6"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    log("Fig. 6 on the one-mode model and on the distributed string; the string's modes")
    law = AffineFeedback(gains.F, gains.K0, gains.R_ff)
    summary.string = dict(write_string_fig6(out / "string", law))
    summary.figures["fig6_string"] = {k: str(summary.string.pop(k)) for k in ("png", "csv")}
    n = summary.string["elements"]
    modes_dir = out / "string" / "modes"
    if modes_main(["--elements", str(n), "--table", "held", "--out", str(modes_dir)]) != 0:
        raise ValueError(f"drillstring modes failed for {n} elements")
    summary.figures["string_modes"] = {
        "json": str(modes_dir / "modes.json"),
        "png": str(modes_dir / "modes.png"),
    }
    summary.seconds["string"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    log("Fig. 5 in SI units from the SSP package, in Ecos and in the project's master")
    summary.si = run_si_demo(fmus_dir, out / "si")
    summary.seconds["si"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    log(
        "Controllers on the reference rig's top drive, with and without braking: Fig. 6-like "
        f"comparison on the {STRING_ELEMENTS}-element string and on the one-mode model, map"
    )
    constrained = design_dir / CONSTRAINED_FILE
    cfile = constrained if constrained.is_file() else None
    rig = known_rig(gains.params)
    string = None if rig is None else string_of_rig(rig, STRING_ELEMENTS)
    comparison = write_controller_comparison(
        out / "controllers" / "string", gains, cfile, string=string, without_braking=True,
        log=None,
    )  # fmt: skip
    one_mode = write_controller_comparison(
        out / "controllers" / "one-mode", gains, cfile, without_braking=True, log=None
    )
    summary.controllers = list(comparison.rows)
    summary.controllers_one_mode = list(one_mode.rows)
    summary.controller_changes = comparison_changes(one_mode.rows, comparison.rows)
    summary.figures["controllers"] = {k: str(v) for k, v in comparison.files.items()}
    summary.figures["controllers_one_mode"] = {k: str(v) for k, v in one_mode.files.items()}
    # The map is the demo's own artifact: computed afresh into a staging folder that replaces the
    # previous map when complete (the sweep itself refuses to overwrite results without --resume).
    map_dir = out / "controllers" / "map"
    staging = map_dir.with_name(f".{map_dir.name}.new")
    if staging.exists():
        shutil.rmtree(staging)
    cmap = write_controller_map(
        staging, design_dir / GAINS_FILE, n=map_points, workers=workers, progress=progress,
        elements=STRING_ELEMENTS, log=None,
    )  # fmt: skip
    summary.map_points = map_points
    replace_dir(staging, map_dir)
    summary.controller_map = list(cmap.by_controller)
    summary.figures["controller_map"] = {
        k: str(map_dir / Path(v).relative_to(staging)) for k, v in cmap.files.items()
    }
    summary.seconds["controllers"] = time.perf_counter() - t0

    written = {p for p, state in _file_states(out).items() if before.get(p) != state}
    summary.files = sorted(written | {SUMMARY_FILE})
    write_json(out / SUMMARY_FILE, summary.to_json())
    return summary


def comparison_changes(
    one_mode: Sequence[Mapping[str, Any]], string: Sequence[Mapping[str, Any]]
) -> list[str]:
    """What the distributed string changes in the comparison: one line per row (controller and
    braking) whose outcome differs between the one-mode model and the string.

    Parameters
    ----------
    one_mode, string : sequence of mapping
        Rows of the two comparisons (:data:`~drillstring.apps.controllers.COMPARISON_COLUMNS`).

    Returns
    -------
    list of str
        ``"<controller> (braking <b>): <one-mode outcome> -> <string outcome>"``; empty when
        every outcome is the same.
    """

    def key(r: Mapping[str, Any]) -> tuple[Any, Any]:
        return r.get("controller"), r.get("braking")

    before = {key(r): r for r in one_mode}
    out = []
    for r in string:
        b = before.get(key(r))
        if b is None or b.get("outcome") == r.get("outcome"):
            continue
        brake = {"four-quadrant": "with braking", "none": "without braking"}.get(
            r.get("braking"), "no drive"
        )
        out.append(f"{r.get('controller')} ({brake}): {b.get('outcome')} -> {r.get('outcome')}")
    return out


def _file_states(root: Path) -> dict[str, tuple[int, int, int]]:
    """Every file under ``root`` (relative POSIX path) -> (inode, mtime in ns, size): a file
    written (the project's writers replace files whole: a new inode) or changed since differs.
    Every writer's files are found, also those it does not return (``si_fig5.json``, the map's
    ``results.csv``, ``spec.json`` and ``plots/``)."""
    if not root.is_dir():
        return {}
    states = {}
    for path in root.rglob("*"):
        if path.is_file():
            st = path.stat()
            states[path.relative_to(root).as_posix()] = (st.st_ino, st.st_mtime_ns, st.st_size)
    return states


def _check_fmus_carry(gains: GainsFile, fmus_dir: str | Path, design_dir: Path) -> None:
    """The FMUs' own gains and parameter set must be the design's (one path for the data)."""
    built = read_loop_model(fmus_dir, None)
    law = built.control
    ok = (
        isinstance(law, AffineFeedback)
        and law.F == gains.F
        and law.K0 == gains.K0
        and law.R_ff == gains.R_ff
        and built.params == gains.params
    )
    if not ok:
        raise ValueError(
            f"the FMUs in {fmus_dir} were not built from {design_dir / GAINS_FILE} (their gains "
            f"or parameter set differ): rebuild them"
        )


def _design_numbers(gains: GainsFile) -> dict[str, Any]:
    return {
        "A": gains.A,
        "taubar_crit": gains.taubar_crit,
        "F": list(gains.F),
        "K0": gains.K0,
        "alpha": gains.alpha,
        "spectral_abscissa": gains.spectral_abscissa,
    }


def _paths(paths: Mapping[str, Path]) -> dict[str, str]:
    return {k: str(v) for k, v in paths.items()}


def print_summary(summary: DemoSummary) -> None:
    """Print the design, the agreement of co-simulation and monolithic solver, the checks.

    Parameters
    ----------
    summary : DemoSummary
        A result of :func:`run_demo`.
    """
    d = summary.design
    print(
        f"   design: A = {d['A']:.5f}, taubar_crit = {d['taubar_crit']:.5f}, "
        f"F = [{', '.join(f'{v:.2f}' for v in d['F'])}], K0 = {d['K0']:.5f}"
    )
    for name in ("fig5", "fig6"):
        r = getattr(summary, name)
        print(
            f"   {name}: co-simulation vs monolithic, max |diff| du/dtau "
            f"{r['max_abs_diff_du']:.3g}, dphi/dtau {r['max_abs_diff_dphi']:.3g} "
            f"({r['max_abs_diff_dphi_rel']:.3g} of "
            f"|dphi/dtau(0)|); late max |dphi/dtau| {r['late_max_abs_dphi_cosim']:.4g}"
        )
    s = summary.string
    if s:
        for name, label in (
            ("one_mode", "one-mode model"),
            ("string", f"string, N = {s['elements']}"),
        ):
            r = s[name]
            print(
                f"   fig6 on the {label}: {r['status']}, lowest bit speed after the switch-on "
                f"{r['min_bit_speed_after_t_on_rpm']:.1f} rpm, peak top torque "
                f"{r['max_top_torque_after_t_on_kNm']:.1f} kN m"
            )
    r = summary.fig6
    print(
        f"   fig6: torsional stick entries before/after t_on "
        f"{r['torsional_stick_before_t_on_cosim']}/{r['torsional_stick_after_t_on_cosim']}, "
        f"suppressed: {r['suppressed']}"
    )
    for name in ("fig5", "fig6"):
        a = getattr(summary, name)["actuator"]
        line = f"   {name} assumes the paper's ideal actuator and exact downhole sensing: "
        line += f"peak R {a['peak_torque_over_R0']:.0f} R0"
        if "peak_torque_Nm" in a:
            lo, hi = a["table_speed_rpm"]
            line += (
                f" ({a['peak_torque_Nm'] / 1e3:.0f} kN m), {a['peak_power_W'] / 1e6:.3g} MW, "
                f"table {lo:.0f} to {hi:.0f} rpm: "
                f"{'within' if a['within_tds_11sa'] else 'beyond'} a TDS-11SA"
            )
        print(line)
    for line in si_demo_lines(summary.si):
        print(f"   {line}")
    n_el = summary.controller_elements
    print(
        "   controllers switched on at tau = 25 from the Fig. 6 state, on the rig's top drive "
        f"with and without braking, on the {n_el}-element string:"
    )
    for line in format_comparison(summary.controllers).splitlines():
        print(f"     {line}")
    print("   the same on the one-mode model (the paper's):")
    for line in format_comparison(summary.controllers_one_mode).splitlines():
        print(f"     {line}")
    print("   what the string changes (outcome on the one-mode model -> on the string):")
    for line in summary.controller_changes or ["no outcome changes"]:
        print(f"     {line}")
    n = summary.map_points
    print(
        f"   {n} x {n} map over surface speed [rpm] x weight on bit [kN] on the {n_el}-element "
        "string, every controller under the TDS-11SA, outcomes per controller:"
    )
    for row in summary.controller_map:
        counts = ", ".join(f"{k} {v}" for k, v in row.items() if k != "controller")
        print(f"     {row['controller']:<11} {counts}")
    for name, paths in summary.figures.items():
        print(f"   {name}: {', '.join(paths.values())}")


def demo_main(argv: Sequence[str] | None = None) -> int:
    """Run the ``demo`` subcommand; exit code 0 (ok) or 2 (missing design or FMUs).

    Runs :func:`run_demo` with ``--design``, ``--fmus``, ``--out`` and ``--H``, then prints
    the summary.
    """
    ap = argparse.ArgumentParser(prog="drillstring demo", description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out"))
    ap.add_argument(
        "--design", type=Path, default=Path("out/design"), help="folder of drillstring design"
    )
    ap.add_argument(
        "--fmus", type=Path, default=Path("build"), help="folder of the built FMUs and SSP packages"
    )
    ap.add_argument("--H", type=float, default=1e-3, help="macro step of the co-simulation")
    ap.add_argument(
        "--workers", type=int, default=2, help="Dask workers of the controller map (0: serial)"
    )
    ap.add_argument(
        "--map-points",
        type=int,
        default=DEMO_MAP_POINTS,
        help=f"points per axis of the controller map (default {DEMO_MAP_POINTS})",
    )
    args = ap.parse_args(argv)
    try:
        summary = run_demo(
            args.design,
            args.fmus,
            args.out,
            H=args.H,
            workers=args.workers,
            map_points=args.map_points,
            progress=True,
            log=lambda s: print(f"\n== {s}", flush=True),
        )
    except RuntimeError as exc:  # a host that is not installed, a run that stopped
        print(f"drillstring demo: {exc}", file=sys.stderr)
        return 2
    except (GainsFileError, ValueError, OSError) as exc:
        print(
            f"drillstring demo: {exc} (run `drillstring design --out {args.design}` and "
            f"`python build_fmus.py --gains {args.design / GAINS_FILE} --out {args.fmus}`)",
            file=sys.stderr,
        )
        return 2
    print("\n== Summary")
    print_summary(summary)
    print(f"   wrote {len(summary.files)} files, listed in {args.out / SUMMARY_FILE}")
    return 0
