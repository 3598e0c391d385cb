"""Shared helpers of the FMU tests (``tests/test_fmu_*.py``; this module is not collected).

* :func:`built_fmus` builds both FMUs once per test session with the real command
  (``python build_fmus.py --gains ... --out ...`` in a subprocess, so the test process is not
  touched by pythonfmu's builder) from a gains file made here;
* :class:`Slave` drives one FMU instance with fmpy and records its log messages;
* :func:`jacobi_fmpy`, :func:`run_libcosim` and :func:`run_c_host` run the same fixed-step Jacobi
  co-simulation of plant and controller in three independent masters. All three follow libcosim's
  ``fixed_step_algorithm``: time in integer nanoseconds, ``t_k = k*H_ns/1e9`` and
  ``h_k = t_{k+1} - t_k`` in double; per macro step every FMU gets its pending inputs, steps and
  is read; then outputs are transferred to the pending inputs of the next step. Initialization:
  read outputs after ``fmi2EnterInitializationMode``, then N (number of FMUs) rounds of set inputs
  / read outputs / transfer, then set inputs, ``fmi2ExitInitializationMode``, read, transfer.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import sysconfig
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pythonfmu  # noqa: F401
from fmpy import extract, read_model_description
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

import drillstring.model.control  # noqa: F401  (import the repository's package before any FMU
import drillstring.model.engine  # noqa: F401  puts its bundled copy on sys.path, see restore_sys_path)

ROOT = Path(__file__).resolve().parents[1]
C_HOST = ROOT / "tests" / "c_host" / "host.c"
PLANT = "DrillStringPlant"
CONTROLLER = "TorsionalController"
#: Plant outputs fed back to the controller inputs of the same name, and the torque back.
FEEDBACK = ("phi", "dphi", "theta", "dtheta")
RECORD_PLANT = ("u", "du", "phi", "dphi", "theta", "dtheta", "d", "g", "tau_n")

_CACHE: dict[str, Any] = {}


@dataclass
class Unit:
    """A built FMU: archive, unpacked folder, model description and value references."""

    model: str
    fmu: Path
    unzipped: Path
    guid: str
    vr: dict[str, int]
    types: dict[str, str]


@dataclass
class Built:
    """Both FMUs of one session build, the gains file and the build folder."""

    plant: Unit
    controller: Unit
    gains: Path
    out: Path
    gains_values: dict[str, Any] = field(default_factory=dict)


@contextlib.contextmanager
def kept_sys_path() -> Iterator[None]:
    """Undo the ``sys.path`` entries pythonfmu adds (one per instantiation: the FMU's resources).

    Without this, processes spawned later by other tests (dask workers) would import the FMUs'
    bundled ``drillstring`` instead of the repository's. The modules the FMUs import
    (``drillstring``, ``pythonfmu``) are imported from the repository and the environment when
    this module loads, so the bundled copies never replace them in the test process itself.
    """
    saved = list(sys.path)
    try:
        yield
    finally:
        sys.path[:] = saved


def restore_sys_path() -> Iterator[None]:
    """:func:`kept_sys_path` as the body of an autouse fixture (a second line of defence)."""
    with kept_sys_path():
        yield


def make_gains_file(path: Path) -> dict[str, Any]:
    """A valid gains file: the paper's F with K0 and R_ff of (27), (31) at an assumed A.

    The FMU tests need a consistent gains file, not a designed one (the synthesis has its own
    tests); A = 0.45 and taubar_crit = 5 are merely admissible values.
    """
    from drillstring.controller.averaged import averaged_model
    from drillstring.controller.gains import PAPER_F, GainsFile, write_gains
    from drillstring.model.params import REFERENCE

    model = averaged_model(REFERENCE, 0.45, 5.0)
    gains = GainsFile(
        F=PAPER_F,
        K0=model.K0,
        R_ff=model.R_ff,
        alpha=1.0,
        A=model.A,
        taubar_crit=model.taubar_crit,
        params=REFERENCE,
        certificate={},
        spectral_abscissa=0.0,
        solver="none (test fixture)",
        solver_status="none",
    )
    write_gains(gains, path)
    return {"F": list(PAPER_F), "K0": model.K0, "R_ff": model.R_ff}


def run_build(
    out: Path, gains: Path, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess:
    """``python build_fmus.py --gains GAINS --out OUT``; raises with its output on failure."""
    proc = subprocess.run(
        [sys.executable, str(ROOT / "build_fmus.py"), "--gains", str(gains), "--out", str(out)],
        capture_output=True,
        text=True,
        env={**os.environ, **(env or {})},
        cwd=ROOT,
        timeout=600,
    )
    if proc.returncode != 0:
        raise AssertionError(f"build_fmus.py failed ({proc.returncode}):\n{proc.stderr}")
    return proc


def _unit(model: str, fmu: Path, root: Path) -> Unit:
    unzipped = root / f"{model}_unzipped"
    extract(str(fmu), str(unzipped))
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    types = {v.name: v.type for v in md.modelVariables}
    return Unit(model, fmu, unzipped, md.guid, vr, types)


def built_fmus(tmp_path_factory: Any) -> Built:
    """Build both FMUs once per session (cached across the FMU test modules)."""
    if "built" not in _CACHE:
        root = Path(tmp_path_factory.mktemp("fmus"))
        gains = root / "gains.json"
        values = make_gains_file(gains)
        out = root / "build"
        run_build(out, gains)
        _CACHE["built"] = Built(
            plant=_unit(PLANT, out / f"{PLANT}.fmu", root),
            controller=_unit(CONTROLLER, out / f"{CONTROLLER}.fmu", root),
            gains=gains,
            out=out,
            gains_values=values,
        )
    return _CACHE["built"]


# ------------------------------------------------------------------------------------------------
# fmpy
# ------------------------------------------------------------------------------------------------


class Slave:
    """One FMU instance driven by fmpy; ``logs`` collects (status, message) of its log calls."""

    def __init__(self, unit: Unit, name: str) -> None:
        self.unit = unit
        self.logs: list[tuple[int, str]] = []

        def logger(env: Any, instance: Any, status: int, category: Any, message: bytes) -> None:
            self.logs.append((int(status), message.decode("utf-8")))

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(_calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(_free)
        self._callbacks = callbacks
        self.fmu = FMU2Slave(
            guid=unit.guid,
            unzipDirectory=str(unit.unzipped),
            modelIdentifier=unit.model,
            instanceName=name,
        )
        with kept_sys_path():
            self.fmu.instantiate(callbacks=callbacks, loggingOn=True)

    # typed access by variable name
    def set(self, **values: Any) -> None:
        for name, value in values.items():
            self._setter(name)([self.unit.vr[name]], [value])

    def get(self, *names: str) -> list[Any]:
        return [self._getter(name)([self.unit.vr[name]])[0] for name in names]

    def _setter(self, name: str) -> Any:
        kind = self.unit.types[name]
        return getattr(self.fmu, f"set{kind}")

    def _getter(self, name: str) -> Any:
        kind = self.unit.types[name]
        return getattr(self.fmu, f"get{kind}")

    def init(self, **values: Any) -> Slave:
        self.set(**values)
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        return self

    def free(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


_libc = None


def _calloc(n: int, size: int) -> int:
    return _c().calloc(n, size)


def _free(ptr: int) -> None:
    _c().free(ptr)


def _c() -> Any:
    global _libc
    if _libc is None:
        import ctypes

        _libc = ctypes.CDLL(None)
        _libc.calloc.restype = ctypes.c_void_p
        _libc.calloc.argtypes = [ctypes.c_size_t, ctypes.c_size_t]
        _libc.free.argtypes = [ctypes.c_void_p]
    return _libc


def grid(k: int, step_ns: int) -> tuple[float, float]:
    """libcosim's communication point t_k and step h_k (integer nanoseconds to double)."""
    t = (k * step_ns) / 1e9
    return t, ((k + 1) * step_ns) / 1e9 - t


# ------------------------------------------------------------------------------------------------
# three masters of the same closed loop
# ------------------------------------------------------------------------------------------------


def _links(built: Built) -> list[tuple[str, int, str, int]]:
    p, c = built.plant, built.controller
    links = [("plant", p.vr[n], "controller", c.vr[n]) for n in FEEDBACK]
    links.append(("controller", c.vr["R_minus_R0"], "plant", p.vr["R_minus_R0"]))
    return links


def _columns(built: Built) -> list[tuple[str, int]]:
    cols = [("plant", built.plant.vr[n]) for n in RECORD_PLANT]
    return cols + [("controller", built.controller.vr["R_minus_R0"])]


def jacobi_fmpy(
    built: Built, step_ns: int, n_steps: int, starts: dict[str, dict[str, float]]
) -> np.ndarray:
    """The closed loop with fmpy, libcosim's exchange (module docstring); rows after each step."""
    units = {"plant": built.plant, "controller": built.controller}
    slaves = {name: Slave(unit, f"{name}_jacobi") for name, unit in units.items()}
    try:
        for name, values in starts.items():
            slaves[name].set(**values)
        links = _links(built)
        cache: dict[tuple[str, int], float] = {}
        pending: dict[tuple[str, int], float] = {}

        def set_inputs(name: str) -> None:
            for (dst, vr), value in pending.items():
                if dst == name:
                    slaves[name].fmu.setReal([vr], [value])

        def get_outputs(name: str) -> None:
            for src, svr, _, _ in links:
                if src == name:
                    cache[(src, svr)] = slaves[name].fmu.getReal([svr])[0]

        def transfer() -> None:
            for src, svr, dst, dvr in links:
                pending[(dst, dvr)] = cache[(src, svr)]

        for name, s in slaves.items():
            s.fmu.setupExperiment(startTime=0.0)
            s.fmu.enterInitializationMode()
            get_outputs(name)
        for _ in range(len(slaves)):
            for name in slaves:
                set_inputs(name)
                get_outputs(name)
            transfer()
        for name, s in slaves.items():
            set_inputs(name)
            s.fmu.exitInitializationMode()
            get_outputs(name)
        transfer()

        cols = _columns(built)
        rows = []
        for k in range(n_steps):
            t, h = grid(k, step_ns)
            for name, s in slaves.items():
                set_inputs(name)
                s.fmu.doStep(t, h)
                get_outputs(name)
            transfer()
            rows.append([t + h] + [slaves[u].fmu.getReal([vr])[0] for u, vr in cols])
        return np.array(rows)
    finally:
        for s in slaves.values():
            s.free()


def run_libcosim(
    built: Built, step_ns: int, n_steps: int, starts: dict[str, dict[str, float]]
) -> np.ndarray:
    """The closed loop in libcosim (libcosimpy), fixed step; rows after each step."""
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level

    log_output_level(CosimLogLevel.ERROR)
    with kept_sys_path():
        return _run_libcosim(built, step_ns, n_steps, starts)


def _run_libcosim(
    built: Built, step_ns: int, n_steps: int, starts: dict[str, dict[str, float]]
) -> np.ndarray:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    ex = CosimExecution.from_step_size(step_size=step_ns)
    units = {"plant": built.plant, "controller": built.controller}
    index = {
        name: ex.add_local_slave(CosimLocalSlave(fmu_path=str(u.fmu), instance_name=name))
        for name, u in units.items()
    }
    for src, svr, dst, dvr in _links(built):
        assert ex.connect_real_variables(index[src], svr, index[dst], dvr) == 0  # raw status
    for name, values in starts.items():
        for var, value in values.items():
            assert ex.real_initial_value(index[name], units[name].vr[var], float(value))
    observer = CosimObserver.create_last_value()
    assert ex.add_observer(observer)
    cols = _columns(built)
    rows = []
    for k in range(n_steps):
        assert ex.step(1), f"libcosim step {k} failed"
        t, h = grid(k, step_ns)
        values = [observer.last_real_values(index[u], [vr])[0] for u, vr in cols]
        rows.append([t + h, *values])
    return np.array(rows)


def libpython() -> Path:
    """The shared libpython of this interpreter (what a C host must load, pythonfmu #202)."""
    name = sysconfig.get_config_var("INSTSONAME") or sysconfig.get_config_var("LDLIBRARY")
    return Path(sysconfig.get_config_var("LIBDIR")) / name


def compile_c_host(out_dir: Path) -> Path:
    """Compile tests/c_host/host.c with the system's cc; returns the executable."""
    cc = shutil.which("cc")
    if cc is None:
        raise AssertionError("no C compiler (cc) on PATH")
    exe = out_dir / "host"
    proc = subprocess.run(
        [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-o", str(exe), str(C_HOST), "-ldl"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    if proc.returncode != 0:
        raise AssertionError(f"cc failed:\n{proc.stderr}")
    return exe


def c_host_env(preload: bool) -> dict[str, str]:
    """Environment of the C host: numpy where the embedded Python finds it, no numba JIT.

    ``PYTHONPATH`` points at this environment's site-packages (numpy; ``.pth`` files there, such
    as the editable install of drillstring, are not processed, so the FMUs use their bundled
    copy). ``DRILLSTRING_JIT=0``: a fresh FMU folder would recompile the numba kernel (about half a
    minute); the plain-Python kernel gives the same numbers bit for bit.
    """
    env = dict(os.environ)
    env["PYTHONPATH"] = sysconfig.get_paths()["purelib"]
    env["DRILLSTRING_JIT"] = "0"
    env.pop("PYTHONHOME", None)
    if preload:
        env["LD_PRELOAD"] = str(libpython())
    return env


def run_c_host(
    exe: Path,
    built: Built,
    step_ns: int,
    n_steps: int,
    starts: dict[str, dict[str, float]],
    work: Path,
    *,
    libpython_directive: bool = True,
    ld_preload: bool = False,
    unload: bool = True,
) -> tuple[subprocess.CompletedProcess, np.ndarray | None]:
    """Write a host configuration, run the C host, return the process and its CSV (or None)."""
    units = {"plant": built.plant, "controller": built.controller}
    csv = work / "host.csv"
    lines = []
    if libpython_directive:
        lines.append(f"libpython {libpython()}")
    for name, u in units.items():
        lines.append(f"fmu {name} {u.unzipped} {u.model} {u.guid}")
    for name, values in starts.items():
        for var, value in values.items():
            lines.append(f"real {name} {units[name].vr[var]} {float(value)!r}")
    for src, svr, dst, dvr in _links(built):
        lines.append(f"connect {src} {svr} {dst} {dvr}")
    for u, vr in _columns(built):
        lines.append(f"record {u} {vr} {u}.{vr}")
    lines += [f"step_ns {step_ns}", f"steps {n_steps}", f"csv {csv}", f"unload {int(unload)}"]
    config = work / "host.cfg"
    config.write_text("\n".join(lines) + "\n")
    if csv.exists():
        csv.unlink()
    proc = subprocess.run(
        [str(exe), str(config)],
        capture_output=True,
        text=True,
        env=c_host_env(ld_preload),
        timeout=600,
    )
    data = np.loadtxt(csv, delimiter=",", skiprows=1) if csv.exists() else None
    return proc, data
