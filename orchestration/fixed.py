"""Fixed-step co-simulation: the communication grid and the loop over it.

Communication points (:func:`run_fixed`):

* ``grid="float"``: ``t_k = t0 + k*H``; every full step passes the nominal ``H`` to the units;
* ``grid="ns"``: libcosim's integer-nanosecond grid, ``t_k = (t0_ns + k*H_ns)/1e9`` with
  ``H_ns = round(H*1e9)``, ``t0_ns = round(t0*1e9)`` (integers, then one division: exactly
  what libcosim passes to ``fmi2DoStep``), step ``t_{k+1} - t_k`` in double;
* ``grid="sum"``: ``t_{k+1} = t_k + H`` accumulated in double, every step ``H``: the grid of
  Ecos and of fmpy's SSP simulator (it drifts from ``k*H`` by rounding, about 4e-11 after 55 000
  steps of 1 ms).

A last step shorter than ``H`` ends on the stop time in all grids.

Both loops, the C loop of a Jacobi run (zero-order hold or linear extrapolation,
:mod:`.native_loop`) and the Python loop below (other runs, or without the C loop), step through
the points of :func:`grid_points`; their rows are the same bits (tested).
"""

from __future__ import annotations

import math

import numpy as np

from drillstring.orchestration import native_loop
from drillstring.orchestration.run import Run

__all__ = ["grid_points", "n_steps", "run_fixed"]


def n_steps(span: float, h: float) -> tuple[int, bool]:
    """Number of fixed steps that cover ``span``, and whether they all equal ``h``.

    Parameters
    ----------
    span : float
        Length of the run.
    h : float
        Macro step.

    Returns
    -------
    n : int
        Number of steps.
    exact : bool
        True when ``n*h`` equals ``span`` to ``1e-9 h``; otherwise the last step is shorter.
    """
    n = round(span / h)
    if n >= 1 and abs(n * h - span) <= 1e-9 * h:
        return n, True
    return max(1, math.ceil(span / h)), False


def grid_points(
    t0: float, t_end: float, h: float, ns_grid: bool, sum_grid: bool
) -> tuple[np.ndarray, np.ndarray]:
    """The communication points of a fixed-step run and the steps passed to the units.

    The points both loops of :func:`run_fixed` step through (module docstring), computed with
    numpy (integer nanoseconds in int64, the sum grid accumulated in order by
    ``np.add.accumulate``).

    Parameters
    ----------
    t0, t_end, h : float
        Start, stop time and macro step.
    ns_grid, sum_grid : bool
        libcosim's nanosecond grid, or the time accumulated (``t + H``, Ecos's grid); neither:
        ``t0 + k*H`` (module docstring).

    Returns
    -------
    times : numpy.ndarray
        ``t_0 = t0, ..., t_N``.
    steps : numpy.ndarray
        ``h_0, ..., h_{N-1}``: the step from ``t_k`` passed to ``fmi2DoStep``.
    """
    n_total, exact = n_steps(t_end - t0, h)
    full = n_total if exact else n_total - 1  # steps on the grid (the last may end on t_end)
    k = np.arange(1, full + 1)
    times = np.empty(n_total + 1)
    times[0] = t0
    steps = np.full(n_total, h)
    if ns_grid:
        h_ns, t0_ns = round(h * 1e9), round(t0 * 1e9)
        times[1 : full + 1] = (t0_ns + k.astype(np.int64) * h_ns) / 1e9
        steps[:full] = np.diff(times[: full + 1])
    elif sum_grid:
        times[: full + 1] = np.add.accumulate(np.concatenate(([t0], steps[:full])))
    else:
        times[1 : full + 1] = t0 + k * h
        times[n_total] = t_end
    if not exact:
        times[n_total] = t_end
        steps[n_total - 1] = t_end - times[n_total - 1]
    return times, steps


def run_fixed(run: Run) -> None:
    """Fixed-step co-simulation of a run set up at its start time (:meth:`.Run.set_up`) to its
    stop time, on the grid of its ``options.grid`` (module docstring), counting the steps in
    ``run.accepted``.

    Parameters
    ----------
    run : Run
        The run: its macro step, recorder, progress callback and options.
    """
    o, step, recorder, progress = run.options, run.step, run.recorder, run.progress
    t0, h = o.start_time, o.step
    times, steps = grid_points(t0, o.stop_time, h, o.grid == "ns", o.grid == "sum")
    recorder.reserve(len(times))  # exact size: no growth in the loop
    if native_loop.supported(step):
        native_loop.run_native(run, times, steps)
        return
    y = step.y
    need_prev = step.linear
    y_prev = np.empty_like(y) if need_prev else None
    y_save = np.empty_like(y) if need_prev else None
    have_prev = False
    h_prev = h
    t = t0
    record, advance = recorder.record, step.advance
    for n, (hn, t_next) in enumerate(zip(steps.tolist(), times[1:].tolist(), strict=True), 1):
        if need_prev:
            np.copyto(y_save, y)
        advance(t, hn, y_prev if have_prev else None, h_prev, 1)
        if need_prev:
            np.copyto(y_prev, y_save)
            have_prev = True
        h_prev = hn
        t = t_next
        run.accepted = n
        record(t)
        if n & 255 == 0:
            progress(t)
    progress(t)
