"""The paper's closed loop (Section V) as two co-simulated FMUs, and the model they describe.

Two FMI 2.0 units, ``DrillStringPlant`` (model (11)-(14), (17)) and ``TorsionalController``
(law (29)-(31)), coupled by :class:`~drillstring.orchestration.master.Master`::

    plant.phi, plant.dphi, plant.theta, plant.dtheta -> controller (same names)
    controller.R_minus_R0 -> plant.R_minus_R0

One wiring: the SSP package ``build_fmus.py`` writes (:mod:`.loop_ssp`, from
:class:`LoopVariant`'s connections and :func:`experiment_start_values`) is what every run starts
from: :func:`closed_loop_master` makes the master of its FMUs and connections, with the start
values an experiment (:class:`~drillstring.model.experiments.Experiment`) defines and any
explicit user overrides ``{"unit.variable": value}``. The gains (F, K0, R_ff) and the parameter
set are the FMUs' own, baked in by ``build_fmus.py``. :func:`loop_model_of` reads the loop the
master runs from the start values of its units (each model description read once per run), so
the monolithic twin (:mod:`.monolithic`) and the co-simulation describe the same system by
construction.
:func:`errors_on_grid` compares the two at the co-simulation's communication points, which must
lie on the monolithic output grid.

The same loop exists in two unit systems (:class:`LoopVariant`): :data:`SCALED`, the FMUs above
in the paper's scaled quantities, and :data:`SI`, ``DrillStringPlantSI`` and
``TorsionalControllerSI`` in SI units and seconds (:mod:`drillstring.model.units`). Every
function here takes the variant (default :data:`SCALED`), whose unit system
(:class:`~drillstring.model.units.UnitSystem`) converts; :class:`LoopModel` is always the scaled
model the FMUs describe, with the scales of their rig (the identity for the scaled FMUs), so the
monolithic twin runs either.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import sys
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drillstring.model.control import LATCH_MODES, AffineFeedback
from drillstring.model.engine import ON_INVALID_CHOICES, EngineOptions, InitialState
from drillstring.model.experiments import Experiment
from drillstring.model.laws import SampledAffine
from drillstring.model.params import PhysicalParams, ScaledParams
from drillstring.model.simulate import SimulationResult
from drillstring.model.units import IDENTITY, PLANT_SI, SCALED_UNITS, SI_UNITS, Scales, UnitSystem
from drillstring.orchestration.connections import StartValue, effective_start_values
from drillstring.orchestration.master import Master
from drillstring.orchestration.results import CosimResult

__all__ = [
    "SCALED",
    "SI",
    "TOPDRIVE",
    "TOPDRIVE_SI",
    "VARIANTS",
    "LoopVariant",
    "LoopModel",
    "fmu_paths",
    "loop_package",
    "experiment_start_values",
    "loop_model",
    "loop_model_of",
    "read_loop_model",
    "closed_loop_master",
    "kept_sys_path",
    "run_cosim",
    "grid_indices",
    "errors_on_grid",
]

UNITS = ("plant", "controller")

# The FMUs' variable names (fmu_src/drillstring_plant.py, fmu_src/drillstring_controller.py).
#: ScaledParams field -> plant parameter
_PARAMS = {f: f for f in ("n", "psi", "gamma", "eta", "beta", "rho", "v0", "omega0")} | {
    "lam": "lambda"
}
#: InitialState field -> plant parameter
_INITIAL = {k: f"{k}0" for k in ("u", "du", "phi", "dphi", "theta", "dtheta")}
#: controller parameters of the gain F
_GAINS = tuple(f"F[{i}]" for i in range(1, 5))
#: PhysicalParams fields = SI plant parameters
_PHYSICAL = tuple(f.name for f in dataclasses.fields(PhysicalParams))

Overrides = Mapping[str, StartValue]


#: The controller FMU's model and the loop's system of each controller family.
_MODELS = {
    "lmi": ("TorsionalController", "DrillStringClosedLoop"),
    "topdrive": ("TopDriveController", "DrillStringTopDrive"),
}


@dataclass(frozen=True)
class LoopVariant:
    """The closed loop in one unit system: its FMU files, package and connecting names.

    Attributes
    ----------
    units : UnitSystem
        The unit system of the FMUs (:data:`~drillstring.model.units.SCALED_UNITS` or
        ``SI_UNITS``), whose suffix ends the names of the FMUs and of the package.
    feedback : tuple of str
        Plant outputs fed to the controller inputs of the same names.
    torque : str
        The controller output fed to the plant input of the same name.
    record : tuple of str
        Plant outputs recorded besides the connected ones.
    controller : str
        Which controller FMU closes the loop: ``"lmi"`` (the paper's law, ``TorsionalController``)
        or ``"topdrive"`` (the industrial laws, ``TopDriveController``, the same connectors).
    """

    units: UnitSystem
    feedback: tuple[str, ...]
    torque: str
    record: tuple[str, ...]
    controller: str = "lmi"

    @property
    def name(self) -> str:
        """The unit system's name, ``"scaled"`` or ``"si"``."""
        return self.units.name

    @property
    def system(self) -> str:
        """The loop's name (``DrillStringClosedLoopSI``), the package's file stem."""
        return _MODELS[self.controller][1] + self.units.suffix

    @property
    def plant_fmu(self) -> str:
        """The plant FMU's file name (as ``build_fmus.py`` writes it)."""
        return f"DrillStringPlant{self.units.suffix}.fmu"

    @property
    def controller_fmu(self) -> str:
        """The controller FMU's file name."""
        return f"{_MODELS[self.controller][0]}{self.units.suffix}.fmu"

    @property
    def ssp(self) -> str:
        """The file name of the loop's SSP package."""
        return f"{self.system}.ssp"

    @property
    def connections(self) -> tuple[str, ...]:
        """``"plant.y -> controller.y"`` for the feedback, and the torque back."""
        return (
            *(f"plant.{n} -> controller.{n}" for n in self.feedback),
            f"controller.{self.torque} -> plant.{self.torque}",
        )


_COUNTERS = ("plant.mode", "plant.stick_events", "plant.torsional_stick", "plant.bit_bounce")
#: The loop in the paper's scaled quantities.
SCALED = LoopVariant(
    SCALED_UNITS,
    ("phi", "dphi", "theta", "dtheta"),
    "R_minus_R0",
    ("plant.u", "plant.du", "plant.d", "plant.g", "plant.tau_n", *_COUNTERS),
)
#: The loop in SI units and seconds.
SI = LoopVariant(
    SI_UNITS,
    ("bit_angle", "bit_speed", "table_angle", "table_speed"),
    "table_torque",
    tuple(f"plant.{q.name}" for q in PLANT_SI if not q.name.endswith(("_angle", "_speed")))
    + _COUNTERS,
)
VARIANTS: dict[str, LoopVariant] = {v.name: v for v in (SCALED, SI)}
#: The same loops closed by the industrial top-drive controller FMU instead of the LMI one.
TOPDRIVE = dataclasses.replace(SCALED, controller="topdrive")
TOPDRIVE_SI = dataclasses.replace(SI, controller="topdrive")


@dataclass(frozen=True)
class LoopModel:
    """The closed loop that the two FMUs describe with given start values.

    Attributes
    ----------
    params : ScaledParams
        The plant's parameter set.
    initial : InitialState
        The plant's initial perturbation.
    options : EngineOptions
        The plant engine's options (RK4 step, torsional-stick model, bit-bounce policy, event
        tolerance).
    control : AffineFeedback or float
        The controller's law (29)-(31), or its feed-forward R_ff alone when the feedback is
        disabled.
    scaling : Scales
        The scales of the FMUs' unit system on their rig (the model above is their scaled
        form): the rig's :class:`~drillstring.model.units.SIScaling` in SI, the identity in
        scaled units.
    """

    params: ScaledParams
    initial: InitialState
    options: EngineOptions
    control: AffineFeedback | float
    scaling: Scales = IDENTITY


def fmu_paths(fmus_dir: str | os.PathLike[str], variant: LoopVariant = SCALED) -> tuple[Path, Path]:
    """The plant and controller FMU files in a folder.

    Parameters
    ----------
    fmus_dir : path
        Folder of the built FMUs.
    variant : LoopVariant
        The unit system.

    Returns
    -------
    (Path, Path)
        Plant and controller FMU.

    Raises
    ------
    ValueError
        Naming the FMU that is missing and how to build it.
    """
    d = Path(fmus_dir)
    paths = (d / variant.plant_fmu, d / variant.controller_fmu)
    missing = [p.name for p in paths if not p.is_file()]
    if missing:
        raise ValueError(
            f"no {' or '.join(missing)} in {str(d)!r} (build them with `python build_fmus.py "
            f"--gains GAINS.json --out {d}`)"
        )
    return paths


def experiment_start_values(
    experiment: Experiment,
    variant: LoopVariant = SCALED,
    *,
    full_initial: bool = False,
) -> dict[str, dict[str, StartValue]]:
    """The start values an experiment defines, per unit.

    Parameters
    ----------
    experiment : Experiment
        The set-up (``docs/model.md``, "Experiments of Figs. 5 and 6"), in scaled time.
    variant : LoopVariant
        The unit system: the initial state, ``h`` and ``t_on`` are converted by its scales on
        the reference rig, the SI FMUs' (:meth:`~drillstring.model.units.UnitSystem.scales`).
    full_initial : bool
        Give all six initial deviations (``u0`` ... ``dtheta0``), not only ``dphi0``.

    Returns
    -------
    dict
        ``{"plant": {dphi0, h, torsional_stick_model}, "controller": {t_on, latch,
        enabled}}`` (no latch for the top-drive controller); the gains and the parameter set
        are the FMUs' own.
    """
    scales = variant.units.scales()
    initial = scales.initial_to_si(experiment.initial())
    h, t_on = scales.time(float(experiment.h)), scales.time(float(experiment.t_on))
    keys = _INITIAL if full_initial else {"dphi": "dphi0"}
    return {
        "plant": {
            **{keys[k]: float(initial[k]) for k in keys},
            "h": h,
            "torsional_stick_model": bool(experiment.torsional_stick),
        },
        "controller": {
            "t_on": t_on,
            # an Enumeration of the FMU: item values 1, 2, 3 in the order of LATCH_MODES; the
            # top-drive laws have no latch (their integrators are preset instead)
            **(
                {"latch": LATCH_MODES.index(experiment.latch) + 1}
                if variant.controller == "lmi"
                else {}
            ),
            "enabled": bool(experiment.enabled),
        },
    }


def _split_overrides(overrides: Overrides | None) -> dict[str, dict[str, StartValue]]:
    out: dict[str, dict[str, StartValue]] = {u: {} for u in UNITS}
    for key, value in (overrides or {}).items():
        unit, _, var = str(key).partition(".")
        if unit not in out or not var:
            raise ValueError(
                f"override {key!r} is not of the form 'plant.variable' or 'controller.variable'"
            )
        out[unit][var] = value
    return out


def loop_model(
    plant: Mapping[str, Any], controller: Mapping[str, Any], variant: LoopVariant = SCALED
) -> LoopModel:
    """The closed loop described by the two FMUs' start values (their variable names).

    Parameters
    ----------
    plant, controller : mapping
        Variable name -> value of every parameter of each FMU.
    variant : LoopVariant
        The unit system of the FMUs; an SI loop is converted to its scaled form
        (:mod:`drillstring.model.units`).

    Returns
    -------
    LoopModel
        Parameter set, initial state, engine options and law, validated like the Python API.
    """
    if variant.controller != "lmi":
        raise ValueError(
            f"loop_model describes the loop closed by the paper's law, not by the "
            f"{variant.controller!r} controller (its law: drillstring.model.laws)"
        )
    system = variant.units
    named = {f: plant[name] for f, name in _PARAMS.items() if name in plant}
    named.update((f, plant[f]) for f in _PHYSICAL if f in plant)
    params, scales = system.parameter_set(named)
    initial = scales.initial_to_scaled({k: plant[name] for k, name in _INITIAL.items()})
    options = EngineOptions(
        h=scales.tau(plant["h"]),
        torsional_stick=bool(plant["torsional_stick_model"]),
        on_invalid=_item(ON_INVALID_CHOICES, plant["on_invalid"]),
        event_tol=scales.tau(plant["event_tol"]),
    )
    if system.physical:
        rig = scales.rig
        for name, plant_value in (("Omega0", rig.Omega0), ("R0", rig.R0), ("C", rig.C),
                                  ("I1", rig.I1)):  # fmt: skip
            if not math.isclose(controller[name], plant_value, rel_tol=1e-12):
                raise ValueError(
                    f"the controller's {name} = {controller[name]!r} is not the plant's "
                    f"{plant_value!r}: (29)-(31) is a law about the plant's nominal motion"
                )
    values = {name: controller[name] for name in (*_GAINS, "K0", "R_ff", "t_on")}
    values["latch"] = _item(LATCH_MODES, controller["latch"])
    law = SampledAffine.from_si(scales, values).feedback
    control: AffineFeedback | float = law if controller["enabled"] else law.R_ff
    return LoopModel(params, initial, options, control, scales)


def _item(names: Sequence[str], value: StartValue) -> str:
    """The name of an FMU Enumeration item (values 1, 2, ... in the order of ``names``)."""
    if isinstance(value, str):
        return value
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= len(names):
        raise ValueError(f"enumeration value {value!r} is not one of 1..{len(names)} ({names})")
    return names[value - 1]


def loop_package(fmus_dir: str | os.PathLike[str], variant: LoopVariant = SCALED) -> Path:
    """The variant's SSP package in a folder of ``build_fmus.py``'s output.

    Parameters
    ----------
    fmus_dir : path
        Folder of the built FMUs and packages.
    variant : LoopVariant
        The loop.

    Returns
    -------
    Path
        ``fmus_dir / variant.ssp``.

    Raises
    ------
    ValueError
        Naming the package that is missing and how to build it.
    """
    package = Path(fmus_dir) / variant.ssp
    if not package.is_file():
        raise ValueError(
            f"no {variant.ssp} in {str(fmus_dir)!r} (build it with `python build_fmus.py "
            f"--gains GAINS.json --out {fmus_dir}`)"
        )
    return package


def closed_loop_master(
    fmus_dir: str | os.PathLike[str],
    experiment: Experiment | None,
    *,
    overrides: Overrides | None = None,
    record: Sequence[str] | None = None,
    variant: LoopVariant = SCALED,
) -> Master:
    """A :class:`Master` of the variant's SSP package set up for an experiment.

    The package ``build_fmus.py`` writes (``fmus_dir / variant.ssp``,
    :mod:`.loop_ssp`) gives the FMUs and their connections; the start values are the FMUs' own,
    replaced by the experiment's (:func:`experiment_start_values`) and then by the overrides.

    Parameters
    ----------
    fmus_dir : path
        Folder of the built FMUs and packages.
    experiment : Experiment or None
        The set-up; None: the FMUs' own start values only.
    overrides : mapping, optional
        ``"plant.variable"`` / ``"controller.variable"`` -> start value, applied last.
    record : sequence of str, optional
        Extra variables recorded (default: the variant's ``record``).
    variant : LoopVariant
        The loop and its unit system (the experiment is converted on the reference rig).

    Returns
    -------
    Master
        The master (a context manager: close it to remove the extracted FMUs);
        :func:`loop_model_of` gives the loop it runs.

    Raises
    ------
    ValueError
        Naming the package that is missing and how to build it, or a bad start value.
    """
    package = loop_package(fmus_dir, variant)
    values = experiment_start_values(experiment, variant) if experiment is not None else {}
    extra = _split_overrides(overrides)
    return Master.from_ssp(
        package,
        (),
        start_values={u: {**values.get(u, {}), **extra[u]} for u in UNITS},
        record=variant.record if record is None else record,
    )


def loop_model_of(master: Master, variant: LoopVariant = SCALED) -> LoopModel:
    """The closed loop a master of :func:`closed_loop_master` runs (its units' start values;
    the model descriptions it has read already).

    Parameters
    ----------
    master : Master
        The master.
    variant : LoopVariant
        Its loop.

    Returns
    -------
    LoopModel
        What the master co-simulates: the monolithic twin's model.
    """
    plant, controller = (effective_start_values(u) for u in master.system.units)
    return loop_model(plant, controller, variant)


def read_loop_model(
    fmus_dir: str | os.PathLike[str],
    experiment: Experiment | None,
    overrides: Overrides | None = None,
    variant: LoopVariant = SCALED,
) -> LoopModel:
    """The closed loop the FMUs run in an experiment (:func:`loop_model_of` of
    :func:`closed_loop_master` with the same arguments).

    Parameters
    ----------
    fmus_dir, experiment, overrides, variant
        As for :func:`closed_loop_master`.

    Returns
    -------
    LoopModel
        What :func:`closed_loop_master` co-simulates with the same arguments.
    """
    with closed_loop_master(fmus_dir, experiment, overrides=overrides, variant=variant) as m:
        return loop_model_of(m, variant)


@contextlib.contextmanager
def kept_sys_path() -> Iterator[None]:
    """Context manager that restores ``sys.path`` on exit.

    pythonfmu adds the FMU's resources folder to ``sys.path`` on every instantiation; processes
    started later must import the repository's ``drillstring``, not the FMU's copy.

    Yields
    ------
    None
        ``sys.path`` is restored to its value at entry when the block exits, also on an error.
    """
    saved = list(sys.path)
    try:
        yield
    finally:
        sys.path[:] = saved


def run_cosim(master: Master, tau_end: float, H: float | None, **kwargs: Any) -> CosimResult:
    """``master.run(tau_end, H, progress=False, **kwargs)`` keeping ``sys.path``.

    Parameters
    ----------
    master : Master
        The closed-loop master.
    tau_end : float
        End of the run.
    H : float or None
        Macro step (None with ``step_control``).
    **kwargs
        Further arguments of :meth:`Master.run`.

    Returns
    -------
    CosimResult
        The run.
    """
    kwargs.setdefault("progress", False)
    with kept_sys_path():
        return master.run(tau_end, H, **kwargs)


def grid_indices(times: np.ndarray, dt: float, n: int) -> np.ndarray:
    """Indices ``k`` with ``times == k*dt`` (to ``1e-9 dt``) on a grid of ``n`` points.

    Parameters
    ----------
    times : numpy.ndarray
        Communication points.
    dt : float
        Step of the grid.
    n : int
        Number of grid points.

    Returns
    -------
    numpy.ndarray
        The indices.

    Raises
    ------
    ValueError
        Naming the first time that is not on the grid.
    """
    k = np.rint(np.asarray(times) / dt).astype(np.int64)
    bad = (np.abs(k * dt - times) > 1e-9 * dt) | (k < 0) | (k >= n)
    if np.any(bad):
        t = float(np.asarray(times)[np.argmax(bad)])
        raise ValueError(f"communication point {t!r} is not on the monolithic grid of step {dt!r}")
    return k


def errors_on_grid(res: CosimResult, mono: SimulationResult, dt: float) -> dict[str, float]:
    """Max |co-simulation - monolithic| of ``plant.du`` and ``plant.dphi`` over the common points.

    Parameters
    ----------
    res : CosimResult
        The co-simulation.
    mono : SimulationResult
        The monolithic run on a grid of step ``dt`` (the points both runs reached count).
    dt : float
        Its output step.

    Returns
    -------
    dict
        Name -> max absolute difference (NaN without common points).
    """
    t = res.time
    t = t[t <= mono.tau[-1] + 1e-9 * dt]
    k = grid_indices(t, dt, len(mono.tau))
    out = {}
    for name in ("du", "dphi"):
        diff = res[f"plant.{name}"][: len(k)] - getattr(mono, name)[k]
        out[name] = float(np.max(np.abs(diff))) if len(diff) else math.nan
    return out
