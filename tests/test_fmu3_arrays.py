"""The along-string profile as array outputs of the FMI 3.0 plant twins (``docs/fmus.md``, "The
FMI 3.0 twins", "Array outputs").

On 16 elements, in fmpy's low-level ``fmpy.fmi3`` API: the scaled twin's arrays are the
engine's profile (:func:`~drillstring.model.engine.string_profiles` of the engine stepped as the
FMU steps) bit for bit, on the native fast path and on the Python path; the SI twin's are that
profile in SI units (the conversions of ``docs/si_fmus.md``: torque C (R0/C + T), speed
(omega0 + dphi)/t*). The array length is the structural parameter ``string_elements``, set in
Configuration Mode; a wrong ``nValues`` is ``fmi3Error``; the FMI 2.0 plants declare no arrays.
The refusals are rows of the FMI 3.0 conformance table (``tests/test_fmu3.py``); fmpy's rules,
the FMI 3.0 schema and ``fmutool -check`` run on the twins in ``tests/test_fmu_checkers.py``.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import fmu_testlib as tl
import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi3 import FMU3Slave

from drillstring.model.engine import Engine, EngineOptions, string_profiles
from drillstring.model.experiments import FIG5
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.pipe import REFERENCE_KAPPA, StringParams
from drillstring.model.units import SIScaling

pytestmark = pytest.mark.fmu

N = 16
H = 0.01
STEPS = 300  # tau in [0, 3]: the torque pulse below sends a wave along the string
ARRAYS = {
    tl.PLANT: ("element_torque_minus_R0", "node_dphi"),
    tl.PLANT_SI: ("element_torque", "node_speed"),
}


def _torque(k: int) -> float:
    return 0.3 if 50 <= k < 150 else 0.0  # a torque pulse at the table (scaled R - R0)


def _engine_profile() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The monolithic engine stepped as the FMU steps: tau, each element's torque less R0 and
    the speed perturbations of the nodes x = i/N, i = 1..N, after each step."""
    eng = Engine(
        REFERENCE,
        options=EngineOptions(keep_events=False),
        initial=FIG5.initial(),
        string=StringParams(elements=N, kappa=REFERENCE_KAPPA),
    )
    data: dict[str, list[float]] = {
        k: [] for k in ("tau", "u", "du", "phi", "dphi", "theta", "dtheta")
    }
    nodes = []
    for k in range(STEPS):
        eng.set_input(_torque(k))
        assert eng.advance(k * H + H).ok
        out = eng.outputs()
        for key, column in data.items():
            column.append(eng.tau if key == "tau" else out[key])
        nodes.append(eng.string_nodes())
    columns = {k: np.array(v) for k, v in data.items()}
    profile = string_profiles(eng.params, eng.string, columns, np.array(nodes))
    return columns["tau"], profile["torque_minus_R0"], profile["dphi_node"][:, 1:]


def _twin(built: tl.Built, model: str) -> Path:
    return built.out / f"{model}3.fmu"


class _Twin:
    """An FMI 3.0 plant twin in fmpy's low-level API, on ``N`` elements."""

    def __init__(self, fmu: Path, folder: Path, name: str, **parameters: float) -> None:
        md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.s = FMU3Slave(
            guid=md.guid,
            unzipDirectory=extract(str(fmu), str(folder)),
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.s.instantiate()
        self.s.enterConfigurationMode()
        self.s.setInt32([self.vr["string_elements"]], [N])
        self.s.exitConfigurationMode()
        for key, value in parameters.items():
            self.s.setFloat64([self.vr[key]], [value])
        self.s.enterInitializationMode(startTime=0.0)
        self.s.exitInitializationMode()

    def get(self, *names: str, n_values: int) -> np.ndarray:
        return np.array(self.s.getFloat64([self.vr[n] for n in names], nValues=n_values))

    def free(self) -> None:
        self.s.terminate()
        self.s.freeInstance()


def test_the_scaled_twin_outputs_the_engine_profile_bit_for_bit(built, tmp_path, monkeypatch):
    _, torque, speed = _engine_profile()
    assert np.ptp(torque[:, 0]) > 1e-2 and np.ptp(speed[:, N // 2]) > 1e-3  # a moving profile
    for path in ("native", "python"):
        monkeypatch.setenv("DRILLSTRING_FMU_NATIVE", "1" if path == "native" else "0")
        twin = _Twin(
            _twin(built, tl.PLANT), tmp_path / path, path, pipe_inertia_ratio=REFERENCE_KAPPA
        )
        try:
            got_t, got_s, scalars = [], [], []
            for k in range(STEPS):
                twin.s.setFloat64([twin.vr["R_minus_R0"]], [_torque(k)])
                twin.s.doStep(k * H, H)
                # both arrays and two scalars in one call: the arrays' elements in order
                row = twin.get(
                    "element_torque_minus_R0",
                    "top_torque_minus_R0",
                    "node_dphi",
                    "dphi",
                    n_values=2 * N + 2,
                )
                got_t.append(row[:N])
                got_s.append(row[N + 1 : 2 * N + 1])
                scalars.append(row[[N, 2 * N + 1]])
            assert np.array_equal(np.array(got_t), torque), path
            assert np.array_equal(np.array(got_s), speed), path
            # the top element is top_torque_minus_R0, the last node the bit
            ends = np.array(scalars)
            assert np.array_equal(ends[:, 0], torque[:, 0]) and np.array_equal(
                ends[:, 1], speed[:, -1]
            )
            for wrong in (N - 1, N + 1):
                with pytest.raises(Exception, match="status 3"):
                    twin.get("node_dphi", n_values=wrong)
            assert twin.get("node_dphi", n_values=N).size == N  # the instance goes on
        finally:
            twin.free()


def test_the_si_twin_outputs_the_profile_in_si(built, tmp_path):
    tau, torque, speed = _engine_profile()
    sc = SIScaling(REFERENCE_RIG)
    h_si = H * sc.t_star
    twin = _Twin(
        _twin(built, tl.PLANT_SI), tmp_path, "si", I_pipe=REFERENCE_KAPPA * REFERENCE_RIG.I1
    )
    try:
        got_t, got_s, ends = [], [], []
        for k in range(STEPS):
            twin.s.setFloat64([twin.vr["table_torque"]], [sc.C * (sc.twist0 + _torque(k))])
            twin.s.doStep(k * h_si, h_si)
            got_t.append(twin.get("element_torque", n_values=N))
            got_s.append(twin.get("node_speed", n_values=N))
            ends.append(twin.get("top_torque", "bit_speed", n_values=2))
    finally:
        twin.free()
    got_t, got_s, ends = np.array(got_t), np.array(got_s), np.array(ends)
    # the SI twin integrates the rig's scaled set, REFERENCE to rounding
    np.testing.assert_allclose(got_t, sc.C * (sc.twist0 + torque), rtol=1e-9)
    np.testing.assert_allclose(got_s, (sc.scaled.omega0 + speed) / sc.t_star, rtol=1e-9)
    assert np.array_equal(ends[:, 0], got_t[:, 0]) and np.array_equal(ends[:, 1], got_s[:, -1])
    assert tau[-1] == pytest.approx(STEPS * H)


@pytest.mark.parametrize("model", ARRAYS)
def test_only_the_fmi3_twin_declares_the_arrays(built, model):
    def variables(fmu: Path) -> dict[str, ET.Element]:
        with zipfile.ZipFile(fmu) as z:
            root = ET.fromstring(z.read("modelDescription.xml"))
        return {v.get("name"): v for v in root.find("ModelVariables")}

    fmi2, fmi3 = variables(built.out / f"{model}.fmu"), variables(_twin(built, model))
    assert not set(ARRAYS[model]) & set(fmi2)
    assert fmi2["string_elements"].get("causality") == "parameter"
    size = fmi3["string_elements"]
    assert (size.get("causality"), size.get("variability")) == ("structuralParameter", "fixed")
    for name in ARRAYS[model]:
        v = fmi3[name]
        assert (v.tag, v.get("causality")) == ("Float64", "output")
        (dim,) = v.findall("Dimension")
        assert dim.get("valueReference") == size.get("valueReference") and dim.get("start") is None
