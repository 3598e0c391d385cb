"""The plant FMU on the distributed string (``docs/model.md``, "The distributed string").

The FMU on 16 elements against the engine stepped the same way (bit for bit, on the native and
the Python path) and the SI FMU's pipe against the scaled one's; the refusals of the string's
parameters are rows P20-P21 of the conformance table (``tests/test_fmu_conformance.py``).
"""

from __future__ import annotations

import fmu_testlib as tl
import numpy as np
import pytest

from drillstring.model.engine import Engine, EngineOptions
from drillstring.model.experiments import FIG5
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.pipe import REFERENCE_KAPPA, StringParams
from drillstring.model.units import SIScaling
from drillstring.orchestration.ssp import read_ssp

pytestmark = pytest.mark.fmu
OK, ERROR = tl.OK, tl.ERROR

N = 16
H = 0.01
STEPS = 600  # tau in [0, 6]: the torque steps below send waves along the string


def _torque(k: int, pulse: bool = True) -> float:
    return 0.3 if pulse and 100 <= k < 300 else 0.0  # a torque pulse at the table


def _engine_run(pulse: bool = True) -> np.ndarray:
    eng = Engine(
        REFERENCE,
        options=EngineOptions(keep_events=False),
        initial=FIG5.initial(),
        string=StringParams(elements=N, kappa=REFERENCE_KAPPA),
    )
    rows = []
    for k in range(STEPS):
        eng.set_input(_torque(k, pulse))
        assert eng.advance(k * H + H).ok  # the FMU steps to t + h with t = k*H
        rows.append(list(eng.outputs().values()))
    return np.array(rows)


def _fmu_run(built: tl.Built, name: str) -> tuple[np.ndarray, list[str]]:
    s = tl.Slave(built.plant, name)
    try:
        s.init(string_elements=N, pipe_inertia_ratio=REFERENCE_KAPPA)
        names = [n for n, c in s.unit.causality.items() if c == "output"]
        rows = []
        for k in range(STEPS):
            s.set(R_minus_R0=_torque(k))
            assert s.step(k * H, H) == OK
            rows.append([float(v) for v in s.get(*names)])
        return np.array(rows), names
    finally:
        s.free()


def test_the_plant_on_sixteen_elements_is_the_engine_bit_for_bit(built, monkeypatch):
    ref = _engine_run()
    keys = list(Engine(REFERENCE).outputs())
    for path in ("native", "python"):
        # the front layer's native fast path, or every step through Python
        monkeypatch.setenv("DRILLSTRING_FMU_NATIVE", "1" if path == "native" else "0")
        got, names = _fmu_run(built, f"string_{path}")
        for j, name in enumerate(names):
            assert np.array_equal(got[:, j], ref[:, keys.index(name)]), (path, name)
    # the pulse reaches the top of the string at once and the bit only after the wave's travel
    # time sqrt(kappa) = 1.37 (137 steps): over the first 100 steps the bit has not felt it
    quiet = _engine_run(pulse=False)
    top, bit = keys.index("top_torque_minus_R0"), keys.index("dphi")
    d_top = np.max(np.abs(ref[100:200, top] - quiet[100:200, top]))
    d_bit = np.max(np.abs(ref[100:200, bit] - quiet[100:200, bit]))
    assert d_top > 1e-2 and d_bit < 1e-3 * d_top, (d_top, d_bit)


def test_the_si_plant_takes_the_pipe_in_si(built):
    sc = SIScaling(REFERENCE_RIG)
    scaled = tl.Slave(built.plant, "string_scaled")
    si = tl.Slave(built.si.plant, "string_si")
    try:
        scaled.init(string_elements=N, pipe_inertia_ratio=REFERENCE_KAPPA)
        si.init(string_elements=N, I_pipe=REFERENCE_KAPPA * REFERENCE_RIG.I1)
        h_si = H * sc.t_star
        for k in range(200):
            assert scaled.step(k * H, H) == OK
            assert si.step(k * h_si, h_si) == OK
        (top,) = scaled.get("top_torque_minus_R0")
        (top_si,) = si.get("top_torque")
        assert top_si == pytest.approx(REFERENCE_RIG.C * (REFERENCE.R0 + top), rel=1e-9)
        assert top != 0.0  # the string is twisting: a real comparison
    finally:
        scaled.free()
        si.free()


def test_the_top_drive_packages_carry_a_string_variant(built):
    # one SSD of each top-drive package runs Fig. 6 on 16 elements (SoftSpeed switched on); the
    # cross-host test of tests/test_ssp.py runs it in the master, Ecos and libcosim
    for ssp in (built.topdrive_ssp, built.si.topdrive_ssp):
        p = read_ssp(ssp, unpack=False, variant="fig6-soft-speed-string")
        plant = p.parameters()["plant"]
        assert plant["string_elements"].value == 16
        default = read_ssp(ssp, unpack=False).parameters()["plant"]
        assert default["string_elements"].value == 1  # the other SSDs: the paper's string
