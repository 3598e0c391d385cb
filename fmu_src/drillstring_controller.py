"""FMI 2.0 co-simulation units of the controllers (pythonfmu script; ``build_fmus.py`` generates
``TorsionalController``, ``TopDriveController`` and their SI variants from the one class here).

A controller FMU is a :class:`drillstring.model.digital.controller.DigitalController`: a law of
:mod:`drillstring.model.laws` between the sensing of :mod:`drillstring.model.sensing` and the top
drive of :mod:`drillstring.model.topdrive`, run by the compiled functions of
:mod:`drillstring.model.digital.block` on its block (no control code lives here, and the
lifecycle is :class:`drillstring_fmu_support.FmuModel`). At each communication point it puts out
the torque for the current inputs, held over the step; ``fmi2DoStep(t, h)`` commits the sample
at t (the law's update, the top drive's torque, the sensing) over h. Under a fixed-step master
with macro step Ts this is the sampled loop of :func:`drillstring.model.sampled.simulate_sampled`
bit for bit: both run the same compiled sample. Switch-on at ``t_on`` (``docs/model.md``,
"Bumpless switch-on"): before it, or with ``enabled`` false, only ``R_ff`` acts; at the first
communication point at or after ``t_on`` the law starts from the current inputs.

Two families (``FAMILY``), the same script:

* ``"lmi"`` -- :class:`~drillstring.model.laws.SampledAffine`, the paper's state feedback (29)-(31)
  with the gains of the synthesis (``build_fmus.py --gains``), bumpless latch, saturation
  behaviour;
* ``"topdrive"`` -- :class:`~drillstring.model.laws.ZTorque`: the industrial speed loop of the
  top drive, ``z_gain = 0`` the plain speed PI (stiff PI, SoftSpeed), ``z_gain > 0`` Z-Torque;
  the law is chosen by Real parameters alone (hosts that cannot set an Enumeration still run the
  law they are given), start values the SoftSpeed tuning of the build configuration.

The variables are declared once (:mod:`drillstring_fmu_units`): the law's parameters from its
table, the operating point, the top drive's limits (off unless ``top_drive`` is true) and the
sensing. The unit system (``UNIT_SYSTEM``) is the class's: in SI the inputs are the plant's total
angles and speeds, the output the absolute table torque, the parameters in SI units, and the rig
scales ``C`` and ``I1`` convert them (``docs/si_fmus.md``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import drillstring_fmu_support as fmu
import drillstring_fmu_units as units
import numpy as np

from drillstring.model import native
from drillstring.model.digital.block import fmu_output, fmu_step
from drillstring.model.digital.controller import DigitalController, OperatingPoint, check_block
from drillstring.model.digital.layout import BLOCK
from drillstring.model.laws import Law, SampledAffine, ZTorque
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.sensing import Sensing
from drillstring.model.timing import Timing
from drillstring.model.topdrive import TDS_11SA, TopDrive, top_drive

SCALED, SI = units.SCALED, units.SI
declare = units.declare

#: The connectors (scaled name, SI name, SI unit, SI display unit, description).
INPUTS = (
    ("phi", "bit_angle", "rad", None, "Measured bit angle"),
    ("dphi", "bit_speed", "rad/s", "rpm", "Measured bit speed"),
    ("theta", "table_angle", "rad", None, "Measured rotary-table angle"),
    ("dtheta", "table_speed", "rad/s", "rpm", "Measured rotary-table speed"),
)
_INPUT_NOTES = {
    SCALED: " perturbation from the nominal motion (plant output, eqs. (9)-(10))",
    SI: " (plant output; total, the law acts on its error from the nominal motion)",
}
_SI_INPUT_START = {
    "bit_angle": 0.0,
    "bit_speed": REFERENCE_RIG.Omega0,
    "table_angle": REFERENCE_RIG.R0 / REFERENCE_RIG.C,
    "table_speed": REFERENCE_RIG.Omega0,
}
#: Enumeration types of the choice parameters.
_TYPES = {
    "latch": "Latch",
    "on_saturation": "OnSaturation",
    "anti_windup": "AntiWindup",
    "braking": "Braking",
    "downhole": "Downhole",
    "torque": "TorqueSensing",
}
#: Top-drive limits a host switches off with 0 (a start value cannot be infinite).
_ZERO_IS_NONE = ("rate", "P_max")
#: The FMU's names of the controller's own timing (:class:`Timing`; the sensing has its own
#: telemetry ``period`` and ``latency``).
_TIMING_NAMES = {"period": "control_period", "latency": "control_latency"}


@dataclass(frozen=True)
class Family:
    """A controller family: its law class and what differs between families."""

    law: type[Law]
    depends_on: tuple[str, ...]
    description: str
    defaults: Mapping[str, Any]
    build: Callable[[Mapping[str, Any]], Law]
    config: Callable[[Mapping[str, Any]], dict[str, Any]]


def _lmi_config(config: Mapping[str, Any]) -> dict[str, Any]:
    g = config["gains"]
    return {**dict(zip(("F[1]", "F[2]", "F[3]", "F[4]"), g["F"], strict=True)), "K0": g["K0"],
            "R_ff": g["R_ff"]}  # fmt: skip


def _topdrive_config(config: Mapping[str, Any]) -> dict[str, Any]:
    top = config["topdrive"]
    tuning = top["tunings"][top["default"]]
    keys = ("kp", "ki", "z_gain", "omega_hp", "omega_lp")
    return {**{k: tuning[k] for k in keys}, "R_ff": config["gains"]["R_ff"]}


def _exposed(family: Family) -> tuple[Any, ...]:
    """The law's parameters the FMU declares: those of the family's defaults (the affine law's
    torque gain, the string design's, is not one: the FMU keeps the paper's law and its value
    references)."""
    return tuple(p for p in family.law.PARAMETERS if p.name in family.defaults)


FAMILIES: dict[str, Family] = {
    "lmi": Family(
        law=SampledAffine,
        depends_on=("phi", "dphi", "theta", "dtheta"),
        description="Torsional stick-slip controller R - R0 = R_ff + F x of Besselink, van de "
        "Wouw and Nijmeijer (IEEE CCA 2011), Section V, eqs. (29)-(31), with bumpless "
        "switch-on at t_on",
        defaults={
            "F[1]": 0.0,
            "F[2]": 0.0,
            "F[3]": 0.0,
            "F[4]": 0.0,
            "K0": 0.0,
            "R_ff": 0.0,
            "t_on": 0.0,
            "latch": "angle",
            "on_saturation": "none",
        },  # fmt: skip
        build=SampledAffine.from_values,
        config=_lmi_config,
    ),
    "topdrive": Family(
        law=ZTorque,
        depends_on=("dtheta",),
        description="Industrial top-drive controller (stiff speed PI, SoftSpeed, Z-Torque) for "
        "the drill-string model of Besselink, van de Wouw and Nijmeijer (IEEE CCA 2011), with "
        "bumpless switch-on at t_on",
        defaults={
            "kp": 0.0,
            "ki": 0.0,
            "z_gain": 0.0,
            "omega_hp": 0.3,
            "omega_lp": 10.0,
            "R_ff": 0.0,
            "t_on": 0.0,
            "anti_windup": "back-calculation",
            "tracking_time": 0.0,
        },  # fmt: skip
        build=ZTorque.from_values,
        config=_topdrive_config,
    ),
}

#: The reference rig's top drive (``docs/controllers.md``, "The top drive"), scaled.
_TOP_DRIVE = top_drive(TDS_11SA, REFERENCE_RIG)


def _declarations(family: Family) -> list[units.Declared]:
    out = [
        declare((scaled, si), "Real", "input", desc, start=0.0, si_start=_SI_INPUT_START[si],
                si_unit=unit, si_display=display, scaled_note=_INPUT_NOTES[SCALED],
                si_note=_INPUT_NOTES[SI])
        for scaled, si, unit, display, desc in INPUTS
    ]  # fmt: skip
    out.append(
        declare(
            ("R_minus_R0", "table_torque"),
            "Real",
            "output",
            "Rotary-table (top-drive) torque applied, held over the step",
            si_unit="N.m",
            si_display="kN.m",
            scaled_note=": the deviation R - R0 (scaled, eq. (13))",
            si_note=": R, absolute",
            depends_on=family.depends_on,
        )
    )
    out += units.from_table(_exposed(family), dict(family.defaults), _TYPES)
    out += [
        declare(("omega0", "Omega0"), "Real", "parameter",
                "Nominal rotary speed: the speed set point the errors are taken from",
                dimension="speed", start=REFERENCE.omega0, si_start=REFERENCE_RIG.Omega0,
                min=fmu.POSITIVE),
        declare("R0", "Real", "parameter",
                "Nominal table torque R0 (eq. (8)): the top drive's limits are on R0 + (R - R0)",
                dimension="torque", start=REFERENCE.R0, si_start=REFERENCE_RIG.R0),
        declare(("rho", "I2"), "Real", "parameter",
                "Inertia of the rotary table or top drive (scaled: rho = I2/I1, eq. (16)); for "
                "the string torque estimated from the motor torque",
                dimension="inertia", start=REFERENCE.rho, si_start=REFERENCE_RIG.I2,
                min=fmu.POSITIVE),
        declare((None, "C"), "Real", "parameter",
                "Torsional stiffness of the string: the torque scale of the conversion to the "
                "scaled law (eq. (16))", dimension="stiffness", si_start=REFERENCE_RIG.C,
                min=fmu.POSITIVE),
        declare((None, "I1"), "Real", "parameter",
                "Inertia of the bit end of the string: with C the time scale t* = sqrt(I1/C)",
                dimension="inertia", si_start=REFERENCE_RIG.I1, min=fmu.POSITIVE),
        declare("enabled", "Boolean", "parameter",
                "Controller enabled; false: the feed-forward R_ff alone, always", start=True),
        declare("top_drive", "Boolean", "parameter",
                "Model the top drive's limits below (start values: the NOV TDS-11SA on the "
                "reference rig); false: the torque is applied as commanded", start=False),
    ]  # fmt: skip
    td = _TOP_DRIVE.values()
    td.update({k: 0.0 for k in _ZERO_IS_NONE if not math.isfinite(td[k])})
    for p_decl in units.from_table(TopDrive.PARAMETERS, td, _TYPES):
        if p_decl.scaled in _ZERO_IS_NONE:
            p_decl = dataclasses.replace(
                p_decl,
                description=p_decl.description + "; 0: none",
                options={**p_decl.options, "min": 0.0},
            )
        out.append(p_decl)
    sensing = Sensing().values()
    for p_decl in units.from_table(Sensing.PARAMETERS, sensing, _TYPES):
        if p_decl.scaled == "seed":
            p_decl = declare("seed", "Integer", "parameter", p_decl.description, start=0, min=0)
        out.append(p_decl)
    # declared last, so that the variables before keep their value references
    out += units.from_table(Timing.PARAMETERS, Timing().values(), _TYPES, rename=_TIMING_NAMES)
    return out


class ControllerFmu(fmu.FmuModel):
    """A digital controller (family ``FAMILY``) in the unit system ``UNIT_SYSTEM``."""

    FAMILY: ClassVar[str] = "lmi"
    UNIT_SYSTEM: ClassVar[str] = SCALED
    DECLARED: ClassVar[tuple[units.Declared, ...]] = ()
    OUTPUT: ClassVar[str] = "R_minus_R0"
    INPUT_NAMES: ClassVar[tuple[str, ...]] = ()
    VALIDITY = (
        "A digital law without limits of validity: finite inputs give a finite output. Before "
        "t_on, or with enabled = false, the law's command is R_ff; the law starts from the "
        "inputs at the first communication point at or after t_on, and its state is updated at "
        "every step with the inputs held over the step (zero-order hold); with control_period > "
        "0 at the first step at or after each multiple of it instead, its command reaching the "
        "drive control_latency later. With top_drive = true "
        "the command passes the top drive's limits (torque range, power, speed range, braking, "
        "lag or rate limit) before it is applied.",
    )

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.FAMILY not in FAMILIES:
            raise ValueError(f"{cls.__name__}: unknown family {cls.FAMILY!r}")
        family = FAMILIES[cls.FAMILY]
        cls.DECLARED = tuple(_declarations(family))
        cls.VARIABLES = units.variables(cls.DECLARED, cls.UNIT_SYSTEM)
        cls.OUTPUT = units.name_in(cls.DECLARED, cls.UNIT_SYSTEM, "R_minus_R0")
        cls.INPUT_NAMES = tuple(units.name_in(cls.DECLARED, cls.UNIT_SYSTEM, s) for s, *_ in INPUTS)
        cls.description = family.description + (" (SI units)" if cls.UNIT_SYSTEM == SI else "")
        if cls.UNIT_SYSTEM == SI:
            cls.TIME_AND_UNITS = (
                "All quantities are in SI units (the unit of each variable is declared, with its "
                "SI base units); time is in seconds. The inputs are the plant's total angles and "
                "speeds, the output the absolute rotary-table torque; the law acts on their "
                "errors from the nominal motion (angle Omega0 t, speed Omega0, twist R0/C) and "
                "runs in the paper's scaled units, converted with C and t* = sqrt(I1/C)."
            )

    block: np.ndarray | None = None
    _fast_block: fmu.FastPath | None = None

    # ----------------------------------------------------------------- the unit system
    def _scales(self, v: Mapping[str, Any]) -> tuple[float, float]:
        """(C, t*) of the conversion to the scaled law (1, 1 in scaled units)."""
        if self.UNIT_SYSTEM == SI:
            return v["C"], math.sqrt(v["I1"] / v["C"])
        return 1.0, 1.0

    def _choices(self, table: Any, v: Mapping[str, Any]) -> dict[str, Any]:
        """The values of a table's parameters, Enumeration codes as their items' names."""
        out = {}
        for p in table:
            out[p.name] = p.choices[v[p.name] - 1] if p.choices else v[p.name]
        return out

    def initial_values(self) -> Mapping[str, Any]:
        """The family's start values of this FMU's build configuration (scaled, converted for
        SI): gains of the synthesis or the default tuning."""
        values = FAMILIES[self.FAMILY].config(self.config)
        if self.UNIT_SYSTEM == SI:
            dims = {d.scaled: d.dimension for d in self.DECLARED}
            values = {k: x * units.si_factor(dims[k]) for k, x in values.items()}
        return values

    def controller(self, v: Mapping[str, Any]) -> tuple[DigitalController, OperatingPoint]:
        """The digital controller and its operating point (scaled) of the parameter values."""
        family = FAMILIES[self.FAMILY]
        C, t = self._scales(v)
        scales = _Scales(C, t)
        law_values = self._choices(_exposed(family), v)
        if self.UNIT_SYSTEM == SI:
            law = family.law.from_si(scales, law_values)
            point = OperatingPoint(v["Omega0"] * t, v["R0"] / C, v["I2"] / v["I1"])
        else:
            law = family.build(law_values)
            point = OperatingPoint(v["omega0"], v["R0"], v["rho"])
        drive = None
        if v["top_drive"]:
            limits = self._choices(TopDrive.PARAMETERS, v)
            for k in _ZERO_IS_NONE:
                if limits[k] == 0.0:
                    limits[k] = math.inf
            drive = (
                TopDrive.from_si(scales, limits) if self.UNIT_SYSTEM == SI else TopDrive(**limits)
            )
        settings = self._choices(Sensing.PARAMETERS, v)
        if settings["downhole"] == "observer":
            raise ValueError(
                "downhole = observer needs the observer's gains, which an FMU parameter cannot "
                "carry: use ideal or telemetry (the observer runs in simulate_sampled)"
            )
        sensing = (
            Sensing.from_si(scales, settings) if self.UNIT_SYSTEM == SI else Sensing(**settings)
        )
        times = {name: v[fmu_name] for name, fmu_name in _TIMING_NAMES.items()}
        timing = Timing.from_si(scales, times) if self.UNIT_SYSTEM == SI else Timing(**times)
        controller = DigitalController(
            law, drive, sensing, enabled=bool(v["enabled"]), timing=timing
        )
        return controller, point

    # ----------------------------------------------------------------- physics
    def configure(self, values: Mapping[str, Any]) -> None:
        self.block = self._block_at_rest(values)

    def _block_at_rest(self, values: Mapping[str, Any]) -> np.ndarray:
        controller, point = self.controller(values)
        b = controller.block(point)
        if self.UNIT_SYSTEM == SI:
            C, t = self._scales(values)
            b[BLOCK.si] = 1.0
            b[BLOCK.t_star] = t
            b[BLOCK.C] = C
            b[BLOCK.omega0_si] = values["Omega0"]
            b[BLOCK.R0_si] = values["R0"]
        return b

    def _load_inputs(self) -> np.ndarray:
        b = self.block
        assert b is not None
        for i, name in enumerate(self.INPUT_NAMES):
            b[BLOCK.inputs + i] = self.values[name]
        b[BLOCK.time] = self.time
        return b

    def output_values(self) -> Mapping[str, Any]:
        b = self._load_inputs()
        fmu_output(b)
        return {self.OUTPUT: float(b[BLOCK.output])}

    def advance(self, t: float, h: float) -> fmu.StepResult:
        b = self._load_inputs()
        fmu_step(b, t, h)
        return fmu.StepResult(t + h)

    # ----------------------------------------------------------------- native fast path
    def fast_path(self) -> fmu.FastPath | None:
        if not native.AVAILABLE or self.block is None:
            return None
        block = self._fast_block
        if block is None or block.io is not self.block:
            step, outputs = native.controller_functions()
            at = {name: BLOCK.inputs + i for i, name in enumerate(self.INPUT_NAMES)}
            block = fmu.FastPath(self.block, step, outputs, at, {self.OUTPUT: BLOCK.output})
            self._fast_block = block
        return block

    # ----------------------------------------------------------------- FMU state
    def save(self) -> tuple[dict[str, Any], Any, Callable[[], bytes]]:
        if self.block is None:
            return {"block": False}, None, lambda: b""
        snapshot = self.block.copy()
        return {"block": True}, snapshot, snapshot.tobytes

    def restore(self, fields: Mapping[str, Any], snapshot: Any, payload: bytes | None) -> None:
        if fields.get("block") not in (True, False) or len(fields) != 1:
            raise ValueError(f"{fields!r} is not the controller's ({{'block': true|false}})")
        if not fields["block"]:
            self.block = None
            return
        block = self._block_at_rest(self.values)
        if snapshot is not None:
            saved = snapshot
        else:
            data = payload or b""
            if len(data) % 8:
                raise ValueError(f"the controller block is {len(data)} bytes, not whole float64s")
            saved = np.frombuffer(data, np.float64)
        check_block(saved, block)  # before anything is changed
        block[:] = saved
        self.block = block


@dataclass(frozen=True)
class _Scales:
    C: float
    t_star: float
