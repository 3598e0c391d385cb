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

A parameter of a control law, a top drive or a sensor converts by a pure scale factor: its
:class:`Dimension` (:data:`DIMENSIONS`) gives the exponents of C (torque) and t* (time) in
``value_SI = value * C**torque * t***time``, so every law has one SI conversion, driven by its
table of parameters (:mod:`drillstring.model.laws`). Offsets appear only where a total quantity
meets a perturbation: the angles (Omega0 t and the nominal twist R0/C), the speeds (Omega0), the
table torque (R0); the controller FMUs convert their connectors there
(:mod:`drillstring.model.digital.block`), the plant FMU by :func:`si_plant_values`.

``docs/si_fmus.md`` has these tables, how well the two unit systems agree and where they are
used. :data:`UNITS` defines every unit the SI FMUs and the SSP packages use, by the exponents of the
SI base units (FMI 2.0 ``BaseUnit``, SSP ``ssc:BaseUnit``) and the display units people read
(rpm, kN, kN.m, mm, m/h).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from drillstring.model.engine import InitialState
from drillstring.model.params import REFERENCE_RIG, PhysicalParams, ScaledParams, weight_on_bit
from drillstring.validation import check_real

__all__ = [
    "BASE_UNITS",
    "Conversion",
    "DisplayUnit",
    "DIMENSIONS",
    "Dimension",
    "PLANT_SI",
    "IDENTITY",
    "SCALED_TIME",
    "SCALED_UNITS",
    "SIScaling",
    "SI_UNITS",
    "Scales",
    "UNIT_SYSTEMS",
    "UnitSystem",
    "UNITS",
    "UnitDef",
    "UnitMismatch",
    "si_scale",
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
        UnitDef("W", {"kg": 1, "m": 2, "s": -3}, (DisplayUnit("kW", 1e-3),)),
        UnitDef("N.m/s", {"kg": 1, "m": 2, "s": -3}, (DisplayUnit("kN.m/s", 1e-3),)),
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
class Dimension:
    """The dimension of a parameter in the scales of Section II: ``value_SI = value *
    C**torque * t***time * L***length`` (angles are the same in both unit systems, eq. (10)).

    Attributes
    ----------
    name : str
        The key in :data:`DIMENSIONS`.
    torque, time, length : int
        Exponents of the torque scale C [N m/rad], the time scale t* [s] and the length scale
        L* [m].
    unit : str
        The SI unit (a key of :data:`UNITS`); ``display`` a display unit of it, or None.
    """

    name: str
    torque: int
    time: int
    unit: str
    display: str | None = None
    length: int = 0


#: Every dimension a law, a top drive or a sensor parameter has.
DIMENSIONS: dict[str, Dimension] = {
    d.name: d
    for d in (
        Dimension("1", 0, 0, "1"),
        Dimension("time", 0, 1, "s"),
        Dimension("angle", 0, 0, "rad"),
        Dimension("speed", 0, -1, "rad/s", "rpm"),
        Dimension("frequency", 0, -1, "rad/s"),
        Dimension("torque", 1, 0, "N.m", "kN.m"),
        Dimension("torque rate", 1, -1, "N.m/s", "kN.m/s"),
        Dimension("power", 1, -1, "W", "kW"),
        Dimension("stiffness", 1, 0, "N.m/rad"),  # torque per angle
        Dimension("impedance", 1, 1, "N.m.s/rad"),  # torque per speed
        Dimension("admittance", -1, -1, "rad/(N.m.s)"),  # speed per torque
        Dimension("inertia", 1, 2, "kg.m2"),
        Dimension("length", 0, 0, "m", "mm", length=1),
        Dimension("velocity", 0, -1, "m/s", "mm/s", length=1),
    )
}

#: The time base of the scaled FMUs in words, for their model descriptions: their numbers of time
#: are the paper's scaled time (Section II), t = t* tau.
SCALED_TIME = (
    f"scaled time tau = t/t*, in units of t* = sqrt(I1/C) seconds of the rig "
    f"({REFERENCE_RIG.t_star:.6g} s on the reference rig)"
)


def si_scale(dimension: str, C: float, t_star: float, L_star: float | None = None) -> float:
    """The factor from scaled to SI values of a parameter of ``dimension``.

    Parameters
    ----------
    dimension : str
        A key of :data:`DIMENSIONS`.
    C : float
        Torsional stiffness of the string [N m/rad] (the torque scale, eq. (16)).
    t_star : float
        Characteristic time t* = sqrt(I1/C) [s] (Section II).
    L_star : float, optional
        Characteristic length L* = 2C/(eps a^2) [m]; needed for a dimension with a length.

    Returns
    -------
    float
        ``C**torque * t_star**time * L_star**length``: SI value = scaled value times this.

    Raises
    ------
    ValueError
        ``dimension`` is not a key of :data:`DIMENSIONS`, or it has a length and no ``L_star``
        is given.
    """
    d = DIMENSIONS.get(dimension)
    if d is None:
        raise ValueError(f"unknown dimension {dimension!r} (known: {', '.join(DIMENSIONS)})")
    scale = C**d.torque * t_star**d.time
    if d.length:
        if L_star is None:
            raise ValueError(f"dimension {dimension!r} needs the length scale L_star")
        scale *= L_star**d.length
    return scale


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
    Quantity(
        "top_torque",
        "N.m",
        "kN.m",
        "Torque at the top of the string, what a sub under the top drive measures",
    ),
)


# The conversions of the module docstring as plain arithmetic on floats (or numpy arrays), written
# once: SIScaling calls them, and drillstring.model.native compiles the same
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
    dtheta: Any, d: Any, g: Any, tau_n: Any, T: Any, top: Any,
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
    top : float or ndarray
        Scaled torque at the top of the string less R0 (``top_torque_minus_R0``).

    Returns
    -------
    tuple of 13 float or ndarray
        Bit angle [rad], bit speed [rad/s], table angle [rad], table speed [rad/s], bit
        position [m], bit velocity [m/s], weight on bit [N] (eqs. (4) and (7),
        :func:`~drillstring.model.params.weight_on_bit`), torque on bit C*T [N m], depth of cut
        [m], delay [s], rate of penetration [m/s], the contact multiplier g and the torque at
        the top of the string C*(R0/C + top) [N m].
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
        C * (twist0 + top),
    )


@dataclass(frozen=True)
class Scales:
    """The scales of a unit system and the conversions of the module docstring.

    A value of a parameter in the unit system is its scaled value times ``C**torque *
    t_star**time * L_star**length`` (:data:`DIMENSIONS`); a table angle or torque is offset by
    the nominal twist ``twist0`` = R0/C. The defaults are the scaled system's: every conversion
    is the identity (bit for bit: a product with 1.0, a quotient by 1.0, a sum with 0.0).
    :class:`SIScaling` holds those of a physical rig.

    Attributes
    ----------
    C : float
        The torque scale: torsional stiffness of the string [N m/rad] (eq. (16)).
    t_star : float
        The time scale t* = sqrt(I1/C) [s] (Section II).
    L_star : float
        The length scale L* = 2C/(eps a^2) [m].
    twist0 : float
        Nominal twist R0/C of the scaled set [rad] (the scaled nominal torque, eq. (8)).
    """

    C: float = 1.0
    t_star: float = 1.0
    L_star: float = 1.0
    twist0: float = 0.0

    def factor(self, dimension: str) -> float:
        """The factor ``C**torque * t_star**time * L_star**length`` from scaled values of
        ``dimension`` (a key of :data:`DIMENSIONS`) to this system's (:func:`si_scale`)."""
        return si_scale(dimension, self.C, self.t_star, self.L_star)

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
        return self.C * (self.twist0 + r)

    def torque_deviation(self, R: Any) -> Any:
        """The scaled deviation r = R/C - R0/C of an absolute table torque R [N m].

        Eq. (16), as :func:`si_torque_deviation` with these C and R0/C.

        Parameters
        ----------
        R : float or ndarray
            Absolute rotary-table torque [N m].

        Returns
        -------
        float or ndarray
            r, the input R - R0 of (13).
        """
        return si_torque_deviation(self.C, self.twist0, R)

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
        x = InitialState.coerce(si)  # the SI values, checked as the scaled ones
        ts, Ls = self.t_star, self.L_star
        return InitialState(
            u=x.u / Ls,
            du=ts * x.du / Ls,
            phi=x.phi,
            dphi=ts * x.dphi,
            theta=x.theta,
            dtheta=ts * x.dtheta,
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


#: The scales of the scaled system: every conversion the identity.
IDENTITY = Scales()


@dataclass(frozen=True, init=False)
class SIScaling(Scales):
    """The scales t*, L*, C of a physical rig (:class:`Scales`) and its plant's SI outputs.

    Parameters
    ----------
    rig : PhysicalParams
        The physical parameter set; its scaled form (15)-(16) is :attr:`scaled`.
    """

    rig: PhysicalParams
    scaled: ScaledParams

    def __init__(self, rig: PhysicalParams) -> None:
        if not isinstance(rig, PhysicalParams):
            raise TypeError(f"SIScaling needs a PhysicalParams, got {type(rig).__name__}")
        scaled = rig.to_scaled()
        for name, value in (("C", rig.C), ("t_star", rig.t_star), ("L_star", rig.L_star),
                            ("twist0", scaled.R0), ("rig", rig), ("scaled", scaled)):  # fmt: skip
            object.__setattr__(self, name, value)

    @property
    def plant_constants(self) -> tuple[float, ...]:
        """The constants of :func:`si_plant_values`: omega0, v0, t*, L*, R0/C of the scaled
        set, and C, n, a, zeta, eps, l, sigma_bar of the rig."""
        p, r = self.scaled, self.rig
        return (p.omega0, p.v0, self.t_star, self.L_star, self.twist0, r.C, float(r.n), r.a,
                r.zeta, r.eps, r.l, r.sigma_bar)  # fmt: skip

    # ------------------------------------------------------------------ the plant
    def plant_outputs(
        self, values: Mapping[str, Any], tau: Any, torque_on_bit: Any = None
    ) -> dict[str, Any]:
        """The SI outputs (:data:`PLANT_SI`) of the scaled plant outputs at time ``tau``.

        Parameters
        ----------
        values : mapping
            Scaled outputs ``u, du, phi, dphi, theta, dtheta, d, g, tau_n`` and, on the
            distributed string, ``top_torque_minus_R0`` (else the one-mode twist theta - phi)
            (floats or arrays,
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
            v["top_torque_minus_R0"] if "top_torque_minus_R0" in v else v["theta"] - v["phi"],
        )  # fmt: skip
        out = dict(zip((q.name for q in PLANT_SI), si, strict=True))
        if torque_on_bit is None:
            out["torque_on_bit"] = self.rig.torque_on_bit(out["depth_of_cut"], v["g"])
        for key in ("mode", "stick_events", "bit_bounce", "torsional_stick"):
            if key in values:
                out[key] = values[key]
        return out


@dataclass(frozen=True)
class UnitSystem:
    """A unit system of the FMUs, the SSP packages and the loop: what each asks of it.

    :data:`SCALED_UNITS` (the paper's scaled quantities, whose conversions are the identity) or
    :data:`SI_UNITS` (SI units and seconds on a rig, :class:`SIScaling`). Code that serves both
    asks the system instead of branching on its name.

    Attributes
    ----------
    name : str
        ``"scaled"`` or ``"si"`` (the FMU scripts' ``UNIT_SYSTEM``).
    suffix : str
        Of the FMUs', packages' and systems' names (``DrillStringPlant`` + suffix).
    physical : bool
        Whether values are a physical rig's (converted by the rig's scales) or scaled.
    quantities : str
        The system in words, for descriptions (``"SI units and seconds"``).
    time_unit : str
        Appended to a time shown to a person (``" s"``; ``""``: the scaled time tau).
    time_note : str
        Appended to the description of a time-valued variable: the unit of its number, which
        a tool cannot read from the scaled FMUs' unit "1" (:data:`SCALED_TIME`).
    """

    name: str
    suffix: str
    physical: bool
    quantities: str
    time_unit: str
    time_note: str

    def scales(self, rig: PhysicalParams = REFERENCE_RIG) -> Scales:
        """The system's scales on ``rig`` (default: the reference rig, the SI FMUs' start
        values): ``SIScaling(rig)`` in SI, :data:`IDENTITY` in the scaled system."""
        return SIScaling(rig) if self.physical else IDENTITY

    def factor(self, dimension: str) -> float:
        """The factor from scaled values of ``dimension`` (a key of :data:`DIMENSIONS`) to the
        system's on the reference rig (1 in the scaled system)."""
        return self.scales().factor(dimension)

    def declared_unit(self, unit: str, display: str | None) -> dict[str, str]:
        """The attributes ``unit`` and ``display_unit`` (if not None) a variable of SI ``unit``
        declares in the system: none in the scaled system, whose numbers are of unit "1"."""
        if not self.physical:
            return {}
        return {"unit": unit} | ({"display_unit": display} if display is not None else {})

    def parameter_set(self, values: Mapping[str, Any]) -> tuple[ScaledParams, Scales]:
        """The scaled parameter set (15)-(16) of a plant's parameter values in the system, and
        the scales of their rig.

        Parameters
        ----------
        values : mapping
            By field name: of :class:`~drillstring.model.params.PhysicalParams` in SI, of
            :class:`~drillstring.model.params.ScaledParams` in the scaled system (others are
            ignored).

        Returns
        -------
        (ScaledParams, Scales)
            The set and the rig's :class:`SIScaling`, or the set and :data:`IDENTITY`.

        Raises
        ------
        ValueError
            A value the parameter set rejects (the message names it), or a rig whose scaled
            set is invalid.
        """
        if self.physical:
            scaling = SIScaling(
                PhysicalParams(**{f.name: values[f.name] for f in fields(PhysicalParams)})
            )
            return scaling.scaled, scaling
        scaled = {f.name: values[f.name] for f in fields(ScaledParams) if f.init}
        return ScaledParams(**scaled), IDENTITY


#: The paper's scaled quantities: every conversion the identity.
SCALED_UNITS = UnitSystem(
    "scaled", "", False, "the paper's scaled quantities", "", f"; in the {SCALED_TIME}"
)
#: SI units and seconds.
SI_UNITS = UnitSystem("si", "SI", True, "SI units and seconds", " s", "; in seconds")
#: The unit systems by name.
UNIT_SYSTEMS: dict[str, UnitSystem] = {u.name: u for u in (SCALED_UNITS, SI_UNITS)}
