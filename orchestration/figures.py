"""The paper's closed-loop figures by co-simulation, with the monolithic solver overlaid.

* Fig. 5 (:func:`write_fig5`): controller (29)-(31) on from tau = 0, dphi/dtau(0) = -2.5: the
  torsional vibration dies out while axial stick-slip goes on; du/dtau and dphi/dtau against tau.
* Fig. 6 (:func:`write_fig6`): torsional-stick model on in the plant (``docs/model.md``,
  "Torsional stick"), open loop (R_ff only) from dphi/dtau(0) = -4.9 until the torsional
  stick-slip is under way, the controller switched on at tau = 25 with the bumpless latch
  "angle" (``docs/model.md``, "Bumpless switch-on"): no torsional stick afterwards, dphi/dtau
  back to a small ripple, d >= 0 throughout.

The set-ups are :data:`~drillstring.model.experiments.FIG5` and
:data:`~drillstring.model.experiments.FIG6` (``docs/model.md``, "Experiments of Figs. 5 and
6"). Both figures co-simulate the plant and controller FMUs on the fmpy master (:mod:`.master`,
fixed macro step H) and run the monolithic twin (:mod:`.monolithic`: the loop the FMUs describe,
same gains, parameters and engine step, sampled at the same communication points) for
comparison. Each writes a PNG and a CSV into ``out_dir`` and returns a flat summary dict (paths,
errors, checks).

Default coupling: Jacobi with linear extrapolation (second order in H). Zero-order hold, the
master's default, is first order: at H = 1e-3 its max error in dphi/dtau over Fig. 5 is 1e-3 to
2e-3 of the initial deviation (depending on the gains) against about 1e-5 with linear
extrapolation (``drillstring crosscheck``). In Fig. 6 both are about 1e-3: the torque jumps at
the switch-on, and an extrapolated line across a jump is only first order for that step.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from drillstring.analysis.severity import actuator_demand
from drillstring.fileio import write_csv
from drillstring.model.control import AffineFeedback
from drillstring.model.experiments import FIG5, FIG6, Experiment
from drillstring.model.params import ScaledParams, known_rig
from drillstring.model.simulate import SimulationResult
from drillstring.model.topdrive import RPM, TDS_11SA, top_drive
from drillstring.orchestration.closed_loop import (
    LoopModel,
    Overrides,
    closed_loop_master,
    grid_indices,
    loop_model_of,
    run_cosim,
)
from drillstring.orchestration.monolithic import run_monolithic
from drillstring.orchestration.results import CosimResult
from drillstring.plotting import plot_velocities

__all__ = ["FIG6_RIPPLE", "actuator_note", "run_pair", "write_fig5", "write_fig6"]

#: Fig. 6: max |dphi/dtau| over the last 10 time units below this fraction of |dphi/dtau(0)|
FIG6_RIPPLE = 0.05
_CSV_HEADER = (
    "tau",
    "du_cosim",
    "dphi_cosim",
    "R_minus_R0_cosim",
    "d_cosim",
    "torsional_stick_count_cosim",
    "du_monolithic",
    "dphi_monolithic",
)
_SCHEME_LABEL = {"jacobi": "Jacobi", "gauss-seidel": "Gauss-Seidel"}
_EXTRAP_LABEL = {"zoh": "ZOH", "linear": "linear extrapolation"}


def _check_H(H: float, h: float, tau_end: float) -> None:
    if not (isinstance(H, int | float) and math.isfinite(H) and H > 0):
        raise ValueError(f"macro step H must be a positive finite number, got {H!r}")
    k = round(H / h)
    if k < 1 or abs(k * h - H) > 1e-9 * H:
        raise ValueError(f"macro step H = {H!r} must be a multiple of the engine step h = {h!r}")
    n = round(tau_end / H)
    if n < 1 or abs(n * H - tau_end) > 1e-9 * tau_end:
        raise ValueError(f"tau_end = {tau_end!r} must be a multiple of the macro step H = {H!r}")


def run_pair(
    fmus_dir: str | os.PathLike[str],
    experiment: Experiment,
    H: float,
    *,
    scheme: str = "jacobi",
    extrapolation: str = "linear",
    overrides: Overrides | None = None,
    check: Callable[[LoopModel], None] | None = None,
) -> tuple[CosimResult, SimulationResult, dict[str, Any], LoopModel]:
    """Co-simulation (fixed step H) and monolithic twin of one closed-loop experiment.

    Parameters
    ----------
    fmus_dir : path
        Folder of the built FMUs and packages (their gains and parameter set are used).
    experiment : Experiment
        The set-up, run over ``[0, experiment.tau_end]``.
    H : float
        Macro step, a multiple of the engine step that divides ``tau_end``.
    scheme, extrapolation : str
        Coupling of the master.
    overrides : mapping, optional
        ``"unit.variable"`` -> start value, for both runs.
    check : callable, optional
        Called with the loop before either run (raises to refuse it).

    Returns
    -------
    cosim : CosimResult
        The co-simulation.
    mono : SimulationResult
        The monolithic twin sampled every H.
    summary : dict
        Steps, wall times, max |difference| of du/dtau and dphi/dtau over the common
        communication points, the co-simulation's failure if any; what the run asks of the
        actuator and the note that says so (``actuator``, ``assumes``: :func:`actuator_note`).
    model : LoopModel
        The loop both ran (:func:`~.closed_loop.loop_model_of`).

    Raises
    ------
    ValueError
        Missing FMUs or package, bad start values, or an ``H`` that is not a multiple of the
        engine step or does not divide ``tau_end``.
    """
    tau_end = experiment.tau_end
    with closed_loop_master(fmus_dir, experiment, overrides=overrides) as master:
        model = loop_model_of(master)
        _check_H(H, model.options.h, tau_end)
        if check is not None:
            check(model)
        cos = run_cosim(master, tau_end, H, scheme=scheme, extrapolation=extrapolation)
    w0 = time.perf_counter()
    mono = run_monolithic(model, tau_end, dt_out=H)
    mono_wall = time.perf_counter() - w0
    n = min(len(cos.time), len(mono.tau))
    k = grid_indices(cos.time[:n], H, len(mono.tau))
    diff = {
        name: float(np.max(np.abs(cos[f"plant.{name}"][:n] - getattr(mono, name)[k])))
        for name in ("du", "dphi")
    }
    actuator, assumes = actuator_note(model.params, mono)
    dphi0 = model.initial.dphi
    summary: dict[str, Any] = {
        "experiment": experiment.name,
        "H": H,
        "scheme": scheme,
        "extrapolation": extrapolation,
        "tau_end": tau_end,
        "engine_h": model.options.h,
        "dphi0": dphi0,
        "steps": cos.stats.accepted,
        "cosim_completed": cos.completed,
        "cosim_failure": None if cos.completed else str(cos.failure),
        "monolithic_completed": mono.status.ok,
        "cosim_wall_s": cos.stats.wall_time,
        "monolithic_wall_s": mono_wall,
        "max_abs_diff_du": diff["du"],
        "max_abs_diff_dphi": diff["dphi"],
        "max_abs_diff_dphi_rel": diff["dphi"] / abs(dphi0) if dphi0 else math.nan,
        "actuator": actuator,
        "assumes": assumes,
    }
    return cos, mono, summary, model


def _write_outputs(
    out_dir: Path,
    name: str,
    cos: CosimResult,
    mono: SimulationResult,
    summary: dict[str, Any],
    title: str,
    t_on: float | None,
    csv_dt: float | None,
) -> dict[str, Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    H = summary["H"]
    label = (
        f"co-simulation ({_SCHEME_LABEL[summary['scheme']]}, "
        f"{_EXTRAP_LABEL[summary['extrapolation']]}, H = {H:g})"
    )
    cos_view = SimpleNamespace(tau=cos.time, du=cos["plant.du"], dphi=cos["plant.dphi"])
    png = plot_velocities(
        out_dir / f"{name}.png",
        [(label, cos_view), ("monolithic (law evaluated continuously)", mono)],
        title=title,
        t_on=t_on,
    )
    n = min(len(cos.time), len(mono.tau))
    every = 1 if csv_dt is None else max(1, round(csv_dt / H))
    rows = [*range(0, n - 1, every), n - 1]  # the last point always
    k = grid_indices(cos.time[:n], H, len(mono.tau))
    cols = (
        cos.time,
        cos["plant.du"],
        cos["plant.dphi"],
        cos["controller.R_minus_R0"],
        cos["plant.d"],
        cos["plant.torsional_stick"],
        mono.du[k],
        mono.dphi[k],
    )
    csv = write_csv(
        out_dir / f"{name}.csv",
        _CSV_HEADER,
        (
            [*(float(c[i]) for c in cols[:5]), int(cols[5][i]), *(float(c[i]) for c in cols[6:])]
            for i in rows
        ),
    )
    return {"png": png, "csv": csv}


def actuator_note(params: ScaledParams, run: SimulationResult) -> tuple[dict[str, Any], str]:
    """What the paper's set-up asks of the top drive over a run, and the line that says so on
    its figure.

    The paper's loop has an ideal actuator (any torque, power and table speed at once) and
    measures the downhole bit angle and speed exactly at every step. The figure states it, with
    the torque, power and table speed the run needed (:func:`~drillstring.analysis.severity.
    actuator_demand`) and, on a known rig, whether a real top drive (:data:`~drillstring.model.
    topdrive.TDS_11SA`) delivers them (``docs/controllers.md``).

    Returns
    -------
    summary : dict
        ``peak_torque_over_R0``, ``min_torque_over_R0``; on a known rig also the SI demand
        (``peak_torque_Nm``, ``min_torque_Nm``, ``peak_power_W``, ``table_speed_rpm``) and
        ``within_tds_11sa``.
    line : str
        The figure's note.
    """
    d = actuator_demand(run.tau, run.R_minus_R0, run.dtheta, params.R0, params.omega0)
    out: dict[str, Any] = {
        "peak_torque_over_R0": d.peak_torque / params.R0,
        "min_torque_over_R0": d.min_torque / params.R0,
    }
    line = (
        "assumes the paper's ideal actuator and exact downhole bit angle and speed:\n"
        f"R/R0 from {out['min_torque_over_R0']:.0f} to {out['peak_torque_over_R0']:.0f}"
    )
    rig = known_rig(params)
    if rig is not None:
        si = d.to_si(rig.C, rig.t_star)
        within = d.within(top_drive(TDS_11SA, rig))
        speeds = (si["min_table_speed"] / RPM, si["max_table_speed"] / RPM)
        out.update(
            peak_torque_Nm=si["peak_torque"],
            min_torque_Nm=si["min_torque"],
            peak_power_W=si["peak_power"],
            table_speed_rpm=speeds,
            within_tds_11sa=within,
        )
        line += (
            f" ({si['min_torque'] / 1e3:.0f} to {si['peak_torque'] / 1e3:.0f} kN m), "
            f"{si['peak_power'] / 1e6:.3g} MW, table {speeds[0]:.0f} to {speeds[1]:.0f} rpm,\n"
            f"{'within' if within else 'beyond'} a {TDS_11SA.name} ({TDS_11SA.torque / 1e3:.3g} "
            f"kN m, {TDS_11SA.power / 1e3:.0f} kW, 0-{TDS_11SA.max_speed / RPM:.0f} rpm)"
        )
    return out, line


def _late_max(t: np.ndarray, y: np.ndarray, t0: float) -> float:
    sel = t >= t0 - 1e-9
    return float(np.max(np.abs(y[sel]))) if np.any(sel) else math.nan


def write_fig5(
    out_dir: str | os.PathLike[str],
    fmus_dir: str | os.PathLike[str],
    H: float = 1e-3,
    *,
    experiment: Experiment = FIG5,
    scheme: str = "jacobi",
    extrapolation: str = "linear",
    csv_dt: float | None = 1e-2,
    overrides: Overrides | None = None,
) -> dict[str, Any]:
    """Fig. 5 by co-simulation: ``fig5.png`` and ``fig5.csv`` in ``out_dir``.

    Parameters
    ----------
    out_dir : path
        Output folder.
    fmus_dir : path
        Folder of the built FMUs.
    H : float
        Macro step.
    experiment : Experiment
        The set-up (default :data:`~drillstring.model.experiments.FIG5`).
    scheme, extrapolation : str
        Coupling of the master.
    csv_dt : float or None
        Sampling of the CSV (None: every communication point).
    overrides : mapping, optional
        ``"unit.variable"`` -> start value, for both runs.

    Returns
    -------
    dict
        Paths ``png`` and ``csv``, :func:`run_pair`'s summary, max |dphi/dtau| over the last
        10 time units of both runs, min d and the axial stick entries of the co-simulation.
    """
    cos, mono, summary, _ = run_pair(
        fmus_dir, experiment, H, scheme=scheme, extrapolation=extrapolation, overrides=overrides
    )
    tau_end = experiment.tau_end
    late = max(0.0, tau_end - 10.0)
    summary["late_window"] = (late, tau_end)
    summary["late_max_abs_dphi_cosim"] = _late_max(cos.time, cos["plant.dphi"], late)
    summary["late_max_abs_dphi_monolithic"] = _late_max(mono.tau, mono.dphi, late)
    summary["min_d_cosim"] = float(np.min(cos["plant.d"]))
    summary["axial_stick_events_cosim"] = int(cos["plant.stick_events"][-1])
    title = (
        rf"Fig. 5: closed loop from $\dot\varphi(0) = {summary['dphi0']:g}$"
        + "\n"
        + summary["assumes"]
    )
    paths = _write_outputs(Path(out_dir), "fig5", cos, mono, summary, title, None, csv_dt)
    return {**paths, **summary}


def write_fig6(
    out_dir: str | os.PathLike[str],
    fmus_dir: str | os.PathLike[str],
    H: float = 1e-3,
    *,
    experiment: Experiment = FIG6,
    scheme: str = "jacobi",
    extrapolation: str = "linear",
    csv_dt: float | None = 1e-2,
    overrides: Overrides | None = None,
) -> dict[str, Any]:
    """Fig. 6 by co-simulation: ``fig6.png`` and ``fig6.csv`` in ``out_dir``.

    Parameters
    ----------
    out_dir, fmus_dir, H, scheme, extrapolation, csv_dt, overrides
        As for :func:`write_fig5`.
    experiment : Experiment
        The set-up (default :data:`~drillstring.model.experiments.FIG6`); the feedback must be
        enabled and switched on inside the run.

    Returns
    -------
    dict
        Besides :func:`run_pair`'s summary: torsional-stick entries before and after ``t_on``
        (co-simulation: the plant's counter ``torsional_stick`` at the communication point
        ``t_on`` and at the end; monolithic: its events), the plant's mode after ``t_on``
        (never 3 = torsional stick), min d and bit-bounce count (the plant stops on bit
        bouncing), max |dphi/dtau| over the last 10 time units and ``suppressed``: all of
        the paper's claims hold (entries before ``t_on``, none after, d >= 0, late ripple
        below ``FIG6_RIPPLE`` |dphi0|).

    Raises
    ------
    ValueError
        If the controller is not switched on inside ``(0, tau_end)``.
    """
    tau_end = experiment.tau_end

    def switched_on_inside(model: LoopModel) -> None:
        law = model.control
        if not isinstance(law, AffineFeedback):
            raise ValueError(f"Fig. 6 needs the feedback enabled (experiment {experiment.name!r})")
        if not 0 < law.t_on < tau_end:
            raise ValueError(f"t_on must lie inside (0, tau_end = {tau_end!r}), got {law.t_on!r}")

    cos, mono, summary, model = run_pair(
        fmus_dir, experiment, H, scheme=scheme, extrapolation=extrapolation, overrides=overrides,
        check=switched_on_inside,
    )  # fmt: skip
    law = model.control
    assert isinstance(law, AffineFeedback)
    t_on = law.t_on
    dphi0 = summary["dphi0"]
    t = cos.time
    count = cos["plant.torsional_stick"]
    on = t <= t_on + 1e-9 * max(1.0, t_on)
    before = int(count[on][-1])
    after = int(count[-1]) - before
    mono_starts = [e.tau for e in mono.events if e.to_mode == "torsional_stick"]
    late = max(t_on, tau_end - 10.0)
    ripple = _late_max(t, cos["plant.dphi"], late)
    summary.update(
        t_on=t_on,
        latch=law.latch,
        torsional_stick_before_t_on_cosim=before,
        torsional_stick_after_t_on_cosim=after,
        torsional_stick_mode_after_t_on_cosim=bool(np.any(cos["plant.mode"][~on] == 3)),
        torsional_stick_before_t_on_monolithic=sum(1 for s in mono_starts if s <= t_on),
        torsional_stick_after_t_on_monolithic=sum(1 for s in mono_starts if s > t_on),
        min_d_cosim=float(np.min(cos["plant.d"])),
        min_d_monolithic=float(np.min(mono.d)),
        bit_bounce_cosim=int(cos["plant.bit_bounce"][-1]),
        late_window=(late, tau_end),
        late_max_abs_dphi_cosim=ripple,
        late_max_abs_dphi_monolithic=_late_max(mono.tau, mono.dphi, late),
        ripple_limit=FIG6_RIPPLE * abs(dphi0),
    )
    summary["suppressed"] = bool(
        cos.completed
        and before >= 1
        and after == 0
        and not summary["torsional_stick_mode_after_t_on_cosim"]
        and summary["min_d_cosim"] >= 0.0
        and summary["bit_bounce_cosim"] == 0
        and ripple < summary["ripple_limit"]
    )
    title = (
        rf"Fig. 6: torsional stick-slip from $\dot\varphi(0) = {dphi0:g}$, "
        rf"controller on at $\tau = {t_on:g}$" + "\n" + summary["assumes"]
    )
    paths = _write_outputs(Path(out_dir), "fig6", cos, mono, summary, title, t_on, csv_dt)
    return {**paths, **summary}
