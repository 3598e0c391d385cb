"""The top drive: what a rig's drive can do with a torque command (its rating), shared by every
law (``docs/controllers.md``, "The top drive").

:class:`TopDrive` is the rating in the paper's scaled units (absolute table torque R/C, table
speed dTheta/dtau, time tau); :func:`top_drive` converts a named SI rating (:class:`Rating`,
e.g. :data:`TDS_11SA`) on a rig. Below them, the model compiled (:func:`envelope`,
:func:`actuate`, :func:`drive_commit`, in the subset numba compiles) on the top drive's section
of the controller's block (:data:`TOP_DRIVE_SLOTS`): the torque range, the power limit |R Omega|
<= P_max, the speed range, braking (four-quadrant or none), and a first-order drive lag or a
torque rate limit.

At a sample instant tau with the table speed Omega = omega0 + dtheta/dtau (absolute, scaled):

1. the envelope [lo, hi] of absolute torques R/C the drive can deliver at Omega
   (:func:`envelope`);
2. the limited command: the command R0 + r clipped into the envelope, then into the rate limit
   ``|R - R_prev| <= rate*dt`` from the torque of the previous sample, dt the period since it;
3. the applied torque: with a lag of time constant T, ``R = R_prev + (1 - exp(-dt/T))*(R_lim -
   R_prev)`` (the lag driven by the limited command over the last interval), clipped into the
   envelope again.

dt is the sample period the previous sample was committed with (the step a master took from
it), not a difference of times: a host's clock and a communication point that differ by
rounding give the same torque.

The applied torque is held over the sample like any digital controller's output. Without a top
drive model (``on`` 0) the command is applied as it is; when nothing limits it the command is
returned exactly (not R0 + r - R0, which can differ from r by rounding).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from drillstring.model.kernel.jit import jit_for
from drillstring.model.tables import (
    Parameter,
    Scales,
    block_layout,
    parameter_slots,
    table_from_si,
    table_to_si,
)
from drillstring.validation import check_choice, check_real

__all__ = ["BRAKING", "RATINGS", "RPM", "TOP_DRIVE_SLOTS", "Rating", "TDS_11SA", "TopDrive",
           "actuate", "drive_commit", "envelope", "top_drive", "top_drive_from_spec"]  # fmt: skip

#: Braking: "four-quadrant" (torque of either sign at any speed: a drive with braking
#: resistors or a regenerative supply) or "none" (no torque against the rotation).
BRAKING = ("four-quadrant", "none")
#: One revolution per minute in rad/s.
RPM = 2.0 * math.pi / 60.0


@dataclass(frozen=True)
class TopDrive:
    """A top drive's limits in scaled units; every limit can be off (infinite, or lag 0).

    Parameters
    ----------
    R_min, R_max : float
        Range of the absolute table torque R/C (units of C; the nominal torque is R0 of (8)).
    rate : float
        Torque rate limit |dR/dtau| (units of C per unit of tau); inf: none.
    lag : float
        Time constant of the drive's first-order torque lag (scaled time); 0: none.
    P_max : float
        Power limit |R*Omega| (units of C per unit of tau; Omega = dTheta/dtau); inf: none.
    omega_min, omega_max : float
        Range of the table speed dTheta/dtau (absolute): no torque drives it further out.
    braking : str
        One of :data:`BRAKING`.
    """

    R_min: float = -math.inf
    R_max: float = math.inf
    rate: float = math.inf
    lag: float = 0.0
    P_max: float = math.inf
    omega_min: float = -math.inf
    omega_max: float = math.inf
    braking: str = "four-quadrant"

    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("R_min", "torque", "Lower limit of the absolute table torque R"),
        Parameter("R_max", "torque", "Upper limit of the absolute table torque R"),
        Parameter("rate", "torque rate", "Torque rate limit |dR/dt|", 0.0, strict=True),
        Parameter("lag", "time", "Time constant of the drive's first-order torque lag", 0.0),
        Parameter("P_max", "power", "Power limit |R Omega|", 0.0, strict=True),
        Parameter("omega_min", "speed", "Lower end of the table speed range"),
        Parameter("omega_max", "speed", "Upper end of the table speed range"),
        Parameter(
            "braking",
            "1",
            "four-quadrant (torque against the rotation allowed) or none",
            choices=BRAKING,
        ),
    )

    def __post_init__(self) -> None:
        for name in ("R_min", "R_max", "omega_min", "omega_max"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
                raise ValueError(f"TopDrive.{name} must be a real number or +-inf, got {value!r}")
            object.__setattr__(self, name, float(value))
        for name in ("rate", "P_max"):
            value = getattr(self, name)
            if value != math.inf:
                check_real(f"TopDrive.{name}", value, lower=0.0)
            object.__setattr__(self, name, float(value))
        object.__setattr__(
            self, "lag", check_real("TopDrive.lag", self.lag, lower=0.0, strict=False)
        )
        check_choice("TopDrive.braking", self.braking, BRAKING)
        if not self.R_min <= self.R_max:
            raise ValueError(f"TopDrive: R_min = {self.R_min!r} is above R_max = {self.R_max!r}")
        if not self.omega_min < self.omega_max:
            raise ValueError(
                f"TopDrive: omega_min = {self.omega_min!r} is not below omega_max = "
                f"{self.omega_max!r}"
            )

    def values(self) -> dict[str, Any]:
        """The limits by name (scaled)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def to_si(self, scales: Scales) -> dict[str, Any]:
        """The limits in SI units (N m, N m/s, s, W, rad/s), each scaled by its dimension.

        Parameters
        ----------
        scales : PhysicalParams or any object with ``C`` and ``t_star``
            The rig's scales.

        Returns
        -------
        dict
            Name -> SI value (infinite limits stay infinite).
        """
        return table_to_si(self.PARAMETERS, self.values(), scales)

    @classmethod
    def from_si(cls, scales: Scales, values: Mapping[str, Any]) -> TopDrive:
        """The top drive of SI limits, the inverse of :meth:`to_si` (missing ones: off).

        Parameters
        ----------
        scales : PhysicalParams or any object with ``C`` and ``t_star``
            The rig's scales.
        values : mapping
            Name -> SI value.

        Returns
        -------
        TopDrive

        Raises
        ------
        ValueError
            An unknown name or a value :class:`TopDrive` rejects.
        """
        return cls(**table_from_si("TopDrive.from_si", cls.PARAMETERS, values, scales))

    def pack(self, b: np.ndarray, at: int) -> None:
        """Write the limits into the controller's block ``b``, whose top-drive section
        (:data:`TOP_DRIVE_SLOTS`) is at ``at``, and switch the model on."""
        b[at + TOP_DRIVE_SLOTS.on] = 1.0
        for p in self.PARAMETERS:
            if not p.choices:
                b[at + getattr(TOP_DRIVE_SLOTS, p.name)] = getattr(self, p.name)
        # 1: four-quadrant, 0: no torque against the rotation
        b[at + TOP_DRIVE_SLOTS.braking] = 1.0 if self.braking == "four-quadrant" else 0.0


#: The top drive's section of the controller's block: its switch (0: no top-drive model, the
#: command applied as it is), one slot per :attr:`TopDrive.PARAMETERS` entry, then its state:
#: the applied absolute torque ``R`` at the last committed sample, the time ``t`` of that
#: sample, ``init`` (1 once a sample has been committed) and its sample period ``dt``.
TOP_DRIVE_SLOTS = block_layout(
    "TopDriveSlots",
    (("on", 1), *parameter_slots(TopDrive.PARAMETERS), ("R", 1), ("t", 1), ("init", 1), ("dt", 1)),
    state=("R", "t", "init", "dt"),
)


@dataclass(frozen=True)
class Rating:
    """A top drive's rating in SI units, as its maker states it.

    Attributes
    ----------
    name : str
        The drive, as it is sold.
    torque : float
        Continuous drilling torque [N m]: the torque range is [-torque, torque] with braking,
        [0, torque] without.
    power : float
        Rated power [W].
    max_speed : float
        Maximum rotary speed [rad/s]; the range is [0, max_speed] (no reverse drilling).
    lag : float
        Time constant of the drive's torque response [s].
    braking : str
        One of :data:`BRAKING`.
    source : str
        Where the numbers come from.
    """

    name: str
    torque: float
    power: float
    max_speed: float
    lag: float
    braking: str
    source: str


#: NOV (Varco) TDS-11SA, the common AC land top drive: 800 hp, continuous drilling torque
#: 37,500 ft lbf (50.8 kN m), 228 rpm; a VFD drive with dynamic braking; a 10 ms torque response
#: (our choice within the 5-20 ms of AC drives). ``docs/controllers.md``, "The top drive".
TDS_11SA = Rating(
    name="NOV TDS-11SA",
    torque=37_500 * 1.3558179483314004,
    power=800 * 745.6998715822702,
    max_speed=228 * RPM,
    lag=0.010,
    braking="four-quadrant",
    source="NOV (Varco) TDS-11SA published rating (800 hp, 37,500 ft lbf, 228 rpm); lag ours",
)


def top_drive(rating: Rating, scales: Scales) -> TopDrive:
    """The scaled limits of a named rating on a rig.

    Parameters
    ----------
    rating : Rating
        E.g. :data:`TDS_11SA`.
    scales : PhysicalParams or any object with ``C`` and ``t_star``
        The rig's scales (eqs. (15)-(16)).

    Returns
    -------
    TopDrive
        Torque range [-torque, torque] (braking) or [0, torque], power, speed range [0,
        max_speed], the lag; scaled by the rig's C and t*.
    """
    low = -rating.torque if rating.braking == "four-quadrant" else 0.0
    return TopDrive.from_si(
        scales,
        {
            "R_min": low,
            "R_max": rating.torque,
            "lag": rating.lag,
            "P_max": rating.power,
            "omega_min": 0.0,
            "omega_max": rating.max_speed,
            "braking": rating.braking,
        },
    )


#: The named ratings (``top_drive_from_spec`` names).
RATINGS = {"tds-11sa": TDS_11SA}


def top_drive_from_spec(spec: str, R0: float, scales: Scales | None = None) -> TopDrive:
    """A top drive from a command-line spec.

    ``"tds-11sa"`` (a name of :data:`RATINGS`; needs the rig's ``scales``): the whole rating;
    ``"<x>R0"``: the torque range [-x R0, x R0] alone (scaled, any parameter set); ``"<x>kNm"``
    or ``"<x>Nm"``: [-x, x] in SI on the rig of ``scales``.

    Parameters
    ----------
    spec : str
        As above (case is ignored).
    R0 : float
        The nominal torque (scaled, units of C).
    scales : PhysicalParams or any object with C and t_star, optional
        The rig, for a named rating or an SI torque.

    Returns
    -------
    TopDrive

    Raises
    ------
    ValueError
        A spec of none of these forms, a limit that is not positive, or no rig for a rating or
        an SI torque; the message names the spec.
    """
    text = str(spec).strip().lower().replace(" ", "")
    if text in RATINGS:
        if scales is None:
            raise ValueError(f"top drive {spec!r}: a named rating needs the physical rig")
        return top_drive(RATINGS[text], scales)
    for suffix, factor, physical in (("knm", 1e3, True), ("nm", 1.0, True), ("r0", R0, False)):
        if text.endswith(suffix):
            try:
                x = float(text[: -len(suffix)]) * factor
            except ValueError:
                break
            if not (math.isfinite(x) and x > 0.0):
                break
            if physical:
                if scales is None:
                    raise ValueError(f"top drive {spec!r}: a torque in N m needs the physical rig")
                return TopDrive.from_si(scales, {"R_min": -x, "R_max": x})
            return TopDrive(R_min=-x, R_max=x)
    raise ValueError(
        f"top drive {spec!r}: expected a rating ({', '.join(RATINGS)}), a multiple of the "
        "nominal torque ('50R0') or a torque in N m ('52kNm', '52000Nm'), positive"
    )


# --------------------------------------------------------------------------------------------
# the top drive, compiled: on the block ``b`` whose top-drive section (TOP_DRIVE_SLOTS) is at ``at``
# --------------------------------------------------------------------------------------------

inline = jit_for(__name__, inline=True)


@inline
def envelope(b, at, omega):
    """(lo, hi): the absolute torques R/C the top drive can deliver at the table speed ``omega``.

    The torque range; the power limit ``|R*omega| <= P_max``; without braking no torque against
    the rotation (``R >= 0`` while ``omega > 0``, ``R <= 0`` while ``omega < 0``); no torque
    that drives the table further out of its speed range (``R <= 0`` at or above ``omega_max``,
    ``R >= 0`` at or below ``omega_min``). Where these exclude each other the upper bound wins.
    """
    lo = b[at + TOP_DRIVE_SLOTS.R_min]
    hi = b[at + TOP_DRIVE_SLOTS.R_max]
    p_max = b[at + TOP_DRIVE_SLOTS.P_max]
    w = abs(omega)
    if p_max < math.inf and w > 0.0:
        limit = p_max / w
        hi = min(hi, limit)
        lo = max(lo, -limit)
    if b[at + TOP_DRIVE_SLOTS.braking] == 0.0:
        if omega > 0.0:
            lo = max(lo, 0.0)
        elif omega < 0.0:
            hi = min(hi, 0.0)
    if omega >= b[at + TOP_DRIVE_SLOTS.omega_max]:
        hi = min(hi, 0.0)
    if omega <= b[at + TOP_DRIVE_SLOTS.omega_min]:
        lo = max(lo, 0.0)
    if lo > hi:
        lo = hi
    return lo, hi


@inline
def actuate(b, at, omega0, R0, r_cmd, dtheta):
    """(r_lim, r_app, R): the limited command and the applied torque R - R0 for the command
    ``r_cmd`` = R - R0 at the table speed ``omega0 + dtheta`` (``omega0``, ``R0``: the
    operating point), and the applied absolute torque R/C (pure: the drive's state is committed
    by :func:`drive_commit`)."""
    if b[at + TOP_DRIVE_SLOTS.on] == 0.0:
        return r_cmd, r_cmd, R0 + r_cmd
    lo, hi = envelope(b, at, omega0 + dtheta)
    R_cmd = R0 + r_cmd
    R = min(max(R_cmd, lo), hi)
    if b[at + TOP_DRIVE_SLOTS.init] != 0.0:
        R_prev = b[at + TOP_DRIVE_SLOTS.R]
        dt = b[at + TOP_DRIVE_SLOTS.dt]
        rate = b[at + TOP_DRIVE_SLOTS.rate]
        if rate < math.inf:
            R = min(max(R, R_prev - rate * dt), R_prev + rate * dt)
        R_lim = R
        T = b[at + TOP_DRIVE_SLOTS.lag]
        if T > 0.0:
            R = R_prev - math.expm1(-dt / T) * (R - R_prev)
            R = min(max(R, lo), hi)
    else:
        R_lim = R
    r_lim = r_cmd if R_lim == R_cmd else R_lim - R0
    r_app = r_cmd if R == R_cmd else R - R0
    return r_lim, r_app, R


@inline
def drive_commit(b, at, tau, R, Ts):
    """Commit the sample ``tau`` (period ``Ts``) at which the drive applied the absolute torque
    ``R`` (nothing without a top-drive model)."""
    if b[at + TOP_DRIVE_SLOTS.on] != 0.0:
        b[at + TOP_DRIVE_SLOTS.R] = R
        b[at + TOP_DRIVE_SLOTS.t] = tau
        b[at + TOP_DRIVE_SLOTS.dt] = Ts
        b[at + TOP_DRIVE_SLOTS.init] = 1.0
