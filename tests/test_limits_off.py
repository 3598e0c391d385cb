"""Limits off = the runs from before the top drive existed, bit for bit.

The references (``tests/data/limits_off_0eb9d33.json``) were computed by the code of commit
0eb9d33 (before the top drive, the sensing and the digital controller) with that commit's own
API, by ``tools/make_limits_off_refs.py`` (``tests/data/README.md`` gives the command): Fig.
6-like runs of the stiff PI, SoftSpeed, Z-Torque and the paper's LMI law sampled every 1e-3 on
the reference set, and the paper's law evaluated continuously; the file also holds the runs'
inputs, read here. Today's code must give the same doubles in every column (the SHA-256 of the
float64 bytes, and a few values compared exactly) and the same events (count, times and modes)
for a bare law, for a digital controller
without a top drive and for one with a top drive whose every limit is off (``TopDrive()``:
unbounded ranges, no rate limit, no lag), with ideal sensing.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from drillstring.model.control import AffineFeedback
from drillstring.model.digital.controller import DigitalController
from drillstring.model.engine import EngineOptions
from drillstring.model.laws import SampledAffine, SpeedPI, ZTorque
from drillstring.model.params import REFERENCE
from drillstring.model.sampled import simulate_sampled
from drillstring.model.sensing import Sensing
from drillstring.model.simulate import simulate
from drillstring.model.topdrive import TopDrive

REFS = json.loads((Path(__file__).parent / "data" / "limits_off_0eb9d33.json").read_text())
INPUTS = REFS["inputs"]
START = {
    "initial": {"dphi": INPUTS["dphi0"]},
    "options": EngineOptions(torsional_stick=True),
    "dt_out": INPUTS["dt_out"],
}
K0 = INPUTS["K0"]
FEEDBACK = AffineFeedback(tuple(INPUTS["F"]), K0, -K0, INPUTS["t_on"], "angle")
KINDS = {"SpeedPI": SpeedPI, "ZTorque": ZTorque}
SAMPLED = (*INPUTS["laws"], "lmi")


def _law(name):
    if name == "lmi":
        return SampledAffine(FEEDBACK)
    kind, values = INPUTS["laws"][name]
    return KINDS[kind](**values, R_ff=-K0, t_on=INPUTS["t_on"])


def _assert_same(result, ref):
    assert result.status.code == ref["status"]
    assert (len(result.tau), len(result.events)) == (ref["rows"], ref["events"])
    for c in INPUTS["columns"]:
        values = np.ascontiguousarray(np.asarray(getattr(result, c), dtype=np.float64))
        # the stored values first: a mismatch then shows numbers, not only a hash
        assert [float(values[i]) for i in INPUTS["sample_rows"]] == ref["samples"][c], c
        assert hashlib.sha256(values.tobytes()).hexdigest() == ref["sha256"][c], c
    # the located events (the severity metrics read the stick from them)
    e = result.events
    names = sorted({x.from_mode for x in e} | {x.to_mode for x in e})
    ev = np.array([[x.tau, names.index(x.from_mode), names.index(x.to_mode)] for x in e])
    assert hashlib.sha256(np.ascontiguousarray(ev).tobytes()).hexdigest() == ref["events_sha256"]


def test_the_references_are_the_older_commits_runs():
    assert REFS["commit"].startswith("0eb9d33")
    assert set(REFS["runs"]) == {*SAMPLED, "lmi-continuous"}
    # the runs are not trivial: every one ran to the end in a state of its own
    assert {r["status"] for r in REFS["runs"].values()} == {"ok"}
    finals = {name: r["samples"]["dphi"][-1] for name, r in REFS["runs"].items()}
    assert len(set(finals.values())) == len(finals)


@pytest.mark.parametrize("drive", ["bare law", "no top drive", "every limit off"])
@pytest.mark.parametrize("name", SAMPLED)
def test_sampled_runs_without_limits_are_the_older_runs_bit_for_bit(name, drive):
    law = _law(name)
    controller = {
        "bare law": law,
        "no top drive": DigitalController(law, None, Sensing()),
        "every limit off": DigitalController(law, TopDrive(), Sensing()),
    }[drive]
    r = simulate_sampled(REFERENCE, controller, INPUTS["tau_end"], INPUTS["Ts"], **START)
    _assert_same(r, REFS["runs"][name])


def test_the_continuous_paper_law_is_the_older_run_bit_for_bit():
    r = simulate(REFERENCE, INPUTS["tau_end"], control=FEEDBACK, progress=False, **START)
    _assert_same(r, REFS["runs"]["lmi-continuous"])
