"""The sampled closed loop: a digital controller with zero-order hold on the monolithic engine.

An industrial top-drive controller is digital. At each sample instant tau_k = k*Ts it reads the
measurements, puts out R - R0 and holds it until tau_k + Ts; this is exactly what a controller
FMU does under a fixed-step master with macro step Ts. :func:`simulate_sampled` runs that loop
on the engine's kernel with the controller's compiled sample
(:mod:`drillstring.model.digital.loop`): the same code the controller FMUs run, without Python
between the samples. The paper's law evaluated continuously stays the monolithic path of
:func:`drillstring.model.simulate.simulate`; its sampled form
(:class:`~drillstring.model.laws.SampledAffine`) converges to it as Ts -> 0, to first order.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillstring.model.digital.controller import DigitalController
from drillstring.model.digital.layout import BLOCK
from drillstring.model.digital.loop import EXTRA_COLUMNS, ROW_SIZE, run_sampled_from
from drillstring.model.engine import Engine, EngineOptions, InitialState, Status
from drillstring.model.experiments import DEFAULT_DT_OUT
from drillstring.model.laws import Law
from drillstring.model.params import ScaledParams
from drillstring.model.pipe import StringParams, torsional_chain
from drillstring.model.prehistory import HistoryFunction
from drillstring.model.simulate import COLUMNS, SimulationResult
from drillstring.validation import check_real

__all__ = ["DEFAULT_TS", "SAMPLED_COLUMNS", "SampledResult", "sample_count", "simulate_sampled"]

#: Default sample period of a digital law: the co-simulation's macro step (scaled time).
DEFAULT_TS = 1e-3
#: Columns of a sampled run: the engine's, then the top drive's over the samples since the
#: previous row (sample-exact extremes of the applied torque R/C and the power, and how many
#: samples the drive limited; :mod:`drillstring.model.digital.loop`).
SAMPLED_COLUMNS = (*COLUMNS, *EXTRA_COLUMNS)


@dataclass
class SampledResult(SimulationResult):
    """A :class:`~drillstring.model.simulate.SimulationResult` of a sampled loop.

    ``R_minus_R0`` is the torque the controller applied and the engine held (the value at a row's
    time is the one held from that instant on); the columns ``R_max``, ``R_min`` (absolute
    applied torque R/C), ``P_max`` (|R Omega|) and ``n_saturated`` cover the samples since the
    previous row. ``Ts`` is the sample period and ``controller`` the digital controller.
    """

    Ts: float = DEFAULT_TS
    controller: Any = None

    @property
    def law(self) -> Law:
        """The controller's law."""
        return self.controller.law


def sample_count(tau: float, Ts: float, what: str) -> int:
    """``tau/Ts`` as an integer: the number of sample periods in ``tau``.

    Parameters
    ----------
    tau : float
        A time (scaled) that must be a whole multiple of ``Ts``.
    Ts : float
        Sample period (scaled), > 0 (checked by the caller).
    what : str
        Name of ``tau`` for the error message (``"tau_end"``, ``"dt_out"``).

    Returns
    -------
    int
        ``round(tau/Ts)``.

    Raises
    ------
    ValueError
        ``tau`` differs from ``round(tau/Ts)*Ts`` by more than 1e-9 of ``max(Ts, |tau|)``.
    """
    k = round(tau / Ts)
    if abs(tau - k * Ts) > 1e-9 * max(Ts, abs(tau)):
        raise ValueError(f"{what} = {tau!r} is not a multiple of the sample period Ts = {Ts!r}")
    return int(k)


def simulate_sampled(
    params: ScaledParams,
    controller: DigitalController | Law,
    tau_end: float,
    Ts: float = DEFAULT_TS,
    *,
    initial: InitialState | Mapping[str, float] | None = None,
    history: HistoryFunction | None = None,
    options: EngineOptions | None = None,
    dt_out: float = DEFAULT_DT_OUT,
    string: StringParams | None = None,
) -> SampledResult:
    """Simulate the full model (11)-(14), (17) under a digital controller with zero-order hold.

    At each sample instant tau_k = k*Ts (k = 0, 1, ...): the controller's sample of the plant's
    state (sensing, law, top drive), its applied torque held over [tau_k, tau_k + Ts) as the input
    R - R0 of (13), the controller's state update, the engine's advance to tau_k + Ts.

    Parameters
    ----------
    params : ScaledParams
        The scaled parameter set (also the controller's operating point: omega0, R0, rho).
    controller : DigitalController or Law
        The controller; a law alone runs with exact measurements and no top-drive limits.
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
    string : StringParams, optional
        The drill pipe (default: the paper's one-mode string; ``docs/model.md``, "The
        distributed string"). The rows hold the bit's and the table's signals. On a string of
        N > 1 elements the controller's string torque is the top element's (a sub under the
        top drive: ``top_torque_minus_R0``) and its motor-torque estimate uses the table
        node's inertia rho + kappa/(2N).

    Returns
    -------
    SampledResult
        Rows every ``dt_out`` (and at an early stop), events, counters and status.

    Raises
    ------
    ValueError
        A time that is not a positive multiple of ``Ts``; an observer sampled with another
        period than the one it was discretised with.
    """
    if isinstance(controller, Law):
        controller = DigitalController(controller)
    if not isinstance(controller, DigitalController):
        raise TypeError(f"controller must be a DigitalController or a Law, got {controller!r}")
    Ts = check_real("Ts", Ts, lower=0.0)
    tau_end = check_real("tau_end", tau_end, lower=0.0)
    n = sample_count(tau_end, Ts, "tau_end")
    every = sample_count(check_real("dt_out", dt_out, lower=0.0), Ts, "dt_out")
    if every < 1:
        raise ValueError(f"dt_out = {dt_out!r} must be at least the sample period Ts = {Ts!r}")
    obs = controller.sensing.observer
    if controller.sensing.downhole == "observer" and obs is not None:
        if not math.isclose(obs.Ts, Ts, rel_tol=1e-12):
            raise ValueError(
                f"the observer was discretised with Ts = {obs.Ts!r}, the loop samples with "
                f"Ts = {Ts!r}"
            )
    engine = Engine(params, options=options, initial=initial, history=history, string=string)
    block = controller.block(params)
    if not engine.string.is_paper:
        # the motor-torque estimate's inertia: the table node's, rho + kappa/(2N)
        block[BLOCK.rho] = torsional_chain(engine.string, params.rho).inertia[0]
    rows = np.empty((n // every + 2, ROW_SIZE))
    acc = np.array([-math.inf, math.inf, 0.0, 0.0])
    k, i = 0, 0
    status = Status("ok", "", 0.0)
    keep = engine.options.keep_events
    while True:
        st, k, i = run_sampled_from(
            *engine.kernel_arrays(), block, k, n, Ts, every, rows, i, acc, keep
        )
        st = int(st)
        # the event log drained into the engine's events on every return, the end of the run
        # too (the events since the last full log or history buffer were lost otherwise)
        status = engine.finish(st)
        if st == 0:
            break  # the run reached tau_end: status "ok" at tau_end
        # what needs Python (a buffer to drain or grow, or the stop's status): then the engine
        # finishes the advance of sample k, and the loop goes on from k + 1
        if status is None:
            status = engine.advance(k * Ts + Ts)
        if not status.ok:
            if i == 0 or engine.tau > rows[i - 1, 0]:
                rows[i, : len(COLUMNS)] = _row(engine)
                rows[i, len(COLUMNS) :] = acc
                i += 1
            break
        k += 1
        if k > n:  # pragma: no cover - the loop returns at k == n
            break
    return SampledResult.of_engine(
        engine, params, rows[:i], status, SAMPLED_COLUMNS, Ts=Ts, controller=controller
    )


def _row(engine: Engine) -> list[float]:
    """The output row (:data:`~drillstring.model.simulate.COLUMNS`) at the engine's time."""
    out = engine.outputs()
    return [engine.tau, *(out[c] for c in COLUMNS[1:])]
