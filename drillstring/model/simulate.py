"""Monolithic simulation API: run the engine over an output grid and collect the results."""

from __future__ import annotations

import math
import os
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any, Self

import numpy as np
from tqdm import tqdm

from drillstring.fileio import write_csv
from drillstring.model.engine import (
    MODE_NAMES,
    OUTPUT_COLUMNS,
    Control,
    Engine,
    EngineOptions,
    Event,
    InitialState,
    Status,
    string_profiles,
    time_in_mode,
)
from drillstring.model.experiments import DEFAULT_DT_OUT
from drillstring.model.kernel import (
    coordinates,
    equations,
    events,
    filippov,
    hermite,
    jit,
    stepper,
)
from drillstring.model.params import REFERENCE, ScaledParams
from drillstring.model.pipe import StringParams
from drillstring.model.prehistory import HistoryFunction
from drillstring.validation import check_real

__all__ = ["COLUMNS", "SimulationResult", "cache_counts", "output_grid", "simulate", "warm_up"]

#: Columns of a simulation result (and of its CSV file).
COLUMNS = OUTPUT_COLUMNS


@dataclass
class SimulationResult:
    """Sampled trajectories (perturbation coordinates), events and the run's outcome.

    The columns (:data:`COLUMNS`) are attributes: ``r.tau``, ``r.du``, ``r.dphi``, ...,
    ``r.R_minus_R0`` (the torque the kernel applied), ``r.mode``. ``status.ok`` is False when
    the run stopped early (bit bouncing, torsional stick outside the model, ...); the arrays then
    end at the stop time, which is the last sample.

    ``profiles`` holds the string along its length at each sample (:func:`~drillstring.model.
    engine.string_profiles`), and the column ``top_torque_minus_R0`` the torque at the top of
    the string less R0 (scaled), what a sub under the top drive measures; on the paper's
    one-mode string it is theta - phi.
    """

    params: ScaledParams
    options: EngineOptions
    data: dict[str, np.ndarray]
    events: list[Event]
    status: Status
    counters: dict[str, int] = field(default_factory=dict)
    string: StringParams = field(default_factory=StringParams)
    profiles: dict[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def of_engine(
        cls,
        engine: Engine,
        params: ScaledParams,
        rows: np.ndarray,
        status: Status,
        columns: Sequence[str] = COLUMNS,
        **fields: Any,
    ) -> Self:
        """The result of ``engine``'s run of ``params``: ``rows`` (one sample a row, the
        ``columns``), the engine's options, events, counters and string, the run's ``status``
        and the subclass's ``fields``."""
        return cls(
            params=params,
            options=engine.options,
            data={c: rows[:, j].copy() for j, c in enumerate(columns)},
            events=engine.events,
            status=status,
            counters=engine.counters,
            string=engine.string,
            **fields,
        )

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

    def axial_stick_fraction(self) -> float:
        """Fraction of the simulated time spent in axial stick, exact from the mode events.

        Returns
        -------
        float
            The time in mode "stick" over [0, tau_end] divided by tau_end, tau_end being the last
            sample (the stop time of a run that stopped early); NaN when tau_end is not > 0. The
            mode at tau = 0 is the first sample's; the events must have been kept
            (``EngineOptions.keep_events``).
        """
        t_end = float(self.tau[-1])
        if not t_end > 0.0:
            return math.nan
        first = MODE_NAMES[int(self.mode[0])]
        return time_in_mode(self.events, "stick", 0.0, t_end, first) / t_end

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write the sampled columns to CSV atomically (temp file + rename).

        Parameters
        ----------
        path : str or path-like
            The file to write.

        Returns
        -------
        Path
            ``path``; the file has the header row :data:`COLUMNS` and one row per sample, floats
            written with ``repr`` (round-trip exact).
        """
        cols = [self.data[c] for c in COLUMNS]
        return write_csv(path, COLUMNS, zip(*(c.tolist() for c in cols), strict=True))

    def profiles_to_csv(self, nodes: str | os.PathLike[str], elements: str | os.PathLike[str]):
        """Write the string along its length at every sample, as two CSV files (atomically).

        Parameters
        ----------
        nodes, elements : str or path-like
            The files: one row per sample and node (``tau_scaled, node, x_scaled,
            phi_node_rad, dphi_node_scaled``: node 0 the rotary table, the last the bit,
            x_scaled its position along the pipe from 0 at the table to 1 at the bit, the
            angle and speed perturbations from the nominal motion), and one row per sample and
            element (``tau_scaled, element, x_scaled, torque_minus_R0_scaled``: the element's
            torque less R0 in units of C; element 0 is the top of the string).

        Returns
        -------
        tuple of Path
            The two paths.
        """
        pr = self.profiles
        tau = self.data["tau"].tolist()

        def rows(values: tuple[np.ndarray, ...], x: np.ndarray):
            for i, t in enumerate(tau):
                for j, xj in enumerate(x.tolist()):
                    yield (t, j, xj, *(float(v[i, j]) for v in values))

        a = write_csv(
            nodes,
            ("tau_scaled", "node", "x_scaled", "phi_node_rad", "dphi_node_scaled"),
            rows((pr["phi_node"], pr["dphi_node"]), pr["x_node"]),
        )
        b = write_csv(
            elements,
            ("tau_scaled", "element", "x_scaled", "torque_minus_R0_scaled"),
            rows((pr["torque_minus_R0"],), pr["x_element"]),
        )
        return a, b


def output_grid(tau_end: float, dt_out: float) -> np.ndarray:
    """The output times of a run: 0, dt_out, 2 dt_out, ..., and tau_end last.

    Parameters
    ----------
    tau_end : float
        End of the run (scaled time), > 0.
    dt_out : float
        Sampling step, > 0.

    Returns
    -------
    ndarray
        Each point is k*dt_out (no accumulated rounding); tau_end replaces the last point
        within 1e-9 dt_out of it, else is appended.
    """
    tau_end = check_real("tau_end", tau_end, lower=0.0)
    dt_out = check_real("dt_out", dt_out, lower=0.0)
    n = int(math.floor(tau_end / dt_out + 1e-9))
    grid = np.arange(n + 1) * dt_out
    if tau_end - grid[-1] > 1e-9 * dt_out:
        grid = np.append(grid, tau_end)
    else:
        grid[-1] = tau_end
    return grid


#: Wall time between two updates of the progress bar.
_PROGRESS_INTERVAL = 0.25


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
    dt_out: float = DEFAULT_DT_OUT,
    options: EngineOptions | None = None,
    progress: bool | None = None,
    times: np.ndarray | None = None,
    string: StringParams | None = None,
) -> SimulationResult:
    """Simulate the model (11)-(14), (17) from tau = 0 to ``tau_end``.

    Parameters
    ----------
    params : ScaledParams
        The scaled parameter set.
    tau_end : float
        End of the run (scaled time).
    control : optional
        The torque law R - R0: None (0), a constant, an
        :class:`~drillstring.model.control.AffineFeedback` (evaluated continuously), or a
        callable ``f(tau, y)`` of the perturbation state.
    initial : InitialState or mapping, optional
        Perturbation at tau = 0, e.g. ``{"dphi": -2.5}`` (Fig. 5).
    history : callable, optional
        Prehistory for tau <= 0 (default: the nominal motion).
    dt_out : float
        Output sampling step; the engine lands on each sample time, so a run equals an FMU
        driven with macro step ``dt_out`` and the same input.
    options : EngineOptions, optional
        Integration options.
    progress : bool, optional
        True/False, or None for a bar that appears only when the run takes more than a second.
    times : array of float, optional
        Increasing output times from 0 to ``tau_end`` instead of the grid of ``dt_out`` (e.g.
        the communication points of an adaptive co-simulation).
    string : StringParams, optional
        The drill pipe (default: the paper's one-mode string).

    Returns
    -------
    SimulationResult
        The sampled columns, events, counters and the outcome (partial on an early stop).
    """
    engine = Engine(
        params, options=options, initial=initial, history=history, control=control, string=string
    )
    grid = output_grid(tau_end, dt_out) if times is None else _times(times, tau_end)
    rows = np.empty((grid.size, len(COLUMNS)))
    nodes = np.empty((grid.size, engine.string_nodes().size))
    n_done = 0
    status = Status("ok", "", 0.0)
    bar = tqdm(
        total=grid.size,
        desc="simulate",
        unit="pt",
        disable=progress is False,
        delay=0.0 if progress else 1.0,
        leave=False,
    )
    chunk = 256
    try:
        while n_done < grid.size and status.ok:
            t0 = time.perf_counter()
            stop = min(grid.size, n_done + chunk)
            got, status = engine.sample(grid[n_done:stop], rows[n_done:stop], nodes[n_done:stop])
            n_done += len(got)
            bar.update(len(got))
            # chunks of about a progress interval: the bar moves, the overhead stays negligible
            elapsed = time.perf_counter() - t0
            if elapsed < 0.5 * _PROGRESS_INTERVAL:
                chunk *= 2
    finally:
        bar.close()
    result = SimulationResult.of_engine(engine, params, rows[:n_done], status)
    result.profiles = string_profiles(params, engine.string, result.data, nodes[:n_done])
    return result


def cache_counts(modules: Iterable[ModuleType]) -> tuple[int, int]:
    """(hits, misses) of numba's cache in this process, summed over the compiled functions of
    ``modules`` (misses: compiled here)."""
    hits = misses = 0
    for module in modules:
        for obj in vars(module).values():
            stats = getattr(obj, "stats", None)
            if hasattr(stats, "cache_hits") and hasattr(stats, "cache_misses"):
                hits += sum(stats.cache_hits.values())
                misses += sum(stats.cache_misses.values())
    return hits, misses


def warm_up() -> dict[str, Any]:
    """Load the compiled kernel from numba's cache (or compile and cache it) with a tiny run.

    Returns
    -------
    dict
        ``jit`` (whether the compiled kernel is used), and with it the dispatchers' cache
        ``cache_hits`` and ``cache_misses`` in this process (misses: compiled here) and the
        ``seconds`` it took.
    """
    info: dict[str, Any] = {"jit": jit.numba_available()}
    if not info["jit"]:
        return info
    t0 = time.perf_counter()
    simulate(REFERENCE, 0.05, dt_out=0.05, initial={"dphi": -0.5}, progress=False)
    hits, misses = cache_counts((stepper, filippov, hermite, events, equations, coordinates))
    info.update(cache_hits=hits, cache_misses=misses, seconds=time.perf_counter() - t0)
    return info
