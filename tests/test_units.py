"""The SI conversions of drillstring.model.units against independent sources of truth.

* the plant's SI outputs in the nominal motion against the rig's own eq. (8) quantities and
  eqs. (4), (7) (``PhysicalParams``: d0, W0, T0, V0, Omega0) and the nominal twist R0/C;
* the SI controller (the digital controller's block with SI connectors, its parameters converted
  by their dimensions) against the scaled one at random states and times: the plant's SI outputs
  of the same state (converted by ``SIScaling``, another code) must give R = C (R0/C + r);
* round trips of the initial state and the gains conversion by hand (F1 C, F2 C t*, ...);
* the units' base-unit exponents by dimensional analysis (N = kg m s^-2, ...), and every
  dimension's SI unit against the units of C, t* and L* raised to its exponents.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from drillstring.model.control import AffineFeedback
from drillstring.model.digital.block import fmu_output, fmu_step
from drillstring.model.digital.controller import DigitalController, OperatingPoint
from drillstring.model.digital.layout import BLOCK
from drillstring.model.engine import InitialState
from drillstring.model.laws import SampledAffine
from drillstring.model.params import REFERENCE_RIG
from drillstring.model.units import (
    DIMENSIONS,
    IDENTITY,
    SCALED_UNITS,
    SI_UNITS,
    UNIT_SYSTEMS,
    UNITS,
    SIScaling,
    UnitDef,
    UnitMismatch,
    si_scale,
    unit_conversion,
)

SC = SIScaling(REFERENCE_RIG)
LAW = AffineFeedback(F=(-3448.5, -1574.7, 481.8, -89.0), K0=0.14, R_ff=-0.14, t_on=0.3)


def test_nominal_motion_in_si_is_the_rigs_nominal_point():
    p = SC.scaled
    tau = 7.25
    nominal = {"u": 0.0, "du": 0.0, "phi": 0.0, "dphi": 0.0, "theta": 0.0, "dtheta": 0.0}
    out = SC.plant_outputs({**nominal, "d": p.d0, "g": 0.0, "tau_n": p.tau_n0}, tau)
    rig = REFERENCE_RIG
    t = rig.t_star * tau
    expect = {
        "bit_speed": rig.Omega0,
        "table_speed": rig.Omega0,
        "bit_velocity": rig.V0,
        "rate_of_penetration": rig.V0,  # one blade's depth of cut per blade passage
        "depth_of_cut": rig.d0,
        "delay": 2 * math.pi / (rig.n * rig.Omega0),  # (8)
        "weight_on_bit": rig.W0,
        "torque_on_bit": rig.T0,
        "bit_angle": rig.Omega0 * t,
        "bit_position": rig.V0 * t,
        "top_torque": rig.R0,  # the nominal torque all along a steadily turning string
    }
    for name, value in expect.items():
        assert out[name] == pytest.approx(value, rel=1e-13), name
    twist = out["table_angle"] - out["bit_angle"]
    assert twist == pytest.approx(rig.R0 / rig.C, rel=1e-13)  # the nominal twist balances R0
    assert SC.table_torque(0.0) == pytest.approx(rig.R0, rel=1e-13)


def test_torque_on_bit_in_torsional_stick_is_the_given_scaled_torque():
    values = dict.fromkeys(("u", "du", "phi", "dphi", "theta", "dtheta"), 0.0)
    values.update(d=0.1, g=0.3, tau_n=0.7)
    out = SC.plant_outputs(values, 1.0, torque_on_bit=2.5)
    assert out["torque_on_bit"] == REFERENCE_RIG.C * 2.5
    formula = SC.plant_outputs(values, 1.0)["torque_on_bit"]
    assert formula == pytest.approx(
        REFERENCE_RIG.C * SC.scaled.n * (0.1 + SC.scaled.beta * SC.scaled.lam * 0.7), rel=1e-13
    )


def _blocks(law):
    """The scaled controller's block and the SI one (parameters through SI and back)."""
    rig, p = REFERENCE_RIG, SC.scaled
    scaled = DigitalController(law).block(p)
    back = SampledAffine.from_si(rig, law.to_si(rig))
    si = DigitalController(back).block(OperatingPoint(rig.Omega0 * rig.t_star, rig.R0 / rig.C,
                                                      rig.I2 / rig.I1))  # fmt: skip
    si[BLOCK.si] = 1.0
    si[BLOCK.t_star], si[BLOCK.C] = rig.t_star, rig.C
    si[BLOCK.omega0_si], si[BLOCK.R0_si] = rig.Omega0, rig.R0
    return scaled, si


@pytest.mark.parametrize("latch", ["none", "angle", "angle+twist"])
def test_si_controller_equals_the_scaled_one_on_the_plants_si_outputs(latch):
    rng = np.random.default_rng(5)
    law = SampledAffine(AffineFeedback(LAW.F, LAW.K0, LAW.R_ff, t_on=LAW.t_on, latch=latch))
    checked = 0
    for _ in range(100):
        scaled, si = _blocks(law)
        # both latch their references at the same switch-on state, then one step of 1e-3
        tau_l = rng.uniform(LAW.t_on, 30.0)
        x_l = rng.normal(size=4)
        _set(scaled, tau_l, x_l, si=False)
        _set(si, tau_l, x_l, si=True)
        fmu_step(scaled, scaled[BLOCK.time], 1e-3)
        fmu_step(si, si[BLOCK.time], 1e-3 * SC.t_star)
        # then any later state
        tau = rng.uniform(tau_l, 60.0)
        x = rng.normal(size=4)
        _set(scaled, tau, x, si=False)
        _set(si, tau, x, si=True)
        fmu_output(scaled)
        fmu_output(si)
        assert si[BLOCK.output] == pytest.approx(SC.table_torque(scaled[BLOCK.output]), rel=1e-11,
                                            abs=1e-9 * abs(LAW.F[0] * REFERENCE_RIG.C))  # fmt: skip
        checked += 1
    assert checked == 100


def _set(block, tau, x, si):
    """Inputs and time of a block: scaled perturbations, or their SI plant outputs at tau."""
    phi, dphi, theta, dtheta = x
    if not si:
        block[BLOCK.inputs : BLOCK.inputs + 4] = x
        block[BLOCK.time] = tau
        return
    p = SC.scaled
    values = {"u": 0.0, "du": 0.0, "d": p.d0, "g": 0.0, "tau_n": p.tau_n0}
    out = SC.plant_outputs({**values, "phi": phi, "dphi": dphi, "theta": theta, "dtheta": dtheta},
                           tau)  # fmt: skip
    names = ("bit_angle", "bit_speed", "table_angle", "table_speed")
    block[BLOCK.inputs : BLOCK.inputs + 4] = [out[k] for k in names]
    block[BLOCK.time] = SC.time(tau)


def test_law_and_initial_state_round_trip():
    law = SampledAffine(LAW)
    si = law.to_si(REFERENCE_RIG)
    back = SampledAffine.from_si(REFERENCE_RIG, si).feedback
    for a, b in zip(back.F, LAW.F, strict=True):
        assert a == pytest.approx(b, rel=1e-15)
    assert (back.K0, back.R_ff, back.t_on) == pytest.approx((LAW.K0, LAW.R_ff, LAW.t_on), rel=1e-14)
    # the conversion, by hand: gains by C and C t*, K0 an angle, R_ff a torque deviation
    C, ts = REFERENCE_RIG.C, REFERENCE_RIG.t_star
    F = tuple(si[f"F[{i}]"] for i in range(1, 5))
    assert F == pytest.approx((C * LAW.F[0], C * ts * LAW.F[1], C * LAW.F[2], C * ts * LAW.F[3]))
    assert si["K0"] == LAW.K0
    assert si["R_ff"] == pytest.approx(C * LAW.R_ff, rel=1e-14)
    assert si["t_on"] == pytest.approx(ts * LAW.t_on, rel=1e-14)
    x = {"u": 0.1, "du": -2.0, "phi": 0.3, "dphi": -2.5, "theta": -0.2, "dtheta": 1.5}
    si_x = SC.initial_to_si(x)
    assert si_x["dphi"] == pytest.approx(-2.5 / ts) and si_x["u"] == pytest.approx(
        0.1 * REFERENCE_RIG.L_star
    )
    back_x = SC.initial_to_scaled(si_x)
    assert [getattr(back_x, k) for k in x] == pytest.approx(list(x.values()), rel=1e-15)
    with pytest.raises(ValueError, match="unknown initial-state key"):
        SC.initial_to_scaled({"omega": 1.0})


def test_every_dimension_has_the_si_unit_of_its_scales():
    """value_SI = value * C**a * t***b * L***c: the unit must be (N m/rad)**a s**b m**c."""
    C, s_, m = UNITS["N.m/rad"].exponents, UNITS["s"].exponents, UNITS["m"].exponents
    for d in DIMENSIONS.values():
        expect: dict[str, int] = {}
        for base, power in ((C, d.torque), (s_, d.time), (m, d.length)):
            for k, v in base.items():
                expect[k] = expect.get(k, 0) + v * power
        expect = {k: v for k, v in expect.items() if v}
        unit = dict(UNITS[d.unit].exponents)
        unit.pop("rad", None)  # rad is dimensionless: a frequency in rad/s is a rate
        expect.pop("rad", None)
        assert unit == expect, d.name
        if d.display is not None:
            UNITS[d.unit].display_unit(d.display)
    rig = REFERENCE_RIG
    assert si_scale("impedance", rig.C, rig.t_star) == pytest.approx(math.sqrt(rig.C * rig.I1))
    assert si_scale("inertia", rig.C, rig.t_star) == pytest.approx(rig.I1)
    assert si_scale("velocity", rig.C, rig.t_star, rig.L_star) == pytest.approx(
        rig.L_star / rig.t_star
    )
    with pytest.raises(ValueError, match="needs the length scale"):
        si_scale("length", rig.C, rig.t_star)
    with pytest.raises(ValueError, match="unknown dimension 'mass'"):
        si_scale("mass", rig.C, rig.t_star)


def test_base_unit_exponents_by_dimensional_analysis():
    def exps(name):
        return dict(UNITS[name].exponents)

    newton = {"kg": 1, "m": 1, "s": -2}
    assert exps("N") == newton
    assert exps("N.m") == {**newton, "m": 2}
    assert exps("N.m/rad") == {**newton, "m": 2, "rad": -1}
    assert exps("N.m.s/rad") == {"kg": 1, "m": 2, "s": -1, "rad": -1}
    assert exps("N/m") == {"kg": 1, "s": -2}
    assert exps("N.s/m") == {"kg": 1, "s": -1}
    assert exps("Pa") == {"kg": 1, "m": -1, "s": -2}
    assert exps("rad/s") == {"rad": 1, "s": -1}
    # (rad/s) / (N m): the inverse of the impedance N.m.s/rad
    inverse = {k: -v for k, v in exps("N.m.s/rad").items()}
    assert exps("rad/(N.m.s)") == inverse
    assert UNITS["rad/s"].display_unit("rpm").factor == pytest.approx(60 / (2 * math.pi))
    assert UNITS["m/s"].display_unit("m/h").factor == 3600.0
    assert UNITS["N.m"].display_unit("kN.m").factor == 1e-3
    with pytest.raises(ValueError, match="no display unit 'rpm'"):
        UNITS["m"].display_unit("rpm")


# ------------------------------------------------------------------------------------------------
# conversions between units of the same dimension (FMI 2.0 / SSP 1.0 BaseUnit factor and offset)
# ------------------------------------------------------------------------------------------------


def test_conversions_by_hand():
    rpm = UnitDef("rpm", dict(UNITS["rad/s"].exponents), factor=math.pi / 30.0)
    # 51.756 rpm = 51.756 * 2 pi / 60 rad/s (the reference rig's Omega0 = 5.41987 rad/s)
    to_rad_s = unit_conversion(rpm, UNITS["rad/s"])
    assert to_rad_s(51.756) == pytest.approx(51.756 * math.pi / 30.0, rel=1e-15)
    assert to_rad_s(51.756) == pytest.approx(5.4198, abs=1e-4)
    assert unit_conversion(UNITS["rad/s"], rpm)(math.pi) == pytest.approx(30.0, rel=1e-15)
    knm = UnitDef("kN.m", dict(UNITS["N.m"].exponents), factor=1000.0)
    c = unit_conversion(knm, UNITS["N.m"])
    assert (c.factor, c.offset, c(2.5)) == (1000.0, 0.0, 2500.0)
    assert unit_conversion(UNITS["N.m"], knm)(2500.0) == 2.5
    # offsets: degF -> degC (212 degF = 100 degC, 32 degF = 0 degC, -40 = -40)
    degc = UnitDef("degC", {"K": 1}, offset=273.15)
    degf = UnitDef("degF", {"K": 1}, factor=5.0 / 9.0, offset=459.67 * 5.0 / 9.0)
    f_to_c = unit_conversion(degf, degc)
    assert f_to_c(212.0) == pytest.approx(100.0, abs=1e-12)
    assert f_to_c(32.0) == pytest.approx(0.0, abs=1e-12)
    assert f_to_c(-40.0) == pytest.approx(-40.0, abs=1e-12)
    assert unit_conversion(degc, UnitDef("K", {"K": 1}))(20.0) == pytest.approx(293.15, rel=1e-15)
    # the same unit under another name converts as the identity
    assert unit_conversion(UnitDef("J", {"kg": 1, "m": 2, "s": -2}), UNITS["N.m"]).identity


def test_incompatible_units_are_refused_naming_both():
    with pytest.raises(UnitMismatch, match=r"'N\.m' \(dimension kg\.m2\.s-2\) cannot be converted"
                       r" to 'rad/s' \(dimension s-1\.rad\)"):  # fmt: skip
        unit_conversion(UNITS["N.m"], UNITS["rad/s"])
    assert UNITS["1"].dimension == "1" and UNITS["N.m/rad"].dimension == "kg.m2.s-2.rad-1"
    with pytest.raises(UnitMismatch):
        unit_conversion(UNITS["1"], UNITS["rad"])  # rad is a base unit in FMI 2.0 and SSP 1.0
    with pytest.raises(ValueError, match="factor must not be 0"):
        UnitDef("zero", {"m": 1}, factor=0.0)
    with pytest.raises(ValueError, match="exponent of m must be an int"):
        UnitDef("half", {"m": 0.5})


# ------------------------------------------------------------------------------------------------
# the unit systems
# ------------------------------------------------------------------------------------------------


def test_the_scaled_system_converts_nothing_bit_for_bit():
    s = SCALED_UNITS.scales(REFERENCE_RIG)  # whatever the rig
    rng = np.random.default_rng(7)
    x = rng.normal(size=50) * 10.0 ** rng.integers(-12, 12, size=50)
    for conv in (s.time, s.tau, s.torque_deviation, s.table_torque):
        assert np.array_equal(conv(x), x)
    assert all(SCALED_UNITS.factor(d) == 1.0 for d in DIMENSIONS)
    initial = InitialState(u=0.1, du=-0.3, phi=1e-3, dphi=-2.5, theta=0.7, dtheta=3.1)
    assert s.initial_to_si(initial) == dataclasses.asdict(initial)
    assert s.initial_to_scaled(dataclasses.asdict(initial)) == initial
    assert SCALED_UNITS.declared_unit("rad/s", "rpm") == {}


def test_the_si_system_is_the_rigs_scaling():
    rig = REFERENCE_RIG
    s = SI_UNITS.scales(rig)
    assert s == SC and (s.C, s.t_star, s.L_star) == (rig.C, rig.t_star, rig.L_star)
    assert s.twist0 == pytest.approx(rig.R0 / rig.C, rel=1e-15)
    # by hand: a speed is divided by t*, a torque rate multiplied by C/t*
    assert SI_UNITS.factor("speed") == pytest.approx(1.0 / rig.t_star, rel=1e-15)
    assert SI_UNITS.factor("torque rate") == pytest.approx(rig.C / rig.t_star, rel=1e-15)
    assert s.time(2.0) == pytest.approx(2.0 * rig.t_star, rel=1e-15)
    assert s.table_torque(0.0) == pytest.approx(rig.R0, rel=1e-12)
    assert SI_UNITS.declared_unit("rad/s", "rpm") == {"unit": "rad/s", "display_unit": "rpm"}
    assert SI_UNITS.declared_unit("s", None) == {"unit": "s"}
    assert UNIT_SYSTEMS == {"scaled": SCALED_UNITS, "si": SI_UNITS}
    assert (SCALED_UNITS.suffix, SI_UNITS.suffix) == ("", "SI")


def test_parameter_set_of_either_system_is_the_same_scaled_set():
    rig = REFERENCE_RIG
    physical = {f.name: getattr(rig, f.name) for f in dataclasses.fields(rig)}
    params, scales = SI_UNITS.parameter_set({**physical, "unused": 1.0})
    assert params == rig.to_scaled() and scales == SIScaling(rig)
    scaled = {f.name: getattr(params, f.name) for f in dataclasses.fields(params)}
    again, identity = SCALED_UNITS.parameter_set(scaled)
    assert again == params and identity == IDENTITY
    with pytest.raises(ValueError, match="beta"):
        SCALED_UNITS.parameter_set({**scaled, "beta": 1.5})
