"""The digital controller, compiled: one sample of sensing, law and top drive on the block.

Two functions carry every host (the controller FMUs, natively and on their Python path; the
compiled sampled loop; a Python caller):

* :func:`sample` -- what the controller puts out at a sample instant for the true plant
  measurements (pure: calling it twice gives the same numbers, as an FMU's output getter must);
* :func:`commit` -- the same sample, then the state one period later: the law's update, the
  top drive's torque, the sensing (telemetry frames, observer, torque estimate), diagnostics.

The controller's own timing (``docs/controllers.md``, "Timing of a real drive";
:mod:`drillstring.model.timing`): with a period P > 0 the law computes at the first sample at or
after each multiple of P, its state advanced by P, its command held until its next computation;
with a latency L that command reaches the drive at the first sample at or after its computation
+ L, until then the drive keeps the command that arrived before (the feed-forward R_ff before
the first). The sensing and the top drive act at every sample of the host. P = 0 is the law at
every sample of the host, the code of before.

The switch-on (``docs/model.md``, "Bumpless switch-on"): before ``t_on``, or with the controller
disabled, only the law's feed-forward R_ff acts; at the first sample at or after ``t_on`` the
law starts from the measurements there. :func:`fmu_output` and :func:`fmu_step` are the same two
functions on an FMU's connectors (``inputs``, ``output``, ``time`` of the block), in the FMU's
unit system (``si``: the SI connectors converted with the rig scales of the block, eqs.
(15)-(16)).

Each part's compiled code runs on its section of the block (:mod:`drillstring.model.laws`,
:mod:`drillstring.model.topdrive`, :mod:`drillstring.model.sensing`,
:mod:`drillstring.model.timing`); each takes the block and the offset of the part's section
in it (:data:`~drillstring.model.digital.layout.BLOCK`).
"""

from __future__ import annotations

from drillstring.model.digital.layout import BLOCK
from drillstring.model.kernel.jit import jit_for
from drillstring.model.laws import (
    feed_forward,
    law_keep,
    law_output,
    law_start,
    law_state,
    law_update,
)
from drillstring.model.sensing import sense_commit, sensed
from drillstring.model.timing import TIMING_SLOTS, at_drive, held_command, law_due, timing_commit
from drillstring.model.topdrive import actuate, drive_commit

jit = jit_for(__name__)
inline = jit_for(__name__, inline=True)

__all__ = ["commit", "fmu_output", "fmu_step", "sample"]


@inline
def _started(b, tau):
    """True when the law acts at ``tau``: enabled, and started or due to start."""
    return b[BLOCK.enabled] != 0.0 and (b[BLOCK.active] != 0.0 or tau >= b[BLOCK.t_on])


@inline
def _law_command(b, tau, theta, dtheta, torque_s, phi_s, dphi_s):
    """The law's command R - R0 at ``tau`` (the feed-forward alone before it has started)."""
    w = BLOCK.law
    if _started(b, tau):
        if b[BLOCK.active] != 0.0:
            x = law_state(b, w)
        else:
            x = law_start(b, w, theta, dtheta, torque_s, phi_s, dphi_s)
        return law_output(b, w, x, theta, dtheta, torque_s, phi_s, dphi_s)
    return feed_forward(b, w)


@inline
def _timed(b, tau, theta, dtheta, torque_s, phi_s, dphi_s):
    """With the controller's own period: (due, r_law, r_cmd), whether the law computes at
    ``tau``, its command (computed now or held), and the command at the drive."""
    m = BLOCK.timing
    r_ff = feed_forward(b, BLOCK.law)
    due = law_due(b, m, tau)
    if due:
        r_law = _law_command(b, tau, theta, dtheta, torque_s, phi_s, dphi_s)
    else:
        r_law = held_command(b, m, r_ff)
    return due, r_law, at_drive(b, m, tau, r_law, r_ff)


# compiled once, not inlined into its two callers: numba's IR inlining of this much took 30 s of
# the controller's first compilation (see drillstring.model.kernel.stepper's step); one call
# per sample
@jit
def _sample(b, tau, phi, dphi, theta, dtheta, top):
    """:func:`sample`'s numbers and (due, r_law, r_law_lim): whether the law computes at
    ``tau`` and its command before and after the drive's limits (the anti-windup's)."""
    phi_s, dphi_s, torque_s = sensed(b, BLOCK.sensing, b[BLOCK.rho], tau, phi, dphi, theta,
                                     dtheta, top)  # fmt: skip
    d = BLOCK.top_drive
    omega0, R0 = b[BLOCK.omega0], b[BLOCK.R0]
    if b[BLOCK.timing + TIMING_SLOTS.period] <= 0.0:
        r_cmd = _law_command(b, tau, theta, dtheta, torque_s, phi_s, dphi_s)
        r_lim, r_app, R = actuate(b, d, omega0, R0, r_cmd, dtheta)
        return r_app, r_cmd, r_lim, R, phi_s, dphi_s, torque_s, True, r_cmd, r_lim
    due, r_law, r_cmd = _timed(b, tau, theta, dtheta, torque_s, phi_s, dphi_s)
    r_lim, r_app, R = actuate(b, d, omega0, R0, r_cmd, dtheta)
    r_law_lim = r_lim
    if r_law != r_cmd:  # on its way: the limits the drive would put on it now
        r_law_lim = actuate(b, d, omega0, R0, r_law, dtheta)[0]
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
    w = BLOCK.law
    period = b[BLOCK.timing + TIMING_SLOTS.period]
    if due and _started(b, tau):
        if b[BLOCK.active] != 0.0:
            x = law_state(b, w)
        else:
            x = law_start(b, w, theta, dtheta, torque_s, phi_s, dphi_s)
        dt = Ts if period <= 0.0 else period
        x = law_update(b, w, x, theta, dtheta, torque_s, phi_s, dphi_s, dt, r_law, r_law_lim)
        law_keep(b, w, x)
        b[BLOCK.active] = 1.0
    if period > 0.0:
        timing_commit(b, BLOCK.timing, tau, due, r_law)
    drive_commit(b, BLOCK.top_drive, tau, R, Ts)
    sense_commit(b, BLOCK.sensing, b[BLOCK.rho], tau, phi, dphi, theta, dtheta, top, r_app, Ts)
    b[BLOCK.r_cmd] = r_cmd
    b[BLOCK.r_app] = r_app
    saturated = r_lim != r_cmd
    b[BLOCK.saturated] = 1.0 if saturated else 0.0
    if saturated:
        b[BLOCK.n_sat] += 1.0
    b[BLOCK.n_samples] += 1.0
    return r_app


@inline
def _fmu_inputs(b, t):
    """(tau, phi, dphi, theta, dtheta) of the FMU's time ``t`` and inputs, scaled.

    SI: tau = t/t*, phi = Phi - Omega0 t, dphi = t* (dPhi/dt - Omega0), theta = Theta - Omega0 t
    - R0/C (the table angle leads the bit by the nominal twist R0/C), dtheta = t* (dTheta/dt -
    Omega0) (``drillstring.model.units``)."""
    i = BLOCK.inputs
    a, v, c, w = b[i], b[i + 1], b[i + 2], b[i + 3]
    if b[BLOCK.si] == 0.0:
        return t, a, v, c, w
    ts = b[BLOCK.t_star]
    W = b[BLOCK.omega0_si]
    return (
        t / ts,
        a - W * t,
        (v - W) * ts,
        c - W * t - b[BLOCK.R0_si] / b[BLOCK.C],
        (w - W) * ts,
    )


@inline
def _fmu_torque(b, r):
    """The FMU's output of the applied torque deviation ``r``: R - R0, or R [N m] in SI."""
    if b[BLOCK.si] == 0.0:
        return r
    return b[BLOCK.R0_si] + b[BLOCK.C] * r


@jit
def fmu_output(b):
    """The FMU's output at its time and inputs, into ``output`` (pure)."""
    tau, phi, dphi, theta, dtheta = _fmu_inputs(b, b[BLOCK.time])
    # an FMU has the four angle and speed inputs: the one-mode string's twist
    r_app = sample(b, tau, phi, dphi, theta, dtheta, theta - phi)[0]
    b[BLOCK.output] = _fmu_torque(b, r_app)


@jit
def fmu_step(b, t, h):
    """The FMU's communication step from ``t`` by ``h`` (the FMU's units): commit the sample at
    ``t`` with its inputs and the period ``h``; the time becomes ``t + h``."""
    tau, phi, dphi, theta, dtheta = _fmu_inputs(b, t)
    Ts = h / b[BLOCK.t_star] if b[BLOCK.si] != 0.0 else h
    commit(b, tau, phi, dphi, theta, dtheta, theta - phi, Ts)
    b[BLOCK.time] = t + h
