"""Adaptive co-simulation: attempt a step, estimate its coupling error, accept or roll back.

Before each step every unit's state is saved (``fmi2GetFMUstate``). After the step the coupling
error is estimated from the exchanged values (:func:`.step_control.coupling_error`); a rejected
step rolls the units back (``fmi2SetFMUstate``, inputs written again) and is retried with a
smaller step (:func:`.step_control.retry_step`); an accepted one is recorded and sets the next
step size (:func:`.step_control.next_step`).
"""

from __future__ import annotations

import numpy as np

from drillstring.orchestration.run import Run
from drillstring.orchestration.step_control import (
    accepts,
    coupling_error,
    next_step,
    retry_step,
    step_to_take,
)

__all__ = ["run_adaptive"]


def run_adaptive(run: Run) -> None:
    """Step-size-controlled co-simulation of a run set up at its start time
    (:meth:`.Run.set_up`) to its stop time, from its first step ``options.step`` with the
    tolerances and limits of ``options.step_control``.

    Parameters
    ----------
    run : Run
        The run: its units (saved and rolled back), their exchange (its inputs are written
        again after a rollback), macro step, recorder (one row per accepted step) and progress
        callback. Counts ``accepted`` (with :meth:`.Run.accept`), ``rejected`` and ``forced``
        steps and logs every attempt in ``step_log``.
    """
    instances, exchange, step, recorder = run.instances, run.exchange, run.step, run.recorder
    control, t_end, h = run.options.step_control, run.options.stop_time, run.options.step
    instances.check_rollback()
    y = exchange.y
    y_n = np.empty_like(y)
    y_prev = np.empty_like(y)
    have_prev = False
    h_prev = h
    t = run.options.start_time
    linear = step.linear
    eps = 1e-12 * max(abs(t_end), 1.0)
    while t < t_end - eps:
        instances.save_states(t)
        np.copyto(y_n, y)
        rejected_here = False
        while True:
            hs = step_to_take(h, t, t_end, control.h_min)
            step.advance(t, hs, y_prev if have_prev else None, h_prev, 0)
            extrapolated = y_prev if linear and have_prev else None
            err, p = coupling_error(y, y_n, extrapolated, hs, h_prev, control)
            accept = accepts(err, hs, control)
            run.step_log.append((t, hs, err, accept))
            if accept:
                break
            run.rejected += 1
            rejected_here = True
            instances.restore_states(t)
            np.copyto(y, y_n)
            exchange.reset_inputs(t)
            h = retry_step(hs, err, p, control)
        if err > 1.0:
            run.forced += 1
        instances.free_states()
        np.copyto(y_prev, y_n)
        have_prev = True
        h_prev = hs
        t = t + hs if t_end - (t + hs) > eps else t_end
        run.accept(hs)
        recorder.record(t)
        if run.accepted % 64 == 0:
            run.progress(t)
        h = next_step(hs, err, p, rejected_here, control)
    run.progress(t)
