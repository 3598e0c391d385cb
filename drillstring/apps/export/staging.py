"""The files bundled into an FMU's ``resources/`` and pythonfmu's build of them.

Staged per FMU: the ``drillstring`` package (the physics; no model code is in the FMU scripts),
the shared lifecycle ``drillstring_fmu_support.py``, the start-up module
``drillstring_fmu_boot.py``, the variable declarations ``drillstring_fmu_units.py``, the script,
the generated class module ``<model>.py`` (:func:`class_module`), a one-line entry module for
pythonfmu (``<model>_entry.py``, :func:`entry_module`), the build configuration
``drillstring_fmu.json`` (package version, controller gains), the record of the Python that
builds the FMU (:mod:`drillstring.apps.export.python_runtime`) and ``requirements.txt``.
"""

from __future__ import annotations

import importlib.util
import json
import shutil
import sys
from importlib import metadata
from pathlib import Path
from typing import Any

from pythonfmu import FmuBuilder

from drillstring.apps.export.python_runtime import RUNTIME_NAME, requirements_file, runtime_file
from drillstring.apps.export.specs import (
    BOOT,
    FMU_MODULES,
    PACKAGE,
    SUPPORT,
    UNITS_MODULE,
    BuildError,
    FmuSpec,
)

__all__ = [
    "CONFIG_NAME",
    "class_module",
    "entry_module",
    "forget_fmu_modules",
    "load_script",
    "package_version",
    "pythonfmu_build",
    "stage",
]

CONFIG_NAME = "drillstring_fmu.json"
#: Files of the drillstring package that are not bundled.
_IGNORE_FILES = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc", ".*")
#: Sub-packages of an installed drillstring that the FMUs do not use (in a source checkout they
#: are folders of their own: controller/, orchestration/, fmu_src/).
_NOT_BUNDLED = {"controller", "orchestration", "fmu_src"}


def _ignore(folder: str, names: list[str]) -> set[str]:
    ignored = set(_IGNORE_FILES(folder, names))
    if Path(folder) == PACKAGE:
        ignored |= _NOT_BUNDLED & set(names)
    return ignored


def package_version() -> str:
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
        'slave class as the attribute "" (see drillstring.apps.export.staging,\n'
        '`entry_module`)."""\n\n'
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


def stage(spec: FmuSpec, staging: Path, config: dict[str, Any], record: dict[str, Any]) -> Path:
    """Write the files bundled into ``resources/``; returns the staged script pythonfmu builds
    (the generated class module)."""
    shutil.copytree(PACKAGE, staging / "drillstring", ignore=_ignore)
    for path in (SUPPORT, BOOT, UNITS_MODULE, spec.script):
        shutil.copyfile(path, staging / path.name)
    name, text = entry_module(spec)
    (staging / f"{name}.py").write_text(text, encoding="utf-8")
    script = staging / f"{spec.model}.py"
    script.write_text(class_module(spec), encoding="utf-8")
    cfg = json.dumps(config, indent=2, sort_keys=True) + "\n"
    (staging / CONFIG_NAME).write_text(cfg, encoding="utf-8")
    (staging / RUNTIME_NAME).write_text(runtime_file(record), encoding="utf-8")
    (staging / "requirements.txt").write_text(requirements_file(record), encoding="utf-8")
    return script


def load_script(spec: FmuSpec, script: Path) -> tuple[Any, Any]:
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


def pythonfmu_build(script: Path, dest: Path, documentation: Path) -> Path:
    """pythonfmu's build of the staged ``script`` with the staging folder's other files as its
    resources and ``documentation`` as its documentation folder; returns the raw FMU."""
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
        forget_fmu_modules()


def forget_fmu_modules() -> None:
    """Drop the FMUs' modules from ``sys.modules`` (each build imports its staged copies)."""
    for name in FMU_MODULES:
        sys.modules.pop(name, None)
