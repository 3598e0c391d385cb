"""The events of the model as tables: what is watched in which mode, and what happens at it.

An event function is positive before its event and reaches <= 0 at it. Each is one signed
quantity of the state or the diagnostics (``docs/model.md``, "Wearflat contact as a Filippov
system", "Validity", "Torsional stick"):

=============== ======================== ============== =========================================
event           function                 watched in     at the event
=============== ======================== ============== =========================================
V_DOWN          V                        slip           V = 0: stick, or slip/up by the sign of g*
V_UP            -V                       moving up      V = 0: as V_DOWN
G_LOW           g*                       axial stick    slip down (g* < 0)
G_HIGH          1 - g*                   axial stick    move up (g* > 1)
W               W                        not tstick     torsional stick, or stop (model off)
BOUNCE          d                        not bouncing   bit bouncing: stop, or count (continue)
BOUNCE_END      -d                       bouncing       contact again
RELEASE         T_max - S                torsional st.  slip restarts from V = W = 0
REVERSE         S                        torsional st.  stop: reverse rotation
DELAY           t_disc - (tau - tau_n)   every mode     the step ends there (RK4's order kept)
=============== ======================== ============== =========================================

The W event is not watched when the torsion is frozen (the fast axial model (18)). Entering axial
or torsional stick is counted; entering torsional stick needs S >= 0 (else reverse rotation).

The last row is not a mode event: a step also ends where the delayed instant tau - tau_n reaches
the next stored discontinuity t_disc of the history (``EVF_DELAY``). These ten are the candidates
for the end of a trial step: :data:`WATCHED` has a bit for each candidate watched in a mode,
:func:`event_value` is its function, :func:`inside` says whether its event lies inside a step.
"""

from __future__ import annotations

import numpy as np

from drillstring.model.kernel.filippov import mode_at_zero_velocity
from drillstring.model.kernel.jit import jit_for
from drillstring.model.kernel.state import (
    D_D,
    D_GSTAR,
    D_RELEASE,
    D_S,
    D_TAUN,
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
    EV_TSTICK_STOP,
    I_BOUNCING,
    I_ENUM,
    I_MODE,
    I_NBOUNCE,
    I_NEVENTS,
    I_NSTICK,
    I_NTSTICK,
    MODE_SLIP,
    MODE_STICK,
    MODE_TSTICK,
    MODE_UP,
    O_CONTINUE,
    O_TSTICK,
    P_V0,
    ST_BOUNCE,
    ST_OK,
    ST_REVERSE,
    ST_TSTICK_OUT,
    X_GINT,
    X_TAU,
    Y_U,
    Y_V,
    Y_W,
)

jit = jit_for(__name__)
inline = jit_for(__name__, inline=True)

EVF_V_DOWN = 0
EVF_V_UP = 1
EVF_G_LOW = 2
EVF_G_HIGH = 3
EVF_W = 4
EVF_BOUNCE = 5
EVF_BOUNCE_END = 6
EVF_RELEASE = 7
EVF_REVERSE = 8
N_EVF = 9
#: Not a mode event: the delayed instant tau - tau_n passes a stored discontinuity, where the
#: step must end to keep RK4's order (``drillstring.model.kernel.hermite.next_discontinuity``).
EVF_DELAY = 9
#: The candidates for the end of a trial step: the event functions and the delayed discontinuity.
N_CANDIDATES = 10

# --- what each event function is -------------------------------------------------------------
# quantity: a column of the state (Q_STATE, index Y_*) or of the diagnostics (Q_DIAG, index D_*)
Q_STATE = 0
Q_DIAG = 1
_SLIP, _STICK, _UP, _TSTICK = (
    (1 << MODE_SLIP),
    (1 << MODE_STICK),
    (1 << MODE_UP),
    (1 << MODE_TSTICK),
)
_ALL = _SLIP | _STICK | _UP | _TSTICK
ANY = -1

#                     V_DOWN  V_UP    G_LOW    G_HIGH   W       BOUNCE  B_END   RELEASE    REVERSE
EVF_SOURCE = np.array([Q_STATE, Q_STATE, Q_DIAG, Q_DIAG, Q_STATE, Q_DIAG, Q_DIAG, Q_DIAG, Q_DIAG])
EVF_INDEX = np.array([Y_V, Y_V, D_GSTAR, D_GSTAR, Y_W, D_D, D_D, D_RELEASE, D_S])
EVF_SIGN = np.array([1.0, -1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0, 1.0])
EVF_OFFSET = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
EVF_MODES = np.array([_SLIP, _UP, _STICK, _STICK, _ALL & ~_TSTICK, _ALL, _ALL, _TSTICK, _TSTICK])
#: bouncing state in which the function is watched (ANY: both)
EVF_BOUNCING = np.array([ANY, ANY, ANY, ANY, ANY, 0, 1, ANY, ANY])
#: 1: also watched with the torsion frozen (the fast model (18))
EVF_FROZEN = np.array([1, 1, 1, 1, 0, 1, 1, 1, 1])

# --- what happens at it ----------------------------------------------------------------------
KEEP = -1  # mode unchanged
AT_ZERO_VELOCITY = -2  # V = 0: stick while 0 <= g* <= 1, else slip down or move up (Filippov)
NONE = -1
#                      V_DOWN            V_UP              G_LOW      G_HIGH   W
ACT_MODE = np.array(
    [AT_ZERO_VELOCITY, AT_ZERO_VELOCITY, MODE_SLIP, MODE_UP, MODE_TSTICK]
    # BOUNCE BOUNCE_END RELEASE          REVERSE
    + [KEEP, KEEP, AT_ZERO_VELOCITY, KEEP]
)
#: status that stops the run, unless the option ACT_UNLESS is set
ACT_STOP = np.array(
    [ST_OK, ST_OK, ST_OK, ST_OK, ST_TSTICK_OUT, ST_BOUNCE, ST_OK, ST_OK, ST_REVERSE]
)
ACT_UNLESS = np.array([NONE, NONE, NONE, NONE, O_TSTICK, O_CONTINUE, NONE, NONE, NONE])
#: event kind logged when the run stops there
ACT_STOP_LOG = np.array([NONE, NONE, NONE, NONE, EV_TSTICK_STOP, EV_BOUNCE, NONE, NONE, NONE])
#: event kind logged when the run goes on
ACT_LOG = np.array(
    [EV_MODE, EV_MODE, EV_MODE, EV_MODE, EV_MODE, EV_BOUNCE, EV_BOUNCE_END, EV_MODE, NONE]
)
#: the velocities set to 0 at the event (rock is not penetrated without rotation)
ACT_ZERO_V = np.array([1, 1, 0, 0, 1, 0, 0, 1, 0])
ACT_ZERO_W = np.array([0, 0, 0, 0, 1, 0, 0, 1, 0])
#: new bouncing state (KEEP: unchanged)
ACT_BOUNCING = np.array([KEEP, KEEP, KEEP, KEEP, KEEP, 1, 0, KEEP, KEEP])
#: counter incremented at the event whether the run stops or not
ACT_COUNT = np.array([NONE, NONE, NONE, NONE, NONE, I_NBOUNCE, NONE, NONE, NONE])


def _watched_masks() -> np.ndarray:
    """WATCHED[mode, bouncing, frozen]: bit ev set when candidate ev is watched there (the
    delayed discontinuity in every mode)."""
    masks = np.zeros((4, 2, 2), dtype=np.int64)
    for mode in range(4):
        for bouncing in range(2):
            for frozen in range(2):
                masks[mode, bouncing, frozen] = 1 << EVF_DELAY
                for ev in range(N_EVF):
                    if (
                        (EVF_MODES[ev] >> mode) & 1
                        and EVF_BOUNCING[ev] in (ANY, bouncing)
                        and (EVF_FROZEN[ev] == 1 or not frozen)
                    ):
                        masks[mode, bouncing, frozen] |= 1 << ev
    return masks


#: The candidates watched in each mode, bouncing state and frozen-torsion setting, from the
#: tables above (a bit per candidate: the event functions, and the delayed discontinuity).
WATCHED = _watched_masks()
assert N_CANDIDATES == N_EVF + 1 == EVF_DELAY + 1 and len(EVF_INDEX) == N_EVF


@inline
def watched(mode: int, bouncing: int, frozen: bool) -> int:
    """The candidates watched in ``mode``, as a bit mask (bit ev: candidate ev)."""
    return WATCHED[mode, bouncing, 1 if frozen else 0]


@inline
def event_value(ev: int, t: float, Y: np.ndarray, D: np.ndarray, t_disc: float) -> float:
    """Candidate ``ev`` at time t, state Y with diagnostics D (positive before its event).

    An event function is a signed entry of Y or D; the delayed discontinuity's is the distance
    ``t_disc - (t - tau_n)`` of the delayed instant to the discontinuity ``t_disc`` ahead of it.
    """
    if ev == EVF_DELAY:
        return t_disc - (t - D[D_TAUN])
    q = Y[EVF_INDEX[ev]] if EVF_SOURCE[ev] == Q_STATE else D[EVF_INDEX[ev]]
    return EVF_SIGN[ev] * q + EVF_OFFSET[ev]


@inline
def inside(ev: int, f0: float, f1: float) -> bool:
    """True when the event of candidate ``ev`` lies inside a step whose ends have the values
    f0, f1 of its function: an event function reaches <= 0 at the end (0 counts when coming
    from > 0); the delayed discontinuity lies strictly inside (a step that ends on it, or that
    has none ahead of it, f0 = -inf, passes nothing)."""
    if ev == EVF_DELAY:
        return f0 > 0.0 and f1 < 0.0
    return f1 < 0.0 or (f1 == 0.0 and f0 > 0.0)


@jit
def log_event(
    E: np.ndarray,
    I: np.ndarray,
    X: np.ndarray,
    P: np.ndarray,
    Y: np.ndarray,
    kind: int,
    frm: int,
    to: int,
    v: float,
    gs: float,
) -> None:
    """Append one row to the event log (the caller guarantees capacity)."""
    n = I[I_ENUM]
    tau = X[X_TAU]
    E[n, E_GINT] = X[X_GINT]
    E[n, E_U] = Y[Y_U] - P[P_V0] * tau
    E[n, E_TAU] = tau
    E[n, E_KIND] = kind
    E[n, E_FROM] = frm
    E[n, E_TO] = to
    E[n, E_V] = v
    E[n, E_GSTAR] = gs
    I[I_ENUM] = n + 1
    I[I_NEVENTS] += 1


@jit
def apply_event(
    ev: int,
    P: np.ndarray,
    O: np.ndarray,
    X: np.ndarray,
    Y: np.ndarray,
    I: np.ndarray,
    D: np.ndarray,
    E: np.ndarray,
) -> int:
    """The action of event ``ev`` on the state at the event; returns a status.

    The state and diagnostics are those at the event (on the far side of the switching
    surface). The caller recomputes the diagnostics of the new mode.
    """
    mode = I[I_MODE]
    v_event = Y[Y_V]
    gs = D[D_GSTAR]
    if ACT_COUNT[ev] != NONE:
        I[ACT_COUNT[ev]] += 1
    stop = ACT_STOP[ev]
    if stop != ST_OK and (ACT_UNLESS[ev] == NONE or O[ACT_UNLESS[ev]] == 0.0):
        if ACT_STOP_LOG[ev] != NONE:
            log_event(E, I, X, P, Y, ACT_STOP_LOG[ev], mode, mode, v_event, gs)
        return stop
    new = ACT_MODE[ev]
    if new == KEEP:
        new = mode
    elif new == AT_ZERO_VELOCITY:
        new = mode_at_zero_velocity(gs)
    if new == MODE_TSTICK and D[D_S] < 0.0:
        return ST_REVERSE
    if ACT_ZERO_W[ev] == 1:
        Y[Y_W] = 0.0
    if ACT_ZERO_V[ev] == 1:
        Y[Y_V] = 0.0
    if ACT_BOUNCING[ev] != KEEP:
        I[I_BOUNCING] = ACT_BOUNCING[ev]
    if new != mode and new == MODE_STICK:
        I[I_NSTICK] += 1
    elif new != mode and new == MODE_TSTICK:
        I[I_NTSTICK] += 1
    I[I_MODE] = new
    if ACT_LOG[ev] != NONE:
        log_event(E, I, X, P, Y, ACT_LOG[ev], mode, new, v_event, gs)
    return ST_OK
