"""What a digital controller knows of the string: the sensing settings (``docs/controllers.md``,
"Sensing"), and the sensing compiled.

:class:`Sensing` says how the downhole bit angle and speed reach the law (exact; by mud-pulse
or wired telemetry at a frame period with latency and noise; or estimated at the surface by an
:class:`Observer`) and how the string torque at the top is known (the twist, as from a torque
sub; or from the motor torque and the table acceleration). The observer's gains are designed by
:func:`drillstring.controller.estimation.design_observer` (the model layer only holds numbers).

Below them, the sensing compiled (:func:`sensed`, :func:`sense_commit`, in the subset numba
compiles) on the sensing's section of the controller's block (:data:`SENSING_SLOTS`). The
measurements are the scaled perturbations of (9)-(10).

* The bit angle and speed (downhole): exact (``ideal``); or by telemetry: a frame (phi, dphi
  plus Gaussian noise) is taken at the first sample at or after each multiple of the frame
  period and arrives a latency later; the controller uses the newest frame that has arrived
  (before the first one it takes the nominal motion, phi = dphi = 0); or estimated from surface
  signals alone (``observer``): a Kalman filter on the linearised averaged torsional model (13),
  (27) with the measurements y = [dtheta, x3], x3 = phi - theta - K0 = -(string torque) - K0,
  and the applied torque as its input.
* The string torque at the top, ``top``: what a torque sub under the top drive reads, the
  torque of the string's top element less R0 (the host passes it: theta - phi, the twist, on
  the one-mode string; the kernel's ``top_torque_minus_R0`` on the distributed string,
  ``docs/model.md``, "The distributed string"): exact (``twist``); or from the motor
  (``motor``): by (13), ``rho*dtheta' = (R - R0) - top`` with rho the table node's inertia
  (rho + kappa/(2N) on the string of N elements, the host's ``rho``), so over the last sample,
  with the applied torque held, the mean string torque is ``r_prev - rho*(dtheta -
  dtheta_prev)/(tau - tau_prev)``, exact for the mean (it lags by half a sample), 0 before the
  first sample.

The noise is a counter-based generator (a 32-bit integer hash of the seed, the frame number and
the channel, then Box-Muller), so the Python and the compiled paths give the same numbers and a
run, restored from an FMU state or repeated, draws the same noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from drillstring.model.kernel.jit import jit_for
from drillstring.model.tables import (
    Parameter,
    Scales,
    block_layout,
    parameter_slots,
    table_from_si,
    table_to_si,
)
from drillstring.validation import check_choice, check_int, check_real

__all__ = [
    "DOWNHOLE",
    "FRAME",
    "N_FRAMES",
    "SENSING_SLOTS",
    "TORQUE",
    "Observer",
    "Sensing",
    "gaussian",
    "hash32",
    "sense_commit",
    "sensed",
    "string_torque",
]

#: How the law gets the bit angle and speed (index: the block's code).
DOWNHOLE = ("ideal", "telemetry", "observer")
SENSE_TELEMETRY = DOWNHOLE.index("telemetry")
SENSE_OBSERVER = DOWNHOLE.index("observer")
#: How the law gets the string torque at the top (index: the block's code).
TORQUE = ("twist", "motor")
TORQUE_MOTOR = TORQUE.index("motor")
#: Telemetry frames kept (ring buffer): latency/period may not exceed N_FRAMES - 2.
N_FRAMES = 64
#: A telemetry frame in the ring buffer: its arrival time, the transmitted phi and dphi.
FRAME = block_layout("Frame", (("arrival", 1), ("phi", 1), ("dphi", 1)))


@dataclass(frozen=True)
class Observer:
    """A discrete Kalman filter on the linearised averaged torsional model (13), (27).

    State ``x = [phi, dphi, x3, dtheta]`` with ``x3 = phi - theta - K0`` (the state of (29)),
    measurements ``y = [dtheta, x3]`` (x3 from the string torque the controller knows), input
    ``u = R - R0 + K0``: the prior of the next sample is ``Ad x + Bd u``, the estimate at a
    sample ``x + M (y - C x)``.

    Parameters
    ----------
    Ad : array (4, 4)
        Discrete system matrix over the sample period ``Ts``.
    Bd : array (4,)
        Discrete input column.
    M : array (4, 2)
        Filter gain.
    K0 : float
        K0 of the model (29)-(30).
    Ts : float
        The sample period the matrices are discretised with (scaled); the controller must be
        sampled with it.
    """

    Ad: np.ndarray
    Bd: np.ndarray
    M: np.ndarray
    K0: float
    Ts: float

    def __post_init__(self) -> None:
        for name, shape in (("Ad", (4, 4)), ("Bd", (4,)), ("M", (4, 2))):
            a = np.array(getattr(self, name), dtype=float)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise ValueError(f"Observer.{name} must be finite of shape {shape}, got {a!r}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "K0", check_real("Observer.K0", self.K0))
        object.__setattr__(self, "Ts", check_real("Observer.Ts", self.Ts, lower=0.0))


@dataclass(frozen=True)
class Sensing:
    """How the controller's measurements are made.

    Parameters
    ----------
    downhole : str
        One of :data:`DOWNHOLE`: the bit angle and speed exact ("ideal"), by telemetry, or
        estimated from surface signals ("observer", needs ``observer``).
    period : float
        Telemetry frame period (scaled time), > 0.
    latency : float
        Telemetry latency (scaled time), >= 0, at most ``(N_FRAMES - 2)*period``.
    noise_phi, noise_dphi : float
        Standard deviations of the noise on the transmitted bit angle and speed, >= 0.
    seed : int
        Seed of the telemetry noise, in [0, 2**32).
    torque : str
        One of :data:`TORQUE`: the string torque at the top exact ("twist") or from the motor
        torque and the table acceleration ("motor").
    observer : Observer or None
        The observer of ``downhole = "observer"``.
    """

    downhole: str = "ideal"
    period: float = 1.0
    latency: float = 0.0
    noise_phi: float = 0.0
    noise_dphi: float = 0.0
    seed: int = 0
    torque: str = "twist"
    observer: Observer | None = field(default=None, compare=False)

    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter(
            "downhole",
            "1",
            "How the law gets the bit angle and speed: ideal, telemetry (frames with latency "
            "and noise), or observer (estimated from surface signals)",
            choices=DOWNHOLE,
        ),
        Parameter("period", "time", "Telemetry frame period", 0.0, strict=True),
        Parameter("latency", "time", "Telemetry latency (frame taken to frame used)", 0.0),
        Parameter("noise_phi", "angle", "Noise (standard deviation) of the transmitted angle", 0.0),
        Parameter(
            "noise_dphi", "speed", "Noise (standard deviation) of the transmitted speed", 0.0
        ),
        Parameter("seed", "1", "Seed of the telemetry noise", 0.0),
        Parameter(
            "torque",
            "1",
            "How the law gets the string torque at the top: twist (measured, e.g. a torque sub) "
            "or motor (motor torque minus table inertia times its acceleration)",
            choices=TORQUE,
        ),
    )

    def __post_init__(self) -> None:
        check_choice("Sensing.downhole", self.downhole, DOWNHOLE)
        check_choice("Sensing.torque", self.torque, TORQUE)
        for p in self.PARAMETERS:
            if not p.choices and p.name != "seed":
                object.__setattr__(self, p.name, p.check("Sensing", getattr(self, p.name)))
        seed = check_int("Sensing.seed", self.seed, lower=0, integral_floats=True)
        if seed >= 2**32:
            raise ValueError(f"Sensing.seed must be below 2**32, got {self.seed!r}")
        object.__setattr__(self, "seed", seed)
        if self.latency > (N_FRAMES - 2) * self.period:
            raise ValueError(
                f"Sensing.latency = {self.latency!r} is more than {N_FRAMES - 2} frame periods "
                f"({self.period!r}): the controller keeps {N_FRAMES} frames"
            )
        if self.downhole == "observer" and not isinstance(self.observer, Observer):
            raise ValueError("Sensing.downhole = 'observer' needs an Observer (observer=...)")

    def values(self) -> dict[str, Any]:
        """The settings by name (scaled; the observer excluded)."""
        return {p.name: getattr(self, p.name) for p in self.PARAMETERS}

    def to_si(self, scales: Scales) -> dict[str, Any]:
        """The settings in SI units (s, rad, rad/s), each scaled by its dimension.

        Parameters
        ----------
        scales : PhysicalParams or any object with ``C`` and ``t_star``
            The rig's scales.

        Returns
        -------
        dict
            Name -> SI value.
        """
        return table_to_si(self.PARAMETERS, self.values(), scales)

    @classmethod
    def from_si(cls, scales: Scales, values: dict[str, Any]) -> Sensing:
        """The settings of SI values, the inverse of :meth:`to_si` (no observer).

        Raises
        ------
        ValueError
            An unknown name or a value :class:`Sensing` rejects.
        """
        scaled = table_from_si("Sensing.from_si", cls.PARAMETERS, values, scales)
        if "seed" in values:
            scaled["seed"] = values["seed"]
        return cls(**scaled)

    def pack(self, b: np.ndarray, at: int) -> None:
        """Write the settings (and the observer's numbers) into the controller's block ``b``,
        whose sensing section (:data:`SENSING_SLOTS`) is at ``at``; the state at rest."""
        S = SENSING_SLOTS
        b[at : at + S.size] = 0.0
        for p in self.PARAMETERS:
            value = getattr(self, p.name)
            b[at + getattr(S, p.name)] = p.choices.index(value) if p.choices else value
        o = self.observer
        if o is not None:
            b[at + S.Ts] = o.Ts
            b[at + S.K0] = o.K0
            for name in ("Ad", "Bd", "M"):
                a = getattr(o, name)
                b[at + getattr(S, name) : at + getattr(S, name) + a.size] = a.ravel()


#: The observer's numbers in the sensing's section: its sample period and K0, then Ad (row-major),
#: Bd and M (row-major; the measurements y = [dtheta, x3]).
_OBSERVER = (("Ts", 1), ("K0", 1), ("Ad", 16), ("Bd", 4), ("M", 8))
#: The sensing's state: the time of the next telemetry frame, the frames taken so far, whether a
#: sample has been committed (for the torque estimate) and that sample's period, table speed and
#: applied torque, the observer's prior estimate of x = [phi, dphi, x3, dtheta] and whether it
#: has been initialised, the ring buffer of telemetry frames (:data:`FRAME` each).
_STATE = (
    ("next", 1), ("taken", 1), ("prev", 1), ("prev_dt", 1), ("prev_dtheta", 1), ("prev_r", 1),
    ("xhat", 4), ("observing", 1), ("frames", N_FRAMES * FRAME.size),
)  # fmt: skip
#: The sensing's section of the controller's block: one slot per :attr:`Sensing.PARAMETERS`
#: entry (a choice: its index), the observer's numbers, the state.
SENSING_SLOTS = block_layout(
    "SensingSlots",
    (*parameter_slots(Sensing.PARAMETERS), *_OBSERVER, *_STATE),
    state=[name for name, _ in _STATE],
)


# --------------------------------------------------------------------------------------------
# the sensing, compiled: on the block ``b`` whose sensing section (SENSING_SLOTS) is at ``at``
# --------------------------------------------------------------------------------------------

inline = jit_for(__name__, inline=True)

_MASK32 = 0xFFFFFFFF


@inline
def hash32(x):
    """A 32-bit integer hash (the "lowbias32" mix of C. Wellons), on 0 <= x < 2**32.

    Products are taken modulo 2**32 by masking, which is exact in Python's integers and in the
    compiled code's wrapping 64-bit integers alike."""
    x = x & _MASK32
    x = x ^ (x >> 16)
    x = (x * 0x7FEB352D) & _MASK32
    x = x ^ (x >> 15)
    x = (x * 0x846CA68B) & _MASK32
    x = x ^ (x >> 16)
    return x


@inline
def gaussian(seed, k, channel):
    """A standard normal number for (seed, frame ``k``, ``channel``) by Box-Muller."""
    h = hash32(hash32(hash32(seed) ^ (k & _MASK32)) ^ (k >> 32) ^ (channel * 0x9E3779B1))
    g = hash32(h ^ 0x85EBCA6B)
    u1 = (h + 0.5) / 4294967296.0
    u2 = (g + 0.5) / 4294967296.0
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@inline
def string_torque(b, at, rho, top, dtheta):
    """The string torque at the top less R0 as the controller knows it; ``top`` is its true value
    (theta - phi on the one-mode string), ``rho`` the table node's inertia."""
    S = SENSING_SLOTS
    if int(b[at + S.torque]) != TORQUE_MOTOR:
        return top
    if b[at + S.prev] == 0.0 or not b[at + S.prev_dt] > 0.0:
        return 0.0
    return b[at + S.prev_r] - rho * (dtheta - b[at + S.prev_dtheta]) / b[at + S.prev_dt]


@inline
def _due(b, at, tau):
    """True when a telemetry frame is taken at the sample ``tau``."""
    nxt = b[at + SENSING_SLOTS.next]
    return tau >= nxt - 1e-9 * max(1.0, abs(nxt))


@inline
def _frame(b, at, k, phi, dphi):
    seed = int(b[at + SENSING_SLOTS.seed])
    return (
        phi + b[at + SENSING_SLOTS.noise_phi] * gaussian(seed, k, 0),
        dphi + b[at + SENSING_SLOTS.noise_dphi] * gaussian(seed, k, 1),
    )


@inline
def _observer_view(b, at, theta, dtheta, torque):
    """The observer's filtered estimate x_k|k = x_k|k-1 + M (y - C x_k|k-1)."""
    x = at + SENSING_SLOTS.xhat
    K0 = b[at + SENSING_SLOTS.K0]
    x3 = -torque - K0
    if b[at + SENSING_SLOTS.observing] == 0.0:  # first sample: the state the measurements give
        return (theta - torque, dtheta, x3, dtheta)
    p0, p1, p2, p3 = b[x], b[x + 1], b[x + 2], b[x + 3]
    e0 = dtheta - p3
    e1 = x3 - p2
    m = at + SENSING_SLOTS.M
    return (
        p0 + b[m] * e0 + b[m + 1] * e1,
        p1 + b[m + 2] * e0 + b[m + 3] * e1,
        p2 + b[m + 4] * e0 + b[m + 5] * e1,
        p3 + b[m + 6] * e0 + b[m + 7] * e1,
    )


@inline
def sensed(b, at, rho, tau, phi, dphi, theta, dtheta, top):
    """(phi, dphi, torque) as the controller knows them at the sample ``tau`` (pure); ``top`` is
    the true string torque at the top less R0, ``rho`` the table node's inertia."""
    S = SENSING_SLOTS
    torque = string_torque(b, at, rho, top, dtheta)
    mode = int(b[at + S.downhole])
    if mode == SENSE_TELEMETRY:
        k = int(b[at + S.taken])
        if _due(b, at, tau) and b[at + S.latency] <= 0.0:
            p, dp = _frame(b, at, k, phi, dphi)
            return p, dp, torque
        # frames arrive in the order they were taken: the newest that has arrived
        now = tau + 1e-9 * max(1.0, abs(tau))
        for j in range(k - 1, max(-1, k - 1 - N_FRAMES), -1):
            f = at + S.frames + (j % N_FRAMES) * FRAME.size
            if b[f + FRAME.arrival] <= now:
                return b[f + FRAME.phi], b[f + FRAME.dphi], torque
        return 0.0, 0.0, torque
    if mode == SENSE_OBSERVER:
        xh = _observer_view(b, at, theta, dtheta, torque)
        return xh[0], xh[1], torque
    return phi, dphi, torque


@inline
def sense_commit(b, at, rho, tau, phi, dphi, theta, dtheta, top, r_app, Ts):
    """Commit the sample ``tau`` (period ``Ts``): take a due telemetry frame, propagate the
    observer with the applied torque ``r_app``, keep what the torque estimate needs."""
    S = SENSING_SLOTS
    mode = int(b[at + S.downhole])
    torque = string_torque(b, at, rho, top, dtheta)
    if mode == SENSE_TELEMETRY and _due(b, at, tau):
        k = int(b[at + S.taken])
        p, dp = _frame(b, at, k, phi, dphi)
        f = at + S.frames + (k % N_FRAMES) * FRAME.size
        b[f + FRAME.arrival] = tau + b[at + S.latency]
        b[f + FRAME.phi] = p
        b[f + FRAME.dphi] = dp
        b[at + S.taken] = k + 1
        b[at + S.next] = (k + 1) * b[at + S.period]
    elif mode == SENSE_OBSERVER:
        xf = _observer_view(b, at, theta, dtheta, torque)
        u = r_app + b[at + S.K0]
        a = at + S.Ad
        bd = at + S.Bd
        for i in range(4):
            row = a + 4 * i
            b[at + S.xhat + i] = (
                b[row] * xf[0] + b[row + 1] * xf[1] + b[row + 2] * xf[2] + b[row + 3] * xf[3]
                + b[bd + i] * u
            )  # fmt: skip
        b[at + S.observing] = 1.0
    b[at + S.prev] = 1.0
    b[at + S.prev_dt] = Ts
    b[at + S.prev_dtheta] = dtheta
    b[at + S.prev_r] = r_app
