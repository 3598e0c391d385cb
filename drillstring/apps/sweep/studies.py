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
* ``controllers``: every controller of :data:`~drillstring.controller.lineup.CONTROLLERS` (stiff
  PI, SoftSpeed, Z-Torque, the LMI law with a fixed or a point-wise gain) as a digital law on
  the full model with torsional stick, from dphi/dtau(0) = ``dphi0_rel*omega0``: the severity
  metrics of :mod:`drillstring.analysis.severity` over the late window, and the best controller.

A and taubar_crit of (22) depend on (gammabar, etabar^2) only; :func:`axial_design` computes them
once per distinct pair (the sweep runs it as a separate task that the point tasks depend on).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillstring.analysis.limit_cycles import design_inputs, limit_cycle
from drillstring.analysis.severity import Severity, best_controller, severity_metrics
from drillstring.apps.sweep.metrics import CONTROLLER_METRICS, controller_column
from drillstring.apps.sweep.spec import SweepOptions, SweepSpec
from drillstring.controller.averaged import averaged_model, open_loop_roots
from drillstring.controller.lineup import LmiGain, controller_lineup, lmi_gain
from drillstring.controller.synthesis import SynthesisInfeasible
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import EngineOptions
from drillstring.model.sampled import simulate_sampled
from drillstring.model.simulate import SimulationResult, simulate

__all__ = [
    "DesignInputs",
    "axial_design",
    "axial_metrics",
    "closed_loop_metrics",
    "controllers_metrics",
    "design_key",
    "evaluate_point",
    "open_loop_metrics",
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


def rightmost_nonzero_root(roots: np.ndarray, tol: float = 1e-9) -> complex:
    """Rightmost root after removing the rigid-body root s = 0 of (29).

    In (29) the angle phi enters only as c*(phi(tau - tau_n) - phi(tau)) and through the twist, so
    s = 0 is a root for every parameter set; it is not a torsional instability. The root with the
    smallest modulus is dropped if it is below ``tol``.

    Parameters
    ----------
    roots : ndarray of complex
        Characteristic roots (e.g. :func:`~drillstring.controller.averaged.open_loop_roots`).
    tol : float
        Modulus below which the smallest root counts as s = 0.

    Returns
    -------
    complex
        The root of largest real part, imaginary part taken >= 0; NaN + NaN j if no root
        remains.
    """
    r = np.asarray(roots, dtype=complex)
    if r.size and np.min(np.abs(r)) < tol:
        r = np.delete(r, int(np.argmin(np.abs(r))))
    if r.size == 0:
        return complex(math.nan, math.nan)
    k = int(np.argmax(r.real))
    return complex(r[k].real, abs(r[k].imag))


def _run(params: Any, tau_end: float, control: Any, opts: SweepOptions) -> SimulationResult:
    return simulate(
        params,
        tau_end,
        control=control,
        initial={"dphi": opts["dphi0"]},
        dt_out=opts["dt_out"],
        options=EngineOptions(h=opts["h"], torsional_stick=False, on_invalid="stop"),
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
    params: Any, design: DesignInputs, tau_end: float, opts: SweepOptions
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
    opts : SweepOptions
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
    root = rightmost_nonzero_root(open_loop_roots(model))
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
    params: Any, design: DesignInputs, tau_end: float, opts: SweepOptions
) -> dict[str, Any]:
    """Closed-loop metrics at one point (see the module docstring).

    Parameters
    ----------
    params : ScaledParams
        The point's parameter set.
    design : DesignInputs
        Its axial design inputs.
    tau_end : float
        Run length (scaled).
    opts : SweepOptions
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
    gain = lmi_gain(
        model, opts.gains_file, feedforward=opts["feedforward"], gain_max=opts["gain_max"]
    )
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
        last = res.tau >= res.tau[-1] - opts["window"] - 1e-9
        dphi = res.dphi[last]
        out["dphi_amplitude"] = float(np.max(np.abs(dphi)))
        out["ripple"] = float(np.ptp(dphi))
        out["converged"] = int(out["dphi_amplitude"] < opts["tol"] * abs(opts["dphi0"]))
    else:
        out.update(dphi_amplitude=math.nan, ripple=math.nan, converged=0)
    return out


def controllers_metrics(
    params: Any, design: DesignInputs, tau_end: float, opts: SweepOptions
) -> dict[str, Any]:
    """Severity of every controller at one point (see the module docstring); the controllers
    not selected by the option ``controllers`` get no values.

    A failed LMI design (no admissible gain at the point) is recorded in ``lmi_design_error``
    with the outcome "no_design" for the LMI law; the industrial laws still run, with the
    point's feed-forward R_ff = -K0 (31). See ``docs/controllers.md``, "Maps".

    Parameters
    ----------
    params : ScaledParams
        The point's parameter set.
    design : DesignInputs
        Its axial design inputs.
    tau_end : float
        Run length (scaled), a multiple of ``Ts``.
    opts : SweepOptions
        Options of the controllers study (``controllers``, ``Ts``, ``dphi0_rel``, ``t_on``,
        ``latch``, ``window``, ``gains``, ``feedforward``, ``tie``, ``vibration_tol``, ...).

    Returns
    -------
    dict
        A, taubar_crit, the LMI gain's norm and abscissa (None when ``lmi`` is not run),
        ``lmi_design_error``, one ``<metric>.<controller>`` column per severity metric of each
        selected controller (flags as 0/1) and ``best``
        (:func:`~drillstring.analysis.severity.best_controller`).

    Raises
    ------
    RuntimeError
        The design inputs failed (:meth:`DesignInputs.check`).
    """
    design.check()
    model = averaged_model(params, design.A, design.taubar_crit)
    error = ""
    gains = opts.gains_file
    K0, R_ff = (
        (gains.K0, gains.R_ff)
        if gains is not None and opts["feedforward"] == "file"
        else (model.K0, model.R_ff)
    )
    gain = LmiGain(F=(0.0, 0.0, 0.0, 0.0), K0=K0, R_ff=R_ff, abscissa=math.nan)
    run_lmi = "lmi" in opts["controllers"]
    if run_lmi:
        try:
            gain = lmi_gain(
                model, gains, feedforward=opts["feedforward"], gain_max=opts["gain_max"]
            )
        except SynthesisInfeasible as exc:
            error = _first_line(exc)
    laws = controller_lineup(params, gain, t_on=opts["t_on"], latch=opts["latch"])
    options = EngineOptions(h=opts["h"], torsional_stick=True, on_invalid=opts["on_invalid"])
    out: dict[str, Any] = {
        "A": design.A,
        "taubar_crit": design.taubar_crit,
        "lmi_gain_norm": (math.nan if error else float(np.linalg.norm(gain.F)))
        if run_lmi
        else None,
        "lmi_abscissa": gain.abscissa if run_lmi else None,
        "lmi_design_error": error,
    }
    found: dict[str, Severity] = {}
    for name in opts["controllers"]:
        law = laws[name]
        if name == "lmi" and error:
            nan = math.nan
            sev = Severity(nan, nan, nan, nan, False, "no_design", nan)
        else:
            res = simulate_sampled(
                params,
                law,
                tau_end,
                opts["Ts"],
                initial={"dphi": opts["dphi0_rel"] * params.omega0},
                options=options,
                dt_out=opts["dt_out"],
            )
            sev = severity_metrics(
                res, opts["window"], t_from=opts["t_on"], vibration_tol=opts["vibration_tol"]
            )
        found[name] = sev
        values = sev.to_dict()
        for metric, kind in CONTROLLER_METRICS:
            value = values[metric]
            out[controller_column(metric, name)] = int(value) if kind == "flag" else value
    out["best"] = best_controller(found, tie=opts["tie"])
    return out


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else ''}"


def axial_metrics(gammabar: float, etabar2: float, taubar_n: float, opts: SweepOptions) -> dict:
    """Limit cycle of the fast model (18) at one (gammabar, etabar^2, taubar_n) (Figs. 3-4).

    Parameters
    ----------
    gammabar, etabar2, taubar_n : float
        Fast-model damping, stiffness and delay of (18).
    opts : SweepOptions
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
        lam_over_vbar0=opts["lam_over_vbar0"],
        h=opts["h"],
        kick=opts["kick"],
        max_periods=opts["max_periods"],
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
        return controllers_metrics(params, design, spec.tau_end, spec.options)
    return closed_loop_metrics(params, design, spec.tau_end, spec.options)
