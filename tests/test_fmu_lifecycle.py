"""What the front layer promises about the process the FMUs live in.

* nothing per instance: 1000 ``fmi2Instantiate``/``fmi2FreeInstance`` cycles in one process grow
  its resident memory by less than 5 MB and leave ``sys.path`` (and the reference count of the
  module pythonfmu executes) unchanged;
* every way the interpreter cannot be had is a logged NULL from ``fmi2Instantiate``, never a
  crash: libpython missing, a Python home without a standard library, site-packages without numpy,
  a missing resources folder, a resources location that is a file;
* another machine: an FMU whose recorded Python does not exist there runs once the three
  ``DRILLSTRING_FMU_*`` variables name a Python that does, with the same results.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import sysconfig
import textwrap

import fmu_testlib as tl
import numpy as np
import pytest

H_NS = 10_000_000
N = 20


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    return tl.compile_c_host(tmp_path_factory.mktemp("c_host"))


@pytest.fixture(scope="module")
def cycles(tmp_path_factory):
    out = tmp_path_factory.mktemp("cycles")
    return tl.compile_c_program(tl.C_CYCLES, out, "-std=gnu11", "-ldl", "-lpthread")


#: An output of each FMU, read after each step by tests/c_host/cycles.c.
OUTPUT = {"plant": "u", "controller": "R_minus_R0"}


def run_cycles(
    exe, unit, which, home, n, *, warmup=1, logging=False, stack_kib=8192, state=True
) -> tuple[subprocess.CompletedProcess, dict[int, int]]:
    """tests/c_host/cycles.c on ``unit`` in a clean environment; (process, {cycles: RSS})."""
    args = [unit.unzipped, unit.model, unit.guid, n, warmup, int(logging), stack_kib]
    args += [unit.vr[OUTPUT[which]], int(state)]
    proc = subprocess.run(
        [str(exe), *map(str, args)],
        capture_output=True,
        text=True,
        env=tl.clean_env(home),
        timeout=600,
    )
    rss = {}
    for line in proc.stdout.splitlines():
        if line.startswith("rss "):
            _, k, size = line.split()
            rss[int(k)] = int(size)
    return proc, rss


#: The stack of the host's worker thread in the small-stack test: the front layer needed more
#: than 128 KiB (its fmi2Instantiate alone 107 KB), the interpreter's start and imports need
#: about 50 KiB.
SMALL_STACK_KIB = 128


@pytest.mark.parametrize("which", ["plant", "controller"])
def test_a_worker_thread_with_a_small_stack_runs_the_fmu(built, cycles, clean_home, which):
    """Every FMI call from a thread of SMALL_STACK_KIB KiB (the host's main thread only waits):
    Python started there, instances made, initialized, stepped, read, an FMU state taken, freed.
    A frame too large for the stack is a SIGSEGV (exit status -11), not a pass."""
    unit = getattr(built, which)
    proc, _ = run_cycles(cycles, unit, which, clean_home, 1)  # the package cache, numba's cache
    assert proc.returncode == 0, proc.stderr
    proc, _ = run_cycles(cycles, unit, which, clean_home, 3, stack_kib=SMALL_STACK_KIB)
    assert proc.returncode == 0, (proc.returncode, proc.stderr)


CYCLES = textwrap.dedent(
    """
    import gc, os, sys
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave

    fmu, unzipped, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
    md = read_model_description(fmu)
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="cycle")

    def rss():
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")

    def cycle():
        s.instantiate()
        s.freeInstance()

    for _ in range(20):  # imports, caches, first allocations
        cycle()
    entry = sys.modules[open(unzipped + "/resources/slavemodule.txt").read().strip()]
    gc.collect()
    r0, path0, refs0 = rss(), list(sys.path), sys.getrefcount(entry.__dict__)
    for _ in range(n):
        cycle()
    gc.collect()
    print(rss() - r0, sys.path == path0, sys.getrefcount(entry.__dict__) - refs0)
    """
)


@pytest.mark.parametrize("which", ["plant", "controller"])
def test_thousand_instances_add_nothing(built, which, tmp_path):
    unit = getattr(built, which)
    proc = subprocess.run(
        [sys.executable, "-c", CYCLES, str(unit.fmu), str(unit.unzipped), "1000"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    grown, same_path, refs = proc.stdout.split()
    print(f"{which}: 1000 instantiate/free cycles: RSS +{int(grown) / 1e6:.2f} MB")
    assert int(grown) < 5_000_000
    assert same_path == "True"
    assert int(refs) == 0


def _plant_only(built, folder, csv):
    return tl.host_config(built, {"plant": folder}, H_NS, N, {}, csv, logging=True)


def _run(host, built, tmp_path, env, folder=None):
    folder = folder or tl.unpack(built.plant.fmu, tmp_path / "plant")
    csv = tmp_path / "out.csv"
    return tl.run_c_host(host, _plant_only(built, folder, csv), tmp_path, env, csv)


@pytest.mark.parametrize(
    ("override", "message"),
    [
        (
            {"DRILLSTRING_FMU_LIBPYTHON": "/nonexistent/libpython3.11.so.1.0"},
            r"cannot load libpython '/nonexistent/libpython3\.11\.so\.1\.0'.*set "
            r"DRILLSTRING_FMU_LIBPYTHON",
        ),
        (
            {"DRILLSTRING_FMU_PYTHONHOME": "/nonexistent"},
            r"Python home '/nonexistent' has no standard library .*DRILLSTRING_FMU_PYTHONHOME",
        ),
        (
            {"DRILLSTRING_FMU_SITE_PACKAGES": "/nonexistent/site-packages"},
            r"site-packages folder '/nonexistent/site-packages' does not exist|"
            r"No module named 'numpy'",
        ),
    ],
    ids=["libpython", "home", "site-packages"],
)
def test_no_usable_python_is_a_logged_null(built, host, tmp_path, clean_home, override, message):
    proc, rows = _run(host, built, tmp_path, tl.clean_env(clean_home, **override))
    assert proc.returncode == 1, proc.stderr  # the host's "an FMU call failed", not a signal
    assert "host: fmi2Instantiate failed for plant" in proc.stderr
    assert re.search(message, proc.stderr), proc.stderr
    assert rows is None


def test_missing_or_bad_resources_are_a_logged_null(built, host, tmp_path, clean_home):
    env = tl.clean_env(clean_home)
    folder = tl.unpack(built.plant.fmu, tmp_path / "plant")
    shutil.rmtree(folder / "resources")
    proc, _ = _run(host, built, tmp_path, env, folder)
    assert proc.returncode == 1
    assert re.search(r"resources folder '.*/plant/resources' does not exist", proc.stderr)
    (folder / "resources").write_text("a file, not a folder")
    proc, _ = _run(host, built, tmp_path, env, folder)
    assert proc.returncode == 1
    assert re.search(r"resources location '.*/plant/resources' is not a folder", proc.stderr)


def test_another_machine_needs_only_the_three_variables(built, host, tmp_path, clean_home):
    """The FMU as built on a machine whose Python lives elsewhere: it says what is missing;
    with DRILLSTRING_FMU_LIBPYTHON/PYTHONHOME/SITE_PACKAGES it runs, with the same numbers."""
    folder = tl.unpack(built.plant.fmu, tmp_path / "plant")
    record = folder / "resources" / "drillstring_fmu_python.cfg"
    text = record.read_text()
    elsewhere = re.sub(r"^(libpython|home|site) (.*)$", r"\1 /opt/elsewhere\2", text, flags=re.M)
    record.write_text(elsewhere)
    env = tl.clean_env(clean_home)
    proc, _ = _run(host, built, tmp_path, env, folder)
    assert proc.returncode == 1 and "cannot load libpython '/opt/elsewhere" in proc.stderr
    overrides = {
        "DRILLSTRING_FMU_LIBPYTHON": str(tl.libpython()),
        "DRILLSTRING_FMU_PYTHONHOME": sys.base_prefix,
        "DRILLSTRING_FMU_SITE_PACKAGES": sysconfig.get_paths()["purelib"],
    }
    proc, rows = _run(host, built, tmp_path, tl.clean_env(clean_home, **overrides), folder)
    assert proc.returncode == 0, proc.stderr
    ref = tl.jacobi_fmpy(built, H_NS, N, {}, units=("plant",))
    assert np.array_equal(rows[1:], ref)


THREADS = textwrap.dedent(
    """
    import ctypes, sys, threading
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave

    pairs = [(sys.argv[i], sys.argv[i + 1]) for i in (1, 3)]
    libs = []
    for fmu, unzipped in pairs:
        model = read_model_description(fmu).coSimulation.modelIdentifier
        libs.append(ctypes.CDLL(f"{unzipped}/binaries/linux64/{model}.so"))
    locks = {ctypes.addressof(ctypes.c_char.in_dll(lib, "drillstring_fmi2_process_lock"))
             for lib in libs}
    path0, errors = list(sys.path), []

    def cycles(fmu, unzipped):
        md = read_model_description(fmu)
        try:
            for i in range(40):
                s = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, instanceName=f"t{i}",
                              modelIdentifier=md.coSimulation.modelIdentifier)
                s.instantiate()
                s.setupExperiment(startTime=0.0)
                s.enterInitializationMode()
                s.exitInitializationMode()
                s.doStep(0.0, 0.01)
                s.terminate()
                s.freeInstance()
        except Exception as exc:
            errors.append(repr(exc))

    threads = [threading.Thread(target=cycles, args=p) for p in pairs]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    print(len(locks), sys.path == path0, errors)
    """
)


def test_all_layers_share_one_lock_and_threads_may_instantiate(built):
    """Both FMUs' copies of the layer bind one process-wide lock; plant and controller
    instantiated, stepped and freed concurrently from two threads leave sys.path unchanged."""
    args = [str(built.plant.fmu), str(built.plant.unzipped)]
    args += [str(built.controller.fmu), str(built.controller.unzipped)]
    proc = subprocess.run(
        [sys.executable, "-c", THREADS, *args], capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().split(maxsplit=2) == ["1", "True", "[]"], proc.stdout
