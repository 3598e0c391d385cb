"""Severity metrics (drillstring.analysis.severity) on synthetic signals with known answers."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from drillstring.analysis.severity import (
    Severity,
    actuator_demand,
    axial_average,
    axial_period,
    best_controller,
    outcome,
    severity_metrics,
    speed_severity,
    stick_fraction,
    utr,
    window_start,
)
from drillstring.model.engine import Event, Status
from drillstring.model.params import REFERENCE
from drillstring.model.topdrive import TopDrive

W0 = REFERENCE.omega0  # 5


def _mode_event(tau, frm, to):
    return Event(tau, "mode", frm, to, 0.0, 0.0, 0.0, 0.0)


def test_utr_and_severity_of_a_sine():
    """omega = omega0 + a*sin over whole periods (samples at the extremes): UTR = a/omega0,
    severity = (2a)/(2*omega0)."""
    t = np.arange(400) * (2 * math.pi / 400) * 3  # three periods, end excluded
    w = W0 + 2.0 * np.sin(t + math.pi / 2)
    assert utr(w, W0) == pytest.approx(2.0 / W0, rel=1e-12)
    assert speed_severity(w) == pytest.approx(2.0 / W0, rel=1e-12)
    assert utr(np.full(5, W0), W0) == 0.0 and speed_severity(np.full(5, W0)) == 0.0


def test_utr_and_severity_of_a_stick_slip_sawtooth():
    """Bit speed 0 .. 10 in a sawtooth: it stops (UTR 1), mean 5, severity (10 - 0)/(2*5) = 1."""
    w = 10.0 * (np.arange(100) % 10) / 9.0
    assert utr(w, W0) == 1.0
    assert float(np.mean(w)) == pytest.approx(5.0, rel=1e-15)
    assert speed_severity(w) == pytest.approx(1.0, rel=1e-15)
    assert math.isnan(speed_severity(np.zeros(4)))  # a stalled bit has no mean speed


def test_stick_fraction_is_exact_from_the_mode_events():
    events = [
        _mode_event(2.0, "slip", "torsional_stick"),
        _mode_event(3.0, "torsional_stick", "stick"),
        _mode_event(4.0, "stick", "slip"),  # axial mode changes do not count
        _mode_event(6.0, "slip", "torsional_stick"),
        _mode_event(8.5, "torsional_stick", "slip"),
    ]
    assert stick_fraction(events, 0.0, 10.0, "slip") == pytest.approx(3.5 / 10.0, rel=1e-15)
    # a window that starts inside a stick
    got = stick_fraction(events, 2.5, 7.0, "torsional_stick")
    assert got == pytest.approx((0.5 + 1.0) / 4.5, rel=1e-15)
    with pytest.raises(ValueError, match="t1 > t0"):
        stick_fraction(events, 3.0, 3.0, "slip")


def test_actuator_demand_from_the_switch_on():
    """Peak and least torque, peak power |R Omega| and table speed range, by hand."""
    tau = np.linspace(0.0, 10.0, 11)
    r = np.array([50.0, 0, 0, 1.0, 2.5, -5.0, 0, 0, 0, 0, 0])
    dtheta = np.array([9.0, 0, 0, 1.0, -1.0, -3.5, 0, 0, 0, 0, 0])
    d = actuator_demand(tau, r, dtheta, 4.0, 2.0, t_from=2.0)
    assert (d.peak_torque, d.min_torque) == (6.5, -1.0)
    # |R Omega| at tau = 3, 4, 5: 5 * 3, 6.5 * 1, |-1 * -1.5|
    assert d.peak_power == 15.0
    assert (d.min_table_speed, d.max_table_speed) == (-1.5, 3.0)
    assert actuator_demand(tau, r, dtheta, 4.0, 2.0).peak_torque == 54.0
    si = d.to_si(C=100.0, t_star=0.5)
    assert si == {"peak_torque": 650.0, "min_torque": -100.0, "peak_power": 3000.0,
                  "min_table_speed": -3.0, "max_table_speed": 6.0}  # fmt: skip
    rated = TopDrive(R_min=-1.0, R_max=6.5, P_max=15.0, omega_min=-1.5, omega_max=3.0)
    assert d.within(rated) and d.within(TopDrive())  # at its limits; no limits
    for short in ({"R_min": -0.5}, {"R_max": 6.4}, {"P_max": 14.9}, {"omega_min": 0.0},
                  {"omega_max": 2.9}):  # fmt: skip
        assert not d.within(dataclasses.replace(rated, **short)), short
    with pytest.raises(ValueError, match="no samples at or after t_from = 11"):
        actuator_demand(tau, r, dtheta, 4.0, 2.0, t_from=11.0)
    with pytest.raises(ValueError, match="differ in shape"):
        actuator_demand(tau, r, dtheta[:-1], 4.0, 2.0)


def test_window_start():
    tau = np.linspace(0.0, 60.0, 6001)
    j = window_start(tau, 20.0)
    assert tau[j] == pytest.approx(40.0) and tau[j - 1] < 40.0
    with pytest.raises(ValueError, match="window = 61.0 is longer than the run"):
        window_start(tau, 61.0)


def _result(tau, dphi, mode, events, r=None, status="ok"):
    r = np.zeros_like(tau) if r is None else r
    data = {"tau": tau, "dphi": dphi, "dtheta": np.zeros_like(tau), "mode": mode, "R_minus_R0": r}
    return SimpleNamespace(
        params=REFERENCE,
        data=data,
        **data,
        events=events,
        status=Status(status, "", float(tau[-1])),
    )


def test_severity_metrics_of_a_stall():
    """Stuck from tau = 30 to the end of a 60-long run: over the last 20 the bit never moves."""
    tau = np.linspace(0.0, 60.0, 601)
    stuck = tau >= 30.0
    dphi = np.where(stuck, -W0, 0.3 * np.sin(tau))
    mode = np.where(stuck, 3, 0)
    events = [_mode_event(30.0, "slip", "torsional_stick")]
    s = severity_metrics(_result(tau, dphi, mode, events), 20.0)
    assert s.stall and s.outcome == "stall" and s.utr == 1.0 and s.stick_fraction == 1.0
    assert math.isnan(s.severity) and s.tau_reached == 60.0
    assert s.peak_torque == pytest.approx(REFERENCE.R0)


def test_severity_metrics_of_stick_slip_steady_and_a_stopped_run():
    tau = np.linspace(0.0, 60.0, 6001)
    # stick-slip: stuck on [45, 46) and [52, 53.5), speed 0 there
    events = [
        _mode_event(45.0, "slip", "torsional_stick"),
        _mode_event(46.0, "torsional_stick", "slip"),
        _mode_event(52.0, "slip", "torsional_stick"),
        _mode_event(53.5, "torsional_stick", "slip"),
    ]
    stuck = ((tau >= 45) & (tau < 46)) | ((tau >= 52) & (tau < 53.5))
    dphi = np.where(stuck, -W0, 2.0)
    s = severity_metrics(_result(tau, dphi, np.where(stuck, 3, 0), events), 20.0)
    assert s.outcome == "stick-slip" and not s.stall
    assert s.stick_fraction == pytest.approx(2.5 / 20.0, rel=1e-12)
    assert s.utr == 1.0
    # steady: a small ripple, no stick
    ripple = 0.01 * np.sin(3 * tau)
    s = severity_metrics(_result(tau, ripple, np.zeros_like(tau), []), 20.0)
    assert s.outcome == "steady" and s.stick_fraction == 0.0
    # averaged over the default axial period 2 pi/eta (no axial stick events): damped by the
    # moving average's factor sin(x)/x, x = 3*pi/eta
    x = 3.0 * math.pi / REFERENCE.eta
    assert s.severity == pytest.approx(0.01 * math.sin(x) / x / W0, rel=2e-3)
    assert outcome(0.06, 0.0, False) == "vibration"
    # a run that stopped: no numbers, its status as outcome
    s = severity_metrics(
        _result(tau[:100], ripple[:100], np.zeros(100), [], status="bit_bounce"), 20.0
    )
    assert s.outcome == "bit_bounce" and math.isnan(s.utr) and math.isnan(s.peak_torque)


def test_the_axial_cycle_averages_out_and_the_torsional_severity_remains():
    """A bit speed with a torsional part a*sin(t) and an axial ripple b*sin(2 pi t/P): averaged
    over the axial period P (k samples) the ripple is gone exactly; the torsional part is the
    mean of k samples of a sine, sin(t - (k-1) dt/2) sin(k dt/2)/(k sin(dt/2))."""
    P, a, b = 0.25, 0.3, 0.2
    tau = np.arange(0, 60.0 + 1e-9, 0.005)
    w = W0 + a * np.sin(tau) + b * np.sin(2 * math.pi * tau / P)
    entries = [_mode_event(t, "slip", "stick") for t in np.arange(0.1, 60.0, P)]
    assert axial_period(entries, 40.0, 60.0, 1.0) == pytest.approx(P, rel=1e-12)
    assert axial_period(entries[:2], 40.0, 60.0, 1.0) == 1.0  # no cycle: the default
    t, wa = axial_average(tau, w, P)
    dt, k = 0.005, 50
    factor = math.sin(k * dt / 2) / (k * math.sin(dt / 2))
    expect = W0 + a * factor * np.sin(t - (k - 1) * dt / 2)
    assert np.max(np.abs(wa - expect)) < 1e-10  # the running sum: 12000 values of about 5
    s = severity_metrics(_result(tau, w - W0, np.zeros_like(tau), entries), 20.0)
    assert s.severity == pytest.approx(a * factor / W0, rel=2e-3)  # not (a + b)/W0
    assert speed_severity(w[tau >= 40]) == pytest.approx((a + b) / W0, rel=2e-2)


def test_a_decay_is_settling_a_sustained_vibration_is_not():
    tau = np.arange(0, 100.0 + 1e-9, 0.01)
    decaying = 3.0 * np.exp(-0.03 * tau) * np.sin(tau)
    s = severity_metrics(_result(tau, decaying, np.zeros_like(tau), []), 30.0)
    assert s.outcome == "settling"  # severity 0.07 > 0.05, the amplitude falls by e^-0.9
    sustained = 0.5 * np.sin(tau)
    assert severity_metrics(_result(tau, sustained, np.zeros_like(tau), []), 30.0).outcome == (
        "vibration"
    )
    # settling time: the averaged speed leaves the 5% band (0.25) for the last time where
    # exp(-0.05 t) ~ 0.25 (the average over the default axial period 2 pi/eta barely damps)
    fast = 2.0 * np.exp(-0.5 * tau) * np.sin(5 * tau)
    s = severity_metrics(_result(tau, fast, np.zeros_like(tau), []), 30.0, t_from=0.0)
    assert s.outcome == "steady"
    assert 2.0 < s.settling_time < math.log(2.0 / 0.25) / 0.5 + 0.5
    assert math.isnan(severity_metrics(_result(tau, sustained, np.zeros_like(tau), []),
                                       30.0).settling_time)  # fmt: skip


def test_torque_and_power_metrics_by_hand():
    tau = np.arange(0, 60.0 + 1e-9, 0.01)
    r = np.where(tau >= 50.0, 3.0, 1.0)  # R = R0 + r
    res = _result(tau, np.zeros_like(tau), np.zeros_like(tau), [], r=r)
    s = severity_metrics(res, 20.0, t_from=25.0)
    R0 = REFERENCE.R0
    assert s.peak_torque_late == pytest.approx(R0 + 3.0)
    # RMS over [40, 60]: half the samples R0 + 1, half (and the end point) R0 + 3
    late = tau >= 40.0 - 1e-9
    expect = math.sqrt(np.mean((R0 + r[late]) ** 2))
    assert s.rms_torque_late == pytest.approx(expect, rel=1e-12)
    assert s.peak_power == pytest.approx((R0 + 3.0) * W0)  # dtheta = 0: Omega = omega0
    assert s.min_table_speed == W0 and math.isnan(s.saturated_fraction)


def _sev(severity, torque, out="steady"):
    return Severity(severity, severity, 0.0, torque, out == "stall", out, 60.0)


def test_best_controller_ranking():
    m = {
        "stiff-pi": _sev(1.0, 10.0, "stick-slip"),
        "soft-speed": _sev(0.015, 8.0),
        "z-torque": _sev(0.0, 12.0),
        "lmi": _sev(0.0, 5000.0),
    }
    # within the tie of 0.02 of the lowest severity the least torque wins
    assert best_controller(m) == "soft-speed"
    assert best_controller(m, tie=0.0) == "z-torque"
    m["soft-speed"] = _sev(math.nan, math.nan, "bit_bounce")
    m["z-torque"] = _sev(math.nan, 1.0, "stall")
    assert best_controller(m) == "lmi"
    # a negative UTR (the bit above omega0 all through the window) does not rank: severity does
    fast = Severity(-0.2, 0.3, 0.0, 1.0, False, "vibration", 60.0)
    slow = Severity(0.05, 0.05, 0.0, 9.0, False, "vibration", 60.0)
    assert best_controller({"fast": fast, "slow": slow}) == "slow"
    assert best_controller({"a": _sev(math.nan, math.nan, "reverse_rotation")}) == ""
