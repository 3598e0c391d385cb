"""Build the drillstring FMUs: the plant, the torsional controller and the top-drive controller
(FMI 2.0 co-simulation), each in the paper's scaled quantities and in SI units, and the closed
loops as SSP 1.0 packages.

Usage::

    python build_fmus.py [--gains out/design/gains.json] [--out build/]

For each FMU, generated from two scripts: ``fmu_src/drillstring_plant.py`` (class
``PlantFmu``: ``DrillStringPlant.fmu`` and ``DrillStringPlantSI.fmu``) and
``fmu_src/drillstring_controller.py`` (class ``ControllerFmu``: ``TorsionalController.fmu``,
``TopDriveController.fmu`` with the industrial laws, tunings of the reference set in its build
configuration, and their SI variants), the unit system and the controller family being class
attributes of a generated module (:func:`class_module`; ``docs/si_fmus.md``):

1. stage the files bundled into the FMU's ``resources/``: the ``drillstring`` package (the physics;
   no model code is in the FMU scripts), the shared lifecycle ``drillstring_fmu_support.py``, the
   start-up module ``drillstring_fmu_boot.py``, the script, a one-line entry module for pythonfmu
   (``<script>_entry.py``, see :func:`entry_module`), the build configuration
   ``drillstring_fmu.json`` (package version, controller gains), the record of the Python that
   builds the FMU ``drillstring_fmu_python.cfg`` (libpython, home, site-packages) and
   ``requirements.txt``; and the ``documentation/`` folder;
2. build with pythonfmu (``canGetAndSetFMUstate`` and ``canSerializeFMUstate`` true);
3. post-process ``modelDescription.xml`` where pythonfmu cannot express the truth: outputs
   ``initial="calculated"`` without start values, listed in ``InitialUnknowns``; the true
   ``ModelStructure`` (each variable's ``depends_on``); ``min``/``max`` of every parameter with a
   range; Enumeration types (``TypeDefinitions``) for the enumeration parameters; each Real's unit
   and display unit, with ``UnitDefinitions`` giving their SI base-unit exponents and display
   units (``drillstring.model.units.UNITS``; "1" throughout the scaled FMUs); start values
   written exactly (17 digits); a GUID derived from
   the content and a pinned ``generationDateAndTime`` when ``SOURCE_DATE_EPOCH`` is set;
4. replace pythonfmu's binaries by the project's front layer: pythonfmu's ``linux64`` library is
   kept as ``binaries/linux64/<id>_pythonfmu.so`` and ``binaries/linux64/<id>.so`` is
   ``fmu_src/fmi_front/*.c`` compiled with the system's C compiler against a header
   generated from the final modelDescription.xml (:func:`model_header`); pythonfmu's untested
   ``win64`` DLL is dropped (only built and tested platforms are shipped);
5. rewrite the archive deterministically (sorted entries, fixed timestamps) and run
   ``fmpy.validate_fmu``; any problem fails the build with the list of problems.

Then ``DrillStringClosedLoop.ssp`` and ``DrillStringClosedLoopSI.ssp``
(:mod:`drillstring.orchestration.loop_ssp`): both FMUs of a unit system, their connections and
units, the parameter sets ``fig5``, ``fig6``, ``reference`` and ``gains``, the default experiment
with a fixed step, validated against the SSP 1.0 schemas that fmpy ships; and
``DrillStringTopDrive.ssp``, ``DrillStringTopDriveSI.ssp``, the same loops closed by the
top-drive controller, with the sets ``stiff-pi``, ``soft-speed`` and ``z-torque`` instead of
``gains``.

Building twice gives identical ``modelDescription.xml`` apart from ``generationDateAndTime``, and
identical FMUs byte for byte when ``SOURCE_DATE_EPOCH`` is set.

The controller's start values of ``F``, ``K0`` and ``R_ff`` come from the gains file written by
``drillstring.controller.gains`` (validated by :func:`drillstring.controller.gains.read_gains`);
without a gains file the synthesis runs first and writes it (see :func:`synthesize_gains`).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import hashlib
import html
import importlib.util
import json
import os
import shlex
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import uuid
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

ROOT = Path(__file__).resolve().parent
FMU_SRC = ROOT / "fmu_src"
PACKAGE = ROOT / "drillstring"
SUPPORT = FMU_SRC / "drillstring_fmu_support.py"
BOOT = FMU_SRC / "drillstring_fmu_boot.py"
UNITS_MODULE = FMU_SRC / "drillstring_fmu_units.py"
#: The front layer's folder: its header and one C file per concern (see drillstring_fmi2.h).
FRONT_LAYER = FMU_SRC / "fmi_front"
CONFIG_NAME = "drillstring_fmu.json"
RUNTIME_NAME = "drillstring_fmu_python.cfg"
DEFAULT_OUT = ROOT / "build"
#: Runtime dependencies of the FMUs' Python code besides the standard library (pythonfmu's own
#: Python files are bundled by pythonfmu; numba is optional: without it the kernel is plain Python).
REQUIREMENTS = "numpy>=2.0\n"
#: Files of the drillstring package that are not bundled.
_IGNORE = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc", ".*")
#: Namespace of the content-derived GUIDs.
_GUID_NAMESPACE = uuid.UUID("6f1c2a8e-1d5b-5d3e-9a7c-2b4f0e8d9c11")
#: Fixed timestamp of the archive entries (the earliest a zip file can hold).
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)
#: Flags of the front layer (plain C, no debug information: the binary is reproducible). No
#: warning is silenced: every formatted text's length is checked (ds_format, ds_strf in log.c).
CFLAGS = ("-std=gnu11", "-O2", "-fPIC", "-shared", "-fvisibility=hidden", "-Wall", "-Wextra")
CFLAGS_STRICT = ("-Werror", "-Wl,-z,defs")
LDLIBS = ("-ldl", "-lpthread")
#: The environment variables that override the recorded Python on another machine.
OVERRIDES = {
    "libpython": "DRILLSTRING_FMU_LIBPYTHON",
    "home": "DRILLSTRING_FMU_PYTHONHOME",
    "site": "DRILLSTRING_FMU_SITE_PACKAGES",
}


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
_FMU_MODULES = (
    "drillstring_fmu_support",
    "drillstring_fmu_boot",
    "drillstring_fmu_units",
    *{spec.script.stem for spec in SPECS},
    *(spec.model for spec in SPECS),
)


# ------------------------------------------------------------------------------------------------
# gains
# ------------------------------------------------------------------------------------------------


def synthesize_gains(path: Path) -> Path:
    """Design the controller for the reference set and write its gains file to ``path``.

    :func:`drillstring.controller.design_controller`: the slope A from the axial limit cycles,
    the LMI synthesis (33) and its certificate.
    """
    from drillstring.controller import design_controller, write_gains
    from drillstring.model.params import REFERENCE

    print(f"build_fmus: no gains file at {path}: designing the controller", file=sys.stderr)
    design = design_controller(REFERENCE, evaluate_paper=False)
    if not design.synthesis.certificate.passed:
        raise BuildError(f"the controller design failed its certificate; no gains file at {path}")
    return write_gains(design.gains, path)


def load_gains(path: Path) -> dict[str, Any]:
    """F, K0, R_ff of a validated gains file, with its name and SHA-256 for traceability."""
    from drillstring.controller.gains import GainsFileError, read_gains
    from drillstring.model.params import REFERENCE

    try:
        gains = read_gains(path)
    except GainsFileError as exc:
        raise BuildError(str(exc)) from None
    if gains.params != REFERENCE:
        print(
            f"build_fmus: warning: the gains in {path} were designed for {gains.params}, the "
            f"plant FMU's start values are the reference set {REFERENCE}",
            file=sys.stderr,
        )
    return {
        "F": list(gains.F),
        "K0": gains.K0,
        "R_ff": gains.R_ff,
        "source": path.name,
        "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
    }


# ------------------------------------------------------------------------------------------------
# the build environment: compiler, Python headers, the Python recorded in the FMU
# ------------------------------------------------------------------------------------------------


def find_compiler() -> list[str]:
    """The C compiler (:func:`drillstring.ccompiler.find_c_compiler`: ``$CC``, else ``cc``,
    ``gcc`` or ``clang`` on PATH)."""
    from drillstring.ccompiler import CompilerNotFound, find_c_compiler

    try:
        return find_c_compiler()
    except CompilerNotFound as exc:
        if os.environ.get("CC"):
            raise BuildError(str(exc)) from None
        raise BuildError(
            f"{exc}: build_fmus.py compiles the FMUs' front layer "
            "(fmu_src/fmi_front/*.c) with the system's C compiler; install one "
            "(Debian: apt-get install gcc) or set CC"
        ) from None


def python_record() -> dict[str, Any]:
    """libpython, home and site-packages of this interpreter (what the FMU will start)."""
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        raise BuildError(
            f"{sys.executable} has no shared libpython (built without --enable-shared): the FMUs "
            "need one to start Python in a host process"
        )
    libdir = Path(sysconfig.get_config_var("LIBDIR"))
    libpython = libdir / (sysconfig.get_config_var("INSTSONAME") or "")
    if not libpython.is_file():
        raise BuildError(f"libpython not found at {libpython}")
    paths = sysconfig.get_paths()
    sites = list(dict.fromkeys([paths["purelib"], paths["platlib"]]))
    return {
        "version": f"{sys.version_info.major}.{sys.version_info.minor}",
        "libpython": str(libpython),
        "home": sys.base_prefix,
        "site": sites,
        "include": paths["include"],
    }


def runtime_file(record: dict[str, Any]) -> str:
    """``resources/drillstring_fmu_python.cfg``: read by the front layer before Python exists."""
    lines = [
        "# The Python that built this FMU (written by build_fmus.py; read by its front layer).",
        f"# On another machine: {OVERRIDES['libpython']}, {OVERRIDES['home']} and "
        f"{OVERRIDES['site']} (':'-separated) override these lines.",
        f"version {record['version']}",
        f"libpython {record['libpython']}",
        f"home {record['home']}",
    ]
    lines += [f"site {s}" for s in record["site"]]
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------------
# staging and building
# ------------------------------------------------------------------------------------------------


def _package_version() -> str:
    from importlib import metadata

    try:
        return metadata.version("drillstring")
    except metadata.PackageNotFoundError:
        return "unknown"


def entry_module(spec: FmuSpec) -> tuple[str, str]:
    """Name and text of the entry module named in ``slavemodule.txt``.

    pythonfmu 0.7.0 compiles and executes the file of that module anew at every ``fmi2Instantiate``
    (with the module's namespace as globals and a fresh dictionary as locals) and keeps, for each
    class bound in those locals, the list of its MRO and two strings per MRO entry (about 1 KB
    per instance, never freed); were the class defined there, it would keep the class and its
    functions too (~64 KB per instance). It takes the slave class from the module's attribute
    named after the class it found there, the empty name when it found none. So this module
    imports the script (once per process) and stores the class under the attribute ``""``:
    executing it binds no class and defines nothing new.
    """
    name = f"{spec.model}_entry"
    text = (
        f'"""Entry module of {spec.model}.fmu for pythonfmu\'s library, written by\n'
        "build_fmus.py: executed at every fmi2Instantiate, it binds no class and stores the\n"
        'slave class as the attribute "" (see build_fmus.py, `entry_module`)."""\n\n'
        f"import {spec.model}\n\n"
        f'globals()[""] = {spec.model}.{spec.model}\n'
    )
    return name, text


def class_module(spec: FmuSpec) -> str:
    """The text of the generated module ``<model>.py`` of a spec."""
    lines = [
        f'"""{spec.model}: the class {spec.base} of {spec.script.name} with',
        ", ".join(f"{k} = {v!r}" for k, v in spec.attributes) + " (written by build_fmus.py).",
        '"""',
        "",
        f"from {spec.script.stem} import {spec.base}",
        "",
        "",
        f"class {spec.model}({spec.base}):",
        f'    """{spec.model}.fmu: see {spec.script.name}."""',
        "",
        f"    MODEL = {spec.model!r}",
        *(f"    {k} = {v!r}" for k, v in spec.attributes),
    ]
    return "\n".join(lines) + "\n"


def _stage(spec: FmuSpec, staging: Path, config: dict[str, Any], record: dict[str, Any]) -> Path:
    """Write the files bundled into ``resources/``; returns the staged script pythonfmu builds
    (the generated class module)."""
    shutil.copytree(PACKAGE, staging / "drillstring", ignore=_IGNORE)
    for path in (SUPPORT, BOOT, UNITS_MODULE, spec.script):
        shutil.copyfile(path, staging / path.name)
    name, text = entry_module(spec)
    (staging / f"{name}.py").write_text(text, encoding="utf-8")
    script = staging / f"{spec.model}.py"
    script.write_text(class_module(spec), encoding="utf-8")
    cfg = json.dumps(config, indent=2, sort_keys=True) + "\n"
    (staging / CONFIG_NAME).write_text(cfg, encoding="utf-8")
    (staging / RUNTIME_NAME).write_text(runtime_file(record), encoding="utf-8")
    (staging / "requirements.txt").write_text(REQUIREMENTS, encoding="utf-8")
    return script


def _load_script(spec: FmuSpec, script: Path) -> tuple[Any, Any]:
    """The staged script's module and an instance of its class (resources = the staging folder)."""
    name = f"_build_fmus_{script.stem}"
    module_spec = importlib.util.spec_from_file_location(name, script)
    assert module_spec is not None and module_spec.loader is not None
    module = importlib.util.module_from_spec(module_spec)
    module_spec.loader.exec_module(module)
    cls = getattr(module, spec.model)
    instance = cls(instance_name="build_fmus", resources=str(script.parent))
    if instance.log_queue:
        raise BuildError(f"{spec.model}: {[m.msg for m in instance.log_queue]}")
    return module, instance


def _pythonfmu_build(script: Path, dest: Path, documentation: Path) -> Path:
    from pythonfmu import FmuBuilder

    staging = script.parent
    files = [p for p in sorted(staging.iterdir()) if p != script]
    saved = list(sys.path)
    try:
        return Path(
            FmuBuilder.build_FMU(
                script,
                dest=dest,
                project_files=files,
                documentation_folder=documentation,
                canGetAndSetFMUstate=True,
                canSerializeFMUstate=True,
            )
        )
    finally:
        sys.path[:] = saved
        _forget_fmu_modules()


def _forget_fmu_modules() -> None:
    for name in _FMU_MODULES:
        sys.modules.pop(name, None)


# ------------------------------------------------------------------------------------------------
# modelDescription.xml post-processing
# ------------------------------------------------------------------------------------------------

#: Attribute order of the type elements in the FMI 2.0 schema (kept for readability).
_ATTRIBUTE_ORDER = ("declaredType", "unit", "displayUnit", "min", "max", "start")


def _format_start(value: Any, kind: str) -> str:
    if kind == "Real":
        return repr(float(value))
    if kind == "Boolean":
        return "true" if value else "false"
    return str(int(value))


def _format_bound(value: float, kind: str) -> str:
    return repr(float(value)) if kind == "Real" else str(int(value))


def _fix_model_description(root: ET.Element, variables: Sequence[Any], starts: dict[str, Any]):
    """Types, units, ranges, exact start values and the true ModelStructure (module docstring)."""
    svs = list(root.find("ModelVariables") or [])
    index = {sv.get("name"): i + 1 for i, sv in enumerate(svs)}
    by_name = {v.name: v for v in variables}
    if set(index) != set(by_name):
        raise BuildError(f"variables {sorted(by_name)} but modelDescription has {sorted(index)}")
    enumerations: dict[str, Any] = {}
    for sv in svs:
        var = by_name[sv.get("name")]
        for child in list(sv):
            sv.remove(child)
        sv.set("causality", var.causality)
        sv.set("variability", var.variability)
        if var.initial is None:
            sv.attrib.pop("initial", None)
        else:
            sv.set("initial", var.initial)
        attrib: dict[str, str] = {}
        if var.type == "Enumeration":
            attrib["declaredType"] = var.type_name
            enumerations[var.type_name] = var
        if var.type == "Real":
            attrib["unit"] = var.unit
            if var.display_unit is not None:
                attrib["displayUnit"] = var.display_unit
        if var.min is not None:
            attrib["min"] = _format_bound(var.min, var.type)
        if var.max is not None:
            attrib["max"] = _format_bound(var.max, var.type)
        if var.causality != "output":
            attrib["start"] = _format_start(starts[var.name], var.type)
        ordered = {k: attrib[k] for k in _ATTRIBUTE_ORDER if k in attrib}
        ET.SubElement(sv, var.type, ordered)

    position = list(root).index(root.find("CoSimulation")) + 1
    root.insert(position, unit_definitions(variables))
    if enumerations:
        types = ET.Element("TypeDefinitions")
        for name, var in sorted(enumerations.items()):
            simple = ET.SubElement(types, "SimpleType", name=name)
            enum = ET.SubElement(simple, "Enumeration")
            for i, (item, desc) in enumerate(var.items):
                ET.SubElement(enum, "Item", name=item, value=str(i + 1), description=desc)
        root.insert(position + 1, types)

    structure = root.find("ModelStructure")
    assert structure is not None
    for child in list(structure):
        structure.remove(child)
    outputs = [v for v in variables if v.causality == "output"]
    out_node = ET.SubElement(structure, "Outputs")
    for var in sorted(outputs, key=lambda v: index[v.name]):
        deps = [index[d] for d in var.depends_on]
        attrib = {"index": str(index[var.name]), "dependencies": " ".join(map(str, deps))}
        if deps:
            attrib["dependenciesKind"] = " ".join("dependent" for _ in deps)
        ET.SubElement(out_node, "Unknown", attrib)
    # initial="calculated": computed from the parameters (and inputs) in initialization mode; no
    # dependencies attribute = may depend on all of them
    node = ET.SubElement(structure, "InitialUnknowns")
    for var in sorted(outputs, key=lambda v: index[v.name]):
        ET.SubElement(node, "Unknown", index=str(index[var.name]))


def unit_definitions(variables: Sequence[Any]) -> ET.Element:
    """``UnitDefinitions`` of the units the Real variables use, with their ``BaseUnit``
    exponents and the display units they name (:data:`drillstring.model.units.UNITS`)."""
    from drillstring.model.units import BASE_UNITS, UNITS

    used: dict[str, set[str]] = {}
    for var in variables:
        if var.type == "Real":
            if var.unit not in UNITS:
                raise BuildError(f"variable {var.name}: unit {var.unit!r} is not defined")
            shown = used.setdefault(var.unit, set())
            if var.display_unit is not None:
                UNITS[var.unit].display_unit(var.display_unit)  # raises if it is not defined
                shown.add(var.display_unit)
    node = ET.Element("UnitDefinitions")
    for name in sorted(used):
        unit = UNITS[name]
        elem = ET.SubElement(node, "Unit", name=name)
        exponents = {k: str(unit.exponents[k]) for k in BASE_UNITS if unit.exponents.get(k)}
        ET.SubElement(elem, "BaseUnit", exponents)
        for display in unit.display:
            if display.name in used[name]:
                attrib = {"name": display.name, "factor": repr(display.factor)}
                if display.offset:
                    attrib["offset"] = repr(display.offset)
                ET.SubElement(elem, "DisplayUnit", attrib)
    return node


def _xml_bytes(root: ET.Element) -> bytes:
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _generation_time(source_date_epoch: int | None) -> str | None:
    if source_date_epoch is None:
        return None
    t = _dt.datetime.fromtimestamp(source_date_epoch, tz=_dt.UTC)
    return t.strftime("%Y-%m-%dT%H:%M:%SZ")


def _set_guid(root: ET.Element, entries: dict[str, bytes], extra: bytes) -> None:
    """GUID from the model description (without GUID and date), the non-binary entries and
    ``extra`` (the front layer's sources and pythonfmu's library): the binaries are made from
    exactly these, and the front layer's binary contains the GUID, so it cannot be hashed."""
    generated = root.get("generationDateAndTime")
    root.set("guid", "")
    root.attrib.pop("generationDateAndTime", None)
    digest = hashlib.sha256(_xml_bytes(root))
    for name in sorted(entries):
        if not name.startswith("binaries/"):
            digest.update(name.encode("utf-8") + b"\0" + hashlib.sha256(entries[name]).digest())
    digest.update(extra)
    root.set("guid", "{" + str(uuid.uuid5(_GUID_NAMESPACE, digest.hexdigest())) + "}")
    if generated is not None:  # keep the attribute order of the FMI schema's listing
        attrib = dict(root.attrib)
        root.attrib.clear()
        for key, value in attrib.items():
            root.set(key, value)
            if key == "generationTool":
                root.set("generationDateAndTime", generated)


# ------------------------------------------------------------------------------------------------
# the front layer
# ------------------------------------------------------------------------------------------------

_TYPE_CODE = {"Real": "R", "Integer": "I", "Enumeration": "E", "Boolean": "B", "String": "S"}
_CAUSALITY_CODE = {"parameter": "DS_PARAMETER", "input": "DS_INPUT", "output": "DS_OUTPUT"}


def model_header(root: ET.Element, entry: str) -> str:
    """``model_data.h`` of the front layer, from the final modelDescription.xml."""
    cs = root.find("CoSimulation")
    assert cs is not None
    svs = list(root.find("ModelVariables") or [])
    rows = {}
    for sv in svs:
        kind = sv[0].tag
        causality = sv.get("causality", "local")
        if causality not in _CAUSALITY_CODE:
            raise BuildError(f"variable {sv.get('name')}: causality {causality} not supported")
        vr = int(sv.get("valueReference", "-1"))
        rows[vr] = (sv.get("name"), _TYPE_CODE[kind], _CAUSALITY_CODE[causality])
    if not rows or min(rows) < 0 or max(rows) > 100_000:
        raise BuildError(f"value references {sorted(rows)} out of the supported range")
    categories = [c.get("name") for c in root.find("LogCategories") or []]
    lines = [
        f"/* model_data.h of {cs.get('modelIdentifier')}: generated by build_fmus.py from its",
        "   modelDescription.xml; do not edit. */",
        f"#define DS_MODEL_IDENTIFIER {json.dumps(cs.get('modelIdentifier'))}",
        f"#define DS_GUID {json.dumps(root.get('guid'))}",
        f"#define DS_ENTRY_MODULE {json.dumps(entry)}",
        f"#define DS_N_VR {max(rows) + 1}",
        f"#define DS_N_LOG_CATEGORIES {len(categories)}",
        "#ifdef DS_MODEL_TABLES /* defined in front.c only */",
        "const ds_variable DS_VARIABLES[DS_N_VR] = {",
    ]
    for vr in sorted(rows):
        name, code, causality = rows[vr]
        lines.append(f"    [{vr}] = {{{json.dumps(name)}, '{code}', {causality}}},")
    lines += [
        "};",
        "const char *const DS_LOG_CATEGORIES[DS_N_LOG_CATEGORIES + 1] = {",
        *[f"    {json.dumps(c)}," for c in categories],
        "    NULL,",
        "};",
        "#endif",
    ]
    return "\n".join(lines) + "\n"


def front_layer_files() -> list[Path]:
    """The front layer's sources (``fmu_src/fmi_front/*.c`` and ``*.h``), sorted by name."""
    files = sorted(p for p in FRONT_LAYER.iterdir() if p.suffix in (".c", ".h"))
    if not any(p.suffix == ".c" for p in files):
        raise BuildError(f"no C files of the front layer in {FRONT_LAYER}")
    return files


def front_layer_digest() -> bytes:
    """SHA-256 over the names and contents of the front layer's sources (for the GUID)."""
    digest = hashlib.sha256()
    for path in front_layer_files():
        content = hashlib.sha256(path.read_bytes()).digest()
        digest.update(path.name.encode("utf-8") + b"\0" + content)
    return digest.digest()


def compile_front_layer(
    header: str, out: Path, include: str, work: Path, extra_flags: Sequence[str] = ()
) -> None:
    """Compile the front layer's C files in one call, with ``header`` as ``model_data.h``, into
    ``out`` (``extra_flags`` after the project's flags: for the tests' analyses)."""
    if not (Path(include) / "Python.h").is_file():
        raise BuildError(
            f"no Python.h in {include}: the front layer needs the headers of the Python that "
            "builds the FMUs (Debian: the python3-dev package of that Python)"
        )
    gen = work / "gen"
    gen.mkdir(parents=True, exist_ok=True)
    (gen / "model_data.h").write_text(header, encoding="utf-8")
    sources = []
    for path in front_layer_files():
        shutil.copyfile(path, gen / path.name)
        if path.suffix == ".c":
            sources.append(str(gen / path.name))
    cmd = [
        *find_compiler(),
        *CFLAGS,
        *CFLAGS_STRICT,
        *extra_flags,
        f"-ffile-prefix-map={gen}=.",
        "-I",
        str(gen),
        "-I",
        include,
        "-o",
        str(out),
        *sources,
        *LDLIBS,
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=gen)
    if proc.returncode != 0:
        raise BuildError(
            f"compiling the front layer failed ({shlex.join(cmd)}):\n{proc.stdout}{proc.stderr}"
        )


# ------------------------------------------------------------------------------------------------
# documentation/
# ------------------------------------------------------------------------------------------------


def _time_base(variables: Sequence[Any]) -> str:
    """The paragraph of ``documentation/index.html`` on what a host reads as the FMU's time."""
    from drillstring.model.params import REFERENCE_RIG

    implicit = (
        "The FMU declares no independent variable, so by FMI 2.0 (section 2.2.7) its time is a "
        "variable <code>time</code> with unit <code>s</code>, and every host reads it as seconds."
    )
    if any(v.type == "Real" and v.unit not in (None, "1") for v in variables):
        return f"<p>{implicit} It is: this FMU's time is in seconds.</p>"
    times = [f"<code>{v.name}</code>" for v in variables if v.name in ("h", "event_tol", "t_on")]
    return (
        f"<p>{implicit} Its numbers are the paper's scaled time tau = t/t*: one unit of this "
        f"FMU's time is t* = sqrt(I1/C) seconds of the rig ({REFERENCE_RIG.t_star:.6g} s for the "
        "reference rig), and in that unit are the start time, the communication points and step "
        "sizes of <code>fmi2SetupExperiment</code> and <code>fmi2DoStep</code>, the default "
        f'experiment and the time parameters ({", ".join(times)}; unit <code>"1"</code>). The '
        "FMUs named <code>...SI</code> are the same model in seconds and SI units, for coupling "
        "with models in seconds.</p>"
    )


def documentation(cls: Any, variables: Sequence[Any], starts: dict[str, Any]) -> str:
    """``documentation/index.html`` of one FMU (FMI 2.0, section 2.1: the documentation's entry)."""
    esc = html.escape
    rows = []
    for v in variables:
        start = "" if v.causality == "output" else _format_start(starts[v.name], v.type)
        if v.type == "Enumeration":
            start += " (" + v.item(int(starts[v.name])) + ")"
            kind = f"Enumeration {v.type_name}: " + ", ".join(
                f"{i + 1} = {n}" for i, (n, _) in enumerate(v.items)
            )
        else:
            kind = v.type
        lo = "" if v.min is None else _format_bound(v.min, v.type)
        hi = "" if v.max is None else _format_bound(v.max, v.type)
        rng = f"[{lo or '-inf'}, {hi or 'inf'}]" if (lo or hi) else ""
        unit = v.unit if v.type == "Real" else ""
        if v.display_unit is not None:
            unit += f" (shown in {v.display_unit})"
        rows.append(
            f"<tr><td><code>{esc(v.name)}</code></td><td>{v.causality}</td><td>{esc(kind)}</td>"
            f"<td>{esc(unit)}</td><td>{esc(start)}</td><td>{esc(rng)}</td>"
            f"<td>{esc(v.description)}</td></tr>"
        )
    validity = "".join(f"<p>{esc(p)}</p>" for p in cls.VALIDITY)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{esc(cls.MODEL)}</title></head>
<body>
<h1>{esc(cls.MODEL)}</h1>
<p>{esc(cls.description)}. FMI 2.0 co-simulation FMU built by the drillstring project
(<code>build_fmus.py</code>): a front layer in plain C
(<code>binaries/linux64/{cls.MODEL}.so</code>) in front of pythonfmu's library
(<code>binaries/linux64/{cls.MODEL}_pythonfmu.so</code>), which runs the Python model in
<code>resources/</code>.</p>

<h2>Time base and units</h2>
<p>{esc(cls.TIME_AND_UNITS)} The start time must be 0 (<code>fmi2SetupExperiment</code>): the
model's history before it is the nominal motion. Any step size &gt; 0 is accepted and need not
be constant; the communication point of <code>fmi2DoStep</code> must be the FMU's current time.
Inputs are held constant over each step.</p>
{_time_base(variables)}

<h2>Variables</h2>
<table border="1" cellspacing="0" cellpadding="3">
<tr><th>name</th><th>causality</th><th>type</th><th>unit</th><th>start</th><th>range</th>
<th>description</th></tr>
{chr(10).join(rows)}
</table>
<p>Outputs are computed from the parameters (<code>initial="calculated"</code>): they can be read
from <code>fmi2EnterInitializationMode</code> on.</p>

<h2>Validity of the model</h2>
{validity}

<h2>Statuses</h2>
<p><code>fmi2Error</code> comes from the very call that received a bad value (a parameter out of
range or an inconsistent combination at <code>fmi2ExitInitializationMode</code>, a non-finite
number, an unknown value reference, a variable of another type, a parameter set after
initialization, a step size &lt;= 0, a communication point that is not the FMU's time, an FMU
state of another FMU or corrupted bytes, an illegal call sequence); the value is not applied and
the instance goes on as before the call. <code>fmi2Warning</code> comes with a logged warning.
<code>fmi2Discard</code> only when the model leaves its validity inside a step: then
<code>fmi2GetRealStatus(fmi2LastSuccessfulTime)</code> is the time reached and the outputs hold
the state there; restore an earlier state (<code>fmi2SetFMUstate</code>) or terminate. Errors,
discards and warnings are always logged; information only with logging on (categories
<code>logInfo</code>, <code>logAll</code>).</p>

<h2>What the host needs</h2>
<p>Linux x86-64 and, on the machine that built the FMU, nothing else: the FMU loads the recorded
libpython itself and starts it with the recorded home and site-packages
(<code>resources/{RUNTIME_NAME}</code>); a host that already runs Python (fmpy, libcosimpy) lends
its interpreter, which then needs numpy. No <code>LD_PRELOAD</code>, <code>PYTHONPATH</code> or
<code>PYTHONHOME</code>. On another machine set</p>
<ul>
<li><code>{OVERRIDES["libpython"]}</code>: the <code>libpython3.11.so</code> of a CPython 3.11
(built with <code>--enable-shared</code>);</li>
<li><code>{OVERRIDES["home"]}</code>: its installation prefix (with
<code>lib/python3.11</code>);</li>
<li><code>{OVERRIDES["site"]}</code>: ':'-separated site-packages with numpy (and numba for the
compiled kernel).</li>
</ul>
<p>The drillstring package is copied once into <code>$DRILLSTRING_FMU_CACHE</code>, else
<code>$XDG_CACHE_HOME/drillstring</code>, else <code>~/.cache/drillstring</code>, where numba keeps
the compiled kernel: the first run on a machine compiles it (logged at info level, 10-20 s), every
later run of the same build, in any unpack folder, loads it. <code>DRILLSTRING_JIT=0</code> runs
the plain-Python kernel instead (bit-identical results, slower).</p>
</body></html>
"""


# ------------------------------------------------------------------------------------------------
# the archive
# ------------------------------------------------------------------------------------------------


def _write_zip(entries: dict[str, bytes], dest: Path, source_date_epoch: int | None) -> None:
    date_time = _ZIP_EPOCH
    if source_date_epoch is not None:
        t = _dt.datetime.fromtimestamp(max(source_date_epoch, 315532800), tz=_dt.UTC)
        date_time = (t.year, t.month, t.day, t.hour, t.minute, t.second)
    tmp = dest.with_name(dest.name + ".tmp")
    with zipfile.ZipFile(tmp, "w") as z:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, date_time=date_time)
            info.compress_type = zipfile.ZIP_DEFLATED
            mode = 0o755 if name.endswith(".so") else 0o644
            info.external_attr = mode << 16
            info.create_system = 3  # unix, so external_attr is read as permissions
            z.writestr(info, entries[name])
    tmp.replace(dest)


def _postprocess(
    raw: Path,
    dest: Path,
    spec: FmuSpec,
    cls: Any,
    starts: dict[str, Any],
    record: dict[str, Any],
    source_date_epoch: int | None,
    work: Path,
) -> None:
    """modelDescription.xml, the binaries, the entry module; then a deterministic archive."""
    with zipfile.ZipFile(raw) as z:
        entries = {info.filename: z.read(info.filename) for info in z.infolist()}
    root = ET.fromstring(entries.pop("modelDescription.xml"))
    _fix_model_description(root, cls.VARIABLES, starts)
    stamp = _generation_time(source_date_epoch)
    if stamp is not None:
        root.set("generationDateAndTime", stamp)

    pythonfmu_lib = entries.pop(f"binaries/linux64/{spec.model}.so", None)
    if pythonfmu_lib is None:
        raise BuildError(f"pythonfmu built no linux64 binary for {spec.model}")
    for name in [n for n in entries if n.startswith("binaries/")]:
        del entries[name]  # other platforms: not built and tested here
    entry, _ = entry_module(spec)
    entries["resources/slavemodule.txt"] = entry.encode("utf-8")
    extra = front_layer_digest()
    extra += hashlib.sha256(pythonfmu_lib).digest() + " ".join(CFLAGS).encode("utf-8")
    _set_guid(root, entries, extra)

    layer = work / f"{spec.model}.so"
    compile_front_layer(model_header(root, entry), layer, record["include"], work)
    entries[f"binaries/linux64/{spec.model}.so"] = layer.read_bytes()
    entries[f"binaries/linux64/{spec.model}_pythonfmu.so"] = pythonfmu_lib
    entries["modelDescription.xml"] = _xml_bytes(root)
    _write_zip(entries, dest, source_date_epoch)


def validate(fmu: Path) -> None:
    """Raise :class:`BuildError` listing every problem ``fmpy.validate_fmu`` reports."""
    from fmpy.validation import validate_fmu

    problems = validate_fmu(str(fmu))
    if problems:
        listing = "\n  ".join(problems)
        raise BuildError(
            f"{fmu.name}: fmpy.validate_fmu reports {len(problems)} problem(s):\n  {listing}"
        )


# ------------------------------------------------------------------------------------------------
# driver
# ------------------------------------------------------------------------------------------------


def build_fmu(
    spec: FmuSpec, out_dir: Path, config: dict[str, Any], source_date_epoch: int | None = None
) -> Path:
    """Build, post-process and validate one FMU into ``out_dir``; returns its path."""
    find_compiler()  # before any work: a missing compiler fails at once
    record = python_record()
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="build_fmus_") as tmp:
        work = Path(tmp)
        staging = work / "staging"
        staging.mkdir()
        script = _stage(spec, staging, config, record)
        saved = list(sys.path)
        sys.path.insert(0, str(staging))
        _forget_fmu_modules()
        try:
            module, instance = _load_script(spec, script)
        finally:
            sys.path[:] = saved
        cls = getattr(module, spec.model)
        starts = dict(instance.values)
        docs = work / "documentation"
        docs.mkdir()
        text = documentation(cls, cls.VARIABLES, starts)
        (docs / "index.html").write_text(text, encoding="utf-8")
        raw = _pythonfmu_build(script, work / "raw", docs)
        dest = out_dir / f"{spec.model}.fmu"
        _postprocess(raw, dest, spec, cls, starts, record, source_date_epoch, work)
    validate(dest)
    return dest


def build_fmus(
    out_dir: str | os.PathLike[str] = DEFAULT_OUT,
    gains_path: str | os.PathLike[str] | None = None,
    source_date_epoch: int | None = None,
) -> dict[str, Path]:
    """Build every FMU (plant, LMI and top-drive controller; scaled and SI) and the SSP packages
    into ``out_dir``; returns {model identifier or package name: path}.

    ``gains_path`` defaults to ``drillstring.controller.gains.DEFAULT_GAINS_PATH``;
    ``source_date_epoch`` defaults to the environment variable ``SOURCE_DATE_EPOCH``.
    """
    from drillstring.controller.gains import DEFAULT_GAINS_PATH

    out = Path(out_dir)
    gains_file = Path(gains_path) if gains_path is not None else DEFAULT_GAINS_PATH
    if not gains_file.is_file():
        synthesize_gains(gains_file)
    if source_date_epoch is None and os.environ.get("SOURCE_DATE_EPOCH"):
        try:
            source_date_epoch = int(os.environ["SOURCE_DATE_EPOCH"])
        except ValueError:
            raise BuildError(
                f"SOURCE_DATE_EPOCH must be an integer, got {os.environ['SOURCE_DATE_EPOCH']!r}"
            ) from None
    gains = load_gains(gains_file)  # before building anything: a bad file fails at once
    base = {"version": _package_version(), "format": 1}
    control = {**base, "gains": gains}
    topdrive = {**control, "topdrive": topdrive_config()}
    built = {
        spec.model: build_fmu(spec, out, config, source_date_epoch)
        for spec, config in (
            (PLANT, base),
            (CONTROLLER, control),
            (PLANT_SI, base),
            (CONTROLLER_SI, control),
            (TOPDRIVE, topdrive),
            (TOPDRIVE_SI, topdrive),
        )
    }
    built.update(build_packages(out, source_date_epoch))
    return built


def topdrive_config() -> dict[str, Any]:
    """The top-drive controller's tunings (scaled, reference set) and which one is its start
    values (:func:`drillstring.orchestration.loop_ssp.topdrive_tunings`)."""
    from drillstring.orchestration.loop_ssp import TOPDRIVE_DEFAULT, topdrive_tunings

    return {"default": TOPDRIVE_DEFAULT, "tunings": topdrive_tunings()}


def build_packages(out_dir: Path, source_date_epoch: int | None = None) -> dict[str, Path]:
    """The SSP 1.0 packages of the closed loop (:mod:`drillstring.orchestration.loop_ssp`) from
    the FMUs in ``out_dir``, validated against the SSP 1.0 schemas that fmpy ships: the loop
    closed by the LMI controller and by the top-drive controller, in both unit systems."""
    from drillstring.orchestration.closed_loop import SCALED, SI, TOPDRIVE, TOPDRIVE_SI
    from drillstring.orchestration.loop_ssp import write_loop_package
    from drillstring.orchestration.ssp import SspError, validate_ssp

    built = {}
    for variant in (SCALED, SI, TOPDRIVE, TOPDRIVE_SI):
        try:
            path = write_loop_package(out_dir, variant, source_date_epoch=source_date_epoch)
        except SspError as exc:
            raise BuildError(f"SSP package {variant.ssp}: {exc}") from None
        problems = validate_ssp(path)
        if problems:
            raise BuildError(f"{path.name}: " + "; ".join(problems))
        built[path.stem] = path
    return built


def main(argv: Sequence[str] | None = None) -> int:
    """Command line entry point; returns the exit status (0 ok, 1 build or validation error)."""
    ap = argparse.ArgumentParser(
        prog="build_fmus.py",
        description="Build, post-process and validate the drillstring plant and controller FMUs.",
    )
    ap.add_argument(
        "--gains",
        type=Path,
        default=None,
        help="gains file of the design (default: out/design/gains.json, designed if missing)",
    )
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder (default: build/)")
    args = ap.parse_args(argv)
    try:
        built = build_fmus(args.out, args.gains)
    except BuildError as exc:
        print(f"build_fmus: error: {exc}", file=sys.stderr)
        return 1
    for path in built.values():
        check = "fmpy.validate_fmu" if path.suffix == ".fmu" else "SSP 1.0 schemas (fmpy's)"
        print(f"{path}: {check}: 0 problems")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
