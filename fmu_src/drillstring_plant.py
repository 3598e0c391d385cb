"""FMI 2.0 co-simulation unit of the drill-string plant (pythonfmu script; ``build_fmus.py``
generates ``DrillStringPlant`` and ``DrillStringPlantSI`` from the one class here).

Wraps :class:`drillstring.model.engine.Engine`, the scaled axial-torsional model (11)-(14) of
Besselink, van de Wouw and Nijmeijer (IEEE CCA 2011) with the Filippov contact law (17) and the
state-dependent delay (14); see ``docs/model.md``, "Wearflat contact as a Filippov system" and
"Validity". No model code lives here: the ``drillstring`` package is bundled into the FMU's
``resources/`` by ``build_fmus.py``, and the lifecycle (checks, phases, step wrapper, errors,
FMU states) is :class:`drillstring_fmu_support.FmuModel`. ``fmi2DoStep(t, h)`` holds the input
over the step and advances the engine to ``t + h`` by the compiled plant step
(:func:`drillstring.model.native.plant_io_step`, the same the front layer runs natively); the
engine locates the events inside the step, so communication points never have to land on an
event.

The FMU state is the whole engine (history buffer, axial mode, counters, integrator state) plus
the FMU's variables; restoring it is bit exact.

The variables are declared once (:data:`DECLARED`, :mod:`drillstring_fmu_units`): in the scaled
unit system (``UNIT_SYSTEM = "scaled"``) the paper's quantities, the scaled parameter set and the
perturbations from the nominal motion; in SI (``"si"``) seconds, the physical parameter set of
eqs. (1)-(8) (start values: the reference rig, ``docs/reference_rig.md``), the absolute table
torque as input and total angles, speeds and positions, weight and torque on bit, depth of cut,
delay and rate of penetration as outputs, converted by
:class:`drillstring.model.units.SIScaling` (eqs. (15)-(16) of the FMU's own rig;
``docs/si_fmus.md``). The unit system's conversions are the few methods under "the unit system"
and the constants of the compiled step; everything else is shared.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from functools import partial
from types import MappingProxyType
from typing import Any, ClassVar

import drillstring_fmu_support as fmu
import drillstring_fmu_units as units
import numpy as np

from drillstring.model import native
from drillstring.model.engine import (
    MODE_NAMES,
    ON_INVALID_CHOICES,
    OUTPUT_KEYS,
    Engine,
    EngineOptions,
    Status,
    string_profiles,
)
from drillstring.model.experiments import FIG5
from drillstring.model.params import REFERENCE, REFERENCE_RIG, ScaledParams
from drillstring.model.pipe import MAX_ELEMENTS, REFERENCE_KAPPA, StringParams
from drillstring.model.units import PLANT_SI, SCALED_UNITS, Scales, UnitSystem
from drillstring.validation import check_real

SCALED, SI = units.SCALED, units.SI
declare = units.declare
_ENGINE_DEFAULTS = EngineOptions()
#: The string whose fields admit any one valid field on its own (the one-element "paper"
#: lumping admits no other number of elements).
_LUMPED = StringParams(lumping="lumped")
#: The engine's event tolerance in scaled time is at most this (EngineOptions.event_tol).
_EVENT_TOL_MAX = 1e-10
ON_INVALID = (
    ("stop", "fmi2Discard with a message naming time and cause; the outputs hold that state"),
    ("continue", "go on; every bit-bouncing episode is counted in bit_bounce and logged"),
)


def _field_check(base: Any, field: str) -> Callable[[Any], Any]:
    """Check of one field of a parameter set, engine option or string on its own (the others at
    ``base``), so that the order in which a host sets parameters never matters; the combination
    is checked when the engine is built (fmi2ExitInitializationMode)."""

    def check(value: Any) -> Any:
        dataclasses.replace(base, **{field: value})
        return value

    return check


P = fmu.POSITIVE
#: The scaled set: FMU name, ScaledParams field, min, max, description (start: the reference
#: set, ``docs/model.md``, "Reference parameter set").
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
#: The physical set: PhysicalParams field, min, unit, display unit, description (start: the
#: reference rig).
_PHYSICAL = (
    ("M", P, "kg", None, "Mass of the bottom-hole assembly (eq. (1))"),
    ("I1", P, "kg.m2", None, "Inertia of the bit end of the string (eq. (2))"),
    ("I2", P, "kg.m2", None, "Inertia of the rotary table or top drive (eq. (3))"),
    ("C", P, "N.m/rad", None, "Torsional stiffness of the drill string (eqs. (2)-(3))"),
    ("K", P, "N/m", None, "Axial stiffness of the drill string (eq. (1))"),
    ("D", 0.0, "N.s/m", None, "Axial damping (eq. (1))"),
    ("a", P, "m", "mm", "Bit radius (eq. (4))"),
    ("eps", P, "Pa", "MPa", "Intrinsic specific energy of the rock (eq. (4))"),
    ("zeta", P, "1", None, "Cutting-face orientation constant zeta (eq. (4))"),
    ("sigma_bar", 0.0, "Pa", "MPa", "Contact stress under the wearflats (eq. (7))"),
    ("l", 0.0, "m", "mm", "Wearflat length (eq. (7))"),
    ("mu", P, "1", None, "Bit-rock friction coefficient of the wearflats (eq. (7))"),
    ("xi", P, "1", None, "Spatial distribution of the wearflat contact (eq. (7))"),
    ("V0", P, "m/s", "m/h", "Nominal axial (hook) velocity = nominal rate of penetration"),
    ("Omega0", P, "rad/s", "rpm", "Nominal rotary speed of table and bit"),
)
#: The initial state, a deviation from the nominal motion at t = 0: FMU name, engine key,
#: dimension, description (start: Fig. 5's).
_INITIAL = (
    ("u0", "u", "length", "Initial axial bit position deviation u(0)"),
    ("du0", "du", "velocity", "Initial axial bit velocity deviation du/dtau(0)"),
    ("phi0", "phi", "angle", "Initial bit angle deviation phi(0)"),
    ("dphi0", "dphi", "speed", "Initial bit speed deviation dphi/dtau(0), > -omega0"),
    ("theta0", "theta", "angle", "Initial rotary-table angle deviation theta(0)"),
    ("dtheta0", "dtheta", "speed", "Initial rotary-table speed deviation dtheta/dtau(0)"),
)
_MODES = ", ".join(f"{code} {name}" for code, name in sorted(MODE_NAMES.items()))
#: The Real outputs: scaled name (an Engine.outputs() key), SI name (a PLANT_SI quantity),
#: description, scaled note, SI note; the SI unit and display unit are the quantity's.
_REALS = (
    ("u", "bit_position", "Axial bit position", " perturbation u, U = v0*tau + u (eq. (11))",
     " U, downwards (0 where the bit is at t = 0 of the nominal motion)"),
    ("du", "bit_velocity", "Axial bit velocity", " perturbation du/dtau (eq. (11))",
     " dU/dt, downwards"),
    ("phi", "bit_angle", "Bit angle", " perturbation phi, Phi = omega0*tau + phi (eq. (13))",
     " Phi (0 at t = 0 of the nominal motion)"),
    ("dphi", "bit_speed", "Bit angular speed", " perturbation dphi/dtau (eq. (13))", " dPhi/dt"),
    ("theta", "table_angle", "Rotary-table angle", " perturbation theta (eq. (13))",
     " Theta = Phi + twist of the string"),
    ("dtheta", "table_speed", "Rotary-table angular speed", " perturbation dtheta/dtau (eq. (13))",
     " dTheta/dt"),
    ("d", "depth_of_cut", "Depth of cut d = U(t) - U(t - t_n) per blade (eq. (5))",
     "; d < 0 is bit bouncing", ""),
    ("g", "contact", "Wearflat contact multiplier g in [0, 1] of the Filippov contact law "
     "(eq. (17))", "", ""),
    ("tau_n", "delay", "State-dependent delay: Phi(t) - Phi(t - t_n) = 2*pi/n (eqs. (6), (14))",
     " (scaled, tau_n)", ""),
    (None, "weight_on_bit", "Weight on bit W^c + W^f, eqs. (4) and (7)", "", ""),
    (None, "torque_on_bit", "Torque on bit T^c + T^f, eqs. (4) and (7)", "", ""),
    (None, "rate_of_penetration", "Rate of penetration: mean axial bit speed over the last "
     "blade passage, d/t_n", "", ""),
)  # fmt: skip
_QUANTITY = {q.name: q for q in PLANT_SI}
#: The Integer outputs (the same in both unit systems): name, description.
_INTEGERS = (
    ("mode", f"Axial contact mode of (17): {_MODES}"),
    ("stick_events", "Number of entries into axial stick (V = 0) so far"),
    (
        "bit_bounce",
        "Validity flag: number of bit-bouncing episodes (d < 0, outside the model, Section II) "
        "so far; nonzero only with on_invalid = continue",
    ),
    (
        "torsional_stick",
        "Number of entries into torsional stick (dPhi/dtau = 0) so far; with "
        "torsional_stick_model = false the run stops there instead",
    ),
)
_START = FIG5.initial()


def _declarations() -> tuple[units.Declared, ...]:
    out = [
        declare(("R_minus_R0", "table_torque"), "Real", "input",
                "Rotary-table (top-drive) torque, held constant over each communication step",
                start=0.0, si_start=REFERENCE_RIG.R0, si_unit="N.m", si_display="kN.m",
                scaled_note=": the deviation R - R0 (scaled, eq. (13))",
                si_note=": R, absolute (start value: the nominal torque R0 of eq. (8))"),
    ]  # fmt: skip
    for scaled, si, desc, s_note, si_note in _REALS:
        q = _QUANTITY[si]
        out.append(
            declare((scaled, si), "Real", "output", desc, si_unit=q.unit, si_display=q.display,
                    scaled_note=s_note, si_note=si_note)
        )  # fmt: skip
    out += [declare(name, "Integer", "output", desc) for name, desc in _INTEGERS]
    out.append(
        declare("n", "Integer", "parameter", "Number of blades of the drag bit (eq. (5))",
                start=REFERENCE.n, min=1, check=_field_check(REFERENCE, "n"),
                si_check=_field_check(REFERENCE_RIG, "n"))
    )  # fmt: skip
    out += [
        declare((name, None), "Real", "parameter", desc, start=getattr(REFERENCE, field), min=lo,
                max=hi, check=_field_check(REFERENCE, field))
        for name, field, lo, hi, desc in _SCALED
    ]  # fmt: skip
    out += [
        declare((None, name), "Real", "parameter", desc, si_start=getattr(REFERENCE_RIG, name),
                si_unit=unit, si_display=display, min=lo,
                check=_field_check(REFERENCE_RIG, name))
        for name, lo, unit, display, desc in _PHYSICAL
    ]  # fmt: skip
    out += [
        declare(name, "Real", "parameter", desc, dimension=dim, start=_START.get(key, 0.0))
        for name, key, dim, desc in _INITIAL
    ]
    out += [
        declare("h", "Real", "parameter",
                "Nominal RK4 step of the engine > 0; each communication step is split into "
                "equal steps no longer than h", dimension="time", start=_ENGINE_DEFAULTS.h,
                min=P, check=_field_check(_ENGINE_DEFAULTS, "h"),
                si_check=partial(check_real, "h", lower=0.0)),
        declare("event_tol", "Real", "parameter",
                "Time tolerance of the engine's event location, in (0, 1e-10 t*]",
                dimension="time", start=_ENGINE_DEFAULTS.event_tol, min=P, max=_EVENT_TOL_MAX,
                check=_field_check(_ENGINE_DEFAULTS, "event_tol"),
                si_check=partial(check_real, "event_tol", lower=0.0)),
        declare("torsional_stick_model", "Boolean", "parameter",
                'Model torsional stick of the bit (docs/model.md, "Torsional stick", our '
                "reconstruction); false: the run stops (fmi2Discard) where the bit stops",
                start=_ENGINE_DEFAULTS.torsional_stick),
        declare("on_invalid", "Enumeration", "parameter",
                "What happens on bit bouncing (d < 0, outside the model's validity, "
                'docs/model.md, "Validity"): 1 = stop, 2 = continue',
                start=_ENGINE_DEFAULTS.on_invalid, items=ON_INVALID, type_name="OnInvalid"),
    ]  # fmt: skip
    out += _string_declarations()
    return tuple(out)


def _string_declarations() -> list[units.Declared]:
    """The distributed string (``docs/model.md``, "The distributed string"): declared after the
    paper's variables, so theirs keep their value references."""
    kappa = REFERENCE_KAPPA
    below3 = math.nextafter(3.0, 0.0)  # kappa and mu must be < 3: the largest accepted value
    return [
        declare(("top_torque_minus_R0", "top_torque"), "Real", "output",
                "Torque at the top of the string, what a sub under the top drive measures",
                si_unit="N.m", si_display="kN.m",
                scaled_note=": its deviation from R0 (scaled; theta - phi on one element)",
                si_note=": absolute"),
        declare("string_elements", "Integer", "parameter",
                "Elements N of the distributed drill pipe (docs/model.md, 'The distributed "
                "string'); 1: the paper's one-mode string, a massless spring (eqs. (11)-(13))",
                start=1, min=1, max=MAX_ELEMENTS, check=_field_check(_LUMPED, "elements")),
        declare(("pipe_inertia_ratio", None), "Real", "parameter",
                "Polar inertia of the drill pipe over I1, kappa in [0, 3) (the bit end keeps "
                "1 - kappa/3); used with string_elements > 1", start=kappa, min=0.0,
                max=below3, check=_field_check(_LUMPED, "kappa")),
        declare(("pipe_mass_ratio", None), "Real", "parameter",
                "Mass of the drill pipe over M, mu in [0, 3) (0: a massless axial spring, as "
                "the paper's); used with string_elements > 1", start=0.0, min=0.0,
                max=below3, check=_field_check(_LUMPED, "axial_mass_ratio")),
        declare((None, "I_pipe"), "Real", "parameter",
                "Polar inertia of the drill pipe, below 3 I1 (I1 keeps a third of it); used "
                "with string_elements > 1", si_start=kappa * REFERENCE_RIG.I1,
                si_unit="kg.m2", min=0.0,
                check=partial(check_real, "I_pipe", lower=0.0, strict=False)),
        declare((None, "M_pipe"), "Real", "parameter",
                "Mass of the drill pipe, below 3 M (0: a massless axial spring, as the "
                "paper's); used with string_elements > 1", si_start=0.0, si_unit="kg", min=0.0,
                check=partial(check_real, "M_pipe", lower=0.0, strict=False)),
    ]  # fmt: skip


DECLARED = _declarations()
#: The along-string profile (``docs/model.md``, "The distributed string"; the engine's
#: :func:`~drillstring.model.engine.string_profiles`) as array outputs of the FMI 3.0 twin, N =
#: string_elements long: each element's torque (table first) and the angular speed of the node at
#: each element's lower end (x = i/N, i = 1..N: the inner nodes, then the bit).
_ARRAYS = {
    SCALED: (
        fmu.ArrayOutput(
            "element_torque_minus_R0", "Torque of each string element less R0 (scaled: in units "
            "of C), from the table (the first: top_torque_minus_R0) to the bit", "string_elements"
        ),
        fmu.ArrayOutput(
            "node_dphi", "Angular speed perturbation of the node at the lower end of each string "
            "element (scaled), from below the table to the bit (the last: dphi)", "string_elements"
        ),
    ),
    SI: (
        fmu.ArrayOutput(
            "element_torque", "Torque of each string element, from the table (the first: "
            "top_torque) to the bit", "string_elements", unit="N.m", display_unit="kN.m"
        ),
        fmu.ArrayOutput(
            "node_speed", "Angular speed of the node at the lower end of each string element, "
            "from below the table to the bit (the last: bit_speed)", "string_elements",
            unit="rad/s", display_unit="rpm"
        ),
    ),
}  # fmt: skip
#: The engine options among the FMU's variables and their dimension (the same name in both unit
#: systems): the engine takes them scaled.
_OPTION_DIMENSIONS = {d.scaled: d.dimension for d in DECLARED if d.scaled in ("h", "event_tol")}


_SPEED = {
    SCALED: "dPhi/dtau = omega0 + dphi > 0, so dphi0 > -omega0 (checked at "
    "fmi2ExitInitializationMode)",
    SI: "the initial bit speed Omega0 + dphi0 > 0 (checked at fmi2ExitInitializationMode), as "
    "must the scaled parameter set of eqs. (15)-(16), beta = zeta mu xi <= 1 in particular",
}
_KIND = {SCALED: ", scaled form", SI: ", in SI units"}
_TIME_AND_UNITS = {
    SI: "All quantities are in SI units (the unit of each variable is declared, with its "
    "SI base units); time is in seconds, t = t* tau with t* = sqrt(I1/C), the time "
    "scale of the paper's scaled model, which the FMU integrates. The input is the "
    "absolute rotary-table torque R; the outputs are total angles, speeds and "
    "positions (not deviations): the bit angle is 0 at t = 0 of the nominal motion "
    "and the table angle is ahead of it by the twist of the string, nominally R0/C. "
    "The initial state is the deviation from the nominal motion at t = 0."
}
#: The outputs of the compiled step in each unit system (the io block's).
_FAST_KEYS = {SCALED: native.PLANT_SCALED_KEYS, SI: native.PLANT_SI_KEYS}


def _validity(system: UnitSystem) -> tuple[str, str]:
    """The FMU documentation's section on the model's validity, in the unit system's terms."""
    return (
        "The model holds while the bit cuts the rock: a depth of cut d < 0 (bit bouncing, "
        "Section II) is outside it. With on_invalid = stop (the default) fmi2DoStep returns "
        "fmi2Discard at the first such instant, located to within event_tol, and names it; with "
        "on_invalid = continue the run goes on, every episode is counted in the output "
        "bit_bounce and the step returns fmi2Warning with a message.",
        f"The bit must rotate forwards: {_SPEED[system.name]}. Where the bit stops rotating it "
        "sticks torsionally: with torsional_stick_model = true that phase is modelled "
        '(docs/model.md, "Torsional stick"), otherwise fmi2DoStep returns fmi2Discard there. A '
        "reverse rotation during torsional stick, a non-finite state and a delay that cannot be "
        "found in the history also end the run with fmi2Discard and a message.",
    )


class PlantFmu(fmu.FmuModel):
    """Drill-string plant (11)-(14), (17) in the unit system ``UNIT_SYSTEM``: input the table
    torque, outputs the bit's and the table's motion."""

    UNIT_SYSTEM: ClassVar[str] = SCALED
    SYSTEM: ClassVar[UnitSystem] = SCALED_UNITS
    VALIDITY = _validity(SCALED_UNITS)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        system = cls.SYSTEM = units.system(cls.UNIT_SYSTEM)
        cls.VARIABLES = units.variables(DECLARED, system)
        cls.ARRAYS = _ARRAYS[system.name]
        cls.FAST_KEYS = _FAST_KEYS[system.name]
        cls.FAST_SI = float(system.physical)
        cls.VALIDITY = _validity(system)
        cls.description = (
            "Axial-torsional drill-string stick-slip model of Besselink, van de Wouw and "
            "Nijmeijer (IEEE CCA 2011), eqs. (11)-(14) with Filippov wearflat contact (17)"
            + _KIND[system.name]
        )
        cls.TIME_AND_UNITS = _TIME_AND_UNITS.get(system.name, cls.TIME_AND_UNITS)

    engine: Engine | None = None
    _out: Mapping[str, Any] = MappingProxyType({})
    #: The io block of the plant's step (layout ``native.PLANT``), one per instance: the front
    #: layer's native fast path steps on it too.
    _io: np.ndarray | None = None
    _input = ""  # the name of the FMU's input
    #: The unit system of the step: the outputs in the io block (``_out``'s keys), SI or not
    #: (set for each generated class by :meth:`__init_subclass__`).
    FAST_KEYS: ClassVar[tuple[str, ...]] = native.PLANT_SCALED_KEYS
    FAST_SI: ClassVar[float] = 0.0
    _fast_block: fmu.FastPath | None = None
    _fast_kernel: Any = None

    # ----------------------------------------------------------------- the unit system
    #: The scales of the FMU's rig (set by :meth:`engine_setup`; the identity when scaled).
    scaling: Scales = SCALED_UNITS.scales()

    def engine_setup(
        self, v: Mapping[str, Any]
    ) -> tuple[ScaledParams, EngineOptions, Mapping[str, float], StringParams]:
        """The engine's parameters, options, initial perturbation and string from the FMU's
        values.

        The parameter set is the unit system's (:meth:`~drillstring.model.units.UnitSystem.
        parameter_set`); the initial state and the options ``h`` and ``event_tol`` are
        converted by its scales (time: divided by t* of the FMU's rig in SI)."""
        on_invalid = ON_INVALID[v["on_invalid"] - 1][0]
        named = {"n": v["n"], **{f: v[name] for name, f, *_ in _SCALED if name in v}}
        named.update((name, v[name]) for name, *_ in _PHYSICAL if name in v)
        # raises for a rig whose scaled set is invalid (beta > 1)
        params, scaling = self.SYSTEM.parameter_set(named)
        if self.SYSTEM.physical and not scaling.rig.Omega0 + v["dphi0"] > 0.0:
            raise ValueError(
                f"the initial bit speed Omega0 + dphi0 = {scaling.rig.Omega0 + v['dphi0']!r} "
                "rad/s is not > 0: the model needs a rotating bit (torsional stick at t = 0)"
            )
        initial = scaling.initial_to_scaled({key: float(v[name]) for name, key, _, _ in _INITIAL})
        scaled = {
            name: v[name] / scaling.factor(dimension)
            for name, dimension in _OPTION_DIMENSIONS.items()
        }
        if not scaled["event_tol"] <= _EVENT_TOL_MAX:
            raise ValueError(
                f"event_tol = {v['event_tol']!r}{self.SYSTEM.time_unit} is above 1e-10 t* = "
                f"{scaling.time(_EVENT_TOL_MAX)!r}{self.SYSTEM.time_unit}"
            )
        options = EngineOptions(
            **scaled, torsional_stick=bool(v["torsional_stick_model"]), on_invalid=on_invalid,
            keep_events=False,
        )  # fmt: skip
        kappa, mu = (
            (v["I_pipe"] / scaling.rig.I1, v["M_pipe"] / scaling.rig.M)
            if self.SYSTEM.physical
            else (v["pipe_inertia_ratio"], v["pipe_mass_ratio"])
        )
        string = StringParams(elements=v["string_elements"], kappa=kappa, axial_mass_ratio=mu)
        self.scaling = scaling
        return params, options, dataclasses.asdict(initial), string

    def converted_outputs(self, eng: Engine) -> Mapping[str, Any]:
        """The FMU's outputs from the engine's state."""
        if not self.SYSTEM.physical:
            return eng.outputs()
        T = eng.diagnostics()["torque_on_bit"]
        return self.scaling.plant_outputs(eng.outputs(), eng.tau, torque_on_bit=T)

    def _stopped(self, eng: Engine, status: Status) -> fmu.StepResult:
        """The result of a step the engine stopped in, at the FMU's time of the stop (the
        engine's message names the scaled time; SI adds t)."""
        t = self.scaling.time(eng.tau)
        message = f"{status.code}: {status.message}"
        if self.SYSTEM.time_unit:
            message += f" (t = {t!r}{self.SYSTEM.time_unit})"
        return fmu.StepResult(t, stop=message)

    def fast_constants(self) -> tuple[float, ...]:
        """The unit system's constants of the step (``native.PLANT.k``)."""
        if self.SYSTEM.physical:
            return self.scaling.plant_constants
        return (0.0,) * native.N_K

    def array_values(self, name: str) -> np.ndarray:
        """The along-string profile now (:data:`_ARRAYS`): the engine's
        :func:`~drillstring.model.engine.string_profiles` at the current sample, converted as
        the FMU's scalar outputs (SI: as ``top_torque`` and ``bit_speed``)."""
        eng = self.engine
        assert eng is not None
        scaled = eng.outputs()
        data = {k: np.array([scaled[k]]) for k in ("u", "du", "phi", "dphi", "theta", "dtheta")}
        data["tau"] = np.array([eng.tau])
        profile = string_profiles(eng.params, eng.string, data, eng.string_nodes()[None, :])
        torque, speed = profile["torque_minus_R0"][0], profile["dphi_node"][0, 1:]
        if not self.SYSTEM.physical:
            return {"element_torque_minus_R0": torque, "node_dphi": speed}[name]
        si = self.scaling.plant_outputs(
            {**scaled, "dphi": speed, "top_torque_minus_R0": torque}, eng.tau
        )
        return {"element_torque": si["top_torque"], "node_speed": si["bit_speed"]}[name]

    # ----------------------------------------------------------------- physics
    def configure(self, values: Mapping[str, Any]) -> None:
        self._use(self._new_engine(values))

    def _new_engine(self, v: Mapping[str, Any]) -> Engine:
        params, options, initial, string = self.engine_setup(v)
        return Engine(params, options=options, initial=initial, string=string)

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
            return self._stopped(eng, status)
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
        eng.set_input(self.scaling.torque_deviation(self.values[self._input]))
        status = eng.advance(self.scaling.tau(t + h))
        if status.ok:  # the compiled step refuses only what the engine refuses
            raise RuntimeError(f"the plant's step refused the step [{t!r}, {t + h!r}]")
        self._use(eng)
        return self._stopped(eng, status)

    # ----------------------------------------------------------------- native fast path
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
        if fields.get("engine") not in (True, False) or len(fields) != 1:
            raise ValueError(f"{fields!r} is not the plant's ({{'engine': true|false}})")
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


assert {d.scaled for d in DECLARED if d.causality == "output" and d.scaled} <= set(OUTPUT_KEYS)
assert tuple(name for name, _ in ON_INVALID) == ON_INVALID_CHOICES
assert native.PLANT_SCALED_KEYS == OUTPUT_KEYS, "the native step's outputs are the engine's"
