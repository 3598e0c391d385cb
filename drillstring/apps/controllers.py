"""``drillstring controllers``: the industrial top-drive laws beside the paper's LMI design.

Two jobs (``docs/controllers.md``), each a function the demo calls and a subcommand:

* ``compare`` (:func:`write_controller_comparison`): the Fig. 6 set-up, the open loop in
  torsional stick-slip until tau = 25, then every controller of
  :data:`~drillstring.controller.lineup.CONTROLLERS` switched on from the same state, as a
  digital law with zero-order hold (and the paper's law also evaluated continuously, the
  monolithic path). One figure of the bit speeds, one table of the severity metrics
  (``comparison.png``, ``comparison.csv``, ``comparison.json`` with the laws' parameters in
  scaled and SI units).
* ``map`` (:func:`write_controller_map`): the controllers sweep study over the surface speed
  [rpm] and the nominal weight on bit [kN] on the design's rig (feed: imposed rate of
  penetration chosen for the nominal WOB), the digital controllers of
  :func:`~drillstring.controller.lineup.rig_lineup` under one top drive, with the linearised
  stability boundaries overlaid (``results.csv``, the maps in ``plots/``, and
  ``by_controller.csv``: how often each controller ends in each outcome and is the best).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import os
import sys
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from drillstring.analysis.severity import OUTCOMES, severity_metrics
from drillstring.apps.colors import CONTROLLER_COLORS
from drillstring.apps.sweep.metrics import controller_column
from drillstring.apps.sweep.runner import SweepError, SweepReport, run_sweep
from drillstring.apps.sweep.spec import (
    CONSTRAINED_CONTROLLERS,
    MAP_CONTROLLERS,
    SweepSpec,
    SweepSpecError,
    spec_from_dict,
)
from drillstring.controller.averaged import averaged_model
from drillstring.controller.design import CONSTRAINED_FILE
from drillstring.controller.gains import DEFAULT_GAINS_PATH, GainsFile, GainsFileError, read_gains
from drillstring.controller.lineup import (
    CONTROLLERS,
    RIG_CONTROLLERS,
    controller_lineup,
    lmi_gain,
)
from drillstring.fileio import save_figure, write_csv, write_json
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import EngineOptions
from drillstring.model.experiments import FIG6, Experiment
from drillstring.model.params import PhysicalParams, ScaledParams, known_rig
from drillstring.model.sampled import DEFAULT_TS, simulate_sampled
from drillstring.model.simulate import SimulationResult, simulate
from drillstring.plotting import new_figure
from drillstring.validation import check_int, check_real

__all__ = [
    "COMPARISON_COLUMNS",
    "MAP_OUTCOMES",
    "MAP_RPM",
    "MAP_V0",
    "Comparison",
    "ControllerMap",
    "controller_map_spec",
    "controllers_main",
    "format_comparison",
    "wob_range",
    "write_controller_comparison",
    "write_controller_map",
]

#: Columns of ``comparison.csv``.
COMPARISON_COLUMNS = (
    "controller",
    "evaluation",
    "outcome",
    "utr",
    "severity",
    "stick_fraction",
    "stall",
    "peak_torque",
    "peak_torque_over_R0",
    "peak_torque_Nm",
    "stick_entries_after_on",
    "status",
    "tau_reached",
)
OPEN_LOOP = "open-loop"
LMI_CONTINUOUS = "lmi-continuous"


def _gains(gains: GainsFile | str | os.PathLike[str]) -> GainsFile:
    return gains if isinstance(gains, GainsFile) else read_gains(gains)


def _matching_rig(params: ScaledParams) -> PhysicalParams | None:
    """A known physical rig whose scaled set is ``params`` (to 1e-9), for the SI columns."""
    return known_rig(params)


# --------------------------------------------------------------------------------------------
# the Fig. 6-like comparison
# --------------------------------------------------------------------------------------------


@dataclass
class Comparison:
    """What :func:`write_controller_comparison` measured and wrote.

    ``rows`` are the rows of ``comparison.csv`` (:data:`COMPARISON_COLUMNS`), ``laws`` each
    law's parameters (scaled and, with a rig, SI), ``files`` the written paths, ``runs`` the
    simulation results by row name.
    """

    rows: list[dict[str, Any]]
    laws: dict[str, dict[str, Any]]
    files: dict[str, Path] = field(default_factory=dict)
    runs: dict[str, SimulationResult] = field(default_factory=dict, repr=False)
    experiment: str = FIG6.name
    Ts: float = DEFAULT_TS
    window: float = 20.0


def _row(
    name: str,
    evaluation: str,
    result: SimulationResult,
    window: float,
    t_on: float,
    rig: PhysicalParams | None,
) -> dict[str, Any]:
    s = severity_metrics(result, window, t_from=t_on)
    R0 = result.params.R0
    entries = sum(
        1
        for e in result.events
        if e.kind == "mode" and e.to_mode == "torsional_stick" and e.tau >= t_on
    )
    return {
        "controller": name,
        "evaluation": evaluation,
        "outcome": s.outcome,
        "utr": s.utr,
        "severity": s.severity,
        "stick_fraction": s.stick_fraction,
        "stall": int(s.stall),
        "peak_torque": s.peak_torque,
        "peak_torque_over_R0": s.peak_torque / R0,
        "peak_torque_Nm": rig.physical_torque(s.peak_torque) if rig is not None else math.nan,
        "stick_entries_after_on": entries,
        "status": result.status.code,
        "tau_reached": s.tau_reached,
    }


def format_comparison(rows: Sequence[dict[str, Any]]) -> str:
    """The comparison table as fixed-width text (what ``drillstring controllers compare`` prints).

    Parameters
    ----------
    rows : sequence of dict
        Rows of :attr:`Comparison.rows` (keys of :data:`COMPARISON_COLUMNS`; ``controller``,
        ``evaluation``, ``outcome``, ``utr``, ``severity``, ``stick_fraction``,
        ``peak_torque_over_R0``, ``peak_torque_Nm`` and ``stick_entries_after_on`` are read).

    Returns
    -------
    str
        A header line, a rule and one line per row, joined by newlines (no trailing newline).

    Raises
    ------
    KeyError
        A row lacks one of the keys read.
    """
    head = (
        f"{'controller':<15} {'evaluation':<13} {'outcome':<11} {'UTR':>7} {'severity':>8} "
        f"{'stick':>6} {'peak R/R0':>10} {'peak R [N m]':>13} {'sticks':>6}"
    )
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r['controller']:<15} {r['evaluation']:<13} {r['outcome']:<11} {r['utr']:>7.3f} "
            f"{r['severity']:>8.3f} {r['stick_fraction']:>6.3f} {r['peak_torque_over_R0']:>10.2f} "
            f"{r['peak_torque_Nm']:>13.4g} {r['stick_entries_after_on']:>6d}"
        )
    return "\n".join(lines)


def _plot(
    path: Path,
    runs: dict[str, SimulationResult],
    omega0: float,
    t_on: float,
    window: float,
    title: str,
) -> Path:
    fig = new_figure((8.0, 9.0))
    axes = fig.subplots(len(CONTROLLERS), 1, sharex=True, sharey=True)
    open_loop = runs[OPEN_LOOP]
    tau_end = float(runs[CONTROLLERS[0]].tau[-1])
    for ax, name in zip(axes, CONTROLLERS, strict=True):
        ax.plot(open_loop.tau, omega0 + open_loop.dphi, color="0.75", lw=0.8, label="open loop")
        r = runs[name]
        ax.plot(r.tau, omega0 + r.dphi, color=CONTROLLER_COLORS[name], lw=1.0, label=name)
        if name == "lmi":
            c = runs[LMI_CONTINUOUS]
            ax.plot(c.tau, omega0 + c.dphi, "k--", lw=0.8, label="lmi, continuous")
        ax.axvline(t_on, color="k", ls=":", lw=1)
        ax.axvspan(tau_end - window, tau_end, color="0.93", zorder=0)
        ax.axhline(omega0, color="k", lw=0.5)
        ax.set_ylabel(r"$\dot\Phi$ (bit)")
        ax.legend(loc="upper left", fontsize=7, ncol=3)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel(r"$\tau$")
    axes[0].set_title(title, fontsize="medium")
    fig.tight_layout()
    return save_figure(fig, path)


def write_controller_comparison(
    out_dir: str | os.PathLike[str],
    gains: GainsFile | str | os.PathLike[str],
    *,
    experiment: Experiment = FIG6,
    Ts: float = DEFAULT_TS,
    window: float = 20.0,
    rig: PhysicalParams | None = None,
    log: Callable[[str], Any] | None = print,
) -> Comparison:
    """Every controller switched on from the same torsional stick-slip state (Fig. 6 set-up).

    The open loop (the feed-forward R_ff alone, (31)) runs from ``experiment.dphi0`` to
    ``experiment.t_on`` with the torsional-stick model on; then each controller of
    :data:`~drillstring.controller.lineup.CONTROLLERS` acts as a digital law with sample period
    ``Ts`` (:func:`~drillstring.model.sampled.simulate_sampled`), the paper's law also
    continuously (:func:`~drillstring.model.simulate.simulate`). The severity metrics are taken
    over the last ``window`` of the run, the peak torque from the switch-on on.

    Parameters
    ----------
    out_dir : path
        Where ``comparison.png``, ``comparison.csv`` and ``comparison.json`` go.
    gains : GainsFile or path
        The LMI design (its parameter set, A, taubar_crit, F and feed-forward are used).
    experiment : Experiment
        The set-up (default :data:`~drillstring.model.experiments.FIG6`).
    Ts : float
        Sample period of the digital laws (scaled).
    window : float
        Late window of the metrics (scaled time).
    rig : PhysicalParams, optional
        For the SI columns; default: a known rig whose scaled set is the gains' (the reference
        rig for the reference set), else none.
    log : callable, optional
        Receives the printed table (None: silent).

    Returns
    -------
    Comparison
    """
    g = _gains(gains)
    Ts = check_real("Ts", Ts, lower=0.0)
    window = check_real("window", window, lower=0.0)
    if window > experiment.tau_end - experiment.t_on:
        raise ValueError(
            f"window = {window!r} reaches back before the switch-on at t_on = {experiment.t_on!r} "
            f"(run length {experiment.tau_end!r})"
        )
    params = g.params
    rig = rig if rig is not None else _matching_rig(params)
    model = averaged_model(params, g.A, g.taubar_crit)
    gain = lmi_gain(model, g, feedforward="file")
    laws = controller_lineup(params, gain, t_on=experiment.t_on, latch=experiment.latch)
    options = EngineOptions(h=experiment.h, torsional_stick=experiment.torsional_stick)
    start = {"initial": experiment.initial(), "options": options}
    runs: dict[str, SimulationResult] = {
        OPEN_LOOP: simulate(params, experiment.tau_end, control=gain.R_ff, **start)
    }
    for name, law in laws.items():
        runs[name] = simulate_sampled(params, law, experiment.tau_end, Ts, **start)
    continuous = AffineFeedback(gain.F, gain.K0, gain.R_ff, experiment.t_on, experiment.latch)
    runs[LMI_CONTINUOUS] = simulate(params, experiment.tau_end, control=continuous, **start)
    sampled = f"Ts = {Ts:g}"
    evaluation = {OPEN_LOOP: "feed-forward", LMI_CONTINUOUS: "continuous"}
    rows = [
        _row(name, evaluation.get(name, sampled), r, window, experiment.t_on, rig)
        for name, r in runs.items()
    ]
    laws_out: dict[str, dict[str, Any]] = {}
    for name, law in laws.items():
        scaled = dataclasses.asdict(law.feedback if name == "lmi" else law)
        laws_out[name] = {"kind": type(law).__name__, "scaled": scaled}
        if rig is not None:
            laws_out[name]["si"] = law.to_si(rig)
    out = Path(out_dir)
    title = (
        f"{experiment.name} set-up: controllers switched on at tau = {experiment.t_on:g}, "
        f"sampled every {Ts:g}"
    )
    files = {
        "figure": _plot(
            out / "comparison.png", runs, params.omega0, experiment.t_on, window, title
        ),
        "table": write_csv(
            out / "comparison.csv",
            COMPARISON_COLUMNS,
            ([r[c] for c in COMPARISON_COLUMNS] for r in rows),
        ),
    }
    summary = {
        "experiment": experiment.name,
        "t_on": experiment.t_on,
        "tau_end": experiment.tau_end,
        "Ts": Ts,
        "window": window,
        "params": params.to_dict(),
        "rig": None if rig is None else rig.to_dict(),
        "rows": rows,
        "laws": laws_out,
    }
    files["json"] = write_json(out / "comparison.json", _jsonable(summary))
    if log is not None:
        log(format_comparison(rows))
    return Comparison(
        rows=rows,
        laws=laws_out,
        files=files,
        runs=runs,
        experiment=experiment.name,
        Ts=Ts,
        window=window,
    )


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, np.generic):
        return _jsonable(obj.item())
    return obj


# --------------------------------------------------------------------------------------------
# the small map
# --------------------------------------------------------------------------------------------


@dataclass
class ControllerMap:
    """What :func:`write_controller_map` ran: the sweep's report and the per-controller counts
    (``by_controller`` rows: controller, one count per outcome, stopped runs, failed points,
    times best)."""

    report: SweepReport
    by_controller: list[dict[str, Any]]
    files: dict[str, Path] = field(default_factory=dict)
    spec: Any = None


#: The outcomes counted per controller in ``by_controller.csv`` (a stopped run counts under
#: ``stopped``, and also under its status code when that is reverse rotation or bit bouncing).
MAP_OUTCOMES = (*OUTCOMES, "no_design", "reverse_rotation", "bit_bounce")


def _count_rows(results: Path, controllers: Sequence[str]) -> list[dict[str, Any]]:
    with open(results, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    best = Counter(r["best"] for r in rows if not r["error"])
    out = []
    for c in controllers:
        outcomes = Counter(r[controller_column("outcome", c)] for r in rows if not r["error"])
        entry: dict[str, Any] = {"controller": c}
        for o in MAP_OUTCOMES:
            entry[o] = outcomes.pop(o, 0)
        entry["stopped"] = sum(entry[o] for o in MAP_OUTCOMES[len(OUTCOMES) + 1 :]) + sum(
            outcomes.values()
        )
        entry["failed_points"] = sum(1 for r in rows if r["error"])
        entry["best"] = best.get(c, 0)
        out.append(entry)
    return out


#: The rpm range of the default map (the reference rig turns at 51.8 rpm).
MAP_RPM = (30.0, 150.0)
#: The feeds v0 (scaled, at the reference speed) whose nominal WOB bounds the default map.
MAP_V0 = (0.25, 2.0)


def wob_range(rig: PhysicalParams, v0: tuple[float, float] = MAP_V0) -> tuple[float, float]:
    """The nominal weights on bit [kN] of the rig's feed at scaled feeds ``v0``, at its speed.

    W0 = n*a*zeta*eps*d0 + n*a*l*sigma_bar, (4) and (7), with d0 = 2*pi*V0/(n*Omega0) of (8)
    and V0 = v0*L*/t*. A WOB at or below the wearflat contact part n*a*l*sigma_bar (16.5 kN on
    the reference rig) is reached by no positive feed.

    Parameters
    ----------
    rig : PhysicalParams
        The rig (its Omega0 is the reference speed).
    v0 : (float, float)
        Scaled feeds, > 0.

    Returns
    -------
    (float, float)
        The two weights on bit in kN.
    """
    lo, hi = (check_real("v0", v, lower=0.0) for v in v0)
    return tuple(  # type: ignore[return-value]
        rig.replace(V0=v * rig.L_star / rig.t_star).W0 / 1e3 for v in (lo, hi)
    )


def controller_map_spec(
    gains_path: str | os.PathLike[str],
    *,
    constrained_path: str | os.PathLike[str] | None = None,
    rig: PhysicalParams | None = None,
    controllers: Sequence[str] = MAP_CONTROLLERS,
    top_drive: str = "tds-11sa",
    n: int = 25,
    rpm: tuple[float, float] = MAP_RPM,
    wob_kN: tuple[float, float] | None = None,
    tau_end: float = 200.0,
    window: float = 30.0,
    Ts: float = DEFAULT_TS,
    dphi0_rel: float = -0.5,
) -> SweepSpec:
    """The sweep of :func:`write_controller_map` (its parameters, same defaults).

    Returns
    -------
    SweepSpec
        The validated controllers study over rpm x W0_kN on the rig.

    Raises
    ------
    ValueError
        No rig for the design's parameter set, or a bad value (a SweepSpecError naming it).
    GainsFileError
        A gains file that cannot be read.
    """
    n = check_int("n", n, lower=2)
    g = read_gains(gains_path)
    rig = rig if rig is not None else _matching_rig(g.params)
    if rig is None:
        raise ValueError(
            "the map's axes are physical (rpm, kN): the design's parameter set matches no known "
            "rig; pass rig="
        )
    wob = wob_range(rig) if wob_kN is None else wob_kN
    names = list(controllers)
    options: dict[str, Any] = {
        "controllers": names,
        "top_drive": top_drive,
        "gains": str(Path(gains_path).resolve()),
        "feedforward": "point",
        "window": window,
        "Ts": Ts,
        "dphi0_rel": dphi0_rel,
    }
    if any(c in CONSTRAINED_CONTROLLERS for c in names):
        path = (
            Path(gains_path).parent / CONSTRAINED_FILE
            if constrained_path is None
            else Path(constrained_path)
        )
        options["gains_constrained"] = str(path.resolve())
    return spec_from_dict(
        {
            "study": "controllers",
            "base": {"kind": "physical", **rig.to_dict()},
            "tau_end": tau_end,
            "sweep": [
                {"param": "rpm", "start": rpm[0], "stop": rpm[1], "num": n},
                {"param": "W0_kN", "start": wob[0], "stop": wob[1], "num": n},
            ],
            "options": options,
        },
        source="controller map",
    )


def write_controller_map(
    out_dir: str | os.PathLike[str],
    gains_path: str | os.PathLike[str],
    *,
    constrained_path: str | os.PathLike[str] | None = None,
    rig: PhysicalParams | None = None,
    controllers: Sequence[str] = MAP_CONTROLLERS,
    top_drive: str = "tds-11sa",
    n: int = 25,
    rpm: tuple[float, float] = MAP_RPM,
    wob_kN: tuple[float, float] | None = None,
    tau_end: float = 200.0,
    window: float = 30.0,
    Ts: float = DEFAULT_TS,
    dphi0_rel: float = -0.5,
    serial: bool = False,
    workers: int | None = None,
    client: Any = None,
    resume: bool = False,
    progress: bool = False,
    log: Callable[[str], Any] | None = print,
) -> ControllerMap:
    """The controller map: n x n points over the surface speed [rpm] and the nominal weight on
    bit [kN] on the rig of the design, every controller under the same top drive.

    Each point (rpm, W0) sets Omega0 and the hook speed V0 whose nominal weight on bit is W0
    (feed: imposed rate of penetration chosen for the nominal WOB; ``docs/controllers.md``,
    "Maps"). The paper-style LMI gain is fixed from ``gains_path``, the input-constrained one
    from ``constrained_path``, their K0 and R_ff taken at each point.

    Parameters
    ----------
    out_dir : path
        The sweep's output folder (``results.csv``, ``plots/``, ``by_controller.csv``).
    gains_path : path
        The gains file of the paper-style LMI design; its parameter set must be the rig's.
    constrained_path : path, optional
        The gains file of the input-constrained design (default: ``gains_constrained.json``
        beside ``gains_path``, where ``drillstring design --torque-limit`` writes it); needed
        only when a constrained controller is in ``controllers``.
    rig : PhysicalParams, optional
        The physical base (default: the known rig whose scaled set is the design's).
    controllers : sequence of str
        Of :data:`~drillstring.controller.lineup.RIG_CONTROLLERS`.
    top_drive : str
        The drive of every controller (``"none"`` or a spec of
        :func:`~drillstring.model.topdrive.top_drive_from_spec`).
    n : int
        Points per axis (>= 2).
    rpm : (float, float)
        Range of the surface speed [rpm].
    wob_kN : (float, float), optional
        Range of the nominal weight on bit [kN] (default: :func:`wob_range` of the rig).
    tau_end, window, Ts, dphi0_rel : float
        Run length, late window, sample period, initial bit speed as a fraction of omega0
        (options of the study, :mod:`drillstring.apps.sweep.spec`).
    serial, workers, client, resume, progress
        As :func:`~drillstring.apps.sweep.runner.run_sweep`.
    log : callable, optional
        Receives the per-controller table (None: silent).

    Returns
    -------
    ControllerMap

    Raises
    ------
    ValueError
        No rig for the design's parameter set, or a bad value (a SweepSpecError naming it).
    GainsFileError
        A gains file that cannot be read.
    """
    spec = controller_map_spec(
        gains_path,
        constrained_path=constrained_path,
        rig=rig,
        controllers=controllers,
        top_drive=top_drive,
        n=n,
        rpm=rpm,
        wob_kN=wob_kN,
        tau_end=tau_end,
        window=window,
        Ts=Ts,
        dphi0_rel=dphi0_rel,
    )
    report = run_sweep(
        spec,
        out_dir,
        serial=serial,
        workers=workers,
        client=client,
        resume=resume,
        progress=progress,
    )
    table = _count_rows(report.results, spec.options["controllers"])
    header = ["controller", *MAP_OUTCOMES, "stopped", "failed_points", "best"]
    files = {
        "by_controller": write_csv(
            Path(out_dir) / "by_controller.csv", header, ([r[h] for h in header] for r in table)
        )
    }
    if log is not None:
        log(
            f"{spec.n_points} points ({spec.axes[0].start:g}-{spec.axes[0].stop:g} rpm x "
            f"{spec.axes[1].start:.4g}-{spec.axes[1].stop:.4g} kN nominal WOB; {spec.feed}; "
            f"top drive {top_drive}), {report.n_failed} failed, {report.wall_time:.1f} s; "
            "outcomes per controller:"
        )
        log(" ".join(f"{h:>16}" for h in header))
        for r in table:
            log(" ".join(f"{r[h]!s:>16}" for h in header))
    return ControllerMap(report=report, by_controller=table, files=files, spec=spec)


# --------------------------------------------------------------------------------------------
# command line
# --------------------------------------------------------------------------------------------


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="drillstring controllers",
        description="Industrial top-drive controllers (stiff PI, SoftSpeed, Z-Torque) beside "
        "the LMI design: the Fig. 6-like comparison and a small map over speed and feed.",
    )
    sub = ap.add_subparsers(dest="job", required=True)
    for job, text in (
        ("compare", "every controller switched on from Fig. 6's stick-slip state at tau = 25"),
        ("map", "n x n map of the severity metrics over speed and WOB for every controller"),
    ):
        p = sub.add_parser(job, help=text, description=text)
        p.add_argument(
            "--gains",
            type=Path,
            default=DEFAULT_GAINS_PATH,
            help=f"gains file of the LMI design (default: {DEFAULT_GAINS_PATH})",
        )
        p.add_argument("--out", type=Path, required=True, help="output folder")
        p.add_argument("--Ts", type=float, default=DEFAULT_TS, help="sample period (scaled)")
        p.add_argument("--window", type=float, default=20.0, help="late window of the metrics")
    m = sub.choices["map"]
    m.description = m.description + (
        ": surface speed [rpm] x nominal weight on bit [kN] on the design's rig, every controller "
        "under one top drive (feed: imposed rate of penetration chosen for the nominal WOB)"
    )
    m.set_defaults(window=30.0)
    m.add_argument("--n", type=int, default=25, help="points per axis (default 25)")
    m.add_argument(
        "--rpm",
        type=float,
        nargs=2,
        default=MAP_RPM,
        metavar=("LO", "HI"),
        help=f"range of the surface speed [rpm] (default {MAP_RPM[0]:g} {MAP_RPM[1]:g})",
    )
    m.add_argument(
        "--wob",
        type=float,
        nargs=2,
        default=None,
        metavar=("LO", "HI"),
        help="range of the nominal weight on bit [kN] (default: what the rig's feed gives for "
        f"v0 in [{MAP_V0[0]:g}, {MAP_V0[1]:g}] at its speed; it must stay above the wearflat "
        "contact part n*a*l*sigma_bar, 16.5 kN on the reference rig)",
    )
    m.add_argument(
        "--gains-constrained",
        type=Path,
        default=None,
        help=f"gains file of the input-constrained design (default: {CONSTRAINED_FILE} beside "
        "--gains)",
    )
    m.add_argument(
        "--controllers",
        nargs="+",
        default=list(MAP_CONTROLLERS),
        metavar="NAME",
        help=f"the controllers (of {', '.join(RIG_CONTROLLERS)}; default "
        f"{' '.join(MAP_CONTROLLERS)})",
    )
    m.add_argument(
        "--top-drive",
        default="tds-11sa",
        help="the drive of every controller: a rating (tds-11sa), a multiple of the nominal "
        "torque (50R0), a torque (52kNm) or none (default tds-11sa)",
    )
    m.add_argument("--tau-end", type=float, default=200.0, help="run length (default 200)")
    m.add_argument(
        "--workers", type=int, default=None, help="Dask workers (default: CPU count; 0: serial)"
    )
    m.add_argument("--resume", action="store_true", help="skip the points already computed")
    m.add_argument("--no-progress", action="store_true", help="no progress bar")
    return ap


def controllers_main(argv: Sequence[str] | None = None) -> int:
    """Run ``drillstring controllers compare|map`` (``docs/controllers.md``, "Fig. 6-like
    comparison" and "Maps").

    ``compare`` writes :func:`write_controller_comparison`'s files, ``map`` the controller map of
    :func:`write_controller_map`; either prints where. A bad gains file, sweep spec, value or
    file error is printed to stderr.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after ``controllers`` (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit code: 0 done, 2 bad input (also argparse's exit code for bad options, which it
        raises as ``SystemExit``).
    """
    args = _parser().parse_args(argv)
    prog = f"drillstring controllers {args.job}"
    try:
        if args.job == "compare":
            result = write_controller_comparison(
                args.out, args.gains, Ts=args.Ts, window=args.window
            )
            print(f"wrote {', '.join(str(p) for p in result.files.values())}")
            return 0
        if args.workers is not None and args.workers < 0:
            print(f"{prog}: --workers must be >= 0, got {args.workers}", file=sys.stderr)
            return 2
        result_map = write_controller_map(
            args.out,
            args.gains,
            constrained_path=args.gains_constrained,
            controllers=args.controllers,
            top_drive=args.top_drive,
            n=args.n,
            rpm=tuple(args.rpm),
            wob_kN=None if args.wob is None else tuple(args.wob),
            tau_end=args.tau_end,
            window=args.window,
            Ts=args.Ts,
            serial=args.workers == 0,
            workers=args.workers or None,
            resume=args.resume,
            progress=not args.no_progress,
        )
        report = result_map.report
        print(f"maps: {report.out_dir / 'plots'}; results: {report.results}")
        return 0
    except (GainsFileError, SweepSpecError, SweepError, ValueError, OSError) as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2
