"""Monolithic twin of the co-simulated closed loop: one solver, the controller law (29)-(31)
evaluated continuously inside the right-hand side (no sample and hold).

It runs the :class:`~drillstring.orchestration.closed_loop.LoopModel` read from the FMUs' own
start values (:func:`~drillstring.orchestration.closed_loop.read_loop_model`), so it describes
the system the co-simulation runs, whatever gains and parameters the FMUs were built with.
"""

from __future__ import annotations

import numpy as np

from drillstring.model.experiments import DEFAULT_DT_OUT
from drillstring.model.simulate import SimulationResult, simulate
from drillstring.orchestration.closed_loop import LoopModel

__all__ = ["run_monolithic"]


def run_monolithic(
    model: LoopModel,
    tau_end: float,
    *,
    dt_out: float = DEFAULT_DT_OUT,
    times: np.ndarray | None = None,
) -> SimulationResult:
    """Simulate plant and controller in one solver.

    Parameters
    ----------
    model : LoopModel
        The closed loop (from :func:`~.closed_loop.read_loop_model`).
    tau_end : float
        End of the run.
    dt_out : float
        Output step.
    times : numpy.ndarray, optional
        Output times from 0 to ``tau_end`` instead of the grid of ``dt_out`` (e.g. the
        communication points of an adaptive co-simulation; the engine lands on each).

    Returns
    -------
    SimulationResult
        The sampled trajectories.
    """
    return simulate(
        model.params,
        tau_end,
        control=model.control,
        initial=model.initial,
        dt_out=dt_out,
        options=model.options,
        progress=False,
        times=times,
    )
