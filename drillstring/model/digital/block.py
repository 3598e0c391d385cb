"""The digital controller, compiled: one sample of sensing, law and top drive on the block.

Two functions carry every host (the controller FMUs, natively and on their Python path; the
compiled sampled loop; a Python caller):

* :func:`sample` -- what the controller puts out at a sample instant for the true plant
  measurements (pure: calling it twice gives the same numbers, as an FMU's output getter must);
* :func:`commit` -- the same sample, then the state one period later: the law's update, the
  top drive's torque, the sensing (telemetry frames, observer, torque estimate), diagnostics.

The controller's own timing (``docs/controllers.md``, "Timing of a real drive"): with a period P
> 0 (``TM_PERIOD``) the law computes at the first sample at or after each multiple of P, its
state advanced by P, its command held until its next computation; with a latency L
(``TM_LATENCY``) that command reaches the drive at the first sample at or after its computation
+ L, until then the drive keeps the command that arrived before (the feed-forward R_ff before
the first). The sensing and the top drive act at every sample of the host. P = 0 is the law at
every sample of the host, the code of before.

The switch-on (``docs/model.md``, "Bumpless switch-on"): before ``t_on``, or with the controller
disabled, only the law's feed-forward R_ff acts; at the first sample at or after ``t_on`` the
law starts from the measurements there. :func:`fmu_output` and :func:`fmu_step` are the same two
functions on an FMU's connectors (``IN``, ``OUT``, ``TIME`` of the block), in the FMU's unit
system (``SI``: the SI connectors converted with the rig scales of the block, eqs. (15)-(16)).
"""

from __future__ import annotations

import math

from drillstring.model.digital.drive import actuate
from drillstring.model.digital.lawcore import law_output, law_start, law_state, law_update
from drillstring.model.digital.layout import (
    B_ACTIVE,
    B_C,
    B_ENABLED,
    B_IN,
    B_LP,
    B_LX,
    B_NSAMPLES,
    B_NSAT,
    B_OMEGA0_SI,
    B_OUT,
    B_R0_SI,
    B_RAPP,
    B_RCMD,
    B_SAT,
    B_SI,
    B_TD,
    B_TDX,
    B_TIME,
    B_TM,
    B_TMX,
    B_TON,
    B_TSTAR,
    LP_RFF,
    TD_ON,
    TDX_DT,
    TDX_INIT,
    TDX_R,
    TDX_T,
    TM_LATENCY,
    TM_PERIOD,
    TMX_CMD,
    TMX_HASCMD,
    TMX_HASLAW,
    TMX_LAW,
    TMX_NEXT,
    TMX_NP,
    TMX_PEND,
)
from drillstring.model.digital.sense import sense_commit, sensed
from drillstring.model.kernel.jit import jit_for

jit = jit_for(__name__)
inline = jit_for(__name__, inline=True)

__all__ = ["commit", "fmu_output", "fmu_step", "sample"]


@inline
def _started(b, tau):
    """True when the law acts at ``tau``: enabled, and started or due to start."""
    return b[B_ENABLED] != 0.0 and (b[B_ACTIVE] != 0.0 or tau >= b[B_TON])


@inline
def _law_command(b, tau, theta, dtheta, torque_s, phi_s, dphi_s):
    """The law's command R - R0 at ``tau`` (the feed-forward alone before it has started)."""
    if _started(b, tau):
        if b[B_ACTIVE] != 0.0:
            x = law_state(b)
        else:
            x = law_start(b, theta, dtheta, torque_s, phi_s, dphi_s)
        return law_output(b, x, theta, dtheta, torque_s, phi_s, dphi_s)
    return b[B_LP + LP_RFF]


@inline
def _near(t):
    """The tolerance of "at or after" a time ``t`` (rounding of a host's clock)."""
    return 1e-9 * max(1.0, abs(t))


@inline
def _timed(b, tau, theta, dtheta, torque_s, phi_s, dphi_s):
    """With the controller's own period: (due, r_law, r_cmd), whether the law computes at
    ``tau``, its command (computed now or held), and the command at the drive."""
    nxt = b[B_TMX + TMX_NEXT]
    due = tau >= nxt - _near(nxt)
    if due:
        r_law = _law_command(b, tau, theta, dtheta, torque_s, phi_s, dphi_s)
    elif b[B_TMX + TMX_HASLAW] != 0.0:
        r_law = b[B_TMX + TMX_LAW]
    else:
        r_law = b[B_LP + LP_RFF]
    if b[B_TM + TM_LATENCY] <= 0.0:
        return due, r_law, r_law
    r_cmd = b[B_TMX + TMX_CMD] if b[B_TMX + TMX_HASCMD] != 0.0 else b[B_LP + LP_RFF]
    now = tau + _near(tau)
    for i in range(int(b[B_TMX + TMX_NP])):
        at = B_TMX + TMX_PEND + 2 * i
        if b[at] <= now:
            r_cmd = b[at + 1]
    return due, r_law, r_cmd


@inline
def _sample(b, tau, phi, dphi, theta, dtheta, top):
    """:func:`sample`'s numbers and (due, r_law, r_law_lim): whether the law computes at
    ``tau`` and its command before and after the drive's limits (the anti-windup's)."""
    phi_s, dphi_s, torque_s = sensed(b, tau, phi, dphi, theta, dtheta, top)
    if b[B_TM + TM_PERIOD] <= 0.0:
        r_cmd = _law_command(b, tau, theta, dtheta, torque_s, phi_s, dphi_s)
        r_lim, r_app, R = actuate(b, tau, r_cmd, dtheta)
        return r_app, r_cmd, r_lim, R, phi_s, dphi_s, torque_s, True, r_cmd, r_lim
    due, r_law, r_cmd = _timed(b, tau, theta, dtheta, torque_s, phi_s, dphi_s)
    r_lim, r_app, R = actuate(b, tau, r_cmd, dtheta)
    r_law_lim = r_lim
    if r_law != r_cmd:  # on its way: the limits the drive would put on it now
        r_law_lim = actuate(b, tau, r_law, dtheta)[0]
    return r_app, r_cmd, r_lim, R, phi_s, dphi_s, torque_s, due, r_law, r_law_lim


@inline
def sample(b, tau, phi, dphi, theta, dtheta, top):
    """(r_app, r_cmd, r_lim, R, phi_s, dphi_s, torque_s) at the sample instant ``tau``.

    ``phi, dphi, theta, dtheta`` are the plant's (scaled perturbations) and ``top`` the torque
    at the top of its string less R0 (theta - phi on the one-mode string); the law sees them
    through the sensing (``phi_s, dphi_s, torque_s``); ``r_cmd`` is the command R - R0 at the
    drive (the law's, or with a latency the one that has arrived), ``r_lim`` the command within
    the top drive's limits, ``r_app`` the torque applied (held over the sample) and ``R`` the
    applied absolute torque R/C.
    """
    out = _sample(b, tau, phi, dphi, theta, dtheta, top)
    return out[0], out[1], out[2], out[3], out[4], out[5], out[6]


@jit
def commit(b, tau, phi, dphi, theta, dtheta, top, Ts):
    """The sample ``tau`` (as :func:`sample`) and the controller's state at ``tau + Ts``.

    Returns the applied torque R - R0 of the sample.
    """
    out = _sample(b, tau, phi, dphi, theta, dtheta, top)
    r_app, r_cmd, r_lim, R, phi_s, dphi_s, torque_s, due, r_law, r_law_lim = out
    period = b[B_TM + TM_PERIOD]
    if due and _started(b, tau):
        if b[B_ACTIVE] != 0.0:
            x = law_state(b)
        else:
            x = law_start(b, theta, dtheta, torque_s, phi_s, dphi_s)
        dt = Ts if period <= 0.0 else period
        x = law_update(b, x, theta, dtheta, torque_s, phi_s, dphi_s, dt, r_law, r_law_lim)
        for i in range(4):
            b[B_LX + i] = x[i]
        b[B_ACTIVE] = 1.0
    if period > 0.0:
        _commit_timing(b, tau, due, r_law, period)
    if b[B_TD + TD_ON] != 0.0:
        b[B_TDX + TDX_R] = R
        b[B_TDX + TDX_T] = tau
        b[B_TDX + TDX_DT] = Ts
        b[B_TDX + TDX_INIT] = 1.0
    sense_commit(b, tau, phi, dphi, theta, dtheta, top, r_app, Ts)
    b[B_RCMD] = r_cmd
    b[B_RAPP] = r_app
    saturated = r_lim != r_cmd
    b[B_SAT] = 1.0 if saturated else 0.0
    if saturated:
        b[B_NSAT] += 1.0
    b[B_NSAMPLES] += 1.0
    return r_app


@inline
def _commit_timing(b, tau, due, r_law, period):
    """The timing's state after the sample ``tau``: the arrived commands taken off the queue,
    the law's new command held and put on it, the law's next computation."""
    m = B_TMX
    latency = b[B_TM + TM_LATENCY]
    if latency > 0.0:
        now = tau + _near(tau)
        n = int(b[m + TMX_NP])
        k = 0
        while k < n and b[m + TMX_PEND + 2 * k] <= now:
            b[m + TMX_CMD] = b[m + TMX_PEND + 2 * k + 1]
            b[m + TMX_HASCMD] = 1.0
            k += 1
        for i in range(n - k):
            b[m + TMX_PEND + 2 * i] = b[m + TMX_PEND + 2 * (i + k)]
            b[m + TMX_PEND + 2 * i + 1] = b[m + TMX_PEND + 2 * (i + k) + 1]
        b[m + TMX_NP] = n - k
    if due:
        b[m + TMX_LAW] = r_law
        b[m + TMX_HASLAW] = 1.0
        b[m + TMX_NEXT] = (math.floor(tau / period + 1e-9) + 1.0) * period
        if latency > 0.0:
            n = int(b[m + TMX_NP])
            b[m + TMX_PEND + 2 * n] = tau + latency
            b[m + TMX_PEND + 2 * n + 1] = r_law
            b[m + TMX_NP] = n + 1
        else:
            b[m + TMX_CMD] = r_law
            b[m + TMX_HASCMD] = 1.0


@inline
def _fmu_inputs(b, t):
    """(tau, phi, dphi, theta, dtheta) of the FMU's time ``t`` and inputs, scaled.

    SI: tau = t/t*, phi = Phi - Omega0 t, dphi = t* (dPhi/dt - Omega0), theta = Theta - Omega0 t
    - R0/C (the table angle leads the bit by the nominal twist R0/C), dtheta = t* (dTheta/dt -
    Omega0) (``drillstring.model.units``)."""
    a, v, c, w = b[B_IN], b[B_IN + 1], b[B_IN + 2], b[B_IN + 3]
    if b[B_SI] == 0.0:
        return t, a, v, c, w
    ts = b[B_TSTAR]
    W = b[B_OMEGA0_SI]
    return (
        t / ts,
        a - W * t,
        (v - W) * ts,
        c - W * t - b[B_R0_SI] / b[B_C],
        (w - W) * ts,
    )


@inline
def _fmu_torque(b, r):
    """The FMU's output of the applied torque deviation ``r``: R - R0, or R [N m] in SI."""
    if b[B_SI] == 0.0:
        return r
    return b[B_R0_SI] + b[B_C] * r


@jit
def fmu_output(b):
    """The FMU's output at its time and inputs, into ``OUT`` (pure)."""
    tau, phi, dphi, theta, dtheta = _fmu_inputs(b, b[B_TIME])
    # an FMU has the four angle and speed inputs: the one-mode string's twist
    r_app = sample(b, tau, phi, dphi, theta, dtheta, theta - phi)[0]
    b[B_OUT] = _fmu_torque(b, r_app)


@jit
def fmu_step(b, t, h):
    """The FMU's communication step from ``t`` by ``h`` (the FMU's units): commit the sample at
    ``t`` with its inputs and the period ``h``; the time becomes ``t + h``."""
    tau, phi, dphi, theta, dtheta = _fmu_inputs(b, t)
    Ts = h / b[B_TSTAR] if b[B_SI] != 0.0 else h
    commit(b, tau, phi, dphi, theta, dtheta, theta - phi, Ts)
    b[B_TIME] = t + h
