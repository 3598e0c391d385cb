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
import math
import os
import sys
import textwrap
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from drillstring.analysis.severity import Severity, severity_metrics
from drillstring.apps.colors import CONTROLLER_COLORS
from drillstring.apps.sweep.options import MAP_WINDOW, ControllerOptions
from drillstring.apps.sweep.runner import SweepError, SweepReport, run_sweep
from drillstring.apps.sweep.spec import SweepSpec, SweepSpecError, spec_from_dict
from drillstring.apps.sweep.studies import OPEN_LOOP, evaluate_controllers, map_top_drive
from drillstring.apps.sweep.tables import BY_CONTROLLER_COLUMNS
from drillstring.controller.averaged import averaged_model
from drillstring.controller.design import CONSTRAINED_FILE
from drillstring.controller.gains import DEFAULT_GAINS_PATH, GainsFile, GainsFileError, read_gains
from drillstring.controller.lineup import (
    CONSTRAINED_CONTROLLERS,
    MAP_CONTROLLERS,
    RIG_CONTROLLERS,
    SENSING,
    TIMED_CONTROLLERS,
    Tuning,
    lmi_gain,
    sensing_note,
)
from drillstring.controller.tuning import IMPEDANCES, SOFT_SPEED_RULES
from drillstring.fileio import load_table, save_figure, write_csv, write_json
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import EngineOptions
from drillstring.model.experiments import FIG6, Experiment
from drillstring.model.params import PhysicalParams, known_rig
from drillstring.model.pipe import StringParams, string_of_rig
from drillstring.model.simulate import SimulationResult, simulate
from drillstring.model.topdrive import BRAKING, RPM
from drillstring.plotting import new_figure
from drillstring.validation import check_int, check_real

__all__ = [
    "COMPARISON_COLUMNS",
    "MAP_SPEC",
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

#: Columns of ``comparison.csv``: SI, the unit in the name (``_kNm`` kN m, ``_kW``, ``_rpm``,
#: ``_s``); ``_over_R0`` a ratio to the nominal torque, ``_scaled`` the paper's scaled time;
#: the others are counts, fractions or dimensionless.
COMPARISON_COLUMNS = (
    "controller",
    "sensing",
    "top_drive",
    "braking",
    "string_elements",
    "outcome",
    "severity",
    "utr",
    "stick_fraction",
    "peak_torque_over_R0",
    "peak_torque_kNm",
    "peak_torque_late_kNm",
    "rms_torque_late_kNm",
    "peak_power_kW",
    "saturated_fraction",
    "min_table_speed_rpm",
    "settling_time_s",
    "stick_entries_after_on",
    "status",
    "t_reached_s",
    "tau_reached_scaled",
)
#: The suffix of a run's name (:attr:`Comparison.runs`) under the drive without braking.
NO_BRAKING = " (no braking)"
#: Elements of the converged string, the default of ``drillstring controllers compare|map``
#: (``docs/controllers.md``, "On the distributed string").
STRING_ELEMENTS = 16
#: The paper's set-up of Fig. 6: its LMI law evaluated continuously, no top drive (the
#: reproduction of the figure; no real drive delivers its torque).
LMI_UNLIMITED = "lmi-unlimited"
#: How each row measures (``sensing`` column).
SENSING_TEXT = {OPEN_LOOP: "-", **SENSING, LMI_UNLIMITED: SENSING["lmi"]}
#: The comparison's run: Fig. 6's switch-on at tau = 25, then 75 (12 torsional periods), the
#: metrics over the last 35 (five periods of the slowest stick-slip, as the maps) and the trend
#: test's window before it, both after the switch-on.
COMPARISON_TAU_END = 100.0
COMPARISON_WINDOW = MAP_WINDOW


def _gains(gains: GainsFile | str | os.PathLike[str]) -> GainsFile:
    return gains if isinstance(gains, GainsFile) else read_gains(gains)


# --------------------------------------------------------------------------------------------
# the Fig. 6-like comparison
# --------------------------------------------------------------------------------------------


@dataclass
class Comparison:
    """What :func:`write_controller_comparison` measured and wrote.

    ``rows`` are the rows of ``comparison.csv`` (:data:`COMPARISON_COLUMNS`), ``laws`` each
    controller's parameters (scaled and, with a rig, SI), ``files`` the written paths, ``runs``
    the simulation results by row name, ``options`` how the controllers ran (with braking).
    """

    rows: list[dict[str, Any]]
    laws: dict[str, dict[str, Any]]
    files: dict[str, Path] = field(default_factory=dict)
    runs: dict[str, SimulationResult] = field(default_factory=dict, repr=False)
    experiment: str = FIG6.name
    options: ControllerOptions = field(default_factory=ControllerOptions)
    elements: int = 1


def _row(
    name: str,
    drive: str,
    result: SimulationResult,
    s: Severity,
    t_on: float,
    rig: PhysicalParams | None,
    braking: str = "four-quadrant",
) -> dict[str, Any]:
    p = result.params
    entries = sum(
        1
        for e in result.events
        if e.kind == "mode" and e.to_mode == "torsional_stick" and e.tau >= t_on
    )
    C = rig.C if rig is not None else math.nan
    t_star = rig.t_star if rig is not None else math.nan
    return {
        "controller": name,
        "sensing": SENSING_TEXT[name],
        "top_drive": drive,
        "braking": braking if drive != "none" else "-",
        "string_elements": 1 if result.string is None else result.string.elements,
        "outcome": s.outcome,
        "severity": s.severity,
        "utr": s.utr,
        "stick_fraction": s.stick_fraction,
        "peak_torque_over_R0": s.peak_torque / p.R0,
        "peak_torque_kNm": s.peak_torque * C / 1e3,
        "peak_torque_late_kNm": s.peak_torque_late * C / 1e3,
        "rms_torque_late_kNm": s.rms_torque_late * C / 1e3,
        "peak_power_kW": s.peak_power * C / t_star / 1e3,
        "saturated_fraction": s.saturated_fraction,
        "min_table_speed_rpm": s.min_table_speed / t_star / RPM,
        "settling_time_s": s.settling_time * t_star,
        "stick_entries_after_on": entries,
        "status": result.status.code,
        "t_reached_s": s.tau_reached * t_star,
        "tau_reached_scaled": s.tau_reached,
    }


def _brake_text(row: dict[str, Any]) -> str:
    b = row.get("braking", "-")
    return {"four-quadrant": "yes", "none": "no"}.get(b, "-")


def format_comparison(rows: Sequence[dict[str, Any]]) -> str:
    """The comparison table as fixed-width text (what ``drillstring controllers compare`` prints).

    Parameters
    ----------
    rows : sequence of dict
        Rows of :attr:`Comparison.rows` (keys of :data:`COMPARISON_COLUMNS`).

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
        f"{'controller':<16} {'brake':<5} {'sensing':<25} {'outcome':<16} {'sev.':>6} {'stick':>5} "
        f"{'peak R/R0':>9} {'peak kN m':>9} {'late pk':>8} {'late rms':>8} {'kW':>6} {'sat.':>5} "
        f"{'min rpm':>7} {'settle s':>8}"
    )
    lines = [head, "-" * len(head)]

    def num(x: float, fmt: str) -> str:
        return "-" if not math.isfinite(x) else format(x, fmt)

    for r in rows:
        lines.append(
            f"{r['controller']:<16} {_brake_text(r):<5} {r['sensing']:<25} {r['outcome']:<16} "
            f"{num(r['severity'], '6.3f'):>6} {num(r['stick_fraction'], '5.3f'):>5} "
            f"{num(r['peak_torque_over_R0'], '9.1f'):>9} {num(r['peak_torque_kNm'], '9.3g'):>9} "
            f"{num(r['peak_torque_late_kNm'], '8.3g'):>8} "
            f"{num(r['rms_torque_late_kNm'], '8.3g'):>8} {num(r['peak_power_kW'], '6.0f'):>6} "
            f"{num(r['saturated_fraction'], '5.3f'):>5} {num(r['min_table_speed_rpm'], '7.1f'):>7} "
            f"{num(r['settling_time_s'], '8.1f'):>8}"
        )
    return "\n".join(lines)


def _plot(
    path: Path,
    runs: dict[str, SimulationResult],
    rows: dict[str, dict[str, Any]],
    rig: PhysicalParams,
    t_on: float,
    window: float,
    title: str,
    rating_kNm: tuple[float, float] | None,
) -> Path:
    """The bit speeds [rpm] against time [s], one panel per controller (with braking solid,
    without dashed; the outcome in the legend), and a panel of the applied table torque [kN m]
    with the drive's rating."""
    t_star = rig.t_star
    omega0 = runs[OPEN_LOOP].params.omega0
    names = [n for n in runs if n != OPEN_LOOP and not n.endswith(NO_BRAKING)]
    fig = new_figure((9.0, 1.6 * len(names) + 3.0))
    axes = np.atleast_1d(fig.subplots(len(names) + 1, 1, sharex=True))
    open_loop = runs[OPEN_LOOP]
    t_end = float(open_loop.tau[-1]) * t_star

    def rpm(r: SimulationResult) -> np.ndarray:
        return (omega0 + r.dphi) / t_star / RPM

    def color(name: str) -> Any:
        return CONTROLLER_COLORS.get(name.split("-")[0] if name.startswith("lmi") else name)

    tq = axes[-1]
    for ax, name in zip(axes[:-1], names, strict=True):
        ax.plot(open_loop.tau * t_star, rpm(open_loop), color="0.75", lw=0.8,
                label=f"open loop: {rows[OPEN_LOOP]['outcome']}")  # fmt: skip
        for key, ls, what in ((name, "-", ""), (name + NO_BRAKING, "--", ", no braking")):
            if key not in runs:
                continue
            r = runs[key]
            ax.plot(r.tau * t_star, rpm(r), color=color(name), lw=1.0, ls=ls,
                    label=f"{name}{what}: {_legend_outcome(rows[key])}")  # fmt: skip
            if name != LMI_UNLIMITED:  # the paper's set-up has no drive: 1000 times the rating
                R = (r.params.R0 + r.R_minus_R0) * rig.C / 1e3
                tq.plot(r.tau * t_star, R, color=color(name), lw=0.7, ls=ls)
        ax.axvline(t_on * t_star, color="k", ls=":", lw=1)
        ax.axvspan(t_end - window * t_star, t_end, color="0.93", zorder=0)
        ax.axhline(omega0 / t_star / RPM, color="k", lw=0.5)
        ax.set_ylabel("bit [rpm]")
        ax.legend(loc="upper left", fontsize=7, ncol=2)
        ax.grid(alpha=0.3)
    if rating_kNm is not None:
        lo, hi = rating_kNm
        for v, text in ((hi, f"rating {hi:.1f} kN m"), (lo, f"braking limit {lo:.1f} kN m")):
            tq.axhline(v, color="r", ls="-.", lw=0.8)
            tq.annotate(text, (0.995, v), xycoords=("axes fraction", "data"), ha="right",
                        va="bottom", fontsize=7, color="r")  # fmt: skip
        tq.axhline(0.0, color="r", ls=":", lw=0.8)  # the limit without braking
        tq.set_ylim(1.15 * min(lo, 0.0) - 0.05 * hi, 1.15 * hi)
    tq.axvline(t_on * t_star, color="k", ls=":", lw=1)
    tq.set_ylabel("table torque [kN m]\n(every drive-limited law)")
    tq.grid(alpha=0.3)
    tq.set_xlabel("time [s]")
    axes[0].set_title(title, fontsize="small")
    fig.tight_layout()
    return save_figure(fig, path)


def _legend_outcome(row: dict[str, Any]) -> str:
    """What a run did: its outcome (steady, stick-slip, ...); a stopped run's reason."""
    if row["status"] != "ok":
        return f"stopped ({row['status']})"
    return str(row["outcome"])


def write_controller_comparison(
    out_dir: str | os.PathLike[str],
    gains: GainsFile | str | os.PathLike[str],
    constrained: GainsFile | str | os.PathLike[str] | None = None,
    *,
    experiment: Experiment = FIG6,
    tau_end: float = COMPARISON_TAU_END,
    options: ControllerOptions | None = None,
    rig: PhysicalParams | None = None,
    string: StringParams | None = None,
    without_braking: bool = False,
    log: Callable[[str], Any] | None = print,
) -> Comparison:
    """Every controller switched on from the same torsional stick-slip state (Fig. 6 set-up),
    all under the same top drive (``docs/controllers.md``, "Fig. 6-like comparison").

    The open loop (the feed-forward R_ff alone, (31)) runs from ``experiment.dphi0`` to
    ``experiment.t_on`` with the torsional-stick model on; then each digital controller of
    :func:`~drillstring.controller.lineup.rig_lineup` (the industrial laws, the paper-style LMI
    design of ``gains``, the constrained design of ``constrained`` with exact, mud-pulse and
    observer sensing) acts with sample period ``Ts`` under the top drive ``top_drive``
    (:func:`~drillstring.apps.sweep.studies.evaluate_controllers`, as at a map's points); and, as
    the paper's set-up, its LMI law continuously without a drive (:data:`LMI_UNLIMITED`). The
    metrics are taken over the last ``window`` of the run, the effort from the switch-on on.

    Parameters
    ----------
    out_dir : path
        Where ``comparison.png``, ``comparison.csv`` and ``comparison.json`` go.
    gains : GainsFile or path
        The paper-style LMI design (its parameter set, A, taubar_crit, F and feed-forward).
    constrained : GainsFile or path, optional
        The input-constrained design (``drillstring design --torque-limit``); None: its rows
        are left out.
    experiment : Experiment
        The set-up (default :data:`~drillstring.model.experiments.FIG6`); run to ``tau_end``.
    tau_end : float
        End of the run (scaled), after the switch-on by more than ``2*window``.
    options : ControllerOptions, optional
        How the lineup is evaluated (default: :class:`~drillstring.apps.sweep.options.
        ControllerOptions`'s): the sample period ``Ts``, the metrics' late ``window`` holding
        ``min_periods`` periods of the slowest oscillation (:data:`~drillstring.analysis.
        severity.SLOWEST_PERIOD`; 0: none, for a quick run whose outcomes are not to be
        trusted), the drive ``top_drive`` of every controller
        (:func:`~drillstring.model.topdrive.top_drive_from_spec`, or "none"), the industrial
        rules' ``tuning`` (``"pipe"`` takes the pipe of ``rig``), ...; the controllers, the
        step, the switch-on and its latch are the comparison's (the rig's lineup, the
        experiment's).
    rig : PhysicalParams, optional
        For the SI columns, the drive and the pipe; default: a known rig whose scaled set is the
        gains' (the reference rig for the reference set).
    string : StringParams, optional
        The drill pipe of every run (default: the paper's one-mode string; ``drillstring
        controllers compare`` takes the converged string of :data:`STRING_ELEMENTS` elements).
        On the distributed string the controllers measure the torque at the top of the string.
    without_braking : bool
        Also run every controller under the same drive without braking (torque range [0,
        R_max]); its rows have ``braking`` "none" and its runs the suffix :data:`NO_BRAKING`.
    log : callable, optional
        Receives the printed table (None: silent).

    Returns
    -------
    Comparison

    Raises
    ------
    ValueError
        A bad value (named; the checks of :class:`~drillstring.apps.sweep.options.
        ControllerOptions`), a window shorter than ``min_periods`` periods of the slowest
        stick-slip or than the trend test needs after the switch-on, no rig for the gains, an
        experiment without the torsional-stick model.
    """
    if not experiment.torsional_stick:
        raise ValueError(
            f"experiment {experiment.name!r} has the torsional-stick model off: the controllers "
            "are evaluated with it on (evaluate_controllers)"
        )
    g = _gains(gains)
    gc = None if constrained is None else _gains(constrained)
    t_on = experiment.t_on
    params = g.params
    if gc is not None and gc.params != params:
        raise ValueError("the constrained design is for another parameter set than the gains")
    rig = rig if rig is not None else known_rig(params)
    if rig is None:
        raise ValueError("no physical rig maps onto the gains' parameter set: give rig=")
    model = averaged_model(params, g.A, g.taubar_crit)
    paper = lmi_gain(model, g, feedforward="file")
    cgain = None if gc is None else lmi_gain(model, gc, feedforward="file")
    rig_names = [n for n in RIG_CONTROLLERS if gc is not None or n not in CONSTRAINED_CONTROLLERS]
    # the timing of a real drive: the rows of TIMED_CONTROLLERS whose controller runs here
    timed = [n for n, (of, _) in TIMED_CONTROLLERS.items() if of in rig_names]
    names = (*rig_names, *timed)
    options = replace(
        ControllerOptions() if options is None else options, controllers=tuple(rig_names),
        h=experiment.h, t_on=t_on, latch=experiment.latch,
    )  # fmt: skip
    tau_end = options.check_run(tau_end)
    drive = map_top_drive(options.top_drive, params, rig)
    brakings = ("four-quadrant", "none") if without_braking and drive is not None else BRAKING[:1]
    start: dict[str, Any] = {"initial": experiment.initial(), "string": string}
    evaluated = {
        b: evaluate_controllers(params, model, paper, cgain, replace(options, braking=b),
                                tau_end=tau_end, scales=rig, names=names, **start)
        for b in brakings
    }  # fmt: skip
    engine = EngineOptions(h=experiment.h, torsional_stick=experiment.torsional_stick)
    runs: dict[str, SimulationResult] = {
        OPEN_LOOP: simulate(params, tau_end, control=paper.R_ff, options=engine, **start)
    }
    braking_of: dict[str, str] = {}
    severity: dict[str, Severity] = {}
    controllers = {name: run.controller for name, run in evaluated["four-quadrant"].items()}
    for name in controllers:
        for b in brakings:
            key = name if b == "four-quadrant" else name + NO_BRAKING
            runs[key], severity[key] = evaluated[b][name].result, evaluated[b][name].severity
            braking_of[key] = b
    continuous = AffineFeedback(paper.F, paper.K0, paper.R_ff, t_on, experiment.latch)
    runs[LMI_UNLIMITED] = simulate(params, tau_end, control=continuous, options=engine, **start)
    for key in (OPEN_LOOP, LMI_UNLIMITED):
        severity[key] = severity_metrics(runs[key], options.window, t_from=t_on)
    row_of = {
        key: _row(key.removesuffix(NO_BRAKING),
                  "none" if key in (OPEN_LOOP, LMI_UNLIMITED) else options.top_drive, r,
                  severity[key],
                  t_on, rig, braking_of.get(key, "four-quadrant"))
        for key, r in runs.items()
    }  # fmt: skip
    rows = list(row_of.values())
    laws_out: dict[str, dict[str, Any]] = {}
    for name, controller in controllers.items():
        law = controller.law
        laws_out[name] = {
            "kind": type(law).__name__,
            "scaled": law.values(),
            "si": law.to_si(rig),
            "sensing": controller.sensing.values(),
            "timing_s": controller.timing.to_si(rig),
        }
    out = Path(out_dir)
    elements = 1 if string is None else string.elements
    model_text = (
        "the one-mode string (the paper's model)"
        if string is None or string.is_paper
        else f"the distributed string, {elements} elements"
    )
    title = (
        f"{experiment.name} set-up on {model_text}: controllers on at t = "
        f"{t_on * rig.t_star:.3g} s, sampled every {options.Ts * rig.t_star * 1e3:.3g} ms, "
        f"top drive {options.top_drive}\n(solid: with braking, dashed: without; "
        f"{LMI_UNLIMITED}: no drive, the paper's; grey band: the metrics' window)\n"
        + "\n".join(
            textwrap.wrap(
                sensing_note([n for n in runs if n in SENSING]), 120, break_on_hyphens=False
            )
        )
    )
    files = {
        "figure": _plot(
            out / "comparison.png",
            runs,
            row_of,
            rig,
            t_on,
            options.window,
            title,
            _rating_kNm(drive, rig),
        ),  # fmt: skip
        "table": write_csv(
            out / "comparison.csv",
            COMPARISON_COLUMNS,
            ([r[c] for c in COMPARISON_COLUMNS] for r in rows),
        ),
    }
    summary = {
        "experiment": experiment.name,
        "t_on": t_on,
        "tau_end": tau_end,
        "Ts": options.Ts,
        "window": options.window,
        "top_drive": {
            "spec": options.top_drive,
            "limits": None if drive is None else drive.to_si(rig),
        },
        "tuning": options.tuning.values(),
        "string": {
            "elements": elements,
            "lumping": "paper" if string is None else string.lumping,
            "kappa": None if string is None else string.kappa,
        },
        "params": params.to_dict(),
        "rig": rig.to_dict(),
        "rows": rows,
        "laws": laws_out,
    }
    files["json"] = write_json(out / "comparison.json", summary)
    if log is not None:
        log(format_comparison(rows))
    return Comparison(
        rows=rows,
        laws=laws_out,
        files=files,
        runs=runs,
        experiment=experiment.name,
        options=options,
        elements=elements,
    )


def _rating_kNm(drive: Any, rig: PhysicalParams) -> tuple[float, float] | None:
    """The drive's torque range [kN m] (its braking limit and rating), None without a drive."""
    if drive is None or not (math.isfinite(drive.R_min) and math.isfinite(drive.R_max)):
        return None
    return drive.R_min * rig.C / 1e3, drive.R_max * rig.C / 1e3


# --------------------------------------------------------------------------------------------
# the small map
# --------------------------------------------------------------------------------------------


@dataclass
class ControllerMap:
    """What :func:`write_controller_map` ran: the sweep's report, the per-controller counts
    (``by_controller`` rows: controller, one count per outcome, stopped runs, failed points,
    times best), the tables written and the spec."""

    report: SweepReport
    by_controller: list[dict[str, Any]]
    files: dict[str, Path] = field(default_factory=dict)
    spec: SweepSpec | None = None


#: The controller map, a sweep spec of the controllers study shipped with the package: 25 x 25
#: points over the surface speed [rpm] and the nominal weight on bit [kN] on the reference rig,
#: the map's controllers on the converged string, its gains files named relative to the design's
#: folder (``drillstring sweep MAP_SPEC --base-dir out/design --out DIR`` runs it as it is).
MAP_SPEC = Path(__file__).parent / "sweep" / "controller_map.json"
#: The feeds v0 (scaled, at the reference speed) whose nominal WOB bounds the default map below.
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
    n: int | None = None,
    rpm: tuple[float, float] | None = None,
    wob_kN: tuple[float, float] | None = None,
    tau_end: float | None = None,
    **options: Any,
) -> SweepSpec:
    """The controller map of :data:`MAP_SPEC` for a design, with the changes given.

    The paper-style LMI gain is fixed from ``gains_path``, the input-constrained one from
    ``constrained_path``, their K0 and R_ff taken at each point; the base is the design's rig,
    the WOB axis from what its feed gives for v0 = 0.25 at its speed (:func:`wob_range`) to
    the spec's upper end.

    Parameters
    ----------
    gains_path : path
        The gains file of the paper-style LMI design; its parameter set must be the rig's.
    constrained_path : path, optional
        The gains file of the input-constrained design (default: the spec's
        ``gains_constrained.json`` beside ``gains_path``, where ``drillstring design
        --torque-limit`` writes it); read only when a constrained controller is run.
    rig : PhysicalParams, optional
        The physical base (default: the known rig whose scaled set is the design's).
    n : int, optional
        Points per axis (>= 2).
    rpm, wob_kN : (float, float), optional
        Ranges of the surface speed [rpm] and of the nominal weight on bit [kN].
    tau_end : float, optional
        Run length (scaled).
    **options
        Options of the controllers study (:class:`~drillstring.apps.sweep.options.
        ControllerOptions`; the tuning as ``impedance``, ``soft_speed``, ``z_matching``).

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
    data = load_table(MAP_SPEC)
    g = read_gains(gains_path)
    rig = rig if rig is not None else known_rig(g.params)
    if rig is None:
        raise ValueError(
            "the map's axes are physical (rpm, kN): the design's parameter set matches no known "
            "rig; pass rig="
        )
    data["base"] = {"kind": "physical", **rig.to_dict()}
    speed, wob = data["sweep"]
    if n is not None:
        speed["num"] = wob["num"] = check_int("n", n, lower=2)
    if rpm is not None:
        speed["start"], speed["stop"] = rpm
    wob["start"], wob["stop"] = (wob_range(rig)[0], wob["stop"]) if wob_kN is None else wob_kN
    if tau_end is not None:
        data["tau_end"] = tau_end
    opts = {**data["options"], **options}
    folder = Path(gains_path).parent
    opts["gains"] = str(Path(gains_path).resolve())
    if any(c in CONSTRAINED_CONTROLLERS for c in opts["controllers"]):
        path = Path(constrained_path or folder / opts["gains_constrained"])
        opts["gains_constrained"] = str(path.resolve())
    else:
        del opts["gains_constrained"]
    data["options"] = opts
    return spec_from_dict(data, source="controller map", base_dir=folder)


def write_controller_map(
    out_dir: str | os.PathLike[str],
    gains_path: str | os.PathLike[str],
    *,
    serial: bool = False,
    workers: int | None = None,
    client: Any = None,
    resume: bool = False,
    progress: bool = False,
    log: Callable[[str], Any] | None = print,
    **changes: Any,
) -> ControllerMap:
    """Run the controller map (:func:`controller_map_spec` of ``gains_path`` and ``changes``)
    into ``out_dir``: every controller under the same top drive at each point (rpm, W0), the
    point setting Omega0 and the hook speed V0 whose nominal weight on bit is W0 (feed:
    imposed rate of penetration chosen for the nominal WOB; ``docs/controllers.md``, "Maps").

    Parameters
    ----------
    out_dir : path
        The sweep's output folder (``results.csv``, ``plots/``, ``by_controller.csv``,
        ``map_si.csv``).
    gains_path : path
        The gains file of the paper-style LMI design.
    serial, workers, client, resume, progress
        As :func:`~drillstring.apps.sweep.runner.run_sweep`.
    log : callable, optional
        Receives the per-controller table (None: silent).
    **changes
        What :func:`controller_map_spec` takes besides ``gains_path``.

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
    spec = controller_map_spec(gains_path, **changes)
    report = run_sweep(spec, out_dir, serial=serial, workers=workers, client=client,
                       resume=resume, progress=progress)  # fmt: skip
    opts = spec.options
    if log is not None:
        braking = opts.braking
        log(
            f"{spec.n_points} points ({spec.axes[0].start:g}-{spec.axes[0].stop:g} rpm x "
            f"{spec.axes[1].start:.4g}-{spec.axes[1].stop:.4g} kN nominal WOB; {spec.feed}; "
            f"top drive {opts.top_drive}, braking {braking}; {opts.elements} element(s)), "
            f"{report.n_failed} failed, {report.wall_time:.1f} s; "
            "outcomes per controller:"
        )
        log(" ".join(f"{h:>16}" for h in BY_CONTROLLER_COLUMNS))
        for r in report.by_controller:
            log(" ".join(f"{r[h]!s:>16}" for h in BY_CONTROLLER_COLUMNS))
    return ControllerMap(report=report, by_controller=report.by_controller, files=report.tables,
                         spec=spec)  # fmt: skip


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
    # the comparison's defaults; the map's are its spec's (MAP_SPEC), where a value is not given
    defaults = ControllerOptions()
    for job, text in (
        ("compare", "every controller switched on from Fig. 6's stick-slip state at tau = 25"),
        ("map", "n x n map of the severity metrics over speed and WOB for every controller "
         f"(the sweep spec {MAP_SPEC.name}, changed by the options given)"),
    ):  # fmt: skip
        p = sub.add_parser(job, help=text, description=text)
        compare = job == "compare"

        def given(value: Any, compare: bool = compare) -> Any:
            return value if compare else None

        p.add_argument(
            "--gains",
            type=Path,
            default=DEFAULT_GAINS_PATH,
            help=f"gains file of the LMI design (default: {DEFAULT_GAINS_PATH})",
        )
        p.add_argument("--out", type=Path, required=True, help="output folder")
        p.add_argument("--Ts", type=float, default=given(defaults.Ts),
                       help=f"sample period (scaled; default {defaults.Ts:g})")  # fmt: skip
        p.add_argument(
            "--window",
            type=float,
            default=given(defaults.window),
            help=f"late window of the metrics (scaled; default {defaults.window:g})",
        )
        p.add_argument(
            "--min-periods",
            type=float,
            default=given(defaults.min_periods),
            help="periods of the slowest stick-slip (7 in scaled time) the window must hold "
            f"(default {defaults.min_periods:g}; 0 for a quick run whose outcomes are not "
            "trusted)",
        )
        p.add_argument(
            "--impedance",
            choices=IMPEDANCES,
            default=given(defaults.tuning.impedance),
            help="string impedance Z of the industrial rules: the lumped sqrt(C*I1) or the "
            "rig's drill pipe J*sqrt(G*rho_steel) (default lumped)",
        )
        p.add_argument(
            "--soft-speed",
            choices=SOFT_SPEED_RULES,
            default=given(defaults.tuning.soft_speed),
            help="SoftSpeed's kp: 2*sqrt(rho)*Z (two-mass) or Z (impedance, the field rule; "
            "default two-mass)",
        )
        p.add_argument(
            "--elements",
            type=int,
            default=given(STRING_ELEMENTS),
            help=f"elements of the drill pipe (default {STRING_ELEMENTS}: the converged "
            "distributed string; 1: the paper's one-mode model)",
        )
        p.add_argument(
            "--z-matching",
            type=float,
            default=given(defaults.tuning.z_matching),
            help="Z-Torque's fraction of full impedance matching, >= 0 (default 1; "
            "Simulator4nDOF: 0.25)",
        )
        p.add_argument(
            "--top-drive",
            default=given(defaults.top_drive),
            help="the drive of every controller: a rating (tds-11sa), a multiple of the nominal "
            "torque (50R0), a torque (52kNm) or none (default tds-11sa)",
        )
    c = sub.choices["compare"]
    c.add_argument(
        "--constrained",
        type=Path,
        default=None,
        help="gains file of the input-constrained design (default: gains_constrained.json "
        "beside --gains, when it is there)",
    )
    c.add_argument("--tau-end", type=float, default=COMPARISON_TAU_END,
                   help=f"run length (default {COMPARISON_TAU_END:g})")  # fmt: skip
    c.add_argument(
        "--braking-only",
        action="store_true",
        help="only the drive with braking (default: every controller with and without)",
    )
    m = sub.choices["map"]
    m.description = m.description + (
        ": surface speed [rpm] x nominal weight on bit [kN] on the design's rig, every controller "
        "under one top drive (feed: imposed rate of penetration chosen for the nominal WOB)"
    )
    m.add_argument("--n", type=int, default=None, help="points per axis (default 25)")
    m.add_argument(
        "--rpm",
        type=float,
        nargs=2,
        default=None,
        metavar=("LO", "HI"),
        help="range of the surface speed [rpm] (default 20 150)",
    )
    m.add_argument(
        "--wob",
        type=float,
        nargs=2,
        default=None,
        metavar=("LO", "HI"),
        help="range of the nominal weight on bit [kN] (default: from what the rig's feed gives "
        f"for v0 = {MAP_V0[0]:g} at its speed to 40; it must stay above the wearflat contact "
        "part n*a*l*sigma_bar, 16.5 kN on the reference rig)",
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
        default=None,
        metavar="NAME",
        help=f"the controllers (of {', '.join(RIG_CONTROLLERS)}; default "
        f"{' '.join(MAP_CONTROLLERS)})",
    )
    m.add_argument("--tau-end", type=float, default=None, help="run length (default 200)")
    m.add_argument(
        "--braking",
        choices=BRAKING,
        default=None,
        help="the drive's braking: four-quadrant (as rated) or none (torque in [0, R_max]; "
        "default four-quadrant)",
    )
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
            options = ControllerOptions(
                top_drive=args.top_drive,
                Ts=args.Ts,
                window=args.window,
                min_periods=args.min_periods,
                tuning=Tuning(args.impedance, args.soft_speed, args.z_matching),
            )
            constrained = args.constrained
            if constrained is None:
                beside = Path(args.gains).with_name(CONSTRAINED_FILE)
                constrained = beside if beside.is_file() else None
            g = read_gains(args.gains)
            string = string_of_rig(known_rig(g.params), args.elements)
            result = write_controller_comparison(
                args.out,
                g,
                constrained,
                string=string,
                without_braking=not args.braking_only,
                tau_end=args.tau_end,
                options=options,
            )
            print(f"wrote {', '.join(str(p) for p in result.files.values())}")
            return 0
        if args.workers is not None and args.workers < 0:
            print(f"{prog}: --workers must be >= 0, got {args.workers}", file=sys.stderr)
            return 2
        spec_keys = ("controllers", "top_drive", "window", "min_periods", "Ts", "impedance",
                     "soft_speed", "z_matching", "elements", "braking")  # fmt: skip
        changes = {k: getattr(args, k) for k in spec_keys if getattr(args, k) is not None}
        result_map = write_controller_map(
            args.out,
            args.gains,
            constrained_path=args.gains_constrained,
            n=args.n,
            rpm=None if args.rpm is None else tuple(args.rpm),
            wob_kN=None if args.wob is None else tuple(args.wob),
            tau_end=args.tau_end,
            serial=args.workers == 0,
            workers=args.workers or None,
            resume=args.resume,
            progress=not args.no_progress,
            **changes,
        )
        report = result_map.report
        print(f"maps: {report.out_dir / 'plots'}; results: {report.results}")
        return 0
    except (GainsFileError, SweepSpecError, SweepError, ValueError, OSError) as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2
