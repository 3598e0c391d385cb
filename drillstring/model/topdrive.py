"""The top drive: what a rig's drive can do with a torque command (its rating), shared by every
law (``docs/controllers.md``, "The top drive").

:class:`TopDrive` is the rating in the paper's scaled units (absolute table torque R/C, table
speed dTheta/dtau, time tau); :func:`top_drive` converts a named SI rating (:class:`Rating`,
e.g. :data:`TDS_11SA`) on a rig. The compiled model is :mod:`drillstring.model.digital.drive`:
the torque range, the power limit |R Omega| <= P_max, the speed range, braking (four-quadrant or
none), and a first-order drive lag or a torque rate limit.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from drillstring.model.digital import layout as L
from drillstring.model.tables import Parameter, Scales, table_from_si, table_to_si
from drillstring.validation import check_choice, check_real

__all__ = ["BRAKING", "RATINGS", "RPM", "Rating", "TDS_11SA", "TopDrive", "top_drive",
           "top_drive_from_spec"]  # fmt: skip

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

    def pack(self, b: np.ndarray) -> None:
        """Write the limits into the block ``b`` (``TD`` entries) and switch the model on."""
        t = L.B_TD
        b[t + L.TD_ON] = 1.0
        b[t + L.TD_RMIN] = self.R_min
        b[t + L.TD_RMAX] = self.R_max
        b[t + L.TD_RATE] = self.rate
        b[t + L.TD_LAG] = self.lag
        b[t + L.TD_PMAX] = self.P_max
        b[t + L.TD_WMIN] = self.omega_min
        b[t + L.TD_WMAX] = self.omega_max
        b[t + L.TD_BRAKE] = 1.0 if self.braking == "four-quadrant" else 0.0


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
