"""Digital control laws of the rotary-table torque R - R0, each written once.

A top-drive controller is a sampled law: at each sample instant it reads the measurements, puts
out a torque that is held until the next instant (zero-order hold) and updates its own state.
Every law here is a frozen dataclass of its parameters with three pure functions,

* ``initial_state(m)``: the law's state at switch-on, from the current measurements ``m``;
* ``output(state, m)``: R - R0 at a sample instant;
* ``update(state, m, Ts)``: the state after one sample period Ts, the measurements held;

and :func:`sample_output` / :func:`sample_update` add the switch-on time ``t_on`` the same way
for all of them (``docs/model.md``, "Bumpless switch-on"): before ``t_on`` only the feed-forward
``R_ff`` acts; at the first sample at or after ``t_on`` the law starts from the current
measurements, so that nothing jumps but the terms the measurements drive. A law's state is a
tuple of floats (``None`` before switch-on), so a host (the sampled monolithic loop,
:func:`drillstring.model.sampled.simulate_sampled`, or a controller FMU) keeps it as data.

The laws (tuning rules: ``drillstring.controller.tuning`` and ``docs/controllers.md``):

* :class:`SpeedPI`: PI on the rotary-table speed, set point omega0 (stiff PI, SoftTorque);
* :class:`ZTorque`: the same PI whose speed set point is lowered by the measured string torque,
  high-pass and low-pass filtered, divided by the string impedance (impedance matching);
* :class:`SampledAffine`: the paper's state feedback (29)-(31), the
  :class:`~drillstring.model.control.AffineFeedback` of the continuous monolithic solver
  evaluated at sample instants by the same :func:`~drillstring.model.control.feedback_torque`.

Everything is in the scaled form of the paper (time tau = t/t*, torques in units of C, angles in
rad, speeds d/dtau; all in perturbation form, eqs. (9)-(10), (13)). The string torque at the top
is the twist torque C*(Theta - Phi); its deviation from the nominal R0 is theta - phi in scaled
form. ``to_si``/``from_si`` convert each law's parameters to and from SI units with the
characteristic time t* and the stiffness C of a :class:`~drillstring.model.params.PhysicalParams`
(eqs. (15)-(16)).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol

from drillstring.model.control import (
    LATCH_MODES,
    AffineFeedback,
    feedback_torque,
    switch_on_references,
)
from drillstring.model.params import PhysicalParams
from drillstring.validation import check_real

__all__ = [
    "Law",
    "LawState",
    "Measurement",
    "SampledAffine",
    "SpeedPI",
    "ZTorque",
    "law_from_si",
    "measure",
    "measurement_from_si",
    "sample_output",
    "sample_update",
]

#: A law's state: a tuple of floats (``None`` before switch-on).
LawState = tuple[float, ...]


class Measurement(NamedTuple):
    """What the controller measures at a sample instant (scaled, perturbation form).

    Attributes
    ----------
    theta : float
        Rotary-table angle theta (eq. (10)).
    dtheta : float
        Rotary-table speed dtheta/dtau (the speed set point omega0 is dtheta = 0).
    torque : float
        String torque at the top minus its nominal value: theta - phi (the twist of (13)).
    phi, dphi : float
        Bit angle and bit speed (downhole; only the paper's law needs them; NaN if absent).
    """

    theta: float
    dtheta: float
    torque: float
    phi: float = math.nan
    dphi: float = math.nan


def measure(y: Sequence[float]) -> Measurement:
    """The measurements of a perturbation state ``y = [u, du, phi, dphi, theta, dtheta]``.

    Parameters
    ----------
    y : sequence of 6 float
        As :meth:`drillstring.model.engine.Engine.perturbation` returns it.

    Returns
    -------
    Measurement
        Table angle and speed, string torque theta - phi, bit angle and speed.
    """
    phi, dphi, theta, dtheta = float(y[2]), float(y[3]), float(y[4]), float(y[5])
    return Measurement(theta, dtheta, theta - phi, phi, dphi)


def measurement_from_si(
    rig: PhysicalParams,
    *,
    theta: float,
    dtheta: float,
    torque: float,
    phi: float = math.nan,
    dphi: float = math.nan,
) -> Measurement:
    """Scaled measurements from SI perturbations of a rig.

    Parameters
    ----------
    rig : PhysicalParams
        Gives t* = sqrt(I1/C) and C (Section II).
    theta, phi : float
        Angle perturbations [rad] (unchanged by the scaling (10)).
    dtheta, dphi : float
        Speed perturbations dTheta/dt - Omega0, dPhi/dt - Omega0 [rad/s]; scaled: times t*.
    torque : float
        String torque at the top minus R0 [N m]; scaled: divided by C (16).

    Returns
    -------
    Measurement
    """
    t = rig.t_star
    return Measurement(
        float(theta), float(dtheta) * t, float(torque) / rig.C, float(phi), float(dphi) * t
    )


class Law(Protocol):
    """What every law provides (see the module docstring)."""

    R_ff: float
    t_on: float

    def initial_state(self, m: Measurement) -> LawState: ...

    def output(self, state: LawState, m: Measurement) -> float: ...

    def update(self, state: LawState, m: Measurement, Ts: float) -> LawState: ...

    def to_si(self, rig: PhysicalParams) -> dict[str, Any]: ...


def sample_output(law: Law, tau: float, state: LawState | None, m: Measurement) -> float:
    """R - R0 put out at the sample instant ``tau``: ``R_ff`` before ``t_on``, then the law.

    Parameters
    ----------
    law : Law
        The control law.
    tau : float
        The sample instant (scaled time).
    state : tuple or None
        The law's state; None until the law has been switched on by :func:`sample_update`. At or
        after ``t_on`` with ``state`` None, the output is that of the state the law would start
        from now (so the switch-on instant is bumpless whatever order a host calls in).
    m : Measurement
        The measurements at ``tau``.

    Returns
    -------
    float
        The torque deviation R - R0 (scaled, eq. (13)), held until the next sample.
    """
    if state is None:
        if tau < law.t_on:
            return law.R_ff
        state = law.initial_state(m)
    return law.output(state, m)


def sample_update(
    law: Law, tau: float, state: LawState | None, m: Measurement, Ts: float
) -> LawState | None:
    """The law's state after the sample period [tau, tau + Ts] (measurements ``m`` at tau).

    Before ``t_on`` the state stays None; at the first sample at or after ``t_on`` the law is
    switched on from the current measurements (``initial_state``) and then updated.

    Parameters
    ----------
    law : Law
        The control law.
    tau : float
        The sample instant that starts the period.
    state : tuple or None
        The state at ``tau`` (None before switch-on).
    m : Measurement
        The measurements at ``tau``.
    Ts : float
        The sample period (> 0; checked by the host).

    Returns
    -------
    tuple or None
        The state at ``tau + Ts``.
    """
    if state is None:
        if tau < law.t_on:
            return None
        state = law.initial_state(m)
    return law.update(state, m, Ts)


def _si_time(rig: PhysicalParams) -> float:
    if not isinstance(rig, PhysicalParams):
        raise TypeError(f"rig must be a PhysicalParams, got {type(rig).__name__}")
    return rig.t_star


def _si_values(
    values: Mapping[str, Any], required: Sequence[str], optional: Sequence[str], where: str
) -> dict[str, float]:
    """The SI values of a law, checked: ``required`` must be there, ``optional`` default to 0."""
    unknown = sorted(set(values) - set(required) - set(optional))
    if unknown:
        known = ", ".join((*required, *optional))
        raise ValueError(f"{where}: unknown SI value(s) {unknown} (known: {known})")
    out = {}
    for key in (*required, *optional):
        if key not in values and key in required:
            raise ValueError(f"{where}: missing SI value {key!r}")
        out[key] = check_real(f"{where} {key}", values.get(key, 0.0))
    return out


def _preset(kp: float, ki: float, e: float) -> float:
    """The integral that makes ``kp*e + ki*I = 0``: bumpless transfer of a PI law."""
    return -kp * e / ki if ki > 0.0 else 0.0


# --------------------------------------------------------------------------------------------
# PI on the rotary-table speed
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SpeedPI:
    """PI control of the rotary-table speed, set point omega0 (dtheta/dtau = 0).

    ``R - R0 = R_ff + kp*e + ki*I`` with the speed error ``e = -dtheta`` and ``I`` the sum of
    ``e*Ts`` over the samples since switch-on (forward Euler, as a drive's controller integrates).
    Bumpless transfer: at switch-on ``I`` is preset to ``-kp*e/ki``, so that the torque is
    continuous, ``R - R0 = R_ff`` at that instant, and the integrator then relaxes the speed
    error (with ``ki = 0`` there is no integrator to preset and the torque steps by ``kp*e``).
    Stiff PI and SoftTorque are this law with different gains
    (``drillstring.controller.tuning``).

    Parameters
    ----------
    kp : float
        Proportional gain, >= 0 (units of C*t*: torque per speed; C*t* = sqrt(C*I1) is the
        impedance of the lumped string, 1 in scaled units).
    ki : float
        Integral gain, >= 0 (units of C: torque per angle).
    R_ff : float
        Feed-forward torque (31): alone before ``t_on``, the bias of the law after it.
    t_on : float
        Switch-on time (scaled).
    """

    kp: float
    ki: float
    R_ff: float = 0.0
    t_on: float = 0.0

    def __post_init__(self) -> None:
        for name in ("kp", "ki"):
            value = check_real(f"SpeedPI.{name}", getattr(self, name), lower=0.0, strict=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "R_ff", check_real("SpeedPI.R_ff", self.R_ff))
        object.__setattr__(self, "t_on", check_real("SpeedPI.t_on", self.t_on))

    def initial_state(self, m: Measurement) -> LawState:
        """The integral preset for a continuous torque: ``ki*I = -kp*e`` (0 when ``ki = 0``)."""
        return (_preset(self.kp, self.ki, -m.dtheta),)

    def output(self, state: LawState, m: Measurement) -> float:
        """``R_ff + kp*e + ki*I`` with ``e = -dtheta`` (eq. (13)'s input R - R0)."""
        return self.R_ff - self.kp * m.dtheta + self.ki * state[0]

    def update(self, state: LawState, m: Measurement, Ts: float) -> LawState:
        """``I <- I + Ts*e``."""
        return (state[0] - Ts * m.dtheta,)

    def to_si(self, rig: PhysicalParams) -> dict[str, Any]:
        """Parameters in SI units: kp [N m s/rad], ki [N m/rad], R_ff [N m], t_on [s]."""
        t = _si_time(rig)
        return {
            "kp": self.kp * rig.C * t,
            "ki": self.ki * rig.C,
            "R_ff": self.R_ff * rig.C,
            "t_on": self.t_on * t,
        }

    @classmethod
    def from_si(cls, rig: PhysicalParams, values: Mapping[str, Any]) -> SpeedPI:
        """Inverse of :meth:`to_si`."""
        t = _si_time(rig)
        v = _si_values(values, ("kp", "ki"), ("R_ff", "t_on"), "SpeedPI.from_si")
        return cls(
            kp=v["kp"] / (rig.C * t), ki=v["ki"] / rig.C, R_ff=v["R_ff"] / rig.C, t_on=v["t_on"] / t
        )


# --------------------------------------------------------------------------------------------
# Z-Torque: speed loop whose set point is corrected by the measured string torque
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ZTorque:
    """Speed PI whose set point is lowered by the filtered string torque over the impedance.

    ``e = -dtheta - z_gain*y`` with ``y = LP(HP(torque))`` and ``R - R0 = R_ff + kp*e + ki*I``,
    ``I`` the sum of ``e*Ts``. The high-pass (corner ``omega_hp``) removes the mean drilling
    torque, so the mean table speed stays at the set point; the low-pass (corner ``omega_lp``)
    is the measurement filter. A stiff speed loop then makes the table speed follow
    ``-z_gain*torque/Z`` at the torsional frequencies: the top looks like a damper of impedance
    ``Z/z_gain`` to the string (Z = sqrt(C*I1) = 1 in scaled units), which absorbs the torsional
    waves when it matches the string's impedance, ``z_gain = 1``. Both filters are first order
    and discretised exactly for inputs held over a sample period. At switch-on the high-pass is
    at rest on the current torque (output 0), the low-pass at 0 and the integral preset for a
    continuous torque as in :class:`SpeedPI`.

    Parameters
    ----------
    kp, ki : float
        Gains of the speed PI (as :class:`SpeedPI`), >= 0.
    z_gain : float
        Torque feedback gain in units of 1/Z (1: impedance matching), >= 0.
    omega_hp : float
        High-pass corner (rad per unit of scaled time), > 0 (default: the tuning of
        ``drillstring.controller.tuning.z_torque``).
    omega_lp : float
        Low-pass corner, > 0.
    R_ff : float
        Feed-forward torque (31).
    t_on : float
        Switch-on time (scaled).
    """

    kp: float
    ki: float
    z_gain: float = 1.0
    omega_hp: float = 0.3
    omega_lp: float = 10.0
    R_ff: float = 0.0
    t_on: float = 0.0

    def __post_init__(self) -> None:
        for name in ("kp", "ki", "z_gain"):
            value = check_real(f"ZTorque.{name}", getattr(self, name), lower=0.0, strict=False)
            object.__setattr__(self, name, value)
        for name in ("omega_hp", "omega_lp"):
            object.__setattr__(
                self, name, check_real(f"ZTorque.{name}", getattr(self, name), lower=0.0)
            )
        object.__setattr__(self, "R_ff", check_real("ZTorque.R_ff", self.R_ff))
        object.__setattr__(self, "t_on", check_real("ZTorque.t_on", self.t_on))

    def initial_state(self, m: Measurement) -> LawState:
        """(integral, high-pass's low-pass state, low-pass output) = (preset, torque, 0)."""
        return (_preset(self.kp, self.ki, -m.dtheta), float(m.torque), 0.0)

    def _error(self, state: LawState, m: Measurement) -> float:
        return -m.dtheta - self.z_gain * state[2]

    def output(self, state: LawState, m: Measurement) -> float:
        """``R_ff + kp*e + ki*I`` with the corrected speed error e."""
        return self.R_ff + self.kp * self._error(state, m) + self.ki * state[0]

    def update(self, state: LawState, m: Measurement, Ts: float) -> LawState:
        """Integral by forward Euler; the filters exactly for the torque held over Ts."""
        integral, z, y = state
        hp = m.torque - z
        a_hp = -math.expm1(-self.omega_hp * Ts)
        a_lp = -math.expm1(-self.omega_lp * Ts)
        return (
            integral + Ts * self._error(state, m),
            z + a_hp * (m.torque - z),
            y + a_lp * (hp - y),
        )

    def to_si(self, rig: PhysicalParams) -> dict[str, Any]:
        """SI parameters: kp [N m s/rad], ki [N m/rad], z_gain as a speed correction per torque
        ``z_gain/Z`` [rad/s per N m] with Z = sqrt(C*I1) [N m s/rad], the corners [rad/s],
        R_ff [N m], t_on [s]."""
        t = _si_time(rig)
        Z = rig.C * t
        return {
            "kp": self.kp * Z,
            "ki": self.ki * rig.C,
            "z_gain": self.z_gain / Z,
            "omega_hp": self.omega_hp / t,
            "omega_lp": self.omega_lp / t,
            "R_ff": self.R_ff * rig.C,
            "t_on": self.t_on * t,
        }

    @classmethod
    def from_si(cls, rig: PhysicalParams, values: Mapping[str, Any]) -> ZTorque:
        """Inverse of :meth:`to_si`."""
        t = _si_time(rig)
        Z = rig.C * t
        required = ("kp", "ki", "z_gain", "omega_hp", "omega_lp")
        v = _si_values(values, required, ("R_ff", "t_on"), "ZTorque.from_si")
        return cls(
            kp=v["kp"] / Z,
            ki=v["ki"] / rig.C,
            z_gain=v["z_gain"] * Z,
            omega_hp=v["omega_hp"] * t,
            omega_lp=v["omega_lp"] * t,
            R_ff=v["R_ff"] / rig.C,
            t_on=v["t_on"] / t,
        )


# --------------------------------------------------------------------------------------------
# the paper's law, sampled
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SampledAffine:
    """The state feedback with feed-forward (29)-(31) of an AffineFeedback, at sample instants.

    The state is the pair of references (phi_ref, twist_ref) latched at switch-on by
    :func:`~drillstring.model.control.switch_on_references`; the output is
    :func:`~drillstring.model.control.feedback_torque` of the measured phi, dphi, theta, dtheta,
    the same function the continuous monolithic solver and the controller FMU evaluate.

    Parameters
    ----------
    feedback : AffineFeedback
        Gain, K0, R_ff, t_on and latch of the law.
    """

    feedback: AffineFeedback

    def __post_init__(self) -> None:
        if not isinstance(self.feedback, AffineFeedback):
            raise TypeError(
                f"SampledAffine.feedback must be an AffineFeedback, got "
                f"{type(self.feedback).__name__}"
            )

    @property
    def R_ff(self) -> float:
        return self.feedback.R_ff

    @property
    def t_on(self) -> float:
        return self.feedback.t_on

    def initial_state(self, m: Measurement) -> LawState:
        """(phi_ref, twist_ref) by the latch of the feedback (``docs/model.md``, "Bumpless
        switch-on")."""
        if not (math.isfinite(m.phi) and math.isfinite(m.dphi)):
            raise ValueError(
                f"the paper's law needs the bit angle and speed, got phi={m.phi!r}, dphi={m.dphi!r}"
            )
        f = self.feedback
        phi_ref, twist_ref = switch_on_references(f.latch_code, m.phi, m.theta, f.K0)
        return (float(phi_ref), float(twist_ref))

    def output(self, state: LawState, m: Measurement) -> float:
        """``R_ff + F x`` of (29)-(31) with the latched references."""
        f = self.feedback
        return float(
            feedback_torque(
                0.0, m.phi, m.dphi, m.theta, m.dtheta, f.F, f.K0, f.R_ff, 0.0, state[0], state[1]
            )
        )

    def update(self, state: LawState, m: Measurement, Ts: float) -> LawState:
        """The references stay as latched."""
        return state

    def to_si(self, rig: PhysicalParams) -> dict[str, Any]:
        """SI parameters: F = [F1 (N m/rad), F2 (N m s/rad), F3 (N m/rad), F4 (N m s/rad)],
        K0 [rad], R_ff [N m], t_on [s], latch."""
        t = _si_time(rig)
        F1, F2, F3, F4 = self.feedback.F
        C = rig.C
        return {
            "F": (F1 * C, F2 * C * t, F3 * C, F4 * C * t),
            "K0": self.feedback.K0,
            "R_ff": self.feedback.R_ff * C,
            "t_on": self.feedback.t_on * t,
            "latch": self.feedback.latch,
        }

    @classmethod
    def from_si(cls, rig: PhysicalParams, values: Mapping[str, Any]) -> SampledAffine:
        """Inverse of :meth:`to_si`."""
        t = _si_time(rig)
        rest = {k: v for k, v in values.items() if k not in ("F", "latch")}
        v = _si_values(rest, ("K0",), ("R_ff", "t_on"), "SampledAffine.from_si")
        if "F" not in values:
            raise ValueError("SampledAffine.from_si: missing SI value 'F'")
        F = tuple(values["F"])
        if len(F) != 4:
            raise ValueError(f"SampledAffine.from_si: F must have 4 entries, got {F!r}")
        F = tuple(check_real(f"SampledAffine.from_si F[{i}]", f) for i, f in enumerate(F))
        C = rig.C
        feedback = AffineFeedback(
            F=(F[0] / C, F[1] / (C * t), F[2] / C, F[3] / (C * t)),
            K0=v["K0"],
            R_ff=v["R_ff"] / C,
            t_on=v["t_on"] / t,
            latch=values.get("latch", LATCH_MODES[0]),
        )
        return cls(feedback)


_LAW_CLASSES: dict[str, type] = {
    "SpeedPI": SpeedPI,
    "ZTorque": ZTorque,
    "SampledAffine": SampledAffine,
}


def law_from_si(kind: str, rig: PhysicalParams, values: Mapping[str, Any]) -> Law:
    """A law from its SI parameters; ``kind`` is the class name (``"SpeedPI"``, ``"ZTorque"``,
    ``"SampledAffine"``)."""
    if kind not in _LAW_CLASSES:
        raise ValueError(f"unknown law kind {kind!r} (known: {', '.join(_LAW_CLASSES)})")
    return _LAW_CLASSES[kind].from_si(rig, values)  # type: ignore[attr-defined, no-any-return]
