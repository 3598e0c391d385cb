"""The plant and controller FMUs driven one by one through fmpy.

* the plant FMU equals the monolithic engine run with the same piecewise-constant input;
* FMU states (get/set, serialize/deserialize) restore bit for bit at 100 random instants, also
  into a fresh instance with other parameters;
* two instances with different parameters do not influence each other;
* the controller output is (29)-(31) with the bumpless switch-on, checked against the formula.

What the FMUs answer to bad input is the conformance table, tests/test_fmu_conformance.py.
"""

from __future__ import annotations

import math

import fmu_testlib as tl
import numpy as np
import pytest

from drillstring.model.control import LATCH_MODES
from drillstring.model.engine import Engine, EngineOptions
from drillstring.model.params import REFERENCE

pytestmark = pytest.mark.fmu

H_NS = 10_000_000  # macro step 0.01
REALS = ("u", "du", "phi", "dphi", "theta", "dtheta", "d", "g", "tau_n")
INTS = ("mode", "stick_events", "bit_bounce", "torsional_stick")


def _record(s: tl.Slave) -> list[float]:
    return s.get(*REALS) + s.get(*INTS)


def _step(s: tl.Slave, k: int, r: float) -> list[float]:
    t, h = tl.grid(k, H_NS)
    s.set(R_minus_R0=r)
    s.fmu.doStep(t, h)
    return _record(s)


def _torque(k: int) -> float:
    return 0.3 * math.sin(0.05 * k)


# ------------------------------------------------------------------------------------------------
# plant against the engine
# ------------------------------------------------------------------------------------------------


def test_plant_alone_equals_monolithic_engine(built):
    """tau in [0, 20], macro step 0.01, R - R0 = 0: same engine, same arithmetic."""
    s = tl.Slave(built.plant, "alone").init()
    try:
        fmu = np.array([_step(s, k, 0.0) for k in range(2000)])
    finally:
        s.free()
    eng = Engine(REFERENCE, options=EngineOptions(keep_events=False), initial={"dphi": -2.5})
    ref = []
    for k in range(2000):
        t, h = tl.grid(k, H_NS)
        eng.set_input(0.0)
        assert eng.advance(t + h).ok
        out = eng.outputs()
        ref.append([out[n] for n in REALS + INTS])
    ref = np.array(ref)
    err = np.max(np.abs(fmu - ref))
    print(f"plant FMU vs engine over [0, 20]: max |difference| = {err:.3g}")
    assert err <= 1e-12
    assert fmu[-1, len(REALS) + 1] >= 20  # a stick-slip run with many located events


# ------------------------------------------------------------------------------------------------
# FMU state
# ------------------------------------------------------------------------------------------------


def test_plant_state_round_trip_is_bit_exact(built):
    n = 1000
    ref_slave = tl.Slave(built.plant, "reference").init()
    try:
        reference = [_step(ref_slave, k, _torque(k)) for k in range(n)]
    finally:
        ref_slave.free()

    rng = np.random.default_rng(20110831)
    instants = set(int(k) for k in rng.choice(np.arange(1, n), size=100, replace=False))
    cross = sorted(instants)[::34]  # three of them also continue in a fresh instance
    s = tl.Slave(built.plant, "interrupted").init()
    disturbed = 0
    try:
        rows = []
        for k in range(n):
            if k in instants:
                state = s.fmu.getFMUstate()
                data = s.fmu.serializeFMUstate(state)
                before = _record(s)
                for j in range(1 + k % 3):  # move on with another input, then come back
                    _step(s, k + j, 1.0)
                disturbed += _record(s) != before
                if k % 2:  # restore from the bytes ...
                    s.fmu.freeFMUstate(state)
                    state = s.fmu.deSerializeFMUstate(data)
                s.fmu.setFMUstate(state)  # ... or from the state itself
                s.fmu.freeFMUstate(state)
                assert _record(s) == before
                if k in cross:
                    _continue_elsewhere(built, data, k, reference)
            rows.append(_step(s, k, _torque(k)))
    finally:
        s.free()
    assert disturbed == 100
    assert rows == reference  # bit for bit, every output at every step


def _continue_elsewhere(built, data: bytes, k: int, reference: list[list[float]]) -> None:
    """Deserialize into a fresh instance initialized with other parameters; continue 20 steps."""
    other = tl.Slave(built.plant, f"fresh_{k}").init(psi=300.0, gamma=3.0, dphi0=-1.0)
    try:
        state = other.fmu.deSerializeFMUstate(data)
        other.fmu.setFMUstate(state)
        other.fmu.freeFMUstate(state)
        assert other.get("psi", "gamma", "dphi0") == [REFERENCE.psi, REFERENCE.gamma, -2.5]
        rows = [_step(other, k + j, _torque(k + j)) for j in range(20)]
        assert rows == reference[k : k + 20]
    finally:
        other.free()


def test_controller_state_round_trip_across_the_switch_on(built):
    """Save before t_on, step past it with other inputs (latching a wrong reference), restore."""
    rng = np.random.default_rng(7)
    x = rng.normal(size=(40, 4))

    def run(c: tl.Slave, ks: range, inputs: np.ndarray) -> list[float]:
        out = []
        for k in ks:
            c.set(**dict(zip(tl.FEEDBACK, inputs[k], strict=True)))
            t, h = tl.grid(k, H_NS)
            c.fmu.doStep(t, h)
            out.append(c.get("R_minus_R0")[0])
        return out

    ref = tl.Slave(built.controller, "c_ref").init(t_on=0.1)
    c = tl.Slave(built.controller, "c_state").init(t_on=0.1)
    try:
        expected = run(ref, range(40), x)
        first = run(c, range(5), x)
        data = c.fmu.serializeFMUstate(state := c.fmu.getFMUstate())
        c.fmu.freeFMUstate(state)
        wrong = run(c, range(5, 20), -x)
        state = c.fmu.deSerializeFMUstate(data)
        c.fmu.setFMUstate(state)
        c.fmu.freeFMUstate(state)
        rest = run(c, range(5, 40), x)
    finally:
        ref.free()
        c.free()
    assert wrong != expected[5:20]
    assert first + rest == expected


# ------------------------------------------------------------------------------------------------
# independence of instances
# ------------------------------------------------------------------------------------------------


def test_two_plant_instances_are_independent(built):
    other = {"psi": 300.0, "gamma": 3.0, "dphi0": -1.0, "h": 2.5e-4}
    n = 300
    solo_a = tl.Slave(built.plant, "solo_a").init()
    solo_a_rows = [_step(solo_a, k, _torque(k)) for k in range(n)]
    solo_a.free()
    solo_b = tl.Slave(built.plant, "solo_b").init(**other)
    solo_b_rows = [_step(solo_b, k, -_torque(k)) for k in range(n)]
    solo_b.free()

    a = tl.Slave(built.plant, "pair_a").init()
    b = tl.Slave(built.plant, "pair_b").init(**other)
    try:
        rows_a, rows_b = [], []
        for k in range(n):  # interleaved, in one process
            rows_b.append(_step(b, k, -_torque(k)))
            rows_a.append(_step(a, k, _torque(k)))
    finally:
        a.free()
        b.free()
    assert rows_a == solo_a_rows
    assert rows_b == solo_b_rows
    assert rows_a != rows_b


# ------------------------------------------------------------------------------------------------
# controller law
# ------------------------------------------------------------------------------------------------


def _law(g: dict, phi, dphi, theta, dtheta, phi_ref=0.0, twist_ref=0.0) -> float:
    """(29)-(31) written out: R - R0 = R_ff + F x, x = [phi - phi_ref, dphi, phi - theta - K0 -
    twist_ref, dtheta]."""
    F, K0 = g["F"], g["K0"]
    x = [phi - phi_ref, dphi, phi - theta - K0 - twist_ref, dtheta]
    return g["R_ff"] + sum(f * xi for f, xi in zip(F, x, strict=True))


def _set_x(c: tl.Slave, x: tuple[float, float, float, float]) -> None:
    c.set(**dict(zip(tl.FEEDBACK, x, strict=True)))


@pytest.mark.parametrize("latch", ["none", "angle", "angle+twist"])
def test_controller_law_and_bumpless_switch_on(built, latch):
    g = built.gains_values
    code = LATCH_MODES.index(latch) + 1  # the Enumeration item's value
    c = tl.Slave(built.controller, f"law_{latch}").init(t_on=0.05, latch=code)
    x1, x2, x3 = (0.3, -0.2, 0.1, 0.05), (0.5, 0.1, -0.2, 0.02), (0.7, -0.3, 0.4, -0.1)

    def refs(x):  # (phi_ref, twist_ref) latched at the state x
        phi, _, theta, _ = x
        return {
            "none": (0.0, 0.0),
            "angle": (phi, 0.0),
            "angle+twist": (phi, phi - theta - g["K0"]),
        }[latch]

    try:
        _set_x(c, x1)
        assert c.get("R_minus_R0")[0] == g["R_ff"]  # before t_on: feed-forward only
        for k in range(5):
            t, h = tl.grid(k, H_NS)
            c.fmu.doStep(t, h)
        # tau = 0.05 = t_on, not yet stepped from: the current inputs act as references
        assert c.get("R_minus_R0")[0] == pytest.approx(_law(g, *x1, *refs(x1)), rel=1e-14)
        _set_x(c, x2)  # the inputs at the switch-on point are latched by doStep(0.05, ...)
        c.fmu.doStep(*tl.grid(5, H_NS))
        _set_x(c, x3)
        assert c.get("R_minus_R0")[0] == pytest.approx(_law(g, *x3, *refs(x2)), rel=1e-14)
    finally:
        c.free()


def test_controller_disabled_gives_feed_forward_only(built):
    g = built.gains_values
    c = tl.Slave(built.controller, "disabled").init(enabled=False, t_on=0.0)
    try:
        for k in range(3):
            _set_x(c, (0.3 * k, -0.2, 0.1, 0.05))
            assert c.get("R_minus_R0")[0] == g["R_ff"]
            c.fmu.doStep(*tl.grid(k, H_NS))
    finally:
        c.free()
