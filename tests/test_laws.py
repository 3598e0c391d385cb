"""The digital control laws (drillstring.model.laws), run by the digital controller
(drillstring.model.digital), and the sampled closed loop (drillstring.model.sampled).

Each law is checked against values computed by hand from its equations, the filters against the
continuous first-order responses they discretise, the SI forms against the laws written directly
in SI units, and the sampled loop against the continuous monolithic solver: equal for a held
torque, first-order convergent in Ts for the paper's law.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drillstring.controller.gains import PAPER_F
from drillstring.model.control import AffineFeedback
from drillstring.model.digital.controller import DigitalController
from drillstring.model.engine import EngineOptions
from drillstring.model.laws import (
    FeedForward,
    SampledAffine,
    SpeedPI,
    ZTorque,
    law_from_si,
)
from drillstring.model.params import REFERENCE, get_physical
from drillstring.model.sampled import simulate_sampled
from drillstring.model.simulate import simulate

K0_REF = 0.18383708216912742  # K0 of (27) at the reference set with A = 0.38541, see gains.json


def _start(law):
    """The law in operation at the reference set, exact measurements, no top drive."""
    return DigitalController(law).start(REFERENCE)


# --------------------------------------------------------------------------------------------
# laws by hand
# --------------------------------------------------------------------------------------------


def test_speed_pi_by_hand():
    run = _start(SpeedPI(kp=2.0, ki=3.0, R_ff=0.5, t_on=1.0))
    m = {"phi": 0.0, "dphi": 0.0, "theta": 0.0, "dtheta": 0.2}
    # before t_on: the feed-forward alone, the law not started
    assert run.output(0.999, **m) == 0.5
    assert run.step(0.999, **m, Ts=0.1) == 0.5 and not run.active
    # switch-on: integral preset to -kp*e/ki = 2*0.2/3, torque continuous
    assert run.output(1.0, **m) == pytest.approx(0.5, abs=1e-15)
    run.step(1.0, **m, Ts=0.1)
    assert run.active
    # one period: I = 0.4/3 - 0.1*0.2; then with dtheta = 0.1: 0.5 - 0.2 + 3*I = 0.64
    assert run.law_state[0] == pytest.approx(0.4 / 3.0 - 0.02, rel=1e-15)
    assert run.output(1.1, **{**m, "dtheta": 0.1}) == pytest.approx(0.64, rel=1e-14)
    # without an integrator the torque steps by kp*e at switch-on
    assert _start(SpeedPI(kp=2.0, ki=0.0, R_ff=0.5)).output(0.0, **m) == pytest.approx(0.1)


def test_z_torque_by_hand():
    run = _start(ZTorque(kp=2.0, ki=3.0, z_gain=0.5, omega_hp=1.0, omega_lp=10.0))
    m1 = {"phi": -1.0, "dphi": 0.0, "theta": 0.0, "dtheta": 0.2}  # torque theta - phi = 1
    assert run.output(0.0, **m1) == pytest.approx(0.0, abs=1e-15)  # bumpless
    run.step(0.0, **m1, Ts=0.1)  # the high-pass sits on its input: nothing moves but I
    assert run.law_state[:3] == pytest.approx((0.4 / 3.0 - 0.02, 1.0, 0.0), rel=1e-15)
    m2 = {"phi": -2.0, "dphi": 0.0, "theta": 0.0, "dtheta": 0.0}  # torque 2
    assert run.output(0.1, **m2) == pytest.approx(3.0 * (0.4 / 3.0 - 0.02), rel=1e-14)
    run.step(0.1, **m2, Ts=0.1)
    # high-pass input 1 held over Ts: z += (1 - e^-0.1)*1, y += (1 - e^-1)*(1 - 0)
    assert run.law_state[1] == pytest.approx(1.0 + (1.0 - math.exp(-0.1)), rel=1e-15)
    assert run.law_state[2] == pytest.approx(1.0 - math.exp(-1.0), rel=1e-15)
    e = -0.5 * (1.0 - math.exp(-1.0))
    assert run.output(0.2, **m2) == pytest.approx(2.0 * e + 3.0 * (0.4 / 3.0 - 0.02), rel=1e-14)


def test_z_torque_filters_are_the_exact_first_order_responses():
    """A torque step of 1 held: high-pass output exp(-w_hp t), low-pass of it the convolution
    w_lp/(w_lp - w_hp)*(exp(-w_hp t) - exp(-w_lp t)) at every sample instant."""
    w_hp, w_lp, Ts = 0.7, 3.0, 0.05
    run = _start(ZTorque(kp=0.0, ki=0.0, z_gain=1.0, omega_hp=w_hp, omega_lp=w_lp))
    run.step(0.0, 0.0, 0.0, 0.0, 0.0, Ts)  # switched on at rest on the torque 0
    for k in range(1, 41):
        run.step(k * Ts, -1.0, 0.0, 0.0, 0.0, Ts)  # torque 1 from tau = Ts on
        t = k * Ts
        assert 1.0 - run.law_state[1] == pytest.approx(math.exp(-w_hp * t), rel=1e-13)
    # the low-pass of a piecewise-constant (sampled) input: exact for the held samples; the
    # continuous convolution is approached to O(Ts)
    lp = w_lp / (w_lp - w_hp) * (math.exp(-w_hp * t) - math.exp(-w_lp * t))
    assert run.law_state[2] == pytest.approx(lp, abs=2.0 * Ts)


def test_z_torque_without_feedback_is_the_speed_pi_bit_for_bit():
    """One compiled law: z_gain = 0 leaves the filters out of the torque exactly."""
    a = _start(SpeedPI(kp=4.47, ki=5.0, R_ff=-0.2))
    b = _start(ZTorque(kp=4.47, ki=5.0, z_gain=0.0, omega_hp=0.3, omega_lp=10.0, R_ff=-0.2))
    rng = np.random.default_rng(3)
    for k in range(200):
        phi, dphi, theta, dtheta = rng.normal(size=4)
        assert a.step(k * 1e-3, phi, dphi, theta, dtheta, 1e-3) == b.step(
            k * 1e-3, phi, dphi, theta, dtheta, 1e-3
        )


def test_sampled_affine_is_feedback_torque_with_latched_references():
    f = AffineFeedback(F=(1.0, 2.0, 3.0, 4.0), K0=0.5, R_ff=-0.5, t_on=2.0, latch="angle")
    run = _start(SampledAffine(f))
    m = {"phi": 2.0, "dphi": 0.1, "theta": 1.5, "dtheta": 0.2}
    assert run.output(1.0, **m) == -0.5
    run.step(2.0, **m, Ts=0.01)
    assert run.law_state[:2] == (2.0, 0.0)  # phi_ref = phi at switch-on
    # R_ff + F1*(phi - phi_ref) + F2*dphi + F3*(phi - theta - K0) + F4*dtheta
    assert run.output(2.0, **m) == pytest.approx(-0.5 + 0.2 + 0.0 + 0.8, rel=1e-15)
    m2 = {"phi": 3.0, "dphi": 0.0, "theta": 1.0, "dtheta": 0.0}
    assert run.output(2.01, **m2) == pytest.approx(-0.5 + 1.0 + 3.0 * 1.5, rel=1e-15)


def test_feed_forward_and_a_disabled_controller_put_out_r_ff():
    run = _start(FeedForward(R_ff=-0.3))
    assert run.step(0.0, 1.0, 2.0, 3.0, 4.0, 0.1) == -0.3
    off = DigitalController(SpeedPI(kp=9.0, ki=9.0, R_ff=0.25), enabled=False).start(REFERENCE)
    assert off.step(5.0, 1.0, 2.0, 3.0, 4.0, 0.1) == 0.25 and not off.active


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: SpeedPI(kp=-1.0, ki=0.0), "SpeedPI.kp must be >= 0, got -1.0"),
        (lambda: SpeedPI(kp=1.0, ki=math.nan), "SpeedPI.ki must be finite, got nan"),
        (lambda: SpeedPI(kp=1.0, ki=1.0, t_on=math.inf), "SpeedPI.t_on must be finite"),
        (lambda: ZTorque(kp=1.0, ki=1.0, omega_hp=0.0), "ZTorque.omega_hp must be > 0, got 0.0"),
        (lambda: ZTorque(kp=1.0, ki=1.0, z_gain="1"), "ZTorque.z_gain must be a real number"),
        (lambda: SpeedPI(kp=1.0, ki=1.0, anti_windup="clamp"), "SpeedPI.anti_windup must be one"),
        (lambda: SampledAffine((1.0, 2.0)), "must be an AffineFeedback"),
        (
            lambda: SampledAffine(AffineFeedback((1.0,) * 4, 0.0, 0.0), on_saturation="stop"),
            "SampledAffine.on_saturation must be one of",
        ),
        (lambda: SpeedPI.from_values({"kp": 1.0, "ki": 1.0, "kd": 2.0}), r"unknown .*\['kd'\]"),
        (lambda: DigitalController(SpeedPI(1.0, 1.0)).start("reference"), "OperatingPoint"),
    ],
)
def test_bad_parameters_are_named(make, message):
    with pytest.raises((ValueError, TypeError), match=message.replace("(", r"\(")):
        make()


# --------------------------------------------------------------------------------------------
# SI forms
# --------------------------------------------------------------------------------------------


def test_si_parameters_by_hand_on_the_reference_rig():
    rig = get_physical("reference-rig")
    t, C = math.sqrt(rig.I1 / rig.C), rig.C
    si = SpeedPI(kp=2.0, ki=3.0, R_ff=0.5, t_on=10.0, tracking_time=2.0).to_si(rig)
    numbers = {k: v for k, v in si.items() if k != "anti_windup"}
    assert numbers == pytest.approx(
        {"kp": 2 * C * t, "ki": 3 * C, "R_ff": 0.5 * C, "t_on": 10 * t, "tracking_time": 2 * t},
        rel=1e-14,
    )
    assert si["anti_windup"] == "back-calculation"
    assert si["kp"] == pytest.approx(433.59, rel=1e-4)  # 2 * 235 N m/rad * 0.92253 s
    z = ZTorque(kp=2.0, ki=3.0, z_gain=0.5, omega_hp=0.1, omega_lp=10.0).to_si(rig)
    Z = math.sqrt(rig.C * rig.I1)  # the lumped string's impedance [N m s/rad]
    assert z["z_gain"] == pytest.approx(0.5 / Z, rel=1e-14)
    assert z["omega_hp"] == pytest.approx(0.1 / t, rel=1e-14)
    si = SampledAffine(AffineFeedback(PAPER_F, K0_REF, -K0_REF)).to_si(rig)
    F = tuple(si[f"F[{i}]"] for i in range(1, 5))
    assert F == pytest.approx((PAPER_F[0] * C, PAPER_F[1] * C * t, PAPER_F[2] * C, -89 * C * t))
    # one R_ff convention: a deviation from R0 in both unit systems; K0 an angle
    assert si["R_ff"] == pytest.approx(-K0_REF * C, rel=1e-15) and si["K0"] == K0_REF


@pytest.mark.parametrize(
    "law",
    [
        SpeedPI(kp=4.47, ki=5.0, R_ff=-0.18, t_on=25.0, anti_windup="conditional"),
        ZTorque(kp=100.0, ki=500.0, z_gain=1.0, omega_hp=0.1, omega_lp=10.0, R_ff=-0.2, t_on=3.0),
        SampledAffine(AffineFeedback(PAPER_F, K0_REF, -K0_REF, 25.0, "angle"), "freeze-angle"),
        FeedForward(R_ff=-0.1, t_on=2.0),
    ],
    ids=["SpeedPI", "ZTorque", "SampledAffine", "FeedForward"],
)
def test_si_round_trip(law):
    rig = get_physical("reference-rig")
    back = law_from_si(type(law).__name__, rig, law.to_si(rig))
    assert type(back) is type(law)
    for name, x in law.values().items():
        y = back.values()[name]
        if isinstance(x, str):
            assert x == y, name
        else:
            assert x == pytest.approx(y, rel=1e-12, abs=1e-15), name


def test_speed_pi_in_si_units_is_the_scaled_law_times_c():
    """Written directly in SI: R - R0 = kp_SI*(-dTheta/dt) + ki_SI*integral(-dTheta/dt) dt; the
    scaled law on the scaled measurements gives the same torque divided by C."""
    rig = get_physical("reference-rig")
    law = SpeedPI(kp=4.47, ki=5.0, R_ff=0.0)
    si = law.to_si(rig)
    run = _start(law)
    Ts_si = 0.01  # s
    speeds = [0.3, -0.1, 0.25, 0.0, -0.4]  # table speed deviations [rad/s]
    integral_si = si["kp"] * speeds[0] / si["ki"]  # the same bumpless preset, in SI
    for k, w in enumerate(speeds):
        tau = k * Ts_si / rig.t_star
        torque = run.output(tau, 0.0, 0.0, 0.0, w * rig.t_star) * rig.C
        if k > 0:
            integral_si -= Ts_si * speeds[k - 1]
        assert torque == pytest.approx(-si["kp"] * w + si["ki"] * integral_si, rel=1e-12)
        run.step(tau, 0.0, 0.0, 0.0, w * rig.t_star, Ts_si / rig.t_star)


# --------------------------------------------------------------------------------------------
# the sampled closed loop
# --------------------------------------------------------------------------------------------


def test_sampled_loop_with_a_held_torque_equals_the_monolithic_run():
    """kp = ki = 0: the law puts out R_ff at every sample; the engine takes the same steps as a
    monolithic run with that torque held (h = 5e-4 divides both Ts and dt_out), so the two runs
    agree up to the event location: the step ends are rounded differently (1e-16) and the axial
    stick events are located to 1e-13 in time, which the run amplifies to about 1e-10."""
    law = SpeedPI(kp=0.0, ki=0.0, R_ff=-K0_REF)
    a = simulate_sampled(REFERENCE, law, 3.0, 1e-3, initial={"dphi": -2.5}, dt_out=0.01)
    b = simulate(REFERENCE, 3.0, control=-K0_REF, initial={"dphi": -2.5}, dt_out=0.01)
    assert a.status.ok and a.tau.shape == b.tau.shape
    np.testing.assert_allclose(a.tau, b.tau, rtol=0, atol=1e-12)
    for col in ("du", "dphi", "theta", "R_minus_R0"):
        np.testing.assert_allclose(getattr(a, col), getattr(b, col), rtol=0, atol=1e-8)
    assert a.counters["stick_events"] == b.counters["stick_events"] > 0


def test_sampled_paper_law_converges_to_the_continuous_one_to_first_order():
    """Zero-order hold over Ts perturbs the torque by O(Ts): the error in dphi/dtau against the
    law evaluated continuously halves with Ts (Fig. 5 set-up, paper's gain)."""
    feedback = AffineFeedback(PAPER_F, K0_REF, -K0_REF)
    ref = simulate(REFERENCE, 4.0, control=feedback, initial={"dphi": -2.5}, dt_out=0.01)
    errors = []
    for Ts in (4e-3, 2e-3, 1e-3):
        r = simulate_sampled(
            REFERENCE, SampledAffine(feedback), 4.0, Ts, initial={"dphi": -2.5}, dt_out=0.04
        )
        k = np.searchsorted(ref.tau, r.tau - 1e-12)
        np.testing.assert_allclose(ref.tau[k], r.tau, atol=1e-12)
        errors.append(float(np.max(np.abs(r.dphi - ref.dphi[k]))))
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    assert all(1.9 < q < 2.1 for q in ratios), (errors, ratios)
    assert errors[-1] < 5e-3


def test_sampled_loop_records_the_law_output_and_stops_like_the_engine():
    law = SpeedPI(kp=1.0, ki=0.5, R_ff=-K0_REF, t_on=6.0)
    # Fig. 6's open loop: with the torsional-stick model off the run stops where the bit stops
    # (tau = 5.57, docs/model.md, "Experiments of Figs. 5 and 6"), before the switch-on
    r = simulate_sampled(REFERENCE, law, 8.0, 1e-3, initial={"dphi": -4.9}, dt_out=0.01)
    assert r.status.code == "torsional_stick" and r.tau[-1] == pytest.approx(r.status.tau)
    assert 5.5 < r.tau[-1] < 5.6 and np.all(np.diff(r.tau) > 0)
    assert np.all(r.R_minus_R0 == -K0_REF)
    s = simulate_sampled(
        REFERENCE,
        law,
        8.0,
        1e-3,
        initial={"dphi": -4.9},
        options=EngineOptions(torsional_stick=True),
    )
    assert s.status.ok and s.tau[-1] == 8.0 and s.counters["torsional_stick_events"] > 0
    # the torque is continuous at switch-on (preset integrator), then -kp*dtheta + ki*I moves it
    k_on = int(np.searchsorted(s.tau, 6.0))
    assert s.tau[k_on] == pytest.approx(6.0) and np.all(s.R_minus_R0[:k_on] == -K0_REF)
    assert s.R_minus_R0[k_on] == pytest.approx(-K0_REF, abs=1e-12)
    assert np.max(np.abs(s.R_minus_R0[k_on + 1 :] + K0_REF)) > 0.01


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"tau_end": 1.0005}, "tau_end = 1.0005 is not a multiple"),
        ({"Ts": 0.0}, "Ts must be > 0"),
        ({"dt_out": 0.0015}, "dt_out = 0.0015 is not a multiple"),
        ({"dt_out": 0.0}, "dt_out must be > 0"),
    ],
)
def test_sampled_loop_refuses_bad_grids(kwargs, message):
    args = {"tau_end": 1.0, "Ts": 1e-3, "dt_out": 0.01, **kwargs}
    with pytest.raises(ValueError, match=message):
        simulate_sampled(REFERENCE, SpeedPI(1.0, 1.0), args.pop("tau_end"), **args)
