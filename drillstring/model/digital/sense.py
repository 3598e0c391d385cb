"""What the controller knows of the string, compiled: downhole telemetry, an observer from
surface signals, and the string torque measured or estimated at the surface.

:class:`drillstring.model.sensing.Sensing` holds the settings; ``docs/controllers.md``,
"Sensing", states the models. The measurements are the scaled perturbations of (9)-(10).

* The bit angle and speed (downhole): exact (``SENSE_IDEAL``); or by telemetry
  (``SENSE_TELEMETRY``): a frame (phi, dphi plus Gaussian noise) is taken at the first sample at
  or after each multiple of the frame period and arrives a latency later; the controller uses the
  newest frame that has arrived (before the first one it takes the nominal motion, phi = dphi =
  0); or estimated from surface signals alone (``SENSE_OBSERVER``): a Kalman filter on the
  linearised averaged torsional model (13), (27) with the measurements y = [dtheta, x3], x3 =
  phi - theta - K0 = -(string torque) - K0, and the applied torque as its input.
* The string torque at the top, ``top``: what a torque sub under the top drive reads, the
  torque of the string's top element less R0 (the host passes it: theta - phi, the twist, on
  the one-mode string; the kernel's ``top_torque_minus_R0`` on the distributed string,
  ``docs/model.md``, "The distributed string"): exact (``TORQUE_TWIST``); or from the motor
  (``TORQUE_MOTOR``): by (13), ``rho*dtheta' = (R - R0) - top`` with rho the table node's
  inertia (rho + kappa/(2N) on the string of N elements, the host's ``RHO``), so over the last
  sample, with the applied torque held, the mean string torque is ``r_prev - rho*(dtheta -
  dtheta_prev)/(tau - tau_prev)``, exact for the mean (it lags by half a sample), 0 before the
  first sample.

The noise is a counter-based generator (a 32-bit integer hash of the seed, the frame number and
the channel, then Box-Muller), so the Python and the compiled paths give the same numbers and a
run, restored from an FMU state or repeated, draws the same noise.
"""

from __future__ import annotations

import math

from drillstring.model.digital.layout import (
    B_FRAMES,
    B_RHO,
    B_SN,
    B_SNX,
    FR_ARRIVAL,
    FR_COLS,
    FR_DPHI,
    FR_PHI,
    N_FRAMES,
    SENSE_OBSERVER,
    SENSE_TELEMETRY,
    SN_AD,
    SN_BD,
    SN_K0,
    SN_LATENCY,
    SN_M,
    SN_MODE,
    SN_NDPHI,
    SN_NPHI,
    SN_PERIOD,
    SN_SEED,
    SN_TORQUE,
    SNX_K,
    SNX_NEXT,
    SNX_OBS,
    SNX_PDTHETA,
    SNX_PR,
    SNX_PREV,
    SNX_PT,
    SNX_XHAT,
    TORQUE_MOTOR,
)
from drillstring.model.kernel.jit import jit_for

inline = jit_for(__name__, inline=True)

__all__ = ["gaussian", "hash32", "sense_commit", "sensed", "string_torque"]

_MASK32 = 0xFFFFFFFF


@inline
def hash32(x):
    """A 32-bit integer hash (the "lowbias32" mix of C. Wellons), on 0 <= x < 2**32.

    Products are taken modulo 2**32 by masking, which is exact in Python's integers and in the
    compiled code's wrapping 64-bit integers alike."""
    x = x & _MASK32
    x = x ^ (x >> 16)
    x = (x * 0x7FEB352D) & _MASK32
    x = x ^ (x >> 15)
    x = (x * 0x846CA68B) & _MASK32
    x = x ^ (x >> 16)
    return x


@inline
def gaussian(seed, k, channel):
    """A standard normal number for (seed, frame ``k``, ``channel``) by Box-Muller."""
    h = hash32(hash32(hash32(seed) ^ (k & _MASK32)) ^ (k >> 32) ^ (channel * 0x9E3779B1))
    g = hash32(h ^ 0x85EBCA6B)
    u1 = (h + 0.5) / 4294967296.0
    u2 = (g + 0.5) / 4294967296.0
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@inline
def string_torque(b, tau, top, dtheta):
    """The string torque at the top less R0 as the controller knows it; ``top`` is its true value
    (theta - phi on the one-mode string)."""
    if int(b[B_SN + SN_TORQUE]) != TORQUE_MOTOR:
        return top
    x = B_SNX
    if b[x + SNX_PREV] == 0.0 or not b[x + SNX_PT] > 0.0:
        return 0.0
    return b[x + SNX_PR] - b[B_RHO] * (dtheta - b[x + SNX_PDTHETA]) / b[x + SNX_PT]


@inline
def _due(b, tau):
    """True when a telemetry frame is taken at the sample ``tau``."""
    nxt = b[B_SNX + SNX_NEXT]
    return tau >= nxt - 1e-9 * max(1.0, abs(nxt))


@inline
def _frame(b, k, phi, dphi):
    seed = int(b[B_SN + SN_SEED])
    return (
        phi + b[B_SN + SN_NPHI] * gaussian(seed, k, 0),
        dphi + b[B_SN + SN_NDPHI] * gaussian(seed, k, 1),
    )


@inline
def _observer_view(b, theta, dtheta, torque):
    """The observer's filtered estimate x_k|k = x_k|k-1 + M (y - C x_k|k-1)."""
    x = B_SNX + SNX_XHAT
    K0 = b[B_SN + SN_K0]
    x3 = -torque - K0
    if b[B_SNX + SNX_OBS] == 0.0:  # first sample: the state the measurements give
        return (theta - torque, dtheta, x3, dtheta)
    p0, p1, p2, p3 = b[x], b[x + 1], b[x + 2], b[x + 3]
    e0 = dtheta - p3
    e1 = x3 - p2
    m = B_SN + SN_M
    return (
        p0 + b[m] * e0 + b[m + 1] * e1,
        p1 + b[m + 2] * e0 + b[m + 3] * e1,
        p2 + b[m + 4] * e0 + b[m + 5] * e1,
        p3 + b[m + 6] * e0 + b[m + 7] * e1,
    )


@inline
def sensed(b, tau, phi, dphi, theta, dtheta, top):
    """(phi, dphi, torque) as the controller knows them at the sample ``tau`` (pure); ``top`` is
    the true string torque at the top less R0."""
    torque = string_torque(b, tau, top, dtheta)
    mode = int(b[B_SN + SN_MODE])
    if mode == SENSE_TELEMETRY:
        k = int(b[B_SNX + SNX_K])
        if _due(b, tau) and b[B_SN + SN_LATENCY] <= 0.0:
            p, dp = _frame(b, k, phi, dphi)
            return p, dp, torque
        # frames arrive in the order they were taken: the newest that has arrived
        now = tau + 1e-9 * max(1.0, abs(tau))
        for j in range(k - 1, max(-1, k - 1 - N_FRAMES), -1):
            f = B_FRAMES + (j % N_FRAMES) * FR_COLS
            if b[f + FR_ARRIVAL] <= now:
                return b[f + FR_PHI], b[f + FR_DPHI], torque
        return 0.0, 0.0, torque
    if mode == SENSE_OBSERVER:
        xh = _observer_view(b, theta, dtheta, torque)
        return xh[0], xh[1], torque
    return phi, dphi, torque


@inline
def sense_commit(b, tau, phi, dphi, theta, dtheta, top, r_app, Ts):
    """Commit the sample ``tau`` (period ``Ts``): take a due telemetry frame, propagate the
    observer with the applied torque ``r_app``, keep what the torque estimate needs."""
    x = B_SNX
    mode = int(b[B_SN + SN_MODE])
    torque = string_torque(b, tau, top, dtheta)
    if mode == SENSE_TELEMETRY and _due(b, tau):
        k = int(b[x + SNX_K])
        p, dp = _frame(b, k, phi, dphi)
        f = B_FRAMES + (k % N_FRAMES) * FR_COLS
        b[f + FR_ARRIVAL] = tau + b[B_SN + SN_LATENCY]
        b[f + FR_PHI] = p
        b[f + FR_DPHI] = dp
        b[x + SNX_K] = k + 1
        b[x + SNX_NEXT] = (k + 1) * b[B_SN + SN_PERIOD]
    elif mode == SENSE_OBSERVER:
        xf = _observer_view(b, theta, dtheta, torque)
        u = r_app + b[B_SN + SN_K0]
        a = B_SN + SN_AD
        bd = B_SN + SN_BD
        for i in range(4):
            row = a + 4 * i
            b[x + SNX_XHAT + i] = (
                b[row] * xf[0] + b[row + 1] * xf[1] + b[row + 2] * xf[2] + b[row + 3] * xf[3]
                + b[bd + i] * u
            )  # fmt: skip
        b[x + SNX_OBS] = 1.0
    b[x + SNX_PREV] = 1.0
    b[x + SNX_PT] = Ts
    b[x + SNX_PDTHETA] = dtheta
    b[x + SNX_PR] = r_app
