"""FMI 2.0 co-simulation unit of the drill-string plant (pythonfmu script of ``DrillStringPlant``).

Wraps :class:`drillstring.model.engine.Engine`, the scaled axial-torsional model (11)-(14) of
Besselink, van de Wouw and Nijmeijer (IEEE CCA 2011) with the Filippov contact law (17) and the
state-dependent delay (14). No model code lives here: the ``drillstring`` package is bundled into
the FMU's ``resources/`` by ``build_fmus.py``. ``fmi2DoStep(t, h)`` holds the input ``R_minus_R0``
over the step and advances the engine to ``t + h``; the engine locates the events inside the
step, so communication points never have to land on an event.

Errors never escape as Python exceptions (pythonfmu turns those into ``fmi2Fatal``): a bad value
is logged at once with status ``fmi2Error`` and every following ``fmi2DoStep`` is refused with
``fmi2Discard`` and a log message until the cause is gone (see ``docs/fmu_usage.md``).

The FMU state (``fmi2GetFMUstate``/``fmi2SerializeFMUstate``) is the whole engine (history
buffer, axial mode, counters, integrator state) plus the FMU's own variables; restoring it is bit
exact.
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
    Integer,
    Real,
    String,
)
from pythonfmu.enums import Fmi2Status

from drillstring.model.engine import MODE_NAMES, Engine, EngineOptions
from drillstring.model.params import REFERENCE, ScaledParams

MODEL = "DrillStringPlant"
_ENGINE_DEFAULTS = EngineOptions()

#: FMU name, ScaledParams field, description. Start values: REFERENCE (NOTES.md section 5).
SCALED_PARAMETERS: tuple[tuple[str, str, str], ...] = (
    ("n", "n", "Number of blades of the drag bit (eq. (5))"),
    ("psi", "psi", "Drill-string design parameter psi (eq. (15))"),
    ("gamma", "gamma", "Scaled axial damping gamma (eq. (15))"),
    ("eta", "eta", "Scaled axial stiffness eta (eq. (15))"),
    ("lambda", "lam", "Scaled bluntness lambda of the wearflats (eq. (16))"),
    ("beta", "beta", "Bit design parameter beta in (0, 1] (eq. (16))"),
    ("rho", "rho", "Inertia ratio rho = I2/I1 of rotary table and bottom-hole assembly (eq. (16))"),
    ("v0", "v0", "Nominal scaled axial velocity v0 (eq. (14))"),
    ("omega0", "omega0", "Nominal scaled angular velocity omega0 (eq. (14))"),
)
#: FMU name, engine initial-state key, default, description (perturbation at tau = 0).
INITIAL_PARAMETERS: tuple[tuple[str, str, float, str], ...] = (
    ("u0", "u", 0.0, "Initial axial position perturbation u(0)"),
    ("du0", "du", 0.0, "Initial axial velocity perturbation du/dtau(0)"),
    ("phi0", "phi", 0.0, "Initial bit angle perturbation phi(0)"),
    (
        "dphi0",
        "dphi",
        -2.5,
        "Initial bit angular velocity perturbation dphi/dtau(0) (Fig. 5: -2.5)",
    ),
    ("theta0", "theta", 0.0, "Initial rotary-table angle perturbation theta(0)"),
    ("dtheta0", "dtheta", 0.0, "Initial rotary-table angular velocity perturbation dtheta/dtau(0)"),
)
#: Real outputs: engine output key, description (all perturbations from the nominal motion).
REAL_OUTPUTS: tuple[tuple[str, str], ...] = (
    ("u", "Axial bit position perturbation u, U = v0*tau + u (eq. (11))"),
    ("du", "Axial bit velocity perturbation du/dtau (eq. (11))"),
    ("phi", "Bit angle perturbation phi, Phi = omega0*tau + phi (eq. (13))"),
    ("dphi", "Bit angular velocity perturbation dphi/dtau (eq. (13))"),
    ("theta", "Rotary-table angle perturbation theta (eq. (13))"),
    ("dtheta", "Rotary-table angular velocity perturbation dtheta/dtau (eq. (13))"),
    ("d", "Depth of cut d = U(tau) - U(tau - tau_n) (eq. (5)); d < 0 is bit bouncing"),
    ("g", "Wearflat contact multiplier g in [0, 1] of the Filippov contact law (eq. (17))"),
    ("tau_n", "State-dependent delay tau_n: Phi(tau) - Phi(tau - tau_n) = 2*pi/n (eq. (14))"),
)
_MODES = ", ".join(f"{code} {name}" for code, name in sorted(MODE_NAMES.items()))
#: Integer outputs: engine output key, description.
INTEGER_OUTPUTS: tuple[tuple[str, str], ...] = (
    ("mode", f"Axial contact mode of (17): {_MODES}"),
    ("stick_events", "Number of entries into axial stick (V = 0) so far"),
    (
        "bit_bounce",
        "Validity flag: number of bit-bouncing episodes (d < 0, outside the model, Section II) "
        "so far; nonzero only with on_invalid = 'continue'",
    ),
    (
        "torsional_stick",
        "Number of entries into torsional stick (dPhi/dtau = 0) so far; with "
        "torsional_stick_model = false the run stops there instead",
    ),
)
#: ModelStructure (written by build_fmus.py): no output depends directly on the input R_minus_R0
#: (they are states or functions of the state), so a master sees no algebraic loop.
OUTPUT_DEPENDENCIES: dict[str, tuple[str, ...]] = {
    name: () for name, _ in REAL_OUTPUTS + INTEGER_OUTPUTS
}


class DrillStringPlant(support.GuardedAccessors, Fmi2Slave):
    """Drill-string plant (11)-(14), (17): input R - R0, outputs the perturbation states."""

    author = "drillstring project"
    license = "MIT"
    description = (
        "Axial-torsional drill-string stick-slip model of Besselink, van de Wouw and Nijmeijer "
        "(IEEE CCA 2011), scaled form (11)-(14) with Filippov wearflat contact (17)"
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=0.01)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        config = support.read_config(self.resources)
        self.version = str(config.get("version", "unknown"))
        self._exit_guard = support.guard_process_exit(self.resources, MODEL)

        # FMU variables (parameters, input); the engine owns the dynamic state
        self._par: dict[str, Any] = {}
        for name, field, _ in SCALED_PARAMETERS:
            self._par[name] = getattr(REFERENCE, field)
        for name, _, default, _ in INITIAL_PARAMETERS:
            self._par[name] = default
        self._par["h"] = _ENGINE_DEFAULTS.h
        self._par["event_tol"] = _ENGINE_DEFAULTS.event_tol
        self._par["torsional_stick_model"] = _ENGINE_DEFAULTS.torsional_stick
        self._par["on_invalid"] = _ENGINE_DEFAULTS.on_invalid
        self._input = 0.0

        self._phase = "instantiated"  # -> initialization -> stepping -> terminated
        self._param_errors: dict[str, str] = {}
        self._input_error: str | None = None
        self._call_error: str | None = None
        self._engine: Engine | None = None
        self._engine_key: tuple | None = None
        self._out: dict[str, float] = {}
        self._ensure_engine()  # start values of the outputs (build time) and outputs before init

        self._register()

    # ----------------------------------------------------------------- variables
    def _register(self) -> None:
        par, fixed, exact = Fmi2Causality.parameter, Fmi2Variability.fixed, Fmi2Initial.exact
        self.register_variable(
            Real(
                "R_minus_R0",
                causality=Fmi2Causality.input,
                variability=Fmi2Variability.continuous,
                description="Rotary-table torque deviation R - R0 (scaled, eq. (13)), held "
                "constant over each communication step",
                getter=lambda: self._input,
                setter=self._set_input,
            )
        )
        for name, desc in REAL_OUTPUTS:
            self.register_variable(
                Real(
                    name,
                    causality=Fmi2Causality.output,
                    variability=Fmi2Variability.continuous,
                    initial=exact,
                    description=desc,
                    getter=lambda key=name: self._out[key],
                )
            )
        for name, desc in INTEGER_OUTPUTS:
            self.register_variable(
                Integer(
                    name,
                    causality=Fmi2Causality.output,
                    variability=Fmi2Variability.discrete,
                    initial=exact,
                    description=desc,
                    getter=lambda key=name: int(self._out[key]),
                )
            )
        for name, _, desc in SCALED_PARAMETERS:
            kind = Integer if name == "n" else Real
            self.register_variable(self._parameter(kind, name, desc, par, fixed, exact))
        for name, _, _, desc in INITIAL_PARAMETERS:
            self.register_variable(self._parameter(Real, name, desc, par, fixed, exact))
        engine_parameters = (
            (
                Real,
                "h",
                "Nominal RK4 step of the engine (scaled time); each communication step "
                "is split into equal steps no longer than h",
            ),
            (Real, "event_tol", "Time tolerance of the engine's event location, in (0, 1e-10]"),
            (
                Boolean,
                "torsional_stick_model",
                "Model torsional stick of the bit (NOTES.md "
                "section 6, our reconstruction); false: the run stops when dPhi/dtau reaches 0",
            ),
            (
                String,
                "on_invalid",
                "On bit bouncing (d < 0, outside the model's validity): "
                "'stop' (fmi2Discard with a log message naming time and cause) or 'continue' "
                "(counted in the output bit_bounce)",
            ),
        )
        for kind, name, desc in engine_parameters:
            self.register_variable(self._parameter(kind, name, desc, par, fixed, exact))

    def _parameter(self, kind: type, name: str, desc: str, *attrs: Any) -> Any:
        causality, variability, initial = attrs
        return kind(
            name,
            causality=causality,
            variability=variability,
            initial=initial,
            description=desc,
            getter=lambda: self._par[name],
            setter=lambda value: self._set_parameter(name, value),
        )

    # ----------------------------------------------------------------- setters
    def _set_input(self, value: Any) -> None:
        if not support.is_finite_real(value):
            self._input_error = f"input R_minus_R0 must be a finite number, got {value!r}"
            self._error(f"{self._input_error}; the value is rejected and fmi2DoStep refused")
            return
        self._input = float(value)
        self._input_error = None

    def _set_parameter(self, name: str, value: Any) -> None:
        if self._phase not in ("instantiated", "initialization"):
            self._call_error = (
                f"parameter {name} is fixed: it cannot be set after initialization (got {value!r})"
            )
            self._error(self._call_error)
            return
        self._par[name] = value
        self._param_errors.pop(name, None)
        problem = self._check_parameters()
        if problem is not None:
            self._param_errors[name] = problem
            self._error(f"bad parameter {name} = {value!r}: {problem}")

    def _check_parameters(self) -> str | None:
        """The Python API's validation of the current values (ScaledParams, EngineOptions)."""
        try:
            self._scaled_params()
            self._engine_options()
            for name, key, _, _ in INITIAL_PARAMETERS:
                if not support.is_finite_real(self._par[name]):
                    return f"initial {key} must be a finite number, got {self._par[name]!r}"
        except (ValueError, TypeError) as exc:
            return str(exc)
        return None

    def _scaled_params(self) -> ScaledParams:
        return ScaledParams(**{field: self._par[name] for name, field, _ in SCALED_PARAMETERS})

    def _engine_options(self) -> EngineOptions:
        return EngineOptions(
            h=self._par["h"],
            torsional_stick=bool(self._par["torsional_stick_model"]),
            on_invalid=self._par["on_invalid"],
            event_tol=self._par["event_tol"],
            keep_events=False,
        )

    # ----------------------------------------------------------------- engine
    def _key(self) -> tuple:
        return tuple(self._par[k] for k in sorted(self._par))

    def _ensure_engine(self) -> None:
        """(Re)build the engine when the parameters changed; raises on invalid parameters."""
        key = self._key()
        if self._engine is not None and key == self._engine_key:
            return
        initial = {key_: float(self._par[name]) for name, key_, _, _ in INITIAL_PARAMETERS}
        self._engine = Engine(
            self._scaled_params(), options=self._engine_options(), initial=initial
        )
        self._engine_key = key
        self._out = self._engine.outputs()

    def _blocking_error(self) -> str | None:
        if self._call_error is not None:
            return self._call_error
        if self._param_errors:
            return "; ".join(f"{k}: {v}" for k, v in sorted(self._param_errors.items()))
        if self._input_error is not None:
            return self._input_error
        return None

    # ----------------------------------------------------------------- FMI life cycle
    def setup_experiment(self, start_time: float, stop_time: Any = None, tolerance: Any = None):
        if start_time != 0.0:
            self._call_error = (
                f"start time must be 0 (the model's time origin, history for tau <= 0 is the "
                f"nominal motion), got {start_time!r}"
            )
            self._error(self._call_error)

    def enter_initialization_mode(self) -> None:
        self._phase = "initialization"
        self._initialize_engine("fmi2EnterInitializationMode")

    def exit_initialization_mode(self) -> None:
        self._initialize_engine("fmi2ExitInitializationMode")
        self._phase = "stepping"

    def _initialize_engine(self, where: str) -> None:
        if self._param_errors:
            self._error(f"{where}: invalid parameters: {self._blocking_error()}")
            return
        try:
            self._ensure_engine()
        except (ValueError, TypeError) as exc:
            self._param_errors["initial state"] = str(exc)
            self._error(f"{where}: cannot start the engine: {exc}")

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
        eng = self._engine
        assert eng is not None
        if eng.failed is not None:
            return self._discard(f"fmi2DoStep refused: the run stopped: {eng.failed.message}")
        if abs(t - eng.tau) > 1e-9 * max(1.0, abs(eng.tau)):
            return self._discard(
                f"fmi2DoStep: communication point t = {t!r} is not the FMU's time {eng.tau!r}"
            )
        target = t + h
        if not target > eng.tau:
            return self._discard(f"fmi2DoStep: t + h = {target!r} does not advance {eng.tau!r}")
        bounces = self._out["bit_bounce"]
        eng.set_input(self._input)
        status = eng.advance(target)
        self._out = eng.outputs()
        if not status.ok:
            return self._discard(f"{status.code}: {status.message}")
        if self._out["bit_bounce"] > bounces:
            self.log(
                f"bit bouncing (d < 0, outside the model's validity) in the step [{t!r}, "
                f"{target!r}]; continuing as on_invalid = 'continue'",
                Fmi2Status.warning,
            )
        return True

    # ----------------------------------------------------------------- logging
    def _error(self, msg: str) -> None:
        self.log(msg, Fmi2Status.error)

    def _discard(self, msg: str) -> bool:
        self.log(msg, Fmi2Status.discard)
        return False

    # ----------------------------------------------------------------- get/set (never raise)
    def _before_get(self) -> None:
        if self._phase == "initialization" and not self._param_errors:
            self._guarded("rebuilding the engine", self._ensure_engine)

    # ----------------------------------------------------------------- FMU state
    def _get_fmu_state(self) -> PlantState:
        fields = {
            "par": dict(self._par),
            "input": self._input,
            "phase": self._phase,
            "param_errors": dict(self._param_errors),
            "input_error": self._input_error,
            "call_error": self._call_error,
        }
        eng = self._engine
        assert eng is not None
        return PlantState(fields, eng, eng.get_state())

    def _set_fmu_state(self, state: Any) -> None:
        try:
            self._restore(state)
        except Exception as exc:
            self._call_error = f"fmi2SetFMUstate failed: {exc}"
            self._error(self._call_error)

    def _restore(self, state: PlantState) -> None:
        if not isinstance(state, PlantState):
            raise TypeError(f"not a {MODEL} state: {type(state).__name__}")
        if state.error is not None:
            raise ValueError(state.error)
        f = state.fields
        self._par = dict(f["par"])
        self._input = f["input"]
        self._phase = f["phase"]
        self._param_errors = dict(f["param_errors"])
        self._input_error = f["input_error"]
        self._call_error = f["call_error"]
        if state.engine is not None and state.engine is self._engine:
            self._engine.set_state(state.snapshot)
        else:  # deserialized, or captured before the engine was rebuilt: fresh engine + bytes
            self._engine = None
            self._ensure_engine()
            assert self._engine is not None
            self._engine.deserialize_state(state.engine_bytes())
        self._engine_key = self._key()
        self._out = self._engine.outputs()

    @staticmethod
    def _fmu_state_to_bytes(state: PlantState) -> bytes:
        return support.pack_state(MODEL, state.fields, state.engine_bytes())

    @staticmethod
    def _fmu_state_from_bytes(data: bytes) -> PlantState:
        try:
            fields, payload = support.unpack_state(MODEL, data)
        except support.StateError as exc:
            return PlantState({}, None, None, error=f"cannot deserialize FMU state: {exc}")
        return PlantState(fields, None, None, payload=payload)


class PlantState:
    """An FMU state: the FMU's own variables and the engine's (snapshot or serialized bytes).

    A state from ``fmi2GetFMUstate`` holds the engine snapshot and the engine it belongs to; its
    bytes are made on demand (``fmi2SerializeFMUstate`` asks twice: size, then content). A state
    from ``fmi2DeSerializeFMUstate`` holds the bytes only.
    """

    __slots__ = ("_payload", "engine", "error", "fields", "snapshot")

    def __init__(
        self,
        fields: dict[str, Any],
        engine: Engine | None,
        snapshot: Any,
        *,
        payload: bytes | None = None,
        error: str | None = None,
    ) -> None:
        self.fields = fields
        self.engine = engine
        self.snapshot = snapshot
        self._payload = payload
        self.error = error

    def engine_bytes(self) -> bytes:
        if self._payload is None:
            eng = self.engine
            assert eng is not None
            current = eng.get_state()
            eng.set_state(self.snapshot)
            try:
                self._payload = eng.serialize_state()
            finally:
                eng.set_state(current)
        return self._payload
