"""The top-drive controller FMUs (stiff PI, SoftSpeed, Z-Torque) against their laws.

* the key check: each tuning of ``TopDriveController``, closing the loop of the SSP package
  ``DrillStringTopDrive.ssp`` in the project's master (fixed step H, Jacobi, zero-order hold),
  equals its law of :mod:`drillstring.model.laws` in the monolithic sampled loop
  (:func:`~drillstring.model.sampled.simulate_sampled`, Ts = H) on a Fig. 6-like run: torsional
  stick-slip from dphi0 = -4.9 with the torsional-stick model on, the law switched on at
  tau = 25. The laws are built here from the tuning rules (``industrial_lineup``), not from the
  FMU's parameters. The same for the LMI controller FMU and the sampled paper's law;
* the SI FMU in the SI package against the same sampled loop of the law converted back from its
  SI parameters (``law_from_si``), compared in SI;
* the top-drive FMU takes the LMI controller's place in the LMI loop's package
  (``Master.from_ssp(..., fmus={"controller": ...})``);
* (Ecos running the SI package's ``fig6-z-torque`` SSD like the master: tests/test_ssp.py, which
  runs every SSD of the four packages in the master, Ecos and libcosim);
* the packages' SSDs carry the tunings; the FMUs' start values, ranges and ModelStructure;
* the FMU's law on hand-computed numbers, its FMU state across the switch-on.
"""

from __future__ import annotations

import json
import math

import fmu_testlib as tl
import numpy as np
import pytest
from fmpy import read_model_description

from drillstring.apps.cosim import cosim_main
from drillstring.controller.lineup import INDUSTRIAL, industrial_lineup
from drillstring.controller.tuning import soft_speed
from drillstring.model.control import AffineFeedback
from drillstring.model.digital.controller import DigitalController
from drillstring.model.experiments import FIG6
from drillstring.model.laws import SampledAffine, SpeedPI, ZTorque, law_from_si
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.sampled import simulate_sampled
from drillstring.model.sensing import Sensing
from drillstring.model.timing import Timing
from drillstring.model.topdrive import TDS_11SA, top_drive
from drillstring.model.units import SIScaling
from drillstring.orchestration.closed_loop import (
    SCALED,
    SI,
    TOPDRIVE,
    TOPDRIVE_SI,
    closed_loop_master,
    kept_sys_path,
    read_loop_model,
    run_cosim,
)
from drillstring.orchestration.connections import declared_start_values
from drillstring.orchestration.loop_ssp import (
    TOPDRIVE_DEFAULT,
    TOPDRIVE_EXPERIMENTS,
    TOPDRIVE_PARAMETERS,
    topdrive_tunings,
)
from drillstring.orchestration.master import Master
from drillstring.orchestration.ssp import SspError, read_ssp

pytestmark = pytest.mark.fmu

SC = SIScaling(REFERENCE_RIG)
H = 1e-3
#: Fig. 6-like run: 25 of open-loop stick-slip, then 15 (about 2.5 stick-slip periods) of control.
TAU_END = 40.0
SIGNALS = ("phi", "dphi", "theta", "dtheta", "u", "du")
AXIAL = ("bit_position", "bit_velocity")


def _starts(unit: tl.Unit) -> dict:
    return declared_start_values(read_model_description(str(unit.fmu)))


def _master(ssp, sets, stop, step, **kw):
    with kept_sys_path(), Master.from_ssp(ssp, sets, **kw) as m:
        res = m.run(stop, step, progress=False)
    assert res.completed, res.failure
    return res


def _sampled(law, variant, built, n_steps, Ts):
    """The monolithic sampled loop of ``law`` with the plant of the FMUs' Fig. 6 set-up."""
    loop = read_loop_model(built.out, FIG6, variant=variant)
    return simulate_sampled(
        loop.params, law, n_steps * Ts, Ts, initial=loop.initial, options=loop.options, dt_out=Ts
    )


def _laws(built) -> dict:
    """The four controllers as laws, from the tuning rules and the gains file (not the FMUs)."""
    g = built.gains_values
    laws = industrial_lineup(REFERENCE, R_ff=g["R_ff"], t_on=FIG6.t_on)
    feedback = AffineFeedback(tuple(g["F"]), g["K0"], g["R_ff"], FIG6.t_on, FIG6.latch)
    return {**laws, "lmi": SampledAffine(feedback)}


@pytest.mark.parametrize("name", [*INDUSTRIAL, "lmi"])
def test_controller_fmu_in_the_master_equals_its_sampled_law(built, name):
    """Master and monolithic sampled loop are bit-identical over the run, every plant signal and
    the torque (the issue asks 1e-12): the plant FMU's engine and the sampled loop take the same
    steps, the FMU and the loop evaluate the same law functions on the same numbers."""
    if name == "lmi":
        res = _master(built.ssp, None, TAU_END, H, variant="fig6")
    else:
        res = _master(built.topdrive_ssp, None, TAU_END, H, variant=f"fig6-{name}")
    law = _laws(built)[name]
    n = round(TAU_END / H)
    mono = _sampled(law, SCALED, built, n, H)
    assert len(res.time) == len(mono.tau) == n + 1
    assert np.max(np.abs(res.time - mono.tau)) <= 1e-12
    worst = {c: float(np.max(np.abs(res[f"plant.{c}"] - getattr(mono, c)))) for c in SIGNALS}
    worst["R_minus_R0"] = float(np.max(np.abs(res["controller.R_minus_R0"] - mono.R_minus_R0)))
    print(f"{name}: master vs sampled engine, max abs difference:", worst)
    assert max(worst.values()) == 0.0, worst  # the same arithmetic in the same order: bit for bit
    # a real run: stick-slip before the switch-on, the law acting after it
    before = res.time < FIG6.t_on
    assert res["plant.torsional_stick"][before][-1] > 0
    assert np.all(res["controller.R_minus_R0"][before] == built.gains_values["R_ff"])
    assert np.ptp(res["controller.R_minus_R0"][~before]) > 0.1


def test_lmi_fmu_with_top_drive_and_telemetry_equals_its_digital_controller(built):
    """The controller FMU's top drive and sensing parameters are the DigitalController's: a low
    gain with the TDS-11SA (the FMU's start values), the angle frozen while saturated, telemetry
    frames every 0.1 used 0.2 late with noise: the master and the sampled loop bit for bit,
    through a run that saturates the drive."""
    F = (-88.16, -65.50, 52.86, -19.72)
    g = built.gains_values
    telemetry = {"period": 0.1, "latency": 0.2, "noise_dphi": 0.01, "seed": 3}
    overrides = {
        **{f"controller.F[{i + 1}]": f for i, f in enumerate(F)},
        "controller.top_drive": True,
        "controller.on_saturation": 2,  # freeze-angle
        "controller.downhole": 2,  # telemetry
        **{f"controller.{k}": v for k, v in telemetry.items()},
    }
    with kept_sys_path(), closed_loop_master(built.out, FIG6, overrides=overrides) as m:
        res = run_cosim(m, TAU_END, H)
    assert res.completed, res.failure
    feedback = AffineFeedback(F, g["K0"], g["R_ff"], FIG6.t_on, FIG6.latch)
    controller = DigitalController(
        SampledAffine(feedback, on_saturation="freeze-angle"),
        top_drive(TDS_11SA, REFERENCE_RIG),
        Sensing(downhole="telemetry", **telemetry),
    )
    n = round(TAU_END / H)
    mono = _sampled(controller, SCALED, built, n, H)
    worst = {c: float(np.max(np.abs(res[f"plant.{c}"] - getattr(mono, c)))) for c in SIGNALS}
    worst["R_minus_R0"] = float(np.max(np.abs(res["controller.R_minus_R0"] - mono.R_minus_R0)))
    assert max(worst.values()) == 0.0, worst
    assert np.sum(mono.n_saturated) > 100  # the drive limited the torque on this run


def test_controller_fmus_period_and_latency_are_the_digital_controllers(built):
    """The controller FMU's own period and latency (control_period, control_latency) are the
    DigitalController's Timing: 20 ms on the reference rig with one period of latency, the
    master and the sampled loop bit for bit."""
    g = built.gains_values
    P = 0.02 / REFERENCE_RIG.t_star
    overrides = {"controller.control_period": P, "controller.control_latency": P}
    with kept_sys_path(), closed_loop_master(built.out, FIG6, overrides=overrides) as m:
        res = run_cosim(m, TAU_END, H)
    assert res.completed, res.failure
    feedback = AffineFeedback(tuple(g["F"]), g["K0"], g["R_ff"], FIG6.t_on, FIG6.latch)
    controller = DigitalController(SampledAffine(feedback), timing=Timing(period=P, latency=P))
    n = round(TAU_END / H)
    mono = _sampled(controller, SCALED, built, n, H)
    worst = {c: float(np.max(np.abs(res[f"plant.{c}"] - getattr(mono, c)))) for c in SIGNALS}
    worst["R_minus_R0"] = float(np.max(np.abs(res["controller.R_minus_R0"] - mono.R_minus_R0)))
    assert max(worst.values()) == 0.0, worst
    # the torque is held over the controller's period: it changes at most every P
    after = res.time >= FIG6.t_on
    changes = np.flatnonzero(np.diff(res["controller.R_minus_R0"][after]) != 0.0)
    assert changes.size > 10 and np.min(np.diff(changes)) * H >= P - H
    # and the SI FMU declares both in seconds
    md = read_model_description(str(built.si.controller.fmu))
    units = {v.name: v.unit for v in md.modelVariables}
    assert units["control_period"] == units["control_latency"] == "s"


@pytest.mark.parametrize("name", INDUSTRIAL)
def test_si_fmu_in_the_master_equals_its_law_converted_back(built, name):
    """The SI loop (step H = 1 ms) against the sampled loop of ``law_from_si`` of the SI FMU's
    parameters (Ts = H/t*) on the rig's scaled set, to 25 + 8 in tau. Not bit-identical: the
    SI plant converts its time to tau (t/t*), the SI law works on total angles and speeds in SI
    units. Relative to each signal's scale, the torsional signals and the table torque agree to
    1e-12, the axial ones to 5e-11 (the axial stick events amplify the difference, as for the
    LMI loop in tests/test_fmu_si.py); measured at most 2.3e-13 (torsional, torque) and
    8.2e-12 (axial velocity)."""
    si = built.si
    applied = read_ssp(si.topdrive_ssp, unpack=False, variant=f"fig6-{name}").start_values()
    values = {**_starts(si.topdrive), **{k: v for k, (_, v) in applied["controller"].items()}}
    n = math.ceil((FIG6.t_on + 8.0) * SC.t_star / H)
    res = _master(si.topdrive_ssp, None, n * H, H, variant=f"fig6-{name}")
    kind = "ZTorque" if values["z_gain"] > 0 else "SpeedPI"
    keys = ("kp", "ki") if kind == "SpeedPI" else TOPDRIVE_PARAMETERS
    law = law_from_si(
        kind,
        REFERENCE_RIG,
        {
            **{k: values[k] for k in keys},
            "R_ff": values["R_ff"],  # a deviation from R0 in SI too
            "t_on": values["t_on"],
        },
    )
    assert law.t_on == pytest.approx(FIG6.t_on, rel=1e-15)
    mono = _sampled(law, SI, built, n, H / SC.t_star)
    ref = SC.plant_outputs(
        {c: getattr(mono, c) for c in ("u", "du", "phi", "dphi", "theta", "dtheta", "d", "g")}
        | {"tau_n": mono.tau_n},
        mono.tau,
    )
    ref["table_torque"] = SC.table_torque(mono.R_minus_R0)
    got = {q: res[f"plant.{q}"] for q in tl.FEEDBACK_SI + AXIAL}
    got["table_torque"] = res["controller.table_torque"]
    worst = {q: float(np.max(np.abs(got[q] - ref[q])) / np.max(np.abs(ref[q]))) for q in got}
    print(f"{name}: SI master vs sampled engine, max relative difference:", worst)
    for q, err in worst.items():
        assert err <= (5e-11 if q in AXIAL else 1e-12), (q, err)
    assert np.ptp(res["controller.table_torque"][res.time > FIG6.t_on * SC.t_star]) > 10.0


def test_topdrive_fmu_takes_the_lmi_controllers_place_in_its_package(built):
    """Same connectors: the top-drive FMU closes the LMI loop's package (no parameter set: the
    FMUs' own start values, SoftSpeed from t_on = 0) exactly as its own package does. The LMI
    package's sets carry the paper's gains and latch, which the top-drive FMU has not: a clear
    error."""
    swapped = _master(built.ssp, (), 2.0, H, fmus={"controller": built.topdrive.fmu})
    own = _master(built.topdrive_ssp, (), 2.0, H)
    assert swapped.data.dtype.names == own.data.dtype.names
    for col in swapped.data.dtype.names:
        assert np.array_equal(swapped[col], own[col]), col
    assert np.ptp(own["controller.R_minus_R0"]) > 0.01
    with pytest.raises((SspError, ValueError), match="has no variable 'F\\[1\\]'"):
        Master.from_ssp(built.ssp, variant="fig6", fmus={"controller": built.topdrive.fmu})
    # and in SI
    si = built.si
    swapped = _master(si.ssp, (), 0.5, H, fmus={"controller": si.topdrive.fmu})
    own = _master(si.topdrive_ssp, (), 0.5, H)
    assert np.array_equal(swapped.data, own.data)


@pytest.mark.parametrize("variant", [TOPDRIVE, TOPDRIVE_SI], ids=["scaled", "si"])
def test_packages_carry_the_tunings_and_the_default_is_the_fmus_start(built, variant):
    b = built.si if variant.name == "si" else built
    p = read_ssp(b.topdrive_ssp, unpack=False)
    assert set(p.sets) == {e.name for e in TOPDRIVE_EXPERIMENTS}
    assert tuple(e.name for e in TOPDRIVE_EXPERIMENTS) == (
        "fig5", *(f"fig6-{t}" for t in INDUSTRIAL), "fig6-soft-speed-string"
    )  # fmt: skip
    assert [c.name for c in p.components] == ["plant", "controller"]
    assert [str(c) for c in p.connections] == list(variant.connections)
    t_on = SC.time(FIG6.t_on) if variant.name == "si" else 25.0
    starts = _starts(b.topdrive)
    tunings = topdrive_tunings(variant)
    for name in INDUSTRIAL:
        six = read_ssp(b.topdrive_ssp, unpack=False, variant=f"fig6-{name}").start_values()
        got = {k: v for k, (_, v) in six["controller"].items()}
        assert {k: got[k] for k in TOPDRIVE_PARAMETERS} == tunings[name]
        assert got["t_on"] == pytest.approx(t_on, rel=1e-15) and got["enabled"] is True
        assert {k: got[k] for k in got if k not in (*TOPDRIVE_PARAMETERS, "t_on")} == {
            k: starts[k] for k in got if k not in (*TOPDRIVE_PARAMETERS, "t_on")
        }
    assert {k: starts[k] for k in TOPDRIVE_PARAMETERS} == tunings[TOPDRIVE_DEFAULT]
    # SystemStructure.ssd (fig5): the FMU's start values, SoftSpeed from t = 0
    five = {k: v for k, (_, v) in p.start_values()["controller"].items()}
    md = read_model_description(str(b.topdrive.fmu))
    assert set(five) == {v.name for v in md.modelVariables if v.causality == "parameter"}
    assert five == {k: starts[k] for k in five}


def test_start_values_are_the_soft_speed_rule_and_the_gains_file(built):
    scaled, si = _starts(built.topdrive), _starts(built.si.topdrive)
    rule = soft_speed(REFERENCE)
    assert (scaled["kp"], scaled["ki"], scaled["z_gain"]) == (rule.kp, rule.ki, 0.0)
    assert scaled["kp"] == 2.0 * math.sqrt(REFERENCE.rho) and scaled["ki"] == REFERENCE.rho
    assert scaled["R_ff"] == built.gains_values["R_ff"] and scaled["t_on"] == 0.0
    C, ts = REFERENCE_RIG.C, REFERENCE_RIG.t_star
    assert si["kp"] == pytest.approx(C * ts * rule.kp, rel=1e-15)
    assert si["ki"] == pytest.approx(C * rule.ki, rel=1e-15)
    assert si["omega_hp"] == pytest.approx(0.3 / ts, rel=1e-15)
    assert si["R_ff"] == pytest.approx(C * built.gains_values["R_ff"], rel=1e-14)
    assert (si["C"], si["I1"], si["Omega0"]) == (C, REFERENCE_RIG.I1, REFERENCE_RIG.Omega0)
    assert (si["R0"], si["I2"]) == (REFERENCE_RIG.R0, REFERENCE_RIG.I2)
    z = topdrive_tunings(TOPDRIVE_SI)["z-torque"]
    assert z["z_gain"] == pytest.approx(1.0 / (C * ts), rel=1e-15)  # 1/Z: impedance matching


def test_model_structure_ranges_and_units(built):
    for unit, inputs, out, speed in (
        (built.topdrive, tl.FEEDBACK, "R_minus_R0", "dtheta"),
        (built.si.topdrive, tl.FEEDBACK_SI, "table_torque", "table_speed"),
    ):
        md = read_model_description(str(unit.fmu))
        variables = {v.name: v for v in md.modelVariables}
        assert [v.name for v in md.modelVariables if v.causality == "input"] == list(inputs)
        (o,) = md.outputs
        assert o.variable.name == out and [d.name for d in o.dependencies] == [speed]
        ranges = {n: float(v.min) for n, v in variables.items() if v.min is not None}
        assert {k: ranges[k] for k in ("kp", "ki", "z_gain")} == dict.fromkeys(
            ("kp", "ki", "z_gain"), 0.0
        )
        assert ranges["omega_hp"] == ranges["omega_lp"] == math.ulp(0.0)
        # the declared bounds are the laws' own validators: the bound passes, beyond it fails
        ZTorque(kp=0.0, ki=0.0, z_gain=0.0, omega_hp=math.ulp(0.0), omega_lp=math.ulp(0.0))
        for bad in ({"kp": -math.ulp(0.0)}, {"omega_hp": 0.0}):
            with pytest.raises(ValueError):
                ZTorque(**{"kp": 1.0, "ki": 1.0, **bad})
        # the law is chosen by Reals alone (hosts that set no Enumeration run the law they are
        # given); the Enumerations are options whose start values are inactive by default
        enums = {v.name: v.start for v in md.modelVariables if v.type == "Enumeration"}
        assert enums == {"anti_windup": "2", "braking": "1", "downhole": "1", "torque": "1"}
        assert variables["top_drive"].start == "false"
    md = read_model_description(str(built.si.topdrive.fmu))
    units = {v.name: v.unit for v in md.modelVariables if v.type == "Real"}
    assert {k: units[k] for k in (
        "bit_angle", "bit_speed", "table_angle", "table_speed", "table_torque", "kp", "ki",
        "z_gain", "omega_hp", "omega_lp", "R_ff", "Omega0", "C", "I1", "I2", "R0", "t_on",
        "R_max", "P_max", "lag", "period", "noise_dphi",
    )} == {
        "bit_angle": "rad", "bit_speed": "rad/s", "table_angle": "rad", "table_speed": "rad/s",
        "table_torque": "N.m", "kp": "N.m.s/rad", "ki": "N.m/rad", "z_gain": "rad/(N.m.s)",
        "omega_hp": "rad/s", "omega_lp": "rad/s", "R_ff": "N.m", "Omega0": "rad/s",
        "C": "N.m/rad", "I1": "kg.m2", "I2": "kg.m2", "R0": "N.m", "t_on": "s", "R_max": "N.m",
        "P_max": "W", "lag": "s", "period": "s", "noise_dphi": "rad/s",
    }  # fmt: skip


def test_law_by_hand_and_state_round_trip_across_the_switch_on(built):
    """Z-Torque with kp = 2, ki = 3, z_gain = 0.5, switched on at t = 0.02 (step 0.01), computed
    by hand; an FMU state saved before the switch-on and restored gives the same outputs."""
    s = tl.Slave(built.topdrive, "by_hand").init(
        kp=2.0, ki=3.0, z_gain=0.5, omega_hp=0.3, omega_lp=10.0, R_ff=-0.1, t_on=0.02
    )
    inputs = [(0.1 * k, 0.2 - 0.05 * k, 0.3 + 0.02 * k, 0.05 * k) for k in range(6)]
    h = 0.01
    integral = hp = lp = 0.0
    try:
        saved = None
        first = []
        for k, (phi, dphi, theta, dtheta) in enumerate(inputs):
            s.set(phi=phi, dphi=dphi, theta=theta, dtheta=dtheta)
            torque = theta - phi
            if k == 2:  # switch-on: integral preset, high-pass at rest
                integral, hp, lp = -2.0 * (-dtheta) / 3.0, torque, 0.0
            r = -0.1 if k < 2 else -0.1 + 2.0 * (-dtheta - 0.5 * lp) + 3.0 * integral
            (got,) = s.get("R_minus_R0")
            assert got == pytest.approx(r, rel=1e-14, abs=1e-15), k
            first.append(got)
            if k == 1:
                saved = s.fmu.getFMUstate()
            if k >= 2:
                e = -dtheta - 0.5 * lp
                a_hp, a_lp = 1.0 - math.exp(-0.3 * h), 1.0 - math.exp(-10.0 * h)
                integral, hp, lp = (
                    integral + h * e,
                    hp + a_hp * (torque - hp),
                    lp + a_lp * ((torque - hp) - lp),
                )
            assert s.step(k * h, h) == tl.OK
        s.fmu.setFMUstate(saved)
        s.fmu.freeFMUstate(saved)
        again = []
        for k in range(1, 6):  # saved before the step from 0.01
            s.set(**dict(zip(tl.FEEDBACK, inputs[k], strict=True)))
            again.append(s.get("R_minus_R0")[0])
            assert s.step(k * h, h) == tl.OK
        assert again == first[1:]
    finally:
        s.free()


def test_disabled_or_z_gain_zero(built):
    """enabled = false: R_ff throughout; z_gain = 0 is the plain speed PI (SpeedPI)."""
    off = tl.Slave(built.topdrive, "off").init(enabled=False, R_ff=-0.2)
    pi = tl.Slave(built.topdrive, "pi").init(kp=3.0, ki=2.0, z_gain=0.0, R_ff=-0.2, t_on=0.0)
    law = DigitalController(SpeedPI(kp=3.0, ki=2.0, R_ff=-0.2)).start(REFERENCE)
    try:
        for k in range(5):
            x = (0.1 * k, 0.3, -0.2 * k, 0.1 - 0.07 * k)
            for s in (off, pi):
                s.set(**dict(zip(tl.FEEDBACK, x, strict=True)))
            assert off.get("R_minus_R0") == [-0.2]
            assert pi.get("R_minus_R0")[0] == law.output(k * 0.01, *x)
            law.step(k * 0.01, *x, 0.01)
            assert off.step(k * 0.01, 0.01) == pi.step(k * 0.01, 0.01) == tl.OK
    finally:
        off.free()
        pi.free()


def test_cosim_command_runs_a_variant(built, tmp_path, capsys):
    """``drillstring cosim PKG --variant fig6-z-torque``: the master of that SSD."""
    out = tmp_path / "zt"
    code = cosim_main(
        [str(built.topdrive_ssp), "--out", str(out), "--variant", "fig6-z-torque",
         "--stop-time", "1.0", "--no-progress"]
    )  # fmt: skip
    assert code == 0, capsys.readouterr().err
    data = np.genfromtxt(out / "cosim.csv", delimiter=",", names=True)
    ref = _master(built.topdrive_ssp, None, 1.0, H, variant="fig6-z-torque")
    assert np.array_equal(data["plantdphi"], ref["plant.dphi"])
    summary = json.loads((out / "cosim.json").read_text())
    assert (summary["variant"], summary["sets_applied"]) == ("fig6-z-torque", ["fig6-z-torque"])
    assert data["plantdphi"][0] == FIG6.dphi0  # Fig. 6's initial state, not the FMU's -2.5
