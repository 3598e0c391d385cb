"""Build the drillstring FMUs: the plant and the torsional controller (FMI 2.0 co-simulation).

Usage::

    python build_fmus.py [--gains out/design/gains.json] [--out build/]

For each of ``fmu_src/drillstring_plant.py`` (``DrillStringPlant.fmu``) and
``fmu_src/torsional_controller.py`` (``TorsionalController.fmu``):

1. stage the project files bundled into the FMU's ``resources/``: the ``drillstring`` package (the
   physics; no model code is in the FMU scripts), the shared ``drillstring_fmu_support.py``, the
   build configuration ``drillstring_fmu.json`` (package version, controller gains) and
   ``requirements.txt`` (numpy only, for ``pythonfmu deploy``);
2. build with pythonfmu (``canGetAndSetFMUstate`` and ``canSerializeFMUstate`` true);
3. post-process ``modelDescription.xml`` where pythonfmu cannot express the truth: the
   ``ModelStructure`` (each script's ``OUTPUT_DEPENDENCIES``: the plant's outputs do not depend
   on its input, the controller's output depends on its four inputs), unit "1" on every Real with
   its ``UnitDefinitions``, start values written with all 17 digits, a GUID derived from the
   content and a pinned ``generationDateAndTime`` when ``SOURCE_DATE_EPOCH`` is set;
4. rewrite the archive deterministically (sorted entries, fixed timestamps) and run
   ``fmpy.validate_fmu``; any problem fails the build with the list of problems.

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
import importlib.util
import json
import os
import shutil
import sys
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
CONFIG_NAME = "drillstring_fmu.json"
DEFAULT_OUT = ROOT / "build"
#: Runtime dependencies of the FMUs' Python code besides the standard library.
REQUIREMENTS = "numpy>=2.0\n"
#: Files of the drillstring package that are not bundled.
_IGNORE = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc", ".*")
#: Namespace of the content-derived GUIDs.
_GUID_NAMESPACE = uuid.UUID("6f1c2a8e-1d5b-5d3e-9a7c-2b4f0e8d9c11")
#: Fixed timestamp of the archive entries (the earliest a zip file can hold).
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)


class BuildError(RuntimeError):
    """A build that cannot be completed or an FMU that fails validation."""


@dataclass(frozen=True)
class FmuSpec:
    """One FMU: its pythonfmu script and the name of its class (= model identifier)."""

    script: Path
    model: str


PLANT = FmuSpec(FMU_SRC / "drillstring_plant.py", "DrillStringPlant")
CONTROLLER = FmuSpec(FMU_SRC / "torsional_controller.py", "TorsionalController")


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
# staging and building
# ------------------------------------------------------------------------------------------------


def _package_version() -> str:
    from importlib import metadata

    try:
        return metadata.version("drillstring")
    except metadata.PackageNotFoundError:
        return "unknown"


def _stage(staging: Path, config: dict[str, Any]) -> list[Path]:
    """Write the project files bundled into ``resources/``; returns their paths."""
    package = staging / "drillstring"
    shutil.copytree(PACKAGE, package, ignore=_IGNORE)
    support = staging / SUPPORT.name
    shutil.copyfile(SUPPORT, support)
    cfg = staging / CONFIG_NAME
    cfg.write_text(json.dumps(config, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    req = staging / "requirements.txt"
    req.write_text(REQUIREMENTS, encoding="utf-8")
    return [package, support, cfg, req]


def _load_script(spec: FmuSpec, staging: Path) -> tuple[Any, Any]:
    """The script module and an instance of its class, resources = the staging folder."""
    name = f"_build_fmus_{spec.script.stem}"
    module_spec = importlib.util.spec_from_file_location(name, spec.script)
    assert module_spec is not None and module_spec.loader is not None
    module = importlib.util.module_from_spec(module_spec)
    module_spec.loader.exec_module(module)
    instance = getattr(module, spec.model)(instance_name="build_fmus", resources=str(staging))
    return module, instance


def _pythonfmu_build(spec: FmuSpec, staging: Path, files: list[Path], dest: Path) -> Path:
    from pythonfmu import FmuBuilder

    saved = list(sys.path)
    try:
        return Path(
            FmuBuilder.build_FMU(
                spec.script,
                dest=dest,
                project_files=files,
                canGetAndSetFMUstate=True,
                canSerializeFMUstate=True,
            )
        )
    finally:
        sys.path[:] = saved
        sys.modules.pop(spec.script.stem, None)


# ------------------------------------------------------------------------------------------------
# modelDescription.xml post-processing
# ------------------------------------------------------------------------------------------------


def _fix_model_description(
    root: ET.Element, dependencies: dict[str, tuple[str, ...]], starts: dict[str, float]
) -> None:
    """Units, exact start values and the true ModelStructure (see the module docstring)."""
    model_variables = root.find("ModelVariables")
    assert model_variables is not None
    variables = list(model_variables)
    index = {sv.get("name"): i + 1 for i, sv in enumerate(variables)}
    for sv in variables:
        real = sv.find("Real")
        if real is None:
            continue
        real.set("unit", "1")
        if real.get("start") is not None:
            real.set("start", repr(float(starts[sv.get("name")])))

    units = ET.Element("UnitDefinitions")
    ET.SubElement(units, "Unit", name="1")
    children = list(root)
    position = children.index(root.find("CoSimulation")) + 1
    root.insert(position, units)

    outputs = [sv for sv in variables if sv.get("causality") == "output"]
    declared = set(dependencies)
    names = {sv.get("name") for sv in outputs}
    if declared != names:
        raise BuildError(
            f"OUTPUT_DEPENDENCIES declares {sorted(declared)} but the outputs are {sorted(names)}"
        )
    structure = root.find("ModelStructure")
    assert structure is not None
    for child in list(structure):
        structure.remove(child)
    out_node = ET.SubElement(structure, "Outputs")
    initial_unknowns = []
    for sv in outputs:
        name = sv.get("name")
        deps = dependencies[name]
        attrib = {"index": str(index[name]), "dependencies": " ".join(str(index[d]) for d in deps)}
        if deps:
            attrib["dependenciesKind"] = " ".join("dependent" for _ in deps)
        ET.SubElement(out_node, "Unknown", attrib)
        if sv.get("initial") in (None, "calculated", "approx"):
            initial_unknowns.append(index[name])
    if initial_unknowns:  # may depend on inputs and parameters: no dependencies attribute
        node = ET.SubElement(structure, "InitialUnknowns")
        for i in initial_unknowns:
            ET.SubElement(node, "Unknown", index=str(i))


def _xml_bytes(root: ET.Element) -> bytes:
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _generation_time(source_date_epoch: int | None) -> str | None:
    if source_date_epoch is None:
        return None
    t = _dt.datetime.fromtimestamp(source_date_epoch, tz=_dt.UTC)
    return t.strftime("%Y-%m-%dT%H:%M:%SZ")


def _rewrite(
    fmu: Path,
    dest: Path,
    dependencies: dict[str, tuple[str, ...]],
    starts: dict[str, float],
    source_date_epoch: int | None,
) -> None:
    """Post-process modelDescription.xml and write a deterministic archive to ``dest``."""
    with zipfile.ZipFile(fmu) as z:
        entries = {info.filename: z.read(info.filename) for info in z.infolist()}
    root = ET.fromstring(entries.pop("modelDescription.xml"))
    _fix_model_description(root, dependencies, starts)

    stamp = _generation_time(source_date_epoch)
    if stamp is not None:
        root.set("generationDateAndTime", stamp)
    generated = root.get("generationDateAndTime")
    root.set("guid", "")
    root.attrib.pop("generationDateAndTime", None)
    digest = hashlib.sha256(_xml_bytes(root))
    for name in sorted(entries):
        digest.update(name.encode("utf-8") + b"\0" + hashlib.sha256(entries[name]).digest())
    root.set("guid", "{" + str(uuid.uuid5(_GUID_NAMESPACE, digest.hexdigest())) + "}")
    if generated is not None:  # keep the attribute order of the FMI schema's listing
        attrib = dict(root.attrib)
        root.attrib.clear()
        for key, value in attrib.items():
            root.set(key, value)
            if key == "generationTool":
                root.set("generationDateAndTime", generated)
    entries["modelDescription.xml"] = _xml_bytes(root)

    date_time = _ZIP_EPOCH
    if source_date_epoch is not None:
        t = _dt.datetime.fromtimestamp(max(source_date_epoch, 315532800), tz=_dt.UTC)
        date_time = (t.year, t.month, t.day, t.hour, t.minute, t.second)
    tmp = dest.with_name(dest.name + ".tmp")
    with zipfile.ZipFile(tmp, "w") as z:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, date_time=date_time)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            info.create_system = 3  # unix, so external_attr is read as permissions
            z.writestr(info, entries[name])
    tmp.replace(dest)


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
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="build_fmus_") as tmp:
        staging = Path(tmp) / "staging"
        staging.mkdir()
        files = _stage(staging, config)
        saved = list(sys.path)
        sys.path.insert(0, str(staging))
        try:
            module, instance = _load_script(spec, staging)
        finally:
            sys.path[:] = saved
        from pythonfmu import Real

        starts = {v.name: float(v.getter()) for v in instance.vars.values() if isinstance(v, Real)}
        raw = _pythonfmu_build(spec, staging, files, Path(tmp) / "raw")
        dest = out_dir / f"{spec.model}.fmu"
        _rewrite(raw, dest, module.OUTPUT_DEPENDENCIES, starts, source_date_epoch)
    validate(dest)
    return dest


def build_fmus(
    out_dir: str | os.PathLike[str] = DEFAULT_OUT,
    gains_path: str | os.PathLike[str] | None = None,
    source_date_epoch: int | None = None,
) -> dict[str, Path]:
    """Build both FMUs into ``out_dir``; returns {model identifier: path}.

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
    return {
        PLANT.model: build_fmu(PLANT, out, base, source_date_epoch),
        CONTROLLER.model: build_fmu(CONTROLLER, out, {**base, "gains": gains}, source_date_epoch),
    }


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
        print(f"{path}: fmpy.validate_fmu: 0 problems")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
