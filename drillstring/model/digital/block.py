"""The digital controller, compiled: one sample of sensing, law and top drive on the block.

Two functions carry every host (the controller FMUs, natively and on their Python path; the
compiled sampled loop; a Python caller):

* :func:`sample` -- what the controller puts out at a sample instant for the true plant
  measurements (pure: calling it twice gives the same numbers, as an FMU's output getter must);
* :func:`commit` -- the same sample, then the state one period later: the law's update, the
  top drive's torque, the sensing (telemetry frames, observer, torque estimate), diagnostics.

The switch-on (``docs/model.md``, "Bumpless switch-on"): before ``t_on``, or with the controller
disabled, only the law's feed-forward R_ff acts; at the first sample at or after ``t_on`` the
law starts from the measurements there. :func:`fmu_output` and :func:`fmu_step` are the same two
functions on an FMU's connectors (``IN``, ``OUT``, ``TIME`` of the block), in the FMU's unit
system (``SI``: the SI connectors converted with the rig scales of the block, eqs. (15)-(16)).
"""

from __future__ import annotations

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
    B_TON,
    B_TSTAR,
    LP_RFF,
    TD_ON,
    TDX_DT,
    TDX_INIT,
    TDX_R,
    TDX_T,
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
def sample(b, tau, phi, dphi, theta, dtheta, top):
    """(r_app, r_cmd, r_lim, R, phi_s, dphi_s, torque_s) at the sample instant ``tau``.

    ``phi, dphi, theta, dtheta`` are the plant's (scaled perturbations) and ``top`` the torque
    at the top of its string less R0 (theta - phi on the one-mode string); the law sees them
    through the sensing (``phi_s, dphi_s, torque_s``); ``r_cmd`` is its command R - R0,
    ``r_lim`` the command within the top drive's limits, ``r_app`` the torque applied (held
    over the sample) and ``R`` the applied absolute torque R/C.
    """
    phi_s, dphi_s, torque_s = sensed(b, tau, phi, dphi, theta, dtheta, top)
    if _started(b, tau):
        if b[B_ACTIVE] != 0.0:
            x = law_state(b)
        else:
            x = law_start(b, theta, dtheta, torque_s, phi_s, dphi_s)
        r_cmd = law_output(b, x, theta, dtheta, torque_s, phi_s, dphi_s)
    else:
        r_cmd = b[B_LP + LP_RFF]
    r_lim, r_app, R = actuate(b, tau, r_cmd, dtheta)
    return r_app, r_cmd, r_lim, R, phi_s, dphi_s, torque_s


@jit
def commit(b, tau, phi, dphi, theta, dtheta, top, Ts):
    """The sample ``tau`` (as :func:`sample`) and the controller's state at ``tau + Ts``.

    Returns the applied torque R - R0 of the sample.
    """
    r_app, r_cmd, r_lim, R, phi_s, dphi_s, torque_s = sample(b, tau, phi, dphi, theta, dtheta, top)
    if _started(b, tau):
        if b[B_ACTIVE] != 0.0:
            x = law_state(b)
        else:
            x = law_start(b, theta, dtheta, torque_s, phi_s, dphi_s)
        x = law_update(b, x, theta, dtheta, torque_s, phi_s, dphi_s, Ts, r_cmd, r_lim)
        for i in range(4):
            b[B_LX + i] = x[i]
        b[B_ACTIVE] = 1.0
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
