"""The digital controller's block: one float64 array, every entry named.

A digital controller (:class:`~drillstring.model.digital.controller.DigitalController`) is a
sampled control law between a sensing stage and the top drive::

    plant measurements -> sensing -> law -> top drive -> table torque, held over the sample

Its parameters and its state live in one float64 array, the *block*, laid out by the table
:data:`SLOTS` below; the compiled functions of :mod:`drillstring.model.digital.block` read and
write it, and so do the controller FMUs (on their Python path and natively in the front layer:
the block is the FMU's io block) and the compiled sampled loop
(:mod:`drillstring.model.digital.loop`). So every host runs the same code on the same numbers.

The block starts with the four entries every FMU io block has (the front layer reads them:
:mod:`drillstring.model.native`). Everything is in the paper's scaled units (time tau, torques in
units of C, perturbation coordinates of (9)-(10)); an SI controller FMU converts its connectors
with the rig scales it holds (``SI``, ``T_STAR``, ``C``, ``OMEGA0_SI``, ``R0_SI``).
"""

from __future__ import annotations

#: Laws (``LAW``): the feed-forward alone, the PI family on the table speed (stiff PI,
#: SoftSpeed, Z-Torque), the paper's state feedback (29)-(31).
LAW_NONE = 0
LAW_PI = 1
LAW_AFFINE = 2

#: Law parameters (``LP`` + index), per kind. Every law has its feed-forward R_ff first.
LP_RFF = 0
# PI on the table speed with torque feedback (drillstring.model.laws.SpeedPI / ZTorque)
PI_KP = 1
PI_KI = 2
PI_ZGAIN = 3  # torque feedback gain (units of 1/Z); 0: the plain speed PI
PI_WHP = 4  # high-pass corner of the torque feedback
PI_WLP = 5  # low-pass corner
PI_AW = 6  # anti-windup: AW_NONE, AW_BACK, AW_COND
PI_TT = 7  # tracking time of back-calculation (> 0)
# the paper's state feedback (drillstring.model.laws.SampledAffine)
AF_F = 1  # F[0..3] at 1..4
AF_K0 = 5
AF_LATCH = 6  # drillstring.model.control.LATCH_MODES index
AF_SAT = 7  # saturation behaviour: SAT_NONE, SAT_FREEZE
AF_G = 8  # gain on the measured string torque at the top (0: the paper's law)
N_LP = 9

AW_NONE = 0
AW_BACK = 1  # back-calculation
AW_COND = 2  # conditional integration
SAT_NONE = 0
SAT_FREEZE = 1  # the bit-angle state is held while the top drive saturates

#: Law state (``LX`` + index), per kind.
PI_I = 0  # integral of the speed error
PI_Z = 1  # the high-pass's internal low-pass state
PI_Y = 2  # the filtered torque
AF_PHIREF = 0
AF_TWISTREF = 1
AF_X1 = 2  # the bit-angle state held while saturated
AF_HOLD = 3  # 1 while it is held
N_LX = 4

#: Top-drive parameters (``TD`` + index), absolute torques and speeds in scaled units.
TD_ON = 0  # 0: no top-drive model (the command is applied as it is)
TD_RMIN = 1  # torque range [R_min, R_max] (absolute table torque R/C)
TD_RMAX = 2
TD_RATE = 3  # torque rate limit |dR/dtau| (inf: none)
TD_LAG = 4  # time constant of the first-order drive lag (0: none)
TD_PMAX = 5  # power limit |R Omega| (inf: none)
TD_WMIN = 6  # table speed range [Omega_min, Omega_max] (absolute)
TD_WMAX = 7
TD_BRAKE = 8  # 1: four-quadrant; 0: no braking (no torque against the rotation)
N_TD = 9
#: Top-drive state (``TDX`` + index).
TDX_R = 0  # the applied absolute torque at the last committed sample
TDX_T = 1  # the time of that sample
TDX_INIT = 2  # 1 once a sample has been committed
TDX_DT = 3  # its sample period: the time from it to the next sample
N_TDX = 4

#: Sensing parameters (``SN`` + index).
SN_MODE = 0  # SENSE_IDEAL, SENSE_TELEMETRY, SENSE_OBSERVER (the downhole phi, dphi)
SN_PERIOD = 1  # telemetry frame period
SN_LATENCY = 2  # telemetry latency
SN_NPHI = 3  # noise standard deviation of the transmitted phi
SN_NDPHI = 4  # ... of the transmitted dphi
SN_SEED = 5
SN_TORQUE = 6  # TORQUE_TWIST (theta - phi), TORQUE_MOTOR (motor torque - rho dtheta/dtau')
SN_TS = 7  # the observer's sample period (it is discretised with it)
SN_K0 = 8  # K0 of the observer's model (29)
SN_AD = 9  # observer: discrete system matrix (16, row-major) ...
SN_BD = SN_AD + 16  # ... input column (4)
SN_M = SN_BD + 4  # ... filter gain (4 x 2, row-major), measurements y = [dtheta, x3]
N_SN = SN_M + 8
SENSE_IDEAL = 0
SENSE_TELEMETRY = 1
SENSE_OBSERVER = 2
TORQUE_TWIST = 0
TORQUE_MOTOR = 1
#: Telemetry frames kept (ring buffer): latency/period may not exceed N_FRAMES - 2.
N_FRAMES = 64
#: Sensing state (``SNX`` + index).
SNX_NEXT = 0  # time of the next telemetry frame
SNX_K = 1  # frames captured so far
SNX_PREV = 2  # 1 once a sample has been committed (for the torque estimate)
SNX_PT = 3  # sample period, table speed and applied torque of that sample
SNX_PDTHETA = 4
SNX_PR = 5
SNX_XHAT = 6  # observer: prior estimate of x = [phi, dphi, x3, dtheta] (4)
SNX_OBS = 10  # 1 once the observer has been initialised
N_SNX = 11
FR_ARRIVAL = 0  # a frame: arrival time, transmitted phi and dphi
FR_PHI = 1
FR_DPHI = 2
FR_COLS = 3

#: Timing of the controller itself (``TM`` + index; ``docs/controllers.md``, "Timing of a real
#: drive"): the law computes at its own period, its command reaches the drive a latency later.
TM_PERIOD = 0  # the law's sample period (0: every sample of the host, as before)
TM_LATENCY = 1  # computation + fieldbus: command computed -> command at the drive
N_TM = 2
#: Commands on their way to the drive (queue): latency/period may not exceed N_PENDING - 1.
N_PENDING = 16
#: Timing state (``TMX`` + index).
TMX_NEXT = 0  # time of the law's next computation
TMX_LAW = 1  # the law's command of its last computation, held until the next
TMX_HASLAW = 2  # 1 once the law has computed
TMX_CMD = 3  # the command at the drive (the newest that has arrived)
TMX_HASCMD = 4  # 1 once a command has arrived
TMX_NP = 5  # commands on their way
TMX_PEND = 6  # ... each (arrival time, command), oldest first
N_TMX = TMX_PEND + 2 * N_PENDING

#: The block: (name, size) in order; the offsets below are computed from it.
SLOTS: tuple[tuple[str, int], ...] = (
    # the four entries of every FMU io block (drillstring.model.native)
    ("STALE", 1),
    ("RESUME", 1),
    ("TIME", 1),
    ("NSTEPS", 1),
    # an FMU's connectors and unit system
    ("SI", 1),  # 1: the connectors are in SI units (converted with the rig scales below)
    ("IN", 4),  # phi, dphi, theta, dtheta (SI: bit angle, bit speed, table angle, table speed)
    ("OUT", 1),  # R - R0 (SI: the absolute table torque R)
    ("T_STAR", 1),  # rig scales of the SI connectors: t* [s], C [N m/rad], Omega0 [rad/s],
    ("C", 1),  # R0 [N m]
    ("OMEGA0_SI", 1),
    ("R0_SI", 1),
    # switch-on (docs/model.md, "Bumpless switch-on")
    ("ENABLED", 1),
    ("T_ON", 1),
    ("ACTIVE", 1),  # 1 once the law has started (its state is valid)
    # operating point: nominal table speed omega0 and torque R0 (absolute), inertia ratio rho
    ("OMEGA0", 1),
    ("R0", 1),
    ("RHO", 1),
    # the law, the top drive, the sensing
    ("LAW", 1),
    ("LP", N_LP),
    ("LX", N_LX),
    ("TD", N_TD),
    ("TDX", N_TDX),
    ("SN", N_SN),
    ("SNX", N_SNX),
    ("FRAMES", N_FRAMES * FR_COLS),
    # what the last committed sample did (diagnostics)
    ("R_CMD", 1),  # the law's command
    ("R_APP", 1),  # the applied torque (R - R0)
    ("SATURATED", 1),  # 1 if the top drive limited the command
    ("N_SAT", 1),  # samples with the command limited
    ("N_SAMPLES", 1),  # samples committed
    # the controller's own period and latency (appended: the entries above keep their offsets)
    ("TM", N_TM),
    ("TMX", N_TMX),
)


def _offsets(slots: tuple[tuple[str, int], ...]) -> dict[str, int]:
    out: dict[str, int] = {}
    at = 0
    for name, size in slots:
        out[name] = at
        at += size
    out["SIZE"] = at
    return out


OFFSETS = _offsets(SLOTS)
B_STALE = OFFSETS["STALE"]
B_RESUME = OFFSETS["RESUME"]
B_TIME = OFFSETS["TIME"]
B_NSTEPS = OFFSETS["NSTEPS"]
B_SI = OFFSETS["SI"]
B_IN = OFFSETS["IN"]
B_OUT = OFFSETS["OUT"]
B_TSTAR = OFFSETS["T_STAR"]
B_C = OFFSETS["C"]
B_OMEGA0_SI = OFFSETS["OMEGA0_SI"]
B_R0_SI = OFFSETS["R0_SI"]
B_ENABLED = OFFSETS["ENABLED"]
B_TON = OFFSETS["T_ON"]
B_ACTIVE = OFFSETS["ACTIVE"]
B_OMEGA0 = OFFSETS["OMEGA0"]
B_R0 = OFFSETS["R0"]
B_RHO = OFFSETS["RHO"]
B_LAW = OFFSETS["LAW"]
B_LP = OFFSETS["LP"]
B_LX = OFFSETS["LX"]
B_TD = OFFSETS["TD"]
B_TDX = OFFSETS["TDX"]
B_SN = OFFSETS["SN"]
B_SNX = OFFSETS["SNX"]
B_FRAMES = OFFSETS["FRAMES"]
B_RCMD = OFFSETS["R_CMD"]
B_RAPP = OFFSETS["R_APP"]
B_SAT = OFFSETS["SATURATED"]
B_NSAT = OFFSETS["N_SAT"]
B_NSAMPLES = OFFSETS["N_SAMPLES"]
B_TM = OFFSETS["TM"]
B_TMX = OFFSETS["TMX"]
B_SIZE = OFFSETS["SIZE"]
#: The entries of the block that are state (what an FMU state saves besides the time).
STATE_SLOTS = ("ACTIVE", "LX", "TDX", "SNX", "FRAMES", "R_CMD", "R_APP", "SATURATED", "N_SAT",
               "N_SAMPLES", "TMX")  # fmt: skip
