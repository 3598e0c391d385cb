"""Tuning rules of the industrial top-drive laws, from the lumped string (``docs/controllers.md``).

The string of the paper is one torsional spring C between the bit inertia I1 and the table
inertia I2 = rho*I1 (eqs. (2)-(3), (13)). In scaled units its torsional frequency with the table
held is omega_s = sqrt(C/I1)*t* = 1 and its characteristic impedance Z = sqrt(C*I1) = 1 (torque
per speed in units of C*t*); the rules below are written with them.

* :func:`stiff_pi`: a speed PI whose loop around the table inertia alone has a bandwidth a decade
  above omega_s and is critically damped: the table holds its speed, the string is a pendulum
  with a fixed top (the rigs' default, and the baseline that shows stick-slip).
* :func:`soft_speed`: SoftSpeed (NOV's tuned speed PI; Kyllingstad and Nessjoen). The integral
  gain cancels the table inertia at the string's frequency, ``ki = rho*omega_s^2``, so that the
  table is a pure damper kp there; the proportional gain by one of two rules
  (:data:`SOFT_SPEED_RULES`): ``"two-mass"``, ``kp = 2*sqrt(rho)*Z``, the smallest that keeps
  both torsional modes of the lumped string on the circle |s| = omega_s, where they share the
  damping ratio 1/(2*sqrt(rho)), the largest common one (:func:`soft_speed_damping` states the
  damping for any kp); or ``"impedance"``, the field rule ``kp = Z``, the top a damper matched
  to the string's impedance (torsional waves absorbed);
* :func:`z_torque`: Z-Torque (Shell), the stiff PI with the set point corrected by the string
  torque over the impedance, ``z_gain = matching/Z`` (``matching = 1``: full matching; a
  fraction, e.g. the 0.25 of the Open Source Drilling Community's Simulator4nDOF), high-pass
  (corner 0.3*omega_s) and low-pass (10*omega_s) filtered.

The impedance Z (:func:`impedance`) is the lumped string's, ``sqrt(C*I1) = 1`` in scaled units,
or the pipe's characteristic impedance ``J*sqrt(G*rho_steel)`` of the simulated rig's drill pipe
(:class:`Pipe`; 296 N m s/rad for the reference rig's 5-in pipe, 1.37 times the lumped 217):
what a field engineer computes from the pipe tables. A rig's pipe is given, or known for the
string of a known rig (:data:`KNOWN_PIPES`, :func:`rig_pipe`); scaled by that rig's sqrt(C*I1).

:func:`linear_closed_loop` builds the closed loop of the linearised torsional model (13), (27)
(:func:`~drillstring.controller.averaged.linearised_ode_matrix`) with a law, in continuous time,
so that the damping a rule states can be checked on the closed loop's eigenvalues.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drillstring.controller.averaged import AveragedModel, linearised_ode_matrix
from drillstring.model.laws import Law, SampledAffine, SpeedPI, ZTorque
from drillstring.model.params import KNOWN_PHYSICAL, ScaledParams
from drillstring.model.tables import Scales, scales_of
from drillstring.validation import check_choice, check_real

__all__ = [
    "IMPEDANCES",
    "KNOWN_PIPES",
    "OMEGA_S",
    "REFERENCE_PIPE",
    "SOFT_SPEED_RULES",
    "STRING_IMPEDANCES",
    "Z_STRING",
    "Pipe",
    "impedance",
    "linear_closed_loop",
    "rig_pipe",
    "soft_speed",
    "soft_speed_damping",
    "stiff_pi",
    "z_torque",
]

#: Torsional frequency sqrt(C/I1) of the string with the table held, scaled (t* = sqrt(I1/C)).
OMEGA_S = 1.0
#: Characteristic impedance sqrt(C*I1) of the lumped string, scaled (units of C*t*).
Z_STRING = 1.0
#: Where the string impedance Z of the rules comes from: the lumped string's sqrt(C*I1) or the
#: drill pipe's J*sqrt(G*rho_steel) from its tables (the choices of a run of the one-mode model).
IMPEDANCES = ("lumped", "pipe")
#: ... and the simulated distributed string's own sqrt(kappa) (``docs/model.md``, "The
#: distributed string"), which needs the string's kappa (:meth:`~drillstring.controller.lineup.
#: Tuning.for_string`).
STRING_IMPEDANCES = (*IMPEDANCES, "string")
#: The proportional gain rules of SoftSpeed.
SOFT_SPEED_RULES = ("two-mass", "impedance")


@dataclass(frozen=True)
class Pipe:
    """Drill pipe, for its torsional characteristic impedance ``J*sqrt(G*rho_steel)``.

    Parameters
    ----------
    od, id : float
        Outer and inner diameter [m], od > id > 0.
    G : float
        Shear modulus [Pa].
    density : float
        Density of the steel [kg/m^3].
    """

    od: float
    id: float
    G: float = 79.3e9
    density: float = 7850.0

    def __post_init__(self) -> None:
        for name in ("od", "id", "G", "density"):
            check_real(f"Pipe.{name}", getattr(self, name), lower=0.0)
        if not self.id < self.od:
            raise ValueError(f"Pipe: id = {self.id!r} is not below od = {self.od!r}")

    @property
    def J(self) -> float:  # noqa: N802 - the engineers' symbol
        """Polar moment of area pi*(od^4 - id^4)/32 [m^4]."""
        return math.pi * (self.od**4 - self.id**4) / 32.0

    @property
    def impedance(self) -> float:
        """Characteristic impedance J*sqrt(G*rho_steel) [N m s/rad]: torque per speed of a
        torsional wave in the pipe."""
        return self.J * math.sqrt(self.G * self.density)


#: The reference rig's drill pipe: 5-in 19.5 lb/ft, OD 127.0 mm, ID 108.6 mm
#: (``docs/reference_rig.md``).
REFERENCE_PIPE = Pipe(od=0.1270, id=0.1086)
#: The drill pipe of each known rig of :data:`~drillstring.model.params.KNOWN_PHYSICAL` whose
#: pipe is documented, by the rig's name.
KNOWN_PIPES: dict[str, Pipe] = {"reference-rig": REFERENCE_PIPE, "pipe-rig": REFERENCE_PIPE}


def rig_pipe(rig: Scales) -> Pipe:
    """The drill pipe of a rig's string: that of the known rig with the same string.

    The string is the torsional stiffness C and the bit-end inertia I1 = C*t*^2 (eqs. (2)-(3));
    a rig that differs from a known one only in its operating point (Omega0, V0: a point of a
    map) has its string, and so its pipe.

    Parameters
    ----------
    rig : PhysicalParams or any object with C and t_star
        The simulated rig.

    Returns
    -------
    Pipe

    Raises
    ------
    ValueError
        No known rig with a known pipe has that string (the message names C and I1).
    """
    C, t_star = scales_of(rig)
    I1 = C * t_star * t_star
    for name, known in KNOWN_PHYSICAL.items():
        if name in KNOWN_PIPES and (
            math.isclose(C, known.C, rel_tol=1e-9) and math.isclose(I1, known.I1, rel_tol=1e-9)
        ):
            return KNOWN_PIPES[name]
    known_strings = ", ".join(
        f"{n}: C = {KNOWN_PHYSICAL[n].C:g} N m/rad, I1 = {KNOWN_PHYSICAL[n].I1:g} kg m^2"
        for n in KNOWN_PIPES
    )
    raise ValueError(
        f"impedance 'pipe': no drill pipe is known for the string of the simulated rig (C = "
        f"{C:.6g} N m/rad, I1 = {I1:.6g} kg m^2; known: {known_strings}); give the pipe "
        "(Tuning(pipe=Pipe(od, id)), impedance(..., pipe=...)) or use the lumped impedance"
    )


def impedance(
    choice: str = "lumped",
    rig: Scales | None = None,
    pipe: Pipe | None = None,
    *,
    kappa: float | None = None,
) -> float:
    """The string impedance Z of the tuning rules, scaled (units of C*t* = sqrt(C*I1)).

    Parameters
    ----------
    choice : str
        One of :data:`STRING_IMPEDANCES`: ``"lumped"``, sqrt(C*I1) (1, the model's own);
        ``"pipe"``, the pipe's J*sqrt(G*rho_steel) over the simulated rig's sqrt(C*I1);
        ``"string"``, the simulated string's own, sqrt(kappa) (needs ``kappa``; on the
        reference rig 1.368, the pipe's 296.5 N m s/rad: its kappa is that pipe's).
    rig : PhysicalParams or any object with C and t_star
        The simulated rig; needed for ``"pipe"``.
    pipe : Pipe, optional
        The rig's drill pipe for ``"pipe"`` (default :func:`rig_pipe` of ``rig``).
    kappa : float, optional
        The simulated string's pipe inertia over I1 for ``"string"``, in (0, 3).

    Returns
    -------
    float
        Z in units of sqrt(C*I1) of ``rig``.

    Raises
    ------
    ValueError
        ``choice`` unknown; ``"pipe"`` without a rig, or for a rig whose pipe is neither given
        nor known (:func:`rig_pipe`); ``"string"`` without a positive kappa.
    """
    check_choice("impedance", choice, STRING_IMPEDANCES)
    if choice == "lumped":
        return Z_STRING
    if choice == "string":
        if kappa is None:
            raise ValueError(
                "impedance 'string' needs the simulated string's kappa = I_pipe/I1 (its "
                "impedance is sqrt(kappa))"
            )
        return math.sqrt(check_real("impedance kappa", kappa, lower=0.0))
    if rig is None:
        raise ValueError(
            "impedance 'pipe' needs the simulated rig (its C and t*): the pipe's impedance is "
            "scaled by that rig's sqrt(C*I1)"
        )
    C, t_star = scales_of(rig)
    pipe = rig_pipe(rig) if pipe is None else pipe
    if not isinstance(pipe, Pipe):
        raise TypeError(f"pipe must be a Pipe, got {pipe!r}")
    return pipe.impedance / (C * t_star)


def _rho(params: ScaledParams) -> float:
    if not isinstance(params, ScaledParams):
        raise TypeError(f"params must be a ScaledParams, got {type(params).__name__}")
    return float(params.rho)


def stiff_pi(
    params: ScaledParams,
    *,
    bandwidth: float = 10.0,
    damping: float = 1.0,
    R_ff: float = 0.0,
    t_on: float = 0.0,
) -> SpeedPI:
    """Stiff speed PI: the table-inertia loop ``rho*s^2 + kp*s + ki`` with natural frequency
    ``bandwidth*omega_s`` and damping ratio ``damping``.

    Parameters
    ----------
    params : ScaledParams
        Gives rho = I2/I1 (16).
    bandwidth : float
        Speed-loop natural frequency in units of omega_s (> 0; default a decade above).
    damping : float
        Damping ratio of the speed loop (> 0; default critically damped).
    R_ff, t_on : float
        Feed-forward (31) and switch-on time of the law.

    Returns
    -------
    SpeedPI
        ``kp = 2*damping*bandwidth*rho``, ``ki = bandwidth^2*rho`` (scaled).
    """
    rho = _rho(params)
    wc = check_real("stiff_pi bandwidth", bandwidth, lower=0.0) * OMEGA_S
    zc = check_real("stiff_pi damping", damping, lower=0.0)
    return SpeedPI(kp=2.0 * zc * wc * rho, ki=wc * wc * rho, R_ff=R_ff, t_on=t_on)


def soft_speed(
    params: ScaledParams,
    *,
    rule: str = "two-mass",
    Z: float = Z_STRING,
    kp: float | None = None,
    R_ff: float = 0.0,
    t_on: float = 0.0,
) -> SpeedPI:
    """SoftSpeed: ``ki = rho*omega_s^2`` (the table inertia cancelled at the string's
    frequency) and ``kp`` by ``rule`` unless given.

    ``"two-mass"``: ``kp = 2*sqrt(rho)*Z``; on the linearised torsional model (13), (27) without
    the bit's velocity weakening (c = 0: the lumped string the rule is tuned from) the closed
    loop's four torsional poles then lie on |s| = omega_s with the damping ratios of
    :func:`soft_speed_damping`. ``"impedance"``: ``kp = Z``, the field rule (the top drive a
    damper matched to the pipe).

    Parameters
    ----------
    params : ScaledParams
        Gives rho.
    rule : str
        One of :data:`SOFT_SPEED_RULES`.
    Z : float
        The string impedance (:func:`impedance`), > 0.
    kp : float, optional
        Proportional gain, overriding the rule.
    R_ff, t_on : float
        Feed-forward (31) and switch-on time.

    Returns
    -------
    SpeedPI
    """
    rho = _rho(params)
    check_choice("soft_speed rule", rule, SOFT_SPEED_RULES)
    Z = check_real("soft_speed Z", Z, lower=0.0)
    if kp is not None:
        gain = check_real("soft_speed kp", kp)
    else:
        gain = 2.0 * math.sqrt(rho) * Z if rule == "two-mass" else Z
    return SpeedPI(kp=gain, ki=rho * OMEGA_S**2, R_ff=R_ff, t_on=t_on)


def soft_speed_damping(rho: float, kp: float) -> tuple[float, float]:
    """Damping ratios of the two torsional modes of the string under the SoftSpeed rule.

    With ``ki = rho`` (omega_s = 1) and c = 0 the closed-loop characteristic polynomial of (13),
    (27) is ``rho*s^4 + kp*s^3 + (2*rho + 1)*s^2 + kp*s + rho``: palindromic, so with
    ``y = s + 1/s`` it is ``s^2*(rho*y^2 + kp*y + 1)``. For ``2*sqrt(rho) <= kp <= 2*rho + 1/2``
    both roots y are real in [-2, 0), every pole has |s| = 1 and the damping ratios are
    ``-y/2``: ``(kp -+ sqrt(kp^2 - 4*rho))/(4*rho)``, whose product is ``1/(4*rho)``; at
    ``kp = 2*sqrt(rho)`` both are ``1/(2*sqrt(rho))``. Below that range the poles leave the
    circle, above it one pair becomes real (overdamped).

    Parameters
    ----------
    rho : float
        Inertia ratio I2/I1 (16), > 0.
    kp : float
        Proportional gain in [2*sqrt(rho), 2*rho + 1/2].

    Returns
    -------
    (float, float)
        The smaller and the larger damping ratio.
    """
    rho = check_real("rho", rho, lower=0.0)
    kp = check_real("kp", kp, lower=0.0)
    disc = kp * kp - 4.0 * rho
    if disc < -1e-12 * kp * kp:
        raise ValueError(
            f"kp = {kp!r} is below 2*sqrt(rho) = {2.0 * math.sqrt(rho)!r}: the poles leave the "
            "circle |s| = omega_s and the rule states no damping"
        )
    if kp > 2.0 * rho + 0.5:
        raise ValueError(
            f"kp = {kp!r} is above 2*rho + 1/2 = {2.0 * rho + 0.5!r}: one pair of poles is real "
            "(overdamped) and off the circle |s| = omega_s"
        )
    root = math.sqrt(max(disc, 0.0))
    return ((kp - root) / (4.0 * rho), (kp + root) / (4.0 * rho))


def z_torque(
    params: ScaledParams,
    *,
    matching: float = 1.0,
    Z: float = Z_STRING,
    omega_hp: float = 0.3,
    omega_lp: float = 10.0,
    bandwidth: float = 10.0,
    R_ff: float = 0.0,
    t_on: float = 0.0,
) -> ZTorque:
    """Z-Torque: the stiff speed PI of :func:`stiff_pi` with the set point lowered by
    ``matching*HP(LP(torque))/Z``.

    Parameters
    ----------
    params : ScaledParams
        Gives rho.
    matching : float
        The fraction of full impedance matching (1: the torque feedback of an impedance Z; the
        Simulator4nDOF default is 0.25), >= 0.
    Z : float
        The string impedance (:func:`impedance`), > 0.
    omega_hp : float
        High-pass corner in units of omega_s. The default 0.3 gives the fastest decay of the
        lumped string's closed loop ((13), (27) with c = 0) at rho = 5 (``docs/controllers.md``):
        a lower corner lets the set-point correction linger (slow recovery of the mean speed),
        a higher one shifts the correction's phase at omega_s.
    omega_lp : float
        Low-pass (measurement filter) corner in units of omega_s: a decade above.
    bandwidth : float
        Speed-loop bandwidth of the PI (see :func:`stiff_pi`).
    R_ff, t_on : float
        Feed-forward (31) and switch-on time.

    Returns
    -------
    ZTorque
    """
    pi = stiff_pi(params, bandwidth=bandwidth)
    matching = check_real("z_torque matching", matching, lower=0.0, strict=False)
    Z = check_real("z_torque Z", Z, lower=0.0)
    return ZTorque(
        kp=pi.kp,
        ki=pi.ki,
        z_gain=matching / Z,
        omega_hp=check_real("z_torque omega_hp", omega_hp, lower=0.0) * OMEGA_S,
        omega_lp=check_real("z_torque omega_lp", omega_lp, lower=0.0) * OMEGA_S,
        R_ff=R_ff,
        t_on=t_on,
    )


def linear_closed_loop(model: AveragedModel, law: Law) -> NDArray[np.float64]:
    """System matrix of the linearised torsional model (13), (27) closed by ``law``.

    The plant is :func:`~drillstring.controller.averaged.linearised_ode_matrix` in the state
    ``x = [phi, dphi, phi - theta - K0, dtheta]``, whose input enters row 4 as ``R_fb/rho``
    (the constant R_ff = -K0 balances K0, (31)). The laws in continuous time, with the
    measured string-torque deviation ``theta - phi - (-K0) = -x3``:

    * :class:`SpeedPI`: extra state ``I' = -dtheta``, ``R_fb = -kp*dtheta + ki*I``;
    * :class:`ZTorque`: extra states ``I' = e``, ``z' = omega_hp*(-x3 - z)``,
      ``y' = omega_lp*(-x3 - z - y)``, ``e = -dtheta - z_gain*y``, ``R_fb = kp*e + ki*I``;
    * :class:`SampledAffine`: ``R_fb = F x`` (the ODE form of (29), no extra state).

    Parameters
    ----------
    model : AveragedModel
        The averaged model (c, tau_n0, rho).
    law : Law
        The law (its R_ff and t_on play no part).

    Returns
    -------
    ndarray
        Square matrix; x first, then the law's states.
    """
    A = linearised_ode_matrix(model)
    rho = model.rho
    if isinstance(law, SampledAffine):
        return A + model.B @ np.asarray(law.feedback.F, dtype=float)[None, :]
    if isinstance(law, SpeedPI):
        M = np.zeros((5, 5))
        M[:4, :4] = A
        M[3, 3] += -law.kp / rho
        M[3, 4] = law.ki / rho
        M[4, 3] = -1.0
        return M
    if isinstance(law, ZTorque):
        M = np.zeros((7, 7))
        M[:4, :4] = A
        I, Z, Y = 4, 5, 6  # noqa: E741
        # e = -x4 - z_gain*y ; R_fb = kp*e + ki*I
        e = np.zeros(7)
        e[3] = -1.0
        e[Y] = -law.z_gain
        M[3] += (law.kp * e) / rho
        M[3, I] += law.ki / rho
        M[I] = e
        M[Z, 2] = -law.omega_hp
        M[Z, Z] = -law.omega_hp
        M[Y, 2] = -law.omega_lp
        M[Y, Z] = -law.omega_lp
        M[Y, Y] = -law.omega_lp
        return M
    raise TypeError(f"no linear closed loop for a law of type {type(law).__name__}")
