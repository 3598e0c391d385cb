"""Severity metrics (drillstring.analysis.severity) on synthetic signals with known answers."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from drillstring.analysis.severity import (
    Severity,
    best_controller,
    outcome,
    peak_torque,
    severity_metrics,
    speed_severity,
    stick_fraction,
    utr,
    window_start,
)
from drillstring.model.engine import Event, Status
from drillstring.model.params import REFERENCE

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


def test_peak_torque_from_the_switch_on():
    tau = np.linspace(0.0, 10.0, 11)
    r = np.array([50.0, 0, 0, 1.0, 2.5, -1.0, 0, 0, 0, 0, 0])
    assert peak_torque(tau, r, 4.0, t_from=2.0) == 6.5
    assert peak_torque(tau, r, 4.0) == 54.0
    with pytest.raises(ValueError, match="no samples at or after t_from = 11"):
        peak_torque(tau, r, 4.0, t_from=11.0)


def test_window_start():
    tau = np.linspace(0.0, 60.0, 6001)
    j = window_start(tau, 20.0)
    assert tau[j] == pytest.approx(40.0) and tau[j - 1] < 40.0
    with pytest.raises(ValueError, match="window = 61.0 is longer than the run"):
        window_start(tau, 61.0)


def _result(tau, dphi, mode, events, r=None, status="ok"):
    return SimpleNamespace(
        params=REFERENCE,
        tau=tau,
        dphi=dphi,
        mode=mode,
        events=events,
        R_minus_R0=np.zeros_like(tau) if r is None else r,
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
    assert s.severity == pytest.approx(0.01 / W0, rel=1e-3)
    assert outcome(0.06, 0.0, False) == "vibration"
    # a run that stopped: no numbers, its status as outcome
    s = severity_metrics(
        _result(tau[:100], ripple[:100], np.zeros(100), [], status="bit_bounce"), 20.0
    )
    assert s.outcome == "bit_bounce" and math.isnan(s.utr) and math.isnan(s.peak_torque)


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
