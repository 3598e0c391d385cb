"""The front layer's native fast path against the Python path of the same FMUs.

While an instance steps, the front layer serves ``fmi2SetReal`` of the inputs, ``fmi2DoStep`` and
``fmi2GetReal``/``fmi2GetInteger`` of the outputs through the compiled entry points of
``drillstring.model.native``, without entering Python; whatever it cannot serve (a history buffer
to grow, a warning to log, a stop, any other call) goes to the Python slave as before. The
Python path (``DRILLSTRING_FMU_NATIVE=0`` when the instance is made, or no compiled kernel at all:
``DRILLSTRING_JIT=0``, tested with the C host in ``test_fmu_cosim.py``) must give the same bits:

* the closed loop of Fig. 6 (stick-slip, torsional stick, switch-on with the angle latch) in both
  unit systems: every output after every step, and the steps the front layer served natively;
* an FMU state taken on one path and set (serialized and deserialized) on the other, and a rewind
  on the fast path;
* a validity stop: its status, its message, ``fmi2LastSuccessfulTime``, and the illegal call
  that follows it;
* a warning of a step (bit bouncing with ``on_invalid = continue``): statuses and messages;
* rejected calls while stepping (a wrong communication point, a non-finite input, a call not
  allowed in the state): the same status and message on both paths, and the instance goes on.
"""

from __future__ import annotations

import gc
import re
import sys
from typing import Any

import fmu_testlib as tl
import numpy as np
import pytest

from drillstring.model.experiments import FIG6
from drillstring.model.params import REFERENCE_RIG
from drillstring.model.units import SIScaling
from drillstring.orchestration.closed_loop import SCALED, SI, experiment_start_values

pytestmark = pytest.mark.fmu

OK, WARNING, DISCARD, ERROR = tl.OK, tl.WARNING, tl.DISCARD, tl.ERROR
_TS = SIScaling(REFERENCE_RIG).t_star
#: unit system -> (variant, macro step, du0 that makes the bit bounce in the second step)
SYSTEMS = {
    "scaled": (SCALED, 0.01, -40.0),
    "si": (SI, 0.01 * _TS, -40.0 * SIScaling(REFERENCE_RIG).L_star / _TS),
}
PATHS = ("native", "python")
SERVED = re.compile(r"fmi2Terminate: (\d+) step\(s\), (\d+) served natively by the front layer")
OFF = re.compile(r"fmi2Terminate: (\d+) step\(s\), the native fast path is off")


def _built(built: tl.Built, system: str) -> tl.Built:
    return built.si if system == "si" else built.scaled


def make(unit: tl.Unit, name: str, path: str, monkeypatch: pytest.MonkeyPatch) -> tl.Slave:
    """An instance on ``path``: the switch is read when the instance is made."""
    monkeypatch.setenv("DRILLSTRING_FMU_NATIVE", "1" if path == "native" else "0")
    return tl.Slave(unit, f"{name}_{path}")


def outputs(s: tl.Slave) -> list[Any]:
    """Every output, in one call per type (the front layer serves such calls natively)."""
    by_type: dict[str, list[str]] = {}
    for name, causality in s.unit.causality.items():
        if causality == "output":
            by_type.setdefault(s.unit.types[name], []).append(name)
    values: list[Any] = []
    for kind, names in sorted(by_type.items()):
        getter = getattr(s.fmu, f"get{'Integer' if kind == 'Enumeration' else kind}")
        values += list(getter([s.unit.vr[n] for n in names]))
    return values


def terminate_counts(s: tl.Slave) -> tuple[int, int | None]:
    """(steps, steps served natively or None: the fast path off) from fmi2Terminate's message."""
    for message in s.messages(OK):
        if m := SERVED.search(message):
            return int(m.group(1)), int(m.group(2))
        if m := OFF.search(message):
            return int(m.group(1)), None
    raise AssertionError(f"no step count in the log: {s.messages()}")


def closed_loop(
    built: tl.Built, system: str, path: str, n: int, monkeypatch: pytest.MonkeyPatch
) -> tuple[np.ndarray, list[list[int]], tuple[int, int | None]]:
    """Fig. 6 as a Jacobi loop of ``n`` steps: the outputs of both units after every step, the
    statuses, and the plant's step counts."""
    variant, H, _ = SYSTEMS[system]
    b = _built(built, system)
    starts = experiment_start_values(FIG6, variant)
    plant = make(b.plant, "loop_plant", path, monkeypatch)
    ctrl = make(b.controller, "loop_ctrl", path, monkeypatch)
    try:
        plant.init(**starts["plant"])
        ctrl.init(**starts["controller"])
        x_vr = [plant.unit.vr[name] for name in variant.feedback]
        u_vr = [ctrl.unit.vr[name] for name in variant.feedback]
        (r_name,) = (k for k, c in ctrl.unit.causality.items() if c == "output")
        r_out, r_in = ctrl.unit.vr[r_name], plant.unit.vr[variant.torque]
        rows, statuses = [], []
        for k in range(n):
            ctrl.fmu.setReal(u_vr, plant.fmu.getReal(x_vr))
            plant.fmu.setReal([r_in], ctrl.fmu.getReal([r_out]))
            statuses.append([plant.step(k * H, H), ctrl.step(k * H, H)])
            rows.append(outputs(plant) + outputs(ctrl))
            if k % 97 == 0:  # a call the front layer hands to Python, in the middle of a run
                plant.get("h")
        plant.fmu.terminate()
        ctrl.fmu.terminate()
        return np.array(rows, dtype=float), statuses, terminate_counts(plant)
    finally:
        plant.free()
        ctrl.free()


@pytest.mark.parametrize("system", list(SYSTEMS))
def test_closed_loop_is_bit_identical_on_both_paths(built, system, monkeypatch):
    n = 3000  # tau in [0, 30]: stick-slip, torsional stick, the switch-on at tau = 25
    fast, fast_status, fast_counts = closed_loop(built, system, "native", n, monkeypatch)
    slow, slow_status, slow_counts = closed_loop(built, system, "python", n, monkeypatch)
    assert np.array_equal(fast, slow, equal_nan=True)
    assert fast_status == slow_status
    assert slow_counts == (n, None)
    steps, served = fast_counts
    assert steps == n
    # every step native but those Python finished (a history buffer grown: a few at most)
    assert n - 10 <= served <= n
    # a real run: events counted, the controller switched on (its output moves)
    names = [k for k, c in _built(built, system).plant.causality.items() if c == "output"]
    assert {"stick_events", "torsional_stick"} <= set(names)
    assert np.ptp(fast[:, -1]) > 0.0 and np.ptp(fast[:, 0]) > 0.0


def _plant_run(s: tl.Slave, H: float, k0: int, n: int, torques: list[float]) -> list[list[Any]]:
    """``n`` steps from step ``k0`` with the given input sequence; outputs and status after each."""
    rows = []
    name = SI.torque if s.unit.model == tl.PLANT_SI else SCALED.torque
    for k in range(k0, k0 + n):
        s.set(**{name: torques[k % len(torques)]})
        st = s.step(k * H, H)
        rows.append([st, *outputs(s)])
    return rows


def _torques(system: str) -> list[float]:
    r = [0.05, -0.1, 0.2, 0.0, 0.1, -0.05]
    return [SIScaling(REFERENCE_RIG).table_torque(x) for x in r] if system == "si" else r


@pytest.mark.parametrize("system", list(SYSTEMS))
@pytest.mark.parametrize(("taken", "set_on"), [("native", "python"), ("python", "native")])
def test_fmu_state_carries_across_the_paths(built, system, taken, set_on, monkeypatch):
    _, H, _ = SYSTEMS[system]
    unit = _built(built, system).plant
    q = _torques(system)
    starts = experiment_start_values(FIG6, SYSTEMS[system][0])["plant"]
    a = make(unit, "state_a", taken, monkeypatch).init(**starts)
    b = make(unit, "state_b", set_on, monkeypatch).init()
    try:
        _plant_run(a, H, 0, 150, q)
        state = a.fmu.getFMUstate()
        data = a.fmu.serializeFMUstate(state)
        after_a = _plant_run(a, H, 150, 300, q)
        b.fmu.setFMUstate(b.fmu.deSerializeFMUstate(data))
        after_b = _plant_run(b, H, 150, 300, q)
        assert after_a == after_b
        # rewind on the instance that took the state: the same steps again, the same bits
        a.fmu.setFMUstate(state)
        assert _plant_run(a, H, 150, 300, q) == after_a
        a.fmu.freeFMUstate(state)
    finally:
        a.free()
        b.free()


def _bouncing(
    built: tl.Built, system: str, path: str, monkeypatch: pytest.MonkeyPatch, **prior: Any
) -> tuple[tl.Slave, list[list[Any]]]:
    _, H, du0 = SYSTEMS[system]
    s = make(_built(built, system).plant, "bounce", path, monkeypatch).init(du0=du0, **prior)
    rows = []
    for k in range(6):
        st = s.step(k * H, H)
        rows.append([st, *outputs(s)])
        if st > WARNING:
            break
    return s, rows


@pytest.mark.parametrize("system", list(SYSTEMS))
def test_validity_stop_alike_on_both_paths(built, system, monkeypatch):
    _, H, _ = SYSTEMS[system]
    seen = {}
    for path in PATHS:
        s, rows = _bouncing(built, system, path, monkeypatch)
        try:
            assert rows[-1][0] == DISCARD, s.logs
            stopped = s.last_successful_time()
            before = len(s.logs)
            again = s.step(len(rows) * H, H)  # not allowed after fmi2Discard
            new = [m for st, _, m in s.logs[before:] if st == ERROR]
            assert again == ERROR and any("illegal call sequence" in m for m in new), new
            seen[path] = (rows, stopped, s.messages(DISCARD), new, s.last_successful_time())
        finally:
            s.free()
    rows, stopped, discards, _, _ = seen["native"]
    assert seen["native"] == seen["python"]
    assert len(rows) == 2 and 0.0 < stopped - H < H  # the bit bounces inside the second step
    assert any(f"stopped at {stopped!r}" in m for m in discards), discards


@pytest.mark.parametrize("system", list(SYSTEMS))
def test_step_warning_alike_on_both_paths(built, system, monkeypatch):
    seen = {}
    for path in PATHS:
        s, rows = _bouncing(built, system, path, monkeypatch, on_invalid=2)
        try:
            seen[path] = (rows, s.messages(WARNING))
        finally:
            s.free()
    rows, warnings = seen["native"]
    assert seen["native"] == seen["python"]
    assert [r[0] for r in rows].count(WARNING) >= 1 and rows[1][0] == WARNING
    assert any("continuing as on_invalid = continue" in m for m in warnings), warnings


def _rejections(s: tl.Slave, system: str) -> list[tuple[int, str]]:
    """Calls a stepping instance must reject, each with its status and error message."""
    _, H, _ = SYSTEMS[system]
    name = SI.torque if system == "si" else SCALED.torque
    vr = s.unit.vr[name]
    out = []
    for call in (
        lambda: s.step(5 * H, H),  # not the FMU's time
        lambda: s.step(2 * H, 0.0),  # h <= 0
        lambda: s.step(2 * H, float("nan")),
        lambda: s.set_raw("Real", [vr], [float("inf")]),
        lambda: s.call("EnterInitializationMode"),  # not allowed while stepping
    ):
        before = len(s.logs)
        st = call()
        out.append((st, " | ".join(m for x, _, m in s.logs[before:] if x == ERROR)))
    return out


@pytest.mark.parametrize("system", list(SYSTEMS))
def test_rejected_calls_alike_on_both_paths(built, system, monkeypatch):
    _, H, _ = SYSTEMS[system]
    q = _torques(system)
    seen = {}
    for path in PATHS:
        s = make(_built(built, system).plant, "reject", path, monkeypatch).init()
        try:
            _plant_run(s, H, 0, 2, q)
            rejected = _rejections(s, system)
            seen[path] = (rejected, _plant_run(s, H, 2, 20, q))  # and it goes on
        finally:
            s.free()
    assert seen["native"] == seen["python"]
    rejected, rows = seen["native"]
    assert all(st == ERROR and message for st, message in rejected), rejected
    assert all(r[0] == OK for r in rows)


# ------------------------------------------------------------------------------------------------
# the descriptor: a typed call, checked by the layer
# ------------------------------------------------------------------------------------------------


def _slave_of(s: tl.Slave) -> Any:
    """The Python slave of an instance made in this process (the FMU runs in the test's
    interpreter), found by its instance name."""
    model = sys.modules["drillstring_fmu_support"].FmuModel
    name = s.fmu.instanceName
    found = [o for o in gc.get_objects() if isinstance(o, model)]
    (slave,) = (o for o in found if getattr(o, "instance_name", None) == name)  # not released
    return slave


def _handover(slave: Any, words: np.ndarray, length: int) -> int:
    """The layer's ds_front_fast(component, descriptor, length), called as the slave calls it."""
    support = sys.modules["drillstring_fmu_support"]
    call = support._FAST_CALL(slave._front.fast)
    return call(slave._front.component, words.ctypes.data, length)


def _corrupt(case: str, d: np.ndarray, vr: dict[str, int]) -> tuple[np.ndarray, int, str]:
    """A corrupted copy of the plant's descriptor ``d``, its length and the reason expected."""
    d = d.copy()
    n = d.size
    n_in, n_out = int(d[7]), int(d[8])
    io_len = int(d[3])
    first_out = 9 + 2 * n_in  # (vr, slot, type) of the first output
    if case == "magic":
        d[0] = 0x1234
        return d, n, "magic 0x1234 version 2, this layer reads 0x44534650 version 2"
    if case == "version":
        d[1] = 1
        return d, n, "magic 0x44534650 version 1, this layer reads 0x44534650 version 2"
    if case == "header":
        return d, 5, "a descriptor of 5 words, the header alone has 9"
    if case == "short":
        return (
            d,
            n - 1,
            f"a descriptor of {n - 1} words, {n_in} inputs and {n_out} outputs need {n}",
        )
    if case == "long":
        d = np.append(d, np.uint64(0))
        return (
            d,
            n + 1,
            f"a descriptor of {n + 1} words, {n_in} inputs and {n_out} outputs need {n}",
        )
    if case == "counts":
        d[7] = 2**40
        return d, n, f"{2**40} inputs and {n_out} outputs, the model has"
    if case == "io length":
        d[3] = 3
        return d, n, "of 3 doubles (at least 4, at most 1048576)"
    if case == "no io":
        d[2] = 0
        return d, n, f"an io block at 0 of {io_len} doubles"
    if case == "no step":
        d[5] = 0
        return d, n, "no step function"
    if case == "input slot":
        d[10] = io_len
        return d, n, f"input R_minus_R0: slot {io_len} outside [4, {io_len})"
    if case == "input slot in the header":
        d[10] = 2  # the FMU's time
        return d, n, f"input R_minus_R0: slot 2 outside [4, {io_len})"
    if case == "input is an output":
        d[9] = vr["u"]
        return d, n, f"input 0: value reference {vr['u']} is not an input"
    if case == "output unknown":
        d[first_out] = 999
        return d, n, "output 0: value reference 999 is no variable of the model"
    if case == "output is a parameter":
        d[first_out] = vr["psi"]
        return d, n, f"output 0: value reference {vr['psi']} is not an output"
    if case == "output type":
        d[first_out] = vr["u"]
        d[first_out + 2] = 1
        return d, n, f"output 0: value reference {vr['u']} is not an Integer"
    if case == "output type code":
        d[first_out + 2] = 7
        return d, n, "output 0: type code 7 (0 Real, 1 Integer)"
    if case == "output slot":
        d[first_out + 1] = 10**6
        return d, n, f"slot 1000000 outside [4, {io_len})"
    if case == "output twice":
        d[first_out + 3] = d[first_out]
        return d, n, "twice"
    raise AssertionError(case)


REFUSED = (
    "magic", "version", "header", "short", "long", "counts", "io length", "no io", "no step",
    "input slot", "input slot in the header", "input is an output", "output unknown",
    "output is a parameter", "output type", "output type code", "output slot", "output twice",
)  # fmt: skip


def test_layer_refuses_a_bad_descriptor(built, monkeypatch):
    """The layer checks the descriptor it is handed (magic, version, its length against the
    counts, the io block's length, every slot against it, value references, causalities and
    types against the model's table) and refuses a bad one with an error naming why; the
    instance then goes on served by Python, and a valid descriptor is taken again: every case of
    :data:`REFUSED` in turn on one instance."""
    s = make(built.plant, "refuse", "native", monkeypatch).init()
    try:
        assert s.step(0.0, 0.01) == OK
        slave = _slave_of(s)
        valid = slave.fast_descriptor(slave._fast)
        for k, case in enumerate(REFUSED):
            words, length, reason = _corrupt(case, valid, s.unit.vr)
            before = len(s.logs)
            assert _handover(slave, words, length) == 1, case
            warnings = [m for st, _, m in s.logs[before:] if st == WARNING]
            assert len(warnings) == 1, (case, warnings)
            assert "the native fast path is refused: " in warnings[0], (case, warnings)
            assert reason in warnings[0], (case, warnings[0])
            assert warnings[0].endswith("the Python slave serves every call of refuse_native")
            python_steps, t = slave._python_steps, 0.01 * (2 * k + 1)
            assert s.step(t, 0.01) == OK, case  # served by Python: the layer holds no descriptor
            assert slave._python_steps == python_steps + 1, case
            assert _handover(slave, valid, valid.size) == 0, case  # a valid one is taken
            assert s.step(t + 0.01, 0.01) == OK, case
            assert slave._python_steps == python_steps + 1, case  # served natively
    finally:
        s.free()


def test_refused_fast_path_runs_on_python_bit_identically(built, monkeypatch):
    """A slave whose descriptor the layer refuses stays on the Python path: one error at the
    handover, counted into the status of that call (its results are right); every step by
    Python, with
    the bits of an instance made with DRILLSTRING_FMU_NATIVE=0; no message through pythonfmu's
    log queue (the slave logs through the layer's typed call)."""
    runs = {}
    for path in ("refused", "python"):
        s = make(
            built.plant, f"bad_{path}", "native" if path == "refused" else "python", monkeypatch
        )
        try:
            slave = _slave_of(s)
            if path == "refused":  # the slave's own (freed with it)
                good = slave.fast_descriptor
                slave.fast_descriptor = lambda fast, good=good: _corrupt(
                    "output slot", good(fast), {}
                )[0]
            s.set(**experiment_start_values(FIG6, SCALED)["plant"])
            s.fmu.setupExperiment(startTime=0.0)
            s.fmu.enterInitializationMode()
            # the first handover: the warning is the call's status
            expected = WARNING if path == "refused" else OK
            assert s.call("ExitInitializationMode") == expected, s.logs
            rows = _plant_run(s, 0.01, 0, 200, _torques("scaled"))
            s.fmu.terminate()
            runs[path] = (rows, s.messages(WARNING), terminate_counts(s), list(slave.log_queue))
        finally:
            s.free()
    rows, warnings, counts, queue = runs["refused"]
    assert rows == runs["python"][0]
    assert all(r[0] == OK for r in rows)
    assert len(warnings) == 1 and "the native fast path is refused" in warnings[0], warnings
    assert counts == (200, None) == runs["python"][2]
    assert queue == [] == runs["python"][3]
