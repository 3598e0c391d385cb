"""FMI 2.0 co-simulation unit of the torsional controller in SI units (pythonfmu script of
``TorsionalControllerSI``).

The same controller as ``TorsionalController`` (``torsional_controller.py``, bundled beside this
script): the law (29)-(31) evaluated by :func:`drillstring.model.control.feedback_torque`, the
bumpless switch-on and the lifecycle are that class's. Here the inputs are the bit's and the
table's angles [rad] and speeds [rad/s], the output is the absolute rotary-table torque R [N m],
time is in seconds, and the law is :class:`drillstring.model.units.PhysicalFeedback`: the errors
are taken from the speed set point ``Omega0`` (angle Omega0 t, speed Omega0), the gains are in
N m/rad and N m s/rad. Their start values are the gains file of the synthesis (scaled, baked in
by ``build_fmus.py --gains``) converted on the reference rig (``docs/reference_rig.md``) by
:meth:`PhysicalFeedback.from_scaled <drillstring.model.units.PhysicalFeedback.from_scaled>`::

    F1_SI = C F1, F2_SI = C t* F2, F3_SI = C F3, F4_SI = C t* F4,
    K0_SI = K0 - R0/C, R_ff_SI = C (R0/C + R_ff), t_on_SI = t* t_on.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import drillstring_fmu_support as fmu
from torsional_controller import GAIN_NAMES, LATCH_ITEMS, TorsionalController

from drillstring.model.control import LATCH_MODES, AffineFeedback
from drillstring.model.params import REFERENCE_RIG
from drillstring.model.units import PhysicalFeedback, SIScaling

_RIG = SIScaling(REFERENCE_RIG)
INPUTS = (
    ("bit_angle", "rad", None, "Measured bit angle Phi (plant output)"),
    ("bit_speed", "rad/s", "rpm", "Measured bit speed dPhi/dt (plant output)"),
    ("table_angle", "rad", None, "Measured rotary-table angle Theta (plant output)"),
    ("table_speed", "rad/s", "rpm", "Measured rotary-table speed dTheta/dt (plant output)"),
)
_X = (
    ("e_phi - phi_ref, e_phi = bit_angle - Omega0 t", "N.m/rad"),
    ("de_phi = bit_speed - Omega0", "N.m.s/rad"),
    ("e_phi - e_theta - K0 - twist_ref, e_theta = table_angle - Omega0 t", "N.m/rad"),
    ("de_theta = table_speed - Omega0", "N.m.s/rad"),
)


def _variables() -> tuple[fmu.Variable, ...]:
    out = [
        fmu.input_real(name, 0.0, desc, unit=unit, display_unit=display)
        for name, unit, display, desc in INPUTS
    ]
    out.append(
        fmu.output(
            "table_torque",
            "Real",
            "Rotary-table (top-drive) torque R = R_ff + F x, absolute (eqs. (29)-(31) in SI)",
            depends_on=[name for name, *_ in INPUTS],
            unit="N.m",
            display_unit="kN.m",
        )
    )
    baked = "; start value: the synthesis result baked in by build_fmus.py --gains, in SI"
    out += [
        fmu.parameter(name, "Real", 0.0, f"State-feedback gain on x{i + 1} = {x}{baked}", unit=u)
        for i, (name, (x, u)) in enumerate(zip(GAIN_NAMES, _X, strict=True))
    ]
    out += [
        fmu.parameter(
            "K0",
            "Real",
            0.0,
            f"Twist offset K0 of x3 (eq. (30), less the nominal twist R0/C){baked}",
            unit="rad",
        ),
        fmu.parameter(
            "R_ff",
            "Real",
            0.0,
            f"Feed-forward table torque R_ff = R0 - C K0 (eqs. (8), (31)){baked}",
            unit="N.m",
            display_unit="kN.m",
        ),
        fmu.parameter(
            "Omega0",
            "Real",
            REFERENCE_RIG.Omega0,
            "Speed set point: the nominal rotary speed the errors are taken from",
            min=fmu.POSITIVE,
            unit="rad/s",
            display_unit="rpm",
        ),
        fmu.parameter(
            "t_on", "Real", 0.0, "Switch-on time of the feedback: before it only R_ff", unit="s"
        ),
        fmu.parameter("enabled", "Boolean", True, "Feedback enabled; false: R = R_ff always"),
        fmu.enumeration(
            "latch",
            "Latch",
            LATCH_ITEMS,
            "angle",
            'Bumpless switch-on (docs/model.md, "Bumpless switch-on"): 1 = none (the paper\'s '
            "law), 2 = angle (phi_ref = e_phi at t_on), 3 = angle+twist (also twist_ref)",
        ),
    ]
    return tuple(out)


class TorsionalControllerSI(TorsionalController):
    """The state feedback (29)-(31) in SI units: R [N m] from the measured angles and speeds."""

    MODEL = "TorsionalControllerSI"
    VARIABLES = _variables()
    OUTPUT = "table_torque"
    TIME_AND_UNITS = (
        "All quantities are in SI units (the unit of each variable is declared, with its SI base "
        "units); time is in seconds. The inputs are the plant's total angles and speeds, the "
        "output the absolute rotary-table torque; the law acts on their errors from the speed "
        "set point Omega0 (angle Omega0 t, speed Omega0)."
    )
    description = (
        "Torsional stick-slip controller R = R_ff + F x of Besselink, van de Wouw and Nijmeijer "
        "(IEEE CCA 2011), Section V, eqs. (29)-(31), in SI units, with bumpless switch-on at t_on"
    )

    FAST_SI = 1.0

    def initial_values(self) -> Mapping[str, Any]:
        """The gains of the build configuration (scaled) converted on the reference rig."""
        g = self.config["gains"]
        law = PhysicalFeedback.from_scaled(
            AffineFeedback(F=tuple(g["F"]), K0=g["K0"], R_ff=g["R_ff"]), _RIG
        )
        return {**dict(zip(GAIN_NAMES, law.F, strict=True)), "K0": law.K0, "R_ff": law.R_ff}

    def new_law(self, v: Mapping[str, Any]) -> PhysicalFeedback:
        return PhysicalFeedback(
            F=tuple(v[name] for name in GAIN_NAMES),  # type: ignore[arg-type]
            K0=v["K0"],
            R_ff=v["R_ff"],
            Omega0=v["Omega0"],
            t_on=v["t_on"],
            latch=LATCH_MODES[v["latch"] - 1],
        )

    def measured(self) -> tuple[float, float, float, float]:
        law, x = self.law, self.values
        assert law is not None
        return law.errors(
            self.time, x["bit_angle"], x["bit_speed"], x["table_angle"], x["table_speed"]
        )
