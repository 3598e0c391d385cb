"""Monolithic simulation API: run the engine over an output grid and collect the results."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from drillstring.fileio import write_csv
from drillstring.model.engine import Control, Engine, EngineOptions, Event, InitialState, Status
from drillstring.model.params import ScaledParams
from drillstring.model.prehistory import HistoryFunction

COLUMNS = ("tau", "u", "du", "phi", "dphi", "theta", "dtheta", "d", "g", "tau_n", "mode")


@dataclass
class SimulationResult:
    """Sampled trajectories (perturbation coordinates), events and the run's outcome.

    ``status.ok`` is False when the run stopped early (bit bouncing, torsional stick outside the
    model, ...); the arrays then end at the stop time, which is the last sample.
    """

    params: ScaledParams
    options: EngineOptions
    data: dict[str, np.ndarray]
    events: list[Event]
    status: Status
    counters: dict[str, int] = field(default_factory=dict)

    def __getattr__(self, name: str) -> np.ndarray:
        data = self.__dict__.get("data", {})
        if name in data:
            return data[name]
        raise AttributeError(name)

    @property
    def flags(self) -> dict[str, bool]:
        """Validity flags: did the bit bounce, did torsional stick occur."""
        return {
            "bit_bounce": self.counters.get("bit_bounce_events", 0) > 0
            or self.status.code == "bit_bounce",
            "torsional_stick": self.counters.get("torsional_stick_events", 0) > 0
            or self.status.code == "torsional_stick",
        }

    def stick_events(self) -> list[Event]:
        """Entries into axial stick (slip or up -> stick)."""
        return [e for e in self.events if e.kind == "mode" and e.to_mode == "stick"]

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write the sampled columns to CSV atomically (temp file + rename)."""
        cols = [self.data[c] for c in COLUMNS]
        return write_csv(path, COLUMNS, zip(*(c.tolist() for c in cols), strict=True))


def output_grid(tau_end: float, dt_out: float) -> np.ndarray:
    """0, dt, 2 dt, ..., with tau_end as the last point (each point k*dt, no accumulation)."""
    if not (math.isfinite(tau_end) and tau_end > 0):
        raise ValueError(f"tau_end must be a positive finite time, got {tau_end!r}")
    if not (math.isfinite(dt_out) and dt_out > 0):
        raise ValueError(f"dt_out must be a positive finite step, got {dt_out!r}")
    n = int(math.floor(tau_end / dt_out + 1e-9))
    grid = np.arange(n + 1) * dt_out
    if tau_end - grid[-1] > 1e-9 * dt_out:
        grid = np.append(grid, tau_end)
    else:
        grid[-1] = tau_end
    return grid


def _times(times: np.ndarray, tau_end: float) -> np.ndarray:
    t = np.asarray(times, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("times must be increasing finite output times, at least two")
    if t[0] != 0.0 or t[-1] != tau_end:
        raise ValueError(
            f"times must run from 0 to tau_end = {tau_end!r}, got {t[0]!r} .. {t[-1]!r}"
        )
    return t


def simulate(
    params: ScaledParams,
    tau_end: float,
    control: Control = None,
    initial: InitialState | Mapping[str, float] | None = None,
    history: HistoryFunction | None = None,
    dt_out: float = 1e-2,
    options: EngineOptions | None = None,
    progress: bool | None = None,
    times: np.ndarray | None = None,
) -> SimulationResult:
    """Simulate the model (11)-(14), (17) from tau = 0 to ``tau_end``.

    ``control`` is the torque law R - R0: None (0), a constant, an
    :class:`~drillstring.model.control.AffineFeedback` (evaluated continuously), or a callable
    ``f(tau, y)``. Outputs are sampled every ``dt_out``; the engine lands on each sample time,
    so a run equals an FMU driven with macro step ``dt_out`` and the same input. ``progress``:
    True/False, or None for a bar that appears only when the run takes more than a second.
    ``times``: increasing output times from 0 to ``tau_end`` instead of the grid of ``dt_out``
    (e.g. the communication points of an adaptive co-simulation).
    """
    engine = Engine(params, options=options, initial=initial, history=history, control=control)
    grid = output_grid(float(tau_end), float(dt_out)) if times is None else _times(times, tau_end)
    rows = np.full((grid.size, len(COLUMNS)), np.nan)
    status = Status("ok", "", 0.0)
    n_done = 0
    bar = tqdm(
        total=grid.size,
        desc="simulate",
        unit="pt",
        disable=progress is False,
        delay=0.0 if progress else 1.0,
        leave=False,
    )
    try:
        for i, t in enumerate(grid):
            if i > 0:
                status = engine.advance(t)
            out = engine.outputs()
            rows[i, 0] = engine.tau
            for j, c in enumerate(COLUMNS[1:], start=1):
                rows[i, j] = out[c]
            n_done = i + 1
            bar.update(1)
            if not status.ok:
                break
    finally:
        bar.close()
    rows = rows[:n_done]
    data = {c: rows[:, j].copy() for j, c in enumerate(COLUMNS)}
    return SimulationResult(
        params=params,
        options=engine.options,
        data=data,
        events=engine.events,
        status=status,
        counters=engine.counters,
    )
