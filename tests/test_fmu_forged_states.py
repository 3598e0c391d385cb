"""Forged FMU states: bytes whose checksum was recomputed after their content
was changed must be refused with fmi2Error naming the field, and leave the instance as it was.

The envelope's checksum (``fmu_src/fmi_front/states.c``) guards against corruption, not against a
forger: anyone can recompute it. Behind it, every array of a restored state is checked against
the instance's layout before anything is overwritten (``Engine.check_state`` for the plant,
``check_block`` for the controllers, the lifecycle's fields in ``drillstring_fmu_support``).

The cases run in subprocesses (this file is also their driver: ``python
test_fmu_forged_states.py FMU FOLDER CASE...``), so a forged state that crashes the host (it did:
SIGSEGV or SIGABRT from a history cut to 3 columns) is a failing test, not the end of the suite.
One subprocess runs the cases of one FMU in order, each on fresh instances, and prints each
case's result as it finishes; a host that dies fails the case it was in, and the cases after it
run on in a new subprocess (the FMU loaded once per subprocess, not once per case: the load and
the import were most of a case's seconds). For each case the driver steps an instance, forges
its own serialized state, deserializes and sets it, then steps on; a reference instance takes
the same path without the forged state. The test asserts the status of fmi2SetFMUstate, the
message, and that the outputs after the refusal are bit for bit the reference's. The same
forging code with no change must give a state that is accepted (so each refusal comes from the
change, not from the forging).
"""

from __future__ import annotations

import ctypes
import io
import json
import re
import struct
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import fmu_testlib as tl
import numpy as np
import pytest

from drillstring.model.digital.layout import BLOCK, SECTIONS
from drillstring.model.kernel import state as S

pytestmark = pytest.mark.fmu
OK, ERROR = tl.OK, tl.ERROR

#: The envelope's header (states.c: StateHeader, no padding): magic, format, phase, last time,
#: model, GUID, payload size, FNV-1a 64 checksum of the header (checksum 0) and the payload.
HEADER = struct.Struct("<8sIId64s64sQQ")
STEPS_BEFORE, STEPS_AFTER, H = 3, 3, 0.01
CTRL_INPUT = {"phi": 0.3, "dphi": -0.2, "theta": 0.1, "dtheta": 0.05}


def _fnv1a(h: int, data: bytes) -> int:
    for b in data:
        h = ((h ^ b) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def reseal(header: list[Any], payload: bytes) -> bytes:
    """The envelope around ``payload`` with its size and checksum recomputed (what a forger
    does)."""
    header = list(header)
    header[6], header[7] = len(payload), 0
    header[7] = _fnv1a(_fnv1a(0xCBF29CE484222325, HEADER.pack(*header)), payload)
    return HEADER.pack(*header) + payload


def open_state(data: bytes) -> tuple[list[Any], dict[str, Any], bytes]:
    """(envelope header, the lifecycle's JSON header, the model's bytes) of serialized bytes."""
    header = list(HEADER.unpack_from(data))
    payload = data[HEADER.size :]
    (n,) = struct.unpack("<Q", payload[:8])
    return header, json.loads(payload[8 : 8 + n]), payload[8 + n :]


def close_state(header: list[Any], fields: dict[str, Any], model: bytes) -> bytes:
    text = json.dumps(fields, sort_keys=True, separators=(",", ":")).encode("utf-8")
    return reseal(header, struct.pack("<Q", len(text)) + text + model)


def _npz(model: bytes, change: Callable[[dict[str, np.ndarray]], None]) -> bytes:
    with np.load(io.BytesIO(model), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    change(arrays)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _set(name: str, index: Any, value: Any) -> Callable[[dict[str, np.ndarray]], None]:
    def change(arrays: dict[str, np.ndarray]) -> None:
        arrays[name][index] = value

    return change


def _block(change: Callable[[np.ndarray], None]) -> Callable[[bytes], bytes]:
    def forge(model: bytes) -> bytes:
        b = np.frombuffer(model, np.float64).copy()
        change(b)
        return b.tobytes()

    return forge


def _block_at(part: str, entry: str, offset: int, value: float) -> Callable[[bytes], bytes]:
    def change(b: np.ndarray) -> None:
        b[getattr(BLOCK, part) + getattr(SECTIONS[part], entry) + offset] = value

    return _block(change)


def _history_cut(arrays: dict[str, np.ndarray]) -> None:
    arrays["history"] = arrays["history"][:, :3].copy()


def _as_float32(arrays: dict[str, np.ndarray]) -> None:
    arrays["history"] = arrays["history"].astype(np.float32)


#: case -> (model kind, forge(fields, model bytes) -> (fields, model bytes), message pattern);
#: a pattern None: the state is accepted.
def _cases() -> dict[str, tuple[str, Callable[..., tuple[dict[str, Any], bytes]], str | None]]:
    def model(f: Callable[[bytes], bytes]):
        return lambda fields, m: (fields, f(m))

    def npz(change: Callable[[dict[str, np.ndarray]], None]):
        return model(lambda m: _npz(m, change))

    def field(path: tuple[str, ...], value: Any):
        def forge(fields: dict[str, Any], m: bytes):
            d = fields["fields"]
            for k in path[:-1]:
                d = d[k]
            d[path[-1]] = value
            return fields, m

        return forge

    return {
        "plant-unchanged": ("plant", npz(lambda a: None), None),
        "plant-history-3-columns": (
            "plant",
            npz(_history_cut),
            r"fmi2SetFMUstate: the FMU state is refused: field model: set_state: the live "
            r"history window ints\[I_HSTART:I_HEND\] = \[\d+, \d+\) does not lie in the 3 "
            r"column\(s\) of array 'history'; nothing was changed",
        ),
        "plant-history-float32": (
            "plant",
            npz(_as_float32),
            r"array 'history' has dtype float32, not float64",
        ),
        "plant-history-rows": (
            "plant",
            npz(lambda a: a.__setitem__("history", a["history"][:4].copy())),
            r"array 'history' has shape \(4, \d+\), not \(6, n\)",
        ),
        "plant-window-end": (
            "plant",
            npz(_set("ints", S.I_HEND, 10**9)),
            r"ints\[I_HSTART:I_HEND\] = \[\d+, 1000000000\) does not lie in the 2048 column",
        ),
        "plant-window-hint": (
            "plant",
            npz(_set("ints", S.I_KHINT, 10**6)),
            r"ints\[I_KHINT\] = 1000000 is not in \[-1, \d+\]",
        ),
        "plant-mode": (
            "plant",
            npz(_set("ints", S.I_MODE, 9)),
            r"ints\[I_MODE\] = 9 is not in \[0, 3\]",
        ),
        "plant-state-nan": (
            "plant",
            npz(_set("y", S.Y_W, np.nan)),
            r"array 'y' holds non-finite numbers",
        ),
        "plant-history-nan": (
            "plant",
            npz(lambda a: a["history"].__setitem__((S.H_U, a["ints"][S.I_HEND] - 1), np.nan)),
            r"the live columns of array 'history' hold non-finite numbers",
        ),
        "plant-latch": (
            "plant",
            npz(_set("control", S.C_LATCH, 7.0)),
            r"control\[C_LATCH\] = 7\.0 is not a latch mode",
        ),
        "plant-input-nan": (
            "plant",
            field(("values", "R_minus_R0"), float("nan")),
            r"the FMU state is refused: field values\.R_minus_R0 = nan: R_minus_R0 must be "
            r"finite",
        ),
        "plant-phase": (
            "plant",
            field(("phase",), "flying"),
            r"the FMU state is refused: field phase = 'flying' is not one of",
        ),
        "controller-unchanged": ("controller", model(lambda m: m), None),
        "controller-block-nan": (
            "controller",
            model(_block(lambda b: b.fill(np.nan))),
            r"the FMU state is refused: field model: the controller block's parameter entry "
            r"\w+ \(block\[\d+\]\) is nan, but this instance's parameters give",
        ),
        "controller-law-state-nan": (
            "controller",
            model(_block_at("law", "x", 0, np.nan)),
            r"the controller block's entry law\.x \(block\[\d+\]\) is nan, not finite",
        ),
        "controller-frame-count": (
            "controller",
            model(_block_at("sensing", "taken", 0, -5.5)),
            r"the controller block's entry sensing\.taken \(block\[\d+\]\) is -5\.5, not a count",
        ),
        "controller-gain": (
            "controller",
            model(_block_at("law", "p", 1, 1e6)),
            r"the controller block's parameter entry law\.p \(block\[\d+\]\) is 1000000\.0",
        ),
        "controller-short": (
            "controller",
            model(lambda m: m[:-16]),
            r"the controller block holds \d+ entries, not \d+",
        ),
    }


# ------------------------------------------------------------------------------------------------
# the driver (in the subprocess)
# ------------------------------------------------------------------------------------------------


def _drive(case: str, unit: tl.Unit) -> dict[str, Any]:
    kind, forge, _ = _cases()[case]
    outputs = [n for n, c in unit.causality.items() if c == "output"]

    def start(name: str) -> tl.Slave:
        s = tl.Slave(unit, name)
        if kind == "controller":
            s.set(t_on=0.0)
        s.init()
        for k in range(STEPS_BEFORE):
            step(s, k)
        return s

    def step(s: tl.Slave, k: int) -> None:
        if kind == "controller":
            s.set(**{n: v * (1 + 0.1 * k) for n, v in CTRL_INPUT.items()})
        else:
            s.set(R_minus_R0=0.05 * (-1) ** k)
        assert s.step(k * H, H) == tl.OK, s.logs

    def go_on(s: tl.Slave) -> list[list[str]]:
        rows = []
        for k in range(STEPS_BEFORE, STEPS_BEFORE + STEPS_AFTER):
            step(s, k)
            rows.append([float(x).hex() for x in s.get(*outputs)])
        return rows

    s = start(f"forged {case}")
    state = s.fmu.getFMUstate()
    data = s.fmu.serializeFMUstate(state)
    s.fmu.freeFMUstate(state)
    header, fields, model = open_state(data)
    fields, model = forge(fields, model)
    forged = close_state(header, fields, model)
    handle = ctypes.c_void_p()
    buf = ctypes.create_string_buffer(forged, len(forged))
    before = len(s.logs)
    deserialized = s.call("DeSerializeFMUstate", buf, len(forged), ctypes.byref(handle))
    status = s.call("SetFMUstate", handle) if deserialized == tl.OK else deserialized
    messages = [m for _, _, m in s.logs[before:]]
    if deserialized == tl.OK:
        s.fmu.freeFMUstate(handle)
    after = go_on(s)
    ref = start(f"reference {case}")
    reference = go_on(ref)
    for instance in (s, ref):  # the next case starts on fresh instances
        instance.fmu.fmi2FreeInstance(instance.fmu.component)
    return {
        "deserialized": deserialized,
        "status": status,
        "messages": messages,
        "after": after,
        "reference": reference,
    }


#: What the driver puts before each case's result on its standard output.
RESULT = "forged-state result: "


def _run_cases(fmu: Path, root: Path, cases: list[str]) -> dict[str, dict[str, Any]]:
    """The result of each of ``cases`` (of one FMU) as the driver reports it, with ``host``: the
    exit status of a host that died in that case (0: it lived on to the next case or exited 0
    after it) and ``stderr``, the end of that host's. One subprocess runs them in order; where it
    dies, the case it was in has no result but the status, and the cases after it run in a new
    subprocess."""
    results: dict[str, dict[str, Any]] = {}
    rest = list(cases)
    while rest:
        folder = root / f"host-{len(results)}"
        run = tl.run_clean(
            [sys.executable, __file__, str(fmu), str(folder), *rest], None, Path(__file__).parent
        )
        done = [json.loads(line[len(RESULT) :]) for line in run.stdout.splitlines()
                if line.startswith(RESULT)]  # fmt: skip
        for i, r in enumerate(done):
            assert r.pop("case") == rest[i], (r, rest)
            last = i == len(done) - 1 and len(done) == len(rest)
            r.update(host=run.returncode if last else 0, stderr=run.stderr[-3000:])
            results[rest[i]] = r
        rest = rest[len(done) :]
        if rest:  # the host died in this case
            results[rest.pop(0)] = {
                "host": run.returncode or "no result",
                "stderr": run.stderr[-3000:],
            }
    return results


# ------------------------------------------------------------------------------------------------
# the tests
# ------------------------------------------------------------------------------------------------

CASES = _cases()


@pytest.fixture(scope="module")
def forged(built, tmp_path_factory) -> Callable[[str], dict[str, Any]]:
    """The result of a case (:func:`_run_cases`), the cases of its FMU run on first use."""
    runs: dict[str, dict[str, dict[str, Any]]] = {}

    def result(case: str) -> dict[str, Any]:
        kind = CASES[case][0]
        if kind not in runs:
            unit = built.plant if kind == "plant" else built.controller
            root = tmp_path_factory.mktemp(f"forged-{kind}")
            runs[kind] = _run_cases(unit.fmu, root, [c for c in CASES if CASES[c][0] == kind])
        return runs[kind][case]

    return result


@pytest.mark.parametrize("case", list(CASES))
def test_forged_state(forged, case):
    message = CASES[case][2]
    r = forged(case)
    assert r["host"] == 0, f"the host died in this case (status {r['host']}): {r['stderr']}"
    assert r["deserialized"] == OK, r["messages"]  # the envelope is intact: the checks are behind
    if message is None:
        assert r["status"] == OK, r["messages"]
    else:
        assert r["status"] == ERROR, r["messages"]
        assert any(re.search(message, m) for m in r["messages"]), r["messages"]
    assert r["after"] == r["reference"], "the instance did not go on as it was"


if __name__ == "__main__":
    fmu, folder = Path(sys.argv[1]), Path(sys.argv[2])
    unit = tl._unit(fmu.stem, fmu, folder)
    for case in sys.argv[3:]:
        print(RESULT + json.dumps({"case": case, **_drive(case, unit)}), flush=True)
