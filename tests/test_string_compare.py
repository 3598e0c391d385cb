"""The comparison and the map on the distributed string.

The one-mode comparison is today's bit for bit (the rows stored from the commit before the
string's comparison); the comparison on N elements writes SI columns with their units and
rows with and without braking; the figure shows the outcome, not the run status.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
from test_controller_sweep import SHORT_FIG6, _design_gains

from drillstring.apps.controllers import (
    COMPARISON_COLUMNS,
    MAP_SPEC,
    NO_BRAKING,
    controller_map_spec,
    wob_range,
    write_controller_comparison,
    write_controller_map,
)
from drillstring.apps.sweep.options import ControllerOptions
from drillstring.apps.sweep.runner import _boundary_overlays, read_results, shown_values
from drillstring.apps.sweep.runner import columns as sweep_columns
from drillstring.apps.sweep.spec import load_spec
from drillstring.apps.sweep.tables import MAP_SI
from drillstring.controller.gains import PAPER_F, write_gains
from drillstring.controller.lineup import RIG_CONTROLLERS, TIMED_CONTROLLERS
from drillstring.model.params import REFERENCE_RIG
from drillstring.model.pipe import REFERENCE_KAPPA, string_of_rig

DATA = Path(__file__).parent / "data" / "comparison_short_109c713.json"
#: The old columns (before the SI names) and their new names.
RENAMED = {"tau_reached": "tau_reached_scaled"}
SHORT = {
    "experiment": SHORT_FIG6,
    "tau_end": 8.0,
    "options": ControllerOptions(window=1.0, min_periods=0.0),
}


@pytest.fixture(scope="module")
def gains():
    paper = _design_gains(PAPER_F)
    record = {"u_max": 212.0, "peak_torque": 147.0, "decay": 0.0, "tau_max": 0.63}
    return paper, _design_gains((-88.16, -65.50, 52.86, -19.72), record)


def _same(a, b) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        a, b = float(a), float(b)
        return (math.isnan(a) and math.isnan(b)) or a == b
    return a == b


@pytest.mark.slow  # an end-to-end run of several seconds: make test, not test-fast
def test_the_one_mode_comparison_is_todays_bit_for_bit(gains, tmp_path) -> None:
    result = write_controller_comparison(tmp_path, *gains, log=None, **SHORT)
    stored = json.loads(DATA.read_text())["rows"]
    # the rows of 109c713, in order; the rows added since (the drive's timing) come on top
    rows = [r for r in result.rows if r["controller"] not in TIMED_CONTROLLERS]
    assert [r["controller"] for r in rows] == [r["controller"] for r in stored]
    assert len(result.rows) == len(stored) + len(TIMED_CONTROLLERS)
    for old, new in zip(stored, rows, strict=True):
        for key, value in old.items():
            got = new[RENAMED.get(key, key)]
            value = float(value) if key not in ("controller", "sensing", "top_drive",
                                                "outcome", "status") else value  # fmt: skip
            assert _same(got, value), (old["controller"], key, got, value)
        assert new["string_elements"] == 1


@pytest.mark.slow  # an end-to-end run of several seconds: make test, not test-fast
def test_the_comparison_on_the_string_in_si_with_and_without_braking(gains, tmp_path) -> None:
    string = string_of_rig(REFERENCE_RIG, 4)
    assert string.kappa == REFERENCE_KAPPA and string_of_rig(REFERENCE_RIG, 1) is None
    result = write_controller_comparison(
        tmp_path, *gains, string=string, without_braking=True, log=None, **SHORT
    )
    with open(result.files["table"], newline="") as fh:
        table = list(csv.DictReader(fh))
    header = list(table[0])
    assert header == list(COMPARISON_COLUMNS)
    # every column says its unit, or that it is a ratio, a count, a fraction or a label
    units = ("_kNm", "_kW", "_rpm", "_s", "_over_R0", "_scaled", "_fraction")
    labels = {"controller", "sensing", "top_drive", "braking", "string_elements", "outcome",
              "severity", "utr", "stick_entries_after_on", "status"}  # fmt: skip
    for c in header:
        assert c in labels or c.endswith(units), c
    assert "tau_reached" not in header
    # every controller with and without braking, under the same drive
    pairs = [(r["controller"], r["braking"]) for r in table]
    for name in RIG_CONTROLLERS:
        assert (name, "four-quadrant") in pairs and (name, "none") in pairs
    assert {r["string_elements"] for r in table} == {"4"}
    rig = REFERENCE_RIG
    for key, run in result.runs.items():
        row = next(
            r for r in result.rows
            if r["controller"] == key.removesuffix(NO_BRAKING)
            and (r["braking"] == "none") == key.endswith(NO_BRAKING)
        )  # fmt: skip
        assert row["t_reached_s"] == pytest.approx(row["tau_reached_scaled"] * rig.t_star)
        assert run.string.elements == 4
        if key.endswith(NO_BRAKING):  # no torque against the rotation: R >= 0
            assert min(run.data["R_min"][1:]) >= -1e-12, key
    summary = json.loads(result.files["json"].read_text())
    assert summary["string"]["elements"] == 4
    assert result.files["figure"].stat().st_size > 10_000


@pytest.mark.slow  # an end-to-end run of several seconds: make test, not test-fast
def test_a_3x3_map_on_the_string_without_braking_in_si(gains, tmp_path) -> None:
    paper = write_gains(gains[0], tmp_path / "paper.json")
    cons = write_gains(gains[1], tmp_path / "constrained.json")
    # the shipped map as drillstring sweep reads it (--base-dir: the design's folder) is the
    # command's default: 25 x 25 over 20-150 rpm and from what the rig's feed gives for
    # v0 = 0.25 at its speed to 40 kN, on the converged string
    design = tmp_path / "design"
    write_gains(gains[0], design / "gains.json")
    write_gains(gains[1], design / "gains_constrained.json")
    shipped = load_spec(MAP_SPEC, base_dir=design)
    assert shipped.to_dict() == controller_map_spec(design / "gains.json").to_dict()
    speed, wob = shipped.axes
    assert (speed.start, speed.stop, speed.num, wob.stop, wob.num) == (20.0, 150.0, 25, 40.0, 25)
    assert wob.start == wob_range(REFERENCE_RIG)[0] and shipped.options.elements == 16
    out = tmp_path / "map"
    m = write_controller_map(
        out, paper, constrained_path=cons, controllers=("stiff-pi", "z-torque", "lmi"), n=3,
        rpm=(40.0, 90.0), wob_kN=(20.0, 30.0), tau_end=4.0, window=1.0, min_periods=0.0,
        elements=4, braking="none", serial=True, log=None,
    )  # fmt: skip
    assert m.spec.options.elements == 4 and m.spec.options.braking == "none"
    with open(m.files["si"], newline="") as fh:
        table = list(csv.DictReader(fh))
    assert m.files["si"].name == MAP_SI and len(table) == 9
    plain = ("outcome.", "utr.", "severity.", "stick_fraction.", "stall.", "saturated_fraction.")
    units = ("_kNm.", "_kW.", "_rpm.", "_s.", "_per_s.")
    for c in table[0]:
        base = c in ("index", "i", "j", "rpm", "W0_kN", "best", "wall_time_s", "error")
        assert (
            base
            or c.startswith(plain)
            or any(u in c for u in units)
            or c.endswith(("_scaled", "_per_s", "_rad_per_s", "_m_per_s"))
        ), c
    raw = {int(r["index"]): r for r in csv.DictReader(open(m.report.results, newline=""))}
    # results.csv, the sweep's working file, holds scaled values: its columns say so
    for c in next(iter(raw.values())):
        metric = c.split(".")[0]
        assert not metric.endswith(("torque", "torque_late", "power", "speed", "abscissa")), c
        assert metric not in ("settling_time", "min_table_speed"), c
    for r in table:
        k = int(r["index"])
        sc = m.spec.point_scales(k)
        for c in ("stiff-pi", "z-torque"):
            scaled = float(raw[k][f"peak_torque_scaled.{c}"])
            assert float(r[f"peak_torque_kNm.{c}"]) == pytest.approx(scaled * sc.C / 1e3)
            t = raw[k][f"settling_time_scaled.{c}"]
            if t and math.isfinite(float(t)):
                assert float(r[f"settling_time_s.{c}"]) == pytest.approx(float(t) * sc.t_star)
    # the figure fixes: stopped runs grey, the settling time only where steady
    assert shown_values("stall", ["0", "1", "0"], ["reverse_rotation", "stall", "steady"]) == [
        None, 1.0, 0.0,
    ]  # fmt: skip
    assert shown_values("settling_time", ["3", "4", ""], ["steady", "settling", "steady"]) == [
        3.0, None, None,
    ]  # fmt: skip
    # the linear overlay is on the runs' string and says so
    rows, _ = read_results(m.report.results, sweep_columns(m.spec))
    overlays = _boundary_overlays(m.spec, rows, tmp_path)
    labels = {o.label for v in overlays.values() for o in v}
    assert all("4-element string" in text for text in labels), labels
    assert any("hatched: unstable" in text for text in labels)
    for name in ("outcome", "stall", "settling_time", "best"):
        assert (out / "plots" / f"{name}.png").stat().st_size > 10_000
