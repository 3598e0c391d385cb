"""The stepping engine: classical RK4 on the delay-Filippov system with located events.

Each step integrates the mode's smooth vector field; the delayed term U(tau - tau_n) comes from
the Hermite history (:mod:`.history`). Event functions of the current mode (V = 0 in slip or
upward motion, g* leaving [0, 1] in stick, W = 0, d = 0, release from torsional stick) are checked
at the step end; a sign change is located by regula falsi (Illinois) on the step fraction, each
trial being a genuine RK4 step from the step start, to a time tolerance ``O[O_EVTOL]``. The step
then ends at the event (on the far side of the switching surface), the mode changes and the event
instant becomes a history node. Steps never pass an event, a switch-on time or the target time.

This module is loaded twice: compiled (``drillstring.model.kernel.stepper``) and, for control
laws that are Python callables, as a plain-Python copy
(``drillstring.model.kernel._stepper_pure``), see :func:`drillstring.model.engine.load_stepper`.
``ext`` is None in the compiled copy.
"""

from __future__ import annotations

import math

import numpy as np

from drillstring.model.control import feedback_torque
from drillstring.model.kernel.equations import rhs
from drillstring.model.kernel.filippov import (
    contact,
    g_star,
    max_bit_torque,
    mode_at_zero_velocity,
    torque_on_bit,
)
from drillstring.model.kernel.hermite import append_node, compact, delay_lookup, next_discontinuity
from drillstring.model.kernel.jit import jit_for
from drillstring.model.kernel.layout import (
    C_ACTIVE,
    C_F0,
    C_K0,
    C_KIND,
    C_LATCH,
    C_PHIREF,
    C_R,
    C_RFF,
    C_TON,
    C_TWISTREF,
    CTRL_AFFINE,
    CTRL_EXTERNAL,
    CTRL_HELD,
    D_D,
    D_G,
    D_GSTAR,
    D_QG,
    D_R,
    D_S,
    D_SIZE,
    D_TAUN,
    D_TOB,
    E_FROM,
    E_GINT,
    E_GSTAR,
    E_KIND,
    E_TAU,
    E_TO,
    E_U,
    E_V,
    EV_BOUNCE,
    EV_BOUNCE_END,
    EV_MODE,
    EV_SWITCH_ON,
    EV_TSTICK_STOP,
    H_PHI,
    H_TAU,
    H_U,
    H_V,
    H_W,
    I_BOUNCING,
    I_ENUM,
    I_HEND,
    I_HSTART,
    I_KHINT,
    I_MODE,
    I_NBOUNCE,
    I_NEVENTS,
    I_NREJECT,
    I_NSTEPS,
    I_NSTICK,
    I_NTSTICK,
    I_STATUS,
    LATCH_ANGLE_TWIST,
    LATCH_NONE,
    MODE_SLIP,
    MODE_STICK,
    MODE_TSTICK,
    MODE_UP,
    O_CONTINUE,
    O_EVTOL,
    O_FREEZE,
    O_H,
    O_TSTICK,
    P_BLADE,
    P_OMEGA0,
    P_R0,
    P_V0,
    ST_BOUNCE,
    ST_DELAY,
    ST_EVLOG_FULL,
    ST_HIST_FULL,
    ST_NONFINITE,
    ST_OK,
    ST_REVERSE,
    ST_TSTICK_OUT,
    ST_ZENO,
    X_GINT,
    X_TAU,
)

jit = jit_for(__name__)

# event functions: each is positive before its event and crosses to <= 0 at it
EVF_V_DOWN = 0  # slip: V reaches 0 from above
EVF_V_UP = 1  # moving up: V reaches 0 from below
EVF_G_LOW = 2  # stick: g* falls below 0 -> slip down
EVF_G_HIGH = 3  # stick: g* exceeds 1 -> move up
EVF_W = 4  # W reaches 0: torsional stick (or out of the model)
EVF_BOUNCE = 5  # d reaches 0: bit bouncing starts
EVF_BOUNCE_END = 6  # d back above 0
EVF_RELEASE = 7  # torsional stick: twist torque exceeds T_max
EVF_REVERSE = 8  # torsional stick: twist torque below 0
N_EVF = 9
EVF_DELAY = 9  # the delayed instant tau - tau_n passes a stored discontinuity (not a mode event)

ZENO_LIMIT = 64


@jit
def control_torque(P, C, tau, Y, ext):
    """R - R0 at (tau, Y): held value, affine feedback (29)-(31) or an external callable."""
    kind = int(C[C_KIND])
    if kind == CTRL_HELD:
        return C[C_R]
    if kind == CTRL_EXTERNAL:
        if ext is not None:
            return ext(tau, Y)
        return np.nan
    w0 = P[P_OMEGA0]
    # activity follows the latch, not tau, so a step ending exactly at t_on stays inactive
    tau_eff = np.inf if C[C_ACTIVE] > 0.0 else -np.inf
    F = (C[C_F0], C[C_F0 + 1], C[C_F0 + 2], C[C_F0 + 3])
    return feedback_torque(
        tau_eff,
        Y[2] - w0 * tau,
        Y[3] - w0,
        Y[4] - w0 * tau,
        Y[5] - w0,
        F,
        C[C_K0],
        C[C_RFF],
        0.0,
        C[C_PHIREF],
        C[C_TWISTREF],
    )


@jit
def stage(P, O, C, H, I, mode, tau, Y, dY, Dout, ext):
    """One evaluation of the vector field with delay, depth of cut and contact; returns status."""
    k, s, u_past = delay_lookup(H, I[I_HSTART], I[I_HEND], I[I_KHINT], Y[2], P[P_BLADE])
    if k < 0:
        return ST_DELAY
    I[I_KHINT] = k
    d = Y[0] - u_past
    gs = g_star(P, tau, Y[0], d)
    g = contact(mode, gs)
    r = control_torque(P, C, tau, Y, ext)
    if not math.isfinite(r):
        return ST_NONFINITE
    rhs(P, O[O_FREEZE] > 0.0, mode, tau, Y, d, g, r, dY)
    twist = P[P_R0] + Y[4] - Y[2]
    Dout[D_D] = d
    Dout[D_TAUN] = tau - s
    Dout[D_G] = g
    Dout[D_GSTAR] = gs
    Dout[D_S] = twist
    Dout[D_TOB] = torque_on_bit(P, mode, d, g, twist)
    Dout[D_R] = r
    return ST_OK


@jit
def rk4(P, O, C, H, I, mode, tau, Y, h, Ynew, Dnew, K, Yt, ext):
    """Classical RK4 step of size h from (tau, Y); diagnostics at the end into Dnew."""
    st = stage(P, O, C, H, I, mode, tau, Y, K[0], Dnew, ext)
    if st != ST_OK:
        return st
    qg = Dnew[D_G]
    for i in range(6):
        Yt[i] = Y[i] + 0.5 * h * K[0, i]
    st = stage(P, O, C, H, I, mode, tau + 0.5 * h, Yt, K[1], Dnew, ext)
    if st != ST_OK:
        return st
    qg += 2.0 * Dnew[D_G]
    for i in range(6):
        Yt[i] = Y[i] + 0.5 * h * K[1, i]
    st = stage(P, O, C, H, I, mode, tau + 0.5 * h, Yt, K[2], Dnew, ext)
    if st != ST_OK:
        return st
    qg += 2.0 * Dnew[D_G]
    for i in range(6):
        Yt[i] = Y[i] + h * K[2, i]
    st = stage(P, O, C, H, I, mode, tau + h, Yt, K[3], Dnew, ext)
    if st != ST_OK:
        return st
    qg += Dnew[D_G]
    Dnew[D_QG] = h / 6.0 * qg
    for i in range(6):
        Ynew[i] = Y[i] + h / 6.0 * (K[0, i] + 2.0 * K[1, i] + 2.0 * K[2, i] + K[3, i])
        if not math.isfinite(Ynew[i]):
            return ST_NONFINITE
    # diagnostics (d, tau_n, g*) at the end state, for the event functions
    return stage(P, O, C, H, I, mode, tau + h, Ynew, K[4], Dnew, ext)


@jit
def event_active(ev, mode, O, I):
    """Whether event function ``ev`` is watched in ``mode``."""
    if ev == EVF_V_DOWN:
        return mode == MODE_SLIP
    if ev == EVF_V_UP:
        return mode == MODE_UP
    if ev == EVF_G_LOW or ev == EVF_G_HIGH:
        return mode == MODE_STICK
    if ev == EVF_W:
        return mode != MODE_TSTICK and O[O_FREEZE] == 0.0
    if ev == EVF_BOUNCE:
        return I[I_BOUNCING] == 0
    if ev == EVF_BOUNCE_END:
        return I[I_BOUNCING] == 1
    return mode == MODE_TSTICK


@jit
def event_value(ev, P, Y, D, t, tdisc):
    """Event function ``ev`` at time t, state Y, diagnostics D (positive before the event)."""
    if ev == EVF_DELAY:
        return tdisc - (t - D[D_TAUN])
    if ev == EVF_V_DOWN:
        return Y[1]
    if ev == EVF_V_UP:
        return -Y[1]
    if ev == EVF_G_LOW:
        return D[D_GSTAR]
    if ev == EVF_G_HIGH:
        return 1.0 - D[D_GSTAR]
    if ev == EVF_W:
        return Y[3]
    if ev == EVF_BOUNCE:
        return D[D_D]
    if ev == EVF_BOUNCE_END:
        return -D[D_D]
    if ev == EVF_RELEASE:
        return max_bit_torque(P, D[D_D]) - D[D_S]
    return D[D_S]


@jit
def locate(ev, P, O, C, H, I, mode, tau, Y, h, f0, f1, Yev, Dev, K, Yt, Ytr, Dtr, tdisc, ext):
    """Step fraction of the event (Illinois regula falsi); the far-side state into Yev, Dev."""
    lo = 0.0
    hi = 1.0
    flo = f0
    fhi = f1
    side = 0
    tol = O[O_EVTOL]
    for _ in range(200):
        if (hi - lo) * h <= tol:
            break
        if fhi != flo:
            th = hi - fhi * (hi - lo) / (fhi - flo)
        else:
            th = 0.5 * (lo + hi)
        margin = 1e-3 * (hi - lo)
        if not (th > lo + margin and th < hi - margin):
            th = 0.5 * (lo + hi)
        st = rk4(P, O, C, H, I, mode, tau, Y, th * h, Ytr, Dtr, K, Yt, ext)
        I[I_NREJECT] += 1
        if st != ST_OK:
            return -1.0
        f = event_value(ev, P, Ytr, Dtr, tau + th * h, tdisc)
        if f <= 0.0:
            hi = th
            fhi = f
            Yev[:] = Ytr
            Dev[:] = Dtr
            if side == -1:
                flo *= 0.5
            side = -1
            if f == 0.0:
                break
        else:
            lo = th
            flo = f
            if side == 1:
                fhi *= 0.5
            side = 1
    return hi


@jit
def log_event(E, I, X, P, Y, kind, frm, to, v, gs):
    n = I[I_ENUM]
    tau = X[X_TAU]
    E[n, E_GINT] = X[X_GINT]
    E[n, E_U] = Y[0] - P[P_V0] * tau
    E[n, E_TAU] = tau
    E[n, E_KIND] = kind
    E[n, E_FROM] = frm
    E[n, E_TO] = to
    E[n, E_V] = v
    E[n, E_GSTAR] = gs
    I[I_ENUM] = n + 1
    I[I_NEVENTS] += 1


@jit
def push_node(H, I, tau, Y, flag):
    """Append the accepted state as a history node; a torsional-stick stretch keeps two nodes."""
    start = I[I_HSTART]
    end = I[I_HEND]
    if I[0] == MODE_TSTICK and end - start >= 2:
        a = end - 1
        b = end - 2
        if (
            H[H_U, a] == Y[0]
            and H[H_U, b] == Y[0]
            and H[H_PHI, a] == Y[2]
            and H[H_PHI, b] == Y[2]
            and H[H_V, a] == 0.0
            and H[H_W, a] == 0.0
            and H[H_V, b] == 0.0
            and H[H_W, b] == 0.0
            and Y[1] == 0.0
            and Y[3] == 0.0
        ):
            H[H_TAU, a] = tau
            return
    I[I_HEND] = append_node(H, end, tau, Y[0], Y[1], Y[2], Y[3], flag)
    # nodes before the current delay interval can never be reached again (Phi non-decreasing)
    keep = I[I_KHINT] - 2
    if keep > start:
        I[I_HSTART] = keep


@jit
def refresh(P, O, C, X, Y, I, H, D, K, ext):
    """Recompute the diagnostics D at the current state (after a mode change or new input)."""
    return stage(P, O, C, H, I, I[I_MODE], X[X_TAU], Y, K[4], D, ext)


@jit
def apply_event(ev, P, O, C, X, Y, I, H, D, E, K, ext):
    """Mode change at a located event (state already at the event); returns a status."""
    mode = I[I_MODE]
    v_event = Y[1]
    gs = D[D_GSTAR]
    if ev == EVF_V_DOWN or ev == EVF_V_UP:
        Y[1] = 0.0
        new = mode_at_zero_velocity(gs)
        if new == MODE_STICK:
            I[I_NSTICK] += 1
        I[I_MODE] = new
        log_event(E, I, X, P, Y, EV_MODE, mode, new, v_event, gs)
    elif ev == EVF_G_LOW:
        I[I_MODE] = MODE_SLIP
        log_event(E, I, X, P, Y, EV_MODE, mode, MODE_SLIP, v_event, gs)
    elif ev == EVF_G_HIGH:
        I[I_MODE] = MODE_UP
        log_event(E, I, X, P, Y, EV_MODE, mode, MODE_UP, v_event, gs)
    elif ev == EVF_W:
        if O[O_TSTICK] == 0.0:
            log_event(E, I, X, P, Y, EV_TSTICK_STOP, mode, mode, v_event, gs)
            return ST_TSTICK_OUT
        if D[D_S] < 0.0:
            return ST_REVERSE
        Y[3] = 0.0
        Y[1] = 0.0  # rock is not penetrated without rotation (NOTES.md section 6)
        I[I_MODE] = MODE_TSTICK
        I[I_NTSTICK] += 1
        log_event(E, I, X, P, Y, EV_MODE, mode, MODE_TSTICK, v_event, gs)
    elif ev == EVF_RELEASE:
        Y[1] = 0.0
        Y[3] = 0.0
        new = mode_at_zero_velocity(gs)
        if new == MODE_STICK:
            I[I_NSTICK] += 1
        I[I_MODE] = new
        log_event(E, I, X, P, Y, EV_MODE, mode, new, v_event, gs)
    elif ev == EVF_REVERSE:
        return ST_REVERSE
    elif ev == EVF_BOUNCE:
        I[I_NBOUNCE] += 1
        log_event(E, I, X, P, Y, EV_BOUNCE, mode, mode, v_event, gs)
        if O[O_CONTINUE] == 0.0:
            return ST_BOUNCE
        I[I_BOUNCING] = 1
    else:
        I[I_BOUNCING] = 0
        log_event(E, I, X, P, Y, EV_BOUNCE_END, mode, mode, v_event, gs)
    return refresh(P, O, C, X, Y, I, H, D, K, ext)


@jit
def step(P, O, C, X, Y, I, H, D, E, K, W, h, t_end, ext):
    """One step to t_end = tau + h, or to the first event inside it; returns a status."""
    tau = X[X_TAU]
    mode = I[I_MODE]
    Ynew = W[0, :6]
    Yt = W[1, :6]
    Yev = W[2, :6]
    Ytr = W[3, :6]
    Ybest = W[4, :6]
    Dnew = W[5, :D_SIZE]
    Dev = W[6, :D_SIZE]
    Dtr = W[7, :D_SIZE]
    Dbest = W[8, :D_SIZE]
    st = rk4(P, O, C, H, I, mode, tau, Y, h, Ynew, Dnew, K, Yt, ext)
    if st != ST_OK:
        return st
    best = 2.0
    best_ev = -1
    for ev in range(N_EVF):
        if not event_active(ev, mode, O, I):
            continue
        f1 = event_value(ev, P, Ynew, Dnew, t_end, 0.0)
        f0 = event_value(ev, P, Y, D, tau, 0.0)
        if f1 < 0.0 or (f1 == 0.0 and f0 > 0.0):
            Yev[:] = Ynew
            Dev[:] = Dnew
            th = locate(
                ev, P, O, C, H, I, mode, tau, Y, h, f0, f1, Yev, Dev, K, Yt, Ytr, Dtr, 0.0, ext
            )
            if th < 0.0:
                return ST_DELAY
            if th < best:
                best = th
                best_ev = ev
                Ybest[:] = Yev
                Dbest[:] = Dev
    # a stored discontinuity passed by the delayed instant ends the step there (order of RK4)
    s0 = tau - D[D_TAUN]
    s1 = t_end - Dnew[D_TAUN]
    tdisc = next_discontinuity(H, I[I_HSTART], I[I_HEND], I[I_KHINT], s0, s1)
    if tdisc > s0:
        f0 = tdisc - s0
        f1 = tdisc - s1
        if f1 < 0.0:
            Yev[:] = Ynew
            Dev[:] = Dnew
            th = locate(
                EVF_DELAY,
                P,
                O,
                C,
                H,
                I,
                mode,
                tau,
                Y,
                h,
                f0,
                f1,
                Yev,
                Dev,
                K,
                Yt,
                Ytr,
                Dtr,
                tdisc,
                ext,
            )
            if th < 0.0:
                return ST_DELAY
            if th < best:
                best = th
                best_ev = EVF_DELAY
                Ybest[:] = Yev
                Dbest[:] = Dev
    I[I_NSTEPS] += 1
    if best_ev < 0:
        Y[:] = Ynew
        D[:] = Dnew
        X[X_GINT] += Dnew[D_QG]
        X[X_TAU] = t_end
        push_node(H, I, t_end, Y, 0.0)
        return ST_OK
    Y[:] = Ybest
    D[:] = Dbest
    X[X_GINT] += Dbest[D_QG]
    X[X_TAU] = t_end if best == 1.0 else tau + best * h
    if best_ev == EVF_DELAY:
        push_node(H, I, X[X_TAU], Y, 0.0)
        return ST_OK
    st = apply_event(best_ev, P, O, C, X, Y, I, H, D, E, K, ext)
    push_node(H, I, X[X_TAU], Y, 1.0)
    return st


@jit
def switch_on(P, C, X, Y, I, D, E):
    """Activate the feedback at t_on, latching the references for a bumpless start."""
    tau = X[X_TAU]
    w0 = P[P_OMEGA0]
    latch = int(C[C_LATCH])
    if latch != LATCH_NONE:
        C[C_PHIREF] = Y[2] - w0 * tau
    if latch == LATCH_ANGLE_TWIST:
        C[C_TWISTREF] = (Y[2] - Y[4]) - C[C_K0]
    C[C_ACTIVE] = 1.0
    log_event(E, I, X, P, Y, EV_SWITCH_ON, I[I_MODE], I[I_MODE], Y[1], D[D_GSTAR])


@jit
def advance(P, O, C, X, Y, I, H, D, E, K, W, to_tau, ext):
    """Integrate to ``to_tau`` (steps partition the interval evenly); returns a status.

    Returns early with ST_EVLOG_FULL / ST_HIST_FULL when a buffer must be drained or grown by
    the caller, and with the model's status codes when the run must stop.
    """
    h_nom = O[O_H]
    zeno = 0
    while True:
        tau = X[X_TAU]
        if tau >= to_tau:
            I[I_STATUS] = ST_OK
            return ST_OK
        if int(C[C_KIND]) == CTRL_AFFINE and C[C_ACTIVE] == 0.0 and tau >= C[C_TON]:
            if I[I_ENUM] >= E.shape[0]:
                return ST_EVLOG_FULL
            switch_on(P, C, X, Y, I, D, E)
            st = refresh(P, O, C, X, Y, I, H, D, K, ext)
            if st != ST_OK:
                I[I_STATUS] = st
                return st
        if I[I_ENUM] + 4 >= E.shape[0]:
            return ST_EVLOG_FULL
        if I[I_HEND] >= H.shape[1]:
            if I[I_HSTART] > 0:
                I[I_HEND] = compact(H, I[I_HSTART], I[I_HEND])
                I[I_KHINT] -= I[I_HSTART]
                I[I_HSTART] = 0
            else:
                return ST_HIST_FULL
        remaining = to_tau - tau
        n = int(math.ceil(remaining / h_nom - 1e-9))
        if n < 1:
            n = 1
        h = remaining / n
        t_end = to_tau if n == 1 else tau + h
        if int(C[C_KIND]) == CTRL_AFFINE and C[C_ACTIVE] == 0.0 and tau < C[C_TON] < t_end:
            t_end = C[C_TON]
            h = t_end - tau
        st = step(P, O, C, X, Y, I, H, D, E, K, W, h, t_end, ext)
        if st != ST_OK:
            I[I_STATUS] = st
            return st
        if X[X_TAU] - tau < 1e-13:
            zeno += 1
            if zeno > ZENO_LIMIT:
                I[I_STATUS] = ST_ZENO
                return ST_ZENO
        else:
            zeno = 0
