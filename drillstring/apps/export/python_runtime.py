"""The Python an FMU starts: the record of the building interpreter written into
``resources/drillstring_fmu_python.cfg``, read by the front layer before Python exists
(``fmu_src/fmi_front/runtime.c``), and the environment variables that override it on another
machine.
"""

from __future__ import annotations

import sys
import sysconfig
from pathlib import Path
from typing import Any

from drillstring.apps.export.specs import BuildError

__all__ = ["OVERRIDES", "RUNTIME_NAME", "python_record", "runtime_file"]

RUNTIME_NAME = "drillstring_fmu_python.cfg"
#: The environment variables that override the recorded Python on another machine.
OVERRIDES = {
    "libpython": "DRILLSTRING_FMU_LIBPYTHON",
    "home": "DRILLSTRING_FMU_PYTHONHOME",
    "site": "DRILLSTRING_FMU_SITE_PACKAGES",
}


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
