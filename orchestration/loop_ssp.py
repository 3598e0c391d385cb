"""The closed loop of Section V as an SSP 1.0 package, in either unit system.

``build_fmus.py`` writes ``DrillStringClosedLoop.ssp`` (the scaled FMUs) and
``DrillStringClosedLoopSI.ssp`` (the SI FMUs) with :func:`write_loop_package`: both FMUs, the
connections of :class:`~drillstring.orchestration.closed_loop.LoopVariant`, every connector with
its unit, four named parameter sets and the default experiment of Fig. 5 with a fixed step:

* ``fig5``, ``fig6``: the experiments of Figs. 5 and 6 (``docs/model.md``, "Experiments of Figs.
  5 and 6"; :data:`~drillstring.model.experiments.FIG5`, ``FIG6``): the plant's whole initial
  state, its RK4 step and torsional-stick model, the controller's switch-on time, latch and
  enabled flag (in SI units in the SI package, converted on the reference rig);
* ``reference``: the plant's parameter set (the scaled reference set, or the reference rig);
* ``gains``: the controller's gains as built (the synthesis's gains file, in SI units in the SI
  package).

The packages of the loop closed by the industrial top-drive controller,
``DrillStringTopDrive.ssp`` and ``DrillStringTopDriveSI.ssp`` (variants
:data:`~drillstring.orchestration.closed_loop.TOPDRIVE`, ``TOPDRIVE_SI``), have the same
connections and plant sets; the controller binds ``fig5``, ``fig6`` (switch-on time and enabled
flag: the PI laws have no latch) and one set per tuning of the reference set,
``stiff-pi``, ``soft-speed`` and ``z-torque`` (:func:`topdrive_tunings`; ``soft-speed`` is the
FMU's start values).

Each component binds, in this order, ``fig5``, ``fig6`` and its own nominal set(s), so libcosim
(which applies the first binding of each component) runs Fig. 5, and Ecos runs the set named by
``--parameterSet``. The values are the FMUs' start values where the set is theirs (``reference``,
``gains``), so the package describes exactly the FMUs it holds.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path

from fmpy import read_model_description

from drillstring.controller.lineup import INDUSTRIAL, industrial_lineup
from drillstring.model.experiments import FIG5, FIG6
from drillstring.model.laws import ZTorque
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.units import UNITS, SIScaling
from drillstring.orchestration.closed_loop import (
    SCALED,
    SI,
    LoopVariant,
    experiment_start_values,
    fmu_paths,
)
from drillstring.orchestration.connections import declared_start_values
from drillstring.orchestration.ssp import (
    SspComponent,
    SspConnection,
    SspConnector,
    SspParameter,
    write_ssp,
)

__all__ = [
    "DEFAULT_STEP",
    "PACKAGE_SETS",
    "TOPDRIVE_DEFAULT",
    "TOPDRIVE_PARAMETERS",
    "TOPDRIVE_SETS",
    "loop_default_experiment",
    "topdrive_tunings",
    "write_loop_package",
]

#: The fixed macro step of the packages' default experiment (scaled time; 1 ms in SI).
DEFAULT_STEP = {SCALED.name: 1e-3, SI.name: 1e-3}
#: The parameter sets of a package, in binding order (module docstring).
PACKAGE_SETS = ("fig5", "fig6", "reference", "gains")
_NOMINAL = {"plant": "reference", "controller": "gains"}
_EXPERIMENTS = {"fig5": FIG5, "fig6": FIG6}
_GAINS = ("F[1]", "F[2]", "F[3]", "F[4]", "K0", "R_ff")
#: The top-drive controller FMU's parameters a tuning sets.
TOPDRIVE_PARAMETERS = ("kp", "ki", "z_gain", "omega_hp", "omega_lp")
#: The tuning that is the top-drive controller FMU's start values.
TOPDRIVE_DEFAULT = "soft-speed"
#: The parameter sets of a top-drive package, in binding order.
TOPDRIVE_SETS = ("fig5", "fig6", "reference", *INDUSTRIAL)


def topdrive_tunings(variant: LoopVariant = SCALED) -> dict[str, dict[str, float]]:
    """The industrial tunings of the reference set as values of the top-drive FMU's parameters.

    :func:`~drillstring.controller.lineup.industrial_lineup` of the scaled reference set; a
    SpeedPI is the FMU's law with ``z_gain = 0`` (its filter corners, unread, are ZTorque's
    defaults). In the SI variant the values are converted on the reference rig
    (:meth:`~drillstring.model.laws.ZTorque.to_si`), as the SI FMU converts its start values.

    Parameters
    ----------
    variant : LoopVariant
        The unit system (``variant.name``).

    Returns
    -------
    dict
        Tuning name (:data:`~drillstring.controller.lineup.INDUSTRIAL`) -> parameter -> value.
    """
    out = {}
    for name, law in industrial_lineup(REFERENCE).items():
        z = law if isinstance(law, ZTorque) else ZTorque(kp=law.kp, ki=law.ki, z_gain=0.0)
        if variant.name == SI.name:
            values = z.to_si(REFERENCE_RIG)
        else:
            values = {k: getattr(z, k) for k in TOPDRIVE_PARAMETERS}
        out[name] = {k: float(values[k]) for k in TOPDRIVE_PARAMETERS}
    return out


def loop_default_experiment(variant: LoopVariant) -> tuple[float, float, float]:
    """The default experiment (start, stop, step) of a loop package: Fig. 5's run.

    See ``docs/model.md``, "Experiments of Figs. 5 and 6".

    Parameters
    ----------
    variant : LoopVariant
        :data:`~drillstring.orchestration.closed_loop.SCALED` or ``SI``.

    Returns
    -------
    tuple of 3 float
        ``(0, stop, step)`` with the fixed step :data:`DEFAULT_STEP` of the variant. Scaled:
        stop = tau_end = 60. SI: 60 t* on the reference rig rounded up to a whole number of
        steps, 55.352 s, so that every host takes the same equal steps.

    Raises
    ------
    KeyError
        ``variant.name`` is not in :data:`DEFAULT_STEP`.
    """
    step = DEFAULT_STEP[variant.name]
    stop = FIG5.tau_end
    if variant.name == SI.name:
        stop = round(math.ceil(SIScaling(REFERENCE_RIG).time(stop) / step) * step, 12)
    return 0.0, float(stop), step


def _parameters(md, values: Mapping[str, object]) -> tuple[SspParameter, ...]:
    variables = {v.name: v for v in md.modelVariables}
    out = []
    for name, value in values.items():
        var = variables[name]
        unit = var.unit if var.type == "Real" and var.unit not in (None, "1") else None
        out.append(SspParameter(name, var.type, value, unit))
    return tuple(out)


def write_loop_package(
    fmus_dir: str | os.PathLike[str],
    variant: LoopVariant,
    out: str | os.PathLike[str] | None = None,
    source_date_epoch: int | None = None,
) -> Path:
    """Write the SSP package of the closed loop of the FMUs in ``fmus_dir`` (module docstring).

    Parameters
    ----------
    fmus_dir : path
        Folder with the variant's two FMUs (``build_fmus.py``'s output).
    variant : LoopVariant
        :data:`~drillstring.orchestration.closed_loop.SCALED`, ``SI``, ``TOPDRIVE`` or
        ``TOPDRIVE_SI``.
    out : path, optional
        The ``.ssp`` file (default ``fmus_dir/<variant.ssp>``).
    source_date_epoch : int, optional
        Timestamp of the archive entries (reproducible builds).

    Returns
    -------
    Path
        The package, validated against the SSP 1.0 schemas.
    """
    paths = dict(zip(("plant", "controller"), fmu_paths(fmus_dir, variant), strict=True))
    target = Path(out) if out is not None else Path(fmus_dir) / variant.ssp
    components = []
    for name, fmu in paths.items():
        md = read_model_description(str(fmu))
        starts = declared_start_values(md)
        connectors = tuple(
            SspConnector(
                v.name,
                v.causality,
                v.type,
                v.unit if v.type == "Real" else None,
            )
            for v in md.modelVariables
            if v.causality in ("input", "output")
        )
        sets = {}
        for set_name, experiment in _EXPERIMENTS.items():
            values = experiment_start_values(experiment, variant, full_initial=True)[name]
            sets[set_name] = _parameters(md, values)
        if name == "plant":
            nominal = {
                v.name: starts[v.name]
                for v in md.modelVariables
                if v.causality == "parameter" and v.name in _plant_parameter_names(variant)
            }
            sets[_NOMINAL[name]] = _parameters(md, nominal)
        elif variant.controller == "topdrive":
            for tuning, values in topdrive_tunings(variant).items():
                sets[tuning] = _parameters(md, values)
        else:
            gains = _GAINS + (("Omega0",) if variant.name == SI.name else ())
            sets[_NOMINAL[name]] = _parameters(md, {g: starts[g] for g in gains})
        components.append(SspComponent(name, f"resources/{fmu.name}", connectors, sets))
    connections = []
    for spec in variant.connections:
        src, dst = (part.strip().split(".", 1) for part in spec.split("->"))
        connections.append(SspConnection(src[0], src[1], dst[0], dst[1]))
    kind = "SI units and seconds" if variant.name == SI.name else "the paper's scaled quantities"
    if variant.controller == "topdrive":
        system, law = "DrillStringTopDrive", "industrial top-drive controller"
    else:
        system, law = "DrillStringClosedLoop", "torsional controller (29)-(31)"
    return write_ssp(
        target,
        name=system + ("SI" if variant.name == SI.name else ""),
        components=components,
        fmus=paths,
        connections=connections,
        units=UNITS,
        default_experiment=loop_default_experiment(variant),
        description=(
            f"Drill-string plant (11)-(14), (17) of Besselink, van de Wouw and Nijmeijer (IEEE "
            f"CCA 2011) and {law} in closed loop, in {kind}"
        ),
        source_date_epoch=source_date_epoch,
    )


def _plant_parameter_names(variant: LoopVariant) -> tuple[str, ...]:
    """The plant parameters of the parameter set itself (not the initial state or engine)."""
    if variant.name == SI.name:
        return tuple(REFERENCE_RIG.to_dict())
    return ("n", "psi", "gamma", "eta", "lambda", "beta", "rho", "v0", "omega0")
