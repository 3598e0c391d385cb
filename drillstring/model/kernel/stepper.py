"""The stepping engine: classical RK4 on the delay-Filippov system with located events.

One step (:func:`step`) integrates the current mode's smooth vector field (:func:`rk4`, whose
stages evaluate :func:`stage`: delay look-up in the Hermite history, depth of cut, contact
multiplier, torque, right-hand side). The candidates for the end of the step watched in the
mode (the event functions and the delayed discontinuity: one table in :mod:`.events`) are
compared at both ends of the step; a sign change is located by regula falsi (Illinois) on the
step fraction, each trial being a genuine RK4 step from the step start (:func:`attempt`). The
step then ends at the earliest event, on the far side of the switching surface; at a mode event
the mode changes (:func:`.events.apply_event`), and the event instant becomes a history node.
Steps never pass an event, a switch-on time or the target time; :func:`advance` splits an
interval into equal steps no longer than the nominal h.

The derivative at the current state (``stages[K_NOW]``) and the diagnostics (``diag``) are kept
up to date, so a step costs four right-hand sides: the end state's evaluation, needed for the
event functions, is the next step's first stage.

This module is loaded twice: compiled (``drillstring.model.kernel.stepper``) and, for control
laws that are Python callables, as a plain-Python copy (``drillstring.model.kernel._stepper_pure``,
see :func:`drillstring.model.engine.load_stepper`); ``ext`` is None in the compiled copy and is
called as ``ext(tau, U, V, Phi, W, Theta, Wt)`` in the plain one.
"""

from __future__ import annotations

import math

import numpy as np

from drillstring.model.control import feedback_torque, switch_on_references
from drillstring.model.kernel.coordinates import to_perturbation
from drillstring.model.kernel.equations import chain_rhs, rhs
from drillstring.model.kernel.events import (
    EVF_DELAY,
    N_CANDIDATES,
    apply_event,
    event_value,
    inside,
    log_event,
    watched,
)
from drillstring.model.kernel.filippov import (
    contact,
    g_star,
    max_bit_torque,
    torque_on_bit,
    twist_torque,
)
from drillstring.model.kernel.hermite import compact, delay_lookup, next_discontinuity, push_node
from drillstring.model.kernel.jit import jit_for
from drillstring.model.kernel.state import (
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
    D_SIZE,
    D_TAUN,
    EV_SWITCH_ON,
    I_BOUNCING,
    I_ENUM,
    I_HEND,
    I_HSTART,
    I_KHINT,
    I_MODE,
    I_NBOUNCE,
    I_NLOCATE,
    I_NSTEPS,
    I_NTRIALS,
    I_STATUS,
    K_NOW,
    O_EVTOL,
    O_FREEZE,
    O_H,
    OUT_D,
    OUT_DPHI,
    OUT_DTHETA,
    OUT_DU,
    OUT_G,
    OUT_MODE,
    OUT_PHI,
    OUT_R,
    OUT_TAU,
    OUT_TAUN,
    OUT_THETA,
    OUT_TOP,
    OUT_U,
    P_BLADE,
    P_KT,
    P_NA,
    P_NT,
    P_OMEGA0,
    P_V0,
    ST_DELAY,
    ST_EVLOG_FULL,
    ST_HIST_FULL,
    ST_NONFINITE,
    ST_OK,
    ST_ZENO,
    X_GINT,
    X_TAU,
    Y_PHI,
    Y_SIZE,
    Y_THETA,
    Y_U,
    Y_V,
    Y_W,
    Y_WT,
    Z_ACC,
    Z_BEST,
    Z_END,
    Z_KNOW,
    Z_KSTAGE,
    Z_NOW,
    Z_STAGE,
    Z_TRIAL1,
    Z_TRIAL2,
    KernelState,
)

jit = jit_for(__name__)
inline = jit_for(__name__, inline=True)

#: RK4 tableau: stage nodes c, stage coefficients a (stage i+1 from stage i) and weights b*6.
RK_C = (0.5, 0.5, 1.0)
RK_A = (0.5, 0.5, 1.0)
RK_B6 = (1.0, 2.0, 2.0, 1.0)

#: Trials allowed to locate one event (a few are needed; the bound only guards a stalled search).
MAX_TRIALS = 100
#: Steps in a row that do not advance time before the run is stopped as Zeno behaviour.
ZENO_LIMIT = 64

# The hot path (stage, rk4, attempt) works on tuples: the parameters and the control law as
# tuples of floats (indexed like the arrays, ``P[P_ETA]``), the state, its derivative and its
# diagnostics as tuples; the history is its only array. Passing arrays between compiled
# functions costs reference counting, which cost more than the arithmetic. What travels
# together is one tuple:
#
# * ``ctx = (P, C, H, hs, he, mode, frozen, Z)``, what the vector field reads besides time and
#   state, fixed during a step: parameters, control law, history and its live window, contact
#   mode, frozen torsion, and the string's inner nodes (the chain array: rows ``Z_*``);
# * ``start = (tau, y, dy/dtau, diagnostics)``, the state a step starts from (its inner nodes
#   in the chain's rows Z_NOW and Z_KNOW);
# * a far side ``(y, dy/dtau, diagnostics, zrow)``, the state that ends a step, its inner nodes
#   in chain row ``zrow`` and their derivative in row ``zrow + 1``.
#
# Besides them: ``hint``, the history look-up's search start, which every evaluation updates,
# and ``ext``, the control law as a Python callable (None when compiled: numba prunes the call
# of a None argument, not of a tuple's entry).


@jit
def as_tuple_23(a):
    """The 23 entries of ``a`` as a tuple (the parameter array, ``P_SIZE``)."""
    return (
        a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9], a[10], a[11], a[12], a[13],
        a[14], a[15], a[16], a[17], a[18], a[19], a[20], a[21], a[22]
    )  # fmt: skip


@jit
def as_tuple_13(a):
    """The 13 entries of ``a`` as a tuple (the control array, ``C_SIZE``)."""
    return (
        a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9], a[10], a[11], a[12]
    )  # fmt: skip


@inline
def as_tuple_6(a):
    """The 6 entries of ``a`` (a state or a derivative) as a tuple."""
    return a[0], a[1], a[2], a[3], a[4], a[5]


@inline
def row_tuple_6(a, r):
    """The 6 entries of row ``r`` of ``a`` as a tuple (no view of the row is made)."""
    return a[r, 0], a[r, 1], a[r, 2], a[r, 3], a[r, 4], a[r, 5]


@inline
def as_tuple_9(a):
    """The 9 entries of ``a`` (diagnostics, ``D_SIZE``) as a tuple."""
    return a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8]


@inline
def axpy6(y, a, k):
    """y + a*k for 6-tuples (the RK stage update, written once)."""
    return (
        y[0] + a * k[0],
        y[1] + a * k[1],
        y[2] + a * k[2],
        y[3] + a * k[3],
        y[4] + a * k[4],
        y[5] + a * k[5],
    )


@inline
def control_torque(P, C, tau, U, V, Phi, W, Theta, Wt, ext):
    """R - R0 at (tau, Y): held value, affine feedback (29)-(31) or an external callable."""
    kind = int(C[C_KIND])
    if kind == CTRL_HELD:
        return C[C_R]
    if kind == CTRL_EXTERNAL:
        if ext is not None:
            return ext(tau, U, V, Phi, W, Theta, Wt)
        return np.nan
    # activity follows the latch, not tau, so a step ending exactly at t_on stays inactive
    tau_eff = np.inf if C[C_ACTIVE] > 0.0 else -np.inf
    _, _, phi, dphi, theta, dtheta = to_perturbation(P, tau, U, V, Phi, W, Theta, Wt)
    F = (C[C_F0], C[C_F0 + 1], C[C_F0 + 2], C[C_F0 + 3])
    return feedback_torque(
        tau_eff, phi, dphi, theta, dtheta, F, C[C_K0], C[C_RFF], 0.0, C[C_PHIREF], C[C_TWISTREF]
    )


@inline
def stage(ctx, hint, tau, y, zin, zout, ext):
    """One evaluation of the vector field at (tau, y): delay, depth of cut, contact, torque.

    The string's inner nodes are read from chain row ``zin``, their derivative written to row
    ``zout``. Returns (status, hint, dy/dtau, d, tau_n, g, g*, R - R0, S).
    """
    P, C, H, hs, he, mode, frozen, Z = ctx
    U, V, Phi, W, Theta, Wt = y
    nt = int(P[P_NT])
    na = int(P[P_NA])
    bit_nb = Theta if nt == 0 else Z[zin, nt - 1]
    table_nb = Phi if nt == 0 else Z[zin, 0]
    hook_side = P[P_V0] * tau if na == 0 else Z[zin, 2 * nt + na - 1]
    k, s, u_past = delay_lookup(H, hs, he, hint, Phi, P[P_BLADE])
    if k < 0:
        return ST_DELAY, hint, _ZERO6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    d = U - u_past
    gs = g_star(P, U, d, hook_side)
    g = contact(mode, gs)
    r = control_torque(P, C, tau, U, V, Phi, W, Theta, Wt, ext)
    S = twist_torque(P, Phi, bit_nb)
    if not math.isfinite(r):
        return ST_NONFINITE, k, _ZERO6, d, tau - s, g, gs, r, S
    dy = rhs(P, frozen, mode, tau, U, V, Phi, W, Theta, Wt, d, g, r, bit_nb, table_nb, hook_side)
    chain_rhs(P, frozen, tau, Z, zin, zout, Phi, Theta, U)
    return ST_OK, k, dy, d, tau - s, g, gs, r, S


@inline
def diagnostics(P, mode, d, taun, g, gs, r, qg, S):
    """The diagnostics of a state as a tuple in the order of the ``D_*`` columns."""
    return d, taun, g, gs, S, torque_on_bit(P, mode, d, g, S), r, qg, max_bit_torque(P, d) - S


@inline
def copy_rows(Z, src, dst):
    """Chain rows ``src`` (a state) and ``src + 1`` (its derivative) into ``dst``, ``dst + 1``."""
    for j in range(Z.shape[1]):
        Z[dst, j] = Z[src, j]
        Z[dst + 1, j] = Z[src + 1, j]


#: A zero derivative and empty diagnostics, returned with a failed stage or trial.
_ZERO6 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
_ZERO9 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@inline
def rk4(ctx, hint, start, h, out, ext):
    """Classical RK4 step of size h from ``start`` = (tau, y0, dy/dtau, diagnostics).

    Returns (status, hint, y, dy/dtau, diagnostics) of the end state, whose inner nodes of the
    string go to chain row ``out`` (their derivative to ``out + 1``); the diagnostics'
    ``D_QG`` is the RK4 quadrature of g over the step. The end state's derivative serves the
    event functions and, when the step is accepted, as the next step's first stage.
    """
    P = ctx[0]
    mode = ctx[5]
    Z = ctx[7]
    m = Z.shape[1]
    tau, y0, k0, d0 = start
    k = k0
    acc = k0
    qg = d0[D_G]
    kz = Z_KNOW
    for j in range(m):
        Z[Z_ACC, j] = Z[Z_KNOW, j]
    for i in range(3):
        yt = axpy6(y0, RK_A[i] * h, k)
        a = RK_A[i] * h
        for j in range(m):
            Z[Z_STAGE, j] = Z[Z_NOW, j] + a * Z[kz, j]
        st, hint, k, d, taun, g, gs, r, S = stage(
            ctx, hint, tau + RK_C[i] * h, yt, Z_STAGE, Z_KSTAGE, ext
        )
        if st != ST_OK:
            return st, hint, y0, _ZERO6, _ZERO9
        kz = Z_KSTAGE
        acc = axpy6(acc, RK_B6[i + 1], k)
        b = RK_B6[i + 1]
        for j in range(m):
            Z[Z_ACC, j] = Z[Z_ACC, j] + b * Z[Z_KSTAGE, j]
        qg += RK_B6[i + 1] * g
    yn = axpy6(y0, h / 6.0, acc)
    for j in range(Y_SIZE):
        if not math.isfinite(yn[j]):
            return ST_NONFINITE, hint, y0, _ZERO6, _ZERO9
    for j in range(m):
        z = Z[Z_NOW, j] + h / 6.0 * Z[Z_ACC, j]
        if not math.isfinite(z):
            return ST_NONFINITE, hint, y0, _ZERO6, _ZERO9
        Z[out, j] = z
    st, hint, k, d, taun, g, gs, r, S = stage(ctx, hint, tau + h, yn, out, out + 1, ext)
    if st != ST_OK:
        return st, hint, y0, _ZERO6, _ZERO9
    return ST_OK, hint, yn, k, diagnostics(P, mode, d, taun, g, gs, r, h / 6.0 * qg, S)


@inline
def trial_fraction(lo, hi, flo, fhi, half):
    """The step fraction of the next trial locating an event in the bracket [lo, hi] (the
    candidate's function f(lo) = flo > 0 >= f(hi) = fhi): regula falsi, bisection where it
    leaves the bracket, and half a tolerance (``half``, as a step fraction) inside an end it
    comes nearer than that to, which closes the bracket from the other side (see
    :func:`attempt`)."""
    if fhi != flo:
        th = hi - fhi * (hi - lo) / (fhi - flo)
    else:
        th = 0.5 * (lo + hi)
    if not (lo < th < hi):
        th = 0.5 * (lo + hi)
    if th - lo < half:
        th = lo + half
    elif hi - th < half:
        th = hi - half
    return th


@inline
def store(Y: np.ndarray, K: np.ndarray, D: np.ndarray, y, k, dg) -> None:
    """Make (y, dy/dtau, diagnostics) the current state (arrays ``y``, ``stages``, ``diag``)."""
    for j in range(Y_SIZE):
        Y[j] = y[j]
        K[K_NOW, j] = k[j]
    for j in range(D_SIZE):
        D[j] = dg[j]


@jit
def refresh(s: KernelState, ext) -> int:
    """Recompute the derivative and diagnostics at the current state (new mode or input)."""
    I = s.ints  # noqa: E741
    P = as_tuple_23(s.params)
    mode = I[I_MODE]
    y = as_tuple_6(s.y)
    frozen = s.options[O_FREEZE] > 0.0
    ctx = (P, as_tuple_13(s.control), s.history, I[I_HSTART], I[I_HEND], mode, frozen, s.chain)
    tau = s.clock[X_TAU]
    st, hint, k, d, taun, g, gs, r, S = stage(ctx, I[I_KHINT], tau, y, Z_NOW, Z_KNOW, ext)
    I[I_KHINT] = hint
    if st != ST_OK:
        return st
    store(s.y, s.stages, s.diag, y, k, diagnostics(P, mode, d, taun, g, gs, r, s.diag[D_QG], S))
    return ST_OK


@jit
def attempt(ctx, hint, bouncing, tol, start, h, t_end, ext):
    """An RK4 step of size h from ``start`` = (tau, y0, dy/dtau, diagnostics) to t_end, cut at
    the first event inside it.

    The candidates watched in the mode (:data:`.events.WATCHED`: the event functions, and the
    delayed instant passing a stored discontinuity) are compared at both ends of the step; each
    whose event lies inside the step is located, and the earliest ends the step. Locating is
    regula falsi with the Illinois modification on the bracket [lo, hi] of step fractions
    (f(lo) > 0 >= f(hi)), each trial a genuine RK4 step of size theta*h from the step start
    (:func:`trial_fraction`): when the estimate comes within half the tolerance of an end of
    the bracket, the trial is put half a tolerance past that end, which closes the bracket from
    the other side, so the far side is reached in a few trials instead of by bisection; at most
    :data:`MAX_TRIALS` a candidate. Trial steps are ``(tau + theta*h) - tau``, so the state of
    a trial belongs exactly to the time ``tau + theta*h`` it is labelled with; trials put the
    string's inner nodes in the chain rows Z_TRIAL1 and Z_TRIAL2 by turns, never over the far
    side's. The step and the trials are one call of :func:`rk4` in one loop: numba compiles
    what it inlines once per call site, and a second site (a trial function of its own) cost a
    third of the kernel's compilation.

    Returns (status, hint, event, theta, far side, trials, locations): ``event`` is the earliest
    candidate (-1: none, ``EVF_DELAY``: a delayed discontinuity), theta in (0, 1] its step
    fraction, within ``tol`` (in time) after the root, the far side (y, dy/dtau, diagnostics,
    chain row) the state that ends the step.
    """
    tau, y0, k0, d0 = start
    _, _, H, hs, he, mode, frozen, Z = ctx
    mask = watched(mode, bouncing, frozen)
    half = 0.5 * tol / h
    # the step itself (ev = -1), then the trials of each candidate ev inside it
    ev = -1
    hh = h
    out = Z_END
    yn, kn, dn = y0, k0, d0
    t_disc = -np.inf
    far = (y0, k0, d0, Z_NOW)  # the earliest far side so far
    best = 2.0
    best_ev = -1
    trials = 0
    located = 0
    # the candidate's bracket, its value at the ends, the side last moved, its trials, and its
    # far side (the state at hi)
    lo, hi, flo, fhi, side, n = 0.0, 1.0, 0.0, 0.0, 0, 0
    found = far
    th = 1.0
    while True:
        st, hint, y, k, dg = rk4(ctx, hint, start, hh, out, ext)
        closed = True
        if ev < 0:
            if st != ST_OK:
                return st, hint, -1, 0.0, far, 0, 0
            yn, kn, dn = y, k, dg
            # the first stored discontinuity the delayed instant passes in the step (-inf: none)
            t_disc = next_discontinuity(H, hs, he, hint, tau - d0[D_TAUN], t_end - dn[D_TAUN])
            far = (yn, kn, dn, Z_END)
        else:
            trials += 1
            n += 1
            if st != ST_OK:
                return ST_DELAY, hint, -1, 0.0, far, trials, located
            f = event_value(ev, tau + th * h, y, dg, t_disc)
            closed = f == 0.0
            if f <= 0.0:
                hi = th
                fhi = f
                found = (y, k, dg, out)
                if side == -1:
                    flo *= 0.5
                side = -1
            else:
                lo = th
                flo = f
                if side == 1:
                    fhi *= 0.5
                side = 1
        # the candidate's next trial; or, once it is located, the next candidate's first
        while closed or n >= MAX_TRIALS or (hi - lo) * h <= tol:
            if ev >= 0 and hi < best:  # located at hi
                best = hi
                best_ev = ev
                if found[3] != Z_END:  # the next candidate's trials reuse the trial rows
                    copy_rows(Z, found[3], Z_BEST)
                far = (found[0], found[1], found[2], Z_BEST if found[3] != Z_END else Z_END)
            ev += 1
            while ev < N_CANDIDATES:
                if (mask >> ev) & 1 != 0:
                    flo = event_value(ev, tau, y0, d0, t_disc)
                    fhi = event_value(ev, t_end, yn, dn, t_disc)
                    if inside(ev, flo, fhi):
                        break
                ev += 1
            if ev >= N_CANDIDATES:
                return ST_OK, hint, best_ev, best, far, trials, located
            located += 1
            lo, hi, side, n = 0.0, 1.0, 0, 0
            found = (yn, kn, dn, Z_END)
            closed = False
        th = trial_fraction(lo, hi, flo, fhi, half)
        hh = (tau + th * h) - tau
        out = Z_TRIAL2 if found[3] == Z_TRIAL1 else Z_TRIAL1


# ``step`` and ``attempt`` are compiled on their own, not inlined as the hot path's smaller
# functions are: numba inlines at its IR level by copying the callee's whole variable scope once
# per block, so inlining these two (everything below them inlined) made the kernel's first
# compilation 2-3x longer (a clean-HOME first use of an FMU, an in-memory compile on a read-only
# machine); the calls cost the reference counting of their arrays, about 20 % per smooth step
# (docs/benchmarks.md).
@jit
def step(P, C, H, I, X, Y, K, D, Z, frozen, tol, h, t_end, ext):
    """One step to t_end = tau + h, or to the first event inside it.

    ``P``, ``C`` are the parameters and the control law as tuples (:func:`as_tuple_14`); the
    arrays are those of the kernel state (history, ints, clock, y, stages, diag, chain). Returns
    (status, event): the mode event that ended the step, for the caller to apply
    (:func:`finish_event`), or -1.
    """
    tau = X[X_TAU]
    ctx = (P, C, H, I[I_HSTART], I[I_HEND], I[I_MODE], frozen, Z)
    start = (tau, as_tuple_6(Y), row_tuple_6(K, K_NOW), as_tuple_9(D))
    st, hint, ev, th, far, trials, located = attempt(
        ctx, I[I_KHINT], I[I_BOUNCING], tol, start, h, t_end, ext
    )
    I[I_KHINT] = hint
    I[I_NTRIALS] += trials
    I[I_NLOCATE] += located
    if st != ST_OK:
        return st, -1
    I[I_NSTEPS] += 1
    y, k, dg, zrow = far
    store(Y, K, D, y, k, dg)
    copy_rows(Z, zrow, Z_NOW)
    X[X_GINT] += dg[D_QG]
    X[X_TAU] = t_end if ev < 0 or th == 1.0 else tau + th * h
    if ev < 0 or ev == EVF_DELAY:
        push_node(H, I, X[X_TAU], Y, 0.0)
        return ST_OK, -1
    return ST_OK, ev


@jit
def finish_event(s: KernelState, ev: int, ext) -> int:
    """Apply mode event ``ev`` at the current state (the far side of the switching surface);
    the event instant becomes a discontinuity node of the history. Returns a status."""
    st = apply_event(ev, s.params, s.options, s.clock, s.y, s.ints, s.diag, s.events)
    if st == ST_OK:
        st = refresh(s, ext)
    push_node(s.history, s.ints, s.clock[X_TAU], s.y, 1.0)
    return st


@jit
def switch_on(s: KernelState) -> None:
    """Activate the feedback at t_on, latching the references for a bumpless start."""
    P, C, Y = s.params, s.control, s.y
    tau = s.clock[X_TAU]
    w0 = P[P_OMEGA0]
    phi_ref, twist_ref = switch_on_references(
        int(C[C_LATCH]), Y[Y_PHI] - w0 * tau, Y[Y_THETA] - w0 * tau, C[C_K0]
    )
    C[C_PHIREF] = phi_ref
    C[C_TWISTREF] = twist_ref
    C[C_ACTIVE] = 1.0
    mode = s.ints[I_MODE]
    log_event(s.events, s.ints, s.clock, P, Y, EV_SWITCH_ON, mode, mode, Y[Y_V], s.diag[D_GSTAR])


@jit
def advance(s: KernelState, to_tau: float, ext) -> int:
    """Integrate to ``to_tau`` (steps partition the interval evenly); returns a status.

    Returns early with ST_EVLOG_FULL / ST_HIST_FULL when a buffer must be drained or grown by
    the caller, and with the model's status codes when the run must stop.
    """
    # the arrays are bound once: passing the state tuple into the loop's functions would cost
    # reference counting on every one of its arrays at every step
    H, I, X, E = s.history, s.ints, s.clock, s.events
    Y, K, D, Z = s.y, s.stages, s.diag, s.chain
    h_nom = s.options[O_H]
    frozen = s.options[O_FREEZE] > 0.0
    tol = s.options[O_EVTOL]
    P = as_tuple_23(s.params)
    C = as_tuple_13(s.control)
    zeno = 0
    while True:
        tau = X[X_TAU]
        # the feedback acts from the first instant at or after t_on (also a run's first sample)
        if int(C[C_KIND]) == CTRL_AFFINE and C[C_ACTIVE] == 0.0 and tau >= C[C_TON]:
            if I[I_ENUM] >= E.shape[0]:
                return ST_EVLOG_FULL
            switch_on(s)
            C = as_tuple_13(s.control)
            st = refresh(s, ext)
            if st != ST_OK:
                I[I_STATUS] = st
                return st
        if tau >= to_tau:
            I[I_STATUS] = ST_OK
            return ST_OK
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
        # each step's end from the interval's end, and the step as the difference of the two
        # times, so that the state after the step belongs exactly to the time it is labelled
        # with (otherwise the rounding of tau + h accumulates over long runs: a precision floor)
        t_end = to_tau if n == 1 else to_tau - (n - 1) * (remaining / n)
        h = t_end - tau
        if int(C[C_KIND]) == CTRL_AFFINE and C[C_ACTIVE] == 0.0 and tau < C[C_TON] < t_end:
            t_end = C[C_TON]
            h = t_end - tau
        st, ev = step(P, C, H, I, X, Y, K, D, Z, frozen, tol, h, t_end, ext)
        if st == ST_OK and ev >= 0:
            st = finish_event(s, ev, ext)
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


@jit
def write_sample(s: KernelState, row: np.ndarray) -> None:
    """The outputs at the current time into ``row`` (columns ``OUT_*``)."""
    P, Y, D = s.params, s.y, s.diag
    tau = s.clock[X_TAU]
    u, du, phi, dphi, theta, dtheta = to_perturbation(
        P, tau, Y[Y_U], Y[Y_V], Y[Y_PHI], Y[Y_W], Y[Y_THETA], Y[Y_WT]
    )
    row[OUT_TAU] = tau
    row[OUT_U] = u
    row[OUT_DU] = du
    row[OUT_PHI] = phi
    row[OUT_DPHI] = dphi
    row[OUT_THETA] = theta
    row[OUT_DTHETA] = dtheta
    row[OUT_D] = D[D_D]
    row[OUT_G] = D[D_G]
    row[OUT_TAUN] = D[D_TAUN]
    row[OUT_R] = D[D_R]
    row[OUT_MODE] = s.ints[I_MODE]
    top_nb = Y[Y_PHI] if int(P[P_NT]) == 0 else s.chain[Z_NOW, 0]
    row[OUT_TOP] = P[P_KT] * (Y[Y_THETA] - top_nb)


@jit
def advance_sampled(
    s: KernelState, times: np.ndarray, rows: np.ndarray, zrows: np.ndarray, i0: int, i1: int, ext
):
    """Advance through ``times[i0:i1]`` writing the outputs at each into ``rows``, and the
    string's inner nodes (chain row ``Z_NOW``) into ``zrows``.

    Returns (status, i): the index of the next row to fill. A buffer status (ST_EVLOG_FULL,
    ST_HIST_FULL) asks the caller to act and call again from i; any other status stops the
    run, its row ``i - 1`` holding the state where it stopped.
    """
    for i in range(i0, i1):
        st = advance(s, times[i], ext)
        if st == ST_EVLOG_FULL or st == ST_HIST_FULL:
            return st, i
        write_sample(s, rows[i])
        for j in range(zrows.shape[1]):
            zrows[i, j] = s.chain[Z_NOW, j]
        if st != ST_OK:
            return st, i + 1
    return ST_OK, i1


# --- a held input ----------------------------------------------------------------------------
# The step of a model whose input R - R0 is held over each interval, written once: the plant FMU
# runs it on both of its paths (drillstring.model.native), Engine.set_input and Engine.advance
# run its two halves.


@inline
def hold(s: KernelState, r: float) -> None:
    """Hold R - R0 = r (a ``CTRL_HELD`` law); the derivative and diagnostics at the current state
    are recomputed only when r changed (a delay not found there is met again, and reported, by
    the next advance)."""
    C = s.control
    if r != C[C_R]:
        C[C_R] = r
        refresh(s, None)


@inline
def advance_drained(s: KernelState, to_tau: float, keep_events: bool, ext) -> int:
    """:func:`advance` to ``to_tau``, the event log drained here when the events are not kept.

    Returns ST_OK, a status that stops the run, ST_HIST_FULL (the caller grows the history
    buffer and calls again) or, only with ``keep_events``, ST_EVLOG_FULL (the caller takes the
    events and calls again).
    """
    while True:
        st = advance(s, to_tau, ext)
        if keep_events:
            return st
        s.ints[I_ENUM] = 0
        if st != ST_EVLOG_FULL:
            return st


@inline
def held_step(s: KernelState, r: float, to_tau: float, keep_events: bool, bounces: float):
    """One interval of a held input: :func:`hold` r, then :func:`advance_drained` to ``to_tau``.

    Returns (status, bounced): the status of :func:`advance_drained` (what the caller must do:
    nothing, stop, grow the history, take the events), and whether the bit bounced in more
    episodes than the ``bounces`` the caller has reported (``on_invalid = continue``).
    """
    hold(s, r)
    st = advance_drained(s, to_tau, keep_events, None)
    return st, s.ints[I_NBOUNCE] > bounces


# --- entry points from Python ----------------------------------------------------------------
# numba dispatches a call with arrays in its C fast path but types a named tuple in Python (a few
# microseconds a call, which is the cost of a whole FMU step); so Python calls these with the
# arrays of a KernelState, in the order of its fields, and they rebuild the named tuple.


@jit
def advance_sampled_from(params, options, control, clock, y, ints, diag, history, events, stages,
                         chain, times, rows, zrows, i0, i1, ext):  # fmt: skip
    """:func:`advance_sampled` of the state made of these arrays."""
    s = KernelState(params, options, control, clock, y, ints, diag, history, events, stages, chain)
    return advance_sampled(s, times, rows, zrows, i0, i1, ext)


@jit
def refresh_from(params, options, control, clock, y, ints, diag, history, events, stages,
                 chain, ext):  # fmt: skip
    """:func:`refresh` of the state made of these arrays."""
    s = KernelState(params, options, control, clock, y, ints, diag, history, events, stages, chain)
    return refresh(s, ext)


@jit
def hold_from(params, options, control, clock, y, ints, diag, history, events, stages, chain,
              r):  # fmt: skip
    """:func:`hold` on the state made of these arrays."""
    s = KernelState(params, options, control, clock, y, ints, diag, history, events, stages, chain)
    hold(s, r)


@jit
def advance_drained_from(params, options, control, clock, y, ints, diag, history, events, stages,
                         chain, to_tau, keep_events, ext):  # fmt: skip
    """:func:`advance_drained` of the state made of these arrays."""
    s = KernelState(params, options, control, clock, y, ints, diag, history, events, stages, chain)
    return advance_drained(s, to_tau, keep_events, ext)


__all__ = [
    "advance",
    "advance_drained",
    "advance_drained_from",
    "advance_sampled",
    "advance_sampled_from",
    "held_step",
    "hold",
    "hold_from",
    "refresh",
    "refresh_from",
    "rk4",
    "stage",
    "step",
    "switch_on",
    "trial_fraction",
]
