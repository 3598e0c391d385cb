"""Physical (SI) units of the model: the scales of eqs. (15)-(16), written once.

The scaled model (11)-(14) measures time in t* = sqrt(I1/C), lengths in L* = 2C/(eps a^2) and
torques in C (Section II of the paper; ``docs/model.md``, "Coordinates"). A physical rig
(:class:`~drillstring.model.params.PhysicalParams`) fixes these scales; :class:`SIScaling`
converts between the scaled quantities (perturbations u, phi, theta of the nominal motion, time
tau) and the SI quantities of the rig (total positions and speeds, time t in seconds)::

    time            t            = t* tau                                   [s]
    bit angle       Phi_SI       = Phi = omega0 tau + phi                   [rad]
    table angle     Theta_SI     = Theta + R0/C = R0/C + omega0 tau + theta [rad]
    bit speed       dPhi_SI/dt   = (omega0 + dphi/dtau) / t*                [rad/s]
    table speed     dTheta_SI/dt = (omega0 + dtheta/dtau) / t*              [rad/s]
    bit position    U_SI         = L* U = L* (v0 tau + u)                   [m], downwards
    bit velocity    dU_SI/dt     = L* (v0 + du/dtau) / t*                   [m/s]
    depth of cut    d_SI         = L* d                                     [m]
    delay           t_n          = t* tau_n                                 [s]
    rate of penetration            d_SI / t_n                               [m/s]
    weight on bit   n a (zeta eps d_SI + l sigma_bar (1 - g))              [N], (4) and (7)
    torque on bit   C T                                                     [N m]
    table torque    R            = C (R0/C + r),  r = (R - R0)/C            [N m]

The bit angle is zero at t = 0 of the nominal motion, the table angle is ahead of it by the
twist of the string, Theta_SI - Phi_SI = R0/C + theta - phi (in rad, the twist torque S of
``docs/model.md`` divided by C): the nominal twist is R0/C. The bit position is zero where the
bit is at t = 0 of the nominal motion. The rate of penetration is the mean axial speed of the bit
over the last blade passage (one delay t_n): V0 in the nominal motion, while the axial bit
velocity itself stops and reverses in axial stick-slip.

The controller of Section V, R - R0 = R_ff + F x with x = [phi - phi_ref, dphi/dtau,
phi - theta - K0 - twist_ref, dtheta/dtau] (29)-(31), reads in SI (:class:`PhysicalFeedback`)::

    R = R_ff_SI + F1_SI (e_phi - phi_ref) + F2_SI de_phi
        + F3_SI (e_phi - e_theta - K0_SI - twist_ref) + F4_SI de_theta

with the errors from the speed set point Omega0, e_phi = Phi_SI - Omega0 t,
de_phi = dPhi_SI/dt - Omega0, e_theta = Theta_SI - Omega0 t, de_theta = dTheta_SI/dt - Omega0,
and the gains::

    F1_SI = C F1 [N m/rad]    F2_SI = C t* F2 [N m s/rad]
    F3_SI = C F3 [N m/rad]    F4_SI = C t* F4 [N m s/rad]
    K0_SI = K0 - R0/C [rad]   R_ff_SI = C (R0/C + R_ff) [N m]    t_on_SI = t* t_on [s]

(e_phi = phi, e_phi - e_theta = phi - theta - R0/C, de_phi = dphi/t*, de_theta = dtheta/t*).
The references phi_ref, twist_ref are angles, the same in both.

``docs/si_fmus.md`` has these tables, how well the two unit systems agree and where they are
used. :data:`UNITS` defines every unit the SI FMUs and the SSP packages use, by the exponents of the
SI base units (FMI 2.0 ``BaseUnit``, SSP ``ssc:BaseUnit``) and the display units people read
(rpm, kN, kN.m, mm, m/h).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from drillstring.model.control import LATCH_MODES, AffineFeedback
from drillstring.model.engine import InitialState
from drillstring.model.params import PhysicalParams, ScaledParams, weight_on_bit
from drillstring.validation import check_choice, check_real

__all__ = [
    "BASE_UNITS",
    "Conversion",
    "DisplayUnit",
    "PLANT_SI",
    "PhysicalFeedback",
    "SIScaling",
    "UNITS",
    "UnitDef",
    "UnitMismatch",
    "setpoint_errors",
    "si_plant_values",
    "si_to_tau",
    "si_torque_deviation",
    "unit_conversion",
]

#: The SI base units of FMI 2.0 and SSP 1.0, in the order of their ``BaseUnit`` attributes.
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


@dataclass(frozen=True)
class DisplayUnit:
    """A display unit: value_display = factor * value + offset (FMI 2.0, section 2.2.2)."""

    name: str
    factor: float
    offset: float = 0.0


@dataclass(frozen=True)
class UnitDef:
    """A unit by the exponents of the SI base units (:data:`BASE_UNITS`) and its display units.

    ``factor`` and ``offset`` are those of FMI 2.0's and SSP 1.0's ``BaseUnit``: a value ``x``
    in this unit is ``factor * x + offset`` in the SI base units (1 and 0 for every unit of
    :data:`UNITS`; ``kN.m`` as a unit of its own has factor 1000, ``degC`` offset 273.15).
    """

    name: str
    exponents: Mapping[str, int] = field(default_factory=dict)
    display: tuple[DisplayUnit, ...] = ()
    factor: float = 1.0
    offset: float = 0.0

    def __post_init__(self) -> None:
        unknown = set(self.exponents) - set(BASE_UNITS)
        if unknown:
            raise ValueError(f"unit {self.name!r}: unknown base units {sorted(unknown)}")
        for k, e in self.exponents.items():
            if isinstance(e, bool) or not isinstance(e, int):
                raise ValueError(f"unit {self.name!r}: exponent of {k} must be an int, got {e!r}")
        check_real(f"factor of unit {self.name!r}", self.factor)
        check_real(f"offset of unit {self.name!r}", self.offset)
        if self.factor == 0.0:
            raise ValueError(f"unit {self.name!r}: factor must not be 0")

    @property
    def dimension(self) -> str:
        """The base-unit exponents as text, in the order of :data:`BASE_UNITS`.

        Returns
        -------
        str
            E.g. ``"kg.m2.s-2"`` for N m, ``"s-1.rad"`` for rad/s, ``"1"`` for a
            dimensionless unit.
        """
        parts = []
        for k in BASE_UNITS:
            e = self.exponents.get(k, 0)
            if e:
                parts.append(k if e == 1 else f"{k}{e}")
        return ".".join(parts) or "1"

    def same_dimension(self, other: UnitDef) -> bool:
        """Whether ``other`` has the same base-unit exponents (absent counts as 0).

        Parameters
        ----------
        other : UnitDef
            Another unit.

        Returns
        -------
        bool
            True when every exponent of :data:`BASE_UNITS` agrees.
        """
        return all(self.exponents.get(k, 0) == other.exponents.get(k, 0) for k in BASE_UNITS)

    def display_definition(self, name: str) -> UnitDef:
        """The display unit ``name`` as a unit of its own (for a parameter or a connector).

        FMI 2.0 displays ``x`` as ``factor_d * x + offset_d``; a value ``v`` in the display unit
        is therefore ``x = (v - offset_d) / factor_d`` in this unit and
        ``self.factor * x + self.offset`` in the base units.

        Parameters
        ----------
        name : str
            One of :attr:`display`, e.g. ``"rpm"`` of ``rad/s``.

        Returns
        -------
        UnitDef
            Unit ``name`` with this unit's exponents, factor ``self.factor / factor_d`` and
            offset ``self.offset - self.factor * offset_d / factor_d``.

        Raises
        ------
        ValueError
            This unit has no display unit ``name``.
        """
        d = self.display_unit(name)
        return UnitDef(
            name,
            dict(self.exponents),
            factor=self.factor / d.factor,
            offset=self.offset - self.factor * d.offset / d.factor,
        )

    def display_unit(self, name: str) -> DisplayUnit:
        """The display unit called ``name``.

        Parameters
        ----------
        name : str
            A display unit's name, e.g. ``"rpm"``.

        Returns
        -------
        DisplayUnit
            The first of :attr:`display` with that name.

        Raises
        ------
        ValueError
            This unit has no display unit ``name``.
        """
        for d in self.display:
            if d.name == name:
                return d
        raise ValueError(f"unit {self.name!r} has no display unit {name!r}")


_RPM = DisplayUnit("rpm", 60.0 / (2.0 * math.pi))
#: Every unit of the project's FMUs and SSP packages ("1": dimensionless, all exponents 0).
UNITS: dict[str, UnitDef] = {
    u.name: u
    for u in (
        UnitDef("1"),
        UnitDef("s", {"s": 1}),
        UnitDef("rad", {"rad": 1}, (DisplayUnit("deg", 180.0 / math.pi),)),
        UnitDef("rad/s", {"s": -1, "rad": 1}, (_RPM,)),
        UnitDef("m", {"m": 1}, (DisplayUnit("mm", 1e3),)),
        UnitDef("m/s", {"m": 1, "s": -1}, (DisplayUnit("m/h", 3600.0), DisplayUnit("mm/s", 1e3))),
        UnitDef("kg", {"kg": 1}),
        UnitDef("kg.m2", {"kg": 1, "m": 2}),
        UnitDef("N", {"kg": 1, "m": 1, "s": -2}, (DisplayUnit("kN", 1e-3),)),
        UnitDef("N.m", {"kg": 1, "m": 2, "s": -2}, (DisplayUnit("kN.m", 1e-3),)),
        UnitDef("N/m", {"kg": 1, "s": -2}),
        UnitDef("N.s/m", {"kg": 1, "s": -1}),
        UnitDef("N.m/rad", {"kg": 1, "m": 2, "s": -2, "rad": -1}),
        UnitDef("N.m.s/rad", {"kg": 1, "m": 2, "s": -1, "rad": -1}),
        UnitDef("rad/(N.m.s)", {"kg": -1, "m": -2, "s": 1, "rad": 1}),
        UnitDef("Pa", {"kg": 1, "m": -1, "s": -2}, (DisplayUnit("MPa", 1e-6),)),
    )
}


class UnitMismatch(ValueError):
    """Two units of different dimensions: a value in one cannot be given in the other."""


@dataclass(frozen=True)
class Conversion:
    """A value in unit ``source`` as a value in unit ``target``: ``factor * x + offset``."""

    source: str
    target: str
    factor: float
    offset: float = 0.0

    @property
    def identity(self) -> bool:
        """True when the conversion changes no value (factor 1, offset 0)."""
        return self.factor == 1.0 and self.offset == 0.0

    def __call__(self, x: Any) -> Any:
        """``x`` (float or array, in :attr:`source`) in :attr:`target`.

        Parameters
        ----------
        x : float or numpy.ndarray
            Value(s) in the source unit.

        Returns
        -------
        float or numpy.ndarray
            ``x * factor + offset``.
        """
        return x * self.factor + self.offset


def unit_conversion(source: UnitDef, target: UnitDef) -> Conversion:
    """The conversion of values in ``source`` into ``target`` (same dimension).

    With ``BaseUnit`` factors f and offsets o (:class:`UnitDef`), a value x in ``source`` is
    f_s x + o_s in the base units, hence (f_s x + o_s - o_t) / f_t in ``target``: factor
    f_s / f_t, offset (o_s - o_t) / f_t (rpm to rad/s: pi/30; kN.m to N.m: 1000; degF to degC:
    5/9 and (459.67 * 5/9 - 273.15)).

    Parameters
    ----------
    source, target : UnitDef
        The units.

    Returns
    -------
    Conversion
        ``target = factor * source + offset``; the identity for units of the same factor and
        offset (whatever their names).

    Raises
    ------
    UnitMismatch
        The base-unit exponents differ; the message names both units and their dimensions.
    """
    if not source.same_dimension(target):
        raise UnitMismatch(
            f"{source.name!r} (dimension {source.dimension}) cannot be converted to "
            f"{target.name!r} (dimension {target.dimension})"
        )
    return Conversion(
        source.name,
        target.name,
        source.factor / target.factor,
        (source.offset - target.offset) / target.factor,
    )


@dataclass(frozen=True)
class Quantity:
    """An SI output of the plant: name, unit, display unit, description."""

    name: str
    unit: str
    display: str | None
    description: str


#: The plant's Real outputs in SI (:meth:`SIScaling.plant_outputs`), in this order.
PLANT_SI: tuple[Quantity, ...] = (
    Quantity("bit_angle", "rad", None, "Bit angle Phi (0 at t = 0 of the nominal motion)"),
    Quantity("bit_speed", "rad/s", "rpm", "Bit angular speed dPhi/dt"),
    Quantity("table_angle", "rad", None, "Rotary-table angle Theta = Phi + twist of the string"),
    Quantity("table_speed", "rad/s", "rpm", "Rotary-table angular speed dTheta/dt"),
    Quantity(
        "bit_position",
        "m",
        "mm",
        "Axial bit position U, downwards (0 where the bit is at t = 0 of the nominal motion)",
    ),
    Quantity("bit_velocity", "m/s", "mm/s", "Axial bit velocity dU/dt, downwards"),
    Quantity("weight_on_bit", "N", "kN", "Weight on bit W^c + W^f, eqs. (4) and (7)"),
    Quantity("torque_on_bit", "N.m", "kN.m", "Torque on bit T^c + T^f, eqs. (4) and (7)"),
    Quantity("depth_of_cut", "m", "mm", "Depth of cut d = U(t) - U(t - t_n) per blade, eq. (5)"),
    Quantity("delay", "s", None, "Delay t_n: Phi(t) - Phi(t - t_n) = 2*pi/n, eq. (6)"),
    Quantity(
        "rate_of_penetration",
        "m/s",
        "m/h",
        "Rate of penetration: mean axial bit speed over the last blade passage, d/t_n",
    ),
    Quantity("contact", "1", None, "Wearflat contact multiplier g in [0, 1] of eq. (17)"),
)


# The conversions of the module docstring as plain arithmetic on floats (or numpy arrays), written
# once: SIScaling and PhysicalFeedback call them, and drillstring.model.native compiles the same
# functions into the FMUs' native step, so that both give the same bits.


def si_to_tau(t_star: Any, t: Any) -> Any:
    """tau = t / t*.

    The scaled time of Section II (with (9)-(10)); plain arithmetic on floats or arrays, also
    compiled by :mod:`drillstring.model.native`.

    Parameters
    ----------
    t_star : float
        Characteristic time t* = sqrt(I1/C) [s].
    t : float or ndarray
        Time [s].

    Returns
    -------
    float or ndarray
        The scaled time tau.
    """
    return t / t_star


def si_torque_deviation(C: Any, twist0: Any, R: Any) -> Any:
    """The scaled deviation r = R/C - R0/C of an absolute table torque R [N m].

    Eq. (16): the input R - R0 of (13) in units of C. Plain arithmetic on floats or arrays,
    also compiled by :mod:`drillstring.model.native`.

    Parameters
    ----------
    C : float
        Torsional stiffness [N m/rad].
    twist0 : float
        Nominal scaled torque R0/C (the nominal twist in rad, :attr:`SIScaling.twist0`).
    R : float or ndarray
        Absolute rotary-table torque [N m].

    Returns
    -------
    float or ndarray
        r = R/C - R0/C.
    """
    return R / C - twist0


def si_plant_values(
    k: tuple[float, ...], tau: Any, u: Any, du: Any, phi: Any, dphi: Any, theta: Any,
    dtheta: Any, d: Any, g: Any, tau_n: Any, T: Any,
) -> tuple[Any, ...]:  # fmt: skip
    """The SI plant outputs (:data:`PLANT_SI` order) of the scaled ones at time ``tau``.

    ``k`` is :attr:`SIScaling.plant_constants`; ``T`` the scaled torque on bit. The
    conversions of the module docstring, as plain arithmetic on floats or arrays (no input
    check), also compiled by :mod:`drillstring.model.native`.

    Parameters
    ----------
    k : tuple of 12 float
        omega0, v0, t* [s], L* [m] and R0/C of the scaled set, then C [N m/rad], n, a [m],
        zeta, eps [Pa], l [m], sigma_bar [Pa] of the rig.
    tau : float or ndarray
        Scaled time.
    u, du, phi, dphi, theta, dtheta : float or ndarray
        Scaled perturbations from the nominal motion, (9)-(10), and their tau-derivatives.
    d : float or ndarray
        Scaled depth of cut (5).
    g : float or ndarray
        Contact multiplier of (17).
    tau_n : float or ndarray
        Scaled delay of (14), > 0.
    T : float or ndarray
        Scaled torque on bit (T/C).

    Returns
    -------
    tuple of 12 float or ndarray
        Bit angle [rad], bit speed [rad/s], table angle [rad], table speed [rad/s], bit
        position [m], bit velocity [m/s], weight on bit [N] (eqs. (4) and (7),
        :func:`~drillstring.model.params.weight_on_bit`), torque on bit C*T [N m], depth of cut
        [m], delay [s], rate of penetration [m/s] and the contact multiplier g.
    """
    omega0, v0, ts, Ls, twist0, C, n, a, zeta, eps, l, sigma_bar = k  # noqa: E741
    d_si = Ls * d
    delay = ts * tau_n
    return (
        omega0 * tau + phi,
        (omega0 + dphi) / ts,
        twist0 + omega0 * tau + theta,
        (omega0 + dtheta) / ts,
        Ls * (v0 * tau + u),
        Ls * (v0 + du) / ts,
        weight_on_bit(n, a, zeta, eps, l, sigma_bar, d_si, g),
        C * T,
        d_si,
        delay,
        d_si / delay,
        g,
    )


def setpoint_errors(
    Omega0: float, t: float, bit_angle: float, bit_speed: float, table_angle: float,
    table_speed: float,
) -> tuple[float, float, float, float]:  # fmt: skip
    """(e_phi, de_phi, e_theta, de_theta): the measured angles and speeds minus the set point's
    Omega0 t and Omega0 (:meth:`PhysicalFeedback.errors`).

    Parameters
    ----------
    Omega0 : float
        Speed set point [rad/s].
    t : float
        Time [s].
    bit_angle : float
        Measured bit angle Phi [rad].
    bit_speed : float
        Measured bit speed dPhi/dt [rad/s].
    table_angle : float
        Measured rotary-table angle Theta [rad].
    table_speed : float
        Measured rotary-table speed dTheta/dt [rad/s].

    Returns
    -------
    tuple of 4 float
        bit_angle - Omega0 t, bit_speed - Omega0, table_angle - Omega0 t, table_speed - Omega0:
        the arguments phi, dphi, theta, dtheta of the law (29)-(31) in SI (module docstring).
    """
    w = Omega0
    return bit_angle - w * t, bit_speed - w, table_angle - w * t, table_speed - w


@dataclass(frozen=True)
class SIScaling:
    """The scales t*, L*, C of a physical rig and the conversions of the module docstring.

    Parameters
    ----------
    rig : PhysicalParams
        The physical parameter set; its scaled form (15)-(16) is :attr:`scaled`.
    """

    rig: PhysicalParams
    scaled: ScaledParams = field(init=False)
    t_star: float = field(init=False)
    L_star: float = field(init=False)
    #: nominal twist R0/C of the scaled set [rad] (the scaled nominal torque, eq. (8))
    twist0: float = field(init=False)

    def __post_init__(self) -> None:
        if not isinstance(self.rig, PhysicalParams):
            raise TypeError(f"SIScaling needs a PhysicalParams, got {type(self.rig).__name__}")
        scaled = self.rig.to_scaled()
        object.__setattr__(self, "scaled", scaled)
        object.__setattr__(self, "t_star", self.rig.t_star)
        object.__setattr__(self, "L_star", self.rig.L_star)
        object.__setattr__(self, "twist0", scaled.R0)

    @property
    def plant_constants(self) -> tuple[float, ...]:
        """The constants of :func:`si_plant_values`: omega0, v0, t*, L*, R0/C of the scaled
        set, and C, n, a, zeta, eps, l, sigma_bar of the rig."""
        p, r = self.scaled, self.rig
        return (p.omega0, p.v0, self.t_star, self.L_star, self.twist0, r.C, float(r.n), r.a,
                r.zeta, r.eps, r.l, r.sigma_bar)  # fmt: skip

    # ------------------------------------------------------------------ time and torque
    def time(self, tau: Any) -> Any:
        """t = t* tau [s].

        Parameters
        ----------
        tau : float or ndarray
            Scaled time.

        Returns
        -------
        float or ndarray
            The time in seconds.
        """
        return self.t_star * tau

    def tau(self, t: Any) -> Any:
        """tau = t / t*.

        Parameters
        ----------
        t : float or ndarray
            Time [s].

        Returns
        -------
        float or ndarray
            The scaled time.
        """
        return si_to_tau(self.t_star, t)

    def table_torque(self, r: Any) -> Any:
        """Absolute table torque R = C (R0/C + r) [N m] of the scaled deviation r = (R - R0)/C.

        Eq. (16) solved for R; the inverse of :meth:`torque_deviation`.

        Parameters
        ----------
        r : float or ndarray
            Scaled torque deviation R - R0 (units of C), the input of (13).

        Returns
        -------
        float or ndarray
            R [N m].
        """
        return self.rig.C * (self.twist0 + r)

    def torque_deviation(self, R: Any) -> Any:
        """The scaled deviation r = R/C - R0/C of an absolute table torque R [N m].

        Eq. (16), as :func:`si_torque_deviation` with the rig's C and R0/C.

        Parameters
        ----------
        R : float or ndarray
            Absolute rotary-table torque [N m].

        Returns
        -------
        float or ndarray
            r, the input R - R0 of (13).
        """
        return si_torque_deviation(self.rig.C, self.twist0, R)

    # ------------------------------------------------------------------ the plant
    def plant_outputs(
        self, values: Mapping[str, Any], tau: Any, torque_on_bit: Any = None
    ) -> dict[str, Any]:
        """The SI outputs (:data:`PLANT_SI`) of the scaled plant outputs at time ``tau``.

        Parameters
        ----------
        values : mapping
            Scaled outputs ``u, du, phi, dphi, theta, dtheta, d, g, tau_n`` (floats or arrays,
            e.g. :meth:`Engine.outputs` or a :class:`SimulationResult`'s columns); any of
            ``mode, stick_events, bit_bounce, torsional_stick`` are passed on unchanged.
        tau : float or array
            The scaled time of the values.
        torque_on_bit : float or array, optional
            The scaled torque on bit T (``Engine.diagnostics()["torque_on_bit"]``, which is the
            twist torque during torsional stick); without it, eqs. (4) and (7) of the physical
            rig at d and g (valid while the bit rotates).

        Returns
        -------
        dict
            Name -> SI value (see the module docstring).
        """
        v = values
        T = 0.0 if torque_on_bit is None else torque_on_bit
        si = si_plant_values(
            self.plant_constants, tau, v["u"], v["du"], v["phi"], v["dphi"], v["theta"],
            v["dtheta"], v["d"], v["g"], v["tau_n"], T,
        )  # fmt: skip
        out = dict(zip((q.name for q in PLANT_SI), si, strict=True))
        if torque_on_bit is None:
            out["torque_on_bit"] = self.rig.torque_on_bit(out["depth_of_cut"], v["g"])
        for key in ("mode", "stick_events", "bit_bounce", "torsional_stick"):
            if key in values:
                out[key] = values[key]
        return out

    def initial_to_scaled(self, si: Mapping[str, float]) -> InitialState:
        """The scaled initial perturbation of SI deviations from the nominal motion at t = 0.

        Parameters
        ----------
        si : mapping
            ``u`` [m], ``du`` [m/s], ``phi`` [rad], ``dphi`` [rad/s], ``theta`` [rad],
            ``dtheta`` [rad/s] (missing keys: 0).

        Returns
        -------
        InitialState
            u/L*, t* du/L*, phi, t* dphi, theta, t* dtheta.
        """
        unknown = set(si) - {"u", "du", "phi", "dphi", "theta", "dtheta"}
        if unknown:
            raise ValueError(f"unknown initial-state key(s) {sorted(unknown)}")
        ts, Ls = self.t_star, self.L_star
        return InitialState(
            u=si.get("u", 0.0) / Ls,
            du=ts * si.get("du", 0.0) / Ls,
            phi=si.get("phi", 0.0),
            dphi=ts * si.get("dphi", 0.0),
            theta=si.get("theta", 0.0),
            dtheta=ts * si.get("dtheta", 0.0),
        )

    def initial_to_si(self, initial: InitialState | Mapping[str, float]) -> dict[str, float]:
        """Inverse of :meth:`initial_to_scaled`.

        Parameters
        ----------
        initial : InitialState or mapping
            Scaled initial perturbation (a mapping of some of its fields, the others 0).

        Returns
        -------
        dict of str to float
            Deviations from the nominal motion at t = 0: ``u`` = L* u [m], ``du`` = L* du/t* [m/s],
            ``phi`` [rad], ``dphi`` = dphi/t* [rad/s], ``theta`` [rad], ``dtheta`` = dtheta/t*
            [rad/s].

        Raises
        ------
        ValueError
            A key of the mapping is not a field, or a value is not a finite real number.
        """
        x = InitialState.coerce(initial)
        ts, Ls = self.t_star, self.L_star
        return {
            "u": Ls * x.u,
            "du": Ls * x.du / ts,
            "phi": x.phi,
            "dphi": x.dphi / ts,
            "theta": x.theta,
            "dtheta": x.dtheta / ts,
        }


@dataclass(frozen=True)
class PhysicalFeedback:
    """The controller (29)-(31) in SI units (module docstring): R = R_ff + F x [N m].

    Parameters
    ----------
    F : tuple of 4 float
        Gains on x = [e_phi - phi_ref, de_phi, e_phi - e_theta - K0 - twist_ref, de_theta]:
        N m/rad, N m s/rad, N m/rad, N m s/rad.
    K0 : float
        Twist offset of x3 [rad] (K0 - R0/C of the scaled law).
    R_ff : float
        Feed-forward table torque [N m] (absolute: C (R0/C + R_ff) of the scaled law).
    Omega0 : float
        Speed set point [rad/s]: the errors are taken from Omega0 t and Omega0.
    t_on : float
        Switch-on time [s] of the feedback.
    latch : str
        Bumpless switch-on, one of :data:`~drillstring.model.control.LATCH_MODES`.
    """

    F: tuple[float, float, float, float]
    K0: float
    R_ff: float
    Omega0: float
    t_on: float = 0.0
    latch: str = "none"

    def __post_init__(self) -> None:
        if len(self.F) != 4:
            raise ValueError(f"PhysicalFeedback.F must have 4 entries, got {self.F!r}")
        F = tuple(check_real(f"PhysicalFeedback.F[{i}]", f) for i, f in enumerate(self.F))
        object.__setattr__(self, "F", F)
        for name in ("K0", "R_ff", "t_on"):
            object.__setattr__(
                self, name, check_real(f"PhysicalFeedback.{name}", getattr(self, name))
            )
        object.__setattr__(
            self, "Omega0", check_real("PhysicalFeedback.Omega0", self.Omega0, lower=0.0)
        )
        check_choice("PhysicalFeedback.latch", self.latch, LATCH_MODES)

    @property
    def latch_code(self) -> int:
        """Index of ``latch`` in :data:`~drillstring.model.control.LATCH_MODES`."""
        return LATCH_MODES.index(self.latch)

    def errors(
        self, t: float, bit_angle: float, bit_speed: float, table_angle: float, table_speed: float
    ) -> tuple[float, float, float, float]:
        """(e_phi, de_phi, e_theta, de_theta): the measured angles and speeds minus the set
        point's Omega0 t and Omega0, the arguments phi, dphi, theta, dtheta of
        :func:`~drillstring.model.control.feedback_torque` in SI.

        Parameters
        ----------
        t : float
            Time [s].
        bit_angle : float
            Measured bit angle Phi [rad].
        bit_speed : float
            Measured bit speed dPhi/dt [rad/s].
        table_angle : float
            Measured rotary-table angle Theta [rad].
        table_speed : float
            Measured rotary-table speed dTheta/dt [rad/s].

        Returns
        -------
        tuple of 4 float
            As :func:`setpoint_errors` with this law's :attr:`Omega0`.
        """
        return setpoint_errors(self.Omega0, t, bit_angle, bit_speed, table_angle, table_speed)

    @classmethod
    def from_scaled(cls, law: AffineFeedback, scaling: SIScaling) -> PhysicalFeedback:
        """The SI law of a scaled law (29)-(31) on the rig of ``scaling``.

        Parameters
        ----------
        law : AffineFeedback
            The scaled law.
        scaling : SIScaling
            The rig's scales.

        Returns
        -------
        PhysicalFeedback
            Gains (C F1, C t* F2, C F3, C t* F4), K0 - R0/C, the absolute feed-forward torque
            C (R0/C + R_ff), the rig's Omega0 as set point, t* t_on and the same latch (module
            docstring).
        """
        C, ts = scaling.rig.C, scaling.t_star
        F1, F2, F3, F4 = law.F
        return cls(
            F=(C * F1, C * ts * F2, C * F3, C * ts * F4),
            K0=law.K0 - scaling.twist0,
            R_ff=scaling.table_torque(law.R_ff),
            Omega0=scaling.rig.Omega0,
            t_on=scaling.time(law.t_on),
            latch=law.latch,
        )

    def to_scaled(self, scaling: SIScaling) -> AffineFeedback:
        """Inverse of :meth:`from_scaled` (the set point must be the rig's Omega0).

        Parameters
        ----------
        scaling : SIScaling
            The rig's scales.

        Returns
        -------
        AffineFeedback
            The scaled law (29)-(31).

        Raises
        ------
        ValueError
            :attr:`Omega0` differs from the rig's Omega0 by more than 1e-12 relative.
        """
        if self.Omega0 != scaling.rig.Omega0 and not math.isclose(
            self.Omega0, scaling.rig.Omega0, rel_tol=1e-12
        ):
            raise ValueError(
                f"the controller's set point Omega0 = {self.Omega0!r} rad/s is not the rig's "
                f"nominal speed {scaling.rig.Omega0!r} rad/s: (29)-(31) is a law about the "
                "nominal motion"
            )
        C, ts = scaling.rig.C, scaling.t_star
        F1, F2, F3, F4 = self.F
        return AffineFeedback(
            F=(F1 / C, F2 / (C * ts), F3 / C, F4 / (C * ts)),
            K0=self.K0 + scaling.twist0,
            R_ff=scaling.torque_deviation(self.R_ff),
            t_on=scaling.tau(self.t_on),
            latch=self.latch,
        )
