"""The build of every FMU and SSP package: stage, build with pythonfmu, post-process, compile the
front layer, archive and validate (:mod:`drillstring.apps.export`).
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from drillstring.apps.export.archive import validate
from drillstring.apps.export.documentation import documentation
from drillstring.apps.export.front_layer import (
    CFLAGS,
    compile_front_layer,
    find_compiler,
    front_layer_digest,
    model_header,
)
from drillstring.apps.export.model_description import (
    fix_model_description,
    generation_time,
    set_guid,
    xml_bytes,
)
from drillstring.apps.export.model_description3 import (
    fmi3_model_description,
    fmi3_model_identifier,
)
from drillstring.apps.export.python_runtime import python_record
from drillstring.apps.export.self_contained import self_contained_fmus
from drillstring.apps.export.specs import (
    CONTROLLER,
    CONTROLLER_SI,
    PLANT,
    PLANT_SI,
    TOPDRIVE,
    TOPDRIVE_SI,
    BuildError,
    FmuSpec,
)
from drillstring.apps.export.staging import (
    entry_module,
    forget_fmu_modules,
    load_script,
    package_version,
    pythonfmu_build,
    stage,
)
from drillstring.controller import design_controller, write_gains
from drillstring.controller.gains import DEFAULT_GAINS_PATH, GainsFileError, read_gains
from drillstring.fileio import write_zip
from drillstring.model.params import REFERENCE
from drillstring.orchestration.closed_loop import SCALED, SI, fmu_paths
from drillstring.orchestration.closed_loop import TOPDRIVE as TOPDRIVE_LOOP
from drillstring.orchestration.closed_loop import TOPDRIVE_SI as TOPDRIVE_SI_LOOP
from drillstring.orchestration.loop_ssp import (
    TOPDRIVE_DEFAULT,
    topdrive_tunings,
    write_loop_package,
)
from drillstring.orchestration.ssp import SspError, validate_ssp

__all__ = [
    "DEFAULT_OUT",
    "FMI_VERSIONS",
    "build_fmu",
    "build_fmus",
    "build_fmus_into",
    "build_packages",
    "load_gains",
    "synthesize_gains",
]

#: The default output folder (relative to the working directory).
DEFAULT_OUT = Path("build")
#: The FMI versions of the build: every FMU as an FMI 2.0 FMU and as its FMI 3.0 twin
#: (``DrillStringPlant3.fmu`` beside ``DrillStringPlant.fmu``: the same slave, the front layer's
#: FMI 3.0 front, :mod:`drillstring.apps.export.model_description3`).
FMI_VERSIONS = (2, 3)
#: The binaries folder of each FMI version (Linux x86-64).
_BINARIES = {2: "binaries/linux64", 3: "binaries/x86_64-linux"}


def synthesize_gains(path: Path) -> Path:
    """Design the controller for the reference set and write its gains file to ``path``.

    :func:`drillstring.controller.design_controller`: the slope A from the axial limit cycles,
    the LMI synthesis (33) and its certificate.
    """
    print(f"build_fmus: no gains file at {path}: designing the controller", file=sys.stderr)
    design = design_controller(REFERENCE, evaluate_paper=False)
    if not design.synthesis.certificate.passed:
        raise BuildError(f"the controller design failed its certificate; no gains file at {path}")
    return write_gains(design.gains, path)


def load_gains(path: Path) -> dict[str, Any]:
    """F, K0, R_ff of a validated gains file, with its name and SHA-256 for traceability."""
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


def _postprocess(
    raw: Path,
    out_dir: Path,
    spec: FmuSpec,
    cls: Any,
    starts: dict[str, Any],
    record: dict[str, Any],
    source_date_epoch: int | None,
    work: Path,
    fmi: tuple[int, ...],
) -> dict[str, Path]:
    """modelDescription.xml, the binaries, the entry module; then a deterministic archive per FMI
    version in ``fmi`` (the FMI 3.0 twin from the final FMI 2.0 description and the same
    entries); returns {model identifier: path}."""
    with zipfile.ZipFile(raw) as z:
        entries = {info.filename: z.read(info.filename) for info in z.infolist()}
    root = ET.fromstring(entries.pop("modelDescription.xml"))
    fix_model_description(root, cls.VARIABLES, starts)
    stamp = generation_time(source_date_epoch)
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
    set_guid(root, entries, extra)

    roots = {2: (spec.model, root)}
    if 3 in fmi:
        model3 = fmi3_model_identifier(spec.model)
        roots[3] = (model3, fmi3_model_description(root, cls.VARIABLES, starts, model3, cls.ARRAYS))
    array_vrs = [cls.array_vr(j) for j in range(len(cls.ARRAYS))]
    written = {}
    for version in fmi:
        model, description = roots[version]
        layer = work / f"{model}.so"
        compile_front_layer(
            model_header(description, entry, array_vrs if version == 3 else ()),
            layer,
            record["include"],
            work,
            fmi=version,
        )
        files = dict(entries)
        files[f"{_BINARIES[version]}/{model}.so"] = layer.read_bytes()
        files[f"{_BINARIES[version]}/{model}_pythonfmu.so"] = pythonfmu_lib
        files["modelDescription.xml"] = xml_bytes(description)
        dest = out_dir / f"{model}.fmu"
        write_zip(dest, files, source_date_epoch)
        written[model] = dest
    return written


def build_fmu(
    spec: FmuSpec,
    out_dir: Path,
    config: dict[str, Any],
    source_date_epoch: int | None = None,
    fmi: tuple[int, ...] = (2,),
) -> dict[str, Path]:
    """Build, post-process and validate one FMU into ``out_dir``, as an FMI 2.0 FMU and/or its
    FMI 3.0 twin (``fmi``); returns {model identifier: path}."""
    if not fmi or set(fmi) - set(FMI_VERSIONS):
        raise BuildError(f"FMI versions {fmi!r}: choose from {FMI_VERSIONS}")
    find_compiler()  # before any work: a missing compiler fails at once
    record = python_record()
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="build_fmus_") as tmp:
        work = Path(tmp)
        staging = work / "staging"
        staging.mkdir()
        script = stage(spec, staging, config, record)
        saved = list(sys.path)
        sys.path.insert(0, str(staging))
        forget_fmu_modules()
        try:
            module, instance = load_script(spec, script)
        finally:
            sys.path[:] = saved
        cls = getattr(module, spec.model)
        starts = dict(instance.values)
        docs = work / "documentation"
        docs.mkdir()
        text = documentation(cls, cls.VARIABLES, starts, record)
        (docs / "index.html").write_text(text, encoding="utf-8")
        raw = pythonfmu_build(script, work / "raw", docs)
        written = _postprocess(
            raw,
            out_dir,
            spec,
            cls,
            starts,
            record,
            source_date_epoch,
            work,
            tuple(sorted(set(fmi))),
        )
    for dest in written.values():
        validate(dest)
    return written


def build_fmus(
    out_dir: str | os.PathLike[str] = DEFAULT_OUT,
    gains_path: str | os.PathLike[str] | None = None,
    source_date_epoch: int | None = None,
    self_contained: bool = False,
    fmi: tuple[int, ...] = FMI_VERSIONS,
) -> dict[str, Path]:
    """Build every FMU (plant, LMI and top-drive controller; scaled and SI) and the SSP packages
    into ``out_dir``; returns {model identifier or package name: path}.

    ``fmi``: the FMI versions, (2, 3) by default: every FMU and its FMI 3.0 twin (``X3.fmu``);
    the SSP packages (FMI 2.0 FMUs) only with 2.

    ``gains_path`` defaults to ``drillstring.controller.gains.DEFAULT_GAINS_PATH``;
    ``source_date_epoch`` defaults to the environment variable ``SOURCE_DATE_EPOCH``;
    ``self_contained``: every FMU carries its Python
    (:mod:`drillstring.apps.export.self_contained`), and so do the SSP packages made of them.
    """
    out = Path(out_dir)
    fmi = tuple(sorted(set(fmi)))
    if not fmi or set(fmi) - set(FMI_VERSIONS):
        raise BuildError(f"FMI versions {fmi!r}: choose from {FMI_VERSIONS}")
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
    base = {"version": package_version(), "format": 1}
    control = {**base, "gains": gains}
    # the top-drive controller's tunings (scaled, reference set) and which is its start values
    tunings = {"default": TOPDRIVE_DEFAULT, "tunings": topdrive_tunings()}
    topdrive = {**control, "topdrive": tunings}
    jobs = (
        (PLANT, base),
        (CONTROLLER, control),
        (PLANT_SI, base),
        (CONTROLLER_SI, control),
        (TOPDRIVE, topdrive),
        (TOPDRIVE_SI, topdrive),
    )
    if self_contained:
        with tempfile.TemporaryDirectory(prefix="build_fmus_normal_") as tmp:
            normal: dict[str, Path] = {}
            for spec, config in jobs:  # the FMI 2.0 FMUs always: they compile the kernel
                normal.update(build_fmu(spec, Path(tmp), config, source_date_epoch, (2, *fmi)))
            fmi2 = {spec.model for spec, _ in jobs}
            wanted = {m: p for m, p in normal.items() if (2 if m in fmi2 else 3) in fmi}
            warmup = [path for m, path in normal.items() if m in fmi2]
            built = self_contained_fmus(wanted, out, source_date_epoch, warmup)
    else:
        built = {}
        for spec, config in jobs:
            built.update(build_fmu(spec, out, config, source_date_epoch, fmi))
    if 2 in fmi:
        built.update(build_packages(out, source_date_epoch))
    return built


def build_packages(out_dir: Path, source_date_epoch: int | None = None) -> dict[str, Path]:
    """The SSP 1.0 packages of the closed loop (:mod:`drillstring.orchestration.loop_ssp`) from
    the FMUs in ``out_dir``, validated against the SSP 1.0 schemas that fmpy ships: the loop
    closed by the LMI controller and by the top-drive controller, in both unit systems."""
    built = {}
    for variant in (SCALED, SI, TOPDRIVE_LOOP, TOPDRIVE_SI_LOOP):
        try:
            path = write_loop_package(out_dir, variant, source_date_epoch=source_date_epoch)
        except SspError as exc:
            raise BuildError(f"SSP package {variant.ssp}: {exc}") from None
        problems = validate_ssp(path)
        if problems:
            raise BuildError(f"{path.name}: " + "; ".join(problems))
        built[path.stem] = path
    return built


def build_fmus_into(out_dir: str | os.PathLike[str], gains: str | os.PathLike[str]) -> Path:
    """Build every FMU and SSP package into ``out_dir`` with the controller gains of ``gains``
    (:func:`build_fmus`, in this process; the builder restores ``sys.path`` and drops the FMUs'
    modules after each FMU).

    Parameters
    ----------
    out_dir : path
        Folder for the FMUs and packages.
    gains : path
        Gains file baked into the controller FMUs.

    Returns
    -------
    Path
        ``out_dir``.

    Raises
    ------
    BuildError
        If the build fails or an FMU does not validate, naming why.
    """
    build_fmus(out_dir, gains)
    fmu_paths(out_dir)
    return Path(out_dir)
