"""The conformance table of the FMUs' FMI boundary: one test per row.

Each row brings a fresh instance into a state (Instantiated, InitializationMode, stepping after two
steps, Terminated, or StepFailed after a validity stop), makes one call and asserts

1. the status the call returns,
2. the message the FMU logged for it (by status and text), and
3. that the instance goes on correctly: from where it is, the normal continuation (finish the
   initialization, three steps; after fmi2Terminate an fmi2Reset first; after a validity stop a
   restored state) gives bit for bit the outputs of a fresh instance that took the same path
   without the bad call -- so a rejected value was not applied and nothing is blocked.

Rows that concern ``fmi2Instantiate`` (no instance to go on with) assert the NULL, the message,
and that a correct instantiation in the same process works afterwards.

The table runs on the scaled FMUs, and its rows that differ in SI (:data:`SYSTEMS`) on the SI
FMUs (``DrillStringPlantSI``, ``TorsionalControllerSI``) too: those with the SI variables (the
table torque for R - R0, the bit's angle and speed for phi and dphi, the physical parameters for
the scaled ones), the time scaled by t* and their own messages (the other rows make the
same call on the same code, the front layer and the lifecycle being the same in both).

The rows ``K1``... concern the industrial top-drive controller (``TopDriveController``,
``TopDriveControllerSI``): its own values and that its law's state goes on alike.

The table of ``docs/fmus.md`` ("Conformance table") is the scaled one:
``test_docs_carry_the_table`` compares them; ``python tests/test_fmu_conformance.py`` prints it.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import fmu_testlib as tl
import pytest

from drillstring.model.params import REFERENCE_RIG
from drillstring.model.units import SIScaling

pytestmark = pytest.mark.fmu

OK, WARNING, DISCARD, ERROR = tl.OK, tl.WARNING, tl.DISCARD, tl.ERROR
STATUS = {OK: "fmi2OK", WARNING: "fmi2Warning", DISCARD: "fmi2Discard", ERROR: "fmi2Error"}
H = 0.01
#: Inputs of the continuation steps (plant: the torque; controller: the measured states).
PLANT_INPUT = (0.05, -0.1, 0.2, 0.0, 0.1, -0.05)
CTRL_INPUT = {"phi": 0.3, "dphi": -0.2, "theta": 0.1, "dtheta": 0.05}


def rx(x: float) -> str:
    """A number as its repr, escaped for a pattern."""
    return re.escape(repr(x))


@dataclass(frozen=True)
class System:
    """The names and values by which the table's rows address one unit system's FMUs."""

    name: str
    #: the macro step (H in scaled time; H t* in seconds)
    H: float
    scale: float
    plant_model: str
    controller_model: str
    plant_input: str
    torques: tuple[float, ...]
    ctrl_inputs: dict[str, float]
    params_class: str
    #: a Real parameter, a valid value of it, and a second Real parameter
    param: str
    param_ok: float
    param2: str
    out_real: str
    out_u: str
    ctrl_in: str
    ctrl_in4: str
    out_of_range: tuple[tuple[str, float, str], ...]
    #: (values making fmi2ExitInitializationMode fail, message, values that fix it)
    inconsistent: tuple[dict[str, float], str, dict[str, float]]
    #: du0 that makes the bit bounce inside the second step
    bounce_du0: float
    #: a torque that stops the table (torsional stick with the model off)
    stop_torque: float
    #: what a validity stop's message adds after the scaled time
    stop_suffix: str


OUT_OF_RANGE = [
    ("psi", -1.0, r"ScaledParams\.psi must be > 0, got -1\.0"),
    ("psi", 0.0, r"ScaledParams\.psi must be > 0, got 0\.0"),
    ("gamma", -0.1, r"ScaledParams\.gamma must be >= 0, got -0\.1"),
    ("eta", 0.0, r"ScaledParams\.eta must be > 0, got 0\.0"),
    ("lambda", -1.0, r"ScaledParams\.lam must be >= 0, got -1\.0"),
    ("beta", 1.5, r"ScaledParams\.beta must be in \(0, 1\], got 1\.5"),
    ("beta", 0.0, r"ScaledParams\.beta must be > 0, got 0\.0"),
    ("rho", 0.0, r"ScaledParams\.rho must be > 0, got 0\.0"),
    ("v0", 0.0, r"ScaledParams\.v0 must be > 0, got 0\.0"),
    ("omega0", -1.0, r"ScaledParams\.omega0 must be > 0, got -1\.0"),
    ("h", 0.0, r"EngineOptions\.h must be > 0, got 0\.0"),
    ("event_tol", 1e-3, r"EngineOptions\.event_tol must be in \(0, 1e-10\], got 0\.001"),
    ("event_tol", 0.0, r"EngineOptions\.event_tol must be in \(0, 1e-10\], got 0\.0"),
]
OUT_OF_RANGE_SI = [
    ("M", -1.0, r"PhysicalParams\.M must be > 0, got -1\.0"),
    ("C", 0.0, r"PhysicalParams\.C must be > 0, got 0\.0"),
    ("D", -0.1, r"PhysicalParams\.D must be >= 0, got -0\.1"),
    ("K", 0.0, r"PhysicalParams\.K must be > 0, got 0\.0"),
    ("l", -1.0, r"PhysicalParams\.l must be >= 0, got -1\.0"),
    ("xi", -1.0, r"PhysicalParams\.xi must be > 0, got -1\.0"),
    ("mu", 0.0, r"PhysicalParams\.mu must be > 0, got 0\.0"),
    ("I2", 0.0, r"PhysicalParams\.I2 must be > 0, got 0\.0"),
    ("V0", 0.0, r"PhysicalParams\.V0 must be > 0, got 0\.0"),
    ("Omega0", -1.0, r"PhysicalParams\.Omega0 must be > 0, got -1\.0"),
    ("h", 0.0, r"h must be > 0, got 0\.0"),
    ("event_tol", -1e-3, r"event_tol must be > 0, got -0\.001"),
    ("event_tol", 0.0, r"event_tol must be > 0, got 0\.0"),
]
_RIG = SIScaling(REFERENCE_RIG)
_TS = _RIG.t_star
SYSTEMS = {
    "scaled": System(
        name="scaled",
        H=H,
        scale=1.0,
        plant_model=tl.PLANT,
        controller_model=tl.CONTROLLER,
        plant_input="R_minus_R0",
        torques=PLANT_INPUT,
        ctrl_inputs=CTRL_INPUT,
        params_class="ScaledParams",
        param="psi",
        param_ok=300.0,
        param2="gamma",
        out_real="dphi",
        out_u="u",
        ctrl_in="phi",
        ctrl_in4="dtheta",
        out_of_range=tuple(OUT_OF_RANGE),
        inconsistent=(
            {"dphi0": -6.0},
            r"fmi2ExitInitializationMode: the parameters are inconsistent: initial dphi = -6\.0 "
            r"gives dPhi/dtau = -1\.0 <= 0.*stays in initialization mode",
            {"dphi0": -2.5},
        ),
        bounce_du0=-40.0,
        stop_torque=-30.0,
        stop_suffix="",
    ),
    "si": System(
        name="si",
        H=H * _TS,
        scale=_TS,
        plant_model=tl.PLANT_SI,
        controller_model=tl.CONTROLLER_SI,
        plant_input="table_torque",
        torques=tuple(_RIG.table_torque(r) for r in PLANT_INPUT),
        ctrl_inputs={
            "bit_angle": 0.3,
            "bit_speed": (_RIG.scaled.omega0 - 0.2) / _TS,
            "table_angle": _RIG.twist0 + 0.1,
            "table_speed": (_RIG.scaled.omega0 + 0.05) / _TS,
        },
        params_class="PhysicalParams",
        param="C",
        param_ok=300.0,
        param2="D",
        out_real="bit_speed",
        out_u="bit_position",
        ctrl_in="bit_angle",
        ctrl_in4="table_speed",
        out_of_range=tuple(OUT_OF_RANGE_SI),
        inconsistent=(
            {"dphi0": -6.0 / _TS},
            r"fmi2ExitInitializationMode: the parameters are inconsistent: the initial bit speed "
            r"Omega0 \+ dphi0 = -1\.08\d+ rad/s is not > 0.*stays in initialization mode",
            {"dphi0": -2.5 / _TS},
        ),
        bounce_du0=-40.0 * _RIG.L_star / _TS,
        stop_torque=_RIG.table_torque(-30.0),
        stop_suffix=r" \(t = 0\.009\d+ s\)",
    ),
}


# ------------------------------------------------------------------------------------------------
# the harness
# ------------------------------------------------------------------------------------------------


def _step_inputs(s: tl.Slave, k: int) -> None:
    sy = s.system
    if s.unit.model == sy.plant_model:
        s.set(**{sy.plant_input: sy.torques[k % len(sy.torques)]})
    else:
        s.set(**{n: v * (1 + 0.1 * k) for n, v in sy.ctrl_inputs.items()})


def slave(sy: System, unit: tl.Unit, name: str, **kw: Any) -> tl.Slave:
    """An instance that knows its unit system (the harness reads ``s.system``)."""
    s = tl.Slave(unit, name, **kw)
    s.system = sy
    return s


def _outputs(s: tl.Slave) -> list[Any]:
    md_outputs = [n for n, c in s.unit.causality.items() if c == "output"]
    return s.get(*md_outputs)


def bring(
    s: tl.Slave,
    state: str,
    prior: dict[str, Any],
    n_steps: int = 2,
    stop_time: float | None = None,
) -> dict[str, Any]:
    """Bring a fresh instance into ``state`` (stepping: after ``n_steps`` steps; ``stop_time``:
    the stop time given to fmi2SetupExperiment, None: none); returns what the continuation needs
    (``k``: the next step's number)."""
    ctx: dict[str, Any] = {"k": 0}
    s.set(**prior)
    if state == "instantiated":
        return ctx
    s.fmu.setupExperiment(startTime=0.0, stopTime=stop_time)
    s.fmu.enterInitializationMode()
    if state == "initialization":
        return ctx
    s.fmu.exitInitializationMode()
    H = s.system.H
    for k in range(n_steps):
        _step_inputs(s, k)
        assert s.step(k * H, H) in (OK, WARNING), s.logs
    ctx["k"] = n_steps
    if state == "terminated":
        s.fmu.terminate()
    elif state == "failed":  # prior: a validity stop in the next steps
        ctx["saved"] = s.fmu.getFMUstate()
        k = n_steps
        while (st := s.step(k * H, H)) == OK:
            k += 1
            assert k < 50, "no validity stop"
        assert st == DISCARD, s.logs
    return ctx


def go_on(s: tl.Slave, state: str, ctx: dict[str, Any]) -> list[list[Any]]:
    """The normal continuation from ``state``: the outputs after each of three steps."""
    if state == "terminated":
        assert s.call("Reset") == OK, s.logs
        state = "instantiated"
        ctx = {"k": 0}
    if state == "instantiated":
        s.fmu.setupExperiment(startTime=0.0)
        s.fmu.enterInitializationMode()
    if state in ("instantiated", "initialization"):
        s.fmu.exitInitializationMode()
    rows, k0, H = [], ctx["k"], s.system.H
    for k in range(k0, k0 + 3):
        _step_inputs(s, k)
        assert s.step(k * H, H) == OK, s.logs
        rows.append(_outputs(s))
    return rows


def restored(s: tl.Slave, state: str, ctx: dict[str, Any]) -> list[list[Any]]:
    """After a validity stop: the state saved before the failing step restored, a short step
    that ends before the stop: fmi2OK and the outputs of an instance that never stopped."""
    s.fmu.setFMUstate(ctx["saved"])
    s.fmu.freeFMUstate(ctx["saved"])
    assert s.step(ctx["k"] * s.system.H, 1e-4 * s.system.scale) == OK, s.logs
    return [_outputs(s)]


def short_step(ref: tl.Slave, ctx: dict[str, Any]) -> list[list[Any]]:
    """The undisturbed counterpart of :func:`restored`."""
    assert ref.step(ctx["k"] * ref.system.H, 1e-4 * ref.system.scale) == OK, ref.logs
    return [_outputs(ref)]


@dataclass(frozen=True)
class Case:
    """One row: in ``state`` (after ``prior`` was set and, when stepping, ``n_steps`` steps),
    ``call`` returns ``status`` and logs a message matching ``message``; then the instance goes
    on (``then``, default :func:`go_on`) as an undisturbed one does (the same path without the
    call: ``reference``, default :func:`go_on` too)."""

    id: str
    unit: str
    state: str
    situation: str
    call: Callable[[tl.Slave, dict[str, Any]], int]
    status: int
    message: str
    prior: dict[str, Any] = field(default_factory=dict)
    n_steps: int = 2
    then: Callable[[tl.Slave, str, dict[str, Any]], list[list[Any]]] = go_on
    reference: Callable[[tl.Slave, dict[str, Any]], list[list[Any]]] | None = None
    reference_state: str | None = None
    check: Callable[[tl.Slave, dict[str, Any]], None] | None = None
    #: the stop time of fmi2SetupExperiment on the way into ``state`` (None: none defined)
    stop_time: float | None = None


def _set(kind: str, name: str, value: Any) -> Callable[[tl.Slave, dict[str, Any]], int]:
    return lambda s, ctx: s.set_raw(kind, [s.unit.vr[name]], [value])


def _set_many(kind: str, **values: Any) -> Callable[[tl.Slave, dict[str, Any]], int]:
    return lambda s, ctx: s.set_raw(kind, [s.unit.vr[n] for n in values], list(values.values()))


def _get(kind: str, name: str) -> Callable[[tl.Slave, dict[str, Any]], int]:
    return lambda s, ctx: s.get_raw(kind, [s.unit.vr[name]])[0]


def _vr(kind: str, vrs: list[int], values: list[Any] | None = None):
    if values is None:
        return lambda s, ctx: s.get_raw(kind, vrs)[0]
    return lambda s, ctx: s.set_raw(kind, vrs, values)


def _fn(name: str, *args: Any) -> Callable[[tl.Slave, dict[str, Any]], int]:
    return lambda s, ctx: s.call(name, *args)


def _step(t: float, h: float) -> Callable[[tl.Slave, dict[str, Any]], int]:
    return lambda s, ctx: s.step(t, h)


def _state_of_other(s: tl.Slave, ctx: dict[str, Any]) -> int:
    other = slave(s.system, _built(s.system).controller, "other").init()
    try:
        state = other.fmu.getFMUstate()
        st = s.call("SetFMUstate", state)
        other.fmu.freeFMUstate(state)
        return st
    finally:
        other.free()


def _bytes_of_other(s: tl.Slave, ctx: dict[str, Any]) -> int:
    other = slave(s.system, _built(s.system).controller, "other").init()
    try:
        state = other.fmu.getFMUstate()
        data = other.fmu.serializeFMUstate(state)
        other.fmu.freeFMUstate(state)
    finally:
        other.free()
    return _deserialize(s, data)


def _deserialize(s: tl.Slave, data: bytes) -> int:
    state = ctypes.c_void_p()
    buf = ctypes.create_string_buffer(data, len(data))
    st = s.call("DeSerializeFMUstate", buf, len(data), ctypes.byref(state))
    assert st != OK or state.value
    return st


def _own_bytes(s: tl.Slave) -> bytes:
    state = s.fmu.getFMUstate()
    data = s.fmu.serializeFMUstate(state)
    s.fmu.freeFMUstate(state)
    return data


def _corrupted(s: tl.Slave, ctx: dict[str, Any]) -> int:
    data = bytearray(_own_bytes(s))
    data[len(data) // 2] ^= 0x01  # one bit of the payload
    return _deserialize(s, bytes(data))


def _truncated(s: tl.Slave, ctx: dict[str, Any]) -> int:
    return _deserialize(s, _own_bytes(s)[:-10])


def _freed_state(s: tl.Slave, ctx: dict[str, Any]) -> int:
    state = s.fmu.getFMUstate()
    pointer = state.value
    s.fmu.freeFMUstate(state)  # sets the host's variable to NULL; the pointer is kept here
    return s.call("SetFMUstate", ctypes.c_void_p(pointer))


def _wrong_size(s: tl.Slave, ctx: dict[str, Any]) -> int:
    state = s.fmu.getFMUstate()
    try:
        buf = ctypes.create_string_buffer(64)
        return s.call("SerializeFMUstate", state, buf, 64)
    finally:
        s.fmu.freeFMUstate(state)


def _fix_and_go_on(fix: dict[str, Any]):
    def then(s: tl.Slave, state: str, ctx: dict[str, Any]) -> list[list[Any]]:
        s.set(**fix)
        return go_on(s, "initialization", ctx)

    return then


def _exit_with(values: dict[str, Any]) -> Callable[[tl.Slave, dict[str, Any]], int]:
    def call(s: tl.Slave, ctx: dict[str, Any]) -> int:
        s.set(**values)
        return s.call("ExitInitializationMode")

    return call


def _save_then(call: Callable[[tl.Slave, dict[str, Any]], int]):
    def wrapped(s: tl.Slave, ctx: dict[str, Any]) -> int:
        ctx["saved"] = s.fmu.getFMUstate()
        return call(s, ctx)

    return wrapped


def _stop_by_torque(s: tl.Slave, ctx: dict[str, Any]) -> int:
    """R - R0 = -30 stops the rotary table: the bit sticks torsionally (model off)."""
    sy = s.system
    s.set(**{sy.plant_input: sy.stop_torque})
    t, h = ctx["k"] * sy.H, 0.25 * sy.scale
    while (st := s.step(t, h)) == OK:
        t += h
        assert t < 5.0 * sy.scale
    ctx["t"] = t
    return st


def _step_counted(s: tl.Slave, ctx: dict[str, Any]) -> int:
    st = s.step(ctx["k"] * s.system.H, s.system.H)
    ctx["k"] += 1
    return st


def _then_warning_step(ref: tl.Slave, ctx: dict[str, Any]) -> list[list[Any]]:
    """The undisturbed counterpart of a step that returned fmi2Warning: the same step."""
    assert _step_counted(ref, ctx) == WARNING
    return go_on(ref, "stepping", ctx)


def _last_time_inside(width: float):
    """fmi2LastSuccessfulTime is the time the FMU reached, inside the failed step."""

    def check(s: tl.Slave, ctx: dict[str, Any]) -> None:
        t0 = ctx.get("t", ctx["k"] * s.system.H)
        t = s.last_successful_time()
        assert t0 < t < t0 + width * s.system.scale, (t0, t)
        assert f"stopped at {t!r}" in " ".join(s.messages(DISCARD))

    return check


R, INT, B, S = "Real", "Integer", "Boolean", "String"
P, C, K = "plant", "controller", "topdrive"


def make_cases(sy: System) -> list[Case]:
    """The table's rows for the FMUs of unit system ``sy``."""
    H = sy.H
    return _table(sy, H)


def _table(sy: System, H: float) -> list[Case]:
    return [
        *[
            Case(
                f"P{i + 1}",
                P,
                "instantiated",
                f"parameter {name} = {value!r} (out of range)",
                _set(R, name, value),
                ERROR,
                rf"parameter {name} = {re.escape(repr(value))} rejected: {msg}; the value is not "
                "applied",
            )
            for i, (name, value, msg) in enumerate(sy.out_of_range)
        ],
        Case(
            "P14",
            P,
            "instantiated",
            "parameter n = 0 (Integer, out of range)",
            _set(INT, "n", 0),
            ERROR,
            rf"parameter n = 0 rejected: {sy.params_class}\.n must be a positive integer, got 0",
        ),
        Case(
            "P15",
            P,
            "instantiated",
            "on_invalid = 3 (no such Enumeration item)",
            _set(INT, "on_invalid", 3),
            ERROR,
            r"on_invalid must be one of 1 \(stop\), 2 \(continue\), got 3",
        ),
        Case(
            "P16",
            P,
            "instantiated",
            f"parameter {sy.param} = NaN",
            _set(R, sy.param, math.nan),
            ERROR,
            rf"parameter {sy.param} = nan rejected: {sy.param} must be finite, got nan",
        ),
        Case(
            "P17",
            P,
            "instantiated",
            "initial state u0 = +inf",
            _set(R, "u0", math.inf),
            ERROR,
            r"parameter u0 = inf rejected: u0 must be finite, got inf",
        ),
        Case(
            "P18",
            P,
            "initialization",
            "dphi0 = -6 < -omega0: inconsistent at fmi2ExitInitializationMode",
            _exit_with(sy.inconsistent[0]),
            ERROR,
            sy.inconsistent[1],
            then=_fix_and_go_on(sy.inconsistent[2]),
        ),
        Case(
            "P19",
            P,
            "instantiated",
            "torsional_stick_model = 2 (fmi2Boolean neither 0 nor 1)",
            _set(B, "torsional_stick_model", 2),
            ERROR,
            r"value 2 for torsional_stick_model is neither fmi2True \(1\) nor fmi2False \(0\)",
        ),
        Case(
            "P20",
            P,
            "instantiated",
            "string_elements = 0 (Integer, out of range)",
            _set(INT, "string_elements", 0),
            ERROR,
            r"parameter string_elements = 0 rejected: StringParams\.elements must be a positive "
            r"integer, got 0",
        ),
        Case(
            "P21",
            P,
            "instantiated",
            "string_elements = 5000 (more than the 4096 allowed)",
            _set(INT, "string_elements", 5000),
            ERROR,
            r"parameter string_elements = 5000 rejected: StringParams\.elements must be <= 4096, "
            r"got 5000",
        ),
        Case(
            "C1",
            C,
            "instantiated",
            "gain F[2] = +inf",
            _set(R, "F[2]", math.inf),
            ERROR,
            r"parameter F\[2\] = inf rejected: F\[2\] must be finite, got inf",
        ),
        Case(
            "C2",
            C,
            "instantiated",
            "K0 = NaN",
            _set(R, "K0", math.nan),
            ERROR,
            r"parameter K0 = nan rejected: K0 must be finite",
        ),
        Case(
            "C3",
            C,
            "instantiated",
            "R_ff = -inf",
            _set(R, "R_ff", -math.inf),
            ERROR,
            r"parameter R_ff = -inf rejected: R_ff must be finite",
        ),
        Case(
            "C4",
            C,
            "instantiated",
            "t_on = NaN",
            _set(R, "t_on", math.nan),
            ERROR,
            r"parameter t_on = nan rejected: t_on must be finite",
        ),
        Case(
            "C5",
            C,
            "instantiated",
            "latch = 0 (no such Enumeration item)",
            _set(INT, "latch", 0),
            ERROR,
            r"latch must be one of 1 \(none\), 2 \(angle\), 3 \(angle\+twist\), got 0",
        ),
        Case(
            "C6",
            C,
            "initialization",
            "latch = 4 in initialization mode",
            _set(INT, "latch", 4),
            ERROR,
            r"latch must be one of .* got 4",
        ),
        Case(
            "I1",
            P,
            "stepping",
            f"input {sy.plant_input} = NaN",
            _set(R, sy.plant_input, math.nan),
            ERROR,
            rf"input {sy.plant_input} = nan rejected: {sy.plant_input} must be finite, got nan",
        ),
        Case(
            "I2",
            P,
            "stepping",
            f"input {sy.plant_input} = -inf",
            _set(R, sy.plant_input, -math.inf),
            ERROR,
            rf"input {sy.plant_input} = -inf rejected",
        ),
        Case(
            "I3",
            C,
            "stepping",
            f"input {sy.ctrl_in} = NaN",
            _set(R, sy.ctrl_in, math.nan),
            ERROR,
            rf"input {sy.ctrl_in} = nan rejected: {sy.ctrl_in} must be finite, got nan",
        ),
        Case(
            "I4",
            C,
            "stepping",
            f"input {sy.ctrl_in4} = +inf",
            _set(R, sy.ctrl_in4, math.inf),
            ERROR,
            rf"input {sy.ctrl_in4} = inf rejected",
        ),
        Case(
            "T1",
            P,
            "instantiated",
            f"fmi2SetInteger on the Real {sy.param}",
            _set(INT, sy.param, 3),
            ERROR,
            rf"fmi2SetInteger: variable {sy.param} \(value reference \d+\) is a Real, "
            r"not an Integer",
        ),
        Case(
            "T2",
            P,
            "instantiated",
            "fmi2SetReal on the Integer n",
            _set(R, "n", 4.0),
            ERROR,
            r"fmi2SetReal: variable n \(value reference \d+\) is an Integer, not a Real",
        ),
        Case(
            "T3",
            P,
            "instantiated",
            "fmi2SetBoolean on the Real h",
            _set(B, "h", 1),
            ERROR,
            r"fmi2SetBoolean: variable h .* is a Real, not a Boolean",
        ),
        Case(
            "T4",
            P,
            "stepping",
            f"fmi2GetInteger of the Real output {sy.out_real}",
            _get(INT, sy.out_real),
            ERROR,
            rf"fmi2GetInteger: variable {sy.out_real} .* is a Real, not an Integer",
        ),
        Case(
            "T5",
            C,
            "instantiated",
            "fmi2SetString on the Enumeration latch",
            _set(S, "latch", "none"),
            ERROR,
            r"fmi2SetString: variable latch .* is an Enumeration, not a String",
        ),
        Case(
            "T6",
            P,
            "stepping",
            "fmi2GetReal of the Integer output mode",
            _get(R, "mode"),
            ERROR,
            r"fmi2GetReal: variable mode .* is an Integer, not a Real",
        ),
        Case(
            "V1",
            P,
            "stepping",
            "fmi2GetReal of value reference 999",
            _vr(R, [999]),
            ERROR,
            r"fmi2GetReal: no variable has value reference 999",
        ),
        Case(
            "V2",
            P,
            "instantiated",
            "fmi2SetReal of value reference 999",
            _vr(R, [999], [1.0]),
            ERROR,
            r"fmi2SetReal: no variable has value reference 999",
        ),
        Case(
            "V3",
            C,
            "stepping",
            "fmi2SetReal of a valid and an unknown reference: none applied",
            lambda s, ctx: s.set_raw(R, [s.unit.vr[sy.ctrl_in], 999], [5.0, 1.0]),
            ERROR,
            r"no variable has value reference 999 \(vr\[1\]\); nothing done",
        ),
        Case(
            "V4",
            P,
            "instantiated",
            f"{sy.param} = 300 (valid) with {sy.param2} = -1 in one call: none applied",
            _set_many(R, **{sy.param: sy.param_ok, sy.param2: -1.0}),
            ERROR,
            rf"parameter {sy.param2} = -1\.0 rejected",
        ),
        Case(
            "S1",
            P,
            "stepping",
            f"fmi2SetReal of the output {sy.out_u}",
            _set(R, sy.out_u, 1.0),
            ERROR,
            rf"variable {sy.out_u} \(value reference \d+\) is an output .* cannot be set",
        ),
        Case(
            "S2",
            P,
            "stepping",
            f"parameter {sy.param} set after initialization",
            _set(R, sy.param, sy.param_ok),
            ERROR,
            rf"parameter {sy.param} \(value reference \d+\) is fixed: it can be set only before "
            r"fmi2ExitInitializationMode, not in state StepComplete",
        ),
        Case(
            "S3",
            C,
            "stepping",
            "parameter t_on set after initialization",
            _set(R, "t_on", 1.0),
            ERROR,
            r"parameter t_on .* is fixed",
        ),
        Case(
            "Q1",
            P,
            "stepping",
            "fmi2ExitInitializationMode a second time",
            _fn("ExitInitializationMode"),
            ERROR,
            r"fmi2ExitInitializationMode: illegal call sequence: not allowed in state StepComplete "
            r"\(allowed in: InitializationMode\)",
        ),
        Case(
            "Q2",
            P,
            "stepping",
            "fmi2EnterInitializationMode after stepping",
            _fn("EnterInitializationMode"),
            ERROR,
            r"fmi2EnterInitializationMode: illegal call sequence: not allowed in state "
            r"StepComplete",
        ),
        Case(
            "Q3",
            P,
            "instantiated",
            "fmi2DoStep before initialization",
            _step(0.0, H),
            ERROR,
            r"fmi2DoStep: illegal call sequence: not allowed in state Instantiated",
        ),
        Case(
            "Q4",
            C,
            "initialization",
            "fmi2DoStep in initialization mode",
            _step(0.0, H),
            ERROR,
            r"fmi2DoStep: illegal call sequence: not allowed in state InitializationMode",
        ),
        Case(
            "Q5",
            P,
            "initialization",
            "fmi2SetupExperiment in initialization mode",
            _fn(
                "SetupExperiment",
                0,
                ctypes.c_double(0.0),
                ctypes.c_double(0.0),
                0,
                ctypes.c_double(0.0),
            ),
            ERROR,
            r"fmi2SetupExperiment: illegal call sequence: not allowed in state "
            r"InitializationMode \(allowed in: Instantiated\)",
        ),
        Case(
            "Q6",
            P,
            "instantiated",
            "fmi2GetReal before initialization",
            _get(R, sy.out_real),
            ERROR,
            r"fmi2GetReal: illegal call sequence: not allowed in state Instantiated",
        ),
        Case(
            "Q7",
            C,
            "instantiated",
            "fmi2Terminate before initialization",
            _fn("Terminate"),
            ERROR,
            r"fmi2Terminate: illegal call sequence: not allowed in state Instantiated",
        ),
        Case(
            "Q8",
            P,
            "terminated",
            "fmi2DoStep after fmi2Terminate",
            _step(2 * H, H),
            ERROR,
            r"fmi2DoStep: illegal call sequence: not allowed in state Terminated",
        ),
        Case(
            "Q9",
            P,
            "failed",
            "fmi2DoStep again after fmi2Discard",
            _step(2 * H, H),
            ERROR,
            r"fmi2DoStep: illegal call sequence: not allowed in state StepFailed",
            prior={"du0": sy.bounce_du0},
            n_steps=1,
            then=restored,
            reference=short_step,
            reference_state="stepping",
        ),
        Case(
            "Q10",
            P,
            "stepping",
            "fmi2CancelStep (fmi2DoStep never returns fmi2Pending)",
            _fn("CancelStep"),
            ERROR,
            r"fmi2CancelStep: illegal call sequence: .*StepInProgress, which this FMU never enters",
        ),
        Case(
            "Q11",
            C,
            "terminated",
            "fmi2SetReal after fmi2Terminate",
            _set(R, sy.ctrl_in, 1.0),
            ERROR,
            r"fmi2SetReal: illegal call sequence: not allowed in state Terminated",
        ),
        Case(
            "Q12",
            P,
            "instantiated",
            "fmi2ExitInitializationMode without entering it",
            _fn("ExitInitializationMode"),
            ERROR,
            r"fmi2ExitInitializationMode: illegal call sequence: not allowed in state Instantiated",
        ),
        Case(
            "A1",
            P,
            "stepping",
            "step size 0",
            _step(2 * H, 0.0),
            ERROR,
            rf"fmi2DoStep: step size must be > 0, got 0\.0 at t = {rx(2 * H)}",
        ),
        Case(
            "A2",
            C,
            "stepping",
            "step size -0.01",
            _step(2 * H, -H),
            ERROR,
            rf"fmi2DoStep: step size must be > 0, got {rx(-H)}",
        ),
        Case(
            "A3",
            P,
            "stepping",
            "step size NaN",
            _step(2 * H, math.nan),
            ERROR,
            rf"fmi2DoStep: time and step size must be finite, got t = {rx(2 * H)}, h = nan",
        ),
        Case(
            "A4",
            P,
            "stepping",
            "communication point 5.0, not the FMU's time 0.02",
            _step(500 * H, H),
            ERROR,
            rf"fmi2DoStep: communication point t = {rx(500 * H)} is not the FMU's time "
            rf"{rx(2 * H)}; "
            r"nothing was computed",
        ),
        Case(
            "A5",
            C,
            "stepping",
            "communication point 0.0 again (a step back)",
            _step(0.0, H),
            ERROR,
            rf"communication point t = 0\.0 is not the FMU's time {rx(2 * H)}",
        ),
        Case(
            "A6",
            P,
            "instantiated",
            "start time 1.0 in fmi2SetupExperiment",
            _fn(
                "SetupExperiment",
                0,
                ctypes.c_double(0.0),
                ctypes.c_double(1.0),
                0,
                ctypes.c_double(0.0),
            ),
            ERROR,
            r"fmi2SetupExperiment: start time must be 0\.0 .* got 1\.0",
        ),
        Case(
            "A7",
            P,
            "instantiated",
            "stop time -1.0 before the start time 0.0 in fmi2SetupExperiment",
            _fn(
                "SetupExperiment",
                0,
                ctypes.c_double(0.0),
                ctypes.c_double(0.0),
                1,
                ctypes.c_double(-1.0),
            ),
            ERROR,
            r"fmi2SetupExperiment: stop time -1\.0 is not at or after the start time 0\.0; "
            r"nothing changed",
        ),
        Case(
            "A8",
            P,
            "stepping",
            f"a step past the stop time {5 * H!r} of fmi2SetupExperiment",
            _step(2 * H, 4 * H),
            ERROR,
            rf"fmi2DoStep: the step \[{rx(2 * H)}, {rx(2 * H + 4 * H)}\] ends after the stop "
            rf"time {rx(5 * H)} defined in fmi2SetupExperiment; nothing was computed",
            stop_time=5 * H,
        ),
        Case(
            "A9",
            C,
            "stepping",
            f"a step past the stop time {5 * H!r} of fmi2SetupExperiment",
            _step(2 * H, 4 * H),
            ERROR,
            rf"fmi2DoStep: the step \[{rx(2 * H)}, {rx(2 * H + 4 * H)}\] ends after the stop "
            rf"time {rx(5 * H)}",
            stop_time=5 * H,
        ),
        Case(
            "X1",
            P,
            "stepping",
            "fmi2SetFMUstate with a state of the controller FMU",
            _state_of_other,
            ERROR,
            r"fmi2SetFMUstate: 0x[0-9a-f]+ is not an FMU state of "
            rf"{sy.plant_model} \(one of another FMU, or freed already\)",
        ),
        Case(
            "X2",
            P,
            "stepping",
            "fmi2DeSerializeFMUstate of the controller's bytes",
            _bytes_of_other,
            ERROR,
            rf"the bytes are an FMU state of {sy.controller_model} \(GUID "
            rf"\{{[-0-9a-f]+\}}\), not of this FMU {sy.plant_model}",
        ),
        Case(
            "X3",
            P,
            "stepping",
            "fmi2DeSerializeFMUstate of bytes with one bit flipped",
            _corrupted,
            ERROR,
            r"corrupted FMU state: checksum mismatch; nothing done",
        ),
        Case(
            "X4",
            C,
            "stepping",
            "fmi2DeSerializeFMUstate of truncated bytes",
            _truncated,
            ERROR,
            r"corrupted FMU state: \d+ bytes, the header announces \d+",
        ),
        Case(
            "X5",
            P,
            "stepping",
            "fmi2DeSerializeFMUstate of arbitrary bytes",
            lambda s, ctx: _deserialize(s, b"not an FMU state at all" * 10),
            ERROR,
            r"230 bytes that are not a serialized FMU state of a drillstring FMU",
        ),
        Case(
            "X6",
            C,
            "stepping",
            "fmi2SetFMUstate with a state freed before",
            _freed_state,
            ERROR,
            rf"is not an FMU state of {sy.controller_model} \(one of another FMU, or freed "
            r"already\)",
        ),
        Case(
            "X7",
            P,
            "stepping",
            "fmi2SerializeFMUstate into a buffer of the wrong size",
            _wrong_size,
            ERROR,
            r"fmi2SerializeFMUstate: buffer of 64 bytes, the state needs \d+",
        ),
        Case(
            "D1",
            P,
            "stepping",
            "bit bouncing inside a step (on_invalid = stop)",
            _save_then(lambda s, ctx: s.step(H, H)),
            DISCARD,
            r"fmi2DoStep: bit_bounce: bit bouncing: depth of cut d < 0, outside the model at tau = "
            rf"0\.010\d+{sy.stop_suffix}; the step \[{rx(H)}, {rx(2 * H)}\] stopped at",
            prior={"du0": sy.bounce_du0},
            n_steps=1,
            then=restored,
            reference=short_step,
            check=_last_time_inside(H),
        ),
        Case(
            "D2",
            P,
            "stepping",
            "torsional stick with torsional_stick_model = false",
            _save_then(_stop_by_torque),
            DISCARD,
            r"fmi2DoStep: torsional_stick: torsional stick: "
            r"outside the model \(dPhi/dtau reached 0 with the torsional-stick model off\)",
            then=restored,
            reference=short_step,
            check=_last_time_inside(0.25),
        ),
        Case(
            "D3",
            P,
            "stepping",
            "bit bouncing inside a step (on_invalid = continue)",
            _step_counted,
            WARNING,
            r"fmi2DoStep: bit bouncing \(d < 0, outside the model's validity\) in the step "
            rf"\[{rx(H)}, {rx(2 * H)}\]; continuing as on_invalid = continue",
            prior={"du0": sy.bounce_du0, "on_invalid": 2},
            n_steps=1,
            reference=_then_warning_step,
        ),
        Case(
            "G1",
            P,
            "stepping",
            "fmi2GetRealStatus(fmi2DoStepStatus)",
            lambda s, ctx: s.call("GetRealStatus", 0, ctypes.byref(ctypes.c_double())),
            DISCARD,
            r"fmi2GetRealStatus\(0\): only fmi2LastSuccessfulTime is available",
        ),
        Case(
            "G2",
            C,
            "stepping",
            "fmi2GetStatus(fmi2DoStepStatus) (no asynchronous steps)",
            lambda s, ctx: s.call("GetStatus", 0, ctypes.byref(ctypes.c_int())),
            DISCARD,
            r"fmi2GetStatus\(0\): not available: fmi2DoStep never returns fmi2Pending",
        ),
        Case(
            "G3",
            P,
            "stepping",
            "fmi2GetDirectionalDerivative (not provided)",
            lambda s, ctx: s.call("GetDirectionalDerivative", None, 0, None, 0, None, None),
            ERROR,
            r"fmi2GetDirectionalDerivative: not provided \(providesDirectionalDerivative is "
            r"false\)",
        ),
        Case(
            "G4",
            C,
            "stepping",
            "fmi2SetRealInputDerivatives (canInterpolateInputs = false)",
            lambda s, ctx: s.call("SetRealInputDerivatives", None, 0, None, None),
            ERROR,
            r"fmi2SetRealInputDerivatives: not provided \(canInterpolateInputs is false\)",
        ),
        Case(
            "G5",
            P,
            "instantiated",
            "fmi2SetDebugLogging with an undeclared category",
            lambda s, ctx: s.call("SetDebugLogging", 1, 1, (ctypes.c_char_p * 1)(b"logEverything")),
            ERROR,
            r"fmi2SetDebugLogging: unknown log category 'logEverything' \(declared: "
            r"logStatusWarning, .*logAll\); nothing changed",
        ),
        *_topdrive_rows(sy, H),
    ]


def _topdrive_rows(sy: System, H: float) -> list[Case]:
    """The rows of the top-drive controller (the front layer and lifecycle are shared: these
    check its own values and that its state goes on alike)."""
    model = sy.controller_model.replace("TorsionalController", "TopDriveController")
    return [
        Case(
            "K1",
            K,
            "instantiated",
            "gain kp = -1 (out of range)",
            _set(R, "kp", -1.0),
            ERROR,
            r"parameter kp = -1\.0 rejected: kp must be in its declared range \[0\.0, inf\], "
            r"got -1\.0; the value is not applied",
        ),
        Case(
            "K2",
            K,
            "instantiated",
            "filter corner omega_hp = 0 (out of range)",
            _set(R, "omega_hp", 0.0),
            ERROR,
            r"parameter omega_hp = 0\.0 rejected: omega_hp must be in its declared range "
            r"\[5e-324, inf\], got 0\.0",
        ),
        Case(
            "K3",
            K,
            "instantiated",
            "z_gain = NaN",
            _set(R, "z_gain", math.nan),
            ERROR,
            r"parameter z_gain = nan rejected: z_gain must be finite, got nan",
        ),
        Case(
            "K4",
            K,
            "initialization",
            "t_on = +inf in initialization mode",
            _set(R, "t_on", math.inf),
            ERROR,
            r"parameter t_on = inf rejected: t_on must be finite",
        ),
        Case(
            "K5",
            K,
            "stepping",
            f"input {sy.ctrl_in4} = NaN",
            _set(R, sy.ctrl_in4, math.nan),
            ERROR,
            rf"input {sy.ctrl_in4} = nan rejected: {sy.ctrl_in4} must be finite, got nan",
        ),
        Case(
            "K6",
            K,
            "stepping",
            "gain ki set after initialization",
            _set(R, "ki", 1.0),
            ERROR,
            r"parameter ki \(value reference \d+\) is fixed: it can be set only before "
            r"fmi2ExitInitializationMode",
        ),
        Case(
            "K7",
            K,
            "instantiated",
            "fmi2SetInteger on the Boolean enabled",
            _set(INT, "enabled", 1),
            ERROR,
            r"fmi2SetInteger: variable enabled \(value reference \d+\) is a Boolean, not an "
            r"Integer",
        ),
        Case(
            "K8",
            K,
            "stepping",
            "communication point 0.0 again (a step back)",
            _step(0.0, H),
            ERROR,
            rf"communication point t = 0\.0 is not the FMU's time {rx(2 * H)}",
        ),
        Case(
            "K9",
            K,
            "stepping",
            "step size 0",
            _step(2 * H, 0.0),
            ERROR,
            rf"fmi2DoStep: step size must be > 0, got 0\.0 at t = {rx(2 * H)}",
        ),
        Case(
            "K10",
            K,
            "stepping",
            "fmi2DeSerializeFMUstate of the LMI controller's bytes",
            _bytes_of_other,
            ERROR,
            rf"the bytes are an FMU state of {sy.controller_model} \(GUID "
            rf"\{{[-0-9a-f]+\}}\), not of this FMU {model}",
        ),
        Case(
            "K11",
            K,
            "stepping",
            "fmi2DeSerializeFMUstate of bytes with one bit flipped",
            _corrupted,
            ERROR,
            r"corrupted FMU state: checksum mismatch; nothing done",
        ),
        Case(
            "K12",
            K,
            "terminated",
            "fmi2DoStep after fmi2Terminate",
            _step(2 * H, H),
            ERROR,
            r"fmi2DoStep: illegal call sequence: not allowed in state Terminated",
        ),
        Case(
            "K13",
            K,
            "instantiated",
            "top-drive lag = -0.01 (out of range)",
            _set(R, "lag", -0.01),
            ERROR,
            r"parameter lag = -0\.01 rejected: lag must be in its declared range \[0\.0, inf\], "
            r"got -0\.01; the value is not applied",
        ),
        Case(
            "K14",
            K,
            "instantiated",
            "telemetry period = 0 (out of range)",
            _set(R, "period", 0.0),
            ERROR,
            r"parameter period = 0\.0 rejected: period must be in its declared range "
            r"\[5e-324, inf\], got 0\.0",
        ),
        Case(
            "K15",
            K,
            "instantiated",
            "anti_windup = 4 (not an item)",
            _set(INT, "anti_windup", 4),
            ERROR,
            r"anti_windup must be one of 1 \(none\), 2 \(back-calculation\), 3 "
            r"\(conditional\), got 4",
        ),
        Case(
            "K16",
            K,
            "initialization",
            "top drive with R_max below R_min: inconsistent at fmi2ExitInitializationMode",
            _exit_with({"top_drive": True, "R_min": 0.0, "R_max": -1.0}),
            ERROR,
            r"fmi2ExitInitializationMode: the parameters are inconsistent: TopDrive: R_min = "
            r"\S+ is above R_max = \S+; the FMU stays in initialization mode",
            then=_fix_and_go_on({"top_drive": False}),
        ),
        Case(
            "K17",
            K,
            "initialization",
            "downhole = observer (its gains are not FMU parameters): refused at exit",
            _exit_with({"downhole": 3}),
            ERROR,
            r"fmi2ExitInitializationMode: the parameters are inconsistent: downhole = observer "
            r"needs the observer's gains, which an FMU parameter cannot carry",
            then=_fix_and_go_on({"downhole": 1}),
        ),
        Case(
            "K18",
            K,
            "initialization",
            "telemetry latency of 100 frame periods: refused at exit",
            _exit_with({"downhole": 2, "period": 0.1 * sy.scale, "latency": 10.0 * sy.scale}),
            ERROR,
            r"fmi2ExitInitializationMode: the parameters are inconsistent: Sensing\.latency = "
            r"\S+ is more than 62 frame periods",
            then=_fix_and_go_on({"downhole": 1, "latency": 0.0}),
        ),
    ]


@dataclass(frozen=True)
class InstantiateCase:
    id: str
    situation: str
    kwargs: Callable[[tl.Unit, Path], dict[str, Any]]
    message: str


def _resources_copy(unit: tl.Unit, tmp: Path, drop: str) -> str:
    import shutil

    res = tmp / "resources"
    shutil.copytree(unit.unzipped / "resources", res)
    (res / drop).unlink()
    return res.as_uri()


INSTANTIATE_CASES = [
    InstantiateCase(
        "N1",
        "wrong GUID",
        lambda u, t: {"guid": "{00000000-0000-0000-0000-0000}"},
        r"GUID \{0+-0000-0000-0000-0000\} does not match this FMU's \{",
    ),
    InstantiateCase(
        "N2",
        "fmuType = fmi2ModelExchange",
        lambda u, t: {"fmu_type": 0},
        r"fmuType fmi2ModelExchange \(0\): DrillStringPlant\.fmu implements "
        r"co-simulation only",
    ),
    InstantiateCase(
        "N3",
        "resources folder missing",
        lambda u, t: {"resources": (t / "gone" / "resources").as_uri()},
        r"resources folder '.*/gone/resources' does not exist",
    ),
    InstantiateCase(
        "N4",
        "resources folder without its Python record",
        lambda u, t: {"resources": _resources_copy(u, t, "drillstring_fmu_python.cfg")},
        r"lacks a readable drillstring_fmu_python\.cfg",
    ),
    InstantiateCase(
        "N5",
        "resource URI on another host",
        lambda u, t: {"resources": "file://elsewhere/tmp/resources"},
        r"names the host 'elsewhere', not a local folder",
    ),
    InstantiateCase(
        "N6",
        "resource URI with invalid percent-encoding",
        lambda u, t: {"resources": "file:///tmp/%zz/resources"},
        r"invalid percent-encoding '%zz' at offset 5",
    ),
    InstantiateCase(
        "N7",
        "resource location that is not a file URI",
        lambda u, t: {"resources": "http://example.org/resources"},
        r"fmuResourceLocation 'http://example\.org/resources' is not a file URI",
    ),
]


# ------------------------------------------------------------------------------------------------
# the tests
# ------------------------------------------------------------------------------------------------


def instantiate_cases(sy: System) -> list[InstantiateCase]:
    """The fmi2Instantiate rows for the plant of unit system ``sy``."""
    return [
        dataclasses.replace(c, message=c.message.replace(tl.PLANT, sy.plant_model))
        for c in INSTANTIATE_CASES
    ]


#: The scaled table (that of docs/fmus.md).
CASES = make_cases(SYSTEMS["scaled"])


def _unit_specific(sy: System) -> list[Case]:
    """The rows of ``sy`` whose call or message differs from the scaled row of the same id
    (its variables, values, time and messages); the others make the same call on the same code
    (the front layer and the lifecycle do not depend on the unit system) and run once, scaled."""
    scaled = {c.id: c for c in CASES}
    return [
        c
        for c in make_cases(sy)
        if (c.situation, c.message) != (scaled[c.id].situation, scaled[c.id].message)
    ]


#: The scaled table and the rows specific to the SI FMUs.
TABLE = [(SYSTEMS["scaled"], c) for c in CASES] + [
    (sy, c) for sy in SYSTEMS.values() if sy.name != "scaled" for c in _unit_specific(sy)
]
INSTANTIATE_TABLE = [(sy, c) for sy in SYSTEMS.values() for c in instantiate_cases(sy)]

BUILT: tl.Built


@pytest.fixture(scope="session")
def built(built):
    """The session's build (conftest), also kept in BUILT for the table's call functions."""
    global BUILT
    BUILT = built
    return BUILT


def _built(sy: System) -> tl.Built:
    """The build's FMUs of unit system ``sy``."""
    return BUILT.si if sy.name == "si" else BUILT.scaled


def _undisturbed(sy: System, c: Case, unit: tl.Unit) -> list[list[Any]]:
    ref = slave(sy, unit, f"{c.id}_reference")
    try:
        state = c.reference_state or c.state
        ctx = bring(ref, state, c.prior, c.n_steps, c.stop_time)
        if c.reference is not None:
            return c.reference(ref, ctx)
        return go_on(ref, state, ctx)
    finally:
        ref.free()


@pytest.mark.parametrize(("sy", "case"), TABLE, ids=[f"{sy.name}-{c.id}" for sy, c in TABLE])
def test_conformance(built, sy, case):
    unit = getattr(_built(sy), case.unit)
    s = slave(sy, unit, case.id)
    try:
        ctx = bring(s, case.state, case.prior, case.n_steps, case.stop_time)
        before = len(s.logs)
        status = case.call(s, ctx)
        new = s.logs[before:]
        assert status == case.status, (STATUS.get(status, status), new)
        expected = [m for st, _, m in new if st == case.status]
        assert any(re.search(case.message, m) for m in expected), new
        if case.check is not None:
            case.check(s, ctx)
        after = case.then(s, case.state, ctx)
        assert after == _undisturbed(sy, case, unit), f"{case.id}: the instance did not go on alike"
    finally:
        s.free()


@pytest.mark.parametrize(
    ("sy", "case"), INSTANTIATE_TABLE, ids=[f"{sy.name}-{c.id}" for sy, c in INSTANTIATE_TABLE]
)
def test_instantiation_conformance(built, sy, case, tmp_path):
    plant = _built(sy).plant
    with pytest.raises(tl.InstantiationError) as info:
        tl.Slave(plant, case.id, **case.kwargs(plant, tmp_path))
    errors = [m for st, _, m in info.value.logs if st == ERROR]
    assert any(re.search(case.message, m) for m in errors), info.value.logs
    s = tl.Slave(plant, f"{case.id}_after").init()  # the process goes on
    try:
        assert s.step(0.0, sy.H) == OK
    finally:
        s.free()


@pytest.mark.parametrize("sy", SYSTEMS.values(), ids=list(SYSTEMS))
def test_errors_are_logged_with_logging_off_and_info_only_with_it_on(built, sy):
    plant = _built(sy).plant
    quiet = tl.Slave(plant, "quiet", logging_on=False)
    loud = tl.Slave(plant, "loud", logging_on=True)
    try:
        for s in (quiet, loud):
            assert s.set_raw(R, [s.unit.vr[sy.param]], [-1.0]) == ERROR
            s.init()
        assert [st for st, _, _ in quiet.logs] == [ERROR]
        assert quiet.logs[0][1] == "logStatusError"
        assert any(st == OK and cat == "logInfo" for st, cat, _ in loud.logs)
        assert not [m for st, _, m in loud.logs if st == OK and "numba" in m]  # compiled already
    finally:
        quiet.free()
        loud.free()


def test_each_row_is_its_own():
    """A row's id names it alone (the "#" column of docs/fmus.md, the test ids; pytest would
    silently number a repeated id), and no two rows make the same call in the same state of the
    same FMU (the table could not tell them apart, and the second would check nothing new)."""
    ids = [c.id for c in CASES] + [c.id for c in INSTANTIATE_CASES]
    assert sorted({i for i in ids if ids.count(i) > 1}) == []
    rows = [(c.unit, c.state, c.situation) for c in CASES]
    rows += [("plant", "(fmi2Instantiate)", c.situation) for c in INSTANTIATE_CASES]
    assert sorted({r for r in rows if rows.count(r) > 1}) == []


def _excerpt(pattern: str) -> str:
    """A message pattern as text: numbers and hex as N, wildcards as '...'."""
    for token in (r"\d+", "[-0-9a-f]+", "[0-9a-f]+", "0+"):
        pattern = pattern.replace(token, "N")
    pattern = pattern.replace(".*", " ... ")
    text = re.sub(r"\\(.)", r"\1", pattern).replace("|", "/")
    return re.sub(" +", " ", text).strip()[:110]


def markdown_table() -> str:
    """The conformance table as ``docs/fmus.md`` carries it."""
    rows = [
        "| # | FMU | State | Call or value | Status | Message (excerpt) |",
        "|---|-----|-------|---------------|--------|-------------------|",
    ]
    names = {P: "plant", C: "controller", K: "top-drive controller"}
    for c in CASES:
        rows.append(
            f"| {c.id} | {names[c.unit]} | {c.state} | {c.situation} | {STATUS[c.status]} "
            f"| {_excerpt(c.message)} |"
        )
    for c in INSTANTIATE_CASES:
        rows.append(
            f"| {c.id} | plant | (fmi2Instantiate) | {c.situation} | NULL | {_excerpt(c.message)} |"
        )
    return "\n".join(rows) + "\n"


def test_docs_carry_the_table():
    doc = (tl.ROOT / "docs" / "fmus.md").read_text(encoding="utf-8")
    assert markdown_table() in doc, (
        "the table of docs/fmus.md differs: run python tests/test_fmu_conformance.py"
    )


if __name__ == "__main__":
    sys.stdout.write(markdown_table())
