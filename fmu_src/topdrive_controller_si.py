"""FMI 2.0 co-simulation unit of the industrial top-drive controllers in SI units (pythonfmu
script of ``TopDriveControllerSI``).

The same controller as ``TopDriveController`` (``topdrive_controller.py``, bundled beside this
script): the laws of :mod:`drillstring.model.laws`, the sampling, the switch-on and the
lifecycle are that class's. Here the inputs are the bit's and the table's angles [rad] and
speeds [rad/s], the output is the absolute rotary-table torque R [N m], time is in seconds.

The laws are dimensionally homogeneous: with their parameters in SI units
(:meth:`SpeedPI.to_si <drillstring.model.laws.SpeedPI.to_si>`,
:meth:`ZTorque.to_si <drillstring.model.laws.ZTorque.to_si>`) and SI measurements -- the table
speed error ``table_speed - Omega0`` [rad/s], the string torque at the top
``C (table_angle - bit_angle)`` [N m] -- the same class puts out the torque in N m, with the
integral in rad and the filters discretised over the step in seconds. ``R_ff`` is the absolute
feed-forward torque R0 + C R_ff_scaled, so the output is the absolute table torque (the
high-pass removes the string's mean torque). The start values are the scaled build
configuration converted on the reference rig (``docs/reference_rig.md``)::

    kp_SI = C t* kp, ki_SI = C ki, z_gain_SI = z_gain/(C t*), omega_SI = omega/t*,
    R_ff_SI = C (R0/C + R_ff), t_on_SI = t* t_on.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import drillstring_fmu_support as fmu
from topdrive_controller import GAINS, TopDriveController

from drillstring.model.laws import Measurement, ZTorque
from drillstring.model.params import REFERENCE_RIG
from drillstring.model.units import SIScaling, setpoint_errors

_RIG = SIScaling(REFERENCE_RIG)
INPUTS = (
    ("bit_angle", "rad", None, "Measured bit angle Phi (plant output; forms the string torque)"),
    ("bit_speed", "rad/s", "rpm", "Bit speed dPhi/dt (plant output; not read: connector of the "
     "loop)"),
    ("table_angle", "rad", None, "Measured rotary-table angle Theta (plant output)"),
    ("table_speed", "rad/s", "rpm", "Measured rotary-table speed dTheta/dt (plant output)"),
)  # fmt: skip
BAKED = "; start value: the SoftTorque tuning baked in by build_fmus.py, in SI"


def _variables() -> tuple[fmu.Variable, ...]:
    out = [
        fmu.input_real(name, 0.0, desc, unit=unit, display_unit=display)
        for name, unit, display, desc in INPUTS
    ]
    out.append(
        fmu.output(
            "table_torque",
            "Real",
            "Rotary-table (top-drive) torque R = R_ff + kp e + ki I, absolute, held over the step",
            depends_on=["table_speed"],
            unit="N.m",
            display_unit="kN.m",
        )
    )
    out += [
        fmu.parameter("kp", "Real", 0.0, f"Proportional gain of the speed PI{BAKED}", min=0.0,
                      unit="N.m.s/rad"),
        fmu.parameter("ki", "Real", 0.0, f"Integral gain of the speed PI{BAKED}", min=0.0,
                      unit="N.m/rad"),
        fmu.parameter(
            "z_gain",
            "Real",
            0.0,
            "Torque feedback of Z-Torque: speed correction per string torque (1/Z, Z = "
            f"sqrt(C I1): impedance matching); 0: the plain speed PI{BAKED}",
            min=0.0,
            unit="rad/(N.m.s)",
        ),
        fmu.parameter("omega_hp", "Real", 0.3 / _RIG.t_star, "High-pass corner of the torque "
                      "feedback (read only when z_gain > 0)", min=fmu.POSITIVE, unit="rad/s"),
        fmu.parameter("omega_lp", "Real", 10.0 / _RIG.t_star, "Low-pass corner of the torque "
                      "feedback (read only when z_gain > 0)", min=fmu.POSITIVE, unit="rad/s"),
        fmu.parameter(
            "R_ff",
            "Real",
            0.0,
            "Feed-forward table torque R_ff = R0 - C K0 (eqs. (8), (31)); start value: the gains "
            "file baked in by build_fmus.py --gains, in SI",
            unit="N.m",
            display_unit="kN.m",
        ),
        fmu.parameter(
            "Omega0",
            "Real",
            REFERENCE_RIG.Omega0,
            "Speed set point of the top drive",
            min=fmu.POSITIVE,
            unit="rad/s",
            display_unit="rpm",
        ),
        fmu.parameter(
            "C",
            "Real",
            REFERENCE_RIG.C,
            "Torsional stiffness of the string: the string torque at the top is "
            "C (table_angle - bit_angle)",
            min=fmu.POSITIVE,
            unit="N.m/rad",
        ),
        fmu.parameter("t_on", "Real", 0.0, "Switch-on time of the law: before it only R_ff",
                      unit="s"),
        fmu.parameter("enabled", "Boolean", True, "Law enabled; false: R = R_ff always"),
    ]  # fmt: skip
    return tuple(out)


class TopDriveControllerSI(TopDriveController):
    """The top-drive controller in SI units: R [N m] from the measured angles and speeds."""

    MODEL = "TopDriveControllerSI"
    VARIABLES = _variables()
    OUTPUT = "table_torque"
    TIME_AND_UNITS = (
        "All quantities are in SI units (the unit of each variable is declared, with its SI base "
        "units); time is in seconds. The inputs are the plant's total angles and speeds, the "
        "output the absolute rotary-table torque; the speed error is taken from the set point "
        "Omega0."
    )
    description = (
        "Industrial top-drive controller (stiff speed PI, SoftTorque/SoftSpeed, Z-Torque) for "
        "the drill-string model of Besselink, van de Wouw and Nijmeijer (IEEE CCA 2011), in SI "
        "units, with bumpless switch-on at t_on"
    )

    def initial_values(self) -> Mapping[str, Any]:
        """The default tuning of the build configuration (scaled) converted on the reference
        rig (module docstring)."""
        scaled = super().initial_values()
        law = ZTorque(**scaled)
        si = law.to_si(REFERENCE_RIG)
        return {**{k: si[k] for k in GAINS}, "R_ff": _RIG.table_torque(law.R_ff)}

    def measured(self) -> Measurement:
        """Errors from the set point (Omega0 t, Omega0) and the string torque, in SI."""
        x = self.values
        e_phi, de_phi, e_theta, de_theta = setpoint_errors(
            x["Omega0"], self.time, x["bit_angle"], x["bit_speed"], x["table_angle"],
            x["table_speed"],
        )  # fmt: skip
        return Measurement(
            e_theta, de_theta, x["C"] * (x["table_angle"] - x["bit_angle"]), e_phi, de_phi
        )
