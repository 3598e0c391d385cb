"""FMI 2.0 co-simulation unit of the torsional controller (pythonfmu script of
``TorsionalController``).

Output ``R_minus_R0 = R_ff + F x`` with ``x = [phi - phi_ref, dphi, phi - theta - K0 - twist_ref,
dtheta]``, the state feedback with feed-forward of Section V, eqs. (29)-(31), evaluated by
:func:`drillstring.model.control.feedback_torque` (the same function the monolithic solver uses; no
control code lives here). Before ``t_on`` only ``R_ff`` acts (the paper's Fig. 6). Bumpless
switch-on (NOTES.md section 7, our reconstruction): at the first communication point at or after
``t_on`` the controller takes the measured angle as its reference, ``phi_ref = phi`` (``latch`` =
"angle"), and with ``latch`` = "angle+twist" also ``twist_ref = phi - theta - K0``; ``latch`` =
"none" is the paper's law. Until that point has been stepped from, outputs at or after ``t_on``
use the current inputs as references (so ``x1 = 0`` at switch-on whatever order the master uses).

The output depends directly on the inputs (declared in ``ModelStructure`` by ``build_fmus.py``);
the FMU has no dynamics, its state is the time, the inputs, the parameters and the latch.
Start values of ``F``, ``K0``, ``R_ff`` come from the gains file of the synthesis, baked in by
``build_fmus.py``. Errors are logged and refused like in the plant FMU.
"""

from __future__ import annotations

import math
from typing import Any

import drillstring_fmu_support as support
from pythonfmu import (
    Boolean,
    DefaultExperiment,
    Fmi2Causality,
    Fmi2Initial,
    Fmi2Slave,
    Fmi2Variability,
    Real,
    String,
)
from pythonfmu.enums import Fmi2Status

from drillstring.model.control import (
    LATCH_MODES,
    AffineFeedback,
    feedback_torque,
    switch_on_references,
)

MODEL = "TorsionalController"
INPUTS: tuple[tuple[str, str], ...] = (
    ("phi", "Measured bit angle perturbation phi (plant output)"),
    ("dphi", "Measured bit angular velocity perturbation dphi/dtau (plant output)"),
    ("theta", "Measured rotary-table angle perturbation theta (plant output)"),
    ("dtheta", "Measured rotary-table angular velocity perturbation dtheta/dtau (plant output)"),
)
GAIN_NAMES = ("F[1]", "F[2]", "F[3]", "F[4]")
#: ModelStructure (written by build_fmus.py): the output depends directly on all four inputs.
OUTPUT_DEPENDENCIES: dict[str, tuple[str, ...]] = {"R_minus_R0": tuple(n for n, _ in INPUTS)}


class TorsionalController(support.GuardedAccessors, Fmi2Slave):
    """State feedback with feed-forward R - R0 = R_ff + F x of Section V, eqs. (29)-(31)."""

    author = "drillstring project"
    license = "MIT"
    description = (
        "Torsional stick-slip controller R - R0 = R_ff + F x of Besselink, van de Wouw and "
        "Nijmeijer (IEEE CCA 2011), Section V, eqs. (29)-(31), with bumpless switch-on at t_on"
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=0.01)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        config = support.read_config(self.resources)
        self.version = str(config.get("version", "unknown"))
        self._exit_guard = support.guard_process_exit(self.resources, MODEL)
        gains = config["gains"]

        self._par: dict[str, Any] = {
            name: float(v) for name, v in zip(GAIN_NAMES, gains["F"], strict=True)
        }
        self._par["K0"] = float(gains["K0"])
        self._par["R_ff"] = float(gains["R_ff"])
        self._par["t_on"] = 0.0
        self._par["enabled"] = True
        self._par["latch"] = "angle"
        self._in = {name: 0.0 for name, _ in INPUTS}
        self._time = 0.0
        self._latched = False
        self._phi_ref = 0.0
        self._twist_ref = 0.0

        self._phase = "instantiated"
        self._param_errors: dict[str, str] = {}
        self._input_errors: dict[str, str] = {}
        self._call_error: str | None = None
        self._register(gains.get("source", "unknown"))

    # ----------------------------------------------------------------- variables
    def _register(self, source: str) -> None:
        par, fixed, exact = Fmi2Causality.parameter, Fmi2Variability.fixed, Fmi2Initial.exact
        for name, desc in INPUTS:
            self.register_variable(
                Real(
                    name,
                    causality=Fmi2Causality.input,
                    variability=Fmi2Variability.continuous,
                    description=desc,
                    getter=lambda key=name: self._in[key],
                    setter=lambda value, key=name: self._set_input(key, value),
                )
            )
        self.register_variable(
            Real(
                "R_minus_R0",
                causality=Fmi2Causality.output,
                variability=Fmi2Variability.continuous,
                initial=Fmi2Initial.calculated,
                description="Rotary-table torque deviation R - R0 = R_ff + F x (eqs. (29)-(31))",
                getter=self._output,
            )
        )
        labels = ("phi - phi_ref", "dphi", "phi - theta - K0 - twist_ref", "dtheta")
        params: list[tuple[type, str, str]] = [
            (Real, name, f"State-feedback gain on x{i + 1} = {label} (synthesis, from {source})")
            for i, (name, label) in enumerate(zip(GAIN_NAMES, labels, strict=True))
        ]
        params += [
            (Real, "K0", f"Nominal twist offset K0 of x3 (eq. (30)), from {source}"),
            (Real, "R_ff", f"Feed-forward torque R_ff = -K0 (eq. (31)), from {source}"),
            (Real, "t_on", "Switch-on time of the feedback: only R_ff acts before it (Fig. 6)"),
            (Boolean, "enabled", "Feedback enabled; false: R - R0 = R_ff at all times"),
            (
                String,
                "latch",
                f"Bumpless switch-on, one of {', '.join(LATCH_MODES)} (NOTES.md section 7): "
                "'angle' takes phi_ref = phi at t_on, 'angle+twist' also twist_ref = "
                "phi - theta - K0, 'none' is the paper's law",
            ),
        ]
        for kind, name, desc in params:
            self.register_variable(
                kind(
                    name,
                    causality=par,
                    variability=fixed,
                    initial=exact,
                    description=desc,
                    getter=lambda key=name: self._par[key],
                    setter=lambda value, key=name: self._set_parameter(key, value),
                )
            )

    # ----------------------------------------------------------------- law
    def _law(self) -> AffineFeedback:
        """The law's parameters, validated like the Python API (AffineFeedback)."""
        return AffineFeedback(
            F=tuple(self._par[name] for name in GAIN_NAMES),  # type: ignore[arg-type]
            K0=self._par["K0"],
            R_ff=self._par["R_ff"],
            t_on=self._par["t_on"],
            latch=self._par["latch"],
        )

    def _candidate_references(self) -> tuple[float, float]:
        phi_ref, twist_ref = switch_on_references(
            LATCH_MODES.index(self._par["latch"]),
            float(self._in["phi"]),
            float(self._in["theta"]),
            float(self._par["K0"]),
        )
        return float(phi_ref), float(twist_ref)

    def _active(self) -> bool:
        return bool(self._par["enabled"]) and self._time >= self._par["t_on"]

    def _output(self) -> float:
        if self._latched:
            phi_ref, twist_ref = self._phi_ref, self._twist_ref
        else:
            phi_ref, twist_ref = self._candidate_references()
        t_on = float(self._par["t_on"]) if self._par["enabled"] else math.inf
        F = tuple(float(self._par[name]) for name in GAIN_NAMES)
        return float(
            feedback_torque(
                float(self._time),
                float(self._in["phi"]),
                float(self._in["dphi"]),
                float(self._in["theta"]),
                float(self._in["dtheta"]),
                F,
                float(self._par["K0"]),
                float(self._par["R_ff"]),
                t_on,
                float(phi_ref),
                float(twist_ref),
            )
        )

    # ----------------------------------------------------------------- setters
    def _set_input(self, name: str, value: Any) -> None:
        if not support.is_finite_real(value):
            self._input_errors[name] = f"input {name} must be a finite number, got {value!r}"
            self._error(f"{self._input_errors[name]}; the value is rejected and fmi2DoStep refused")
            return
        self._in[name] = float(value)
        self._input_errors.pop(name, None)

    def _set_parameter(self, name: str, value: Any) -> None:
        if self._phase not in ("instantiated", "initialization"):
            self._call_error = (
                f"parameter {name} is fixed: it cannot be set after initialization (got {value!r})"
            )
            self._error(self._call_error)
            return
        self._par[name] = value
        self._param_errors.pop(name, None)
        if name == "enabled":
            return
        try:
            self._law()
        except (ValueError, TypeError) as exc:
            self._param_errors[name] = str(exc)
            self._error(f"bad parameter {name} = {value!r}: {exc}")

    def _blocking_error(self) -> str | None:
        if self._call_error is not None:
            return self._call_error
        for errors in (self._param_errors, self._input_errors):
            if errors:
                return "; ".join(f"{k}: {v}" for k, v in sorted(errors.items()))
        return None

    # ----------------------------------------------------------------- FMI life cycle
    def setup_experiment(self, start_time: float, stop_time: Any = None, tolerance: Any = None):
        if support.is_finite_real(start_time):
            self._time = float(start_time)
        else:
            self._call_error = f"start time must be a finite number, got {start_time!r}"
            self._error(self._call_error)

    def enter_initialization_mode(self) -> None:
        self._phase = "initialization"

    def exit_initialization_mode(self) -> None:
        if self._param_errors:
            self._error(f"fmi2ExitInitializationMode: invalid parameters: {self._blocking_error()}")
        self._phase = "stepping"

    def terminate(self) -> None:
        self._phase = "terminated"

    def do_step(self, current_time: float, step_size: float) -> bool:
        try:
            return self._do_step(current_time, step_size)
        except Exception as exc:  # never let pythonfmu turn an exception into fmi2Fatal
            self._call_error = f"fmi2DoStep({current_time!r}, {step_size!r}) failed: {exc!r}"
            self._error(self._call_error)
            return False

    def _do_step(self, t: float, h: float) -> bool:
        if self._phase != "stepping":
            what = "before initialization" if self._phase != "terminated" else "after fmi2Terminate"
            return self._discard(f"fmi2DoStep called {what} (state: {self._phase})")
        problem = self._blocking_error()
        if problem is not None:
            return self._discard(f"fmi2DoStep refused: {problem}")
        if not (math.isfinite(t) and math.isfinite(h)):
            return self._discard(f"fmi2DoStep: time and step must be finite, got t={t!r}, h={h!r}")
        if h <= 0.0:
            return self._discard(f"fmi2DoStep: step size must be > 0, got {h!r} at t = {t!r}")
        if abs(t - self._time) > 1e-9 * max(1.0, abs(self._time)):
            return self._discard(
                f"fmi2DoStep: communication point t = {t!r} is not the FMU's time {self._time!r}"
            )
        self._time = t
        if not self._latched and self._active():
            self._phi_ref, self._twist_ref = self._candidate_references()
            self._latched = True
        self._time = t + h
        return True

    # ----------------------------------------------------------------- logging
    def _error(self, msg: str) -> None:
        self.log(msg, Fmi2Status.error)

    def _discard(self, msg: str) -> bool:
        self.log(msg, Fmi2Status.discard)
        return False

    # ----------------------------------------------------------------- FMU state
    def _fields(self) -> dict[str, Any]:
        return {
            "par": dict(self._par),
            "in": dict(self._in),
            "time": self._time,
            "latched": self._latched,
            "phi_ref": self._phi_ref,
            "twist_ref": self._twist_ref,
            "phase": self._phase,
            "param_errors": dict(self._param_errors),
            "input_errors": dict(self._input_errors),
            "call_error": self._call_error,
        }

    def _get_fmu_state(self) -> ControllerState:
        return ControllerState(self._fields())

    def _set_fmu_state(self, state: Any) -> None:
        try:
            if not isinstance(state, ControllerState):
                raise TypeError(f"not a {MODEL} state: {type(state).__name__}")
            if state.error is not None:
                raise ValueError(state.error)
            f = state.fields
            self._par = dict(f["par"])
            self._in = dict(f["in"])
            self._time = f["time"]
            self._latched = f["latched"]
            self._phi_ref = f["phi_ref"]
            self._twist_ref = f["twist_ref"]
            self._phase = f["phase"]
            self._param_errors = dict(f["param_errors"])
            self._input_errors = dict(f["input_errors"])
            self._call_error = f["call_error"]
        except Exception as exc:
            self._call_error = f"fmi2SetFMUstate failed: {exc}"
            self._error(self._call_error)

    @staticmethod
    def _fmu_state_to_bytes(state: ControllerState) -> bytes:
        return support.pack_state(MODEL, state.fields)

    @staticmethod
    def _fmu_state_from_bytes(data: bytes) -> ControllerState:
        try:
            fields, _ = support.unpack_state(MODEL, data)
        except support.StateError as exc:
            return ControllerState({}, error=f"cannot deserialize FMU state: {exc}")
        return ControllerState(fields)


class ControllerState:
    """An FMU state of the controller: all of its variables (it has no dynamics)."""

    __slots__ = ("error", "fields")

    def __init__(self, fields: dict[str, Any], error: str | None = None) -> None:
        self.fields = fields
        self.error = error
