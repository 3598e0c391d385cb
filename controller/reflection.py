"""The reflection of a torsional wave at the top drive (``docs/controllers.md``, "Reflection at
the top drive").

On the distributed string (``docs/model.md``, "The distributed string") a wave arriving at the
rotary table from below is reflected by the table's mechanical impedance: its inertia rho and the
law's torque per speed. With the law's feedback torque ``R_fb = -Z_law(s)*W`` (W the table speed,
the Laplace variable s in 1/tau) the top's impedance is ``Z_top(s) = rho*s + Z_law(s)`` and a speed
wave arriving with amplitude w_u leaves with ``w_d = r*w_u``,

    r(omega) = (Z_pipe - Z_top(i*omega)) / (Z_pipe + Z_top(i*omega)),   Z_pipe = sqrt(kappa)

(scaled, units of C*t*). The torque wave is reflected with ``-r``. ``r = 0``: the top absorbs
the wave (a damper of the pipe's impedance on a massless table); ``|r| = 1``: nothing is
absorbed (a held table, r = -1; the table's inertia alone, r = exp(-2i*atan(rho*omega/Z_pipe))).

The top-drive laws as one-ports (what they do with the table speed and the torque measured at
the top, all in continuous time as :func:`~drillstring.controller.tuning.linear_closed_loop`):

* :class:`~drillstring.model.laws.SpeedPI` (stiff PI, SoftSpeed): ``Z_law = kp + ki/s``;
* :class:`~drillstring.model.laws.ZTorque` with the string torque at the top T (the motor torque
  less rho times the table's acceleration, the rig lineup's ``Sensing(torque="motor")``, which
  is the pipe's torque at the table): ``e = -W - z_gain*H(s)*T``, ``H = LP*HP``,
  ``R_fb = P(s)*e``, ``P = kp + ki/s``, and ``T = R_fb - rho*s*W``, so
  ``Z_top = (rho*s + P)/(1 + z_gain*H*P)``: a stiff loop (P large) makes the top
  ``1/(z_gain*H)``, the impedance Z-Torque matches.

The LMI laws feed back the bit's angle and speed: they are no one-port at the top and have no
reflection coefficient.
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillstring.analysis.modes import TABLES, torsional_exact_modes
from drillstring.model.laws import Law, SpeedPI, ZTorque
from drillstring.validation import check_choice, check_real

__all__ = [
    "MODE_TABLE",
    "Reflection",
    "reflection",
    "reflection_at_modes",
    "top_impedance",
]

#: The table condition of the modes the reflection is evaluated at (``docs/controllers.md``,
#: "Reflection at the top drive": the held table, where a reflecting top puts the waves the
#: bit's velocity weakening feeds).
MODE_TABLE = "held"


def top_impedance(law: Law | None, rho: float, s: complex) -> complex:
    """``Z_top(s)``: the table's inertia ``rho`` and the law at the Laplace variable ``s``.

    Parameters
    ----------
    law : SpeedPI, ZTorque or None
        The top-drive law (None: no law, the table's inertia alone).
    rho : float
        The table's inertia I2/I1, >= 0 (0: a massless table).
    s : complex
        The Laplace variable (1/tau), not 0.

    Returns
    -------
    complex
        Torque per speed in units of C*t*.

    Raises
    ------
    TypeError
        A law that is no one-port at the top (the LMI laws).
    """
    rho = check_real("rho", rho, lower=0.0, strict=False)
    if law is None:
        return rho * s
    if isinstance(law, SpeedPI):
        return rho * s + (law.kp + law.ki / s)
    if isinstance(law, ZTorque):
        P = law.kp + law.ki / s
        H = (s / (s + law.omega_hp)) * (law.omega_lp / (s + law.omega_lp))
        return (rho * s + P) / (1.0 + law.z_gain * H * P)
    raise TypeError(
        f"a law of type {type(law).__name__} is no one-port at the top (it feeds back the bit): "
        "it has no reflection coefficient"
    )


def reflection(Z_pipe: float, Z_top: complex) -> complex:
    """The speed wave's reflection coefficient ``(Z_pipe - Z_top)/(Z_pipe + Z_top)``.

    An infinite ``Z_top`` (a held table) gives -1.
    """
    Z_pipe = check_real("Z_pipe", Z_pipe, lower=0.0)
    if cmath.isinf(Z_top):
        return complex(-1.0, 0.0)
    return (Z_pipe - Z_top) / (Z_pipe + Z_top)


@dataclass(frozen=True)
class Reflection:
    """The reflection at one mode: its scaled frequency, Z_top there, r, |r| and arg r [deg]."""

    mode: int
    omega: float
    Z_top: complex
    r: complex

    @property
    def magnitude(self) -> float:
        """|r|."""
        return abs(self.r)

    @property
    def phase_deg(self) -> float:
        """arg r in degrees, in (-180, 180]."""
        return math.degrees(cmath.phase(self.r))

    def values(self, t_star: float | None = None) -> dict[str, Any]:
        """The numbers by name (the frequency in Hz with t* [s], else NaN)."""
        hz = math.nan if t_star is None else self.omega / (2.0 * math.pi * t_star)
        return {
            "mode": self.mode,
            "omega_scaled": self.omega,
            "frequency_hz": hz,
            "Z_top_re": self.Z_top.real,
            "Z_top_im": self.Z_top.imag,
            "r_magnitude": self.magnitude,
            "r_phase_deg": self.phase_deg,
        }


def reflection_at_modes(
    law: Law | None,
    rho: float,
    kappa: float,
    *,
    table: str = MODE_TABLE,
    count: int = 2,
    omegas: Sequence[float] | None = None,
) -> list[Reflection]:
    """The reflection coefficient of ``law`` at the string's first ``count`` modes.

    Parameters
    ----------
    law : SpeedPI, ZTorque or None
        The top-drive law (None: the table's inertia alone).
    rho : float
        The table's inertia I2/I1.
    kappa : float
        The pipe's inertia over I1, in (0, 3): Z_pipe = sqrt(kappa).
    table : str
        The modes of the continuous string with the table ``"held"`` (default) or ``"free"``
        (:func:`~drillstring.analysis.modes.torsional_exact_modes`).
    count : int
        How many modes.
    omegas : sequence of float, optional
        The scaled frequencies instead of the string's modes.

    Returns
    -------
    list of Reflection
    """
    check_choice("table", table, TABLES)
    kappa = check_real("kappa", kappa, lower=0.0)
    rho = check_real("rho", rho, lower=0.0, strict=False)
    if omegas is None:
        if rho == 0.0 and table == "free":
            raise ValueError("the free table's modes need the table's inertia rho > 0")
        # the held table's modes do not depend on rho (a massless table is allowed)
        omegas = torsional_exact_modes(kappa, rho if rho > 0.0 else 1.0, table, count)
    Z_pipe = math.sqrt(kappa)
    out = []
    for k, w in enumerate(np.asarray(omegas, dtype=float), start=1):
        Z = top_impedance(law, rho, complex(0.0, float(w)))
        out.append(Reflection(mode=k, omega=float(w), Z_top=Z, r=reflection(Z_pipe, Z)))
    return out
