"""Index constants of the kernel arrays (see :mod:`drillstring.model.kernel`)."""

# parameters P
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
P_SIZE = 14

# options O
O_H = 0  # nominal step
O_TSTICK = 1  # 1: torsional stick model of NOTES.md section 6; 0: stop at W = 0
O_CONTINUE = 2  # 1: continue through bit bouncing (counted); 0: stop
O_FREEZE = 3  # 1: torsion frozen at nominal speed (constant delay tau_n0)
O_EVTOL = 4  # event location tolerance in time
O_SIZE = 5

# control C
C_KIND = 0  # CTRL_HELD, CTRL_AFFINE, CTRL_EXTERNAL
C_R = 1  # held torque R - R0
C_TON = 2
C_F0 = 3  # F[0..3] at 3..6
C_K0 = 7
C_RFF = 8
C_PHIREF = 9
C_TWISTREF = 10
C_LATCH = 11  # LATCH_NONE, LATCH_ANGLE, LATCH_ANGLE_TWIST
C_ACTIVE = 12  # 1 once tau >= t_on has been reached (references latched)
C_SIZE = 13

CTRL_HELD = 0
CTRL_AFFINE = 1
CTRL_EXTERNAL = 2
LATCH_NONE = 0
LATCH_ANGLE = 1
LATCH_ANGLE_TWIST = 2

# float scalars X
X_TAU = 0
X_GINT = 1  # running integral of g over tau (for the averaged contact force, Section III)
X_SIZE = 2

# int scalars I
I_MODE = 0
I_HSTART = 1
I_HEND = 2
I_KHINT = 3
I_NSTEPS = 4
I_NEVENTS = 5
I_NSTICK = 6  # entries into axial stick
I_NBOUNCE = 7  # entries into bit bouncing
I_NTSTICK = 8  # entries into torsional stick
I_BOUNCING = 9
I_ENUM = 10  # rows used in the event log E
I_STATUS = 11
I_NREJECT = 12  # event-location re-integrations
I_SIZE = 13

# diagnostics D (at the current time)
D_D = 0  # depth of cut d, eq. (5)
D_TAUN = 1  # delay tau_n, eq. (14)
D_G = 2  # contact multiplier g, eq. (17)
D_GSTAR = 3  # g that keeps dV/dtau = 0
D_S = 4  # scaled twist torque S = R0 + Theta - Phi
D_TOB = 5  # torque on bit T
D_R = 6  # applied R - R0
D_QG = 7  # RK4 quadrature of g over the last step
D_SIZE = 8

# history rows
H_TAU = 0
H_U = 1
H_V = 2
H_PHI = 3
H_W = 4
H_FLAG = (
    5  # 1: derivative discontinuity at this node (event, or tau = 0), tracked through the delay
)
H_ROWS = 6

# event log columns
E_TAU = 0
E_KIND = 1
E_FROM = 2
E_TO = 3
E_V = 4
E_GSTAR = 5
E_GINT = 6  # running integral of g at the event
E_U = 7  # u = U - v0*tau at the event
E_COLS = 8

# axial/torsional modes
MODE_SLIP = 0  # moving down, full wearflat contact, g = 0
MODE_STICK = 1  # axial stick, V = 0, g = g*
MODE_UP = 2  # moving up, no contact, g = 1
MODE_TSTICK = 3  # torsional (and axial) stick, NOTES.md section 6

# event kinds
EV_MODE = 0
EV_BOUNCE = 1
EV_BOUNCE_END = 2
EV_SWITCH_ON = 3
EV_TSTICK_STOP = 4

# status codes
ST_OK = 0
ST_TSTICK_OUT = 1  # W reached 0 with the torsional stick model off
ST_BOUNCE = 2  # d < 0 with on_invalid = stop
ST_REVERSE = 3  # twist torque negative while stuck: reverse rotation
ST_EVLOG_FULL = 4  # internal: drain the event log and call again
ST_HIST_FULL = 5  # internal: grow the history buffer and call again
ST_NONFINITE = 6
ST_DELAY = 7  # delay not found in the history (too short history / too short delay)
ST_ZENO = 8  # events accumulate without progress
