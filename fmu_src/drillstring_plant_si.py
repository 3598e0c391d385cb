"""FMI 2.0 co-simulation unit of the drill-string plant in SI units (pythonfmu script of
``DrillStringPlantSI``).

The same plant as ``DrillStringPlant`` (``drillstring_plant.py``, bundled beside this script): the
same engine, lifecycle, FMU states and validity rules; this class replaces only the variables and
the conversions between the FMU's SI quantities and the engine's scaled ones, which are
:class:`drillstring.model.units.SIScaling` (eqs. (15)-(16) of the physical parameter set the FMU
is given): time in seconds (t = t* tau), the absolute rotary-table torque R in N m as input, the
bit's and table's angles and speeds, the axial position and velocity of the bit, weight and
torque on bit, depth of cut, delay and rate of penetration as outputs. The parameters are the
physical set of eqs. (1)-(8) (start values: the reference rig, ``docs/reference_rig.md``), the
initial state the deviation from the nominal motion at t = 0 in SI units.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import drillstring_fmu_support as fmu
from drillstring_plant import _OUTPUTS, ON_INVALID, DrillStringPlant

from drillstring.model import native
from drillstring.model.engine import Engine, EngineOptions
from drillstring.model.experiments import FIG5
from drillstring.model.params import REFERENCE_RIG, PhysicalParams, ScaledParams
from drillstring.model.units import PLANT_SI, SIScaling
from drillstring.validation import check_real

_ENGINE_DEFAULTS = EngineOptions()
_RIG = SIScaling(REFERENCE_RIG)
#: The engine's event tolerance in scaled time is at most this (EngineOptions.event_tol).
_EVENT_TOL_MAX = 1e-10


def _physical_field(field: str) -> Callable[[Any], Any]:
    """Check of one field of PhysicalParams on its own (the others at the reference rig); the
    combination is checked at fmi2ExitInitializationMode."""

    def check(value: Any) -> Any:
        dataclasses.replace(REFERENCE_RIG, **{field: value})
        return value

    return check


def _positive(name: str) -> Callable[[Any], Any]:
    def check(value: Any) -> Any:
        return check_real(name, value, lower=0.0)

    return check


P = fmu.POSITIVE
#: PhysicalParams field, min, unit, display unit, description (start: the reference rig).
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
#: FMU name, initial-state key, unit, display unit, description (deviation at t = 0).
_INITIAL = (
    ("u0", "u", "m", "mm", "Initial axial bit position deviation from the nominal motion"),
    ("du0", "du", "m/s", "mm/s", "Initial axial bit velocity deviation from V0"),
    ("phi0", "phi", "rad", None, "Initial bit angle deviation from the nominal motion"),
    ("dphi0", "dphi", "rad/s", "rpm", "Initial bit speed deviation from Omega0, > -Omega0"),
    ("theta0", "theta", "rad", None, "Initial table angle deviation from the nominal motion"),
    ("dtheta0", "dtheta", "rad/s", "rpm", "Initial table speed deviation from Omega0"),
)
#: The Integer outputs (contact mode and counters) are the scaled plant's.
_INTEGER_OUTPUTS = {name: (kind, desc) for name, kind, desc in _OUTPUTS if kind == "Integer"}
#: The Fig. 5 start: the bit slowed down, dphi/dtau(0) = -2.5 (scaled) in rad/s.
_START = _RIG.initial_to_si(FIG5.initial())


def _variables() -> tuple[fmu.Variable, ...]:
    out: list[fmu.Variable] = [
        fmu.input_real(
            "table_torque",
            _RIG.table_torque(0.0),
            "Rotary-table (top-drive) torque R, absolute, held constant over each communication "
            "step (start value: the nominal torque R0 of eq. (8))",
            unit="N.m",
            display_unit="kN.m",
        )
    ]
    out += [
        fmu.output(q.name, "Real", q.description, unit=q.unit, display_unit=q.display)
        for q in PLANT_SI
    ]
    out += [fmu.output(name, kind, desc) for name, (kind, desc) in _INTEGER_OUTPUTS.items()]
    out.append(
        fmu.parameter(
            "n",
            "Integer",
            REFERENCE_RIG.n,
            "Number of blades of the drag bit (eq. (5))",
            min=1,
            check=_physical_field("n"),
        )
    )
    for name, lo, unit, display, desc in _PHYSICAL:
        out.append(
            fmu.parameter(
                name,
                "Real",
                getattr(REFERENCE_RIG, name),
                desc,
                min=lo,
                check=_physical_field(name),
                unit=unit,
                display_unit=display,
            )
        )
    for name, key, unit, display, desc in _INITIAL:
        out.append(fmu.parameter(name, "Real", _START[key], desc, unit=unit, display_unit=display))
    out += [
        fmu.parameter(
            "h",
            "Real",
            _RIG.time(_ENGINE_DEFAULTS.h),
            "Nominal RK4 step of the engine > 0; each communication step is split into equal "
            "steps no longer than h",
            min=P,
            check=_positive("h"),
            unit="s",
        ),
        fmu.parameter(
            "event_tol",
            "Real",
            _RIG.time(_ENGINE_DEFAULTS.event_tol),
            "Time tolerance of the engine's event location, in (0, 1e-10 t*] with t* = sqrt(I1/C)",
            min=P,
            check=_positive("event_tol"),
            unit="s",
        ),
        fmu.parameter(
            "torsional_stick_model",
            "Boolean",
            _ENGINE_DEFAULTS.torsional_stick,
            'Model torsional stick of the bit (docs/model.md, "Torsional stick", our '
            "reconstruction); false: the run stops (fmi2Discard) when the bit stops rotating",
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


class DrillStringPlantSI(DrillStringPlant):
    """The drill-string plant (11)-(14), (17) in SI units: input R [N m], time in seconds."""

    MODEL = "DrillStringPlantSI"
    VARIABLES = _variables()
    TIME_AND_UNITS = (
        "All quantities are in SI units (the unit of each variable is declared, with its SI base "
        "units); time is in seconds, t = t* tau with t* = sqrt(I1/C), the time scale of the "
        "paper's scaled model, which the FMU integrates. The input is the absolute rotary-table "
        "torque R; the outputs are total angles, speeds and positions (not deviations): the bit "
        "angle is 0 at t = 0 of the nominal motion and the table angle is ahead of it by the twist "
        "of the string, nominally R0/C. The initial state is the deviation from the nominal "
        "motion at t = 0."
    )
    VALIDITY = (
        "The model holds while the bit cuts the rock: a depth of cut d < 0 (bit bouncing, "
        "Section II) is outside it. With on_invalid = stop (the default) fmi2DoStep returns "
        "fmi2Discard at the first such instant, located to within event_tol, and names it (in "
        "the scaled time tau and in seconds); with on_invalid = continue the run goes on, every "
        "episode is counted in the output bit_bounce and the step returns fmi2Warning.",
        "The bit must rotate forwards: the initial bit speed Omega0 + dphi0 > 0 (checked at "
        "fmi2ExitInitializationMode), as must the scaled parameter set of eqs. (15)-(16), "
        "beta = zeta mu xi <= 1 in particular. Where the bit stops rotating it sticks "
        "torsionally: with torsional_stick_model = true that phase is modelled (docs/model.md, "
        '"Torsional stick"), otherwise fmi2DoStep returns fmi2Discard there. A reverse rotation '
        "during torsional stick, a non-finite state and a delay that cannot be found in the "
        "history also end the run with fmi2Discard and a message.",
    )
    description = (
        "Axial-torsional drill-string stick-slip model of Besselink, van de Wouw and Nijmeijer "
        "(IEEE CCA 2011), eqs. (11)-(14) with Filippov wearflat contact (17), in SI units"
    )

    scaling: SIScaling = _RIG

    def engine_setup(
        self, v: Mapping[str, Any]
    ) -> tuple[ScaledParams, EngineOptions, Mapping[str, float]]:
        rig = PhysicalParams(n=v["n"], **{name: v[name] for name, *_ in _PHYSICAL})
        scaling = SIScaling(rig)  # raises for a rig whose scaled set is invalid (beta > 1)
        speed = rig.Omega0 + v["dphi0"]
        if not speed > 0.0:
            raise ValueError(
                f"the initial bit speed Omega0 + dphi0 = {speed!r} rad/s is not > 0: the model "
                "needs a rotating bit (torsional stick at t = 0)"
            )
        tol = scaling.tau(v["event_tol"])
        if not tol <= _EVENT_TOL_MAX:
            raise ValueError(
                f"event_tol = {v['event_tol']!r} s is above 1e-10 t* = "
                f"{_EVENT_TOL_MAX * scaling.t_star!r} s"
            )
        options = EngineOptions(
            h=scaling.tau(v["h"]),
            torsional_stick=bool(v["torsional_stick_model"]),
            on_invalid=ON_INVALID[v["on_invalid"] - 1][0],
            event_tol=tol,
            keep_events=False,
        )
        initial = scaling.initial_to_scaled({key: float(v[name]) for name, key, *_ in _INITIAL})
        self.scaling = scaling
        return scaling.scaled, options, dataclasses.asdict(initial)

    def engine_input(self) -> float:
        return self.scaling.torque_deviation(self.values["table_torque"])

    def engine_time(self, t: float) -> float:
        return self.scaling.tau(t)

    def fmu_time(self, tau: float) -> float:
        return self.scaling.time(tau)

    def converted_outputs(self, eng: Engine) -> Mapping[str, Any]:
        T = eng.diagnostics()["torque_on_bit"]
        return self.scaling.plant_outputs(eng.outputs(), eng.tau, torque_on_bit=T)

    FAST_KEYS = native.PLANT_SI_KEYS
    FAST_SI = 1.0

    def fast_constants(self) -> tuple[float, ...]:
        return self.scaling.plant_constants

    def stop_message(self, eng: Engine, message: str) -> str:
        return f"{message} (t = {self.scaling.time(eng.tau)!r} s)"
