"""The model of Section II: parameters, the stepping engine, the monolithic simulation, the
controller law and the paper's experiments (``docs/model.md``)."""

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
from drillstring.model.simulate import SimulationResult, simulate

__all__ = [
    "DEFAULT_H",
    "FIG5",
    "FIG6",
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
    "get_params",
    "get_physical",
    "load_params",
    "params_from_spec",
    "read_params",
    "save_params",
    "simulate",
]
