"""One run of the :class:`~drillstring.orchestration.master.Master`: what it was asked
(:class:`RunOptions`, checked by :meth:`Master.run`) and its state (:class:`Run`: the units,
their exchange, the macro step, the recorder, the progress callback and the step counts), which
:meth:`Run.set_up` initializes and the loops of :mod:`.fixed`, :mod:`.native_loop` and
:mod:`.adaptive` advance.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from drillstring.orchestration.exchange import Exchange
from drillstring.orchestration.instances import Instances
from drillstring.orchestration.recorder import Recorder
from drillstring.orchestration.results import StepStats
from drillstring.orchestration.step import JacobiStep, macro_step
from drillstring.orchestration.step_control import StepControl

__all__ = ["STEP_LOG_DTYPE", "Run", "RunOptions"]

#: The dtype of :meth:`Run.step_table`: one row per attempted step of a controlled run.
STEP_LOG_DTYPE = np.dtype([("time", float), ("h", float), ("error", float), ("accepted", bool)])


@dataclass(frozen=True)
class RunOptions:
    """The options of one run, as :meth:`Master.run` takes and checks them.

    Attributes
    ----------
    start_time, stop_time : float
        The run's span.
    step : float
        The fixed macro step, or the first step of a controlled run.
    step_control : StepControl or None
        Step-size control with rollback (None: fixed steps).
    scheme : {"jacobi", "gauss-seidel"}
        Coupling scheme of a macro step.
    extrapolation : {"zoh", "linear"}
        Inputs over a step.
    exchange : {"propagate", "simple"}
        The exchange after a step.
    grid : {"float", "ns", "sum"}
        Communication points of a fixed-step run (:mod:`.fixed`).
    progress : bool or None
        The progress bar (None: only on a terminal).
    """

    start_time: float
    stop_time: float
    step: float
    step_control: StepControl | None
    scheme: Literal["jacobi", "gauss-seidel"]
    extrapolation: Literal["zoh", "linear"]
    exchange: Literal["propagate", "simple"]
    grid: Literal["float", "ns", "sum"]
    progress: bool | None


class Run:
    """One run on fresh instances: its units and, from :meth:`set_up` on, their exchange, the
    macro step and the recorder; the step counts the loops keep.

    Parameters
    ----------
    options : RunOptions
        What the run was asked.
    instances : Instances
        The units, not instantiated yet (the caller releases them).
    record : sequence of str
        The extra ``"unit.var"`` to record.
    progress : callable
        Called with the simulated time now and then.

    Attributes
    ----------
    accepted : int
        Steps taken (recorded rows after the first).
    rejected, forced : int
        A controlled run's retried steps, and those accepted at ``h_min`` although the error
        estimate was above tolerance.
    h_min, h_max : float
        The range of a controlled run's accepted steps.
    step_log : list
        ``(t, h, error, accepted)`` of every attempt of a controlled run.
    """

    exchange: Exchange
    step: JacobiStep
    recorder: Recorder | None

    def __init__(
        self,
        options: RunOptions,
        instances: Instances,
        record: Sequence[str],
        progress: Callable[[float], None],
    ) -> None:
        self.options = options
        self.instances = instances
        self.record = tuple(record)
        self.progress = progress
        self.recorder = None
        self.accepted = 0
        self.rejected = 0
        self.forced = 0
        self.h_min = math.inf
        self.h_max = 0.0
        self.step_log: list[tuple[float, float, float, bool]] = []

    def set_up(self) -> None:
        """Instantiate the units and initialize them (FMI 2.0 section 4.2.4): every input holds
        its source's value, and the first row is recorded at the start time.

        Raises
        ------
        UnitFailure
            For the first FMI call that fails.
        """
        o, instances = self.options, self.instances
        t0 = o.start_time
        instances.instantiate(t0, o.stop_time)
        self.exchange = exchange = Exchange(instances, o.exchange == "simple")
        self.recorder = Recorder(instances, exchange, self.record)
        self.step = macro_step(instances, exchange, o.scheme, o.extrapolation)
        instances.enter_initialization(t0)
        exchange.exchange(t0)
        instances.exit_initialization(t0)
        exchange.exchange(t0)
        self.recorder.record(t0)

    def accept(self, h: float) -> None:
        """Count an accepted step of size ``h`` of a controlled run."""
        self.accepted += 1
        self.h_min = min(self.h_min, h)
        self.h_max = max(self.h_max, h)

    def stats(self, wall_time: float) -> StepStats:
        """The step counts, ``h_min`` and ``h_max`` NaN without an accepted step (a fixed-step
        run's steps are the differences of its recorded times).

        Parameters
        ----------
        wall_time : float
            Seconds the run took.

        Returns
        -------
        StepStats
            The counts.
        """
        h_min, h_max = self.h_min, self.h_max
        if self.options.step_control is None and self.recorder is not None and self.recorder.n > 1:
            steps = np.diff(self.recorder.times())
            h_min, h_max = float(steps.min()), float(steps.max())
        return StepStats(
            accepted=self.accepted,
            rejected=self.rejected,
            forced=self.forced,
            h_min=h_min if self.accepted else math.nan,
            h_max=h_max if self.accepted else math.nan,
            wall_time=wall_time,
        )

    def step_table(self) -> np.ndarray | None:
        """The attempts of a controlled run as a structured array (:data:`STEP_LOG_DTYPE`);
        None for a fixed-step run."""
        if self.options.step_control is None:
            return None
        return np.array(self.step_log, dtype=STEP_LOG_DTYPE)
