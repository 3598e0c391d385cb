"""History buffer numerics: cubic Hermite interpolation and the state-dependent delay (14).

The past of U and Phi is stored at the integrator's nodes together with their derivatives V and
W, so a cubic Hermite interpolant reproduces it to O(h^4), the order of the RK4 scheme. The delay
tau_n solves Phi(tau) - Phi(tau - tau_n) = 2*pi/n (eq. (6)/(14)); Phi is non-decreasing while the
model is valid (W >= 0), so the past instant is bracketed by a monotone search over nodes and
refined by Newton's method with a bisection safeguard. On a flat (stuck) stretch of Phi the most
recent matching instant is taken (``docs/model.md``, "Torsional stick").
"""

from __future__ import annotations

import numpy as np

from drillstring.model.kernel.jit import jit_for
from drillstring.model.kernel.state import (
    H_FLAG,
    H_PHI,
    H_TAU,
    H_U,
    H_V,
    H_W,
    I_HEND,
    I_HSTART,
    I_KHINT,
    I_MODE,
    MODE_TSTICK,
    Y_PHI,
    Y_U,
    Y_V,
    Y_W,
)

jit = jit_for(__name__)
inline = jit_for(__name__, inline=True)

#: Newton on the cubic is quadratic: after a Newton step shorter than this (in the interval's
#: unit) the next one would be below rounding, so the iteration stops there (iterating further
#: only chases the rounding noise of Phi, which grows with Phi).
NEWTON_STEP_TOL = 1e-9
NEWTON_MAX = 60


@inline
def hermite(y0: float, y1: float, m0: float, m1: float, dt: float, s: float) -> float:
    """Cubic Hermite interpolant on one interval at local coordinate s in [0, 1]."""
    s2 = s * s
    s3 = s2 * s
    return (
        (2.0 * s3 - 3.0 * s2 + 1.0) * y0
        + (s3 - 2.0 * s2 + s) * dt * m0
        + (-2.0 * s3 + 3.0 * s2) * y1
        + (s3 - s2) * dt * m1
    )


@inline
def hermite_slope(y0: float, y1: float, m0: float, m1: float, dt: float, s: float) -> float:
    """d/dtau of :func:`hermite` (note: per unit time, not per unit s)."""
    s2 = s * s
    ds = (
        (6.0 * s2 - 6.0 * s) * y0
        + (3.0 * s2 - 4.0 * s + 1.0) * dt * m0
        + (-6.0 * s2 + 6.0 * s) * y1
        + (3.0 * s2 - 2.0 * s) * dt * m1
    )
    return ds / dt


@inline
def find_interval(H: np.ndarray, start: int, end: int, k_hint: int, row: int, value: float) -> int:
    """Largest node index k in [start, end) with H[row, k] <= value (row non-decreasing).

    Returns start - 1 when value lies before the first node. The walk starts at ``k_hint`` and is
    O(1) amortised, since successive look-ups move forward by about one node per step.
    """
    k = k_hint
    if k < start:
        k = start
    if k > end - 1:
        k = end - 1
    if H[row, k] > value:
        while k > start and H[row, k] > value:
            k -= 1
        if H[row, k] > value:
            return start - 1
        return k
    while k + 1 < end and H[row, k + 1] <= value:
        k += 1
    return k


@inline
def delay_lookup(
    H: np.ndarray, start: int, end: int, k_hint: int, phi_now: float, blade: float
) -> tuple[int, float, float]:
    """Past instant s with Phi(s) = phi_now - blade, eq. (14). Returns (k, s, U(s)).

    k is the history interval holding s; k < 0 flags failure: -1 when the history does not reach
    back far enough, -2 when s lies after the last node (delay shorter than the current step).
    """
    target = phi_now - blade
    k = find_interval(H, start, end, k_hint, H_PHI, target)
    if k < start:
        return -1, 0.0, 0.0
    if k >= end - 1:
        if H[H_PHI, k] == target:
            return k, H[H_TAU, k], H[H_U, k]
        return -2, 0.0, 0.0
    t0 = H[H_TAU, k]
    dt = H[H_TAU, k + 1] - t0
    p0 = H[H_PHI, k]
    p1 = H[H_PHI, k + 1]
    if dt <= 0.0 or p0 == target:
        return k, t0, H[H_U, k]
    w0 = H[H_W, k]
    w1 = H[H_W, k + 1]
    lo = 0.0
    hi = 1.0
    s = (target - p0) / (p1 - p0)
    for _ in range(NEWTON_MAX):
        f = hermite(p0, p1, w0, w1, dt, s) - target
        if f == 0.0:
            break
        if f < 0.0:
            lo = s
        else:
            hi = s
        fp = hermite_slope(p0, p1, w0, w1, dt, s) * dt
        newton = fp > 0.0
        s_new = s - f / fp if newton else 0.5 * (lo + hi)
        if s_new <= lo or s_new >= hi:
            s_new = 0.5 * (lo + hi)
            newton = False
        converged = newton and abs(s_new - s) <= NEWTON_STEP_TOL
        s = s_new
        if converged:
            break
    u_past = hermite(H[H_U, k], H[H_U, k + 1], H[H_V, k], H[H_V, k + 1], dt, s)
    return k, t0 + s * dt, u_past


@inline
def append_node(
    H: np.ndarray, end: int, tau: float, U: float, V: float, Phi: float, W: float, flag: float
) -> int:
    """Write a node at column ``end`` (caller guarantees capacity); returns the new end."""
    H[H_TAU, end] = tau
    H[H_U, end] = U
    H[H_V, end] = V
    H[H_PHI, end] = Phi
    H[H_W, end] = W
    H[H_FLAG, end] = flag
    return end + 1


@inline
def push_node(H: np.ndarray, I: np.ndarray, tau: float, Y: np.ndarray, flag: float) -> None:
    """Append the accepted state as a history node; a torsional-stick stretch keeps two nodes.

    Nodes before the current delay interval are dropped (they can never be reached again, Phi
    being non-decreasing), so the live window stays about one delay long.
    """
    start = I[I_HSTART]
    end = I[I_HEND]
    if I[I_MODE] == MODE_TSTICK and end - start >= 2:
        a = end - 1
        b = end - 2
        if (
            H[H_U, a] == Y[Y_U]
            and H[H_U, b] == Y[Y_U]
            and H[H_PHI, a] == Y[Y_PHI]
            and H[H_PHI, b] == Y[Y_PHI]
            and H[H_V, a] == 0.0
            and H[H_W, a] == 0.0
            and H[H_V, b] == 0.0
            and H[H_W, b] == 0.0
            and Y[Y_V] == 0.0
            and Y[Y_W] == 0.0
        ):
            H[H_TAU, a] = tau
            return
    I[I_HEND] = append_node(H, end, tau, Y[Y_U], Y[Y_V], Y[Y_PHI], Y[Y_W], flag)
    keep = I[I_KHINT] - 2
    if keep > start:
        I[I_HSTART] = keep


@inline
def next_discontinuity(
    H: np.ndarray, start: int, end: int, k_hint: int, s0: float, s1: float
) -> float:
    """Time of the first flagged node in (s0, s1], or -inf if none.

    A flagged node is a derivative discontinuity of the stored solution (an event, or the joint
    of prehistory and initial state). When the delayed instant tau - tau_n passes it, the
    right-hand side loses smoothness, so the step must end exactly there to keep RK4's order.
    """
    k = find_interval(H, start, end, k_hint, H_TAU, s0)
    if k < start:
        k = start - 1
    k += 1
    while k < end and H[H_TAU, k] <= s1:
        if H[H_FLAG, k] > 0.0 and H[H_TAU, k] > s0:
            return H[H_TAU, k]
        k += 1
    return -np.inf


@jit
def compact(H: np.ndarray, start: int, end: int) -> int:
    """Move the live columns [start, end) to the front; returns the new end (start becomes 0)."""
    n = end - start
    for r in range(H.shape[0]):
        for j in range(n):
            H[r, j] = H[r, start + j]
    return n


@jit
def interpolate(H: np.ndarray, start: int, end: int, tau: float, out: np.ndarray) -> bool:
    """U, V, Phi, W at a past time tau by Hermite interpolation (V, W from the slopes)."""
    k = find_interval(H, start, end, start, H_TAU, tau)
    if k < start:
        return False
    if k >= end - 1:
        if H[H_TAU, end - 1] < tau:
            return False
        k = end - 2 if end - start >= 2 else k
    if k + 1 >= end:
        out[0] = H[H_U, k]
        out[1] = H[H_V, k]
        out[2] = H[H_PHI, k]
        out[3] = H[H_W, k]
        return True
    t0 = H[H_TAU, k]
    dt = H[H_TAU, k + 1] - t0
    if dt <= 0.0:
        out[0] = H[H_U, k + 1]
        out[1] = H[H_V, k + 1]
        out[2] = H[H_PHI, k + 1]
        out[3] = H[H_W, k + 1]
        return True
    s = (tau - t0) / dt
    u0, u1, v0, v1 = H[H_U, k], H[H_U, k + 1], H[H_V, k], H[H_V, k + 1]
    p0, p1, w0, w1 = H[H_PHI, k], H[H_PHI, k + 1], H[H_W, k], H[H_W, k + 1]
    out[0] = hermite(u0, u1, v0, v1, dt, s)
    out[1] = hermite_slope(u0, u1, v0, v1, dt, s)
    out[2] = hermite(p0, p1, w0, w1, dt, s)
    out[3] = hermite_slope(p0, p1, w0, w1, dt, s)
    return True
