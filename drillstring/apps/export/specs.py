"""What is built: the FMUs (model identifier, script, class and its attributes), the sources
they are made from, and the error of a build that cannot be completed.

The sources are package data of the installed package (``drillstring.fmu_src``, the repository's
``fmu_src/``): the FMU scripts, their lifecycle and start-up modules, the variable declarations
and the C front layer (``fmu_src/fmi_front/``). The ``drillstring`` package itself is bundled
into each FMU's ``resources/`` (:mod:`drillstring.apps.export.staging`).
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

__all__ = [
    "BOOT",
    "CONTROLLER",
    "CONTROLLER_SI",
    "FMU_MODULES",
    "FMU_SRC",
    "FRONT_LAYER",
    "PACKAGE",
    "PLANT",
    "PLANT_SI",
    "SPECS",
    "SUPPORT",
    "TOPDRIVE",
    "TOPDRIVE_SI",
    "UNITS_MODULE",
    "BuildError",
    "FmuSpec",
]

#: The FMU sources (``fmu_src/``, installed as the package data ``drillstring.fmu_src``).
FMU_SRC = Path(str(files("drillstring.fmu_src")))
#: The ``drillstring`` package, bundled into every FMU.
PACKAGE = Path(__file__).resolve().parents[2]
SUPPORT = FMU_SRC / "drillstring_fmu_support.py"
BOOT = FMU_SRC / "drillstring_fmu_boot.py"
UNITS_MODULE = FMU_SRC / "drillstring_fmu_units.py"
#: The front layer's folder: its header and one C file per concern (see drillstring_fmi2.h).
FRONT_LAYER = FMU_SRC / "fmi_front"


class BuildError(RuntimeError):
    """A build that cannot be completed or an FMU that fails validation."""


@dataclass(frozen=True)
class FmuSpec:
    """One FMU: its model identifier, the script it comes from and how.

    The FMU's class is generated: a module ``<model>.py`` that derives a class named ``model``
    from the script's class ``base`` with the class ``attributes`` (the unit system, the
    controller family), so one script gives every variant (:func:`class_module`).
    """

    model: str
    script: Path
    base: str
    attributes: tuple[tuple[str, str], ...] = ()


PLANT_SCRIPT = FMU_SRC / "drillstring_plant.py"
#: The plant in the paper's scaled quantities and in SI units (time in seconds, torque in N m),
#: from one script: the unit system is a class attribute.
PLANT = FmuSpec("DrillStringPlant", PLANT_SCRIPT, "PlantFmu", (("UNIT_SYSTEM", "scaled"),))
PLANT_SI = FmuSpec("DrillStringPlantSI", PLANT_SCRIPT, "PlantFmu", (("UNIT_SYSTEM", "si"),))
CONTROLLER_SCRIPT = FMU_SRC / "drillstring_controller.py"


def _controller(model: str, family: str, system: str) -> FmuSpec:
    return FmuSpec(
        model, CONTROLLER_SCRIPT, "ControllerFmu", (("FAMILY", family), ("UNIT_SYSTEM", system))
    )


#: The torsional controller (29)-(31) and the industrial top-drive controllers (stiff PI,
#: SoftSpeed, Z-Torque), each in both unit systems, from one script.
CONTROLLER = _controller("TorsionalController", "lmi", "scaled")
CONTROLLER_SI = _controller("TorsionalControllerSI", "lmi", "si")
TOPDRIVE = _controller("TopDriveController", "topdrive", "scaled")
TOPDRIVE_SI = _controller("TopDriveControllerSI", "topdrive", "si")
SPECS = (PLANT, CONTROLLER, PLANT_SI, CONTROLLER_SI, TOPDRIVE, TOPDRIVE_SI)
#: The Python modules of the FMUs, dropped from ``sys.modules`` around each build so that every
#: build imports its own staged copies.
FMU_MODULES = (
    "drillstring_fmu_support",
    "drillstring_fmu_boot",
    "drillstring_fmu_units",
    *{spec.script.stem for spec in SPECS},
    *(spec.model for spec in SPECS),
)
