"""The model of Section II: parameters, the stepping engine, the monolithic simulation, the
controller law, the digital top-drive laws and their sampled loop, and the paper's experiments
(``docs/model.md``, ``docs/controllers.md``)."""

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
from drillstring.model.laws import Measurement, SampledAffine, SpeedPI, ZTorque
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
from drillstring.model.sampled import SampledResult, simulate_sampled
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
    "Measurement",
    "ParameterError",
    "PhysicalParams",
    "SampledAffine",
    "SampledResult",
    "ScaledParams",
    "SimulationResult",
    "SpeedPI",
    "Status",
    "StringParams",
    "ZTorque",
    "get_params",
    "get_physical",
    "load_params",
    "params_from_spec",
    "read_params",
    "save_params",
    "simulate",
    "simulate_sampled",
]
