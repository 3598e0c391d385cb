"""What the front layer promises about the process the FMUs live in.

* nothing per instance: 4000 cycles of instantiation, initialization, a step and
  ``fmi2FreeInstance`` in a plain C host grow its resident memory by less than 1 MiB after the
  first 100, with logging off and on; ``fmi2FreeInstance`` frees the instance's FMU states and,
  in a Python host, the slave at once (no cyclic garbage), and leaves ``sys.path`` (and the
  reference count of the module pythonfmu executes) unchanged;
* a host's worker thread with a small stack (128 KiB) runs the FMUs;
* every way the interpreter cannot be had is a logged NULL from ``fmi2Instantiate``, never a
  crash: libpython missing, a Python home without a standard library, site-packages without numpy,
  a missing resources folder, a resources location that is a file;
* another machine: an FMU whose recorded Python does not exist there runs once the three
  ``DRILLSTRING_FMU_*`` variables name a Python that does, with the same results.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import sysconfig
import textwrap

import fmu_testlib as tl
import numpy as np
import pytest

pytestmark = pytest.mark.fmu

H_NS = 10_000_000
N = 20


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    return tl.compile_c_host(tmp_path_factory.mktemp("c_host"))


@pytest.fixture(scope="module")
def cycles(tmp_path_factory):
    out = tmp_path_factory.mktemp("cycles")
    return tl.compile_c_program(tl.C_CYCLES, out, "-std=gnu11", "-ldl", "-lpthread")


@pytest.fixture(scope="module")
def sigint_host(tmp_path_factory):
    out = tmp_path_factory.mktemp("sigint")
    return tl.compile_c_program(
        tl.ROOT / "tests" / "c_host" / "sigint.c", out, "-std=gnu11", "-ldl"
    )


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


#: Cycles of the growth test, and those after which its first measurement is taken (imports,
#: caches, the allocator's first pages).
GROWTH_CYCLES, WARMUP = 4000, 100
MIB = 1 << 20


@pytest.mark.parametrize("logging", [False, True], ids=["logging-off", "logging-on"])
@pytest.mark.parametrize("which", ["plant", "controller"])
def test_instances_add_nothing(built, cycles, clean_home, which, logging):
    """4000 cycles of fmi2Instantiate, initialization, a step, an output read, an FMU state taken
    and left to fmi2FreeInstance, fmi2FreeInstance, in a plain C host (no Python of its own):
    the resident memory after the last cycle is less than 1 MiB above that after cycle 100.

    Before: +13.3 MB for the plant without the state (pythonfmu 0.7.0's leaks per instance and
    per log message, the slaves left to the cyclic garbage collector), +802 MB with it
    (fmi2FreeInstance did not free the instance's FMU states)."""
    unit = getattr(built, which)
    proc, rss = run_cycles(
        cycles, unit, which, clean_home, GROWTH_CYCLES, warmup=WARMUP, logging=logging
    )
    assert proc.returncode == 0, proc.stderr
    grown = rss[GROWTH_CYCLES] - rss[WARMUP]
    print(f"{which}, logging {logging}: cycles {WARMUP}..{GROWTH_CYCLES}: RSS {grown:+d} bytes")
    assert grown < MIB
    messages = int(proc.stdout.split("messages ")[1])
    assert messages == (2 * GROWTH_CYCLES if logging else 0)  # which Python, the package cache


PYTHON_HOST = textwrap.dedent(
    """
    import ctypes, gc, sys
    from pathlib import Path
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave
    sys.path.insert(0, sys.argv[3])
    import fmu_testlib as tl

    fmu, unzipped, _, model, output = sys.argv[1:6]
    md = read_model_description(fmu)
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=model,
                  instanceName="cycle")
    logs = []
    callbacks = tl.make_callbacks(logs)
    uri = Path(unzipped, "resources").as_uri().encode()
    vr = {v.name: v.valueReference for v in md.modelVariables}[output]

    def cycle():
        s.component = s.fmi2Instantiate(b"cycle", 1, md.guid.encode(), uri,
                                        ctypes.byref(callbacks), 0, 1)
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        s.doStep(0.0, 0.01)
        s.getReal([vr])
        s.getFMUstate()  # left to fmi2FreeInstance
        s.terminate()
        s.fmi2FreeInstance(s.component)

    for _ in range(5):  # imports, caches
        cycle()
    entry = sys.modules[open(unzipped + "/resources/slavemodule.txt").read().strip()]
    gc.collect()
    gc.disable()  # what the instances leave behind is freed without the cyclic collector
    path0, refs0 = list(sys.path), sys.getrefcount(entry.__dict__)
    for _ in range(50):
        cycle()
    alive = [o for o in gc.get_objects() if type(o).__name__ == model]
    print(sys.path == path0, sys.getrefcount(entry.__dict__) - refs0, len(alive),
          len(logs) > 0, [m for st, _, m in logs if st > 1])
    """
)


def _python_host_env(clean_home):
    """This environment, with the package cache of the session's clean HOME (compiled once)."""
    return {**os.environ, "DRILLSTRING_FMU_CACHE": str(tl.package_cache(clean_home))}


@pytest.mark.parametrize("which", ["plant", "controller"])
def test_python_host_keeps_nothing_of_its_instances(built, which, clean_home):
    """A Python host (fmpy in one process): after 50 cycles with logging on (terminated, an FMU
    state left to fmi2FreeInstance) sys.path and the reference count of the module pythonfmu
    executes are unchanged, and no slave is alive with the cyclic garbage collector off: each was
    freed by fmi2FreeInstance at once."""
    unit = getattr(built, which)
    args = [str(unit.fmu), str(unit.unzipped), str(tl.ROOT / "tests"), unit.model, OUTPUT[which]]
    proc = subprocess.run(
        [sys.executable, "-c", PYTHON_HOST, *args],
        capture_output=True,
        text=True,
        env=_python_host_env(clean_home),
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().split(maxsplit=4) == ["True", "0", "0", "True", "[]"], proc.stdout


def test_freed_instance_frees_its_fmu_states(built):
    """fmi2FreeInstance frees the FMU states the instance still owns: a state of a freed
    instance is refused by another instance of the same FMU, as one freed by fmi2FreeFMUstate
    is; a state the other instance took itself stays usable."""
    a = tl.Slave(built.plant, "owner").init()
    b = tl.Slave(built.plant, "other").init()
    try:
        assert a.step(0.0, 0.01) == tl.OK
        taken_by_a = a.fmu.getFMUstate()
        taken_by_b = b.fmu.getFMUstate()
        b.fmu.setFMUstate(taken_by_a)  # another instance of the same FMU may set it
        a.free()
        assert b.call("SetFMUstate", taken_by_a) == tl.ERROR
        assert (
            "is not an FMU state of DrillStringPlant (one of another FMU, or freed already)"
            in (b.messages(tl.ERROR)[-1])
        )
        b.fmu.setFMUstate(taken_by_b)
        assert b.step(0.0, 0.01) == tl.OK
        b.fmu.freeFMUstate(taken_by_b)
    finally:
        b.free()


def _plant_only(built, folder, csv):
    return tl.host_config(built, {"plant": folder}, H_NS, N, {}, csv, logging=True)


def _run(host, built, tmp_path, env, folder=None, unit="plant"):
    """The C host on ``unit`` alone (:func:`_plant_only`, :func:`_controller_only`), unpacked
    into ``tmp_path`` unless ``folder`` is given."""
    folder = folder or tl.unpack(getattr(built, unit).fmu, tmp_path / unit)
    csv = tmp_path / "out.csv"
    config = {"plant": _plant_only, "controller": _controller_only}[unit]
    return tl.run_c_host(host, config(built, folder, csv), tmp_path, env, csv)


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


@pytest.mark.parametrize("which", ["plant", "controller"])
@pytest.mark.parametrize("mode", ["default", "handler"])
def test_the_hosts_sigint_disposition_is_left_alone(
    built, sigint_host, clean_home, tmp_path, which, mode
):
    """Ctrl-C stops a C host running the FMUs: after the FMU started Python,
    made an instance and stepped it (tests/c_host/sigint.c), SIGINT has the disposition the host
    gave it: the default one ends the process by the signal (CPython's own handler, which its
    _signal module installs when first imported, only set a flag: the host ran on), the host's
    own handler runs."""
    unit = getattr(built, which)
    folder = tl.unpack(unit.fmu, tmp_path / which)  # no character that needs percent-encoding
    args = [folder, unit.model, unit.guid, unit.vr[OUTPUT[which]], mode]
    proc = subprocess.run(
        [str(sigint_host), *map(str, args)],
        capture_output=True,
        text=True,
        env=tl.clean_env(clean_home),
        timeout=600,
    )
    lines = proc.stdout.splitlines()
    if mode == "default":
        assert lines == ["before default", "after default"], (lines, proc.stderr)
        assert proc.returncode == -signal.SIGINT, proc.stderr
    else:
        assert lines == ["before host", "after host", "host handler ran"], (lines, proc.stderr)
        assert proc.returncode == 0, proc.stderr


#: A Python host (fmpy, in a subprocess: a lost slave must not take the test process with it)
#: that moves the unpacked FMU away between steps and calls fmi2Reset, then puts it back.
RESET_AFTER_MOVE = textwrap.dedent(
    """
    import json, sys
    from pathlib import Path
    import fmu_testlib as tl

    unit = tl._unit(tl.PLANT, Path(sys.argv[1]), Path(sys.argv[2]))
    out = {}
    def steps(s, k0, n):
        return [[s.step(k * 0.01, 0.01), *s.get("u", "dphi")] for k in range(k0, k0 + n)]
    s = tl.Slave(unit, "moved").init()
    out["before"] = steps(s, 0, 2)
    moved = unit.unzipped.with_name("moved away")
    unit.unzipped.rename(moved)
    n = len(s.logs)
    out["reset_moved"] = s.call("Reset")
    out["messages"] = s.messages()[n:]
    out["went_on"] = steps(s, 2, 1)
    moved.rename(unit.unzipped)
    out["reset_back"] = s.call("Reset")
    s.init()
    out["after"] = steps(s, 0, 2)
    ref = tl.Slave(unit, "reference").init()
    out["reference"] = steps(ref, 0, 3)
    ref.free()
    s.free()
    print(json.dumps(out))
    """
)


def test_reset_after_the_folder_moved_is_an_error_naming_it(built, tmp_path):
    """fmi2Reset after the unpacked FMU was moved away: fmi2Error naming the missing resources
    folder, never fmi2Fatal (pythonfmu's reset makes a new slave from that folder and lost the
    old one); the instance goes on as it was, and once the folder is back fmi2Reset works."""
    proc = tl.run_clean(
        [sys.executable, "-c", RESET_AFTER_MOVE, str(built.plant.fmu), str(tmp_path)],
        {**os.environ, "PYTHONPATH": str(tl.ROOT / "tests")},
        tl.ROOT / "tests",
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    r = json.loads(proc.stdout.strip().splitlines()[-1])
    assert r["reset_moved"] == tl.ERROR, r["messages"]
    missing = re.escape(str(tmp_path))
    assert any(
        re.search(rf"fmi2Reset: resources folder '{missing}/.*/resources' does not exist", m)
        and "nothing was reset" in m
        for m in r["messages"]
    ), r["messages"]
    assert r["went_on"] == r["reference"][2:], "the instance did not go on as it was"
    assert r["reset_back"] == tl.OK
    assert r["after"] == r["before"] == r["reference"][:2]


#: ``cmd`` with the folders before ``--`` made read-only (a read-only bind mount of each over
#: itself, in a mount namespace of its own: root ignores permission bits, a mount does not).
_READ_ONLY = """set -e
while [ "$1" != "--" ]; do
  mount --bind "$1" "$1"; mount -o remount,bind,ro "$1" "$1"; shift
done
shift
exec "$@"
"""


def read_only(cmd: list[str], folders: list[os.PathLike]) -> list[str]:
    unshare = shutil.which("unshare")
    assert unshare, "unshare (util-linux) is needed for read-only folders"
    flags = "-m" if os.geteuid() == 0 else "-rm"
    return [unshare, flags, "--", "sh", "-c", _READ_ONLY, "ro", *map(str, folders), "--", *cmd]


def _controller_only(built, folder, csv):
    """The controller alone, its feedback held off the reference and switched on mid-run: the
    torque it records changes at the switch-on."""
    held = dict(zip(built.feedback, (0.3, -0.2, 0.1, 0.4), strict=True))
    starts = {"controller": {"t_on": N * H_NS * 1e-9 / 2, **held}}
    return tl.host_config(built, {"controller": folder}, H_NS, N, starts, csv, logging=True)


def test_read_only_home_and_unpack_folder(built, host, tmp_path, clean_home):
    """With HOME and the unpack folder read-only, numba has no writable place for its cache
    (neither the package's __pycache__ nor ~/.cache/numba: its "no locator available", which
    stopped every FMU at fmi2Instantiate): the FMU runs, numba compiling in memory, and logs so;
    the numbers are those of the normal run, and nothing was written into either folder. The
    controller shows it: every compiled function of the package, the plant's kernel among them,
    is decorated on import through the same fallback (``drillstring.model.kernel.jit.cached``,
    the FMUs' C entry points too), and the controller compiles in memory in a few seconds where
    the plant's kernel takes half a minute."""
    home = tmp_path / "home"
    home.mkdir()
    folder = tl.unpack(built.controller.fmu, tmp_path / "controller")
    listing = sorted(p.relative_to(folder) for p in folder.rglob("*"))
    csv = tmp_path / "out.csv"
    config = tmp_path / "host.cfg"
    config.write_text(_controller_only(built, folder, csv), encoding="utf-8")
    proc = subprocess.run(
        read_only([str(host), str(config)], [home, folder]),
        capture_output=True,
        text=True,
        env=tl.clean_env(home),
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert "no locator" not in proc.stderr
    assert re.search(r"numba compiled \d+ kernel function\(s\) .* in memory only", proc.stderr)
    assert list(home.iterdir()) == []
    assert sorted(p.relative_to(folder) for p in folder.rglob("*")) == listing
    rows = np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2)
    assert len(np.unique(rows[:, -1])) > 1, "the torque did not change at the switch-on"
    reference = tmp_path / "reference"
    reference.mkdir()
    ref_proc, ref_rows = _run(host, built, reference, tl.clean_env(clean_home), unit="controller")
    assert ref_proc.returncode == 0, ref_proc.stderr
    assert np.array_equal(rows, ref_rows)


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


def test_all_layers_share_one_lock_and_threads_may_instantiate(built, clean_home):
    """Both FMUs' copies of the layer bind one process-wide lock; plant and controller
    instantiated, stepped and freed concurrently from two threads leave sys.path unchanged."""
    args = [str(built.plant.fmu), str(built.plant.unzipped)]
    args += [str(built.controller.fmu), str(built.controller.unzipped)]
    proc = subprocess.run(
        [sys.executable, "-c", THREADS, *args],
        capture_output=True,
        text=True,
        env=_python_host_env(clean_home),
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().split(maxsplit=2) == ["1", "True", "[]"], proc.stdout
