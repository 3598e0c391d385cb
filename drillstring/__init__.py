"""drillstring: the axial-torsional drill-string stick-slip model of Besselink, van de Wouw and
Nijmeijer (IEEE CCA 2011), its analysis, LMI controller synthesis and FMI 2.0 co-simulation.

The user API of the model is importable from here::

    import drillstring as ds
    r = ds.simulate(ds.REFERENCE, 60, initial={"dphi": -2.5})

The layers, each importing only those before it: ``drillstring.model`` (Section II: parameters,
engine, simulation, control law), ``drillstring.analysis`` (Section III), ``drillstring.controller``
(Sections IV-V), ``drillstring.orchestration`` (co-simulation of the FMUs), ``drillstring.apps``
(command line, demo, sweeps). ``docs/model.md`` states every reconstruction the results rest on.
"""

from drillstring.model.control import AffineFeedback
from drillstring.model.engine import (
    Engine,
    EngineOptions,
    EngineState,
    Event,
    InitialState,
    Status,
)
from drillstring.model.experiments import DEFAULT_H, FIG5, FIG6, Experiment
from drillstring.model.params import (
    PIPE_RIG,
    REFERENCE,
    REFERENCE_RIG,
    ParameterError,
    PhysicalParams,
    ScaledParams,
    get_params,
    get_physical,
    load_params,
    params_from_spec,
    read_params,
    save_params,
)
from drillstring.model.pipe import StringParams
from drillstring.model.simulate import SimulationResult, simulate

__all__ = [
    "DEFAULT_H",
    "FIG5",
    "FIG6",
    "PIPE_RIG",
    "REFERENCE",
    "REFERENCE_RIG",
    "AffineFeedback",
    "Engine",
    "EngineOptions",
    "EngineState",
    "Event",
    "Experiment",
    "InitialState",
    "ParameterError",
    "PhysicalParams",
    "ScaledParams",
    "SimulationResult",
    "Status",
    "StringParams",
    "get_params",
    "get_physical",
    "load_params",
    "params_from_spec",
    "read_params",
    "save_params",
    "simulate",
]
