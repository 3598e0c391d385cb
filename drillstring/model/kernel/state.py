"""The kernel's state: one named tuple of arrays, and the names of their entries.

:class:`KernelState` is what :class:`drillstring.model.engine.Engine` owns and what the compiled
kernel functions take; numba compiles (and caches) functions of a named tuple of arrays like
functions of plain arrays. Every entry of every array has a name below (``Y_V`` is the axial
velocity in ``state.y``, ``I_MODE`` the contact mode in ``state.ints``), so no raw index appears
in the kernel. The arrays:

* ``params`` model parameters (``P_*``), read only;
* ``options`` integration options (``O_*``);
* ``control`` the torque law R - R0 and its switch-on latch (``C_*``);
* ``clock`` time and the running integral of g (``X_*``);
* ``y`` the state ``[U, V, Phi, W, Theta, Wt]`` in total scaled coordinates (``Y_*``,
  ``docs/model.md``, "Coordinates");
* ``ints`` the contact mode, the history window, counters and the status (``I_*``);
* ``diag`` depth of cut, delay, contact multiplier, torques at the current time (``D_*``);
* ``history`` past of U, V, Phi, W at the integrator's nodes (rows ``H_*``, live columns
  ``ints[I_HSTART]:ints[I_HEND]``);
* ``events`` the event log (rows of ``E_*`` columns), drained by the engine;
* ``stages`` RK stage derivatives (row ``K_NOW`` is always the derivative at the current state);
* ``chain`` the inner nodes of the string (``docs/model.md``, "The distributed string"): row
  ``Z_NOW`` their state, columns ``Z_*`` offsets below, row ``Z_KNOW`` its derivative, the other
  rows the RK stages and trial ends of a step (no columns for the paper's one-mode model).

A step's trial states and their diagnostics are tuples of the compiled code, not arrays
(``drillstring.model.kernel.stepper``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# --- parameters P ----------------------------------------------------------------------------
P_N = 0
P_PSI = 1
P_GAMMA = 2
P_ETA = 3
P_LAM = 4
P_BETA = 5
P_RHO = 6
P_V0 = 7
P_OMEGA0 = 8
P_TAUN0 = 9
P_D0 = 10
P_NPSI = 11
P_BLADE = 12  # 2*pi/n, the angle between blades, eq. (6)
P_R0 = 13
# the string (drillstring.model.pipe; the paper's one-mode model: 1, rho, 1, 0, eta^2, 1, 0, 0, 0)
P_KT = 14  # torsional stiffness of one element
P_JT = 15  # inertia of the rotary-table node
P_JB = 16  # inertia of the bit node
P_JI = 17  # inertia of an inner torsional node
P_KA = 18  # axial stiffness of one element
P_MB = 19  # axial mass of the bit node
P_MI = 20  # axial mass of an inner node
P_NT = 21  # inner torsional nodes, N - 1 (0: one element)
P_NA = 22  # inner axial nodes (0: a massless axial spring)
P_SIZE = 23

# --- options O -------------------------------------------------------------------------------
O_H = 0  # nominal step
O_TSTICK = 1  # 1: torsional-stick model (docs/model.md, "Torsional stick"); 0: stop at W = 0
O_CONTINUE = 2  # 1: continue through bit bouncing (counted); 0: stop
O_FREEZE = 3  # 1: torsion frozen at nominal speed (constant delay tau_n0): the fast model (18)
O_EVTOL = 4  # event location tolerance in time
O_SIZE = 5

# --- control C -------------------------------------------------------------------------------
C_KIND = 0  # CTRL_HELD, CTRL_AFFINE, CTRL_EXTERNAL
C_R = 1  # held torque R - R0
C_TON = 2  # switch-on time of the feedback
C_F0 = 3  # the gain F, 4 slots
C_K0 = C_F0 + 4
C_RFF = 8
C_PHIREF = 9
C_TWISTREF = 10
C_LATCH = 11  # index into drillstring.model.control.LATCH_MODES
C_ACTIVE = 12  # 1 once tau >= t_on has been reached (references latched)
C_SIZE = 13

CTRL_HELD = 0
CTRL_AFFINE = 1
CTRL_EXTERNAL = 2

# --- clock X ---------------------------------------------------------------------------------
X_TAU = 0
X_GINT = 1  # running integral of g over tau (for the averaged contact force, Section III)
X_SIZE = 2

# --- state Y ---------------------------------------------------------------------------------
Y_U = 0  # axial bit position
Y_V = 1  # axial bit velocity
Y_PHI = 2  # bit angle
Y_W = 3  # bit angular velocity
Y_THETA = 4  # rotary-table angle
Y_WT = 5  # rotary-table angular velocity
Y_SIZE = 6

# --- integers I ------------------------------------------------------------------------------
I_MODE = 0  # contact mode, MODE_*
I_HSTART = 1  # first live history column
I_HEND = 2  # one past the last live history column
I_KHINT = 3  # history interval of the last delay look-up (search start of the next one)
I_NSTEPS = 4
I_NEVENTS = 5
I_NSTICK = 6  # entries into axial stick
I_NBOUNCE = 7  # entries into bit bouncing
I_NTSTICK = 8  # entries into torsional stick
I_BOUNCING = 9  # 1 while d < 0 (on_invalid = continue)
I_ENUM = 10  # rows used in the event log
I_STATUS = 11
I_NTRIALS = 12  # RK4 trials spent locating events
I_NLOCATE = 13  # event locations (mode events and delayed discontinuities)
I_SIZE = 14

# --- diagnostics D (at the current time) -----------------------------------------------------
D_D = 0  # depth of cut d, eq. (5)
D_TAUN = 1  # delay tau_n, eq. (14)
D_G = 2  # contact multiplier g, eq. (17)
D_GSTAR = 3  # g that keeps dV/dtau = 0
D_S = 4  # scaled twist torque S = R0 + Theta - Phi
D_TOB = 5  # torque on bit T
D_R = 6  # applied R - R0
D_QG = 7  # RK4 quadrature of g over the last step
D_RELEASE = 8  # T_max - S: positive while a torsional stick can hold
D_SIZE = 9

# --- history rows H --------------------------------------------------------------------------
H_TAU = 0
H_U = 1
H_V = 2
H_PHI = 3
H_W = 4
H_FLAG = 5  # 1: derivative discontinuity here (event, or tau = 0), tracked through the delay
H_ROWS = 6

# --- event log columns E ---------------------------------------------------------------------
E_TAU = 0
E_KIND = 1
E_FROM = 2
E_TO = 3
E_V = 4
E_GSTAR = 5
E_GINT = 6  # running integral of g at the event
E_U = 7  # u = U - v0*tau at the event
E_COLS = 8

# --- RK stages K ----------------------------------------------------------------------------
K_NOW = 0  # derivative at the current state (stage 1 of the next step)
K_END = 4  # derivative at the end state of the last trial step
K_ROWS = 5

# --- rows of the chain array Z (each state row is followed by its derivative row) -------------
Z_NOW = 0  # the inner nodes' state now (persistent)
Z_KNOW = 1  # its derivative now
Z_STAGE = 2  # an RK stage's state
Z_ACC = 3  # the RK weighted sum of the stage derivatives
Z_KSTAGE = 4  # an RK stage's derivative
Z_END = 5  # the end of a full step (row 6: its derivative)
Z_TRIAL1 = 7  # the end of a trial step of event location (row 8: its derivative)
Z_TRIAL2 = 9  # the other trial end (row 10), so the nearest far side found is kept
Z_BEST = 11  # the earliest event's far side over the candidates (row 12)
Z_ROWS = 13
# columns: torsional angles of the inner nodes, their speeds, axial positions, velocities (node
# 1 next to the rotary table or the hook, the last next to the bit), in total coordinates


def chain_columns(nt: int, na: int) -> int:
    """Columns of the chain array for ``nt`` inner torsional and ``na`` inner axial nodes."""
    return 2 * nt + 2 * na


# --- output columns OUT (one sample of a run: time, perturbations, diagnostics, mode) ---------
OUT_TAU = 0
OUT_U = 1
OUT_DU = 2
OUT_PHI = 3
OUT_DPHI = 4
OUT_THETA = 5
OUT_DTHETA = 6
OUT_D = 7
OUT_G = 8
OUT_TAUN = 9
OUT_R = 10  # the torque R - R0 the kernel applied
OUT_MODE = 11
OUT_TOP = 12  # torque at the top of the string less R0 (what a sub under the top drive reads)
OUT_SIZE = 13
#: Names of the output columns, in order (``drillstring.model.simulate`` columns).
OUTPUT_COLUMNS = (
    "tau",
    "u",
    "du",
    "phi",
    "dphi",
    "theta",
    "dtheta",
    "d",
    "g",
    "tau_n",
    "R_minus_R0",
    "mode",
    "top_torque_minus_R0",
)

# --- contact modes ---------------------------------------------------------------------------
MODE_SLIP = 0  # moving down, full wearflat contact, g = 0
MODE_STICK = 1  # axial stick, V = 0, g = g*
MODE_UP = 2  # moving up, no contact, g = 1
MODE_TSTICK = 3  # torsional (and axial) stick, docs/model.md, "Torsional stick"

# --- kinds of logged events ------------------------------------------------------------------
EV_MODE = 0
EV_BOUNCE = 1
EV_BOUNCE_END = 2
EV_SWITCH_ON = 3
EV_TSTICK_STOP = 4

# --- status codes ----------------------------------------------------------------------------
ST_OK = 0
ST_TSTICK_OUT = 1  # W reached 0 with the torsional stick model off
ST_BOUNCE = 2  # d < 0 with on_invalid = stop
ST_REVERSE = 3  # twist torque negative while stuck: reverse rotation
ST_EVLOG_FULL = 4  # internal: drain the event log and call again
ST_HIST_FULL = 5  # internal: grow the history buffer and call again
ST_NONFINITE = 6
ST_DELAY = 7  # delay not found in the history (too short history / too short delay)
ST_ZENO = 8  # events accumulate without progress


class KernelState(NamedTuple):
    """All arrays of one engine (see the module docstring for their layout)."""

    params: np.ndarray
    options: np.ndarray
    control: np.ndarray
    clock: np.ndarray
    y: np.ndarray
    ints: np.ndarray
    diag: np.ndarray
    history: np.ndarray
    events: np.ndarray
    stages: np.ndarray
    chain: np.ndarray


#: Arrays that make up the resumable state (``events`` is drained after every call).
PERSISTENT = (
    "params", "options", "control", "clock", "y", "ints", "diag", "history", "stages", "chain"
)  # fmt: skip


def allocate(history: np.ndarray, event_capacity: int, chain_columns: int = 0) -> KernelState:
    """A zeroed state around a prepared history buffer, with ``chain_columns`` for the string."""
    return KernelState(
        params=np.zeros(P_SIZE),
        options=np.zeros(O_SIZE),
        control=np.zeros(C_SIZE),
        clock=np.zeros(X_SIZE),
        y=np.zeros(Y_SIZE),
        ints=np.zeros(I_SIZE, dtype=np.int64),
        diag=np.zeros(D_SIZE),
        history=history,
        events=np.zeros((event_capacity, E_COLS)),
        stages=np.zeros((K_ROWS, Y_SIZE)),
        chain=np.zeros((Z_ROWS, chain_columns)),
    )
