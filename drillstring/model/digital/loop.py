"""The sampled closed loop, compiled: a digital controller on the engine's kernel, sample by
sample, without Python in between.

At each sample instant tau_k = k*Ts: the plant's perturbation state at the engine's time, the
controller's sample and commit (:func:`drillstring.model.digital.block.commit`; the string
torque it senses is the top element's, the kernel's ``top_torque_minus_R0``), its applied
torque held over [tau_k, tau_k + Ts) as the input R - R0 of (13), a row of outputs every
``every`` samples, and the kernel's advance to tau_k + Ts (the end a unit reaches when a
fixed-step master steps it from tau_k by Ts, so that a co-simulation of the controller FMU
takes exactly these steps). :func:`drillstring.model.sampled.simulate_sampled` drives it and
does what needs Python (the event log drained, the history buffer grown).

Each row holds the kernel's outputs (:data:`~drillstring.model.kernel.state.OUTPUT_COLUMNS`)
and then :data:`EXTRA_COLUMNS`: the extremes of the applied absolute torque R/C and of the
power |R*Omega| over the samples since the previous row (Omega = omega0 + dtheta/dtau, the
table speed) and how many of them the top drive limited, so a coarse output grid still gives
exact peaks.
"""

from __future__ import annotations

import math

from drillstring.model.digital.block import commit
from drillstring.model.digital.layout import BLOCK
from drillstring.model.kernel.coordinates import to_perturbation
from drillstring.model.kernel.jit import jit_for
from drillstring.model.kernel.state import (
    OUT_SIZE,
    P_KT,
    P_NT,
    ST_EVLOG_FULL,
    ST_HIST_FULL,
    ST_OK,
    X_TAU,
    Y_PHI,
    Y_THETA,
    Y_U,
    Y_V,
    Y_W,
    Y_WT,
    Z_NOW,
    KernelState,
)
from drillstring.model.kernel.stepper import advance_drained, hold, write_sample

jit = jit_for(__name__)

__all__ = ["EXTRA_COLUMNS", "run_sampled_from"]

#: Columns after the kernel's outputs in each row (since the previous row, sample-exact).
EXTRA_COLUMNS = ("R_max", "R_min", "P_max", "n_saturated")
X_RMAX = OUT_SIZE
X_RMIN = OUT_SIZE + 1
X_PMAX = OUT_SIZE + 2
X_NSAT = OUT_SIZE + 3
ROW_SIZE = OUT_SIZE + 4


@jit
def _run(s, b, k, n, Ts, every, rows, i, acc, keep_events):
    """Samples k..n of the loop; see :func:`run_sampled_from`."""
    P, X, Y = s.params, s.clock, s.y
    while True:
        tau = k * Ts
        _, _, phi, dphi, theta, dtheta = to_perturbation(
            P, X[X_TAU], Y[Y_U], Y[Y_V], Y[Y_PHI], Y[Y_W], Y[Y_THETA], Y[Y_WT]
        )
        # the torque a sub under the top drive reads: the twist on one element, else the top
        # element's (the kernel's top_torque_minus_R0)
        if int(P[P_NT]) == 0:
            top = theta - phi
        else:
            top = P[P_KT] * (Y[Y_THETA] - s.chain[Z_NOW, 0])
        hold(s, commit(b, tau, phi, dphi, theta, dtheta, top, Ts))
        R = b[BLOCK.r_app] + b[BLOCK.R0]
        power = abs(R * (b[BLOCK.omega0] + dtheta))
        acc[0] = max(acc[0], R)
        acc[1] = min(acc[1], R)
        acc[2] = max(acc[2], power)
        acc[3] += b[BLOCK.saturated]
        if k % every == 0 or k == n:
            write_sample(s, rows[i])
            rows[i, X_RMAX] = acc[0]
            rows[i, X_RMIN] = acc[1]
            rows[i, X_PMAX] = acc[2]
            rows[i, X_NSAT] = acc[3]
            acc[0] = -math.inf
            acc[1] = math.inf
            acc[2] = 0.0
            acc[3] = 0.0
            i += 1
        if k == n:
            return ST_OK, k, i
        # tau_k + Ts, not (k + 1)*Ts: the end a fixed-step master reaches from tau_k
        st = advance_drained(s, tau + Ts, keep_events, None)
        if st == ST_EVLOG_FULL or st == ST_HIST_FULL:
            return st, k, i
        if st != ST_OK:
            if X[X_TAU] > rows[i - 1, 0]:
                write_sample(s, rows[i])
                rows[i, X_RMAX] = acc[0]
                rows[i, X_RMIN] = acc[1]
                rows[i, X_PMAX] = acc[2]
                rows[i, X_NSAT] = acc[3]
                i += 1
            return st, k, i
        k += 1


@jit
def run_sampled_from(params, options, control, clock, y, ints, diag, history, events, stages,
                     chain, b, k, n, Ts, every, rows, i, acc, keep_events):  # fmt: skip
    """Run the sampled loop from sample ``k`` to ``n`` on the kernel state of these arrays and
    the controller block ``b``; rows from ``rows[i]`` on.

    ``acc`` holds the running extremes of
    the extra columns. Returns (status, k, i): ST_OK at the end (``k == n``), a buffer status
    (ST_EVLOG_FULL, ST_HIST_FULL: the advance of sample k is unfinished; finish it, then call
    again from k + 1 and i), or the status that stopped the run (its last row at the stop).
    """
    s = KernelState(params, options, control, clock, y, ints, diag, history, events, stages, chain)
    return _run(s, b, k, n, Ts, every, rows, i, acc, keep_events)
