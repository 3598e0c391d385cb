"""The top drive, compiled: what becomes of a torque command at the rotary table.

A top drive (or rotary table drive) delivers a torque within its rating: a torque range, a power
limit, a speed range and, without a braking resistor or regenerative supply, no torque against
the rotation. Its torque follows the command with a first-order lag (the drive's current loop,
5-20 ms) or at a limited rate. :class:`drillstring.model.topdrive.TopDrive` holds the rating;
``docs/controllers.md``, "The top drive", states the model and the rating of the reference rig.

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
drive model (``TD_ON`` 0) the command is applied as it is; when nothing limits it the command is
returned exactly (not R0 + r - R0, which can differ from r by rounding).
"""

from __future__ import annotations

import math

from drillstring.model.digital.layout import (
    B_OMEGA0,
    B_R0,
    B_TD,
    B_TDX,
    TD_BRAKE,
    TD_LAG,
    TD_ON,
    TD_PMAX,
    TD_RATE,
    TD_RMAX,
    TD_RMIN,
    TD_WMAX,
    TD_WMIN,
    TDX_DT,
    TDX_INIT,
    TDX_R,
)
from drillstring.model.kernel.jit import jit_for

inline = jit_for(__name__, inline=True)

__all__ = ["actuate", "envelope"]


@inline
def envelope(b, omega):
    """(lo, hi): the absolute torques R/C the top drive can deliver at the table speed ``omega``.

    The torque range; the power limit ``|R*omega| <= P_max``; without braking no torque against
    the rotation (``R >= 0`` while ``omega > 0``, ``R <= 0`` while ``omega < 0``); no torque
    that drives the table further out of its speed range (``R <= 0`` at or above ``omega_max``,
    ``R >= 0`` at or below ``omega_min``). Where these exclude each other the upper bound wins.
    """
    lo = b[B_TD + TD_RMIN]
    hi = b[B_TD + TD_RMAX]
    p_max = b[B_TD + TD_PMAX]
    w = abs(omega)
    if p_max < math.inf and w > 0.0:
        limit = p_max / w
        hi = min(hi, limit)
        lo = max(lo, -limit)
    if b[B_TD + TD_BRAKE] == 0.0:
        if omega > 0.0:
            lo = max(lo, 0.0)
        elif omega < 0.0:
            hi = min(hi, 0.0)
    if omega >= b[B_TD + TD_WMAX]:
        hi = min(hi, 0.0)
    if omega <= b[B_TD + TD_WMIN]:
        lo = max(lo, 0.0)
    if lo > hi:
        lo = hi
    return lo, hi


@inline
def actuate(b, tau, r_cmd, dtheta):
    """(r_lim, r_app, R): the limited command and the applied torque R - R0 for the command
    ``r_cmd`` = R - R0 at time ``tau``, and the applied absolute torque R/C (pure: the drive's
    state is committed by :func:`drillstring.model.digital.block.commit`)."""
    if b[B_TD + TD_ON] == 0.0:
        return r_cmd, r_cmd, b[B_R0] + r_cmd
    R0 = b[B_R0]
    lo, hi = envelope(b, b[B_OMEGA0] + dtheta)
    R_cmd = R0 + r_cmd
    R = min(max(R_cmd, lo), hi)
    if b[B_TDX + TDX_INIT] != 0.0:
        R_prev = b[B_TDX + TDX_R]
        dt = b[B_TDX + TDX_DT]
        rate = b[B_TD + TD_RATE]
        if rate < math.inf:
            R = min(max(R, R_prev - rate * dt), R_prev + rate * dt)
        R_lim = R
        T = b[B_TD + TD_LAG]
        if T > 0.0:
            R = R_prev - math.expm1(-dt / T) * (R - R_prev)
            R = min(max(R, lo), hi)
    else:
        R_lim = R
    r_lim = r_cmd if R_lim == R_cmd else R_lim - R0
    r_app = r_cmd if R == R_cmd else R - R0
    return r_lim, r_app, R
