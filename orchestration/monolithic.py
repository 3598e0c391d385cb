"""Monolithic reference of the co-simulated closed loop: one solver, the controller law of
(29)-(31) evaluated continuously inside the right-hand side (no sample-and-hold).

It reads the same gains file the controller FMU is built from, and uses the parameter set
stored in it, so the two runs describe the same system.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

from drillstring.controller.gains import GainsFile, read_gains
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import EngineOptions
from drillstring.model.params import ScaledParams
from drillstring.model.simulate import SimulationResult, simulate


def closed_loop_law(gains: GainsFile, t_on: float = 0.0, latch: str = "none") -> AffineFeedback:
    """The controller FMU's law as a continuous :class:`AffineFeedback`."""
    return AffineFeedback(F=gains.F, K0=gains.K0, R_ff=gains.R_ff, t_on=t_on, latch=latch)


def run_monolithic(
    gains: GainsFile | str | os.PathLike[str],
    tau_end: float,
    *,
    initial: Mapping[str, float] | None = None,
    t_on: float = 0.0,
    latch: str = "none",
    enabled: bool = True,
    params: ScaledParams | None = None,
    options: EngineOptions | None = None,
    dt_out: float = 1e-2,
    progress: bool | None = None,
) -> SimulationResult:
    """Simulate plant + controller in one solver. ``enabled=False`` applies R_ff only."""
    g = gains if isinstance(gains, GainsFile) else read_gains(gains)
    p = params or g.params
    control: float | AffineFeedback = closed_loop_law(g, t_on, latch) if enabled else g.R_ff
    return simulate(
        p,
        tau_end,
        control=control,
        initial=initial,
        dt_out=dt_out,
        options=options,
        progress=progress,
    )
