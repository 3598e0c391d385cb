"""Set-valued wearflat contact (17) as a Filippov system, and torsional stick.

See ``docs/model.md``, "Wearflat contact as a Filippov system" and "Torsional stick".

Modes: slip down (V > 0, g = 0), axial stick (V = 0, g = g* in [0, 1]), moving up (V < 0, g = 1),
and torsional stick (W = 0, V = 0, Phi and U frozen; only with the torsional-stick option).
"""

from __future__ import annotations

import numpy as np

from drillstring.model.kernel.jit import jit_for
from drillstring.model.kernel.state import (
    MODE_SLIP,
    MODE_STICK,
    MODE_TSTICK,
    MODE_UP,
    P_BETA,
    P_D0,
    P_GAMMA,
    P_KA,
    P_KT,
    P_LAM,
    P_N,
    P_NPSI,
    P_R0,
    P_V0,
)

jit = jit_for(__name__)
inline = jit_for(__name__, inline=True)


@inline
def g_star(P: np.ndarray, U: float, d: float, hook_side: float) -> float:
    """The contact multiplier that keeps dV/dtau = 0 at V = 0.

    g* = [(d - d0) - (gamma*v0 - eta^2*(U - v0*tau)) / (n*psi)] / lambda; +inf or -inf for a
    sharp bit (lambda = 0), where stick is impossible. On the distributed string the spring
    force is the bit element's, k_a*(U - hook_side), with ``hook_side`` the axial position of
    the bit's neighbour (v0*tau, the hook, for the paper's massless spring).
    """
    num = (d - P[P_D0]) - (P[P_GAMMA] * P[P_V0] - P[P_KA] * (U - hook_side)) / P[P_NPSI]
    lam = P[P_LAM]
    if lam > 0.0:
        return num / lam
    return np.inf if num > 0.0 else -np.inf


@inline
def contact(mode: int, gstar: float) -> float:
    """g of (17) in a mode: 0 slipping down, 1 moving up, g* in axial stick."""
    if mode == MODE_SLIP:
        return 0.0
    if mode == MODE_UP:
        return 1.0
    if mode == MODE_STICK:
        return gstar
    return min(max(gstar, 0.0), 1.0)


@jit
def mode_at_zero_velocity(gstar: float) -> int:
    """Axial mode chosen when V reaches 0: stick while 0 <= g* <= 1 (Filippov sliding)."""
    if gstar < 0.0:
        return MODE_SLIP
    if gstar > 1.0:
        return MODE_UP
    return MODE_STICK


@inline
def max_bit_torque(P: np.ndarray, d: float) -> float:
    """T_max = n*d + n*beta*lambda, the largest torque on bit while stuck."""
    return P[P_N] * (d + P[P_BETA] * P[P_LAM])


@inline
def twist_torque(P: np.ndarray, Phi: float, neighbour: float) -> float:
    """Scaled twist torque on the bit S = R0 + Theta - Phi (R0 the nominal twist, eq. (8)); on
    the distributed string the bit element's, R0 + k_t*(neighbour - Phi)."""
    return P[P_R0] + P[P_KT] * neighbour - P[P_KT] * Phi


@inline
def torque_on_bit(P: np.ndarray, mode: int, d: float, g: float, twist: float) -> float:
    """Scaled torque on bit T = n*d + n*beta*lambda*(1 - g); T = S while torsionally stuck."""
    if mode == MODE_TSTICK:
        return twist
    return P[P_N] * (d + P[P_BETA] * P[P_LAM] * (1.0 - g))
