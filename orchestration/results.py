"""Results of a co-simulation run: trajectories, step statistics, failure report, CSV.

The CSV follows the FMI Cross-Check conventions: comma separated, first line the
variable names in double quotes, ``"time"`` first, one row per communication point,
values with round-trip precision (``%.17g``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drillstring.fileio import atomic_write

__all__ = ["FmuFailure", "StepStats", "CosimResult", "write_csv"]


@dataclass(frozen=True)
class FmuFailure:
    """Which unit failed, in which FMI call, at what time, and what it logged."""

    unit: str
    function: str
    status: str
    #: communication point at which the failing call started
    time: float
    #: macro step being attempted (None outside doStep)
    step_size: float | None
    #: the unit's log messages (most recent last)
    messages: tuple[str, ...] = ()
    #: fmi2LastSuccessfulTime when the FMU reports it after a discard
    last_successful_time: float | None = None

    def __str__(self) -> str:
        where = f"t={self.time!r}" + (f", h={self.step_size!r}" if self.step_size else "")
        msg = "; ".join(self.messages[-3:]) if self.messages else "no log message"
        return f"unit {self.unit!r}: {self.function} returned {self.status} at {where}: {msg}"

    @property
    def in_setup(self) -> bool:
        """Whether the unit failed before the first macro step: in instantiation, setting up
        the experiment, setting start values or initialization, i.e. it refused its input
        (a GUID, a parameter value) rather than leaving its model during the run."""
        return self.function != "fmi2DoStep"

    def line(self, kind: str = "unit") -> str:
        """The failure on one line: the unit (called ``kind``: an SSP component), the call, the
        time and what the unit logged at error level (its last messages if none), so that a
        bad value is named with its variable, e.g. ``unit 'plant': fmi2SetReal (psi) returned
        error at t=0.0: [error] ... parameter psi = -1.5 rejected: ScaledParams.psi must be
        > 0, got -1.5 ...``."""
        errors = [m for m in self.messages if m.startswith(("[error]", "[fatal]"))]
        msg = "; ".join(errors[-3:] or self.messages[-3:]) or "no log message"
        where = f"t={self.time!r}" + (f", h={self.step_size!r}" if self.step_size else "")
        text = f"{kind} {self.unit!r}: {self.function} returned {self.status} at {where}: {msg}"
        return " ".join(text.split())


@dataclass(frozen=True)
class StepStats:
    """Step counts of a run (adaptive runs reject and retry steps)."""

    accepted: int
    rejected: int = 0
    #: steps accepted at h_min although the error estimate was above tolerance
    forced: int = 0
    h_min: float = float("nan")
    h_max: float = float("nan")
    wall_time: float = 0.0

    @property
    def attempted(self) -> int:
        """Macro steps actually computed by the units (accepted + rejected)."""
        return self.accepted + self.rejected


@dataclass(frozen=True)
class CosimResult:
    """Trajectories at the communication points and how the run went.

    ``data`` is a numpy structured array with field ``"time"`` then ``"unit.var"`` for
    every connected output, every connected input (the exchanged value: equal to its
    source output at the same communication point) and every requested variable.
    ``failure`` is None when the run reached the stop time.
    """

    data: np.ndarray
    stats: StepStats
    failure: FmuFailure | None = None
    #: (unit, status, category, message) of every message the FMUs logged
    log: tuple[tuple[str, str, str, str], ...] = ()
    #: adaptive runs: structured array (time, h, error, accepted) of every attempt
    step_log: np.ndarray | None = field(default=None, repr=False)

    @property
    def completed(self) -> bool:
        """The run reached the stop time (no failure)."""
        return self.failure is None

    @property
    def time(self) -> np.ndarray:
        """The communication points (``data["time"]``)."""
        return self.data["time"]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.data[name]

    def to_csv(self, path: str | os.PathLike) -> Path:
        """Write ``data`` as FMI Cross-Check CSV (see :func:`write_csv`).

        Parameters
        ----------
        path : path
            The CSV file.

        Returns
        -------
        Path
            ``path``.
        """
        return write_csv(self.data, path)


def write_csv(data: np.ndarray, path: str | os.PathLike) -> Path:
    """Write a structured array as FMI Cross-Check CSV, atomically.

    The file is written next to ``path`` under a temporary name and renamed over it, so
    readers never see a partial file.

    Parameters
    ----------
    data : numpy.ndarray
        Structured array whose first field is ``"time"``.
    path : path
        The CSV file.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        If the first field is not ``"time"`` or a name cannot be quoted.
    """
    names = data.dtype.names
    if not names or names[0] != "time":
        raise ValueError(f"first field must be 'time', got {names}")
    for n in names:
        if '"' in n or "\n" in n:
            raise ValueError(f"variable name {n!r} cannot be written in a quoted CSV header")
    path = Path(path)
    header = ",".join(f'"{n}"' for n in names)
    table = np.column_stack([np.asarray(data[n], dtype=float) for n in names])

    def write(fh) -> None:
        fh.write((header + "\n").encode())
        if len(table):
            np.savetxt(fh, table, fmt="%.17g", delimiter=",")

    return atomic_write(path, write)
