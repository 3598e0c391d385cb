"""The SI conversions of drillstring.model.units against independent sources of truth.

* the plant's SI outputs in the nominal motion against the rig's own eq. (8) quantities and
  eqs. (4), (7) (``PhysicalParams``: d0, W0, T0, V0, Omega0) and the nominal twist R0/C;
* the SI controller law against the scaled law (29)-(31) at random states: the gains conversion
  written in the module docstring (F1 C, F2 C t*, F3 C, F4 C t*, K0 - R0/C, C (R0/C + R_ff),
  t* t_on) must give R = C (R0/C + r) for every state and time;
* round trips of the initial state and of the law;
* the units' base-unit exponents by dimensional analysis (N = kg m s^-2, ...).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drillstring.model.control import AffineFeedback, feedback_torque, switch_on_references
from drillstring.model.params import REFERENCE_RIG
from drillstring.model.units import (
    UNITS,
    DisplayUnit,
    PhysicalFeedback,
    SIScaling,
    UnitDef,
    UnitMismatch,
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


@pytest.mark.parametrize("latch", ["none", "angle", "angle+twist"])
def test_si_law_equals_the_scaled_law_converted(latch):
    rng = np.random.default_rng(5)
    law = AffineFeedback(LAW.F, LAW.K0, LAW.R_ff, t_on=LAW.t_on, latch=latch)
    si = PhysicalFeedback.from_scaled(law, SC)
    p = SC.scaled
    for _ in range(200):
        tau = rng.uniform(0.0, 60.0)
        phi, dphi, theta, dtheta = rng.normal(size=4)
        # the references latched at some earlier state
        phi_l, theta_l = rng.normal(size=2)
        refs = switch_on_references(law.latch_code, phi_l, theta_l, law.K0)
        r = feedback_torque(tau, phi, dphi, theta, dtheta, law.F, law.K0, law.R_ff, law.t_on, *refs)
        # the same state and latch instant in SI
        values = {"u": 0.0, "du": 0.0, "d": p.d0, "g": 0.0, "tau_n": p.tau_n0}
        now = SC.plant_outputs(
            {**values, "phi": phi, "dphi": dphi, "theta": theta, "dtheta": dtheta}, tau
        )
        t = SC.time(tau)
        e = si.errors(t, now["bit_angle"], now["bit_speed"], now["table_angle"], now["table_speed"])
        tau_l = rng.uniform(0.0, tau)
        then = SC.plant_outputs(
            {**values, "phi": phi_l, "dphi": 0.0, "theta": theta_l, "dtheta": 0.0}, tau_l
        )
        el = si.errors(SC.time(tau_l), then["bit_angle"], 0.0, then["table_angle"], 0.0)
        refs_si = switch_on_references(si.latch_code, el[0], el[2], si.K0)
        R = feedback_torque(t, *e, si.F, si.K0, si.R_ff, si.t_on, *refs_si)
        if (tau < law.t_on) != (t < si.t_on):
            continue  # the switch-on instant itself, to rounding
        assert R == pytest.approx(SC.table_torque(r), rel=1e-11, abs=1e-9 * abs(si.F[0]))


def test_law_and_initial_state_round_trip():
    si = PhysicalFeedback.from_scaled(LAW, SC)
    back = si.to_scaled(SC)
    for a, b in zip(back.F, LAW.F, strict=True):
        assert a == pytest.approx(b, rel=1e-15)
    assert (back.K0, back.R_ff, back.t_on) == pytest.approx((LAW.K0, LAW.R_ff, LAW.t_on), rel=1e-14)
    # the written conversion, by hand
    C, ts = REFERENCE_RIG.C, REFERENCE_RIG.t_star
    assert si.F == pytest.approx((C * LAW.F[0], C * ts * LAW.F[1], C * LAW.F[2], C * ts * LAW.F[3]))
    assert si.K0 == pytest.approx(LAW.K0 - REFERENCE_RIG.R0 / C, rel=1e-14)
    assert si.R_ff == pytest.approx(REFERENCE_RIG.R0 + C * LAW.R_ff, rel=1e-14)
    assert si.Omega0 == REFERENCE_RIG.Omega0
    with pytest.raises(ValueError, match="set point Omega0 = 1.0 rad/s is not the rig's"):
        PhysicalFeedback(si.F, si.K0, si.R_ff, Omega0=1.0).to_scaled(SC)
    x = {"u": 0.1, "du": -2.0, "phi": 0.3, "dphi": -2.5, "theta": -0.2, "dtheta": 1.5}
    si_x = SC.initial_to_si(x)
    assert si_x["dphi"] == pytest.approx(-2.5 / ts) and si_x["u"] == pytest.approx(
        0.1 * REFERENCE_RIG.L_star
    )
    back_x = SC.initial_to_scaled(si_x)
    assert [getattr(back_x, k) for k in x] == pytest.approx(list(x.values()), rel=1e-15)
    with pytest.raises(ValueError, match="unknown initial-state key"):
        SC.initial_to_scaled({"omega": 1.0})


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
    rpm = UNITS["rad/s"].display_definition("rpm")
    # 51.756 rpm = 51.756 * 2 pi / 60 rad/s (the reference rig's Omega0 = 5.41987 rad/s)
    to_rad_s = unit_conversion(rpm, UNITS["rad/s"])
    assert to_rad_s(51.756) == pytest.approx(51.756 * math.pi / 30.0, rel=1e-15)
    assert to_rad_s(51.756) == pytest.approx(5.4198, abs=1e-4)
    assert unit_conversion(UNITS["rad/s"], rpm)(math.pi) == pytest.approx(30.0, rel=1e-15)
    knm = UNITS["N.m"].display_definition("kN.m")
    assert (knm.factor, knm.offset) == (1000.0, 0.0)
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
    # a display unit with an offset becomes a unit with the inverse offset
    shifted = UnitDef("K", {"K": 1}, (DisplayUnit("degC", 1.0, -273.15),)).display_definition(
        "degC"
    )
    assert shifted.offset == 273.15
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
