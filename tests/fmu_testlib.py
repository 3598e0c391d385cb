"""Shared helpers of the tests, above all the FMU tests' (this module is not collected).

* :func:`built_fmus` designs the controller and builds the six FMUs and the four SSP packages
  once per test session with the real command (``python build_fmus.py --gains ... --design
  --out ...`` in a subprocess, so the test process is not touched by pythonfmu's builder; the
  gains file does not exist yet, so the command designs it first); :func:`build_only` builds
  one or two FMUs more where a test needs a build of its own (other gains, the installed
  package);
* :func:`build_small_fmus` builds the master's small test FMUs of ``tests/fmus/``;
* :class:`Slave` drives one FMU instance with fmpy, records its log messages (formatted as a C
  host formats them) and returns raw statuses;
* :func:`jacobi_fmpy`, :func:`run_libcosim` and :func:`run_c_host` run the same fixed-step Jacobi
  co-simulation of plant and controller in three independent masters. All three follow libcosim's
  ``fixed_step_algorithm``: time in integer nanoseconds, ``t_k = k*H_ns/1e9`` and
  ``h_k = t_{k+1} - t_k`` in double; per macro step every FMU gets its pending inputs, steps and
  is read; then outputs are transferred to the pending inputs of the next step. Initialization:
  read outputs after ``fmi2EnterInitializationMode``, then N (number of FMUs) rounds of set inputs
  / read outputs / transfer, then set inputs, ``fmi2ExitInitializationMode``, read, transfer.
  ``jacobi_fmpy(..., grid=ecos_grid)`` uses the time grid of the Ecos engine instead
  (``t_{k+1} = t_k + H`` accumulated in double);
* :func:`clean_env` is the environment of the "independent host" tests: ``env -i`` with only
  ``PATH=/usr/bin:/bin``, ``HOME``, ``LANG`` and the machine's ``OPENBLAS_*`` settings;
  :func:`first_use` is the first run of the FMUs in such an environment (it compiles the kernel
  into :func:`package_cache`);
  :func:`ecos_command` runs the ``ecos`` command line of the ``ecospy`` wheel in it;
* for every test: :func:`gains_file` (a consistent gains file of given gains),
  :func:`load_script` (a script of ``tools/`` as a module), :func:`strict_json`.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)
from pythonfmu import FmuBuilder

import drillstring.model.control  # noqa: F401  (import the repository's package before any FMU
import drillstring.model.engine  # noqa: F401  puts its bundled copy on sys.path, see restore_sys_path)
from drillstring.apps.export import build as builder
from drillstring.apps.export.model_description3 import fmi3_model_identifier
from drillstring.controller.averaged import averaged_model
from drillstring.controller.gains import PAPER_F, GainsFile, read_gains, write_gains
from drillstring.model.params import REFERENCE
from drillstring.orchestration.closed_loop import SCALED
from drillstring.orchestration.hosts import ecos_command, load_ecospy  # noqa: F401  (the tests' hosts)
from drillstring.orchestration.loop_ssp import write_loop_package
from drillstring.orchestration.master import Master
from drillstring.orchestration.master import Unit as MasterUnit

ROOT = Path(__file__).resolve().parents[1]
C_HOST = ROOT / "tests" / "c_host" / "host.c"
#: Instances made and freed in a loop from a thread with a given stack (tests/c_host/cycles.c).
C_CYCLES = ROOT / "tests" / "c_host" / "cycles.c"
PLANT = "DrillStringPlant"
CONTROLLER = "TorsionalController"
#: Plant outputs fed back to the controller inputs of the same name, and the torque back.
FEEDBACK = ("phi", "dphi", "theta", "dtheta")
RECORD_PLANT = ("u", "du", "phi", "dphi", "theta", "dtheta", "d", "g", "tau_n")
#: The same loop in SI units (DrillStringPlantSI, TorsionalControllerSI).
PLANT_SI = "DrillStringPlantSI"
CONTROLLER_SI = "TorsionalControllerSI"
#: The industrial top-drive controller, in both unit systems (the LMI controller's connectors).
TOPDRIVE = "TopDriveController"
TOPDRIVE_SI = "TopDriveControllerSI"
FEEDBACK_SI = ("bit_angle", "bit_speed", "table_angle", "table_speed")
RECORD_PLANT_SI = (
    "bit_position",
    "bit_velocity",
    *FEEDBACK_SI,
    "depth_of_cut",
    "contact",
    "delay",
    "weight_on_bit",
    "torque_on_bit",
    "rate_of_penetration",
)
OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4


@dataclass
class Unit:
    """A built FMU: archive, unpacked folder, model description and value references."""

    model: str
    fmu: Path
    unzipped: Path
    guid: str
    vr: dict[str, int]
    types: dict[str, str]
    causality: dict[str, str] = field(default_factory=dict)


@dataclass
class Built:
    """The plant and controller of one session build (in one unit system), the gains file, the
    build folder and the names that connect them; :attr:`si` is the same build's SI loop."""

    plant: Unit
    controller: Unit
    gains: Path
    out: Path
    #: F, K0 and R_ff of the gains file
    gains_values: dict[str, Any] = field(default_factory=dict)
    #: what the build command wrote to stderr
    build_log: str = ""
    units: str = "scaled"
    feedback: tuple[str, ...] = FEEDBACK
    torque: str = "R_minus_R0"
    record: tuple[str, ...] = RECORD_PLANT
    ssp: Path | None = None
    other: Built | None = None
    #: the top-drive controller of the same unit system, and the package of its loop
    topdrive: Unit | None = None
    topdrive_ssp: Path | None = None

    @property
    def si(self) -> Built:
        """The SI FMUs of the same build (``DrillStringPlantSI``, ``TorsionalControllerSI``)."""
        if self.units == "si":
            return self
        assert self.other is not None
        return self.other

    @property
    def scaled(self) -> Built:
        if self.units == "scaled":
            return self
        assert self.other is not None
        return self.other


@contextlib.contextmanager
def kept_sys_path() -> Iterator[None]:
    """Restore ``sys.path`` after the block (a second line of defence: the FMUs' front layer
    leaves it unchanged, which tests/test_fmu_lifecycle.py checks).

    The modules the FMUs import (``drillstring``, ``pythonfmu``) are imported from the repository
    and the environment when this module loads, so the bundled copies never replace them in the
    test process itself.
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


def gains_file(
    F: tuple[float, ...],
    A: float,
    taubar_crit: float,
    *,
    constraint: dict[str, Any] | None = None,
    solver: str = "test",
    solver_status: str = "input",
    spectral_abscissa: float = -1.0,
) -> GainsFile:
    """A consistent gains file of the reference set with the gains ``F``, not a designed one:
    K0 and R_ff of (27), (31) at ``A``, ``taubar_crit``, no certificate."""
    model = averaged_model(REFERENCE, A, taubar_crit)
    return GainsFile(
        F=F,
        K0=model.K0,
        R_ff=model.R_ff,
        alpha=1.0,
        A=A,
        taubar_crit=taubar_crit,
        params=REFERENCE,
        certificate={},
        spectral_abscissa=spectral_abscissa,
        solver=solver,
        solver_status=solver_status,
        constraint=constraint,
    )


def strict_json(text: str) -> Any:
    """Parse as a strict JSON reader (``JSON.parse``) does: no NaN, Infinity, -Infinity."""

    def refuse(word: str) -> None:
        raise ValueError(f"not JSON: {word}")

    return json.loads(text, parse_constant=refuse)


def make_gains_file(path: Path) -> Path:
    """A valid gains file: the paper's F with K0 and R_ff of (27), (31) at an assumed A.

    Other gains than the session build's designed ones (:func:`other_gains_fmus`): a consistent
    gains file, not a designed one; A = 0.45 and taubar_crit = 5 are merely admissible values.
    """
    gains = gains_file(
        PAPER_F,
        0.45,
        5.0,
        solver="none (test fixture)",
        solver_status="none",
        spectral_abscissa=0.0,
    )
    return write_gains(gains, path)


def run_build(
    out: Path,
    gains: Path,
    env: dict[str, str] | None = None,
    *,
    base: Mapping[str, str] | None = None,
    design: bool = False,
) -> subprocess.CompletedProcess:
    """``python build_fmus.py --gains GAINS --out OUT`` (with ``--design``: the controller
    designed into GAINS if it does not exist) in the environment ``base`` (this process's by
    default) updated with ``env``; raises with its output on failure."""
    proc = subprocess.run(
        [sys.executable, str(ROOT / "build_fmus.py"), "--gains", str(gains), "--out", str(out)]
        + (["--design"] if design else []),
        capture_output=True,
        text=True,
        env={**(os.environ if base is None else base), **(env or {})},
        cwd=ROOT,
        timeout=600,
    )
    if proc.returncode != 0:
        raise AssertionError(f"build_fmus.py failed ({proc.returncode}):\n{proc.stderr}")
    return proc


def build_only(
    models: tuple[str, ...],
    out: str | os.PathLike[str],
    gains: str | os.PathLike[str],
    source_date_epoch: int | None = None,
    fmi: tuple[int, ...] = (2,),
    self_contained: bool = False,
) -> dict[str, Path]:
    """:func:`drillstring.apps.export.build.build_fmus` with only the FMUs ``models`` built (the
    others and the SSP packages left out) in the FMI versions ``fmi`` (the FMI 3.0 twin of ``X``
    is ``X3``), self-contained or not, in this process; returns {model identifier: path}.

    The build proper is ``build_fmus``'s own: the gains file read (or designed when missing),
    ``SOURCE_DATE_EPOCH`` from the environment unless ``source_date_epoch`` is given, each FMU's
    build configuration; only the calls of ``build_fmu`` for other FMUs and of
    ``build_packages`` are skipped. For the tests that need one or two FMUs of a build of their
    own (the session builds every FMU once, :func:`built_fmus`); the determinism test runs it
    in a Python that imports the installed package instead of the checkout.
    """
    real_fmu, real_packages = builder.build_fmu, builder.build_packages

    def only(spec: Any, *args: Any, **kwargs: Any) -> dict[str, Path]:
        return real_fmu(spec, *args, **kwargs) if spec.model in models else {}

    builder.build_fmu, builder.build_packages = only, lambda *args, **kwargs: {}
    try:
        built = builder.build_fmus(out, gains, source_date_epoch, self_contained, fmi)
    finally:
        builder.build_fmu, builder.build_packages = real_fmu, real_packages
    name = {2: lambda m: m, 3: fmi3_model_identifier}
    assert set(built) == {name[v](m) for m in models for v in fmi}, built
    return built


@dataclass
class OtherGains:
    """The session's plant (scaled) beside a controller built from other gains
    (:func:`other_gains_fmus`)."""

    #: the folder of the two FMUs
    out: Path
    #: the gains file of its controller
    gains: Path


def other_gains_fmus(built: Built, root: Path) -> OtherGains:
    """``TorsionalController`` built (:func:`build_only`) from the gains of
    :func:`make_gains_file` (the paper's F at an assumed A), beside a copy of the session's
    ``DrillStringPlant``, and their SSP package (every run of the loop starts from it): the
    closed loop of other gains than the session's designed ones, for ``test_cosim_figures`` (a
    build of its own, so its users are ``slow``)."""
    gains = make_gains_file(root / "gains.json")
    out = root / "build"
    build_only((CONTROLLER,), out, gains)
    shutil.copyfile(built.plant.fmu, out / built.plant.fmu.name)
    write_loop_package(out, SCALED)
    return OtherGains(out, gains)


#: Folder of the session's unpacked FMUs, which every in-process fmpy test uses: its file URI
#: needs percent-encoding (fmpy encodes it), "%20" included.
UNPACKED = "unpacked ü#%[x] 100%20"


def _unit(model: str, fmu: Path, root: Path) -> Unit:
    unzipped = root / UNPACKED / model
    extract(str(fmu), str(unzipped))
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    types = {v.name: v.type for v in md.modelVariables}
    causality = {v.name: v.causality for v in md.modelVariables}
    return Unit(model, fmu, unzipped, md.guid, vr, types, causality)


def bench_build(work: Path) -> Built:
    """The benchmarks' build: the FMUs and packages of :func:`make_gains_file`'s gains built by
    ``build_fmus.py`` into ``work/build``, its scaled plant and controller unpacked under
    ``work``."""
    gains = make_gains_file(work / "gains.json")
    run_build(work / "build", gains)
    units = {m: _unit(m, work / "build" / f"{m}.fmu", work) for m in (PLANT, CONTROLLER)}
    return Built(units[PLANT], units[CONTROLLER], gains, work / "build")


def built_fmus(root: Path, environ: Mapping[str, str]) -> Built:
    """Design the controller and build the FMUs into ``root`` (once per session: conftest's
    ``built``): ``python build_fmus.py --gains GAINS --design --out OUT`` in the environment
    ``environ``, where GAINS does not exist yet, so the command designs the controller first
    (the synthesis with its certificate) and writes GAINS, then builds every FMU and SSP package
    with it."""
    gains = root / "design" / "gains.json"
    assert not gains.exists()
    out = root / "build"
    log = run_build(out, gains, base=environ, design=True).stderr
    designed = read_gains(gains)
    values = {"F": list(designed.F), "K0": designed.K0, "R_ff": designed.R_ff}
    scaled = Built(
        plant=_unit(PLANT, out / f"{PLANT}.fmu", root),
        controller=_unit(CONTROLLER, out / f"{CONTROLLER}.fmu", root),
        gains=gains,
        out=out,
        gains_values=values,
        build_log=log,
        ssp=out / "DrillStringClosedLoop.ssp",
        topdrive=_unit(TOPDRIVE, out / f"{TOPDRIVE}.fmu", root),
        topdrive_ssp=out / "DrillStringTopDrive.ssp",
    )
    si = Built(
        plant=_unit(PLANT_SI, out / f"{PLANT_SI}.fmu", root),
        controller=_unit(CONTROLLER_SI, out / f"{CONTROLLER_SI}.fmu", root),
        gains=gains,
        out=out,
        gains_values=values,
        build_log=log,
        units="si",
        feedback=FEEDBACK_SI,
        torque="table_torque",
        record=RECORD_PLANT_SI,
        ssp=out / "DrillStringClosedLoopSI.ssp",
        other=scaled,
        topdrive=_unit(TOPDRIVE_SI, out / f"{TOPDRIVE_SI}.fmu", root),
        topdrive_ssp=out / "DrillStringTopDriveSI.ssp",
    )
    scaled.other = si
    return scaled


# ------------------------------------------------------------------------------------------------
# the master's small test FMUs (tests/fmus/)
# ------------------------------------------------------------------------------------------------

#: The scripts of the master's test FMUs (short name -> pythonfmu script).
SMALL_SCRIPTS = {
    "integrator": ROOT / "tests" / "fmus" / "msttest_integrator.py",
    "gain": ROOT / "tests" / "fmus" / "msttest_gain.py",
    "oscillator": ROOT / "tests" / "fmus" / "msttest_oscillator.py",
}


def build_small_fmus(dest: Path) -> dict[str, Path]:
    """Build the master's test FMUs (:data:`SMALL_SCRIPTS`) into ``dest`` with pythonfmu and
    state their true ModelStructure; returns {short name: path to .fmu}.

    pythonfmu lists every output without a ``dependencies`` attribute, which in FMI 2.0 means
    "depends on all inputs": a master would then see false algebraic loops. Each script declares
    ``OUTPUT_DEPENDENCIES``, which is written into ``ModelStructure/Outputs`` of the built FMU.
    Built once per session (conftest's ``small_fmus``).
    """
    dest.mkdir(parents=True, exist_ok=True)
    built = {}
    with kept_sys_path():
        for name, script in SMALL_SCRIPTS.items():
            fmu = FmuBuilder.build_FMU(
                script, dest=dest, canGetAndSetFMUstate=True, canSerializeFMUstate=True
            )
            _patch_model_structure(Path(fmu), _output_dependencies(script))
            built[name] = Path(fmu)
    return built


def load_script(path: Path, name: str) -> ModuleType:
    """A script that is no installed module (``tools/``, ``tests/fmus/``) loaded as the module
    ``name``, which ``sys.modules`` holds (dataclasses look their module up there)."""
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def integrator_loop(
    small_fmus: dict[str, Path],
    ka: float = 1.0,
    kb: float = -1.0,
    a0: float = 1.0,
    b0: float = 0.0,
    a_extra: dict[str, float] | None = None,
    **kw: Any,
) -> Master:
    """Two integrators in a loop, a' = k_a b, b' = k_b a, from a(0) = a0, b(0) = b0 (``a_extra``:
    more start values of A); ``kw`` goes to the :class:`Master`."""
    units = [
        MasterUnit("A", small_fmus["integrator"], {"x0": a0, "k": ka, **(a_extra or {})}),
        MasterUnit("B", small_fmus["integrator"], {"x0": b0, "k": kb}),
    ]
    return Master(units, ["A.x -> B.u", "B.x -> A.u"], **kw)


def _output_dependencies(script: Path) -> dict[str, list[str]]:
    return load_script(script, f"_deps_{script.stem}").OUTPUT_DEPENDENCIES


@contextlib.contextmanager
def edited_model_description(src: Path, dst: Path) -> Iterator[ET.Element]:
    """The model description of the FMU ``src`` as the root element the block edits, written with
    the rest of the archive unchanged to ``dst`` (which may be ``src``: replaced only once the
    copy is whole) when the block ends without an error."""
    with zipfile.ZipFile(src) as z:
        entries = {info.filename: z.read(info.filename) for info in z.infolist()}
    root = ET.fromstring(entries["modelDescription.xml"])
    yield root
    entries["modelDescription.xml"] = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
    tmp = dst.with_suffix(".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in entries.items():
            z.writestr(name, data)
    tmp.replace(dst)


def _patch_model_structure(fmu: Path, deps: dict[str, list[str]]) -> None:
    with edited_model_description(fmu, fmu) as root:
        variables = root.find("ModelVariables").iter("ScalarVariable")
        index = {sv.get("name"): i + 1 for i, sv in enumerate(variables)}
        name_of = {v: k for k, v in index.items()}
        outputs = root.find("ModelStructure/Outputs")
        seen = set()
        for unknown in outputs.iter("Unknown"):
            name = name_of[int(unknown.get("index"))]
            seen.add(name)
            unknown.set("dependencies", " ".join(str(index[d]) for d in deps[name]))
            unknown.set("dependenciesKind", " ".join("fixed" for _ in deps[name]))
        if seen != set(deps):
            raise RuntimeError(f"{fmu.name}: OUTPUT_DEPENDENCIES {sorted(deps)} != {sorted(seen)}")
        # FMI 2.0 wants every output with initial="calculated" (the default) listed as an
        # initial unknown; no dependencies attribute = may depend on all start values.
        structure = root.find("ModelStructure")
        initial = ET.Element("InitialUnknowns")
        for unknown in outputs.iter("Unknown"):
            ET.SubElement(initial, "Unknown", index=unknown.get("index"))
        structure.insert(list(structure).index(outputs) + 1, initial)


# ------------------------------------------------------------------------------------------------
# fmpy
# ------------------------------------------------------------------------------------------------


#: The C type of each FMI 2.0 type but String's (char pointers).
_CTYPES = {"Real": ctypes.c_double, "Integer": ctypes.c_int, "Boolean": ctypes.c_int}


class Slave:
    """One FMU instance driven by fmpy.

    ``logs`` collects (status, category, message) of its log calls, formatted by fmpy's logger
    proxy like a C host formats them; :meth:`call` returns the raw status of an FMI function
    (fmpy raises for statuses worse than fmi2Warning).
    """

    def __init__(
        self,
        unit: Unit,
        name: str,
        *,
        logging_on: bool = True,
        guid: str | None = None,
        resources: str | None = None,
        fmu_type: int = 1,
    ) -> None:
        self.unit = unit
        self.logs: list[tuple[int, str, str]] = []
        self.fmu = FMU2Slave(
            guid=unit.guid if guid is None else guid,
            unzipDirectory=str(unit.unzipped),
            modelIdentifier=unit.model,
            instanceName=name,
        )
        self._callbacks = make_callbacks(self.logs)
        uri = resources or Path(unit.unzipped, "resources").as_uri()
        self.fmu.callbacks = self._callbacks
        self.fmu.component = self.fmu.fmi2Instantiate(
            name.encode("utf-8"),
            fmu_type,
            self.fmu.guid.encode("utf-8"),
            uri.encode("utf-8"),
            ctypes.byref(self._callbacks),
            0,
            1 if logging_on else 0,
        )
        if self.fmu.component is None:
            raise InstantiationError(self.logs)

    # typed access by variable name
    def set(self, **values: Any) -> None:
        for name, value in values.items():
            self._typed("set", name)([self.unit.vr[name]], [value])

    def get(self, *names: str) -> list[Any]:
        return [self._typed("get", name)([self.unit.vr[name]])[0] for name in names]

    def _typed(self, verb: str, name: str) -> Any:
        """fmpy's ``set``/``get`` method of the variable ``name``'s type."""
        kind = self.unit.types[name]
        return getattr(self.fmu, f"{verb}{'Integer' if kind == 'Enumeration' else kind}")

    def call(self, function: str, *args: Any) -> int:
        """Raw status of ``fmi2<function>(component, *args)``."""
        try:
            return int(getattr(self.fmu, f"fmi2{function}")(self.fmu.component, *args))
        except FMICallException as exc:
            return int(exc.status)

    def set_raw(self, kind: str, vrs: list[int], values: list[Any]) -> int:
        """Raw status of fmi2Set<kind> (no type checks here: that is what is tested)."""
        if kind == "String":
            arr = (ctypes.c_char_p * len(values))(*[str(v).encode() for v in values])
        else:
            arr = (_CTYPES[kind] * len(values))(*values)
        return self.call(f"Set{kind}", (ctypes.c_uint * len(vrs))(*vrs), len(vrs), arr)

    def get_raw(self, kind: str, vrs: list[int]) -> tuple[int, list[Any]]:
        arr = ({**_CTYPES, "String": ctypes.c_char_p}[kind] * len(vrs))()
        st = self.call(f"Get{kind}", (ctypes.c_uint * len(vrs))(*vrs), len(vrs), arr)
        return st, list(arr)

    def step(self, t: float, h: float) -> int:
        return self.call("DoStep", ctypes.c_double(t), ctypes.c_double(h), 1)

    def last_successful_time(self) -> float:
        value = ctypes.c_double(float("nan"))
        assert self.call("GetRealStatus", 2, ctypes.byref(value)) == OK
        return value.value

    def messages(self, status: int | None = None) -> list[str]:
        return [m for s, _, m in self.logs if status is None or s == status]

    def init(self, **values: Any) -> Slave:
        self.set(**values)
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        return self

    def free(self) -> None:
        self.fmu.fmi2FreeInstance(self.fmu.component)
        self.fmu.freeLibrary()


class InstantiationError(Exception):
    """fmi2Instantiate returned NULL; ``logs`` holds what the FMU said."""

    def __init__(self, logs: list[tuple[int, str, str]]) -> None:
        super().__init__("fmi2Instantiate returned NULL: " + " | ".join(m for _, _, m in logs))
        self.logs = logs


def make_callbacks(sink: list[tuple[int, str, str]]) -> fmi2CallbackFunctions:
    """fmi2CallbackFunctions appending (status, category, message) to ``sink``.

    The FMUs pass each message as a printf format without arguments ('%' written as '%%'); this
    logger formats it as printf would. (fmpy's native logger proxy would do it too, but it keeps
    one Python logger per process: the last one registered receives every instance's messages.)
    """

    def logger(env: Any, instance: Any, status: int, category: Any, message: bytes) -> None:
        cat = category.decode("utf-8") if category else ""
        text = message.decode("utf-8", "replace").replace("%%", "%")
        sink.append((int(status), cat, text))

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(_calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(_free)
    return callbacks


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


def libcosim_grid(step_ns: int, n_steps: int) -> list[tuple[float, float]]:
    return [grid(k, step_ns) for k in range(n_steps)]


def ecos_grid(step: float, n_steps: int) -> list[tuple[float, float]]:
    """The Ecos engine's grid: constant h, t_{k+1} = t_k + h accumulated in double."""
    points, t = [], 0.0
    for _ in range(n_steps):
        points.append((t, step))
        t = t + step
    return points


# ------------------------------------------------------------------------------------------------
# three masters of the same closed loop
# ------------------------------------------------------------------------------------------------


def _links(built: Built) -> list[tuple[str, int, str, int]]:
    p, c = built.plant, built.controller
    links = [("plant", p.vr[n], "controller", c.vr[n]) for n in built.feedback]
    links.append(("controller", c.vr[built.torque], "plant", p.vr[built.torque]))
    return links


def _columns(built: Built) -> list[tuple[str, int]]:
    cols = [("plant", built.plant.vr[n]) for n in built.record]
    return cols + [("controller", built.controller.vr[built.torque])]


def jacobi_fmpy(
    built: Built,
    step_ns: int,
    n_steps: int,
    starts: dict[str, dict[str, float]],
    points: list[tuple[float, float]] | None = None,
    units: tuple[str, ...] = ("plant", "controller"),
    initial_exchange: bool = True,
) -> np.ndarray:
    """The closed loop with fmpy, libcosim's exchange (module docstring); rows after each step.

    ``points``: the (t, h) of each step (default: libcosim's grid); ``units=("plant",)`` runs the
    plant alone with its input at its start value. ``initial_exchange=False`` is fmpy.ssp's
    start instead of libcosim's: every connected input is 0 for the first step and nothing is
    exchanged in initialization mode.
    """
    points = points or libcosim_grid(step_ns, n_steps)
    units = {name: getattr(built, name) for name in units}
    slaves = {name: Slave(unit, f"{name}_jacobi") for name, unit in units.items()}
    try:
        for name, values in starts.items():
            slaves[name].set(**values)
        links = [link for link in _links(built) if link[0] in units and link[2] in units]
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

        if initial_exchange:
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
        else:
            for s in slaves.values():
                s.fmu.setupExperiment(startTime=0.0)
                s.fmu.enterInitializationMode()
                s.fmu.exitInitializationMode()
            pending.update({(dst, dvr): 0.0 for _, _, dst, dvr in links})

        cols = [c for c in _columns(built) if c[0] in units]
        rows = []
        for t, h in points:
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
    """The shared libpython of this interpreter."""
    name = sysconfig.get_config_var("INSTSONAME") or sysconfig.get_config_var("LDLIBRARY")
    return Path(sysconfig.get_config_var("LIBDIR")) / name


def clean_env(home: Path, **extra: str) -> dict[str, str]:
    """``env -i`` with only ``PATH=/usr/bin:/bin``, ``HOME``, ``LANG`` and the machine's
    ``OPENBLAS_*`` settings (plus ``extra``): no ``LD_PRELOAD``, ``PYTHONPATH``,
    ``PYTHONHOME``, ``VIRTUAL_ENV`` or ``DRILLSTRING_*``. ``home`` is a folder of the test
    session, so the FMUs' package cache (:func:`package_cache`) starts empty once per session."""
    env = {"PATH": "/usr/bin:/bin", "HOME": str(home), "LANG": os.environ.get("LANG", "C.UTF-8")}
    env.update({k: v for k, v in os.environ.items() if k.startswith("OPENBLAS_")})
    env.update(extra)
    return env


#: Overrides of the Python a self-contained FMU would use, pointing nowhere: run with
#: :func:`clean_env` in isolation, such an FMU must not need them (it brings its own).
BOGUS_PYTHON = {
    "DRILLSTRING_FMU_LIBPYTHON": "/nonexistent/libpython3.11.so",
    "DRILLSTRING_FMU_PYTHONHOME": "/nonexistent",
    "DRILLSTRING_FMU_SITE_PACKAGES": "/nonexistent",
}


def package_cache(home: Path) -> Path:
    """The FMUs' package cache of a clean environment (:func:`clean_env`) with this HOME: there
    the FMUs keep their copy of the package and numba its compiled kernel."""
    return home / ".cache" / "drillstring"


@dataclass
class FirstUse:
    """The FMUs' first use on a machine (:func:`first_use`): the C host's two runs."""

    home: Path
    #: the first run: the package is copied into the cache and the kernel compiled there
    first: subprocess.CompletedProcess
    #: the same closed loop from another unpack folder: the cache is found, nothing compiled
    again: subprocess.CompletedProcess


def first_use(built: Built, root: Path, env: Mapping[str, str]) -> FirstUse:
    """The C host runs the closed loop (5 steps of 2 ms, logging on) in the clean environment
    ``env`` (:func:`clean_env`) whose HOME, not created yet, becomes an empty folder, then again
    from a second unpack folder; its work goes into ``root``.

    The HOME is the session's ``clean_home`` (conftest): the one numba compilation of the
    clean-environment hosts happens here, and the test of the first use reads both runs."""
    home = Path(env["HOME"])
    home.mkdir()
    exe = compile_c_host(root)
    runs = []
    for k in (1, 2):
        work = root / f"unpack{k}"
        dirs = {
            n: unpack(getattr(built, n).fmu, work / UNPACKED / n) for n in ("plant", "controller")
        }
        csv = work / "host.csv"
        starts = {"controller": {"t_on": 0.5}}
        config = host_config(built, dirs, 2_000_000, 5, starts, csv, logging=True)
        runs.append(run_c_host(exe, config, work, dict(env), csv)[0])
    return FirstUse(home, *runs)


#: Makes self-contained FMUs in a fresh process: the step of ``build_fmus.py --self-contained``.
_SELF_CONTAINED = (
    "import json, sys; from pathlib import Path; "
    "from drillstring.apps.export.self_contained import self_contained_fmus; "
    "fmus = {m: Path(f) for m, f in json.loads(sys.argv[1]).items()}; "
    "warmup = [Path(f) for f in json.loads(sys.argv[3])]; "
    "self_contained_fmus(fmus, Path(sys.argv[2]), warmup=warmup)"
)


def self_contained_units(built: Built, root: Path, environ: Mapping[str, str]) -> Built:
    """``built`` with its plant and controller replaced by their self-contained forms
    (:func:`drillstring.apps.export.self_contained.self_contained_fmus`, in a subprocess run in
    the environment ``environ``), written to and unpacked in ``root``. The plant's FMI 3.0 twin
    is made self-contained in the same call (``out/DrillStringPlant3.fmu``): one runtime bundle
    and one kernel compiled by the FMI 2.0 plant and controller for all three, as
    ``build_fmus.py --self-contained`` makes them."""
    out = root / "build"
    fmus = {u.model: str(u.fmu) for u in (built.plant, built.controller)}
    twin = fmi3_model_identifier(built.plant.model)
    fmus[twin] = str(built.out / f"{twin}.fmu")
    warmup = [str(u.fmu) for u in (built.plant, built.controller)]
    proc = subprocess.run(
        [sys.executable, "-c", _SELF_CONTAINED, json.dumps(fmus), str(out), json.dumps(warmup)],
        capture_output=True,
        text=True,
        env=dict(environ),
        cwd=root,
        timeout=900,
    )
    if proc.returncode != 0:
        raise AssertionError(f"self_contained_fmus failed ({proc.returncode}):\n{proc.stderr}")
    return dataclasses.replace(
        built,
        plant=_unit(built.plant.model, out / built.plant.fmu.name, root),
        controller=_unit(built.controller.model, out / built.controller.fmu.name, root),
        out=out,
    )


def compile_c_host(out_dir: Path) -> Path:
    """Compile tests/c_host/host.c with the system's cc; returns the executable."""
    return compile_c_program(C_HOST, out_dir, "-std=c99", "-ldl")


def compile_c_program(source: Path, out_dir: Path, std: str, *libs: str) -> Path:
    """Compile a C program of the tests with the system's cc (warnings are errors)."""
    cc = shutil.which("cc")
    if cc is None:
        raise AssertionError("no C compiler (cc) on PATH")
    exe = out_dir / source.stem
    proc = subprocess.run(
        [cc, std, "-O2", "-Wall", "-Wextra", "-Werror", "-o", str(exe), str(source), *libs],
        capture_output=True,
        text=True,
        timeout=300,
    )
    if proc.returncode != 0:
        raise AssertionError(f"cc failed:\n{proc.stderr}")
    return exe


def unpack(fmu: Path, folder: Path) -> Path:
    """Unzip ``fmu`` into ``folder`` (which may need percent-encoding in a URI)."""
    folder.mkdir(parents=True, exist_ok=True)
    extract(str(fmu), str(folder))
    return folder


def host_config(
    built: Built,
    dirs: dict[str, Path],
    step_ns: int,
    n_steps: int,
    starts: dict[str, dict[str, float]],
    csv: Path,
    *,
    logging: bool = False,
    extra: tuple[str, ...] = (),
) -> str:
    """The C host's configuration for the units in ``dirs`` (name -> unpacked folder)."""
    units = {name: getattr(built, name) for name in dirs}
    lines = [*extra]
    for name, u in units.items():
        lines.append(f"fmu {name} {u.model} {u.guid} {dirs[name]}")
    for name, values in starts.items():
        for var, value in values.items():
            kind = {"Real": "real", "Integer": "integer", "Enumeration": "integer"}.get(
                units[name].types[var], "boolean"
            )
            lines.append(f"{kind} {name} {units[name].vr[var]} {float(value)!r}")
    for src, svr, dst, dvr in _links(built):
        if src in units and dst in units:
            lines.append(f"connect {src} {svr} {dst} {dvr}")
    for u, vr in _columns(built):
        if u in units:
            lines.append(f"record {u} {vr} {u}.{vr}")
    lines += [f"step_ns {step_ns}", f"steps {n_steps}", f"csv {csv}", f"logging {int(logging)}"]
    return "\n".join(lines) + "\n"


def run_c_host(
    exe: Path,
    config: str,
    work: Path,
    env: dict[str, str],
    csv: Path,
) -> tuple[subprocess.CompletedProcess, np.ndarray | None]:
    """Write ``config``, run the C host in ``env``, return the process and its CSV (or None)."""
    path = work / "host.cfg"
    path.write_text(config, encoding="utf-8")
    if csv.exists():
        csv.unlink()
    proc = subprocess.run(
        [str(exe), str(path)], capture_output=True, text=True, env=env, timeout=600
    )
    data = np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2) if csv.exists() else None
    return proc, data


# ------------------------------------------------------------------------------------------------
# Ecos (the ecospy wheel; its binaries need libtbb.so.12 of the tbb wheel)
# ------------------------------------------------------------------------------------------------


def read_ecos_csv(path: Path) -> tuple[list[str], np.ndarray]:
    """Header and data of an Ecos CSV (columns ``instance::variable[TYPE]``)."""
    lines = path.read_text().splitlines()
    header = [h.strip() for h in lines[0].split(",")]
    data = np.array([[float(x) for x in line.split(",")] for line in lines[1:] if line.strip()])
    return header, data


def ssp_folder(
    built: Built, folder: Path, starts: dict[str, dict[str, float]], name: str = "loop"
) -> Path:
    """An SSP folder (SystemStructure.ssd) of plant and controller with their connections and
    a parameter set ``initial`` of ``starts``, for ``ecos simulate --path FOLDER``."""
    folder.mkdir(parents=True, exist_ok=True)
    units = {"plant": built.plant, "controller": built.controller}
    for u in units.values():
        shutil.copyfile(u.fmu, folder / u.fmu.name)
    comps = []
    for cname, u in units.items():
        connectors = []
        for src, svr, dst, dvr in _links(built):
            for unit, vr, kind in ((src, svr, "output"), (dst, dvr, "input")):
                if unit == cname:
                    name_ = next(n for n, v in units[unit].vr.items() if v == vr)
                    connectors.append(
                        f'<ssd:Connector name="{name_}" kind="{kind}"><ssc:Real/></ssd:Connector>'
                    )
        params = "".join(
            f'<ssv:Parameter name="{var}"><ssv:Real value="{float(value)!r}"/></ssv:Parameter>'
            for var, value in starts.get(cname, {}).items()
        )
        bindings = (
            f"<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
            f'<ssv:ParameterSet name="initial"><ssv:Parameters>{params}</ssv:Parameters>'
            f"</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>"
            f"</ssd:ParameterBindings>"
        )
        comps.append(
            f'<ssd:Component name="{cname}" source="{u.fmu.name}">'
            f"<ssd:Connectors>{''.join(sorted(set(connectors)))}</ssd:Connectors>{bindings}"
            "</ssd:Component>"
        )

    def var(unit: str, vr: int) -> str:
        return next(n for n, v in units[unit].vr.items() if v == vr)

    conns = "".join(
        f'<ssd:Connection startElement="{src}" startConnector="{var(src, svr)}" '
        f'endElement="{dst}" endConnector="{var(dst, dvr)}"/>'
        for src, svr, dst, dvr in _links(built)
    )
    ssd = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<ssd:SystemStructureDescription version="1.0" name="' + name + '" '
        'xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
        'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
        'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">'
        f'<ssd:System name="{name}"><ssd:Elements>{"".join(comps)}</ssd:Elements>'
        f"<ssd:Connections>{conns}</ssd:Connections></ssd:System>"
        "</ssd:SystemStructureDescription>\n"
    )
    (folder / "SystemStructure.ssd").write_text(ssd, encoding="utf-8")
    return folder


def fmpy_command(*args: str) -> list[str]:
    """The ``fmpy`` command line of this environment (``python -m fmpy.cli``)."""
    return [sys.executable, "-m", "fmpy.cli", *args]


def run_clean(
    cmd: list[str],
    env: Mapping[str, str] | None = None,
    cwd: Path | None = None,
    timeout: float = 600,
) -> subprocess.CompletedProcess:
    """``cmd`` run to its end in ``env`` and ``cwd`` (None: this process's), its output captured
    as text."""
    return subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd, timeout=timeout)


def call_sequence(steps: list[tuple[str, Callable[[], Any]]]) -> None:
    """Run named calls, re-raising with the name of the one that failed."""
    for name, fn in steps:
        try:
            fn()
        except Exception as exc:
            raise AssertionError(f"{name} failed: {exc}") from exc


def fmu_with_units(
    src: Path, dst: Path, units: dict[str, str | None], defs: dict[str, str] | None = None
) -> Path:
    """A copy of an FMU whose model description declares other units for some Real variables.

    ``units``: variable -> unit name (None: no unit); ``defs``: unit name -> the attributes of
    its ``BaseUnit`` as XML text (``'kg="1" m="2" s="-2" factor="1000"'``), added to (or made
    into) ``UnitDefinitions``. The FMU's code is unchanged: it computes with the numbers it is
    given, so declaring a unit is honest only where every value it meets is given in it.
    """
    with edited_model_description(src, dst) as root:
        unit_defs = root.find("UnitDefinitions")
        if unit_defs is None and defs:
            unit_defs = ET.Element("UnitDefinitions")
            after = max(i for i, e in enumerate(root) if e.tag in ("CoSimulation", "ModelExchange"))
            root.insert(after + 1, unit_defs)
        for name, base in (defs or {}).items():
            unit_defs.append(ET.fromstring(f'<Unit name="{name}"><BaseUnit {base}/></Unit>'))
        for sv in root.iter("ScalarVariable"):
            if sv.get("name") in units:
                real = sv.find("Real")
                real.attrib.pop("displayUnit", None)
                real.attrib.pop("unit", None)
                if units[sv.get("name")] is not None:
                    real.set("unit", units[sv.get("name")])
    return dst
