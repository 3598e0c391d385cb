"""The controller's own period and latency (drillstring/model/timing.py):
a latency of one period delays the applied torque by exactly one period, the law's state
advances by its own period, the default is the controller of before bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from drillstring.controller.averaged import averaged_model
from drillstring.controller.lineup import SENSING, TIMED_CONTROLLERS, LmiGain, rig_lineup
from drillstring.model.digital.controller import DigitalController, OperatingPoint
from drillstring.model.experiments import FIG6
from drillstring.model.laws import SpeedPI
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.sampled import simulate_sampled
from drillstring.model.timing import N_PENDING, Timing
from drillstring.model.topdrive import TDS_11SA, top_drive

POINT = OperatingPoint(omega0=5.0, R0=4.0, rho=5.0)
T_STAR = 0.9225  # the reference rig's t* [s]
SUB = 10  # host samples per controller period


def _response(law, timing, Ts, step_at, n=80, size=-1.0):
    """The applied torque for a step of ``size`` in the measured table speed at sample
    ``step_at`` (the host sampling every ``Ts``)."""
    run = DigitalController(law, timing=timing).start(POINT)
    out = []
    for k in range(n):
        dtheta = size if k >= step_at else 0.0
        out.append(run.step(k * Ts, 0.0, 0.0, 0.0, dtheta, Ts))
    return np.array(out)


@pytest.mark.parametrize("ms", [10, 20, 50])
@pytest.mark.parametrize("step_at", [20, 25])
def test_one_period_of_latency_delays_the_torque_by_exactly_one_period(ms, step_at):
    P = ms * 1e-3 / T_STAR  # 10, 20, 50 ms on the reference rig, scaled
    Ts = P / SUB
    law = SpeedPI(kp=2.0, ki=0.0)
    late = _response(law, Timing(period=P, latency=P), Ts, step_at)
    now = _response(law, Timing(period=P), Ts, step_at)
    # without latency the law sees the step at its next computation and applies it at once
    seen = -(-step_at // SUB) * SUB
    assert np.all(now[:seen] == 0.0) and np.all(now[seen:] == 2.0)
    # with one period of latency: the same torque exactly one period (SUB samples) later
    assert np.all(late[: seen + SUB] == 0.0)
    assert np.array_equal(late[SUB:], now[:-SUB])
    # and, in time, one period after the computation from the stepped measurement
    first = int(np.argmax(late != 0.0))
    assert first * Ts - seen * Ts == pytest.approx(P, rel=1e-12)


def test_the_law_advances_by_its_own_period_and_holds_its_command():
    P, Ts = 0.05, 0.005
    law = SpeedPI(kp=0.0, ki=1.0)  # the torque is the integral of the speed error
    r = _response(law, Timing(period=P), Ts, step_at=0, n=40)
    # computed at samples 0, 10, 20, 30 from e = 1 over P each: 0, P, 2P, 3P, held between
    assert np.array_equal(r, np.repeat([0.0, 1.0, 2.0, 3.0], 10) * P)


def test_a_host_that_samples_off_the_period_computes_at_the_first_sample_after_it():
    P = 20e-3 / T_STAR
    Ts = 1e-3  # the comparison's host period: 0.9225 ms, not a divisor of 20 ms
    law = SpeedPI(kp=2.0, ki=0.0)
    r = _response(law, Timing(period=P, latency=P), Ts, step_at=1, n=200)
    k = np.arange(200)
    computed = int(np.ceil(P / Ts))  # the first computation after the step: at or after P
    first = int(np.argmax(r != 0.0))
    # applied at the first sample at or after that computation + P
    assert first == int(np.ceil((computed * Ts + P) / Ts - 1e-9))
    assert first * Ts - computed * Ts == pytest.approx(P, abs=Ts)
    assert np.all(r[k >= first] == 2.0)


def test_the_default_and_a_period_of_one_host_sample_are_the_controller_of_before():
    drive = top_drive(TDS_11SA, REFERENCE_RIG)
    law = SpeedPI(kp=20.0, ki=100.0, R_ff=0.5, t_on=FIG6.t_on)
    Ts = 1e-3
    start = {"initial": FIG6.initial(), "dt_out": Ts}
    runs = [
        simulate_sampled(REFERENCE, DigitalController(law, drive, timing=t), 27.0, Ts, **start)
        for t in (Timing(), Timing(period=Ts))
    ]
    assert np.array_equal(runs[0].R_minus_R0, runs[1].R_minus_R0)
    assert np.array_equal(runs[0].dtheta, runs[1].dtheta)
    assert np.ptp(runs[0].R_minus_R0[runs[0].tau > FIG6.t_on]) > 0.0


def test_timing_is_checked_and_converts_to_seconds():
    with pytest.raises(ValueError, match="needs the controller's own period"):
        Timing(latency=0.1)
    with pytest.raises(ValueError, match="Timing.period"):
        Timing(period=-1.0)
    with pytest.raises(ValueError, match=f"more than {N_PENDING - 2} periods"):
        Timing(period=0.01, latency=0.01 * (N_PENDING - 1))
    t = Timing.from_si(REFERENCE_RIG, {"period": 0.02, "latency": 0.02})
    assert t.period == pytest.approx(0.02 / REFERENCE_RIG.t_star)
    assert t.to_si(REFERENCE_RIG) == pytest.approx({"period": 0.02, "latency": 0.02})
    with pytest.raises(TypeError, match="timing"):
        DigitalController(SpeedPI(kp=1.0, ki=1.0), timing=0.02)


def test_the_timed_rows_are_their_controller_with_one_period_of_latency():
    model = averaged_model(REFERENCE, 0.385415, 2.392788)
    paper = LmiGain(F=(-3353.65, -2028.44, 520.61, -57.11), K0=model.K0, R_ff=model.R_ff,
                    abscissa=float("nan"))  # fmt: skip
    drive = top_drive(TDS_11SA, REFERENCE_RIG)
    kw = {"paper": paper, "top_drive": drive, "scales": REFERENCE_RIG, "Ts": 1e-3}
    timed = rig_lineup(REFERENCE, model, constrained=paper, names=list(TIMED_CONTROLLERS), **kw)
    assert list(timed) == list(TIMED_CONTROLLERS)
    plain = rig_lineup(REFERENCE, model, constrained=paper, **kw)
    for name, (of, period) in TIMED_CONTROLLERS.items():
        P = period / REFERENCE_RIG.t_star
        assert timed[name].timing == Timing(period=P, latency=P)
        assert timed[name].law == plain[of].law and timed[name].sensing == plain[of].sensing
        assert (
            SENSING[name].startswith(SENSING[of]) and f"{period * 1e3:g} ms late" in SENSING[name]
        )
    assert {p for _, p in TIMED_CONTROLLERS.values()} == {0.01, 0.02, 0.05}
