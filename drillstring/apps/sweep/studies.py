"""Point functions of the parameter sweeps: one parameter point -> a dict of metrics.

Every function here is a deterministic function of its arguments (no seeds, no global state other
than a cache of pure results), so a point computed on a Dask worker equals the same point computed
in this process.

* ``open-loop``: the averaged model (29) with R_fb = 0 (its rightmost characteristic root at
  tau_n0, the rigid-body root s = 0 of the bit angle excluded) and the full model (11)-(14), (17)
  from dphi/dtau(0) = ``dphi0`` with the feed-forward only, R - R0 = R_ff = -K0 (31), torsional
  stick model off: does dPhi/dtau reach 0 (and when), the fraction of time in axial stick, bit
  bouncing.
* ``closed-loop``: the gain of Theorem 1 (LMI (33)) designed at the point, or one fixed gains
  file, and the full closed loop (29)-(31) from dphi/dtau(0) = ``dphi0``: convergence, residual
  ripple and the largest torque |R - R0| (Remark 1: the design can fail on the full model).
* ``axial``: the averaged contact force (lambda/vbar0)<gbar>_a of the fast model (18) (Fig. 4).
* ``controllers``: the digital controllers of :func:`~drillstring.controller.lineup.rig_lineup`
  chosen by the option ``controllers`` (stiff PI, SoftSpeed, Z-Torque with the string torque
  from the motor, the paper-style LMI law with a fixed or a point-wise gain, the
  input-constrained LMI law), every one under the same top drive, on the full model with
  torsional stick from dphi/dtau(0) = ``dphi0_rel*omega0``: the severity metrics of
  :mod:`drillstring.analysis.severity` over the late window, the linearised closed loop's
  spectral abscissa, and the best controller. Its runs are :func:`evaluate_controllers`, which
  also runs the Fig. 6-like comparison (:mod:`drillstring.apps.controllers`).

A and taubar_crit of (22) depend on (gammabar, etabar^2) only; :func:`axial_design` computes them
once per distinct pair (the sweep runs it as a separate task that the point tasks depend on).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from drillstring.analysis.limit_cycles import design_inputs, limit_cycle
from drillstring.analysis.severity import Severity, best_controller, severity_metrics
from drillstring.apps.sweep.metrics import CONTROLLER_METRICS, controller_column
from drillstring.apps.sweep.options import (
    AxialOptions,
    ClosedLoopOptions,
    ControllerOptions,
    OpenLoopOptions,
)
from drillstring.apps.sweep.spec import Axis, SweepSpec
from drillstring.controller.averaged import (
    AveragedModel,
    averaged_model,
    delay_roots,
    linearised_ode_matrix,
)
from drillstring.controller.lineup import CONSTRAINED_CONTROLLERS, LmiGain, lmi_gain, rig_lineup
from drillstring.controller.string_spectrum import string_abscissa
from drillstring.controller.synthesis import SynthesisInfeasible
from drillstring.controller.tuning import linear_closed_loop
from drillstring.model.control import AffineFeedback
from drillstring.model.digital.controller import DigitalController
from drillstring.model.engine import EngineOptions, InitialState
from drillstring.model.params import PhysicalParams, ScaledParams
from drillstring.model.pipe import StringParams, string_of_rig
from drillstring.model.sampled import SampledResult, simulate_sampled
from drillstring.model.simulate import SimulationResult, simulate
from drillstring.model.tables import Scales
from drillstring.model.topdrive import TopDrive, top_drive_from_spec
from drillstring.validation import check_int

__all__ = [
    "OPEN_LOOP",
    "DesignInputs",
    "LawRun",
    "LinearBoundary",
    "axial_design",
    "axial_metrics",
    "boundary_model",
    "closed_loop_metrics",
    "controllers_metrics",
    "design_key",
    "evaluate_controllers",
    "evaluate_point",
    "linear_abscissa",
    "linear_boundary",
    "lineup_at",
    "map_top_drive",
    "open_loop_metrics",
    "point_gains",
    "rightmost_nonzero_root",
]

# --------------------------------------------------------------------------------------------
# axial design inputs, once per (gammabar, etabar^2)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class DesignInputs:
    """A and taubar_crit of (22) at (gammabar, etabar^2); ``error`` is set if they failed."""

    gammabar: float
    etabar2: float
    A: float = math.nan
    taubar_crit: float = math.nan
    error: str = ""

    def check(self) -> None:
        """Raise if the design inputs failed; the point cannot be computed without them.

        Raises
        ------
        RuntimeError
            ``error`` is set (the message names gammabar, etabar2 and the error).
        """
        if self.error:
            raise RuntimeError(
                f"axial design inputs at gammabar = {self.gammabar!r}, etabar2 = "
                f"{self.etabar2!r} failed: {self.error}"
            )


def design_key(params: Any) -> tuple[float, float]:
    """The key of the axial design inputs of a parameter set.

    Parameters
    ----------
    params : ScaledParams
        Any object with ``gammabar`` and ``etabar2``.

    Returns
    -------
    tuple of 2 float
        (gammabar, etabar^2) of (18): all that
        :func:`~drillstring.analysis.limit_cycles.design_inputs` reads.
    """
    return (float(params.gammabar), float(params.etabar2))


_DESIGN_CACHE: dict[tuple[float, float], DesignInputs] = {}


def axial_design(params: Any) -> DesignInputs:
    """A and taubar_crit of (22) for ``params``, cached per process by :func:`design_key`.

    The cache uses exact floats: :func:`~drillstring.analysis.limit_cycles.design_inputs`
    depends on nothing else.

    Parameters
    ----------
    params : ScaledParams
        The point's parameter set.

    Returns
    -------
    DesignInputs
        A and taubar_crit, or NaN and ``error`` (the exception's type and message) if the
        computation failed: this function never raises, every point that needs the inputs
        reports the error (:meth:`DesignInputs.check`).
    """
    key = design_key(params)
    if key not in _DESIGN_CACHE:
        try:
            d = design_inputs(params)
            out = DesignInputs(*key, A=float(d.A), taubar_crit=float(d.taubar_crit))
        except Exception as exc:  # recorded and reported by every point that needs it
            out = DesignInputs(*key, error=f"{type(exc).__name__}: {exc}")
        _DESIGN_CACHE[key] = out
    return _DESIGN_CACHE[key]


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------


def rightmost_nonzero_root(roots: np.ndarray) -> complex:
    """Rightmost root after removing the rigid-body root s = 0 of (29).

    In (29) the angle phi enters only as c*(phi(tau - tau_n) - phi(tau)) and through the twist, so
    s = 0 is a root for every parameter set; it is not a torsional instability. The root with the
    smallest modulus is dropped if it is below 1e-9.

    Parameters
    ----------
    roots : ndarray of complex
        Characteristic roots (e.g. :func:`~drillstring.controller.averaged.delay_roots`).

    Returns
    -------
    complex
        The root of largest real part, imaginary part taken >= 0; NaN + NaN j if no root
        remains.
    """
    r = np.asarray(roots, dtype=complex)
    if r.size and np.min(np.abs(r)) < 1e-9:
        r = np.delete(r, int(np.argmin(np.abs(r))))
    if r.size == 0:
        return complex(math.nan, math.nan)
    k = int(np.argmax(r.real))
    return complex(r[k].real, abs(r[k].imag))


def _run(
    params: Any, tau_end: float, control: Any, opts: OpenLoopOptions | ClosedLoopOptions
) -> SimulationResult:
    return simulate(
        params,
        tau_end,
        control=control,
        initial={"dphi": opts.dphi0},
        dt_out=opts.dt_out,
        options=EngineOptions(h=opts.h, torsional_stick=False, on_invalid="stop"),
        progress=False,
    )


def _outcome(result: SimulationResult) -> dict[str, Any]:
    code = result.status.code
    return {
        "torsional_stick": int(code == "torsional_stick"),
        "bit_bounce": int(code == "bit_bounce"),
        "axial_stick_fraction": result.axial_stick_fraction(),
        "status": code,
        "tau_reached": float(result.tau[-1]),
    }


# --------------------------------------------------------------------------------------------
# studies
# --------------------------------------------------------------------------------------------


def open_loop_metrics(
    params: Any, design: DesignInputs, tau_end: float, opts: OpenLoopOptions
) -> dict[str, Any]:
    """Open-loop metrics at one point (see the module docstring).

    Parameters
    ----------
    params : ScaledParams
        The point's parameter set.
    design : DesignInputs
        Its axial design inputs.
    tau_end : float
        Run length (scaled).
    opts : OpenLoopOptions
        ``h``, ``dphi0``, ``dt_out`` of the open-loop study.

    Returns
    -------
    dict
        The open-loop columns of :data:`~drillstring.apps.sweep.metrics.METRICS`: A,
        taubar_crit, R_ff = -K0 (31), the rightmost nonzero root of (29) with R_fb = 0, the
        run's outcome (torsional stick reached and when, axial stick fraction, bit bounce,
        status, tau reached).

    Raises
    ------
    RuntimeError
        The design inputs failed (:meth:`DesignInputs.check`).
    """
    design.check()
    model = averaged_model(params, design.A, design.taubar_crit)
    root = rightmost_nonzero_root(delay_roots(model))
    res = _run(params, tau_end, float(model.R_ff), opts)
    out = {
        "A": design.A,
        "taubar_crit": design.taubar_crit,
        "R_ff": float(model.R_ff),
        "root_real": root.real,
        "root_imag": root.imag,
        **_outcome(res),
    }
    out["time_to_stick"] = res.status.tau if out["torsional_stick"] else math.nan
    return out


def closed_loop_metrics(
    params: Any, design: DesignInputs, tau_end: float, opts: ClosedLoopOptions
) -> dict[str, Any]:
    """Closed-loop metrics at one point (see the module docstring).

    Parameters
    ----------
    params, design, tau_end
        As for :func:`open_loop_metrics`.
    opts : ClosedLoopOptions
        Options of the closed-loop study (``gains``, ``feedforward``, ``gain_max``, ``h``,
        ``dphi0``, ``dt_out``, ``window``, ``tol``).

    Returns
    -------
    dict
        The closed-loop columns of :data:`~drillstring.apps.sweep.metrics.METRICS`: ||F||, the
        closed-loop spectral abscissa at tau_n0, max |R - R0|, and over the late ``window``
        the largest |dphi/dtau| and its peak-to-peak ripple; ``converged`` when that largest
        |dphi/dtau| is below ``tol*|dphi0|`` (NaN and 0 for a run that stopped).

    Raises
    ------
    RuntimeError
        The design inputs failed (:meth:`DesignInputs.check`).
    SynthesisInfeasible
        The LMI (33) has no admissible gain at the point (``gains = "design"``).
    """
    design.check()
    model = averaged_model(params, design.A, design.taubar_crit)
    gain = lmi_gain(model, opts.gains_file, feedforward=opts.feedforward, gain_max=opts.gain_max)
    law = AffineFeedback(F=gain.F, K0=gain.K0, R_ff=gain.R_ff)
    res = _run(params, tau_end, law, opts)
    out = {
        "A": design.A,
        "taubar_crit": design.taubar_crit,
        "gain_norm": float(np.linalg.norm(gain.F)),
        "abscissa_closed": gain.abscissa,
        "max_dR": float(np.max(np.abs(res.R_minus_R0))),
        **_outcome(res),
    }
    if res.status.ok:
        last = res.tau >= res.tau[-1] - opts.window - 1e-9
        dphi = res.dphi[last]
        out["dphi_amplitude"] = float(np.max(np.abs(dphi)))
        out["ripple"] = float(np.ptp(dphi))
        out["converged"] = int(out["dphi_amplitude"] < opts.tol * abs(opts.dphi0))
    else:
        out.update(dphi_amplitude=math.nan, ripple=math.nan, converged=0)
    return out


def map_top_drive(
    value: str, params: ScaledParams, scales: Scales | None, braking: str = "four-quadrant"
) -> TopDrive | None:
    """The top drive of the option ``top_drive`` at a point, with or without braking.

    Parameters
    ----------
    value : str
        ``"none"`` or a spec of :func:`~drillstring.model.topdrive.top_drive_from_spec`
        (``"tds-11sa"``, ``"50R0"``, ``"52kNm"``).
    params : ScaledParams
        The point (its R0 for a multiple of the nominal torque).
    scales : PhysicalParams or None
        The point's rig (C, t*) for a rating or a torque in N m.
    braking : str
        The option ``braking``: "four-quadrant" (the drive as specified) or "none" (its torque
        range cut to [0, R_max]: no torque against the rotation).

    Returns
    -------
    TopDrive or None
        None for ``"none"``.
    """
    if value == "none":
        return None
    drive = top_drive_from_spec(value, params.R0, scales)
    if braking == "none":
        drive = replace(drive, R_min=max(0.0, drive.R_min), braking="none")
    return drive


def _abscissa(M: np.ndarray) -> float:
    """Spectral abscissa of ``M``, the rigid-body root of the bit angle left out exactly: when
    no equation depends on phi (column 0 is zero), the eigenvalues other than that s = 0 are
    those of ``M`` without phi's row and column."""
    if not np.any(M[:, 0]):
        M = M[1:, 1:]
    return float(np.max(np.linalg.eigvals(M).real))


def linear_abscissa(
    model: AveragedModel,
    controller: DigitalController | None,
    string: StringParams | None = None,
) -> float:
    """Spectral abscissa of the torsional model (13), (27) linearised about the point, closed by
    the controller's law in continuous time (:func:`~drillstring.controller.tuning.
    linear_closed_loop`); ``None``: the open loop, R - R0 = R_ff.

    The rigid-body root s = 0 of the bit angle (the PI laws and the open loop do not feed phi
    back) is left out. What the linearisation leaves out: the sampling (Ts), the top drive's
    limits and lag, the axial stick-slip (averaged, (22)); the torque from the motor is the
    string torque there. A law whose bit angle and speed are delayed (telemetry) or estimated
    (observer) gets NaN: its closed loop is not that ODE.

    On the distributed string (``string`` of N > 1 elements) it is the same loop on the
    string the map's runs take: :func:`~drillstring.controller.string_spectrum.string_abscissa`
    with the bit law's delay (the toolkit's delay-equation root finder) and the string torque
    the controller senses (the top element's, or the motor's estimate); NaN where the root
    finder does not find the rigid-body root s = 0 it must leave out (it raises then).

    Parameters
    ----------
    model : AveragedModel
        The averaged model (29)-(31) of the point (c, tau_n0, rho).
    controller : DigitalController or None
        The controller.
    string : StringParams, optional
        The pipe (None: the paper's one-mode model, the ODE (13), (27)).

    Returns
    -------
    float
        The largest real part; < 0: the linearised closed loop is stable.
    """
    if controller is not None and controller.sensing.downhole != "ideal":
        return math.nan
    if string is not None and not string.is_paper:
        law = None if controller is None else controller.law
        torque = (
            "motor" if controller is not None and controller.sensing.torque == "motor" else "top"
        )
        try:
            return string_abscissa(model, law, string, torque=torque, bit="delay")
        except RuntimeError:  # the root finder missed the rigid-body root: no abscissa
            return math.nan
    if controller is None:
        return _abscissa(linearised_ode_matrix(model))
    return _abscissa(linear_closed_loop(model, controller.law))


def point_gains(
    model: AveragedModel,
    opts: ControllerOptions,
    names: tuple[str, ...] | None = None,
    roots: bool = True,
) -> tuple[LmiGain, LmiGain | None, tuple[str, ...], str]:
    """The LMI gains of the controllers study at one point, and the controllers they allow.

    The paper-style LMI gain from the option ``gains`` (or designed at the point) and the
    constrained one from ``gains_constrained``, their K0 and R_ff as ``feedforward`` says. A
    failed design at the point leaves ``lmi`` out (the error is returned).

    Parameters
    ----------
    model : AveragedModel
        The point's averaged model.
    opts : ControllerOptions
        The controllers study's options.
    names : tuple of str, optional
        A subset of the option's controllers.
    roots : bool
        Compute the LMI gains' spectral abscissae at tau_n0 of (29) (False: NaN).

    Returns
    -------
    paper, constrained : LmiGain
        The gains (``constrained`` None when no constrained law is run; ``paper`` without a
        design carries the point's feed-forward only).
    names : tuple of str
        The controllers that can run (``lmi`` left out when its design failed).
    error : str
        The design error of ``lmi`` ("" when none).
    """
    names = tuple(opts.controllers if names is None else names)
    error = ""
    gains = opts.gains_file
    K0, R_ff = (
        (gains.K0, gains.R_ff)
        if gains is not None and opts.feedforward == "file"
        else (model.K0, model.R_ff)
    )
    paper = LmiGain(F=(0.0, 0.0, 0.0, 0.0), K0=K0, R_ff=R_ff, abscissa=math.nan)
    if "lmi" in names:
        try:
            paper = lmi_gain(
                model, gains, feedforward=opts.feedforward, gain_max=opts.gain_max, roots=roots
            )
        except SynthesisInfeasible as exc:
            lines = str(exc).strip().splitlines()
            error = f"{type(exc).__name__}: {lines[0] if lines else ''}"
    constrained = None
    if any(c in CONSTRAINED_CONTROLLERS for c in names):
        constrained = lmi_gain(
            model, opts.constrained_file, feedforward=opts.feedforward, roots=roots
        )
    return paper, constrained, tuple(c for c in names if not (c == "lmi" and error)), error


@dataclass(frozen=True)
class LawRun:
    """One controller's run at a point (:func:`evaluate_controllers`): the controller, its run
    and the run's severity metrics."""

    controller: DigitalController
    result: SampledResult
    severity: Severity


def lineup_at(
    params: ScaledParams,
    model: AveragedModel,
    paper: LmiGain,
    constrained: LmiGain | None,
    opts: ControllerOptions,
    scales: Scales | None,
    names: tuple[str, ...] | None = None,
) -> dict[str, DigitalController]:
    """:func:`~drillstring.controller.lineup.rig_lineup` of ``names`` (default: the option
    ``controllers``), every one under the top drive of the options (:func:`map_top_drive`)
    with their sample period, tuning and switch-on.

    Parameters
    ----------
    params, model, paper, constrained, opts, scales, names
        As for :func:`evaluate_controllers` (``constrained`` None: its laws cannot be asked
        for).

    Returns
    -------
    dict
        Name -> DigitalController.
    """
    return rig_lineup(
        params,
        model,
        paper=paper,
        constrained=constrained,
        top_drive=map_top_drive(opts.top_drive, params, scales, opts.braking),
        scales=scales if scales is not None else _NO_RIG,
        Ts=opts.Ts,
        tuning=opts.tuning,
        t_on=opts.t_on,
        latch=opts.latch,
        names=tuple(opts.controllers if names is None else names),
    )


def evaluate_controllers(
    params: ScaledParams,
    model: AveragedModel,
    paper: LmiGain,
    constrained: LmiGain | None,
    opts: ControllerOptions,
    *,
    tau_end: float,
    initial: InitialState | Mapping[str, float],
    scales: Scales | None,
    string: StringParams | None = None,
    names: tuple[str, ...] | None = None,
) -> dict[str, LawRun]:
    """Every controller of the lineup run from the same state, and its severity metrics: the one
    evaluation of the controllers study's points and of the Fig. 6-like comparison.

    Each controller of :func:`lineup_at` runs as a
    :class:`~drillstring.model.digital.controller.DigitalController` in the sampled loop
    (:func:`~drillstring.model.sampled.simulate_sampled`) from ``initial`` with the
    torsional-stick model on; the metrics are those of
    :func:`~drillstring.analysis.severity.severity_metrics` over the late ``window`` of the
    options (the bit speed averaged over the axial cycle, the trend test against the window
    before, the drive's effort from the switch-on ``t_on``). ``docs/controllers.md``, "Maps" and
    "Fig. 6-like comparison".

    Parameters
    ----------
    params : ScaledParams
        The point's parameter set.
    model : AveragedModel
        Its averaged model (29)-(31).
    paper, constrained : LmiGain
        The paper-style and the input-constrained LMI gains (:func:`~drillstring.controller.
        lineup.lmi_gain`); ``paper.R_ff`` is every law's feed-forward (31).
    opts : ControllerOptions
        Which controllers, under which drive, sampled how, switched on when, measured how.
    tau_end : float
        Run length (scaled), a multiple of ``opts.Ts``.
    initial : mapping
        The engine's initial perturbation (``{"dphi": ...}``).
    scales : PhysicalParams, optional
        The point's rig, for a top drive rated in SI units and the telemetry's seconds.
    string : StringParams, optional
        The drill pipe (None: the paper's one-mode model).
    names : tuple of str, optional
        The controllers (default: ``opts.controllers``).

    Returns
    -------
    dict
        Name -> :class:`LawRun`, in the order of ``names``.
    """
    controllers = lineup_at(params, model, paper, constrained, opts, scales, names)
    engine = EngineOptions(h=opts.h, torsional_stick=True, on_invalid=opts.on_invalid)
    out = {}
    for name, controller in controllers.items():
        result = simulate_sampled(params, controller, tau_end, opts.Ts, initial=initial,
                                  options=engine, dt_out=opts.dt_out, string=string)  # fmt: skip
        severity = severity_metrics(
            result, opts.window, t_from=opts.t_on, vibration_tol=opts.vibration_tol
        )
        out[name] = LawRun(controller, result, severity)
    return out


@dataclass(frozen=True)
class LinearBoundary:
    """The linearised closed loops' spectral abscissae on a grid of a 2-D sweep.

    ``x``, ``y``: the grid values of the two axes; ``abscissa``: name -> array of shape
    ``(x.size, y.size)`` for each controller and ``"open-loop"`` (:func:`linear_abscissa`).
    The stability boundary is its 0 contour.
    """

    x: np.ndarray
    y: np.ndarray
    abscissa: dict[str, np.ndarray]


def boundary_model(elements: int) -> str:
    """What the map's linear overlay is computed on, as its legend says."""
    if elements == 1:
        return "linearised averaged one-mode model (13), (27)"
    return f"linearised averaged bit law (28) with its delay on the {elements}-element string"


#: The name of the open loop (R - R0 = R_ff) in a :class:`LinearBoundary`.
OPEN_LOOP = "open-loop"


def linear_boundary(
    spec: SweepSpec,
    design: DesignInputs,
    refine: int | None = None,
) -> LinearBoundary:
    """:func:`linear_abscissa` of the open loop and of each controller on a grid ``refine``
    times finer than the map's (the same ranges and scales), for the stability boundary.

    The design inputs A, taubar_crit must be those of every point (an rpm x WOB map leaves
    gammabar, etabar^2 as they are). The controllers are the study's, less a law whose gain is
    designed at each point (``gains = "design"``): its boundary is drawn from the map's points.

    Parameters
    ----------
    spec : SweepSpec
        A 2-D controllers sweep.
    design : DesignInputs
        A and taubar_crit of the sweep.
    refine : int, optional
        Intervals of the fine grid per interval of the map's, >= 1 (default 4 on the one-mode
        model; 1 on the distributed string, whose delay-equation roots cost about 40 ms a law
        and a point).

    Returns
    -------
    LinearBoundary

    Raises
    ------
    ValueError
        Not a 2-D controllers sweep, or ``refine`` < 1.
    """
    if spec.study != "controllers" or len(spec.axes) != 2:
        raise ValueError("the linearised boundary is drawn for a 2-D controllers sweep")
    if refine is None:
        refine = 4 if spec.options.elements == 1 else 1
    refine = check_int("refine", refine, lower=1)
    design.check()
    opts = spec.options
    names = tuple(c for c in opts.controllers if not (c == "lmi" and opts.gains_file is None))
    fine = [
        Axis(a.param, a.start, a.stop, refine * (a.num - 1) + 1, a.scale).values()
        for a in spec.axes
    ]
    shape = (fine[0].size, fine[1].size)
    out = {name: np.full(shape, math.nan) for name in (OPEN_LOOP, *names)}
    physical = isinstance(spec.base, PhysicalParams)
    for i, xv in enumerate(fine[0]):
        for j, yv in enumerate(fine[1]):
            values = {spec.axes[0].param: float(xv), spec.axes[1].param: float(yv)}
            params = spec.params_at(values)
            scales = spec.physical_at(values) if physical else spec.point_scales(0)
            model = averaged_model(params, design.A, design.taubar_crit)
            string = string_of_rig(scales, opts.elements)
            out[OPEN_LOOP][i, j] = linear_abscissa(model, None, string)
            paper, constrained, wanted, _ = point_gains(model, opts, names, roots=False)
            controllers = lineup_at(params, model, paper, constrained, opts, scales, wanted)
            for name, c in controllers.items():
                out[name][i, j] = linear_abscissa(model, c, string)
    return LinearBoundary(x=fine[0], y=fine[1], abscissa=out)


@dataclass(frozen=True)
class _Unscaled:
    """The scales of a scaled set of no known rig (only telemetry needs real ones, and the
    spec refuses it there)."""

    C: float = 1.0
    t_star: float = 1.0


_NO_RIG = _Unscaled()


def controllers_metrics(
    params: Any,
    design: DesignInputs,
    tau_end: float,
    opts: ControllerOptions,
    scales: Scales | None = None,
) -> dict[str, Any]:
    """Severity of every controller at one point (see the module docstring); the controllers
    not selected by the option ``controllers`` get no values.

    The controllers run by :func:`evaluate_controllers` from dphi/dtau(0) =
    ``dphi0_rel*omega0``, on the point's rig's pipe as ``elements`` elements; each also gets
    the linearised closed loop's spectral abscissa (:func:`linear_abscissa`). A failed LMI
    design (no admissible gain at the point) is recorded in ``lmi_design_error`` with the
    outcome "no_design" for the LMI law; the other laws still run, with the point's
    feed-forward R_ff = -K0 (31). See ``docs/controllers.md``, "Maps".

    Parameters
    ----------
    params, design, tau_end
        As for :func:`open_loop_metrics` (``tau_end`` a multiple of ``Ts``).
    opts : ControllerOptions
        Options of the controllers study.
    scales : PhysicalParams, optional
        As for :func:`evaluate_controllers`.

    Returns
    -------
    dict
        A, taubar_crit, the open loop's linearised abscissa, the LMI gains' norms and
        abscissae at tau_n0 of (29) (None when not run), ``lmi_design_error``, one
        ``<metric>.<controller>`` column per metric of :data:`~drillstring.apps.sweep.metrics.
        CONTROLLER_METRICS` of each selected controller (flags as 0/1) and ``best``
        (:func:`~drillstring.analysis.severity.best_controller`).

    Raises
    ------
    RuntimeError
        The design inputs failed (:meth:`DesignInputs.check`).
    """
    design.check()
    model = averaged_model(params, design.A, design.taubar_crit)
    names = tuple(opts.controllers)
    paper, constrained, wanted, error = point_gains(model, opts)
    string = string_of_rig(scales, opts.elements)
    runs = evaluate_controllers(
        params, model, paper, constrained, opts, tau_end=tau_end,
        initial={"dphi": opts.dphi0_rel * params.omega0}, scales=scales, string=string,
        names=wanted,
    )  # fmt: skip
    run_lmi = "lmi" in names
    out: dict[str, Any] = {
        "A": design.A,
        "taubar_crit": design.taubar_crit,
        "open_loop_abscissa_scaled": linear_abscissa(model, None, string),
        "lmi_gain_norm": (math.nan if error else float(np.linalg.norm(paper.F)))
        if run_lmi
        else None,
        "lmi_abscissa_scaled": paper.abscissa if run_lmi else None,
        "lmi_design_error": error,
        "lmi_constrained_gain_norm": None
        if constrained is None
        else float(np.linalg.norm(constrained.F)),
        "lmi_constrained_abscissa_scaled": None if constrained is None else constrained.abscissa,
    }
    found: dict[str, Severity] = {}
    for name in names:
        if name not in runs:  # the LMI design failed at the point
            nan = math.nan
            sev = Severity(nan, nan, nan, nan, False, "no_design", nan)
            linear = nan
        else:
            sev = runs[name].severity
            linear = linear_abscissa(model, runs[name].controller, string)
        found[name] = sev
        values = {**sev.to_dict(), "linear_abscissa": linear}
        for metric, kind in CONTROLLER_METRICS:
            value = values[metric]
            out[controller_column(metric, name)] = int(value) if kind == "flag" else value
    out["best"] = best_controller(found, tie=opts.tie)
    return out


def axial_metrics(gammabar: float, etabar2: float, taubar_n: float, opts: AxialOptions) -> dict:
    """Limit cycle of the fast model (18) at one (gammabar, etabar^2, taubar_n) (Figs. 3-4).

    Parameters
    ----------
    gammabar, etabar2, taubar_n : float
        Fast-model damping, stiffness and delay of (18).
    opts : AxialOptions
        ``lam_over_vbar0``, ``h``, ``kick``, ``max_periods`` of the axial study.

    Returns
    -------
    dict
        ``average`` ((lambda/vbar0)<gbar>_a of (22), 0 at the equilibrium), ``period``,
        ``stick_fraction``, ``stick_phases``, ``kind`` (periodic, equilibrium, not_converged,
        invalid) and ``time_simulated`` of
        :func:`~drillstring.analysis.limit_cycles.limit_cycle`.
    """
    lc = limit_cycle(
        gammabar,
        etabar2,
        taubar_n,
        lam_over_vbar0=opts.lam_over_vbar0,
        h=opts.h,
        kick=opts.kick,
        max_periods=opts.max_periods,
        n_samples=0,
    )
    return {
        "average": lc.average,
        "period": lc.period,
        "stick_fraction": lc.stick_fraction,
        "stick_phases": lc.stick_phases,
        "kind": lc.kind,
        "time_simulated": lc.time_simulated,
    }


def evaluate_point(spec: SweepSpec, index: int, design: DesignInputs | None) -> dict[str, Any]:
    """The metrics of point ``index`` of ``spec``: the default point function of a sweep.

    Parameters
    ----------
    spec : SweepSpec
        The sweep; its study selects :func:`axial_metrics`, :func:`open_loop_metrics`,
        :func:`closed_loop_metrics` or :func:`controllers_metrics`.
    index : int
        Row-major point index.
    design : DesignInputs or None
        The point's axial design inputs (:func:`axial_design`); None for the axial study.

    Returns
    -------
    dict
        Metric name -> value, the study's columns of
        :data:`~drillstring.apps.sweep.metrics.METRICS`.

    Raises
    ------
    ValueError
        ``design`` is None for a full-model study.
    IndexError
        ``index`` is outside the sweep.
    """
    if spec.study == "axial":
        return axial_metrics(*spec.axial_point(index), spec.options)
    if design is None:
        raise ValueError(f"the {spec.study} study needs the axial design inputs of the point")
    params = spec.point_params(index)
    if spec.study == "open-loop":
        return open_loop_metrics(params, design, spec.tau_end, spec.options)
    if spec.study == "controllers":
        return controllers_metrics(
            params, design, spec.tau_end, spec.options, scales=spec.point_scales(index)
        )
    return closed_loop_metrics(params, design, spec.tau_end, spec.options)
