"""build_fmus.py and the modelDescription.xml of both FMUs (issue 5).

Checked against the FMI 2.0 standard (fmpy's validator) and against independent sources of truth:
the start values against the gains file, the reference set and a direct engine run; the
ModelStructure against the physics (the plant's outputs are states, the controller's output is
a static function of its inputs); determinism by rebuilding.
"""

from __future__ import annotations

import hashlib
import importlib.util
import re
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import fmu_testlib as tl
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from drillstring.model.engine import Engine, EngineOptions
from drillstring.model.params import REFERENCE


@pytest.fixture(scope="session")
def built(tmp_path_factory):
    return tl.built_fmus(tmp_path_factory)


@pytest.fixture(autouse=True)
def _sys_path():
    yield from tl.restore_sys_path()


def _units(built):
    return {"plant": built.plant, "controller": built.controller}


@pytest.mark.parametrize("which", ["plant", "controller"])
def test_validate_fmu_reports_zero_problems(built, which):
    problems = validate_fmu(str(_units(built)[which].fmu))
    assert problems == []


def test_capabilities_default_experiment_and_module_names(built):
    names = set()
    for unit in _units(built).values():
        md = read_model_description(str(unit.fmu))
        cs = md.coSimulation
        assert cs.modelIdentifier == unit.model
        assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
        assert not cs.canBeInstantiatedOnlyOncePerProcess
        de = md.defaultExperiment
        assert (float(de.startTime), float(de.stopTime), float(de.stepSize)) == (0.0, 20.0, 0.01)
        with zipfile.ZipFile(unit.fmu) as z:
            names.add(z.read("resources/slavemodule.txt").decode().strip())
            assert z.read("resources/requirements.txt").decode().split() == ["numpy>=2.0"]
            files = set(z.namelist())
        # the physics is bundled as a package, not written into the FMU script
        assert {
            "resources/drillstring/model/engine.py",
            "resources/drillstring/model/control.py",
        } <= files
        assert f"binaries/linux64/{unit.model}.so" in files
        assert not [f for f in files if "__pycache__" in f or f.endswith((".pyc", ".nbi"))]
    # both FMUs run in one interpreter: their Python modules need distinct names (pythonfmu #228)
    assert names == {"drillstring_plant", "torsional_controller"}


def test_every_variable_has_description_and_unit(built):
    for unit in _units(built).values():
        md = read_model_description(str(unit.fmu))
        assert [u.name for u in md.unitDefinitions] == ["1"]
        for v in md.modelVariables:
            assert v.description and len(v.description) > 10, v.name
            if v.type == "Real":
                assert v.unit == "1", v.name
            if v.causality in ("parameter", "input"):
                assert v.start is not None, v.name


def test_plant_outputs_exact_and_independent_of_input(built):
    md = read_model_description(str(built.plant.fmu))
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    assert [v.name for v in outputs] == [
        "u", "du", "phi", "dphi", "theta", "dtheta", "d", "g", "tau_n",
        "mode", "stick_events", "bit_bounce", "torsional_stick",
    ]  # fmt: skip
    assert all(v.initial == "exact" for v in outputs)
    # dependencies="" (no direct feedthrough), not absent (which would mean "all inputs")
    assert [u.variable.name for u in md.outputs] == [v.name for v in outputs]
    assert all(u.dependencies == [] for u in md.outputs)
    assert md.initialUnknowns == []


def test_controller_output_depends_on_its_four_inputs(built):
    md = read_model_description(str(built.controller.fmu))
    inputs = [v for v in md.modelVariables if v.causality == "input"]
    assert [v.name for v in inputs] == ["phi", "dphi", "theta", "dtheta"]
    (out,) = md.outputs
    assert out.variable.name == "R_minus_R0"
    assert out.dependencies == inputs
    assert out.dependenciesKind == ["dependent"] * 4
    assert [u.variable.name for u in md.initialUnknowns] == ["R_minus_R0"]


def _starts(unit):
    md = read_model_description(str(unit.fmu))
    return {v.name: v.start for v in md.modelVariables if v.start is not None}


def test_start_values_are_exact(built):
    plant = _starts(built.plant)
    fields = {"lambda": "lam"}
    for name in ("n", "psi", "gamma", "eta", "lambda", "beta", "rho", "v0", "omega0"):
        assert float(plant[name]) == float(getattr(REFERENCE, fields.get(name, name))), name
    assert float(plant["dphi0"]) == -2.5
    assert float(plant["h"]) == EngineOptions().h
    # exact outputs: the engine's own initial outputs, bit for bit (17 significant digits)
    eng = Engine(REFERENCE, options=EngineOptions(), initial={"dphi": -2.5})
    for name, value in eng.outputs().items():
        assert float(plant[name]) == value, name
    ctrl = _starts(built.controller)
    g = built.gains_values
    assert [float(ctrl[f"F[{i}]"]) for i in range(1, 5)] == g["F"]
    assert (float(ctrl["K0"]), float(ctrl["R_ff"])) == (g["K0"], g["R_ff"])
    assert ctrl["latch"] == "angle" and float(ctrl["t_on"]) == 0.0


def _xml(fmu: Path) -> bytes:
    with zipfile.ZipFile(fmu) as z:
        return z.read("modelDescription.xml")


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_rebuild_is_deterministic(built, tmp_path):
    pinned = {"SOURCE_DATE_EPOCH": "1700000000"}
    a, b = tmp_path / "a", tmp_path / "b"
    tl.run_build(a, built.gains, env=pinned)
    tl.run_build(b, built.gains, env=pinned)
    for model in (tl.PLANT, tl.CONTROLLER):
        fa, fb = a / f"{model}.fmu", b / f"{model}.fmu"
        assert _sha(fa) == _sha(fb), f"{model}.fmu differs between two pinned builds"
        assert b'generationDateAndTime="2023-11-14T22:13:20Z"' in _xml(fa)
        # the session build (build time not pinned) differs only in generationDateAndTime
        strip = re.compile(rb' generationDateAndTime="[^"]*"')
        assert strip.sub(b"", _xml(fa)) == strip.sub(b"", _xml(built.out / f"{model}.fmu"))
    guids = {read_model_description(str(a / f"{m}.fmu")).guid for m in (tl.PLANT, tl.CONTROLLER)}
    assert len(guids) == 2


def _build_module():
    spec = importlib.util.spec_from_file_location(
        "build_fmus_under_test", tl.ROOT / "build_fmus.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_validation_failure_fails_the_build(built, tmp_path):
    bf = _build_module()
    broken = tmp_path / f"{tl.PLANT}.fmu"
    with zipfile.ZipFile(built.plant.fmu) as z:
        entries = {n: z.read(n) for n in z.namelist()}
    root = ET.fromstring(entries["modelDescription.xml"])
    outputs = root.find("ModelStructure/Outputs")
    outputs.remove(outputs[0])  # an output missing from ModelStructure: invalid FMI 2.0
    entries["modelDescription.xml"] = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
    with zipfile.ZipFile(broken, "w") as z:
        for name, data in entries.items():
            z.writestr(name, data)
    with pytest.raises(
        bf.BuildError, match=r"(?s)validate_fmu reports 1 problem.*ModelStructure/Outputs"
    ):
        bf.validate(broken)
    bf.validate(built.plant.fmu)  # the real one passes


def test_bad_gains_file_fails_loudly(tmp_path):
    bad = tmp_path / "gains.json"
    bad.write_text('{"F": [1, 2, 3, 4], "K0": 0.1, "R_ff": -0.1}\n')
    with pytest.raises(AssertionError, match=r"(?s)failed \(1\).*missing key"):
        tl.run_build(tmp_path / "out", bad)
    assert not (tmp_path / "out").exists()  # nothing built


def test_missing_gains_file_runs_the_synthesis(tmp_path):
    gains = tmp_path / "designed" / "gains.json"
    proc = tl.run_build(tmp_path / "out", gains)
    assert "designing the controller" in proc.stderr
    from drillstring.controller.gains import read_gains

    designed = read_gains(gains)  # a valid gains file, and the FMU's start values are its gains
    md = read_model_description(str(tmp_path / "out" / f"{tl.CONTROLLER}.fmu"))
    starts = {v.name: float(v.start) for v in md.modelVariables if v.type == "Real" and v.start}
    assert [starts[f"F[{i}]"] for i in range(1, 5)] == list(designed.F)
    assert (starts["K0"], starts["R_ff"]) == (designed.K0, designed.R_ff)
