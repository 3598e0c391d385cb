"""FMI 2.0 co-simulation unit of the industrial top-drive controllers (pythonfmu script of
``TopDriveController``).

A digital speed controller of the top drive (``docs/controllers.md``): a PI on the rotary-table
speed whose set point is, optionally, lowered by the filtered string torque over the string's
impedance. The laws are those of :mod:`drillstring.model.laws`, evaluated by
:func:`~drillstring.model.laws.sample_output` and :func:`~drillstring.model.laws.sample_update`
(no control code lives here, and the lifecycle is :class:`drillstring_fmu_support.FmuModel`):

* ``z_gain = 0``: :class:`~drillstring.model.laws.SpeedPI`, ``R - R0 = R_ff + kp e + ki I`` with
  ``e = -dtheta`` -- the stiff PI and SoftTorque/SoftSpeed, which differ only in their gains;
* ``z_gain > 0``: :class:`~drillstring.model.laws.ZTorque`, the same PI with
  ``e = -dtheta - z_gain LP(HP(theta - phi))`` (Z-Torque).

The FMU is the sampler: at each communication point it puts out the law's torque for the
current inputs and holds it over the step (the output depends directly on ``dtheta`` only); each
``fmi2DoStep(t, h)`` updates the law's state (integral, filters) over ``h`` with the inputs at
``t``. Under a fixed-step master with macro step Ts this is the sampled loop of
:func:`drillstring.model.sampled.simulate_sampled`. Switch-on at ``t_on`` as for the LMI
controller (``docs/model.md``, "Bumpless switch-on"): before it only ``R_ff`` acts; at the first
communication point at or after ``t_on`` the law starts from the current inputs (integral
preset for a continuous torque, high-pass at rest). ``enabled`` = false keeps ``R_ff`` alone.

The inputs are those of the LMI controller (``TorsionalController``), so that this FMU takes its
place in the closed loop: the string torque at the top, C (Theta - Phi), is formed from the
measured angles (its deviation from R0 is theta - phi, scaled); the bit speed ``dphi`` is an
input only for that drop-in connection, the laws do not read it. The start values of the gains
are the SoftTorque tuning of the reference set and the feed-forward of the gains file, baked in
by ``build_fmus.py``; the SSP package ``DrillStringTopDrive.ssp`` carries the three tunings as
parameter sets.

``topdrive_controller_si.py`` derives ``TopDriveControllerSI`` from :class:`TopDriveController`,
replacing the variables, the law's parameters (:meth:`TopDriveController.new_law`,
:meth:`~TopDriveController.initial_values`) and the measurements (:meth:`~TopDriveController.
measured`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import drillstring_fmu_support as fmu

from drillstring.model.laws import (
    LawState,
    Measurement,
    SpeedPI,
    ZTorque,
    sample_output,
    sample_update,
)

INPUTS = (
    ("phi", "Measured bit angle perturbation phi (plant output; forms the string torque)"),
    ("dphi", "Bit angular velocity perturbation (plant output; not read: connector of the loop)"),
    ("theta", "Measured rotary-table angle perturbation theta (plant output)"),
    ("dtheta", "Measured rotary-table angular velocity perturbation dtheta/dtau (plant output)"),
)
#: The law's parameters besides R_ff and t_on (the tunings' keys).
GAINS = ("kp", "ki", "z_gain", "omega_hp", "omega_lp")
BAKED = "; start value: the SoftTorque tuning baked in by build_fmus.py"


def law_parameters(
    kp: float, ki: float, z_gain: float, omega_hp: float, omega_lp: float, R_ff: float, t_on: float
) -> SpeedPI | ZTorque:
    """The law of the FMU's parameters: SpeedPI when ``z_gain = 0``, else ZTorque (validated
    like the Python API)."""
    if z_gain == 0.0:
        return SpeedPI(kp=kp, ki=ki, R_ff=R_ff, t_on=t_on)
    return ZTorque(
        kp=kp, ki=ki, z_gain=z_gain, omega_hp=omega_hp, omega_lp=omega_lp, R_ff=R_ff, t_on=t_on
    )


def _variables() -> tuple[fmu.Variable, ...]:
    out = [fmu.input_real(name, 0.0, desc) for name, desc in INPUTS]
    out.append(
        fmu.output(
            "R_minus_R0",
            "Real",
            "Rotary-table torque deviation R - R0 = R_ff + kp e + ki I, held over the step",
            depends_on=["dtheta"],
        )
    )
    out += [
        fmu.parameter("kp", "Real", 0.0, f"Proportional gain of the speed PI (units of Z){BAKED}",
                      min=0.0),
        fmu.parameter("ki", "Real", 0.0, f"Integral gain of the speed PI (units of C){BAKED}",
                      min=0.0),
        fmu.parameter(
            "z_gain",
            "Real",
            0.0,
            "Torque feedback gain of Z-Torque in units of 1/Z (1: impedance matching); 0: the "
            f"plain speed PI (stiff PI, SoftTorque){BAKED}",
            min=0.0,
        ),
        fmu.parameter("omega_hp", "Real", 0.3, "High-pass corner of the torque feedback "
                      "(rad per unit of tau; read only when z_gain > 0)", min=fmu.POSITIVE),
        fmu.parameter("omega_lp", "Real", 10.0, "Low-pass corner of the torque feedback "
                      "(rad per unit of tau; read only when z_gain > 0)", min=fmu.POSITIVE),
        fmu.parameter(
            "R_ff",
            "Real",
            0.0,
            "Feed-forward torque R_ff = -K0 (eq. (31)); start value: the gains file baked in by "
            "build_fmus.py --gains",
        ),
        fmu.parameter("t_on", "Real", 0.0, "Switch-on time of the law: before it only R_ff"),
        fmu.parameter("enabled", "Boolean", True, "Law enabled; false: R - R0 = R_ff always"),
    ]  # fmt: skip
    return tuple(out)


class TopDriveController(fmu.FmuModel):
    """Digital top-drive speed controller: stiff PI, SoftTorque (z_gain = 0) or Z-Torque."""

    MODEL = "TopDriveController"
    VARIABLES = _variables()
    VALIDITY = (
        "A digital law without limits of validity: finite inputs give a finite output. Before "
        "t_on, or with enabled = false, the output is R_ff; the law starts from the inputs at "
        "the first communication point at or after t_on, and its state is updated at every "
        "step with the inputs held over the step (zero-order hold).",
    )
    description = (
        "Industrial top-drive controller (stiff speed PI, SoftTorque/SoftSpeed, Z-Torque) for "
        "the drill-string model of Besselink, van de Wouw and Nijmeijer (IEEE CCA 2011), with "
        "bumpless switch-on at t_on"
    )

    #: The output's name.
    OUTPUT = "R_minus_R0"

    law: SpeedPI | ZTorque | None = None
    state: LawState | None = None

    def initial_values(self) -> Mapping[str, Any]:
        """The default tuning and R_ff of this FMU's build configuration (scaled)."""
        top = self.config["topdrive"]
        tuning = top["tunings"][top["default"]]
        return {**{k: tuning[k] for k in GAINS}, "R_ff": self.config["gains"]["R_ff"]}

    def new_law(self, v: Mapping[str, Any]) -> SpeedPI | ZTorque:
        """The law of the parameter values."""
        return law_parameters(*(v[k] for k in GAINS), R_ff=v["R_ff"], t_on=v["t_on"])

    def measured(self) -> Measurement:
        """Table angle and speed, string torque theta - phi, bit angle and speed (scaled)."""
        x = self.values
        return Measurement(x["theta"], x["dtheta"], x["theta"] - x["phi"], x["phi"], x["dphi"])

    # ----------------------------------------------------------------- law
    def configure(self, values: Mapping[str, Any]) -> None:
        self.law = self.new_law(values)
        self.state = None

    def output_values(self) -> Mapping[str, Any]:
        law = self.law
        assert law is not None
        if not self.values["enabled"]:
            return {self.OUTPUT: float(law.R_ff)}
        return {self.OUTPUT: float(sample_output(law, self.time, self.state, self.measured()))}

    def advance(self, t: float, h: float) -> fmu.StepResult:
        law = self.law
        assert law is not None
        if self.values["enabled"]:
            self.state = sample_update(law, t, self.state, self.measured(), h)
        return fmu.StepResult(t + h)

    # ----------------------------------------------------------------- FMU state
    def save(self) -> tuple[dict[str, Any], Any, Callable[[], bytes]]:
        state = None if self.state is None else list(self.state)
        return {"state": state, "law": self.law is not None}, None, lambda: b""

    def restore(self, fields: Mapping[str, Any], snapshot: Any, payload: bytes | None) -> None:
        self.law = self.new_law(self.values) if fields["law"] else None
        self.state = None if fields["state"] is None else tuple(fields["state"])
