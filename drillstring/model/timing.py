"""The timing of a real drive's controller: its own sample period and its latency
(``docs/controllers.md``, "Timing of a real drive").

A top drive's supervisory speed loop runs at 10-50 ms on the drive's PLC, and its torque command
reaches the drive's converter over a fieldbus: the command computed from the measurements of an
instant acts from a latency later (computation plus fieldbus, about a period). :class:`Timing`
holds the two numbers; the compiled model is in :mod:`drillstring.model.digital.block`:

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

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from drillstring.model.digital import layout as L
from drillstring.model.tables import Parameter, Scales, table_from_si, table_to_si

__all__ = ["Timing"]


@dataclass(frozen=True)
class Timing:
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
        for p in self.PARAMETERS:
            object.__setattr__(self, p.name, p.check("Timing", getattr(self, p.name)))
        if self.latency > 0.0 and self.period == 0.0:
            raise ValueError(
                f"Timing.latency = {self.latency!r} needs the controller's own period "
                "(Timing.period > 0): the latency is counted from the law's computation"
            )
        if self.latency > (L.N_PENDING - 2) * self.period:
            raise ValueError(
                f"Timing.latency = {self.latency!r} is more than {L.N_PENDING - 2} periods "
                f"({self.period!r}): the controller queues {L.N_PENDING} commands"
            )

    @property
    def is_host(self) -> bool:
        """True for the law at every sample of the host, without latency (the default)."""
        return self.period == 0.0

    def values(self) -> dict[str, Any]:
        """The settings by name (scaled)."""
        return {p.name: getattr(self, p.name) for p in self.PARAMETERS}

    def to_si(self, scales: Scales) -> dict[str, Any]:
        """The settings in seconds, with the rig's t*."""
        return table_to_si(self.PARAMETERS, self.values(), scales)

    @classmethod
    def from_si(cls, scales: Scales, values: dict[str, Any]) -> Timing:
        """The settings of values in seconds, the inverse of :meth:`to_si`.

        Raises
        ------
        ValueError
            An unknown name or a value :class:`Timing` rejects.
        """
        return cls(**table_from_si("Timing.from_si", cls.PARAMETERS, values, scales))

    def pack(self, b: np.ndarray) -> None:
        """Write the settings into the block ``b`` (the timing's state at rest)."""
        b[L.B_TM + L.TM_PERIOD] = self.period
        b[L.B_TM + L.TM_LATENCY] = self.latency
        b[L.B_TMX : L.B_TMX + L.N_TMX] = 0.0
