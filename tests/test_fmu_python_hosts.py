"""The FMUs in hosts that are themselves a Python other than the FMUs' own.

A host process that runs Python lends its interpreter to the FMU (``fmu_src/fmi_front/
runtime.c``): a process holds one Python, and the FMU's compiled modules (numpy, numba,
pythonfmu's library) are those of the Python that built it. The rule, tested here with fmpy
(``tests/python_host/fmpy_host.py``) in interpreters provided by ``tools/python_hosts.py``:

* **another minor version** (pyenv's 3.12, else Debian 13's 3.13 in a Debian tree): refused at
  ``fmi2Instantiate`` with a logged error naming the host's version, ABI and executable and the
  FMU's version and ABI, before any of the FMU's Python code runs in it (no package copied into
  the cache). Before this rule such a host ran the FMU silently on its own numpy (3.12.1 and
  3.13.0 with numpy 2.5.5, even compiling the kernel with their own numba);
* **the same minor version, another build** (Debian's python3 3.11.2 when the FMUs are built
  with pyenv's 3.11.7): the same ABI, so the interpreter is accepted, and the FMU runs only with
  the numpy and numba of the versions it was built with (``require`` lines of
  ``drillstring_fmu_python.cfg``). Followed as a user would: a host environment with another
  numpy and no numba is refused naming both versions of each; with the FMU's numpy still for
  want of numba; with ``DRILLSTRING_JIT=0`` (numba waived) it runs; after ``pip install -r
  resources/requirements.txt`` it runs with the native fast path. Both runs equal the normal
  host's (the building Python running the same script) bit for bit.

``DRILLSTRING_TEST_OTHER_PYTHON`` and ``DRILLSTRING_TEST_SAME_MINOR_PYTHON`` choose the
interpreters (a path, or minor versions as ``tools/python_hosts.py`` takes them).
"""

from __future__ import annotations

import json
import os
import platform
import re
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path
from typing import Any

import fmu_testlib as tl
import numba
import numpy
import pytest

pytestmark = pytest.mark.fmu

python_hosts = tl.load_script(tl.ROOT / "tools" / "python_hosts.py", "python_hosts")

HOST_SCRIPT = tl.ROOT / "tests" / "python_host" / "fmpy_host.py"
STEPS, H = 200, 0.01
#: The FMUs' Python: the one that runs the tests built them (tests/fmu_testlib.run_build).
FMU_VERSION = f"{sys.version_info.major}.{sys.version_info.minor}"
FMU_ABI = sysconfig.get_config_var("SOABI")
OTHER_MINOR = os.environ.get("DRILLSTRING_TEST_OTHER_PYTHON", "3.12,3.13")
SAME_MINOR = os.environ.get("DRILLSTRING_TEST_SAME_MINOR_PYTHON", FMU_VERSION)


def _abi_of(version: str) -> str:
    """The SOABI of CPython ``version`` on this platform (the FMU's with another version)."""
    major, minor = version.split(".")[:2]
    return re.sub(r"^cpython-\d+", f"cpython-{major}{minor}", FMU_ABI)


def run_host(host: Any, fmus: list[Path], work: Path, home: Path, **env: str) -> dict[str, Any]:
    """fmpy_host.py in ``host`` (HOME ``home``, a clean environment plus ``env``) with copies of
    ``fmus``, all inside the host's root; its report."""
    work.mkdir(parents=True, exist_ok=True)
    home.mkdir(parents=True, exist_ok=True)
    script = Path(shutil.copy(HOST_SCRIPT, work))
    copies = [Path(shutil.copy(f, work)) for f in fmus]
    out = work / "out.json"
    args = [host.inside(p) for p in (script, out)] + [str(STEPS), repr(H)]
    args += [host.inside(p) for p in copies]
    extra = {**host.env, **env, "TMPDIR": host.inside(work)}
    proc = subprocess.run(
        host.command(*args),
        capture_output=True,
        text=True,
        env=tl.clean_env(Path(host.inside(home)), **extra),
        timeout=600,
    )
    # a refusal is a NULL from fmi2Instantiate, never a crash of the host
    assert proc.returncode == 0, (proc.returncode, proc.stderr)
    report = json.loads(out.read_text())
    assert report["python"] == host.version
    return report


def problems(result: dict[str, Any]) -> list[str]:
    """The FMU's messages of status fmi2Warning or worse."""
    return [m for s, _, m in result["logs"] if s >= tl.WARNING]


def _normal_host() -> Any:
    """The building Python itself (this process's interpreter) as fmpy host."""
    return python_hosts.Host(sys.executable, platform.python_version())


@pytest.fixture(scope="session")
def other_minor(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """A CPython of another minor version with fmpy and tqdm (everything the FMU imports
    besides numba): before the rule, it ran the FMU."""
    host = python_hosts.provide(OTHER_MINOR, tmp_path_factory.mktemp("other_minor"), ["tqdm>=4.66"])
    assert host.version.rsplit(".", 1)[0] != FMU_VERSION, host
    return host


@pytest.mark.slow  # an interpreter's environment installed (and maybe a Debian tree made)
def test_a_python_host_of_another_minor_version_gets_a_logged_null(built, other_minor, tmp_path):
    host = other_minor
    check = subprocess.run(
        host.command("-c", "import numpy, tqdm, fmpy"),
        capture_output=True,
        text=True,
        env={"PATH": "/usr/bin:/bin", **host.env},
    )
    assert check.returncode == 0, check.stderr  # the FMU's imports would succeed there
    work = host.outside("/tmp/another_minor") if host.root != Path("/") else tmp_path / "work"
    home = work / "home"
    report = run_host(host, [built.plant.fmu, built.controller.fmu], work, home)
    expected = (
        rf"^fmi2Instantiate: the host process runs Python {re.escape(host.version)} "
        rf"\(ABI {re.escape(_abi_of(host.version))}; {re.escape(report['executable'])}\), but "
        rf"this FMU was built with Python {re.escape(FMU_VERSION)} \(ABI {re.escape(FMU_ABI)}\)"
        r" and runs only in an interpreter of that version and ABI"
    )
    for result in report["fmus"]:  # two FMUs, two copies of the front layer in one process
        assert not result["instantiated"], result
        (message,) = problems(result)
        assert [s for s, _, _ in result["logs"]] == [tl.ERROR], result["logs"]
        assert re.search(expected, message), message
        for advice in ("requirements.txt (pip install -r that file)", "DRILLSTRING_FMU_LIBPYTHON"):
            assert advice in message, message
    # refused before any of the FMU's Python ran: nothing was copied into the package cache
    assert not tl.package_cache(home).exists()


def test_a_python_host_of_the_same_minor_version_runs_only_on_the_fmus_numpy_and_numba(
    built, clean_home, tmp_path
):
    """Followed as a user would (module docstring); the runs of the fast-path plant equal the
    normal host's bit for bit. HOME is clean_home's: its kernel cache, compiled by the first
    use, is taken by the other build as well (numba's cache is per minor version)."""
    start = [f"numpy!={numpy.__version__}", "tqdm>=4.66"]  # another numpy, no numba
    host = python_hosts.provide(SAME_MINOR, tmp_path / "host", start)
    prefix = subprocess.run(
        host.command("-c", "import sys; print(sys.base_prefix)"),
        capture_output=True,
        text=True,
        env={"PATH": "/usr/bin:/bin", **host.env},
    ).stdout.strip()
    assert host.version.rsplit(".", 1)[0] == FMU_VERSION
    assert (host.root, prefix) != (Path("/"), sys.base_prefix), "the building Python itself"
    chrooted = host.root != Path("/")
    work = host.outside("/tmp/same_minor") if chrooted else tmp_path / "work"
    home = host.outside("/root") if chrooted else clean_home
    plant = [built.plant.fmu]

    ref = run_host(_normal_host(), plant, tmp_path / "normal", clean_home)["fmus"][0]
    assert ref["instantiated"] and len(ref["rows"]) == STEPS, ref["logs"]

    # 1. another numpy, no numba
    (result,) = run_host(host, plant, work / "1", home)["fmus"]
    assert not result["instantiated"]
    (message,) = problems(result)
    other = re.search(r"this Python imports numpy (\S+) \(", message)
    assert other and other.group(1) != numpy.__version__, message
    for part in (
        f"Python {host.version} (",
        f"built with numpy {numpy.__version__}, this Python imports numpy {other.group(1)} (",
        f"built with numba {numba.__version__}, this Python imports no numba (ModuleNotFound",
        f"pip install numpy=={numpy.__version__} numba=={numba.__version__}",
        "set DRILLSTRING_JIT=0",
        "requirements.txt",
    ):
        assert part in message, (part, message)
    # the same rule where the FMU starts its Python itself (a C host) and finds these packages
    plant_dir = tl.unpack(built.plant.fmu, tmp_path / "c_host" / "plant")
    csv = tmp_path / "c_host" / "out.csv"
    config = tl.host_config(built, {"plant": plant_dir}, 10_000_000, 5, {}, csv, logging=True)
    site = {"DRILLSTRING_FMU_SITE_PACKAGES": str(host.outside(host.site))}
    exe = tl.compile_c_host(tmp_path / "c_host")
    proc, rows = tl.run_c_host(
        exe, config, tmp_path / "c_host", tl.clean_env(clean_home, **site), csv
    )
    assert proc.returncode == 1 and rows is None, proc.stderr  # a NULL, not a signal
    for part in (
        f"built with numpy {numpy.__version__}, this Python imports numpy {other.group(1)} (",
        "set DRILLSTRING_FMU_SITE_PACKAGES to site-packages that hold them",
    ):
        assert part in proc.stderr, (part, proc.stderr)

    # 2. the FMU's numpy, still no numba
    python_hosts.install(host, [f"numpy=={numpy.__version__}"])
    (result,) = run_host(host, plant, work / "2", home)["fmus"]
    assert not result["instantiated"]
    (message,) = problems(result)
    assert "built with numpy" not in message and "numpy==" not in message, message
    assert f"built with numba {numba.__version__}, this Python imports no numba" in message

    # 3. numba waived: the plain-Python kernel
    (result,) = run_host(host, plant, work / "3", home, DRILLSTRING_JIT="0")["fmus"]
    assert result["instantiated"] and not problems(result), result["logs"]
    assert any("the native fast path is off" in m for _, _, m in result["logs"])
    assert result["rows"] == ref["rows"]

    # 4. what the FMU asks for: its requirements.txt
    requirements = built.plant.unzipped / "resources" / "requirements.txt"
    python_hosts.install(host, ["-r", str(requirements)])  # pip runs outside the host's root
    (result,) = run_host(host, plant, work / "4", home)["fmus"]
    assert result["instantiated"] and not problems(result), result["logs"]
    assert any(f"{STEPS} served natively" in m for _, _, m in result["logs"]), result["logs"]
    assert any(
        f"using the Python {host.version} that runs in the host" in m for _, _, m in result["logs"]
    )
    assert result["rows"] == ref["rows"]
