"""The Python an FMU starts: the record of the building interpreter written into
``resources/drillstring_fmu_python.cfg``, read by the front layer before Python exists
(``fmu_src/fmi_front/runtime.c``), and the environment variables that override it on another
machine.

The record also states what an interpreter must be for the FMU to run in it, started by the
layer or lent by a Python host: the version and ABI (``abi``, the SOABI its extension modules
are built for), checked by the front layer, and the versions of the modules that compute its
numbers (``require`` lines), checked by ``fmu_src/drillstring_fmu_boot.py``; the same versions
are pinned in ``resources/requirements.txt`` (:func:`requirements_file`), what a Python host
installs.
"""

from __future__ import annotations

import importlib
import sys
import sysconfig
from pathlib import Path
from typing import Any

from drillstring.apps.export.specs import BuildError

__all__ = [
    "OTHER_REQUIREMENTS",
    "OVERRIDES",
    "RUNTIME_MODULES",
    "RUNTIME_NAME",
    "python_record",
    "requirements_file",
    "runtime_file",
]

RUNTIME_NAME = "drillstring_fmu_python.cfg"
#: The environment variables that override the recorded Python on another machine.
OVERRIDES = {
    "libpython": "DRILLSTRING_FMU_LIBPYTHON",
    "home": "DRILLSTRING_FMU_PYTHONHOME",
    "site": "DRILLSTRING_FMU_SITE_PACKAGES",
}
#: The modules that compute the FMUs' numbers: their versions in the building Python are recorded
#: ("none": not importable), and an FMU runs only in an interpreter that imports the same
#: (drillstring_fmu_boot.module_mismatch; numba is optional: without it the kernel is plain
#: Python, and ``DRILLSTRING_JIT=0`` waives its check).
RUNTIME_MODULES = ("numpy", "numba")
#: The other runtime dependency of the FMUs' Python code besides the standard library (pythonfmu's
#: own Python files are bundled by pythonfmu); its version does not change the numbers.
OTHER_REQUIREMENTS = ("tqdm>=4.66",)


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
        "abi": sysconfig.get_config_var("SOABI"),
        "libpython": str(libpython),
        "home": sys.base_prefix,
        "site": sites,
        "include": paths["include"],
        "modules": {name: _module_version(name) for name in RUNTIME_MODULES},
    }


def _module_version(name: str) -> str | None:
    """``__version__`` of the module as this interpreter imports it, None: not importable."""
    try:
        module = importlib.import_module(name)
    except ImportError:
        return None
    return str(getattr(module, "__version__", "unknown"))


def runtime_file(record: dict[str, Any]) -> str:
    """``resources/drillstring_fmu_python.cfg``: read by the front layer before Python exists."""
    lines = [
        "# The Python that built this FMU (written by build_fmus.py; read by its front layer).",
        f"# On another machine: {OVERRIDES['libpython']}, {OVERRIDES['home']} and "
        f"{OVERRIDES['site']} (':'-separated) override these lines.",
        f"version {record['version']}",
        f"abi {record['abi']}",
        f"libpython {record['libpython']}",
        f"home {record['home']}",
    ]
    lines += [f"site {s}" for s in record["site"]]
    lines += [f"require {n} {v or 'none'}" for n, v in record["modules"].items()]
    return "\n".join(lines) + "\n"


def requirements_file(record: dict[str, Any]) -> str:
    """``resources/requirements.txt``: what a Python host of the FMU installs (``pip install -r``),
    the modules of the recorded versions pinned."""
    pins = [f"{n}=={v}" for n, v in record["modules"].items() if v is not None]
    return "\n".join([*pins, *OTHER_REQUIREMENTS]) + "\n"
