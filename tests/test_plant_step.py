"""The plant's step on its io block against the engine's own calls.

The plant FMU has one step routine, the compiled plant step on the io block ``native.PLANT``
(:func:`drillstring.model.native.plant_io_step`): the front layer runs it through its ``cfunc``,
the FMU's Python path through :func:`~drillstring.model.native.plant_step_from`, and the FMU
tests hold the two paths to the same bits. Here the step is held to a twin engine driven by
``Engine.set_input`` and ``Engine.advance`` (the kernel's ``hold`` and ``advance_drained``, the
halves of the same held step), bit for bit:

* outputs, counters and the whole kernel state after every step, through axial and torsional
  stick, with the history buffer grown (what the step leaves to Python, :meth:`Engine.finish`)
  and more events in a step than the event log holds (drained by the step: the FMU keeps no
  events);
* the SI plant's outputs against the Python conversions of :class:`~drillstring.model.units.
  SIScaling` (what the SI FMU computed in Python before);
* bit bouncing: the warning of a new episode, the stop and the outputs at it;
* what it refuses without changing anything (the Python path then names the error).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drillstring.model import native
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import Engine, EngineOptions
from drillstring.model.kernel import state as S
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.units import SIScaling

P = native.PLANT
TORQUES = (0.05, -0.1, 0.2, 0.0, 0.1, -0.05)


def new_io(eng: Engine, keys: tuple[str, ...], outputs: dict, scaling: SIScaling | None = None):
    """The plant's io block as the FMU sets it up for ``eng`` (constants, outputs at its state)."""
    io = np.zeros(P.size)
    io[native.IO_RESUME] = -1.0
    io[P.si] = 0.0 if scaling is None else 1.0
    if scaling is not None:
        io[P.k : P.k + native.N_K] = scaling.plant_constants
    io[P.out : P.out + len(keys)] = [outputs[k] for k in keys]
    return io


def plant_step(eng: Engine, io: np.ndarray, t: float, h: float, x: float):
    """One step as the FMU's Python path makes it; returns (result, statuses Python finished,
    the engine's status after them or None)."""
    io[P.input] = x
    asked = []
    while True:
        code = native.plant_step_from(io, *eng.kernel_arrays(), t, h)
        if code != native.RESUME:
            return code, asked, None
        st = int(io[native.IO_RESUME])
        io[native.IO_RESUME] = -1.0
        asked.append(st)
        status = eng.finish(st)
        if status is not None:
            return code, asked, status


def same_state(a: Engine, b: Engine) -> bool:
    sa, sb = a.get_state().arrays, b.get_state().arrays
    return sa.keys() == sb.keys() and all(np.array_equal(sa[k], sb[k]) for k in sa)


def outputs_of(io: np.ndarray, keys: tuple[str, ...]) -> list[float]:
    return io[P.out : P.out + len(keys)].tolist()


def test_step_is_the_engines_held_input_and_advance():
    opt = EngineOptions(
        torsional_stick=True, history_capacity=16, event_capacity=16, keep_events=False
    )
    eng = Engine(REFERENCE, options=opt, initial={"dphi": -4.9})
    twin = Engine(REFERENCE, options=opt, initial={"dphi": -4.9})
    keys = native.PLANT_SCALED_KEYS
    io = new_io(eng, keys, eng.outputs())
    asked: set[int] = set()
    most = 0  # events in one step
    # short steps, then long ones (more events in one step than the event log holds)
    steps = [0.01] * 1500 + [6.0] * 3
    t = 0.0
    for k, h in enumerate(steps):
        before = twin.counters["events"]
        x = TORQUES[k % len(TORQUES)]
        code, finished, status = plant_step(eng, io, t, h, x)
        twin.set_input(x)
        twin_status = twin.advance(t + h)
        assert twin_status.ok
        assert code == native.DONE and status is None, (k, finished, status)
        asked.update(finished)
        assert io[P.tau] == twin.tau == t + h
        assert outputs_of(io, keys) == list(twin.outputs().values()), k
        most = max(most, twin.counters["events"] - before)
        t += h
    assert same_state(eng, twin)
    assert eng.counters == twin.counters
    assert twin.counters["torsional_stick_events"] >= 1 and twin.counters["stick_events"] >= 10
    # what the step left to Python: the history grown (the event log it drained itself)
    assert asked == {S.ST_HIST_FULL} and eng.kernel_arrays().history.shape[1] > 16
    assert most > opt.event_capacity


def test_si_step_matches_the_python_conversions():
    scaling = SIScaling(REFERENCE_RIG)
    opt = EngineOptions(torsional_stick=True, keep_events=False)
    initial = {"dphi": -4.9}
    eng = Engine(scaling.scaled, options=opt, initial=initial)
    twin = Engine(scaling.scaled, options=opt, initial=initial)

    def si_outputs(e: Engine) -> dict:
        T = e.diagnostics()["torque_on_bit"]
        return scaling.plant_outputs(e.outputs(), e.tau, torque_on_bit=T)

    keys = native.PLANT_SI_KEYS
    io = new_io(eng, keys, si_outputs(eng), scaling)
    H = 0.01 * scaling.t_star
    for k in range(1500):
        R = scaling.table_torque(TORQUES[k % len(TORQUES)])
        code, _, _ = plant_step(eng, io, k * H, H, R)
        twin.set_input(scaling.torque_deviation(R))
        assert twin.advance(scaling.tau(k * H + H)).ok
        assert code == native.DONE
        expected = si_outputs(twin)
        assert outputs_of(io, keys) == [expected[q] for q in keys], k
    assert same_state(eng, twin)
    assert twin.counters["stick_events"] >= 5


@pytest.mark.parametrize("how", ["stop", "continue"])
def test_bit_bouncing_is_reported(how):
    opt = EngineOptions(on_invalid=how, keep_events=False)
    eng = Engine(REFERENCE, options=opt, initial={"du": -40.0})
    twin = Engine(REFERENCE, options=opt, initial={"du": -40.0})
    keys = native.PLANT_SCALED_KEYS
    io = new_io(eng, keys, eng.outputs())
    reports = []
    for k in range(20):
        code, finished, status = plant_step(eng, io, k * 0.01, 0.01, 0.0)
        twin.set_input(0.0)
        twin_status = twin.advance(k * 0.01 + 0.01)
        reports.append((code, finished))
        assert outputs_of(io, keys) == list(twin.outputs().values()), k
        assert io[P.tau] == twin.tau
        if code == native.RESUME:
            assert status == twin_status
        if not twin_status.ok:
            break
    bounce = keys.index("bit_bounce")
    if how == "continue":
        # one episode: reported once, by the step in which it began (ST_OK: a warning)
        assert [r for r in reports if r[0] != native.DONE] == [(native.RESUME, [S.ST_OK])]
        assert outputs_of(io, keys)[bounce] == 1.0 and len(reports) == 20
    else:
        assert reports[-1] == (native.RESUME, [S.ST_BOUNCE]) and eng.failed is not None
        assert eng.tau < len(reports) * 0.01  # the outputs hold the state at the stop
        # a stopped run is not stepped again: refused, nothing changed
        before = eng.get_state().arrays
        kept = io.copy()
        assert plant_step(eng, io, eng.tau, 0.01, 0.0)[0] == native.NOT_STARTED
        assert all(np.array_equal(before[k], v) for k, v in eng.get_state().arrays.items())
        assert np.array_equal(io, kept)


@pytest.mark.parametrize(
    ("x", "t", "h", "control"),
    [
        (math.nan, 0.0, 0.01, None),
        (math.inf, 0.0, 0.01, None),
        (0.1, 0.0, math.inf, None),
        (0.1, -1.0, 0.5, None),  # a target before the engine's time
        (0.1, 0.0, 0.01, AffineFeedback((-1.0, -1.0, 0.5, -0.1), 0.2, -0.2)),  # not held
    ],
)
def test_refused_steps_change_nothing(x, t, h, control):
    eng = Engine(REFERENCE, initial={"dphi": -2.5}, control=control)
    eng.advance(0.5)
    keys = native.PLANT_SCALED_KEYS
    io = new_io(eng, keys, eng.outputs())
    io[P.input] = x
    kept, before = io.copy(), eng.get_state().arrays
    assert native.plant_step_from(io, *eng.kernel_arrays(), t, h) == native.NOT_STARTED
    assert np.array_equal(io, kept, equal_nan=True)
    assert all(np.array_equal(before[k], v) for k, v in eng.get_state().arrays.items())


def test_io_layout_is_its_table():
    # the four slots every FMU's block begins with, then the plant's entries in order
    assert P[:4] == (native.IO_STALE, native.IO_RESUME, native.IO_TIME, native.IO_NSTEPS)
    offsets = list(P)
    # the outputs: the 13 SI quantities (the top-of-string torque the last) and 4 integers
    assert offsets == sorted(offsets) and P.size == P.out + 17
    assert P.k + native.N_K == P.tau
