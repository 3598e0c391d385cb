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

from drillstring.model import (
    DEFAULT_H,
    FIG5,
    FIG6,
    PIPE_RIG,
    REFERENCE,
    REFERENCE_RIG,
    AffineFeedback,
    Engine,
    EngineOptions,
    EngineState,
    Event,
    Experiment,
    InitialState,
    ParameterError,
    PhysicalParams,
    ScaledParams,
    SimulationResult,
    Status,
    StringParams,
    get_params,
    get_physical,
    load_params,
    params_from_spec,
    read_params,
    save_params,
    simulate,
)

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
