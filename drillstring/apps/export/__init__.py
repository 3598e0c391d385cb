"""The build of the drillstring FMUs and SSP packages (``python build_fmus.py`` in a source
checkout, ``drillstring fmus`` where the package is installed).

Six FMI 2.0 co-simulation FMUs, and their FMI 3.0 twins (``X3.fmu``, ``--fmi``), from two
scripts (:mod:`drillstring.apps.export.specs`):
``fmu_src/drillstring_plant.py`` (class ``PlantFmu``: ``DrillStringPlant`` and
``DrillStringPlantSI``) and ``fmu_src/drillstring_controller.py`` (class ``ControllerFmu``:
``TorsionalController``, ``TopDriveController`` with the industrial laws, and their SI
variants), the unit system and the controller family being class attributes of a generated
module (``docs/si_fmus.md``). For each FMU (:func:`~drillstring.apps.export.build.build_fmu`):

1. stage the files bundled into its ``resources/`` (:mod:`~drillstring.apps.export.staging`:
   the ``drillstring`` package, the FMU modules, the build configuration, the record of the
   Python that builds it, :mod:`~drillstring.apps.export.python_runtime`) and write its
   ``documentation/`` (:mod:`~drillstring.apps.export.documentation`);
2. build with pythonfmu (``canGetAndSetFMUstate`` and ``canSerializeFMUstate`` true);
3. post-process ``modelDescription.xml`` where pythonfmu cannot express the truth
   (:mod:`~drillstring.apps.export.model_description`: ModelStructure, units, ranges,
   enumerations, exact start values, a content-derived GUID);
4. replace pythonfmu's binaries by the project's front layer
   (:mod:`~drillstring.apps.export.front_layer`): pythonfmu's ``linux64`` library is kept as
   ``binaries/linux64/<id>_pythonfmu.so`` and ``binaries/linux64/<id>.so`` is
   ``fmu_src/fmi_front/*.c`` compiled with the system's C compiler against a header generated
   from the final modelDescription.xml; pythonfmu's untested ``win64`` DLL is dropped;
5. for the FMI 3.0 twin: its model description from the same declarations
   (:mod:`~drillstring.apps.export.model_description3`) and the front layer with its FMI 3.0
   front, beside the same entries (``binaries/x86_64-linux``);
6. write the archive deterministically and run ``fmpy.validate_fmu``
   (:mod:`~drillstring.apps.export.archive`); any problem fails the build with the list of
   problems.

Then the SSP 1.0 packages of the closed loop (:mod:`drillstring.orchestration.loop_ssp`: one SSD
per experiment), validated against the SSP 1.0 schemas that fmpy ships.

Building twice gives identical ``modelDescription.xml`` apart from ``generationDateAndTime``, and
identical FMUs byte for byte when ``SOURCE_DATE_EPOCH`` is set. The controllers' gains come from
a gains file (:func:`drillstring.controller.gains.read_gains`); without one the synthesis runs
first and writes it (:func:`~drillstring.apps.export.build.synthesize_gains`).
"""

from drillstring.apps.export.build import DEFAULT_OUT, build_fmu, build_fmus, build_fmus_into
from drillstring.apps.export.specs import SPECS, BuildError, FmuSpec

__all__ = [
    "DEFAULT_OUT",
    "SPECS",
    "BuildError",
    "FmuSpec",
    "build_fmu",
    "build_fmus",
    "build_fmus_into",
]
