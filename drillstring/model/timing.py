"""The timing of a real drive's controller: its own sample period and its latency
(``docs/controllers.md``, "Timing of a real drive").

A top drive's supervisory speed loop runs at 10-50 ms on the drive's PLC, and its torque command
reaches the drive's converter over a fieldbus: the command computed from the measurements of an
instant acts from a latency later (computation plus fieldbus, about a period). :class:`Timing`
holds the two numbers; below it, the model compiled on the timing's section of the controller's
block (:data:`TIMING_SLOTS`; :mod:`drillstring.model.digital.block` calls it):

* ``period`` P: the law computes at the first sample of the host at or after each multiple of
  P, its state advanced by P, and its command is held until its next computation. 0 (the
  default) is the law at every sample of the host (the sampled loop's ``Ts``, an FMU's macro
  step), the controller of before, bit for bit;
* ``latency`` L: the command computed at tau reaches the drive at the first sample of the host
  at or after tau + L; until then the drive keeps the one that arrived before (the feed-forward
  R_ff before the first). L > 0 needs P > 0.

The sensing (the torque estimated from the motor, telemetry frames, the observer) and the top
drive (its limits and lag) act at every sample of the host: they are the drive's and the
sensors', which run faster than the supervisory loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from drillstring.model.kernel.jit import jit_for
from drillstring.model.tables import (
    Parameter,
    Tabled,
    block_layout,
    parameter_slots,
)

__all__ = [
    "N_PENDING",
    "TIMING_SLOTS",
    "Timing",
    "at_drive",
    "held_command",
    "law_due",
    "near",
    "timing_commit",
]

#: Commands on their way to the drive (queue): latency/period may not exceed N_PENDING - 1.
N_PENDING = 16


@dataclass(frozen=True)
class Timing(Tabled):
    """The controller's own sample period and its latency (scaled time).

    Parameters
    ----------
    period : float
        The law's sample period, >= 0 (0: every sample of the host).
    latency : float
        Command computed -> command at the drive, >= 0; > 0 needs ``period`` > 0 and may be at
        most ``(N_PENDING - 2)*period`` (the commands on their way are queued).

    Raises
    ------
    ValueError
        A value out of its range, naming it.
    """

    period: float = 0.0
    latency: float = 0.0

    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter(
            "period",
            "time",
            "The controller's own sample period (the law computes at each multiple of it, its "
            "command held in between); 0: at every communication step",
            0.0,
        ),
        Parameter(
            "latency",
            "time",
            "Latency of the controller (computation and fieldbus): its command reaches the drive "
            "this long after the measurements it was computed from; needs a period > 0",
            0.0,
        ),
    )

    def __post_init__(self) -> None:
        self._check_table()
        if self.latency > 0.0 and self.period == 0.0:
            raise ValueError(
                f"Timing.latency = {self.latency!r} needs the controller's own period "
                "(Timing.period > 0): the latency is counted from the law's computation"
            )
        if self.latency > (N_PENDING - 2) * self.period:
            raise ValueError(
                f"Timing.latency = {self.latency!r} is more than {N_PENDING - 2} periods "
                f"({self.period!r}): the controller queues {N_PENDING} commands"
            )

    def pack(self, b: np.ndarray, at: int) -> None:
        """Write the settings into the controller's block ``b``, whose timing section
        (:data:`TIMING_SLOTS`) is at ``at``, its state at rest."""
        b[at : at + TIMING_SLOTS.size] = 0.0
        for p in self.PARAMETERS:
            b[at + getattr(TIMING_SLOTS, p.name)] = getattr(self, p.name)


#: The timing's state: the time of the law's next computation, the law's command of its last
#: computation (held until the next) and whether it has computed, the command at the drive (the
#: newest that has arrived) and whether one has, the number of commands on their way and the
#: queue of them, each (arrival time, command), oldest first.
_STATE = (
    ("next", 1), ("law", 1), ("has_law", 1), ("cmd", 1), ("has_cmd", 1), ("n_pending", 1),
    ("pending", 2 * N_PENDING),
)  # fmt: skip
#: The timing's section of the controller's block: one slot per :attr:`Timing.PARAMETERS`
#: entry, then the state.
TIMING_SLOTS = block_layout(
    "TimingSlots",
    (*parameter_slots(Timing.PARAMETERS), *_STATE),
    state=[name for name, _ in _STATE],
)


# --------------------------------------------------------------------------------------------
# the timing, compiled: on the block ``b`` whose timing section (TIMING_SLOTS) is at ``at``
# --------------------------------------------------------------------------------------------

inline = jit_for(__name__, inline=True)


@inline
def near(t):
    """The tolerance of "at or after" a time ``t`` (rounding of a host's clock)."""
    return 1e-9 * max(1.0, abs(t))


@inline
def law_due(b, at, tau):
    """True when the law computes at the sample ``tau`` (its period > 0)."""
    nxt = b[at + TIMING_SLOTS.next]
    return tau >= nxt - near(nxt)


@inline
def held_command(b, at, r_ff):
    """The law's command held from its last computation (``r_ff`` before the first)."""
    if b[at + TIMING_SLOTS.has_law] != 0.0:
        return b[at + TIMING_SLOTS.law]
    return r_ff


@inline
def at_drive(b, at, tau, r_law, r_ff):
    """The command at the drive at ``tau`` when the law's command is ``r_law``: ``r_law``
    without latency, else the newest command that has arrived (``r_ff`` before the first)."""
    T = TIMING_SLOTS
    if b[at + T.latency] <= 0.0:
        return r_law
    r_cmd = b[at + T.cmd] if b[at + T.has_cmd] != 0.0 else r_ff
    now = tau + near(tau)
    for i in range(int(b[at + T.n_pending])):
        entry = at + T.pending + 2 * i
        if b[entry] <= now:
            r_cmd = b[entry + 1]
    return r_cmd


@inline
def timing_commit(b, at, tau, due, r_law):
    """The timing's state after the sample ``tau``: the arrived commands taken off the queue,
    the law's new command (``due``: computed at ``tau``) held and put on it, the law's next
    computation."""
    T = TIMING_SLOTS
    q = at + T.pending  # the queue
    period = b[at + T.period]
    latency = b[at + T.latency]
    if latency > 0.0:
        now = tau + near(tau)
        n = int(b[at + T.n_pending])
        k = 0
        while k < n and b[q + 2 * k] <= now:
            b[at + T.cmd] = b[q + 2 * k + 1]
            b[at + T.has_cmd] = 1.0
            k += 1
        for i in range(n - k):
            b[q + 2 * i] = b[q + 2 * (i + k)]
            b[q + 2 * i + 1] = b[q + 2 * (i + k) + 1]
        b[at + T.n_pending] = n - k
    if due:
        b[at + T.law] = r_law
        b[at + T.has_law] = 1.0
        b[at + T.next] = (math.floor(tau / period + 1e-9) + 1.0) * period
        if latency > 0.0:
            n = int(b[at + T.n_pending])
            b[q + 2 * n] = tau + latency
            b[q + 2 * n + 1] = r_law
            b[at + T.n_pending] = n + 1
        else:
            b[at + T.cmd] = r_law
            b[at + T.has_cmd] = 1.0
