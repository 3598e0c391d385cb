"""Model parameters: scaled set, physical set, the reference set, and parameter files.

Two frozen dataclasses:

* :class:`ScaledParams` holds the dimensionless parameters of the scaled model, eqs. (11)-(14) of
  Besselink, van de Wouw and Nijmeijer (IEEE CCA 2011): ``n, psi, gamma, eta, lam, beta, rho, v0,
  omega0`` (``lam`` is the paper's lambda). Derived quantities (nominal delay, depth of cut, torque,
  and the fast-time quantities of Section III) are properties.
* :class:`PhysicalParams` holds the dimensional parameters of eqs. (1)-(8) and maps them onto the
  scaled set with eqs. (15)-(16), using t* = sqrt(I1/C) and L* = 2C/(eps*a^2).

Validation happens on construction; any bad value raises :class:`ParameterError` (a ``ValueError``)
whose message names the field and the value. Rules:

* ``n`` (both classes) must be a positive integer. ``bool`` is rejected. A float is accepted only if
  it is integral (``4.0`` is coerced to ``4``, as FMI hosts and JSON writers may deliver integers as
  reals); ``4.5`` is rejected.
* Every other field must be a finite real number (``bool`` and strings are rejected); it is
  stored as ``float``.
* Scaled: ``psi, eta, rho, v0, omega0 > 0``; ``gamma >= 0`` (undamped allowed); ``lam >= 0``
  (``lam = 0`` is a perfectly sharp cutter); ``0 < beta <= 1``.
* Physical: ``M, I1, I2, C, K, a, eps, zeta, mu, xi, V0, Omega0 > 0``; ``D, sigma_bar, l >= 0``
  (no axial damping, no contact stress, a sharp cutter are all meaningful limits). ``mu, xi > 0``
  because ``beta = zeta*mu*xi`` must be positive; ``beta <= 1`` is checked by :meth:`to_scaled`.

Named sets
----------
``"reference"`` is :data:`REFERENCE`, our reconstruction of the paper's Table I (``docs/model.md``,
"Reference parameter set"). ``"reference-rig"`` is :data:`REFERENCE_RIG`, a physical rig in SI
units that maps onto it by (15)-(16) (``docs/reference_rig.md``). ``"pipe-rig"`` is
:data:`PIPE_RIG`, the same rig with its axial mass M and stiffness K made consistent with its
drill pipe (``docs/reference_rig.md``, "The pipe rig"): a second, labelled rig that does not map
onto :data:`REFERENCE`; the reference set stays the default everywhere. :func:`get_params`,
:data:`KNOWN_PARAMS` and :func:`params_from_spec` always give :class:`ScaledParams` (a physical
set converted by :meth:`PhysicalParams.to_scaled`, like :func:`load_params` does for files);
:func:`get_physical` and :data:`KNOWN_PHYSICAL` give the physical sets as :class:`PhysicalParams`.

Parameter files
---------------
TOML (``.toml``) or JSON (``.json``), chosen by suffix. One flat table: a ``kind`` key, either
``"scaled"`` or ``"physical"``, then exactly the fields of that kind. Every field is required; any
other key is an error naming the key. In files and dicts the scaled field ``lam`` is spelt
``lambda`` (``lam`` is accepted on input too, but not both). Example (``data/reference.toml``)::

    kind = "scaled"
    n = 4
    psi = 250.0
    gamma = 6.324555320336759
    eta = 10.0
    lambda = 1.58
    beta = 0.5
    rho = 5.0
    v0 = 1.0
    omega0 = 5.0

A physical file has ``kind = "physical"`` and the keys ``M, I1, I2, C, K, D, n, a, eps, zeta,
sigma_bar, l, mu, xi, V0, Omega0`` (SI units). :func:`load_params` always returns a
:class:`ScaledParams` (physical files are converted with :meth:`PhysicalParams.to_scaled`);
:func:`read_params` returns whichever kind the file holds. :func:`save_params` writes either kind
atomically (temporary file in the same folder, then ``os.replace``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

from drillstring.fileio import load_table, write_text
from drillstring.validation import check_int, check_real

__all__ = [
    "KNOWN_PARAMS",
    "KNOWN_PHYSICAL",
    "PIPE_RIG",
    "REFERENCE",
    "REFERENCE_RIG",
    "REFERENCE_PIPE_EA_L",
    "REFERENCE_PIPE_LENGTH",
    "REFERENCE_PIPE_MASS",
    "REFERENCE_RIG_CHOICES",
    "REFERENCE_RIG_PIPE",
    "ParameterError",
    "PhysicalParams",
    "ScaledParams",
    "get_params",
    "get_physical",
    "known_rig",
    "load_params",
    "params_from_spec",
    "read_params",
    "rig_from_spec",
    "save_params",
]


class ParameterError(ValueError):
    """An invalid parameter value, an unknown or missing key, or an unreadable parameter file."""


# --------------------------------------------------------------------------------------------
# value checks
# --------------------------------------------------------------------------------------------


def _check_fields(obj: Any, ints: tuple[str, ...], rules: Mapping[str, tuple[float, bool]]) -> None:
    """Validate and coerce the fields of a frozen dataclass in place."""
    cls = type(obj).__name__
    for name in ints:
        value = check_int(
            f"{cls}.{name}", getattr(obj, name), lower=1, integral_floats=True, error=ParameterError
        )
        object.__setattr__(obj, name, value)
    for name, (lower, strict) in rules.items():
        value = check_real(
            f"{cls}.{name}", getattr(obj, name), lower=lower, strict=strict, error=ParameterError
        )
        object.__setattr__(obj, name, value)


def _dict_to_fields(
    cls: type, data: Mapping[str, Any], aliases: Mapping[str, str], *, complete: bool = True
) -> dict[str, Any]:
    """Map keys of ``data`` to field names of the dataclass ``cls``; unknown or duplicate (via
    alias) keys are errors, and so are missing ones if ``complete``."""
    fields = tuple(f.name for f in dataclasses.fields(cls))
    where = cls.__name__
    if not isinstance(data, Mapping):
        raise ParameterError(
            f"{where}: expected a mapping of parameters, got {type(data).__name__}"
        )
    out: dict[str, Any] = {}
    for key, value in data.items():
        name = aliases.get(key, key)
        if name not in fields:
            known = ", ".join(aliases.get(f, f) for f in fields)
            raise ParameterError(f"{where}: unknown key {key!r} (known keys: {known})")
        if name in out:
            raise ParameterError(f"{where}: key {key!r} given twice (as {name!r} and an alias)")
        out[name] = value
    missing = [f for f in fields if f not in out]
    if complete and missing:
        raise ParameterError(f"{where}: missing key(s) {', '.join(missing)}")
    return out


# --------------------------------------------------------------------------------------------
# scaled parameters
# --------------------------------------------------------------------------------------------

_SCALED_RULES: dict[str, tuple[float, bool]] = {
    # name: (lower bound, strict)
    "psi": (0.0, True),
    "gamma": (0.0, False),
    "eta": (0.0, True),
    "lam": (0.0, False),
    "beta": (0.0, True),
    "rho": (0.0, True),
    "v0": (0.0, True),
    "omega0": (0.0, True),
}
# file/dict key -> field name; "lambda" is the paper's name and the key written to files
_SCALED_IN_ALIASES = {"lambda": "lam"}
_SCALED_OUT_KEYS = {"lam": "lambda"}


@dataclass(frozen=True)
class ScaledParams:
    """Dimensionless parameters of the scaled model, eqs. (11)-(17).

    Attributes: ``n`` blades; ``psi`` drill-string design (15); ``gamma``, ``eta`` axial damping
    and stiffness (15); ``lam`` bluntness lambda (16); ``beta`` bit design (16); ``rho`` inertia
    ratio I2/I1 (16); ``v0`` nominal axial velocity; ``omega0`` nominal angular velocity (14).
    """

    n: int
    psi: float
    gamma: float
    eta: float
    lam: float
    beta: float
    rho: float
    v0: float
    omega0: float

    def __post_init__(self) -> None:
        _check_fields(self, ("n",), _SCALED_RULES)
        if self.beta > 1.0:
            raise ParameterError(f"ScaledParams.beta must be in (0, 1], got {self.beta!r}")

    # -- derived quantities -----------------------------------------------------------------
    @property
    def tau_n0(self) -> float:
        """Nominal scaled delay tau_n0 = 2*pi/(n*omega0), eq. (14) with phi = 0."""
        return 2.0 * math.pi / (self.n * self.omega0)

    @property
    def d0(self) -> float:
        """Nominal scaled depth of cut d0 = v0*tau_n0, eq. (8) scaled by L*."""
        return self.v0 * self.tau_n0

    @property
    def sqrt_npsi(self) -> float:
        """sqrt(n*psi): the fast-time factor of Section III (taubar = tau*sqrt(n*psi))."""
        return math.sqrt(self.n * self.psi)

    @property
    def gammabar(self) -> float:
        """gammabar = gamma/sqrt(n*psi), eq. (18)."""
        return self.gamma / self.sqrt_npsi

    @property
    def etabar(self) -> float:
        """etabar = eta/sqrt(n*psi), eq. (18)."""
        return self.eta / self.sqrt_npsi

    @property
    def etabar2(self) -> float:
        """etabar^2 = eta^2/(n*psi), the vertical axis of Fig. 2."""
        return self.eta**2 / (self.n * self.psi)

    @property
    def vbar0(self) -> float:
        """vbar0 = v0/sqrt(n*psi), eq. (18)."""
        return self.v0 / self.sqrt_npsi

    @property
    def taubar_n0(self) -> float:
        """Nominal delay in fast time, taubar_n0 = tau_n0*sqrt(n*psi) (Section III, Fig. 2)."""
        return self.tau_n0 * self.sqrt_npsi

    @property
    def h_max(self) -> float:
        """The largest sensible integration step: a tenth of the model's shortest time scale,
        the axial period 2*pi/sqrt(n*psi), the nominal delay tau_n0 or the torsional period
        2*pi (scaled time makes the torsional natural frequency 1); about 0.02 for the
        reference set, whose runs use 5e-4."""
        return min(2.0 * math.pi / self.sqrt_npsi, self.tau_n0, 2.0 * math.pi) / 10.0

    @property
    def R0(self) -> float:
        """Nominal scaled rotary-table torque R0/C = n*d0 + n*beta*lambda, eq. (8) with (16)."""
        return self.n * self.d0 + self.n * self.beta * self.lam

    # -- copies and dicts ---------------------------------------------------------------------
    def replace(self, **changes: Any) -> ScaledParams:
        """Validated copy with ``changes`` applied (key ``"lambda"`` is accepted for ``lam``).

        Parameters
        ----------
        **changes
            New values by field name.

        Returns
        -------
        ScaledParams
            The copy, validated like a new instance.

        Raises
        ------
        ParameterError
            An unknown field, a field given twice (``lam`` and ``lambda``) or an invalid value.
        """
        mapped = _dict_to_fields(ScaledParams, changes, _SCALED_IN_ALIASES, complete=False)
        return dataclasses.replace(self, **mapped)

    def to_dict(self) -> dict[str, Any]:
        """Fields as a dict in declaration order, with the file key ``"lambda"`` for ``lam``.

        Returns
        -------
        dict of str to object
            ``n`` (int), then ``psi, gamma, eta, lambda, beta, rho, v0, omega0`` (float): a
            parameter file's table without its ``kind`` key (:meth:`from_dict` reads it back).
        """
        return {_SCALED_OUT_KEYS.get(k, k): v for k, v in dataclasses.asdict(self).items()}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        """Build from a dict of all nine fields (``"lambda"`` or ``"lam"``); no extra keys.

        Parameters
        ----------
        data : mapping
            Field values by name, as in a parameter file without its ``kind`` key.

        Returns
        -------
        ScaledParams
            The validated set.

        Raises
        ------
        ParameterError
            ``data`` is not a mapping, has an unknown, duplicate or missing key, or a bad value.
        """
        return cls(**_dict_to_fields(cls, data, _SCALED_IN_ALIASES))


# --------------------------------------------------------------------------------------------
# physical parameters
# --------------------------------------------------------------------------------------------

_PHYSICAL_RULES: dict[str, tuple[float, bool]] = {
    "M": (0.0, True),  # BHA mass [kg]
    "I1": (0.0, True),  # BHA inertia [kg m^2]
    "I2": (0.0, True),  # rotary-table inertia [kg m^2]
    "C": (0.0, True),  # torsional stiffness [N m/rad]
    "K": (0.0, True),  # axial stiffness [N/m]
    "D": (0.0, False),  # axial damping [N s/m]
    "a": (0.0, True),  # bit radius [m]
    "eps": (0.0, True),  # intrinsic specific energy [Pa]
    "zeta": (0.0, True),  # cutting-face orientation [-]
    "sigma_bar": (0.0, False),  # contact stress [Pa]
    "l": (0.0, False),  # wearflat length [m]
    "mu": (0.0, True),  # friction coefficient [-]
    "xi": (0.0, True),  # wearflat distribution [-]
    "V0": (0.0, True),  # nominal axial (hook) velocity [m/s]
    "Omega0": (0.0, True),  # nominal angular velocity [rad/s]
}


def weight_on_bit(
    n: Any,
    a: Any,
    zeta: Any,
    eps: Any,
    l: Any,  # noqa: E741
    sigma_bar: Any,
    d: Any,
    g: Any,  # noqa: E741
) -> Any:
    """Weight on bit W^c + W^f [N], eq. (4) plus eq. (7), of the rig's n, a, zeta, eps, l,
    sigma_bar at depth of cut ``d`` [m] and contact multiplier ``g`` (plain arithmetic: floats,
    numpy arrays, and compiled by :mod:`drillstring.model.native`).

    Parameters
    ----------
    n, a, zeta, eps, l, sigma_bar : float
        The rig's fields of :class:`PhysicalParams` (SI units).
    d : float or ndarray
        Depth of cut [m], eq. (5).
    g : float or ndarray
        Contact multiplier of (17): 0 full wearflat contact (dU/dt > 0), 1 none (dU/dt < 0),
        in between in axial stick; W^f = n*a*l*sigma_bar*(1 - g).

    Returns
    -------
    float or ndarray
        n*a*(zeta*eps*d + l*sigma_bar*(1 - g)) [N], broadcast over the arguments (no input
        check).
    """
    return n * a * (zeta * eps * d + l * sigma_bar * (1.0 - g))


@dataclass(frozen=True)
class PhysicalParams:
    """Dimensional parameters of eqs. (1)-(8) (SI units), mapped to the scaled set by (15)-(16)."""

    M: float
    I1: float
    I2: float
    C: float
    K: float
    D: float
    n: int
    a: float
    eps: float
    zeta: float
    sigma_bar: float
    l: float  # noqa: E741 -- the paper's wearflat length
    mu: float
    xi: float
    V0: float
    Omega0: float

    def __post_init__(self) -> None:
        _check_fields(self, ("n",), _PHYSICAL_RULES)

    @property
    def t_star(self) -> float:
        """Characteristic time t* = sqrt(I1/C) [s] (Section II)."""
        return math.sqrt(self.I1 / self.C)

    @property
    def L_star(self) -> float:
        """Characteristic length L* = 2C/(eps*a^2) [m] (Section II)."""
        return 2.0 * self.C / (self.eps * self.a**2)

    @property
    def d0(self) -> float:
        """Nominal depth of cut d0 = (2*pi/n)*V0/Omega0 [m], eq. (8)."""
        return 2.0 * math.pi / self.n * self.V0 / self.Omega0

    def weight_on_bit(self, d: Any, g: Any = 0.0) -> Any:
        """Weight on bit W^c + W^f [N] at depth of cut ``d`` [m] and contact multiplier ``g``:
        :func:`weight_on_bit` of this rig (eq. (4) plus eq. (7))."""
        return weight_on_bit(self.n, self.a, self.zeta, self.eps, self.l, self.sigma_bar, d, g)

    def torque_on_bit(self, d: Any, g: Any = 0.0) -> Any:
        """Torque on bit T^c + T^f [N m] at depth of cut ``d`` [m]: eq. (4) plus eq. (7).

        T^c = n*a^2*eps*d/2 and T^f = a*xi*mu*W^f/2 with W^f as in :meth:`weight_on_bit`: the
        torque while the bit slips torsionally (in torsional stick the torque is what holds the
        bit, ``docs/model.md``, "Torsional stick").

        ``d`` and ``g`` as for :func:`weight_on_bit`; broadcast, no input check (plain
        arithmetic).
        """
        cutting = 0.5 * self.n * self.a**2 * self.eps * d
        contact = 0.5 * self.a * self.xi * self.mu * self.contact_weight
        return cutting + contact * (1.0 - g)

    @property
    def W0(self) -> float:
        """Nominal weight on bit W^c + W^f [N]: eq. (4) at d = d0 plus eq. (7) with dU/dt > 0."""
        return self.weight_on_bit(self.d0)

    @property
    def contact_weight(self) -> float:
        """The wearflat contact part W^f = n*a*l*sigma_bar [N] of the nominal weight on bit,
        eq. (7) with dU/dt > 0: the least nominal WOB of any positive feed."""
        return self.n * self.a * self.l * self.sigma_bar

    def hook_speed_for_weight(self, W0: float) -> float:
        """The hook speed V0 [m/s] whose nominal weight on bit is ``W0`` at this set's Omega0.

        The inverse of :attr:`W0`: with d0 = 2*pi*V0/(n*Omega0) of (8), eqs. (4) and (7) give
        ``W0 = n*a*zeta*eps*d0 + n*a*l*sigma_bar``, so
        ``V0 = (W0 - n*a*l*sigma_bar)*Omega0/(2*pi*a*zeta*eps)``. The feed stays an imposed rate
        of penetration (the paper's hook speed); ``W0`` only chooses it.

        Parameters
        ----------
        W0 : float
            Nominal weight on bit [N], above :attr:`contact_weight`.

        Returns
        -------
        float
            V0 [m/s], > 0.

        Raises
        ------
        ParameterError
            ``W0`` is not a finite number above the contact part (no positive feed reaches it);
            the message names the value.
        """
        W0 = check_real("W0", W0, error=ParameterError)
        contact = self.contact_weight
        if not W0 > contact:
            raise ParameterError(
                f"W0 = {W0!r} N is not above the wearflat contact part n*a*l*sigma_bar = "
                f"{contact!r} N of eq. (7): no positive feed gives that nominal weight on bit"
            )
        return (W0 - contact) * self.Omega0 / (2.0 * math.pi * self.a * self.zeta * self.eps)

    @property
    def T0(self) -> float:
        """Nominal torque on bit T^c + T^f [N m]: eq. (4) at d = d0 plus eq. (7) with dU/dt > 0."""
        return self.torque_on_bit(self.d0)

    @property
    def R0(self) -> float:
        """Nominal rotary-table torque [N m], eq. (8): it balances the torque on bit :attr:`T0`
        (eqs. (2)-(3) in the nominal motion)."""
        return self.T0

    @property
    def surface_speed_rpm(self) -> float:
        """Nominal rotary speed Omega0 of table and bit in revolutions per minute."""
        return self.Omega0 * 60.0 / (2.0 * math.pi)

    @property
    def rop_m_per_h(self) -> float:
        """Nominal rate of penetration V0 in metres per hour."""
        return self.V0 * 3600.0

    @property
    def depth_of_cut_per_rev_mm(self) -> float:
        """Nominal depth of cut per revolution n*d0 = 2*pi*V0/Omega0, eq. (8), in millimetres."""
        return self.n * self.d0 * 1e3

    def to_scaled(self) -> ScaledParams:
        """Scaled parameters by eqs. (15)-(16), v0 = V0*t*/L*, omega0 = Omega0*t* (Section II).

        Returns
        -------
        ScaledParams
            psi, gamma, eta of (15); lambda, beta, rho of (16); v0 and omega0 as above; the same n.

        Raises
        ------
        ParameterError
            The computed values are not a valid scaled set (e.g. beta = zeta*mu*xi > 1); the
            message says they were computed by (15)-(16).
        """
        t_star, L_star = self.t_star, self.L_star
        values = {
            "n": self.n,
            "psi": self.zeta * self.eps * self.a * self.I1 / (self.M * self.C),
            "gamma": self.D / self.M * t_star,
            "eta": math.sqrt(self.K * self.I1 / (self.M * self.C)),
            "lam": self.a**2 * self.l * self.sigma_bar / (2.0 * self.zeta * self.C),
            "beta": self.zeta * self.mu * self.xi,
            "rho": self.I2 / self.I1,
            "v0": self.V0 * t_star / L_star,
            "omega0": self.Omega0 * t_star,
        }
        try:
            return ScaledParams(**values)
        except ParameterError as exc:
            raise ParameterError(f"{exc} (computed from PhysicalParams by eqs. (15)-(16))") from exc

    @classmethod
    def from_scaled(
        cls,
        scaled: ScaledParams,
        *,
        C: float,
        I1: float,
        a: float,
        eps: float,
        zeta: float,
        xi: float,
        sigma_bar: float,
    ) -> PhysicalParams:
        """The physical set that :meth:`to_scaled` maps onto ``scaled``, given seven choices.

        Eqs. (15)-(16) give nine scaled values from sixteen physical ones (``n`` is shared), so
        seven are free. With the torsional stiffness ``C`` and the bit-end inertia ``I1`` (hence
        t* = sqrt(I1/C)) and the bit-rock values ``a, eps, zeta, xi, sigma_bar`` chosen, (15)-(16)
        solve uniquely for the rest::

            M = zeta*eps*a*t*^2/psi    D = gamma*M/t*    K = eta^2*M/t*^2    I2 = rho*I1
            l = 2*zeta*C*lambda/(a^2*sigma_bar)          mu = beta/(zeta*xi)
            Omega0 = omega0/t*         V0 = v0*L*/t*,  L* = 2*C/(eps*a^2)

        Derivation and the reference rig: ``docs/reference_rig.md``.

        Parameters
        ----------
        scaled : ScaledParams
            The scaled set to reproduce.
        C : float
            Torsional stiffness [N m/rad].
        I1 : float
            Bit-end (BHA) inertia [kg m^2].
        a : float
            Bit radius [m].
        eps : float
            Intrinsic specific energy [Pa].
        zeta : float
            Cutting-face orientation [-].
        xi : float
            Wearflat distribution [-].
        sigma_bar : float
            Contact stress [Pa].

        Returns
        -------
        PhysicalParams
            The set whose :meth:`to_scaled` equals ``scaled`` to rounding.

        Raises
        ------
        ParameterError
            ``scaled`` is not a :class:`ScaledParams`, a choice is not a finite number > 0
            (named), or the result is not a valid :class:`PhysicalParams`.
        """
        if not isinstance(scaled, ScaledParams):
            raise ParameterError(
                f"PhysicalParams.from_scaled: expected ScaledParams, got {type(scaled).__name__}"
            )
        chosen = {
            name: check_real(
                f"PhysicalParams.from_scaled: {name}", value, lower=0.0, error=ParameterError
            )
            for name, value in (
                ("C", C),
                ("I1", I1),
                ("a", a),
                ("eps", eps),
                ("zeta", zeta),
                ("xi", xi),
                ("sigma_bar", sigma_bar),
            )
        }
        C, I1, a, eps = chosen["C"], chosen["I1"], chosen["a"], chosen["eps"]
        zeta, xi, sigma_bar = chosen["zeta"], chosen["xi"], chosen["sigma_bar"]
        s = scaled
        t_star = math.sqrt(I1 / C)
        L_star = 2.0 * C / (eps * a**2)
        M = zeta * eps * a * I1 / (s.psi * C)
        return cls(
            M=M,
            I1=I1,
            I2=s.rho * I1,
            C=C,
            K=s.eta**2 * M * C / I1,
            D=s.gamma * M / t_star,
            n=s.n,
            a=a,
            eps=eps,
            zeta=zeta,
            sigma_bar=sigma_bar,
            l=2.0 * zeta * C * s.lam / (a**2 * sigma_bar),
            mu=s.beta / (zeta * xi),
            xi=xi,
            V0=s.v0 * L_star / t_star,
            Omega0=s.omega0 / t_star,
        )

    def replace(self, **changes: Any) -> PhysicalParams:
        """Return a validated copy with ``changes`` applied.

        Parameters
        ----------
        **changes
            New values by field name.

        Returns
        -------
        PhysicalParams
            The copy, validated like a new instance.

        Raises
        ------
        ParameterError
            An unknown field or an invalid value.
        """
        return dataclasses.replace(
            self, **_dict_to_fields(PhysicalParams, changes, {}, complete=False)
        )

    def to_dict(self) -> dict[str, Any]:
        """Fields as a dict in declaration order.

        Returns
        -------
        dict of str to object
            The sixteen fields ``M, I1, I2, C, K, D, n, a, eps, zeta, sigma_bar, l, mu, xi, V0,
            Omega0`` (SI units; ``n`` an int, the others float): a parameter file's table without
            its ``kind`` key (:meth:`from_dict` reads it back).
        """
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        """Build from a dict of all sixteen fields; no extra keys.

        Parameters
        ----------
        data : mapping
            Field values by name (SI units), as in a parameter file without its ``kind`` key.

        Returns
        -------
        PhysicalParams
            The validated set.

        Raises
        ------
        ParameterError
            ``data`` is not a mapping, has an unknown or missing key, or a bad value.
        """
        return cls(**_dict_to_fields(cls, data, {}))


# --------------------------------------------------------------------------------------------
# named sets
# --------------------------------------------------------------------------------------------

#: Our reconstruction of Table I (``docs/model.md``, "Reference parameter set"): gammabar = 0.2,
#: etabar^2 = 0.1, tau_n0 = pi/10, taubar_n0 = 9.93. Also stored in
#: ``drillstring/model/data/reference.toml``.
REFERENCE = ScaledParams(
    n=4,
    psi=250.0,
    gamma=2.0 * math.sqrt(10.0),
    eta=10.0,
    lam=1.58,
    beta=0.5,
    rho=5.0,
    v0=1.0,
    omega0=5.0,
)

#: The seven free physical choices of the reference rig (``docs/reference_rig.md``): a 4 km
#: string of 5-in drill pipe (C) over a 59 m collar section (I1 with a third of the pipe's polar
#: inertia), an 8 1/2-in four-bladed PDC bit (a) in a 60 MPa rock (eps, sigma_bar), cutting-face
#: constant zeta = 0.6 and a uniform wearflat contact over the bit face (xi = 4/3).
REFERENCE_RIG_CHOICES: dict[str, float] = {
    "C": 235.0,
    "I1": 200.0,
    "a": 0.10795,
    "eps": 60e6,
    "zeta": 0.6,
    "xi": 4.0 / 3.0,
    "sigma_bar": 60e6,
}

#: A physical (SI) rig that maps onto :data:`REFERENCE` by eqs. (15)-(16) (to rounding, about
#: 1e-16 relative): t* = 0.92 s, L* = 0.67 mm. Also stored in
#: ``drillstring/model/data/reference_rig.toml``.
REFERENCE_RIG = PhysicalParams.from_scaled(REFERENCE, **REFERENCE_RIG_CHOICES)

#: The reference rig's drill pipe and its steel (``docs/reference_rig.md``): 5-in 19.5 lb/ft
#: pipe, OD 127.0 mm and ID 108.6 mm [m], density 7850 kg/m^3, shear modulus G = 79.3 GPa and
#: Young's modulus E = 206.8 GPa [Pa]. Its length is the one whose GJ/L is the rig's C.
REFERENCE_RIG_PIPE: dict[str, float] = {
    "od": 0.1270,
    "id": 0.1086,
    "density": 7850.0,
    "G": 79.3e9,
    "E": 206.8e9,
}


def _pipe_length_and_mass(pipe: Mapping[str, float], C: float) -> tuple[float, float, float]:
    """The length L = G*J/C [m] of ``pipe`` whose torsional stiffness is C, its mass [kg] and its
    axial stiffness E*A/L [N/m] (J = pi*(od^4 - id^4)/32, A = pi*(od^2 - id^2)/4)."""
    od, id_ = pipe["od"], pipe["id"]
    J = math.pi * (od**4 - id_**4) / 32.0
    area = math.pi * (od**2 - id_**2) / 4.0
    length = pipe["G"] * J / C
    return length, pipe["density"] * area * length, pipe["E"] * area / length


#: The reference rig's pipe: its length [m] (G*J/C = 4008.9 m), its mass [kg] (107 146 kg) and
#: its axial stiffness E*A/L [N/m] (1.756e5 N/m), from :data:`REFERENCE_RIG_PIPE` and C.
REFERENCE_PIPE_LENGTH, REFERENCE_PIPE_MASS, REFERENCE_PIPE_EA_L = _pipe_length_and_mass(
    REFERENCE_RIG_PIPE, REFERENCE_RIG_CHOICES["C"]
)

#: The pipe rig (``docs/reference_rig.md``, "The pipe rig"): the reference rig with M and K
#: consistent with its pipe. M is the bottom-hole assembly (the reference rig's M, the collars
#: alone) plus the one-mode share of the pipe, a third of its mass (48 946 kg); K is the pipe's
#: E*A/L (1.756e5 N/m). Everything else, the axial damping D included, is the reference rig's.
#: It does NOT map onto :data:`REFERENCE` (psi = 67.6, eta = 1.75); the reference set stays the
#: default everywhere. Also stored in ``drillstring/model/data/pipe_rig.toml``.
PIPE_RIG = REFERENCE_RIG.replace(
    M=REFERENCE_RIG.M + REFERENCE_PIPE_MASS / 3.0, K=REFERENCE_PIPE_EA_L
)

#: Physical named sets, as :class:`PhysicalParams` (see :func:`get_physical`).
KNOWN_PHYSICAL: dict[str, PhysicalParams] = {"reference-rig": REFERENCE_RIG, "pipe-rig": PIPE_RIG}

#: Every named set as :class:`ScaledParams`; a physical set appears converted by (15)-(16).
KNOWN_PARAMS: dict[str, ScaledParams] = {
    "reference": REFERENCE,
    **{name: phys.to_scaled() for name, phys in KNOWN_PHYSICAL.items()},
}


def get_params(name: str) -> ScaledParams:
    """Return a named parameter set as :class:`ScaledParams`.

    ``"reference"`` is the scaled reference set; ``"reference-rig"`` is the physical reference
    rig converted by (15)-(16) (equal to ``"reference"`` to rounding); ``"pipe-rig"`` the rig
    whose M and K are its pipe's, converted likewise (psi = 67.6, eta = 1.75). :func:`get_physical`
    returns a physical set in SI units.

    Parameters
    ----------
    name : str
        A key of :data:`KNOWN_PARAMS`.

    Returns
    -------
    ScaledParams
        The named set.

    Raises
    ------
    ParameterError
        ``name`` is not a known set (the message lists them).
    """
    try:
        return KNOWN_PARAMS[name]
    except (KeyError, TypeError):
        known = ", ".join(sorted(KNOWN_PARAMS))
        raise ParameterError(
            f"unknown parameter set {name!r} (known: {known}; use load_params(path) for a file)"
        ) from None


def get_physical(name: str) -> PhysicalParams:
    """Return a physical named set (SI units), e.g. ``"reference-rig"``.

    Parameters
    ----------
    name : str
        A key of :data:`KNOWN_PHYSICAL`.

    Returns
    -------
    PhysicalParams
        The named set.

    Raises
    ------
    ParameterError
        ``name`` is not a physical set (the message says if it is a scaled one).
    """
    try:
        return KNOWN_PHYSICAL[name]
    except (KeyError, TypeError):
        known = ", ".join(sorted(KNOWN_PHYSICAL))
        scaled = isinstance(name, str) and name in KNOWN_PARAMS
        hint = " is a scaled set (use get_params)" if scaled else " is unknown"
        raise ParameterError(
            f"parameter set {name!r}{hint}; physical sets: {known} "
            "(use read_params(path) for a file)"
        ) from None


def known_rig(params: ScaledParams) -> PhysicalParams | None:
    """The known physical set (:data:`KNOWN_PHYSICAL`) whose scaled set is ``params``, every
    field to a relative 1e-9 (the conversion (15)-(16) rounds).

    Parameters
    ----------
    params : ScaledParams
        A scaled set.

    Returns
    -------
    PhysicalParams or None
        The first match, or None.
    """
    for rig in KNOWN_PHYSICAL.values():
        s = rig.to_scaled()
        if all(
            math.isclose(getattr(s, f.name), getattr(params, f.name), rel_tol=1e-9)
            for f in dataclasses.fields(ScaledParams)
        ):
            return rig
    return None


def params_from_spec(spec: str | os.PathLike[str]) -> ScaledParams:
    """A known set name (see :func:`get_params`) or else the path of a parameter file, as
    :class:`ScaledParams` (physical sets and files are converted by (15)-(16)).

    Parameters
    ----------
    spec : str or path-like
        A key of :data:`KNOWN_PARAMS`, or a path that has a ``.toml``/``.json`` suffix or exists.

    Returns
    -------
    ScaledParams
        The named or loaded set.

    Raises
    ------
    ParameterError
        ``spec`` is neither a known set nor a readable, valid parameter file.
    """
    path = _spec_file(spec)
    return get_params(str(spec)) if path is None else load_params(path)


def rig_from_spec(spec: str | os.PathLike[str]) -> PhysicalParams | None:
    """The physical rig of a parameter set named as :func:`params_from_spec` takes it.

    Parameters
    ----------
    spec : str or path-like
        A key of :data:`KNOWN_PARAMS`, or a parameter file.

    Returns
    -------
    PhysicalParams or None
        A physical set (a key of :data:`KNOWN_PHYSICAL`, a physical file) as it is; for a scaled
        one the known rig whose scaled set it is (:func:`known_rig`), else None.

    Raises
    ------
    ParameterError
        As :func:`params_from_spec`.
    """
    if isinstance(spec, str) and spec in KNOWN_PHYSICAL:
        return KNOWN_PHYSICAL[spec]
    path = _spec_file(spec)
    read = get_params(str(spec)) if path is None else read_params(path)
    return read if isinstance(read, PhysicalParams) else known_rig(read)


def _spec_file(spec: str | os.PathLike[str]) -> Path | None:
    """The parameter file ``spec`` names (a ``.toml``/``.json`` suffix, or a path that exists),
    or None for the name of a set (a key of :data:`KNOWN_PARAMS` is never a file)."""
    if isinstance(spec, str) and spec in KNOWN_PARAMS:
        return None
    path = Path(spec)
    return path if path.suffix.lower() in _SUFFIXES or path.exists() else None


# --------------------------------------------------------------------------------------------
# files
# --------------------------------------------------------------------------------------------

_KINDS: dict[str, type[ScaledParams] | type[PhysicalParams]] = {
    "scaled": ScaledParams,
    "physical": PhysicalParams,
}
_SUFFIXES = (".toml", ".json")


def _suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise ParameterError(
            f"parameter file {str(path)!r}: suffix must be .toml or .json, got {suffix!r}"
        )
    return suffix


def read_params(path: str | os.PathLike[str]) -> ScaledParams | PhysicalParams:
    """Read a parameter file (format in the module docstring) and return the kind it holds.

    Parameters
    ----------
    path : path-like
        A ``.toml`` or ``.json`` parameter file.

    Returns
    -------
    ScaledParams or PhysicalParams
        As the file's ``kind`` says.

    Raises
    ------
    ParameterError
        Bad suffix, unreadable or unparsable file, missing or unknown ``kind``, or bad contents;
        the message names the file.
    """
    path = Path(path)
    suffix = _suffix(path)
    try:
        data = load_table(path)
    except OSError as exc:
        raise ParameterError(f"cannot read parameter file {str(path)!r}: {exc}") from exc
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        msg = f"parameter file {str(path)!r} is not valid {suffix[1:]}: {exc}"
        raise ParameterError(msg) from exc
    if not isinstance(data, dict):
        raise ParameterError(f"parameter file {str(path)!r}: top level must be a table/object")
    data = dict(data)
    kind = data.pop("kind", None)
    if kind is None:
        raise ParameterError(
            f"parameter file {str(path)!r}: missing key 'kind' (one of {', '.join(_KINDS)})"
        )
    if kind not in _KINDS:
        raise ParameterError(
            f"parameter file {str(path)!r}: kind must be one of {', '.join(_KINDS)}, got {kind!r}"
        )
    try:
        return _KINDS[kind].from_dict(data)
    except ParameterError as exc:
        raise ParameterError(f"parameter file {str(path)!r}: {exc}") from exc


def load_params(path: str | os.PathLike[str]) -> ScaledParams:
    """Load a parameter file as :class:`ScaledParams` (physical files converted by (15)-(16)).

    Parameters
    ----------
    path : path-like
        A ``.toml`` or ``.json`` parameter file of either kind.

    Returns
    -------
    ScaledParams
        The set, converted by :meth:`PhysicalParams.to_scaled` if the file is physical.

    Raises
    ------
    ParameterError
        As :func:`read_params`, or a physical set that maps to invalid scaled values.
    """
    p = read_params(path)
    return p.to_scaled() if isinstance(p, PhysicalParams) else p


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):  # never produced by validated params; guard the int branch
        raise TypeError(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)  # shortest round-trip repr; always has '.' or 'e'; finite by validation
    if isinstance(value, str):
        return json.dumps(value)  # a JSON string literal is a valid TOML basic string
    raise TypeError(f"cannot write {value!r} to TOML")


def save_params(p: ScaledParams | PhysicalParams, path: str | os.PathLike[str]) -> Path:
    """Write ``p`` to ``path`` (.toml or .json by suffix) atomically.

    Parameters
    ----------
    p : ScaledParams or PhysicalParams
        The set; its ``kind`` is written with it.
    path : path-like
        Target file; the suffix chooses the format.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ParameterError
        A suffix other than ``.toml``/``.json``, or ``p`` of another type.
    """
    path = Path(path)
    suffix = _suffix(path)
    kind = next((k for k, c in _KINDS.items() if isinstance(p, c)), None)
    if kind is None:
        raise ParameterError(f"save_params: expected ScaledParams or PhysicalParams, got {p!r}")
    data = {"kind": kind, **p.to_dict()}
    if suffix == ".toml":
        lines = [f"# drillstring parameter file ({kind})"]
        lines += [f"{key} = {_toml_value(value)}" for key, value in data.items()]
        text = "\n".join(lines) + "\n"
    else:
        text = json.dumps(data, indent=2) + "\n"
    return write_text(path, text)
