"""The lower bound of the kernel's cost per step: a minimal compiled RK4 loop of the same work.

Per step it does what the kernel must do on a smooth stretch of the open-loop model in slip
(V > 0, g = 0, R = R0): four right-hand sides of (11)-(13), each with the delay look-up of
(14) by Newton's method on the cubic Hermite history (the kernel's own interpolant, first
guess, stopping rule and iteration bound), and one history node appended per step. Nothing
else: no modes, no events, no diagnostics, no status checks, no bracketing safeguard of the
Newton iteration, no buffer management (the history array is large enough for the whole run).
It is the kernel stripped to its arithmetic, so the ratio of the two is the cost of the
kernel's structure; ``bench/engine.py`` checks that, started from the kernel's state past the
delayed discontinuity of tau = 0, both compute the same trajectory bit for bit.
"""

from __future__ import annotations

import math

import numba

from drillstring.model.kernel.hermite import (
    NEWTON_MAX,
    NEWTON_STEP_TOL,
    hermite,
    hermite_slope,
)
from drillstring.model.kernel.state import H_PHI, H_TAU, H_U, H_V, H_W


@numba.njit(cache=True, nogil=True, inline="always")
def _delayed_u(H, end, k, target):
    """(k, U(s)) at the past instant s with Phi(s) = target: forward walk from k, Newton."""
    while k + 2 < end and H[H_PHI, k + 1] <= target:
        k += 1
    t0 = H[H_TAU, k]
    dt = H[H_TAU, k + 1] - t0
    p0 = H[H_PHI, k]
    p1 = H[H_PHI, k + 1]
    w0 = H[H_W, k]
    w1 = H[H_W, k + 1]
    s = (target - p0) / (p1 - p0)
    for _ in range(NEWTON_MAX):
        f = hermite(p0, p1, w0, w1, dt, s) - target
        if f == 0.0:
            break
        s_new = s - f / (hermite_slope(p0, p1, w0, w1, dt, s) * dt)
        converged = abs(s_new - s) <= NEWTON_STEP_TOL
        s = s_new
        if converged:
            break
    return k, hermite(H[H_U, k], H[H_U, k + 1], H[H_V, k], H[H_V, k + 1], dt, s)


@numba.njit(cache=True, nogil=True, inline="always")
def _rhs(p, k, H, end, tau, y):
    """(k, dY/dtau) of (11)-(13) in slip (g = 0) with R = R0, eq. (14) for the delay."""
    n, npsi, gamma, eta, v0, d0, rho, blade = p
    U, V, Phi, W, Theta, Wt = y
    k, u_past = _delayed_u(H, end, k, Phi - blade)
    d = U - u_past
    twist = Phi - Theta
    dV = -gamma * (V - v0) - eta * eta * (U - v0 * tau) + npsi * (d0 - d)
    return k, (V, dV, W, -twist + n * (d0 - d), Wt, twist / rho)


@numba.njit(cache=True, nogil=True, inline="always")
def _axpy(y, a, k):
    return (
        y[0] + a * k[0],
        y[1] + a * k[1],
        y[2] + a * k[2],
        y[3] + a * k[3],
        y[4] + a * k[4],
        y[5] + a * k[5],
    )


@numba.njit(cache=True, nogil=True)
def minimal_loop(p, H, state, tau_end, h_nom):
    """RK4 from ``state`` to tau_end in equal steps no longer than h_nom; appends nodes to H.

    ``p`` = (n, n*psi, gamma, eta, v0, d0, rho, 2*pi/n); H holds the history in the kernel's
    rows ``H_*``, with room for all steps. ``state`` = (tau, y, dy/dtau at y, end of the
    history, interval of the last delay look-up), e.g. taken from the kernel's state. Each
    step's end is computed from the interval's end, as the kernel does (its results depend on
    it). Returns (state, steps).
    """
    tau, y, f1, end, k = state
    steps = 0
    while tau < tau_end:
        remaining = tau_end - tau
        n = max(int(math.ceil(remaining / h_nom - 1e-9)), 1)
        t_end = tau_end if n == 1 else tau_end - (n - 1) * (remaining / n)
        h = t_end - tau
        k, f2 = _rhs(p, k, H, end, tau + 0.5 * h, _axpy(y, 0.5 * h, f1))
        k, f3 = _rhs(p, k, H, end, tau + 0.5 * h, _axpy(y, 0.5 * h, f2))
        k, f4 = _rhs(p, k, H, end, tau + h, _axpy(y, h, f3))
        y = _axpy(y, h / 6.0, _axpy(_axpy(_axpy(f1, 2.0, f2), 2.0, f3), 1.0, f4))
        k, f1 = _rhs(p, k, H, end, tau + h, y)
        tau = t_end
        H[H_TAU, end] = tau
        H[H_U, end] = y[0]
        H[H_V, end] = y[1]
        H[H_PHI, end] = y[2]
        H[H_W, end] = y[3]
        end += 1
        steps += 1
    return (tau, y, f1, end, k), steps
