"""The sampled closed loop: a digital control law with zero-order hold on the monolithic engine.

An industrial top-drive controller is digital. At each sample instant tau_k = k*Ts it reads the
measurements, puts out R - R0 and holds it until tau_k + Ts; this is exactly what a controller
FMU does under a fixed-step master with macro step Ts. :func:`simulate_sampled` runs that loop
on :class:`~drillstring.model.engine.Engine`: the law (:mod:`drillstring.model.laws`) is
evaluated by :func:`~drillstring.model.laws.sample_output` and
:func:`~drillstring.model.laws.sample_update`, the engine holds the torque
(:meth:`~drillstring.model.engine.Engine.set_input`) and integrates over the period
(:meth:`~drillstring.model.engine.Engine.advance`). The paper's law evaluated continuously stays
the monolithic path of :func:`drillstring.model.simulate.simulate`; its sampled form
(:class:`~drillstring.model.laws.SampledAffine`) converges to it as Ts -> 0, to first order.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillstring.model.engine import Engine, EngineOptions, InitialState, Status
from drillstring.model.experiments import DEFAULT_DT_OUT
from drillstring.model.laws import Law, measure, sample_output, sample_update
from drillstring.model.params import ScaledParams
from drillstring.model.prehistory import HistoryFunction
from drillstring.model.simulate import COLUMNS, SimulationResult
from drillstring.validation import check_real

__all__ = ["DEFAULT_TS", "SampledResult", "sample_count", "simulate_sampled"]

#: Default sample period of a digital law: the co-simulation's macro step (scaled time).
DEFAULT_TS = 1e-3


@dataclass
class SampledResult(SimulationResult):
    """A :class:`~drillstring.model.simulate.SimulationResult` of a sampled loop.

    ``R_minus_R0`` is the torque the law put out and the engine held (the value at a row's
    time is the one held from that instant on). ``Ts`` is the sample period and ``law`` the law.
    """

    Ts: float = DEFAULT_TS
    law: Any = None


def sample_count(tau: float, Ts: float, what: str) -> int:
    """``tau/Ts`` as an integer, or a ValueError naming ``what`` if it is not one (to 1e-9)."""
    k = round(tau / Ts)
    if abs(tau - k * Ts) > 1e-9 * max(Ts, abs(tau)):
        raise ValueError(f"{what} = {tau!r} is not a multiple of the sample period Ts = {Ts!r}")
    return int(k)


def simulate_sampled(
    params: ScaledParams,
    law: Law,
    tau_end: float,
    Ts: float = DEFAULT_TS,
    *,
    initial: InitialState | Mapping[str, float] | None = None,
    history: HistoryFunction | None = None,
    options: EngineOptions | None = None,
    dt_out: float = DEFAULT_DT_OUT,
) -> SampledResult:
    """Simulate the full model (11)-(14), (17) under a digital law with zero-order hold.

    At each sample instant tau_k = k*Ts (k = 0, 1, ...): the measurements of the state
    (:func:`~drillstring.model.laws.measure`), the law's output held over [tau_k, tau_k + Ts)
    as the input R - R0 of (13), the law's state update, the engine's advance to tau_k + Ts.

    Parameters
    ----------
    params : ScaledParams
        The scaled parameter set.
    law : Law
        A law of :mod:`drillstring.model.laws` (its ``t_on`` is the switch-on time).
    tau_end : float
        End of the run, a multiple of ``Ts``.
    Ts : float
        Sample period (scaled time), > 0.
    initial : InitialState or mapping, optional
        Perturbation at tau = 0, e.g. ``{"dphi": -4.9}`` (Fig. 6).
    history : callable, optional
        Prehistory for tau <= 0 (default: the nominal motion).
    options : EngineOptions, optional
        Integration options (step h, torsional stick, ...); each period is split into equal
        steps no longer than h.
    dt_out : float
        Output sampling, a multiple of ``Ts``.

    Returns
    -------
    SampledResult
        Rows every ``dt_out`` (and at an early stop), events, counters and status.
    """
    Ts = check_real("Ts", Ts, lower=0.0)
    tau_end = check_real("tau_end", tau_end, lower=0.0)
    n = sample_count(tau_end, Ts, "tau_end")
    every = sample_count(check_real("dt_out", dt_out, lower=0.0), Ts, "dt_out")
    if every < 1:
        raise ValueError(f"dt_out = {dt_out!r} must be at least the sample period Ts = {Ts!r}")
    engine = Engine(params, options=options, initial=initial, history=history)
    rows = np.empty((n // every + 2, len(COLUMNS)))
    n_rows = 0
    state = None
    status = Status("ok", "", 0.0)
    for k in range(n + 1):
        tau = k * Ts
        m = measure(engine.perturbation())
        engine.set_input(sample_output(law, tau, state, m))
        if k % every == 0 or k == n:
            rows[n_rows] = _row(engine)
            n_rows += 1
        if k == n:
            break
        state = sample_update(law, tau, state, m, Ts)
        status = engine.advance((k + 1) * Ts)
        if not status.ok:
            if engine.tau > rows[n_rows - 1, 0]:
                rows[n_rows] = _row(engine)
                n_rows += 1
            break
    rows = rows[:n_rows]
    data = {c: rows[:, j].copy() for j, c in enumerate(COLUMNS)}
    return SampledResult(
        params=params,
        options=engine.options,
        data=data,
        events=engine.events,
        status=status,
        counters=engine.counters,
        Ts=Ts,
        law=law,
    )


def _row(engine: Engine) -> list[float]:
    """The output row (:data:`~drillstring.model.simulate.COLUMNS`) at the engine's time."""
    out = engine.outputs()
    return [engine.tau, *(out[c] for c in COLUMNS[1:])]
