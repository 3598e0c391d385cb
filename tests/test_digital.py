"""The digital controller's top drive, anti-windup and sensing on hand-computed cases
(drillstring.model.digital, drillstring.model.topdrive, drillstring.model.sensing).

* every limit of the top drive by hand: torque range, power, braking, speed range, the lag's
  first-order response, the rate limit; without a top drive the command passes exactly;
* anti-windup (back-calculation, conditional integration) and the affine law's frozen angle by
  hand over a saturated stretch;
* telemetry frames, latency and noise; the noise is the same in the compiled and the plain
  Python code; the string torque from the motor is the twist for a table driven by (13);
* the named rating on the reference rig against its datasheet numbers converted by hand.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drillstring.model.control import AffineFeedback
from drillstring.model.digital.controller import DigitalController, OperatingPoint
from drillstring.model.digital.layout import BLOCK
from drillstring.model.laws import (
    FEED_FORWARD_PARAMS,
    LAW_SLOTS,
    FeedForward,
    SampledAffine,
    SpeedPI,
)
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.sampled import simulate_sampled
from drillstring.model.sensing import Sensing, gaussian, string_torque
from drillstring.model.topdrive import RPM, TDS_11SA, TopDrive, top_drive

POINT = OperatingPoint(omega0=5.0, R0=4.0, rho=5.0)


def _run(law, drive=None, sensing=None):
    return DigitalController(law, drive, sensing or Sensing()).start(POINT)


def _applied(drive, r_cmd, dtheta=0.0, tau=0.0):
    """R - R0 applied for a command, from rest (no history in the drive)."""
    return _run(FeedForward(R_ff=r_cmd), drive).output(tau, 0.0, 0.0, 0.0, dtheta)


# --------------------------------------------------------------------------------------------
# the top drive
# --------------------------------------------------------------------------------------------


def test_without_a_top_drive_the_command_is_applied_exactly():
    for r in (0.1, -3.7, 1e6, 1 / 3):
        assert _applied(None, r) == r  # not (R0 + r) - R0


def test_torque_range_and_power_limit_by_hand():
    drive = TopDrive(R_min=-10.0, R_max=20.0)
    assert _applied(drive, 1.0) == 1.0  # within everything: exact
    assert _applied(drive, 30.0) == pytest.approx(20.0 - 4.0)  # R = R_max
    assert _applied(drive, -30.0) == pytest.approx(-10.0 - 4.0)  # R = R_min
    power = TopDrive(R_min=-10.0, R_max=20.0, P_max=60.0)
    # at Omega = omega0 + dtheta = 5 the power allows |R| <= 60/5 = 12
    assert _applied(power, 30.0) == pytest.approx(12.0 - 4.0)
    assert _applied(power, -30.0) == pytest.approx(-10.0 - 4.0)  # the range is tighter
    # at Omega = 12 (dtheta = 7): |R| <= 5
    assert _applied(power, 30.0, dtheta=7.0) == pytest.approx(5.0 - 4.0)
    assert _applied(power, -30.0, dtheta=7.0) == pytest.approx(-5.0 - 4.0)


def test_braking_and_speed_range_by_hand():
    none = TopDrive(R_min=-10.0, R_max=20.0, braking="none")
    assert _applied(none, -30.0) == pytest.approx(0.0 - 4.0)  # no torque against the rotation
    assert _applied(none, 30.0) == pytest.approx(20.0 - 4.0)
    assert _applied(none, -30.0, dtheta=-6.0) == pytest.approx(-10.0 - 4.0)  # Omega < 0: R <= 0
    assert _applied(none, 30.0, dtheta=-6.0) == pytest.approx(0.0 - 4.0)
    band = TopDrive(R_min=-10.0, R_max=20.0, omega_min=0.0, omega_max=8.0)
    assert _applied(band, -30.0) == pytest.approx(-10.0 - 4.0)  # braking allowed inside
    assert _applied(band, 30.0, dtheta=3.0) == pytest.approx(0.0 - 4.0)  # at omega_max: R <= 0
    assert _applied(band, -30.0, dtheta=3.0) == pytest.approx(-10.0 - 4.0)
    assert _applied(band, -30.0, dtheta=-5.0) == pytest.approx(0.0 - 4.0)  # at omega_min: R >= 0
    assert _applied(band, 30.0, dtheta=-5.0) == pytest.approx(20.0 - 4.0)


def _command_step(drive, r, Ts):
    """At rest on R0 (one sample of R_ff = 0), then the command R_ff = r held."""
    run = _run(FeedForward(R_ff=0.0), drive)
    run.step(0.0, 0.0, 0.0, 0.0, 0.0, Ts)
    # the law's feed-forward, changed in place
    run.block[BLOCK.law + LAW_SLOTS.p + FEED_FORWARD_PARAMS.R_ff] = r
    return run


def test_drive_lag_is_the_first_order_response():
    """A command step held: R - R0 follows 2 (1 - exp(-t/T)) at the sample instants."""
    T, Ts = 0.02, 0.001
    run = _command_step(TopDrive(lag=T), 2.0, Ts)
    for k in range(1, 60):
        r = run.step(k * Ts, 0.0, 0.0, 0.0, 0.0, Ts)
        assert r == pytest.approx(2.0 * (1.0 - math.exp(-k * Ts / T)), rel=1e-12), k
        assert not run.saturated  # a lag is not a limit: no anti-windup acts on it


def test_rate_limit_by_hand():
    run = _command_step(TopDrive(rate=100.0), 5.0, 0.01)
    assert run.step(0.01, 0.0, 0.0, 0.0, 0.0, 0.01) == pytest.approx(1.0)  # 100 * 0.01
    assert run.saturated
    assert run.step(0.02, 0.0, 0.0, 0.0, 0.0, 0.01) == pytest.approx(2.0)
    for k in range(3, 8):
        r = run.step(k * 0.01, 0.0, 0.0, 0.0, 0.0, 0.01)
    assert r == 5.0 and not run.saturated  # reached: the command exactly


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: TopDrive(R_min=1.0, R_max=0.0), "R_min = 1.0 is above R_max = 0.0"),
        (lambda: TopDrive(lag=-1.0), "TopDrive.lag must be >= 0"),
        (lambda: TopDrive(rate=0.0), "TopDrive.rate must be > 0"),
        (lambda: TopDrive(R_max=math.nan), "TopDrive.R_max must be a real number or"),
        (lambda: TopDrive(braking="regenerative"), "TopDrive.braking must be one of"),
        (lambda: TopDrive(omega_min=3.0, omega_max=3.0), "omega_min = 3.0 is not below"),
    ],
)
def test_bad_top_drives_are_named(make, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        make()


def test_named_rating_on_the_reference_rig_by_hand():
    """37,500 ft lbf = 50.84 kN m, 800 hp = 596.6 kW, 228 rpm, converted by C and t*."""
    rig = REFERENCE_RIG
    td = top_drive(TDS_11SA, rig)
    torque = 37_500 * 0.3048 * 4.4482216152605  # ft lbf -> N m
    assert td.R_max == pytest.approx(torque / rig.C, rel=1e-12)
    assert td.R_max / REFERENCE.R0 == pytest.approx(49.0, abs=0.1)  # about 49 R0
    assert td.R_min == -td.R_max and td.braking == "four-quadrant"
    assert td.P_max == pytest.approx(800 * 745.69987158227022 * rig.t_star / rig.C, rel=1e-12)
    assert td.omega_max == pytest.approx(228 * 2 * math.pi / 60 * rig.t_star, rel=1e-12)
    assert td.omega_min == 0.0 and td.lag == pytest.approx(0.010 / rig.t_star)
    back = td.to_si(rig)
    assert back["R_max"] == pytest.approx(torque, rel=1e-12)
    assert back["omega_max"] / RPM == pytest.approx(228.0, rel=1e-12)


# --------------------------------------------------------------------------------------------
# anti-windup and the affine law's saturation behaviour
# --------------------------------------------------------------------------------------------


def _pi_saturated(anti_windup, n=6):
    """SpeedPI kp = 1, ki = 2 against a drive limited to R <= R0 + 0.1, speed error e = 1 held:
    (applied R - R0, integral after the sample, command) per sample from the switch-on."""
    law = SpeedPI(kp=1.0, ki=2.0, anti_windup=anti_windup, tracking_time=0.25)
    run = _run(law, TopDrive(R_max=POINT.R0 + 0.1))
    out = []
    for k in range(n):
        out.append((run.step(k * 0.1, 0.0, 0.0, 0.0, -1.0, 0.1), run.law_state[0], run.commanded))
    return out


def test_back_calculation_by_hand():
    """I' = e + (r_lim - r_cmd)/(ki Tt), forward Euler: e = 1, r_cmd = 1 + 2 I, r_lim <= 0.1;
    the integral preset at switch-on to -kp e/ki = -0.5 (r_cmd = 0: bumpless)."""
    I = -0.5  # noqa: E741
    for r_app, integral, r_cmd in _pi_saturated("back-calculation"):
        cmd = 1.0 + 2.0 * I
        lim = min(cmd, 0.1)
        assert r_cmd == pytest.approx(cmd, rel=1e-14, abs=1e-15)
        assert r_app == pytest.approx(lim, rel=1e-12, abs=1e-15)
        I = I + 0.1 * (1.0 + (lim - cmd) / (2.0 * 0.25))  # noqa: E741
        assert integral == pytest.approx(I, rel=1e-14)


def test_conditional_integration_holds_the_integral_while_saturated():
    got = _pi_saturated("conditional")
    windup = _pi_saturated("none")
    assert got[0][1] == pytest.approx(-0.4)  # the switch-on sample is not saturated: I moves
    # saturated afterwards, the error pushing further: held
    assert [g[1] for g in got[1:]] == pytest.approx([-0.4] * 5)
    assert windup[-1][1] == pytest.approx(-0.4 + 0.5)  # without anti-windup it winds up
    assert all(g[0] == pytest.approx(0.1) for g in got[1:])


def _freeze(on_saturation):
    """F = (-10, -10, 0, 0), R <= R0 + 3: the bit falls behind (dphi = -0.5) for six samples,
    then recovers (dphi = +0.5); applied torques."""
    f = AffineFeedback(F=(-10.0, -10.0, 0.0, 0.0), K0=0.0, R_ff=0.0, t_on=0.0, latch="angle")
    run = _run(SampledAffine(f, on_saturation), TopDrive(R_max=POINT.R0 + 3.0))
    out = []
    for k in range(8):
        phi = -0.05 * k if k <= 5 else -0.25 + 0.05 * (k - 5)
        dphi = -0.5 if k <= 5 else 0.5
        out.append(run.step(k * 0.1, phi, dphi, 0.0, 0.0, 0.1))
    return out


def test_the_affine_law_freezes_its_angle_while_saturated():
    """r = -10 x1 - 10 dphi. Frozen: x1 held at 0 while the command (5) exceeds the limit 3;
    from the sample it comes back (k = 6, -5) x1 goes on from 0: k = 7, x1 = 0.05, -5.5. The
    paper's law instead makes up the lag: x1 = phi, -10 (-0.2) - 5 = -3 at k = 6."""
    assert _freeze("freeze-angle") == pytest.approx([3.0] * 6 + [-5.0, -5.5], rel=1e-12)
    assert _freeze("none") == pytest.approx([3.0] * 6 + [-3.0, -3.5], rel=1e-12)


# --------------------------------------------------------------------------------------------
# sensing
# --------------------------------------------------------------------------------------------


def test_telemetry_frames_and_latency():
    f = AffineFeedback(F=(0.0, 1.0, 0.0, 0.0), K0=0.0, R_ff=0.0, t_on=0.0, latch="none")
    s = Sensing(downhole="telemetry", period=0.5, latency=0.3)
    run = _run(SampledAffine(f), sensing=s)
    seen = []
    for k in range(25):
        tau = k * 0.1
        seen.append(run.step(tau, 0.0, tau, 0.0, 0.0, 0.1))  # dphi = tau
    # frames at 0, 0.5, 1.0, ... with dphi = their time, used from 0.3 later; nominal before
    expect = [0.0 if k * 0.1 < 0.3 - 1e-12 else 0.5 * math.floor((k * 0.1 - 0.3) / 0.5 + 1e-9)
              for k in range(25)]  # fmt: skip
    assert seen == pytest.approx(expect, abs=1e-12)


def test_telemetry_noise_is_gaussian_seeded_and_the_same_in_python():
    draws = np.array([gaussian(7, k, 0) for k in range(20000)])
    assert abs(draws.mean()) < 0.03 and abs(draws.std() - 1.0) < 0.02
    other = np.array([gaussian(8, k, 0) for k in range(200)])
    assert not np.array_equal(draws[:200], other)
    py = getattr(gaussian, "py_func", gaussian)
    assert [py(7, k, 1) for k in range(50)] == [gaussian(7, k, 1) for k in range(50)]
    f = AffineFeedback(F=(0.0, 1.0, 0.0, 0.0), K0=0.0, R_ff=0.0, latch="none")
    s = Sensing(downhole="telemetry", period=0.1, noise_dphi=0.2, seed=7)
    r1, r2 = _run(SampledAffine(f), sensing=s), _run(SampledAffine(f), sensing=s)
    a = [r1.step(k * 0.1, 0.0, 0.0, 0.0, 0.0, 0.1) for k in range(100)]
    assert a == [r2.step(k * 0.1, 0.0, 0.0, 0.0, 0.0, 0.1) for k in range(100)]
    assert np.std(a) == pytest.approx(0.2, rel=0.2)


def test_string_torque_from_the_motor_is_the_twist_of_equation_13():
    """A table driven by (13) with the held torque r and a constant twist w: rho dtheta' = r - w;
    the estimate r_prev - rho (dtheta - dtheta_prev)/Ts is w to rounding."""
    run = _run(SpeedPI(kp=0.3, ki=0.2), sensing=Sensing(torque="motor"))
    dtheta, w, Ts = 0.2, 0.7, 0.01
    for k in range(30):
        r = run.step(k * Ts, -w, 0.0, 0.0, dtheta, Ts)  # the twist theta - phi = w
        dtheta += Ts * (r - w) / POINT.rho  # (13) over the sample
        estimate = string_torque(run.block, BLOCK.sensing, POINT.rho, w, dtheta)
        assert estimate == pytest.approx(w, rel=1e-10)


def test_bad_sensing_is_named():
    with pytest.raises(ValueError, match="Sensing.torque must be one of"):
        Sensing(torque="strain")
    with pytest.raises(ValueError, match="more than 62 frame periods"):
        Sensing(downhole="telemetry", period=0.1, latency=7.0)
    with pytest.raises(ValueError, match="needs an Observer"):
        Sensing(downhole="observer")


def test_a_complete_sampled_run_reports_where_it_ended():
    # the status of a run that reached tau_end names tau_end (it said 0.0: the status of a
    # run without a buffer drain was the initial one)
    r = simulate_sampled(REFERENCE, SpeedPI(kp=4.47, ki=5.0), 2.0, 1e-3)
    assert r.status.ok and r.status.tau == pytest.approx(2.0, abs=1e-12) == r.tau[-1]
