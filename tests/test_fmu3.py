"""The FMI 3.0 twins of the FMUs (``X3.fmu`` beside ``X.fmu`` in the session build).

* their model descriptions: the same variables (names, value references, causality,
  variability, start, min, max, units) as the FMI 2.0 ones, plus the independent variable
  ``time`` (the schema of FMI 3.0, fmpy's rules and ``fmutool -check`` run on every FMU of the
  build, the twins included, in ``tests/test_fmu_checkers.py``);
* the same numbers: the FMI 3.0 plant equals the FMI 2.0 plant bit for bit on the open loop of
  Fig. 5 (fmpy's ``simulate_fmu`` and its low-level ``fmpy.fmi3`` API), and the closed loop of
  FMI 3.0 plant and controller equals that of the FMI 2.0 pair;
* the conformance rows of the FMI 3.0 front (``fmu_src/fmi_front/front3.c``): statuses, illegal
  call sequences, unknown value references, types it has none of, a wrong instantiation token,
  a negative step, a wrong communication point, a state of another FMU refused, and a failed
  instantiation that returns NULL with a message at once (in a subprocess: a hang would show as
  its timeout).
"""

from __future__ import annotations

import ctypes
import math
import re
import shutil
import subprocess
import sys
import textwrap
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import fmpy
import fmu_testlib as tl
import isolation
import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave, fmi3LogMessageCallback

from drillstring.apps.export import cli as export_cli
from drillstring.apps.export.build import build_fmus
from drillstring.apps.export.specs import BuildError
from drillstring.model.experiments import FIG5

pytestmark = pytest.mark.fmu

OK, WARNING, DISCARD, ERROR = tl.OK, tl.WARNING, tl.DISCARD, tl.ERROR
#: Every FMU of the build and its twin.
MODELS = (
    tl.PLANT,
    tl.CONTROLLER,
    tl.PLANT_SI,
    tl.CONTROLLER_SI,
    tl.TOPDRIVE,
    tl.TOPDRIVE_SI,
)
#: FMI 2.0 type element -> FMI 3.0 type element.
FMI3_TYPE = {
    "Real": "Float64",
    "Integer": "Int32",
    "Enumeration": "Enumeration",
    "Boolean": "Boolean",
}


def twin(built: tl.Built, model: str) -> Path:
    path = built.out / f"{model}3.fmu"
    assert path.is_file(), f"the build wrote no {path.name}"
    return path


def _root(fmu: Path) -> ET.Element:
    with zipfile.ZipFile(fmu) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


# ------------------------------------------------------------------------------------------------
# model descriptions
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("model", MODELS)
def test_fmi3_model_description_declares_the_fmi2_variables(built, model):
    fmu3 = twin(built, model)
    with zipfile.ZipFile(fmu3) as z:
        names = set(z.namelist())
    assert f"binaries/x86_64-linux/{model}3.so" in names
    assert f"binaries/x86_64-linux/{model}3_pythonfmu.so" in names

    r2, r3 = _root(built.out / f"{model}.fmu"), _root(fmu3)
    assert r3.get("fmiVersion") == "3.0"
    token = r3.get("instantiationToken")
    assert re.fullmatch(r"\{[0-9a-f-]{36}\}", token) and token != r2.get("guid")
    cs = r3.find("CoSimulation")
    assert cs.get("modelIdentifier") == f"{model}3"
    assert cs.get("canGetAndSetFMUState") == cs.get("canSerializeFMUState") == "true"
    assert cs.get("hasEventMode") == "false"
    assert cs.get("canHandleVariableCommunicationStepSize") == "true"

    vars2 = {sv.get("name"): sv for sv in r2.find("ModelVariables")}
    vars3 = {v.get("name"): v for v in r3.find("ModelVariables")}
    # the plants' along-string profile: FMI 3.0 arrays (tests/test_fmu3_arrays.py), sized by a
    # structural parameter
    arrays = {n: v for n, v in vars3.items() if v.find("Dimension") is not None}
    assert len(arrays) == (2 if model in (tl.PLANT, tl.PLANT_SI) else 0)
    sizes = {d.get("valueReference") for v in arrays.values() for d in v.findall("Dimension")}
    assert set(vars3) == set(vars2) | {"time"} | set(arrays)
    for name in arrays:
        vars3.pop(name)
    time = vars3.pop("time")
    assert (time.tag, time.get("causality"), time.get("variability")) == (
        "Float64",
        "independent",
        "continuous",
    )
    scaled = all(sv[0].get("unit") in (None, "1") for sv in vars2.values())
    assert time.get("unit") == ("1" if scaled else "s")
    assert int(time.get("valueReference")) not in {
        int(v.get("valueReference")) for v in vars3.values()
    }
    for name, sv in vars2.items():
        v3, t2 = vars3[name], sv[0]
        assert v3.tag == FMI3_TYPE[t2.tag], name
        for key in ("valueReference", "causality", "variability", "initial", "description"):
            if key == "causality" and sv.get("valueReference") in sizes:
                assert v3.get(key) == "structuralParameter", name
                continue
            expected = sv.get(key)
            if key == "description" and expected is not None:  # the statuses in FMI 3.0's words
                expected = re.sub(r"\bfmi2(OK|Warning|Discard|Error|Fatal)\b", r"fmi3\1", expected)
            assert v3.get(key) == expected, (name, key)
    # the twin's texts name FMI 3.0's statuses, never FMI 2.0's
    text3 = ET.tostring(r3, encoding="unicode")
    assert "fmi2" not in text3, re.findall(r".{40}fmi2.{20}", text3)
    if model in (tl.PLANT, tl.PLANT_SI):
        assert "fmi3Discard" in text3 and "fmi2Discard" in ET.tostring(r2, encoding="unicode")
        for key in ("unit", "displayUnit", "min", "max", "start", "declaredType"):
            assert v3.get(key) == t2.get(key), (name, key)

    # ModelStructure: FMI 2.0's 1-based indices become value references
    index = [sv.get("valueReference") for sv in r2.find("ModelVariables")]

    def by_vr(unknowns: list[ET.Element]) -> list[tuple[str, str]]:
        return [
            (
                index[int(u.get("index")) - 1],
                " ".join(index[int(i) - 1] for i in (u.get("dependencies") or "").split()),
            )
            for u in unknowns
        ]

    s2, s3 = r2.find("ModelStructure"), r3.find("ModelStructure")
    array_vrs = [(v.get("valueReference"), "") for v in arrays.values()]
    outputs3 = [(u.get("valueReference"), u.get("dependencies")) for u in s3.findall("Output")]
    assert outputs3 == by_vr(s2.findall("Outputs/Unknown")) + array_vrs
    initial3 = [u.get("valueReference") for u in s3.findall("InitialUnknown")]
    initial2 = [vr for vr, _ in by_vr(s2.findall("InitialUnknowns/Unknown"))]
    assert initial3 == initial2 + [vr for vr, _ in array_vrs]
    units2 = {u.get("name") for u in r2.find("UnitDefinitions")}
    assert {u.get("name") for u in r3.find("UnitDefinitions")} == units2 | {time.get("unit")}


def test_fmi3_front_exports_every_fmi3_function_and_is_not_linked_to_python(built, tmp_path):
    """The twin's library exports exactly the functions of the standard's fmi3Functions.h (the
    copy fmpy ships), and the process lock the FMI 2.0 FMUs share; Python's C API is resolved at
    run time, as in the FMI 2.0 layer."""
    header = (Path(fmpy.__file__).parent / "c-code" / "fmi3Functions.h").read_text()
    standard = set(re.findall(r"^#define (fmi3\w+)\s+fmi3FullName\(", header, re.M))
    assert len(standard) > 60 and "fmi3DoStep" in standard
    nm = shutil.which("nm")
    assert nm is not None
    for model in MODELS:
        folder = tmp_path / model
        extract(str(twin(built, model)), str(folder))
        lib = folder / "binaries" / "x86_64-linux" / f"{model}3.so"
        run = {"capture_output": True, "text": True, "check": True}
        defined = subprocess.run([nm, "-D", "--defined-only", str(lib)], **run).stdout.split()
        undefined = subprocess.run([nm, "-D", "--undefined-only", str(lib)], **run).stdout
        assert {s for s in defined[2::3] if s.startswith("fmi3")} == standard, model
        assert [s for s in defined[2::3] if not s.startswith(("fmi3", "_"))] == [
            "drillstring_fmi2_process_lock"
        ], model
        assert not [s for s in undefined.split() if s.startswith(("Py", "_Py"))], model


# ------------------------------------------------------------------------------------------------
# the same numbers
# ------------------------------------------------------------------------------------------------


def test_fmi3_plant_equals_fmi2_plant_on_fig5_open_loop_in_simulate_fmu(built):
    """Fig. 5's open loop (dphi/dtau(0) = -2.5, R - R0 = 0) over its 60 units of tau, H = 0.01."""
    kwargs = {
        "stop_time": FIG5.tau_end,
        "output_interval": 0.01,
        "fmi_type": "CoSimulation",
        "start_values": {"dphi0": FIG5.dphi0},
    }
    r2 = simulate_fmu(str(built.plant.fmu), **kwargs)
    r3 = simulate_fmu(str(twin(built, tl.PLANT)), **kwargs)
    # the twin records its arrays too (tests/test_fmu3_arrays.py): on the default one element
    # the top torque and the bit's speed
    arrays = {"element_torque_minus_R0": "top_torque_minus_R0", "node_dphi": "dphi"}
    assert set(r3.dtype.names) == set(r2.dtype.names) | set(arrays)
    assert len(r2) == len(r3) == 6001
    for name in r2.dtype.names:
        assert np.array_equal(r2[name], r3[name]), name
    for name, scalar in arrays.items():
        assert np.array_equal(r3[name][:, 0], r2[scalar]), name
    assert np.ptp(r2["dphi"]) > 1.0  # the run is the stick-slip of Fig. 5, not a rest state


class Twin:
    """One instance of an FMU in either FMI version, driven by fmpy's low-level API."""

    def __init__(self, fmu: Path, folder: Path, fmi: int, name: str) -> None:
        md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        unzipped = extract(str(fmu), str(folder))
        model = md.coSimulation.modelIdentifier
        cls = FMU3Slave if fmi == 3 else FMU2Slave
        self.fmi = fmi
        self.fmu = cls(
            guid=md.guid, unzipDirectory=unzipped, modelIdentifier=model, instanceName=name
        )
        self.fmu.instantiate()

    def set(self, **values: float) -> None:
        vrs, xs = [self.vr[n] for n in values], list(values.values())
        (self.fmu.setFloat64 if self.fmi == 3 else self.fmu.setReal)(vrs, xs)

    def get(self, *names: str) -> list[float]:
        vrs = [self.vr[n] for n in names]
        return (self.fmu.getFloat64 if self.fmi == 3 else self.fmu.getReal)(vrs)

    def start(self) -> None:
        if self.fmi == 3:
            self.fmu.enterInitializationMode(startTime=0.0)
        else:
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()

    def step(self, t: float, h: float) -> None:
        self.fmu.doStep(t, h)

    def free(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


def _open_loop(
    built: tl.Built, tmp: Path, fmi: int, n_steps: int, names=tl.RECORD_PLANT, **start: float
) -> np.ndarray:
    """The plant of one FMI version alone (R - R0 = 0) from the start values ``start``: per step
    of 10 ms the time at its end and ``names``."""
    fmu = twin(built, tl.PLANT) if fmi == 3 else built.plant.fmu
    plant = Twin(fmu, tmp / f"open{fmi}", fmi, f"open{fmi}")
    try:
        plant.set(**start)
        plant.start()
        plant.fmu.exitInitializationMode()
        rows = []
        for k in range(n_steps):
            t, h = tl.grid(k, 10_000_000)
            plant.step(t, h)
            rows.append([t + h, *plant.get(*names)])
        return np.array(rows)
    finally:
        plant.free()


def test_fmi3_plant_equals_fmi2_plant_on_fig5_open_loop_in_the_low_level_api(built, tmp_path):
    r2 = _open_loop(built, tmp_path, 2, 6000, dphi0=FIG5.dphi0)
    r3 = _open_loop(built, tmp_path, 3, 6000, dphi0=FIG5.dphi0)
    assert r2.shape == r3.shape == (6000, 1 + len(tl.RECORD_PLANT))
    assert np.array_equal(r2, r3)


def _closed_loop(built: tl.Built, tmp: Path, fmi: int, n_steps: int) -> np.ndarray:
    """Fig. 5's closed loop (the session's designed controller on from tau = 0) in libcosim's
    Jacobi exchange (:func:`fmu_testlib.jacobi_fmpy`) on the twins of one FMI version."""
    plant_fmu = twin(built, tl.PLANT) if fmi == 3 else built.plant.fmu
    ctrl_fmu = twin(built, tl.CONTROLLER) if fmi == 3 else built.controller.fmu
    plant = Twin(plant_fmu, tmp / f"plant{fmi}", fmi, f"plant{fmi}")
    ctrl = Twin(ctrl_fmu, tmp / f"ctrl{fmi}", fmi, f"ctrl{fmi}")
    try:
        plant.set(dphi0=FIG5.dphi0)
        for s in (plant, ctrl):
            s.start()

        def exchange() -> None:
            ctrl.set(**dict(zip(tl.FEEDBACK, plant.get(*tl.FEEDBACK), strict=True)))
            plant.set(R_minus_R0=ctrl.get("R_minus_R0")[0])

        for _ in range(2):
            exchange()
        for s in (plant, ctrl):
            s.fmu.exitInitializationMode()
        feedback, torque = plant.get(*tl.FEEDBACK), ctrl.get("R_minus_R0")[0]
        rows = []
        for k in range(n_steps):
            t, h = tl.grid(k, 10_000_000)
            ctrl.set(**dict(zip(tl.FEEDBACK, feedback, strict=True)))
            plant.set(R_minus_R0=torque)
            plant.step(t, h)
            ctrl.step(t, h)
            feedback, torque = plant.get(*tl.FEEDBACK), ctrl.get("R_minus_R0")[0]
            rows.append([*plant.get(*tl.RECORD_PLANT), torque])
        return np.array(rows)
    finally:
        plant.free()
        ctrl.free()


def test_fmi3_closed_loop_equals_fmi2_closed_loop(built, tmp_path):
    r2 = _closed_loop(built, tmp_path, 2, 6000)
    r3 = _closed_loop(built, tmp_path, 3, 6000)
    assert np.array_equal(r2, r3)
    # the controller acts: the closed loop differs from the open loop of the same plant
    open_loop = _open_loop(built, tmp_path, 2, 6000, dphi0=FIG5.dphi0)[:, 1:]
    assert not np.array_equal(r2[:, : len(tl.RECORD_PLANT)], open_loop)


# ------------------------------------------------------------------------------------------------
# the conformance rows of the FMI 3.0 front
# ------------------------------------------------------------------------------------------------

F64 = ctypes.c_double
VR = ctypes.c_uint32
BOOL = ctypes.c_bool


class Raw:
    """One FMI 3.0 instance called through ctypes with raw statuses and its log messages."""

    def __init__(
        self,
        unzipped: Path,
        model: str,
        token: str,
        name: str = "raw",
        resources: str | None = None,
        logging_on: bool = True,
    ) -> None:
        self.logs: list[tuple[int, str, str]] = []
        self.lib = ctypes.CDLL(str(unzipped / "binaries" / "x86_64-linux" / f"{model}.so"))

        def log(env: Any, status: int, category: bytes, message: bytes) -> None:
            self.logs.append((status, category.decode(), message.decode()))

        self._log = fmi3LogMessageCallback(log)
        f = self.lib.fmi3InstantiateCoSimulation
        f.restype = ctypes.c_void_p
        f.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p, BOOL, BOOL, BOOL, BOOL]
        f.argtypes += [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p, fmi3LogMessageCallback]
        f.argtypes += [ctypes.c_void_p]
        path = resources if resources is not None else f"{unzipped / 'resources'}/"
        self.instance = f(
            name.encode(), token.encode(), path.encode(), False, logging_on, False, False,
            None, 0, None, self._log, None,
        )  # fmt: skip

    def call(self, function: str, *args: Any) -> int:
        """Raw status of ``fmi3<function>(instance, *args)``."""
        f = getattr(self.lib, f"fmi3{function}")
        f.restype = ctypes.c_int
        return f(ctypes.c_void_p(self.instance), *args)

    def get64(self, *vrs: int) -> tuple[int, list[float]]:
        values = (F64 * len(vrs))()
        status = self.call("GetFloat64", (VR * len(vrs))(*vrs), len(vrs), values, len(vrs))
        return status, list(values)

    def set64(self, vrs: list[int], values: list[float]) -> int:
        n = len(vrs)
        return self.call("SetFloat64", (VR * n)(*vrs), n, (F64 * n)(*values), n)

    def enter(self, start: float = 0.0, stop: float | None = None) -> int:
        return self.call(
            "EnterInitializationMode", BOOL(False), F64(0.0), F64(start),
            BOOL(stop is not None), F64(stop or 0.0),
        )  # fmt: skip

    def step(self, t: float, h: float) -> tuple[int, tuple[bool, bool, bool, float]]:
        flags = [BOOL(), BOOL(), BOOL(), F64()]
        status = self.call("DoStep", F64(t), F64(h), BOOL(True), *(ctypes.byref(x) for x in flags))
        return status, tuple(x.value for x in flags)

    def free(self) -> None:
        if self.instance:
            f = self.lib.fmi3FreeInstance
            f.argtypes = [ctypes.c_void_p]
            f(self.instance)
            self.instance = None

    def last(self) -> tuple[int, str]:
        status, _, message = self.logs[-1]
        return status, message


@pytest.fixture(scope="module")
def plant3(built, tmp_path_factory):
    fmu = twin(built, tl.PLANT)
    folder = tmp_path_factory.mktemp("plant3")
    extract(str(fmu), str(folder))
    md = read_model_description(str(fmu))
    return folder, md


def _raw(plant3: Any, **kwargs: Any) -> Raw:
    folder, md = plant3
    raw = Raw(folder, md.coSimulation.modelIdentifier, md.guid, **kwargs)
    assert raw.instance, raw.logs
    return raw


def _vr(plant3: Any) -> dict[str, int]:
    return {v.name: v.valueReference for v in plant3[1].modelVariables}


def _stepping(plant3: Any) -> Raw:
    raw = _raw(plant3)
    assert raw.enter() == OK
    assert raw.call("ExitInitializationMode") == OK
    for k in range(2):
        assert raw.step(0.01 * k, 0.01)[0] == OK
    return raw


def test_fmi3_statuses_and_flags_of_a_normal_run(plant3):
    vr = _vr(plant3)
    raw = _raw(plant3)
    try:
        assert raw.enter() == OK
        assert raw.call("ExitInitializationMode") == OK
        status, flags = raw.step(0.0, 0.01)
        assert (status, flags) == (OK, (False, False, False, 0.01))
        assert raw.get64(vr["time"]) == (OK, [0.01])
        status, (phi,) = raw.get64(vr["phi"])
        assert status == OK and math.isfinite(phi)
        # Int64 enumeration, Int32, Boolean
        e = (ctypes.c_int64 * 1)()
        assert raw.call("GetInt64", (VR * 1)(vr["on_invalid"]), 1, e, 1) == OK and e[0] == 1
        n = (ctypes.c_int32 * 1)()
        assert raw.call("GetInt32", (VR * 1)(vr["n"]), 1, n, 1) == OK and n[0] == 4
        b = (BOOL * 1)()
        assert raw.call("GetBoolean", (VR * 1)(vr["torsional_stick_model"]), 1, b, 1) == OK
        assert b[0] is False
        assert raw.call("Terminate") == OK
        assert raw.call("Reset") == OK
        assert raw.enter() == OK
    finally:
        raw.free()


def _row(
    plant3: Any,
    state: str,
    call: Callable[[Raw, dict[str, int]], int],
    status: int,
    message: str,
) -> None:
    raw = _stepping(plant3) if state == "stepping" else _raw(plant3)
    try:
        before = len(raw.logs)
        got = call(raw, _vr(plant3))
        assert got == status, raw.logs[before:]
        assert raw.logs[before:], "no message"
        s, text = raw.last()
        assert s == status and re.search(message, text), raw.logs[before:]
        if state == "stepping":  # the instance goes on: one more step from where it was
            assert raw.step(0.02, 0.01)[0] == OK
    finally:
        raw.free()


ROWS = {
    "do-step-before-initialization": (
        "instantiated",
        lambda r, vr: r.step(0.0, 0.01)[0],
        ERROR,
        r"^fmi3DoStep: illegal call sequence: not allowed in state Instantiated \(allowed in: "
        r"StepMode\)$",
    ),
    "exit-initialization-before-enter": (
        "instantiated",
        lambda r, vr: r.call("ExitInitializationMode"),
        ERROR,
        r"^fmi3ExitInitializationMode: illegal call sequence: not allowed in state Instantiated",
    ),
    "enter-initialization-twice": (
        "stepping",
        lambda r, vr: r.enter(),
        ERROR,
        r"^fmi3EnterInitializationMode: illegal call sequence: not allowed in state StepMode",
    ),
    "unknown-value-reference": (
        "stepping",
        lambda r, vr: r.get64(999)[0],
        ERROR,
        r"^fmi3GetFloat64: no variable has value reference 999 \(valueReferences\[0\]\); "
        r"nothing done$",
    ),
    "wrong-type": (
        "stepping",
        lambda r, vr: r.get64(vr["n"])[0],
        ERROR,
        r"^fmi3GetFloat64: variable n \(value reference \d+\) is an Int32, not a Float64",
    ),
    "float32-not-an-abort": (
        "stepping",
        lambda r, vr: r.call("GetFloat32", (VR * 1)(vr["phi"]), 1, (ctypes.c_float * 1)(), 1),
        ERROR,
        r"^fmi3GetFloat32: DrillStringPlant3\.fmu has no Float32 variables: phi",
    ),
    "clock-not-an-abort": (
        "stepping",
        lambda r, vr: r.call("GetClock", (VR * 1)(vr["phi"]), 1, (BOOL * 1)()),
        ERROR,
        r"^fmi3GetClock: DrillStringPlant3\.fmu has no Clock variables",
    ),
    "n-values-mismatch": (
        "stepping",
        lambda r, vr: r.call("GetFloat64", (VR * 1)(vr["phi"]), 1, (F64 * 2)(), 2),
        ERROR,
        r"^fmi3GetFloat64: nValues = 2 for 1 value references",
    ),
    "array-n-values-mismatch": (
        "stepping",
        lambda r, vr: r.call("GetFloat64", (VR * 1)(vr["node_dphi"]), 1, (F64 * 2)(), 2),
        ERROR,
        r"^fmi3GetFloat64: nValues = 2 for 1 value references, which hold 1 values",
    ),
    "structural-parameter-outside-configuration": (
        "instantiated",
        lambda r, vr: r.call(
            "SetInt32", (VR * 1)(vr["string_elements"]), 1, (ctypes.c_int32 * 1)(16), 1
        ),
        ERROR,
        r"^fmi3SetInt32: variable string_elements .* is a structural parameter .* only in "
        r"ConfigurationMode",
    ),
    "configuration-mode-only-structural": (
        "instantiated",
        lambda r, vr: max(r.call("EnterConfigurationMode"), r.set64([vr["psi"]], [300.0])),
        ERROR,
        r"^fmi3SetFloat64: variable psi .* is not a structural parameter: in ConfigurationMode "
        r"only those can be set",
    ),
    "set-an-output": (
        "stepping",
        lambda r, vr: r.set64([vr["phi"]], [1.0]),
        ERROR,
        r"^fmi3SetFloat64: variable phi .* is an output",
    ),
    "set-time": (
        "instantiated",
        lambda r, vr: r.set64([vr["time"]], [1.0]),
        ERROR,
        r"^fmi3SetFloat64: variable time .* is the independent variable",
    ),
    "parameter-after-initialization": (
        "stepping",
        lambda r, vr: r.set64([vr["psi"]], [300.0]),
        ERROR,
        r"^fmi3SetFloat64: parameter psi .* only before fmi3ExitInitializationMode",
    ),
    "negative-step": (
        "stepping",
        lambda r, vr: r.step(0.02, -0.01)[0],
        ERROR,
        r"^fmi3DoStep: step size must be > 0, got -0\.01 at t = 0\.02",
    ),
    "wrong-communication-point": (
        "stepping",
        lambda r, vr: r.step(0.5, 0.01)[0],
        ERROR,
        r"^fmi3DoStep: communication point t = 0\.5 is not the FMU's time 0\.02",
    ),
    "event-mode-not-provided": (
        "stepping",
        lambda r, vr: r.call("EnterEventMode"),
        ERROR,
        r"^fmi3EnterEventMode: not provided \(hasEventMode is false\)$",
    ),
    "start-time-not-zero": (
        "instantiated",
        lambda r, vr: r.enter(1.0),
        ERROR,
        r"^fmi3EnterInitializationMode: start time must be 0\.0",
    ),
    "step-past-stop-time": (
        "instantiated",
        lambda r, vr: max(
            r.enter(0.0, 0.05), r.call("ExitInitializationMode"), r.step(0.0, 0.06)[0]
        ),
        ERROR,
        r"^fmi3DoStep: the step \[0\.0, 0\.06\] ends after the stop time 0\.05 defined in "
        r"fmi3EnterInitializationMode; nothing was computed$",
    ),
    "stop-time-before-start": (
        "instantiated",
        lambda r, vr: r.enter(1.0, 0.5),
        ERROR,
        r"^fmi3EnterInitializationMode: stop time 0\.5 is not at or after the start time 1\.0",
    ),
}


@pytest.mark.parametrize("row", ROWS, ids=list(ROWS))
def test_fmi3_conformance_row(plant3, row):
    _row(plant3, *ROWS[row])


def test_fmi3_states_round_trip_and_a_foreign_state_is_refused(plant3, built, tmp_path):
    vr = _vr(plant3)
    raw = _stepping(plant3)
    try:
        state = ctypes.c_void_p()
        assert raw.call("GetFMUState", ctypes.byref(state)) == OK
        size = ctypes.c_size_t()
        assert raw.call("SerializedFMUStateSize", state, ctypes.byref(size)) == OK
        data = (ctypes.c_uint8 * size.value)()
        assert raw.call("SerializeFMUState", state, data, size) == OK
        assert raw.step(0.02, 0.01)[0] == OK
        after = raw.get64(vr["phi"], vr["dphi"])
        copy = ctypes.c_void_p()
        assert raw.call("DeserializeFMUState", data, size, ctypes.byref(copy)) == OK
        assert raw.call("SetFMUState", copy) == OK
        assert raw.get64(vr["time"]) == (OK, [0.02])
        assert raw.step(0.02, 0.01)[0] == OK
        assert raw.get64(vr["phi"], vr["dphi"]) == after  # the same step again, bit for bit
        for s in (state, copy):
            assert raw.call("FreeFMUState", ctypes.byref(s)) == OK

        # the serialized state of the FMI 2.0 plant (another FMU: its GUID) is refused
        fmu2 = tl.Slave(built.plant, "foreign")
        try:
            fmu2.init()
            foreign = bytes(fmu2.fmu.serializeFMUstate(fmu2.fmu.getFMUstate()))
        finally:
            fmu2.free()
        buf = (ctypes.c_uint8 * len(foreign)).from_buffer_copy(foreign)
        out = ctypes.c_void_p()
        assert raw.call("DeserializeFMUState", buf, len(foreign), ctypes.byref(out)) == ERROR
        assert re.search(
            r"^fmi3DeserializeFMUState: the bytes are an FMU state of DrillStringPlant \(GUID "
            r".*\), not of this FMU DrillStringPlant3",
            raw.last()[1],
        )
        # a pointer that is not one of its states
        bogus = (ctypes.c_uint8 * 64)()
        assert raw.call("SetFMUState", ctypes.cast(bogus, ctypes.c_void_p)) == ERROR
        assert re.search(
            r"^fmi3SetFMUState: .* is not an FMU state of DrillStringPlant3", raw.last()[1]
        )
        assert raw.step(0.03, 0.01)[0] == OK
    finally:
        raw.free()


def test_fmi3_wrong_token_and_bad_resources_give_null_with_a_message(plant3, tmp_path):
    folder, md = plant3
    model = md.coSimulation.modelIdentifier
    wrong = Raw(folder, model, "{00000000-0000-0000-0000-000000000000}")
    assert not wrong.instance
    assert wrong.last()[0] == ERROR
    assert re.search(
        r"^fmi3InstantiateCoSimulation: instantiationToken \{0{8}-.*\} does not match this "
        r"FMU's \{",
        wrong.last()[1],
    )
    empty = tmp_path / "empty"
    empty.mkdir()
    missing = Raw(folder, model, md.guid, resources=f"{empty}/")
    assert not missing.instance
    assert re.search(
        r"^fmi3InstantiateCoSimulation: resources folder .* lacks a readable", missing.last()[1]
    )
    relative = Raw(folder, model, md.guid, resources="resources/")
    assert not relative.instance
    assert re.search(r"is not an absolute path", relative.last()[1])
    # model exchange: NULL with the reason
    f = wrong.lib.fmi3InstantiateModelExchange
    f.restype = ctypes.c_void_p
    f.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p, BOOL, BOOL, ctypes.c_void_p]
    f.argtypes += [fmi3LogMessageCallback]
    assert not f(
        b"me", md.guid.encode(), f"{folder}/resources/".encode(), False, False, None, wrong._log
    )
    assert re.search(
        r"^fmi3InstantiateModelExchange: .* implements co-simulation only", wrong.last()[1]
    )
    good = _raw(plant3)  # the process goes on: a correct instantiation works
    good.free()


def test_fmi3_failed_instantiation_in_python_returns_null_without_a_hang(plant3, tmp_path):
    """The slave's module raises at import: NULL and the message, then a correct instance in the
    same process; in a subprocess, so that a hang (the GIL never released) is its timeout."""
    folder, md = plant3
    broken = tmp_path / "broken"
    shutil.copytree(folder / "resources", broken)
    entry = (broken / "slavemodule.txt").read_text().strip()
    (broken / f"{entry}.py").write_text("raise RuntimeError('broken on purpose')\n")
    script = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_fmu3 import Raw
        from pathlib import Path
        folder = Path({str(folder)!r})
        model, token = {md.coSimulation.modelIdentifier!r}, {md.guid!r}
        bad = Raw(folder, model, token, resources={f"{broken}/"!r})
        print("NULL" if not bad.instance else "INSTANCE")
        for status, category, message in bad.logs:
            print(status, message)
        good = Raw(folder, model, token)
        print("GOOD" if good.instance else "FAILED", flush=True)
        good.free()
        """
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == "NULL" and lines[-1] == "GOOD", proc.stdout
    assert any("broken on purpose" in line for line in lines), proc.stdout
    assert any(line.startswith(f"{ERROR} fmi3InstantiateCoSimulation: ") for line in lines)


# ------------------------------------------------------------------------------------------------
# Ecos
# ------------------------------------------------------------------------------------------------


def _ecos_closed_loop(built: tl.Built, suffix: str, n_steps: int) -> np.ndarray:
    ecospy = tl.load_ecospy()
    structure = ecospy.EcosSimulationStructure()
    structure.add_model("plant", str(built.out / f"{tl.PLANT}{suffix}.fmu"))
    structure.add_model("controller", str(built.out / f"{tl.CONTROLLER}{suffix}.fmu"))
    for name in tl.FEEDBACK:
        structure.make_real_connection(f"plant::{name}", f"controller::{name}")
    structure.make_real_connection("controller::R_minus_R0", "plant::R_minus_R0")
    structure.add_parameter_set("initial", {"plant::dphi0": FIG5.dphi0})
    rows = []
    with tl.kept_sys_path(), ecospy.EcosSimulation(structure=structure, step_size=0.01) as sim:
        sim.init(parameter_set="initial")
        for _ in range(n_steps):
            sim.step()
            plant = [sim.get_real(f"plant::{name}") for name in tl.RECORD_PLANT]
            rows.append([sim.get_time(), *plant, sim.get_real("controller::R_minus_R0")])
        sim.terminate()
    return np.array(rows)


def test_ecos_api_fmi3_closed_loop_equals_fmi2(built):
    """Ecos's engine (its Python API, in this process) runs the FMI 3.0 pair: bit for bit the
    FMI 2.0 pair's closed loop of Fig. 5 (Ecos skips the Enumeration parameters of the FMI 3.0
    twins, which it does not support; their start values apply)."""
    r2 = _ecos_closed_loop(built, "", 3000)
    r3 = _ecos_closed_loop(built, "3", 3000)
    assert r2.shape == r3.shape == (3000, len(tl.RECORD_PLANT) + 2)
    assert np.array_equal(r2, r3)
    assert np.ptp(r2[:, -1]) > 0.1  # the feedback acted


def _ecos_cli_plant(built: tl.Built, clean_home: Path, folder: Path, suffix: str) -> tuple:
    """``drillstring ecos simulate --path X.fmu`` (Ecos's command line, as a user types it) on
    the plant alone, from Fig. 5's initial speed to tau = 2, in a clean environment."""
    folder.mkdir()
    fmu = shutil.copyfile(built.out / f"{tl.PLANT}{suffix}.fmu", folder / "plant.fmu")
    env = tl.clean_env(clean_home, TMPDIR=str(folder))
    env["PATH"] = f"{Path(sys.executable).parent}:{env['PATH']}"
    command = ["drillstring", "ecos", "simulate", "--path", str(fmu), "--stepSize", "0.01"]
    proc = tl.run_clean([*command, "--stopTime", "2"], env, folder)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    (csv,) = folder.glob("*.csv")
    return tl.read_ecos_csv(csv)


def test_ecos_command_line_runs_the_fmi3_plant_like_the_fmi2_plant(built, clean_home, tmp_path):
    """``ecos simulate`` (the command line, not only the Python API) on the FMI 3.0 plant: every
    column the FMI 2.0 plant's run writes is the same in its CSV (as Ecos prints it,
    ``std::to_string``: 6 decimals; the Python API's test compares the doubles), and the plant
    moves."""
    h2, d2 = _ecos_cli_plant(built, clean_home, tmp_path / "fmi2", "")
    h3, d3 = _ecos_cli_plant(built, clean_home, tmp_path / "fmi3", "3")
    shared = [name for name in h2 if name in h3]
    assert len(shared) > len(tl.RECORD_PLANT), (h2, h3)
    assert d2.shape[0] == d3.shape[0] > 150
    for name in shared:
        assert np.array_equal(d2[:, h2.index(name)], d3[:, h3.index(name)]), name
    phi = [name for name in shared if name.endswith("::phi[REAL]") or name.endswith("::phi")]
    assert phi and np.ptp(d2[:, h2.index(phi[0])]) > 0


def test_docs_carry_the_fmi3_rows():
    """docs/fmus.md's table of the FMI 3.0 rows names every row of :data:`ROWS` with its status
    and the start of its message."""
    text = (tl.ROOT / "docs" / "fmus.md").read_text(encoding="utf-8")
    status = {ERROR: "fmi3Error"}
    for row, (state, _, code, pattern) in ROWS.items():
        (line,) = [x for x in text.splitlines() if x.startswith(f"| {row} |")]
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells[1] == state and cells[3] == status[code], line
        first = re.match(r"\^(fmi3\w+):", pattern)
        assert first is not None and cells[4].startswith(f"{first.group(1)}:"), line


# ------------------------------------------------------------------------------------------------
# a C host: FMI 3.0 without Python in the host, normal and self-contained
# ------------------------------------------------------------------------------------------------

#: The plant's outputs the C host records, and the number of its steps of 0.01.
HOST3_OUTPUTS = ("phi", "dphi", "theta", "dtheta", "u", "du")
HOST3_STEPS = 200


def _host3(fmu: Path, work: Path, env: dict[str, str], wrap=None) -> tuple[Any, np.ndarray]:
    """``tests/c_host/host3.c`` on the unpacked twin ``fmu`` (a folder whose name needs no
    quoting in a URI is not needed: FMI 3.0 passes a native path), in ``env``."""
    work.mkdir(parents=True, exist_ok=True)
    exe = tl.compile_c_program(tl.ROOT / "tests" / "c_host" / "host3.c", work, "-std=c11", "-ldl")
    folder = tl.unpack(fmu, work / "drill ü#%[x] 100%20")
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    csv = work / "host3.csv"
    cmd = [str(exe), str(folder), md.coSimulation.modelIdentifier, md.guid, "10000000"]
    cmd += [str(HOST3_STEPS), str(csv), *(str(vr[n]) for n in HOST3_OUTPUTS)]
    proc = tl.run_clean(wrap(cmd) if wrap else cmd, env, work)
    rows = np.loadtxt(csv, delimiter=",", ndmin=2) if csv.exists() else np.empty((0, 0))
    return proc, rows


def _fmi2_reference(built: tl.Built, tmp: Path) -> np.ndarray:
    """The FMI 2.0 plant in fmpy on the C host's grid and columns."""
    return _open_loop(built, tmp, 2, HOST3_STEPS, HOST3_OUTPUTS)


def test_c_host_runs_the_fmi3_plant_in_a_clean_environment(built, tmp_path, clean_home):
    """No Python in the host process, no libpython preloaded: the twin starts Python itself
    (the kernel compiled in clean_home) and gives the FMI 2.0 plant's numbers bit for bit."""
    proc, rows = _host3(twin(built, tl.PLANT), tmp_path / "host3", tl.clean_env(clean_home))
    assert proc.returncode == 0, proc.stderr
    assert rows.shape == (HOST3_STEPS, len(HOST3_OUTPUTS) + 1)
    assert np.array_equal(rows, _fmi2_reference(built, tmp_path))


@pytest.mark.slow
def test_self_contained_fmi3_plant_runs_where_no_python_is(built, self_contained, tmp_path):
    """The twin made self-contained with the session's self-contained FMUs (conftest's
    ``self_contained``: one bundle, its kernel compiled by the FMI 2.0 plant's and controller's
    warm-up) runs in the C host in isolation (``tests/isolation.py``: no Python installation, no
    checkout, no cache) with bogus overrides of the Python it would use: the FMI 2.0 plant's
    numbers."""
    fmu = twin(self_contained, tl.PLANT)
    with zipfile.ZipFile(fmu) as z:
        assert b"self-contained 1" in z.read("resources/drillstring_fmu_python.cfg")
    work = tmp_path / "isolated"
    home = work / "home"
    home.mkdir(parents=True)
    env = tl.clean_env(home, **tl.BOGUS_PYTHON)
    hidden = [*isolation.python_installations(), isolation.ROOT, *isolation.user_caches(home)]

    def wrap(cmd: list[str]) -> list[str]:
        return isolation.isolated(cmd, work, hidden, [])

    proc, rows = _host3(fmu, work, env, wrap)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert np.array_equal(rows, _fmi2_reference(built, tmp_path))


# ------------------------------------------------------------------------------------------------
# the command line
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "versions", "self_contained"),
    [
        ([], (2, 3), False),
        (["--fmi", "both"], (2, 3), False),
        (["--fmi", "2"], (2,), False),
        (["--fmi", "3"], (3,), False),
        (["--self-contained"], (2,), True),
        (["--self-contained", "--fmi", "3"], (3,), True),
    ],
)
def test_build_command_passes_the_fmi_versions(
    monkeypatch, tmp_path, argv, versions, self_contained
):
    seen: dict[str, Any] = {}

    def build(out: Any, gains: Any, *, self_contained: bool, fmi: tuple[int, ...]) -> dict:
        seen.update(self_contained=self_contained, fmi=fmi)
        return {}

    monkeypatch.setattr(export_cli, "build_fmus", build)
    assert export_cli.export_main(["--out", str(tmp_path / "out"), *argv]) == 0
    assert seen == {"self_contained": self_contained, "fmi": versions}


def test_build_refuses_unknown_fmi_versions(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        export_cli.export_main(["--out", str(tmp_path / "out"), "--fmi", "4"])
    assert exc.value.code == 2 and "invalid choice: '4'" in capsys.readouterr().err
    for bad in ((), (1,), (2, 4)):
        with pytest.raises(BuildError, match=r"FMI versions .*: choose from \(2, 3\)"):
            build_fmus(tmp_path / "none", tmp_path / "no-gains.json", fmi=bad)
    assert not (tmp_path / "none").exists()
