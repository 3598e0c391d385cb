"""The SI FMUs (DrillStringPlantSI, TorsionalControllerSI) against the scaled ones.

* model descriptions: FMI 2.0 valid, every Real with its unit, the units' base-unit exponents
  and display units those of drillstring.model.units, the physical parameters' start values the
  reference rig and their declared ranges its validators;
* the SI plant driven with the torque sequence of the Fig. 5 closed loop equals the scaled plant
  driven with the same torque, converted (the same engine: both get the same scaled inputs and
  engine times, so only the conversions of the outputs differ) -- to 1e-12 relative, every
  output; the torque on bit also against eqs. (4) and (7) of the rig at the SI depth of cut;
* the SI closed loop of Fig. 5 equals the scaled closed loop, converted;
* the SI controller's output is the scaled law converted (units.PhysicalFeedback).

"Relative" is max |a - b| over the run divided by max |b| of the scaled signal converted.
"""

from __future__ import annotations

import dataclasses
import math
import re
import zipfile

import fmu_testlib as tl
import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from drillstring.model.experiments import FIG5
from drillstring.model.params import REFERENCE_RIG, ParameterError
from drillstring.model.units import PLANT_SI, UNITS, SIScaling
from drillstring.orchestration.closed_loop import SCALED, SI, closed_loop_master, kept_sys_path

SC = SIScaling(REFERENCE_RIG)
H = 0.01  # macro step of the Fig. 5 runs (scaled time); in SI H t*
SI_REALS = tuple(q.name for q in PLANT_SI)
INTS = ("mode", "stick_events", "bit_bounce", "torsional_stick")
#: the plant's SI outputs that the torsional part of the loop determines
TORSIONAL = ("bit_angle", "bit_speed", "table_angle", "table_speed", "delay")


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


# ------------------------------------------------------------------------------------------------
# model descriptions
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("which", ["plant", "controller"])
def test_si_fmus_are_valid_with_units_and_display_units(built, which):
    unit = getattr(built.si, which)
    assert validate_fmu(str(unit.fmu)) == []
    md = read_model_description(str(unit.fmu))
    assert md.coSimulation.modelIdentifier == unit.model
    defined = {u.name: u for u in md.unitDefinitions}
    for name, u in defined.items():
        ours = UNITS[name]
        base = {k: getattr(u.baseUnit, k) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")}
        assert base == {k: ours.exponents.get(k, 0) for k in base}, name
        for d in u.displayUnits:
            assert float(d.factor) == ours.display_unit(d.name).factor
    for v in md.modelVariables:
        if v.type == "Real":
            assert v.unit in defined, v.name
            if v.displayUnit is not None:
                assert v.displayUnit in {d.name for d in defined[v.unit].displayUnits}
    with zipfile.ZipFile(unit.fmu) as z:
        entry = z.read("resources/slavemodule.txt").decode().strip()
        module = re.findall(r"^import (\w+)$", z.read(f"resources/{entry}.py").decode(), re.M)[0]
        # the thin SI script and the scaled script it derives from are both bundled
        files = set(z.namelist())
    assert module.endswith("_si") and f"resources/{module}.py" in files
    assert f"resources/{module[:-3]}.py" in files


def test_si_plant_parameters_are_the_reference_rig_with_its_ranges(built):
    md = read_model_description(str(built.si.plant.fmu))
    v = {x.name: x for x in md.modelVariables}
    units = {"M": "kg", "I1": "kg.m2", "C": "N.m/rad", "V0": "m/s", "Omega0": "rad/s", "a": "m"}
    for name, value in REFERENCE_RIG.to_dict().items():
        assert float(v[name].start) == value, name
        if name in units:
            assert v[name].unit == units[name]
        lo = float(v[name].min) if v[name].min is not None else None
        assert lo is not None, name
        # the declared minimum is the validator's: accepted at it, rejected just below
        if lo > 0.0:
            with pytest.raises(ParameterError):
                dataclasses.replace(REFERENCE_RIG, **{name: 0.0 if name != "n" else 0})
        else:
            dataclasses.replace(REFERENCE_RIG, **{name: 0.0})
            with pytest.raises(ParameterError):
                dataclasses.replace(REFERENCE_RIG, **{name: -1e-300})
    assert v["V0"].displayUnit == "m/h" and v["Omega0"].displayUnit == "rpm"
    assert float(v["dphi0"].start) == pytest.approx(FIG5.dphi0 / REFERENCE_RIG.t_star, rel=1e-15)
    assert float(v["table_torque"].start) == pytest.approx(REFERENCE_RIG.R0, rel=1e-14)
    assert float(v["h"].start) == pytest.approx(5e-4 * REFERENCE_RIG.t_star, rel=1e-15)


def test_si_controller_gains_are_the_gains_file_converted(built):
    md = read_model_description(str(built.si.controller.fmu))
    v = {x.name: float(x.start) for x in md.modelVariables if x.type == "Real" and x.start}
    g = built.gains_values
    C, ts = REFERENCE_RIG.C, REFERENCE_RIG.t_star
    assert v["F[1]"] == pytest.approx(C * g["F"][0], rel=1e-15)
    assert v["F[2]"] == pytest.approx(C * ts * g["F"][1], rel=1e-15)
    assert v["F[3]"] == pytest.approx(C * g["F"][2], rel=1e-15)
    assert v["F[4]"] == pytest.approx(C * ts * g["F"][3], rel=1e-15)
    assert v["K0"] == pytest.approx(g["K0"] - REFERENCE_RIG.R0 / C, rel=1e-14)
    assert v["R_ff"] == pytest.approx(REFERENCE_RIG.R0 + C * g["R_ff"], rel=1e-14)
    assert v["Omega0"] == REFERENCE_RIG.Omega0


# ------------------------------------------------------------------------------------------------
# the plant: same engine, same numbers
# ------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def fig5_torque(built):
    """The scaled torque sequence R - R0 of the Fig. 5 closed loop (macro step H)."""
    with kept_sys_path(), closed_loop_master(built.out, FIG5) as m:
        res = m.run(FIG5.tau_end, H, progress=False)
    assert res.completed
    return np.asarray(res["plant.R_minus_R0"][:-1])  # the input of each step


def test_si_plant_equals_scaled_plant_converted_on_fig5(built, fig5_torque):
    """Same engine arithmetic: the SI plant on the grid t_k = k H t* computes the engine times
    t_k/t* and the torques R_k/C - R0/C; the scaled plant is given exactly those, and the
    reference rig's scaled set, initial state and RK4 step as the SI plant converts them."""
    n = len(fig5_torque)
    t = np.arange(n + 1) * (H * SC.t_star)
    taus = t / SC.t_star
    R = SC.table_torque(fig5_torque)
    r = SC.torque_deviation(R)
    init = SC.initial_to_scaled(SC.initial_to_si(FIG5.initial()))
    scaled_starts = {
        **SC.scaled.to_dict(),
        "dphi0": init.dphi,
        "h": SC.tau(SC.time(FIG5.h)),
        "event_tol": SC.tau(SC.time(1e-13)),
    }
    si = tl.Slave(built.si.plant, "si_fig5").init()
    sc = tl.Slave(built.plant, "scaled_fig5").init(**scaled_starts)
    got, ref = [], []
    try:
        for k in range(n):
            si.set(table_torque=float(R[k]))
            assert si.step(t[k], t[k + 1] - t[k]) == tl.OK, si.logs
            got.append(si.get(*SI_REALS, *INTS))
            sc.set(R_minus_R0=float(r[k]))
            assert sc.step(taus[k], taus[k + 1] - taus[k]) == tl.OK, sc.logs
            ref.append(sc.get(*tl.RECORD_PLANT, *INTS))
    finally:
        si.free()
        sc.free()
    got, ref = np.array(got), np.array(ref)
    scaled = dict(zip(tl.RECORD_PLANT + INTS, ref.T, strict=True))
    converted = SC.plant_outputs(scaled, taus[1:])
    worst = {}
    for j, name in enumerate(SI_REALS):
        worst[name] = _rel(got[:, j], converted[name])
    print("SI plant vs scaled plant converted, Fig. 5:", {k: f"{v:.1e}" for k, v in worst.items()})
    assert max(worst.values()) <= 1e-12, worst
    assert np.array_equal(got[:, len(SI_REALS) :], ref[:, len(tl.RECORD_PLANT) :])  # counters
    assert got[-1, len(SI_REALS) + 1] >= 10  # a run with axial stick-slip events
    # torque on bit: the kernel's T times C against eqs. (4) and (7) at the SI depth of cut
    d, g = got[:, SI_REALS.index("depth_of_cut")], got[:, SI_REALS.index("contact")]
    assert _rel(got[:, SI_REALS.index("torque_on_bit")], REFERENCE_RIG.torque_on_bit(d, g)) < 1e-12


# ------------------------------------------------------------------------------------------------
# the closed loop
# ------------------------------------------------------------------------------------------------


def test_si_closed_loop_equals_scaled_closed_loop_on_fig5(built):
    """Fig. 5 as two closed loops with the same coupling (macro step H, H t* in SI), the
    scaled FMUs on the reference rig's scaled set, the SI FMUs with their defaults.

    The loop's own signals -- angles, speeds, delay and the table torque -- agree to 1e-12. The
    axial signals agree to 5e-11 (measured 1.5e-11 in the contact multiplier, 1.3e-11 in the axial
    velocity): the controllers compute the same torque in other arithmetic (errors from Omega0 t
    in seconds, not perturbations in tau; 5e-13 relative), and the axial stick-slip events turn
    a difference of that size into this one. With identical engine inputs the plant agrees to
    1e-15 (the test above)."""
    starts = {"plant": {**SC.scaled.to_dict(), "h": SC.tau(SC.time(FIG5.h))}}
    overrides = {f"plant.{k}": v for k, v in starts["plant"].items()}
    with kept_sys_path(), closed_loop_master(built.out, FIG5, overrides=overrides) as m:
        a = m.run(FIG5.tau_end, H, progress=False)
    with kept_sys_path(), closed_loop_master(built.out, FIG5, variant=SI) as m:
        b = m.run(SC.time(FIG5.tau_end), SC.time(H), progress=False)
    assert a.completed and b.completed and len(a.time) == len(b.time)
    scaled = {k.split(".", 1)[1]: a[k] for k in a.data.dtype.names if k.startswith("plant.")}
    ref = SC.plant_outputs(scaled, a.time)
    ref["table_torque"] = SC.table_torque(a["controller.R_minus_R0"])
    got = {k.split(".", 1)[1]: b[k] for k in b.data.dtype.names if k.startswith("plant.")}
    got["table_torque"] = b["controller.table_torque"]
    worst = {name: _rel(got[name], ref[name]) for name in (*SI_REALS, "table_torque")}
    print("SI closed loop vs scaled, Fig. 5:", {k: f"{v:.1e}" for k, v in worst.items()})
    for name, err in worst.items():
        assert err <= (1e-12 if name in (*TORSIONAL, "table_torque") else 5e-11), (name, err)
    assert np.array_equal(got["stick_events"], scaled["stick_events"])
    assert np.array_equal(got["mode"], scaled["mode"])


def test_si_controller_is_the_scaled_law_converted(built):
    g = built.gains_values
    c = tl.Slave(built.si.controller, "si_law").init(t_on=0.0, latch=1)
    rng = np.random.default_rng(11)
    p = SC.scaled
    try:
        for k in range(20):
            t, h = k * 0.01, 0.01
            x = rng.normal(size=4)
            tau = SC.tau(t)
            values = {"u": 0.0, "du": 0.0, "d": p.d0, "g": 0.0, "tau_n": p.tau_n0}
            si = SC.plant_outputs(
                dict(zip(("phi", "dphi", "theta", "dtheta"), x, strict=True)) | values, tau
            )
            c.set(**{n: float(si[n]) for n in tl.FEEDBACK_SI})
            r = g["R_ff"] + sum(
                f * xi
                for f, xi in zip(g["F"], (x[0], x[1], x[0] - x[2] - g["K0"], x[3]), strict=True)
            )
            assert c.get("table_torque")[0] == pytest.approx(
                SC.table_torque(r), rel=1e-12, abs=1e-9 * abs(g["F"][0]) * REFERENCE_RIG.C
            )
            assert c.step(t, h) == tl.OK
    finally:
        c.free()
    assert math.isfinite(SC.table_torque(0.0))


def test_si_loop_model_is_the_scaled_model(built):
    """read_loop_model of the SI FMUs converts back to the scaled model of the same loop."""
    from drillstring.orchestration.closed_loop import read_loop_model

    a = read_loop_model(built.out, FIG5, variant=SCALED)
    b = read_loop_model(built.out, FIG5, variant=SI)
    assert b.scaling is not None and a.scaling is None
    for f in dataclasses.fields(a.params):
        assert getattr(b.params, f.name) == pytest.approx(getattr(a.params, f.name), rel=1e-14)
    assert b.initial.dphi == pytest.approx(a.initial.dphi, rel=1e-15)
    assert b.options.h == pytest.approx(a.options.h, rel=1e-15)
    assert b.control.F == pytest.approx(a.control.F, rel=1e-14)
    assert (b.control.K0, b.control.R_ff) == pytest.approx((a.control.K0, a.control.R_ff))
    assert b.control.latch == a.control.latch == FIG5.latch
