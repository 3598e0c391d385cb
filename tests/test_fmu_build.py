"""build_fmus.py and the modelDescription.xml of the FMUs (plant, LMI and top-drive controller).

Checked against the FMI 2.0 standard (fmpy's validator) and against independent sources of truth:
the start values against the gains file and the reference set, the computed outputs against a
direct engine run, the declared ranges against the model's own validators, the ModelStructure
against the physics (the plant's outputs are states, the controller's output is a static function
of its inputs); the archive's content (front layer, pythonfmu's library, documentation, linux64
only); determinism by rebuilding.
"""

from __future__ import annotations

import hashlib
import importlib.util
import math
import re
import shutil
import subprocess
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


def _units(built):
    return {"plant": built.plant, "controller": built.controller, "topdrive": built.topdrive}


@pytest.mark.parametrize("which", ["plant", "controller", "topdrive"])
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
            entry = z.read("resources/slavemodule.txt").decode().strip()
            text = z.read(f"resources/{entry}.py").decode()
            (script,) = re.findall(r"^import (\w+)$", text, flags=re.M)
            names.add(script)
            # the slave class under the attribute "" and no class bound when pythonfmu executes
            # it (build_fmus.entry_module: pythonfmu 0.7.0 leaks per class it finds there)
            assert f'globals()[""] = {script}.{unit.model}' in text
            assert not re.search(r"^(class|from) ", text, flags=re.M)
            assert z.read("resources/requirements.txt").decode().split() == ["numpy>=2.0"]
            files = set(z.namelist())
        # the physics is bundled as a package, not written into the FMU script
        assert {
            "resources/drillstring/model/engine.py",
            "resources/drillstring/model/control.py",
            "resources/drillstring_fmu_support.py",
            "resources/drillstring_fmu_boot.py",
            "documentation/index.html",
        } <= files
        # only the platform that is built and tested: the front layer and pythonfmu's library
        binaries = sorted(f for f in files if f.startswith("binaries/"))
        assert binaries == [
            f"binaries/linux64/{unit.model}.so",
            f"binaries/linux64/{unit.model}_pythonfmu.so",
        ]
        assert not [f for f in files if "__pycache__" in f or f.endswith((".pyc", ".nbi"))]
    # both FMUs run in one interpreter: their Python modules need distinct names (pythonfmu imports
    # each FMU's script by its module name into the one shared interpreter)
    assert names == {"drillstring_plant", "torsional_controller", "topdrive_controller"}


def test_front_layer_is_not_linked_to_python(built, tmp_path):
    """The layer must load in a process without libpython: it resolves Python's C API at run
    time. Its exports are the FMI 2.0 functions only."""
    nm = shutil.which("nm")
    assert nm is not None
    for unit in _units(built).values():
        lib = unit.unzipped / "binaries" / "linux64" / f"{unit.model}.so"
        undefined = subprocess.run(
            [nm, "-D", "--undefined-only", str(lib)], capture_output=True, text=True, check=True
        ).stdout.split()
        assert not [s for s in undefined if s.startswith(("Py", "_Py"))], undefined
        exported = subprocess.run(
            [nm, "-D", "--defined-only", str(lib)], capture_output=True, text=True, check=True
        ).stdout.split()
        symbols = {s for s in exported if s.startswith("fmi2")}
        assert len(symbols) == 34 and "fmi2DoStep" in symbols and "fmi2Instantiate" in symbols
        # and the lock all copies of the layer in a process share (a unique symbol)
        others = [s for s in exported[2::3] if not s.startswith(("fmi2", "_"))]
        assert others == ["drillstring_fmi2_process_lock"], exported
        assert "u drillstring_fmi2_process_lock" in " ".join(exported)


#: The largest stack frame any function of the front layer may have: a host may call the FMI
#: functions from a worker thread with a small stack (tests/test_fmu_lifecycle.py runs one).
MAX_FRAME = 4096


def test_front_layer_frames_are_small(built, tmp_path):
    """GCC's -fstack-usage for every function of the layer: a static frame below MAX_FRAME bytes
    (paths and messages live on the heap; the interpreter's record once held 64 KiB of paths on
    the stack, fmi2Instantiate needed a 107 KB frame)."""
    bf = _build_module()
    with zipfile.ZipFile(built.plant.fmu) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
        entry = z.read("resources/slavemodule.txt").decode().strip()
    work = tmp_path / "layer"
    out = tmp_path / "layer.so"
    include = bf.python_record()["include"]
    bf.compile_front_layer(bf.model_header(root, entry), out, include, work, ("-fstack-usage",))
    rows = [
        line.split("\t")
        for su in sorted(tmp_path.rglob("*.su"))
        for line in su.read_text().splitlines()
    ]
    names = {row[0].rsplit(":", 1)[-1] for row in rows}
    assert {"fmi2Instantiate", "ds_python_instantiate", "ds_logf", "fmi2DoStep"} <= names
    big = [(f, int(n), kind) for f, n, kind in rows if int(n) >= MAX_FRAME]
    unbounded = [(f, kind) for f, _, kind in rows if "dynamic" in kind and "bounded" not in kind]
    assert not big, big
    assert not unbounded, unbounded


def test_python_record_names_this_interpreter(built):
    import sysconfig

    for unit in _units(built).values():
        text = (unit.unzipped / "resources" / "drillstring_fmu_python.cfg").read_text()
        rec = dict(line.split(" ", 1) for line in text.splitlines() if not line.startswith("#"))
        assert rec["version"] == f"{sys.version_info.major}.{sys.version_info.minor}"
        assert Path(rec["libpython"]).resolve() == tl.libpython().resolve()
        assert rec["home"] == sys.base_prefix
        assert rec["site"] == sysconfig.get_paths()["purelib"]
        for var in ("DRILLSTRING_FMU_LIBPYTHON", "DRILLSTRING_FMU_PYTHONHOME"):
            assert var in text


def test_documentation_says_what_a_host_needs(built):
    for unit in _units(built).values():
        doc = (unit.unzipped / "documentation" / "index.html").read_text()
        for needed in (
            "Time base and units",
            "start time must be 0",
            "Validity of the model",
            "What the host needs",
            "DRILLSTRING_FMU_LIBPYTHON",
            "DRILLSTRING_FMU_PYTHONHOME",
            "DRILLSTRING_FMU_SITE_PACKAGES",
            "DRILLSTRING_FMU_CACHE",
            "DRILLSTRING_JIT=0",
        ):
            assert needed in doc, (unit.model, needed)
        md = read_model_description(str(unit.fmu))
        for v in md.modelVariables:
            assert f"<code>{v.name}</code>" in doc
    plant = (built.plant.unzipped / "documentation" / "index.html").read_text()
    assert "bit bouncing" in plant and "dphi0 &gt; -omega0" in plant


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


def test_outputs_are_calculated_initial_unknowns(built):
    for unit in _units(built).values():
        md = read_model_description(str(unit.fmu))
        outputs = [v for v in md.modelVariables if v.causality == "output"]
        assert outputs and all(v.initial == "calculated" and v.start is None for v in outputs)
        assert [u.variable.name for u in md.initialUnknowns] == [v.name for v in outputs]
        assert all(u.dependencies is None for u in md.initialUnknowns)  # on all knowns


def test_plant_outputs_independent_of_input(built):
    md = read_model_description(str(built.plant.fmu))
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    assert [v.name for v in outputs] == [
        "u", "du", "phi", "dphi", "theta", "dtheta", "d", "g", "tau_n",
        "mode", "stick_events", "bit_bounce", "torsional_stick",
    ]  # fmt: skip
    # dependencies="" (no direct feedthrough), not absent (which would mean "all inputs")
    assert [u.variable.name for u in md.outputs] == [v.name for v in outputs]
    assert all(u.dependencies == [] for u in md.outputs)


def test_controller_output_depends_on_its_four_inputs(built):
    md = read_model_description(str(built.controller.fmu))
    inputs = [v for v in md.modelVariables if v.causality == "input"]
    assert [v.name for v in inputs] == ["phi", "dphi", "theta", "dtheta"]
    (out,) = md.outputs
    assert out.variable.name == "R_minus_R0"
    assert out.dependencies == inputs
    assert out.dependenciesKind == ["dependent"] * 4


def test_enumerations_of_on_invalid_and_latch(built):
    from drillstring.model.control import LATCH_MODES

    for unit, name, type_name, items in (
        (built.plant, "on_invalid", "OnInvalid", ("stop", "continue")),
        (built.controller, "latch", "Latch", LATCH_MODES),
    ):
        md = read_model_description(str(unit.fmu))
        var = next(v for v in md.modelVariables if v.name == name)
        assert var.type == "Enumeration" and var.declaredType.name == type_name
        assert [(i.name, int(i.value)) for i in var.declaredType.items] == [
            (n, k + 1) for k, n in enumerate(items)
        ]
        start = {"on_invalid": "stop", "latch": "angle"}[name]
        assert int(var.start) == items.index(start) + 1


def _ranges(unit):
    md = read_model_description(str(unit.fmu))
    return {
        v.name: (v.type, v.min, v.max)
        for v in md.modelVariables
        if v.min is not None or v.max is not None
    }


def test_declared_ranges_are_the_validators(built):
    """Every parameter with a range declares it, and the model's own validator agrees at both
    ends: the bound itself is accepted, the next representable value outside is refused."""
    from drillstring.model.engine import EngineOptions
    from drillstring.model.params import ScaledParams

    ranges = _ranges(built.plant)
    assert set(ranges) == {
        "n", "psi", "gamma", "eta", "lambda", "beta", "rho", "v0", "omega0", "h", "event_tol",
    }  # fmt: skip
    fields = {"lambda": "lam"}

    def accepted(name, value):
        try:
            if name in ("h", "event_tol"):
                EngineOptions(**{name: value})
            else:
                ScaledParams(**{**REFERENCE.__dict__, fields.get(name, name): value})
        except ValueError:
            return False
        return True

    for name, (kind, lo, hi) in ranges.items():
        for bound, outward in ((lo, -math.inf), (hi, math.inf)):
            if bound is None:
                continue
            x = int(bound) if kind == "Integer" else float(bound)
            beyond = (
                x + (1 if outward > 0 else -1) if kind == "Integer" else math.nextafter(x, outward)
            )
            assert accepted(name, x), (name, x)
            assert not accepted(name, beyond), (name, beyond)
    assert _ranges(built.controller) == {}  # gains and t_on: any finite number


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
    ctrl = _starts(built.controller)
    g = built.gains_values
    assert [float(ctrl[f"F[{i}]"]) for i in range(1, 5)] == g["F"]
    assert (float(ctrl["K0"]), float(ctrl["R_ff"])) == (g["K0"], g["R_ff"])
    assert int(ctrl["latch"]) == 2 and float(ctrl["t_on"]) == 0.0


def test_calculated_outputs_at_initialization_are_the_engines(built):
    """Read in initialization mode, bit for bit the engine's initial outputs."""
    s = tl.Slave(built.plant, "init_outputs")
    try:
        s.fmu.setupExperiment(startTime=0.0)
        s.fmu.enterInitializationMode()
        eng = Engine(REFERENCE, options=EngineOptions(), initial={"dphi": -2.5})
        for name, value in eng.outputs().items():
            assert s.get(name)[0] == value, name
    finally:
        s.free()


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
    models = (tl.PLANT, tl.CONTROLLER, tl.PLANT_SI, tl.CONTROLLER_SI, tl.TOPDRIVE, tl.TOPDRIVE_SI)
    for model in models:
        fa, fb = a / f"{model}.fmu", b / f"{model}.fmu"
        assert _sha(fa) == _sha(fb), f"{model}.fmu differs between two pinned builds"
        assert b'generationDateAndTime="2023-11-14T22:13:20Z"' in _xml(fa)
        # the session build (build time not pinned) differs only in generationDateAndTime
        strip = re.compile(rb' generationDateAndTime="[^"]*"')
        assert strip.sub(b"", _xml(fa)) == strip.sub(b"", _xml(built.out / f"{model}.fmu"))
    for package in (
        "DrillStringClosedLoop.ssp",
        "DrillStringClosedLoopSI.ssp",
        "DrillStringTopDrive.ssp",
        "DrillStringTopDriveSI.ssp",
    ):
        assert _sha(a / package) == _sha(b / package), f"{package} differs between two builds"
    guids = {read_model_description(str(a / f"{m}.fmu")).guid for m in models}
    assert len(guids) == len(models)


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
    with pytest.raises(bf.BuildError, match=r"(?s)validate_fmu reports \d+ problem.*Outputs"):
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


def test_missing_compiler_fails_the_build_with_the_reason(tmp_path, monkeypatch):
    bf = _build_module()
    monkeypatch.setenv("PATH", str(tmp_path))  # no cc, gcc or clang there
    monkeypatch.delenv("CC", raising=False)
    with pytest.raises(bf.BuildError, match=r"no C compiler found .*install one"):
        bf.find_compiler()
    monkeypatch.setenv("CC", "no-such-compiler")
    with pytest.raises(bf.BuildError, match=r"CC='no-such-compiler': no-such-compiler not found"):
        bf.find_compiler()
