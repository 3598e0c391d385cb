"""Adaptive co-simulation: attempt a step, estimate its coupling error, accept or roll back.

Before each step every unit's state is saved (``fmi2GetFMUstate``). After the step the coupling
error is estimated from the exchanged values (:func:`.step_control.coupling_error`); a rejected
step rolls the units back (``fmi2SetFMUstate``, inputs written again) and is retried with a
smaller step (:func:`.step_control.retry_step`); an accepted one is recorded and sets the next
step size (:func:`.step_control.next_step`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from drillstring.orchestration.exchange import Exchange
from drillstring.orchestration.instances import Instances
from drillstring.orchestration.recorder import Recorder
from drillstring.orchestration.step import JacobiStep
from drillstring.orchestration.step_control import (
    StepControl,
    accepts,
    coupling_error,
    next_step,
    retry_step,
    step_to_take,
)

__all__ = ["run_adaptive"]


def run_adaptive(
    step: JacobiStep,
    instances: Instances,
    exchange: Exchange,
    recorder: Recorder,
    stats: dict,
    step_log: list[tuple[float, float, float, bool]],
    t0: float,
    t_end: float,
    h: float,
    control: StepControl,
    progress: Callable[[float], None],
) -> None:
    """Step-size-controlled co-simulation from ``t0`` (initialized and recorded) to ``t_end``.

    Parameters
    ----------
    step : JacobiStep or GaussSeidelStep
        The macro step.
    instances : Instances
        The units (saved and rolled back).
    exchange : Exchange
        Their exchange (its inputs are written again after a rollback).
    recorder : Recorder
        Receives one row per accepted step.
    stats : dict
        Counts ``accepted``, ``rejected``, ``forced`` steps and the range ``h_min``,
        ``h_max`` of the accepted ones.
    step_log : list
        Receives ``(t, h, err, accepted)`` of every attempt.
    t0, t_end : float
        Start and stop time.
    h : float
        First step to attempt.
    control : StepControl
        Tolerances and limits.
    progress : callable
        Called with the simulated time now and then.
    """
    instances.check_rollback()
    y = exchange.y
    y_n = np.empty_like(y)
    y_prev = np.empty_like(y)
    have_prev = False
    h_prev = h
    t = t0
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
            step_log.append((t, hs, err, accept))
            if accept:
                break
            stats["rejected"] += 1
            rejected_here = True
            instances.restore_states(t)
            np.copyto(y, y_n)
            exchange.reset_inputs(t)
            h = retry_step(hs, err, p, control)
        if err > 1.0:
            stats["forced"] += 1
        instances.free_states()
        np.copyto(y_prev, y_n)
        have_prev = True
        h_prev = hs
        t = t + hs if t_end - (t + hs) > eps else t_end
        stats["accepted"] += 1
        stats["h_min"] = min(stats["h_min"], hs)
        stats["h_max"] = max(stats["h_max"], hs)
        recorder.record(t)
        if stats["accepted"] % 64 == 0:
            progress(t)
        h = next_step(hs, err, p, rejected_here, control)
    progress(t)
