"""FMI 2.0 co-simulation unit of the drill-string plant (pythonfmu script of ``DrillStringPlant``).

Wraps :class:`drillstring.model.engine.Engine`, the scaled axial-torsional model (11)-(14) of
Besselink, van de Wouw and Nijmeijer (IEEE CCA 2011) with the Filippov contact law (17) and the
state-dependent delay (14); see ``docs/model.md``, "Wearflat contact as a Filippov system" and
"Validity". No model code lives here: the ``drillstring`` package is bundled into the FMU's
``resources/`` by ``build_fmus.py``, and the lifecycle (checks, phases, step wrapper, errors,
FMU states) is :class:`drillstring_fmu_support.FmuModel`. ``fmi2DoStep(t, h)`` holds the input
``R_minus_R0`` over the step and advances the engine to ``t + h``; the engine locates the events
inside the step, so communication points never have to land on an event. The step is the compiled
plant step :func:`drillstring.model.native.plant_io_step` on the plant's io block, whether the
front layer runs it (the native fast path) or this script does; Python keeps what needs Python:
the messages of a stop or a warning, growing the history buffer, the FMU states.

The FMU state is the whole engine (history buffer, axial mode, counters, integrator state) plus
the FMU's variables; restoring it is bit exact.

The unit system is the class's: :class:`DrillStringPlant` speaks the paper's scaled quantities;
``drillstring_plant_si.py`` derives ``DrillStringPlantSI`` from it, which only replaces the
variables and the conversions between the FMU's quantities and the engine's
(:meth:`DrillStringPlant.engine_setup`, :meth:`~DrillStringPlant.engine_input`,
:meth:`~DrillStringPlant.engine_time` and :meth:`~DrillStringPlant.fmu_time`,
:meth:`~DrillStringPlant.converted_outputs`, :meth:`~DrillStringPlant.stop_message`;
``docs/si_fmus.md``) and the unit system of the compiled step (``FAST_SI``, ``FAST_KEYS``,
:meth:`~DrillStringPlant.fast_constants`), which must agree with them; everything else is this
class.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any

import drillstring_fmu_support as fmu
import numpy as np

from drillstring.model import native
from drillstring.model.engine import (
    MODE_NAMES,
    ON_INVALID_CHOICES,
    OUTPUT_KEYS,
    Engine,
    EngineOptions,
)
from drillstring.model.params import REFERENCE, ScaledParams

_ENGINE_DEFAULTS = EngineOptions()
ON_INVALID = (
    ("stop", "fmi2Discard with a message naming time and cause; the outputs hold that state"),
    ("continue", "go on; every bit-bouncing episode is counted in bit_bounce and logged"),
)


def _scaled_field(field: str) -> Callable[[Any], Any]:
    """Check of one field of ScaledParams on its own (the others at the reference set), so
    that the order in which a host sets parameters never matters; the combination is checked
    when the engine is built (fmi2ExitInitializationMode)."""

    def check(value: Any) -> Any:
        dataclasses.replace(REFERENCE, **{field: value})
        return value

    return check


def _option(name: str) -> Callable[[Any], Any]:
    def check(value: Any) -> Any:
        EngineOptions(**{name: value})
        return value

    return check


P = fmu.POSITIVE
#: FMU name, ScaledParams field, min, max, description. Start values: the reference set
#: (``docs/model.md``, "Reference parameter set").
_SCALED = (
    ("psi", "psi", P, None, "Drill-string design parameter psi > 0 (eq. (15))"),
    ("gamma", "gamma", 0.0, None, "Scaled axial damping gamma >= 0 (eq. (15))"),
    ("eta", "eta", P, None, "Scaled axial stiffness eta > 0 (eq. (15))"),
    ("lambda", "lam", 0.0, None, "Scaled bluntness lambda >= 0 of the wearflats (eq. (16))"),
    ("beta", "beta", P, 1.0, "Bit design parameter beta in (0, 1] (eq. (16))"),
    ("rho", "rho", P, None, "Inertia ratio rho = I2/I1 > 0 of rotary table and BHA (eq. (16))"),
    ("v0", "v0", P, None, "Nominal scaled axial velocity v0 > 0 (eq. (14))"),
    ("omega0", "omega0", P, None, "Nominal scaled angular velocity omega0 > 0 (eq. (14))"),
)
#: FMU name, engine initial-state key, start, description (perturbation at tau = 0).
_INITIAL = (
    ("u0", "u", 0.0, "Initial axial position perturbation u(0)"),
    ("du0", "du", 0.0, "Initial axial velocity perturbation du/dtau(0)"),
    ("phi0", "phi", 0.0, "Initial bit angle perturbation phi(0)"),
    ("dphi0", "dphi", -2.5, "Initial bit angular velocity perturbation dphi/dtau(0), > -omega0"),
    ("theta0", "theta", 0.0, "Initial rotary-table angle perturbation theta(0)"),
    ("dtheta0", "dtheta", 0.0, "Initial rotary-table angular velocity perturbation dtheta/dtau(0)"),
)
_MODES = ", ".join(f"{code} {name}" for code, name in sorted(MODE_NAMES.items()))
#: Outputs (all perturbations from the nominal motion): name, type, description.
_OUTPUTS = (
    ("u", "Real", "Axial bit position perturbation u, U = v0*tau + u (eq. (11))"),
    ("du", "Real", "Axial bit velocity perturbation du/dtau (eq. (11))"),
    ("phi", "Real", "Bit angle perturbation phi, Phi = omega0*tau + phi (eq. (13))"),
    ("dphi", "Real", "Bit angular velocity perturbation dphi/dtau (eq. (13))"),
    ("theta", "Real", "Rotary-table angle perturbation theta (eq. (13))"),
    ("dtheta", "Real", "Rotary-table angular velocity perturbation dtheta/dtau (eq. (13))"),
    ("d", "Real", "Depth of cut d = U(tau) - U(tau - tau_n) (eq. (5)); d < 0 is bit bouncing"),
    ("g", "Real", "Wearflat contact multiplier g in [0, 1] of the Filippov contact law (eq. (17))"),
    (
        "tau_n",
        "Real",
        "State-dependent delay tau_n: Phi(tau) - Phi(tau - tau_n) = 2*pi/n (eq. (14))",
    ),
    ("mode", "Integer", f"Axial contact mode of (17): {_MODES}"),
    ("stick_events", "Integer", "Number of entries into axial stick (V = 0) so far"),
    (
        "bit_bounce",
        "Integer",
        "Validity flag: number of bit-bouncing episodes (d < 0, outside the model, Section II) "
        "so far; nonzero only with on_invalid = continue",
    ),
    (
        "torsional_stick",
        "Integer",
        "Number of entries into torsional stick (dPhi/dtau = 0) so far; with "
        "torsional_stick_model = false the run stops there instead",
    ),
)


def _variables() -> tuple[fmu.Variable, ...]:
    out: list[fmu.Variable] = [
        fmu.input_real(
            "R_minus_R0",
            0.0,
            "Rotary-table torque deviation R - R0 (scaled, eq. (13)), held constant over each "
            "communication step",
        )
    ]
    out += [fmu.output(name, kind, desc) for name, kind, desc in _OUTPUTS]
    out.append(
        fmu.parameter(
            "n",
            "Integer",
            REFERENCE.n,
            "Number of blades of the drag bit (eq. (5))",
            min=1,
            check=_scaled_field("n"),
        )
    )
    for name, field, lo, hi, desc in _SCALED:
        start = getattr(REFERENCE, field)
        check = _scaled_field(field)
        out.append(fmu.parameter(name, "Real", start, desc, min=lo, max=hi, check=check))
    for name, _, start, desc in _INITIAL:
        out.append(fmu.parameter(name, "Real", start, desc))
    out += [
        fmu.parameter(
            "h",
            "Real",
            _ENGINE_DEFAULTS.h,
            "Nominal RK4 step of the engine (scaled time) > 0; each communication step is split "
            "into equal steps no longer than h",
            min=P,
            check=_option("h"),
        ),
        fmu.parameter(
            "event_tol",
            "Real",
            _ENGINE_DEFAULTS.event_tol,
            "Time tolerance of the engine's event location, in (0, 1e-10]",
            min=P,
            max=1e-10,
            check=_option("event_tol"),
        ),
        fmu.parameter(
            "torsional_stick_model",
            "Boolean",
            _ENGINE_DEFAULTS.torsional_stick,
            'Model torsional stick of the bit (docs/model.md, "Torsional stick", our '
            "reconstruction); false: the run stops (fmi2Discard) when dPhi/dtau reaches 0",
        ),
        fmu.enumeration(
            "on_invalid",
            "OnInvalid",
            ON_INVALID,
            _ENGINE_DEFAULTS.on_invalid,
            "What happens on bit bouncing (d < 0, outside the model's validity, docs/model.md, "
            '"Validity"): 1 = stop, 2 = continue',
        ),
    ]
    return tuple(out)


class DrillStringPlant(fmu.FmuModel):
    """Drill-string plant (11)-(14), (17): input R - R0, outputs the perturbation states."""

    MODEL = "DrillStringPlant"
    VARIABLES = _variables()
    VALIDITY = (
        "The model holds while the bit cuts the rock: a depth of cut d < 0 (bit bouncing, "
        "Section II) is outside it. With on_invalid = stop (the default) fmi2DoStep returns "
        "fmi2Discard at the first such instant, located to within event_tol, and names it; with "
        "on_invalid = continue the run goes on, every episode is counted in the output "
        "bit_bounce and the step returns fmi2Warning with a message.",
        "The bit must rotate forwards: dPhi/dtau = omega0 + dphi > 0, so dphi0 > -omega0 "
        "(checked at fmi2ExitInitializationMode). Where dPhi/dtau reaches 0 the bit sticks "
        "torsionally: with torsional_stick_model = true that phase is modelled (docs/model.md, "
        '"Torsional stick"), otherwise fmi2DoStep returns fmi2Discard there. A reverse rotation '
        "during torsional stick, a non-finite state and a delay tau_n that cannot be found in "
        "the history also end the run with fmi2Discard and a message.",
    )
    description = (
        "Axial-torsional drill-string stick-slip model of Besselink, van de Wouw and Nijmeijer "
        "(IEEE CCA 2011), scaled form (11)-(14) with Filippov wearflat contact (17)"
    )

    engine: Engine | None = None
    _out: Mapping[str, Any] = MappingProxyType({})
    #: The io block of the plant's step (layout ``native.PLANT``), one per instance: the front
    #: layer's native fast path steps on it too.
    _io: np.ndarray | None = None
    _input = ""  # the name of the FMU's input
    #: The unit system of the step: the outputs in the io block (``_out``'s keys), SI or not.
    FAST_KEYS: tuple[str, ...] = native.PLANT_SCALED_KEYS
    FAST_SI = 0.0
    _fast_block: fmu.FastPath | None = None
    _fast_kernel: Any = None

    # ----------------------------------------------------------------- the unit system
    def engine_setup(
        self, v: Mapping[str, Any]
    ) -> tuple[ScaledParams, EngineOptions, Mapping[str, float]]:
        """The engine's parameters, options and initial perturbation from the FMU's values."""
        params = ScaledParams(n=v["n"], **{f: v[name] for name, f, *_ in _SCALED})
        options = EngineOptions(
            h=v["h"],
            torsional_stick=bool(v["torsional_stick_model"]),
            on_invalid=ON_INVALID[v["on_invalid"] - 1][0],
            event_tol=v["event_tol"],
            keep_events=False,
        )
        initial = {key: float(v[name]) for name, key, _, _ in _INITIAL}
        return params, options, initial

    def engine_input(self) -> float:
        """The engine's input R - R0 (scaled) from the FMU's input."""
        return self.values["R_minus_R0"]

    def engine_time(self, t: float) -> float:
        """The engine's (scaled) time of the FMU's time ``t``."""
        return t

    def converted_outputs(self, eng: Engine) -> Mapping[str, Any]:
        """The FMU's outputs from the engine's state."""
        return eng.outputs()

    def stop_message(self, eng: Engine, message: str) -> str:
        """The message of a validity stop (the engine's, which names the scaled time)."""
        return message

    # ----------------------------------------------------------------- physics
    def configure(self, values: Mapping[str, Any]) -> None:
        self._use(self._new_engine(values))

    def _new_engine(self, v: Mapping[str, Any]) -> Engine:
        params, options, initial = self.engine_setup(v)
        return Engine(params, options=options, initial=initial)

    def _use(self, eng: Engine) -> None:
        """Make ``eng`` the plant's engine: the io block of the step takes the unit system's
        constants and the outputs at the engine's state."""
        assert not eng.options.keep_events, "the plant's step keeps no events (engine_setup)"
        if self._io is None:
            self._io = np.zeros(native.PLANT.size)
            (self._input,) = (v.name for v in self.VARIABLES if v.causality == "input")
        io = self._io
        io[native.PLANT.si] = self.FAST_SI
        io[native.PLANT.k : native.PLANT.k + native.N_K] = self.fast_constants()
        self.engine = eng
        self._out = self.converted_outputs(eng)
        io[native.PLANT.out : native.PLANT.out + len(self.FAST_KEYS)] = [
            self._out[k] for k in self.FAST_KEYS
        ]

    def _pull_outputs(self) -> None:
        """The outputs the step wrote into the io block."""
        io = self._io
        assert io is not None
        values = io[native.PLANT.out : native.PLANT.out + len(self.FAST_KEYS)].tolist()
        self._out = dict(zip(self.FAST_KEYS, values, strict=True))

    def output_values(self) -> Mapping[str, Any]:
        return self._out

    def advance(self, t: float, h: float) -> fmu.StepResult:
        eng, io = self.engine, self._io
        assert eng is not None and io is not None
        st = self.fast_resume  # the kernel status of a step the front layer began natively
        while True:
            if st is None:
                io[native.PLANT.input] = self.values[self._input]
                code = native.plant_step_from(io, *eng.kernel_arrays(), t, h)
                if code == native.DONE:
                    self._pull_outputs()
                    return fmu.StepResult(t + h)
                if code == native.NOT_STARTED:
                    return self._refused(t, h)
                st = int(io[native.IO_RESUME])
                io[native.IO_RESUME] = -1.0
            status = eng.finish(st)
            if status is not None:
                break
            st = None  # the history buffer grown: the step goes on
        self._pull_outputs()
        if not status.ok:
            stop = self.stop_message(eng, f"{status.code}: {status.message}")
            return fmu.StepResult(self.fmu_time(eng.tau), stop=stop)
        # the step finished with ST_OK only for a new bit-bounce episode (on_invalid = continue)
        return fmu.StepResult(
            t + h,
            warning=f"bit bouncing (d < 0, outside the model's validity) in the step "
            f"[{t!r}, {t + h!r}]; continuing as on_invalid = continue",
        )

    def _refused(self, t: float, h: float) -> fmu.StepResult:
        """A step the compiled step refused, nothing changed: the engine names what is wrong
        (raises ``ValueError``), or a run that stopped before stops again."""
        eng = self.engine
        assert eng is not None
        eng.set_input(self.engine_input())
        status = eng.advance(self.engine_time(t + h))
        if status.ok:  # the compiled step refuses only what the engine refuses
            raise RuntimeError(f"the plant's step refused the step [{t!r}, {t + h!r}]")
        self._use(eng)
        stop = self.stop_message(eng, f"{status.code}: {status.message}")
        return fmu.StepResult(self.fmu_time(eng.tau), stop=stop)

    def fmu_time(self, tau: float) -> float:
        """The FMU's time of the engine's time ``tau`` (inverse of :meth:`engine_time`)."""
        return tau

    # ----------------------------------------------------------------- native fast path
    def fast_constants(self) -> tuple[float, ...]:
        """The unit system's constants of the step (``native.PLANT.k``)."""
        return (0.0,) * native.N_K

    def fast_path(self) -> fmu.FastPath | None:
        eng = self.engine
        if not native.AVAILABLE or eng is None or eng.failed is not None or self._io is None:
            return None
        ks = eng.kernel_arrays()
        block = self._fast_block
        if block is None:
            step, outputs = native.plant_functions()
            names = {v.name for v in self.VARIABLES if v.causality == "output"}
            at = {k: native.PLANT.out + i for i, k in enumerate(self.FAST_KEYS) if k in names}
            block = fmu.FastPath(self._io, step, outputs, {self._input: native.PLANT.input}, at)
            self._fast_block = block
        if self._fast_kernel is not ks:
            block.args = native.array_addresses(ks)
            self._fast_kernel = ks
        return block if block.args is not None else None

    def fast_push(self, io: np.ndarray) -> None:
        # the rest of the block is kept up to date by the steps, configure and restore
        ks = self._fast_kernel
        io[native.PLANT.hcap] = ks.history.shape[1]
        io[native.PLANT.ecap] = ks.events.shape[0]

    def fast_pull(self, io: np.ndarray) -> None:
        self._pull_outputs()

    # ----------------------------------------------------------------- FMU state
    def save(self) -> tuple[dict[str, Any], Any, Callable[[], bytes]]:
        eng = self.engine
        if eng is None:
            return {"engine": False}, None, lambda: b""
        snapshot = (eng, eng.get_state())

        def payload() -> bytes:
            current = eng.get_state()
            eng.set_state(snapshot[1])
            try:
                return eng.serialize_state()
            finally:
                eng.set_state(current)

        return {"engine": True}, snapshot, payload

    def restore(self, fields: Mapping[str, Any], snapshot: Any, payload: bytes | None) -> None:
        if not fields["engine"]:
            self.engine, self._out = None, MappingProxyType({})
            return
        eng = self.engine
        if eng is not None and snapshot is not None and snapshot[0] is eng:
            eng.set_state(snapshot[1])
        else:  # deserialized, or of another instance/engine: a fresh engine, then the bytes
            eng = self._new_engine(self.values)
            if snapshot is not None:
                eng.set_state(snapshot[1])
            else:
                eng.deserialize_state(payload or b"")
        self._use(eng)


assert {name for name, _, _ in _OUTPUTS} <= set(OUTPUT_KEYS), "outputs the engine lacks"
assert tuple(name for name, _ in ON_INVALID) == ON_INVALID_CHOICES
assert native.PLANT_SCALED_KEYS == OUTPUT_KEYS, "the native step's outputs are the engine's"
