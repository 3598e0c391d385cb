"""Tests for the parameter sweeps (drillstring.apps.sweep: runner, spec, studies).

The Dask run is checked against the serial run of the same sweep point by point; resume and
failure handling use cheap stand-in point functions; the metrics are checked against independent
computations (sampled mode fractions, the characteristic determinant of (29), the control law
(29)-(31) evaluated by hand at tau = 0).
"""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import fmu_testlib as tl
import numpy as np
import pytest

from drillstring.apps.sweep.options import ClosedLoopOptions
from drillstring.apps.sweep.runner import SweepError, columns, read_results, run_sweep, sweep_main
from drillstring.apps.sweep.spec import (
    MAX_POINTS,
    SweepSpecError,
    load_spec,
    spec_from_dict,
)
from drillstring.apps.sweep.studies import (
    axial_design,
    closed_loop_metrics,
    rightmost_nonzero_root,
)
from drillstring.controller.averaged import averaged_model, delay_roots
from drillstring.controller.gains import PAPER_F, write_gains
from drillstring.model.engine import EngineOptions
from drillstring.model.params import REFERENCE, PhysicalParams, save_params
from drillstring.model.simulate import simulate

# 3 x 3 open-loop plane; omega0 = 25 makes taubar_n0 = 1.99 < taubar_crit = 2.39, where the
# averaged model (25) does not hold: those three points must fail and be recorded.
OPEN_3X3 = {
    "study": "open-loop",
    "base": "reference",
    "tau_end": 5.0,
    "sweep": [
        {"param": "omega0", "start": 4.0, "stop": 25.0, "num": 3},
        {"param": "v0", "start": 0.5, "stop": 1.5, "num": 3},
    ],
}
AXIAL_1D = {
    "study": "axial",
    "base": "reference",
    "sweep": [{"param": "taubar_n", "start": 8.0, "stop": 16.0, "num": 6}],
}


def rows_of(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


# --------------------------------------------------------------------------------------------
# Dask == serial
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def serial_3x3(tmp_path_factory):
    spec = spec_from_dict(OPEN_3X3)
    out = tmp_path_factory.mktemp("serial")
    report = run_sweep(spec, out, serial=True, progress=False, plots=False)
    return spec, report


def test_a_real_sweep_keeps_its_failed_points(serial_3x3):
    """The 3 x 3 plane run serially: every point has its row, sorted; omega0 = 25 fails with
    the reason (taubar_n0 below the critical delay) and the sweep is finished but not complete;
    the six other points ran to the end."""
    _, report = serial_3x3
    assert report.finished and not report.complete
    rows = rows_of(report.results)
    assert [int(r["index"]) for r in rows] == list(range(9))
    failed = [r for r in rows if r["error"]]
    assert [float(r["omega0"]) for r in failed] == [25.0] * 3
    assert all("taubar_n0" in r["error"] for r in failed)
    ok = [r for r in rows if not r["error"]]
    assert len(ok) == 6
    assert all(r["status"] == "ok" and float(r["tau_reached"]) == 5.0 for r in ok)


def test_open_loop_root_is_a_characteristic_root(serial_3x3):
    """root_real/root_imag solve det(sI - A0 - A1 exp(-s tau_n0)) = 0 (docs/model.md, "Equation
    (30)") and are not the rigid-body root s = 0."""
    spec, report = serial_3x3
    row = rows_of(report.results)[1]  # omega0 = 4, v0 = 1
    p = spec.point_params(1)
    assert (p.omega0, p.v0) == (4.0, 1.0)
    d = axial_design(p)
    m = averaged_model(p, d.A, d.taubar_crit)
    s = complex(float(row["root_real"]), float(row["root_imag"]))
    assert abs(s) > 0.1
    det = np.linalg.det(s * np.eye(4) - m.A0 - m.A1 * np.exp(-s * m.tau_n0))
    assert abs(det) < 1e-9
    # every other nonzero root found lies to the left
    others = delay_roots(m, n_roots=8)
    assert np.all(others.real[np.abs(others) > 1e-6] <= s.real + 1e-12)


# --------------------------------------------------------------------------------------------
# resume and failures (stand-in point functions: no physics, instant)
# --------------------------------------------------------------------------------------------

CALLS: list[int] = []


def fake_point(spec, index, design):
    CALLS.append(index)
    return {
        "average": 0.25 * index,
        "period": 1.0 + index,
        "stick_fraction": 0.5,
        "stick_phases": 1,
        "kind": "periodic",
        "time_simulated": 10.0,
    }


def interrupted_after(k):
    def point(spec, index, design):
        if len(CALLS) == k:
            raise KeyboardInterrupt  # like Ctrl-C / a killed job
        return fake_point(spec, index, design)

    return point


def failing_on(bad):
    def point(spec, index, design):
        if index in bad:
            raise ValueError(f"point {index} broke\nsecond line")
        return fake_point(spec, index, design)

    return point


def test_resume_after_interrupt_has_every_point_once(tmp_path):
    spec = spec_from_dict(AXIAL_1D)
    CALLS.clear()
    with pytest.raises(KeyboardInterrupt):
        run_sweep(spec, tmp_path, serial=True, progress=False, point_fn=interrupted_after(4))
    done = rows_of(tmp_path / "results.csv")
    assert [int(r["index"]) for r in done] == [0, 1, 2, 3]
    # killed in the middle of writing a fifth row: a partial line without newline
    with open(tmp_path / "results.csv", "a") as fh:
        fh.write("4,4,12.8,0.5")
    with pytest.raises(SweepError, match="--resume"):
        run_sweep(spec, tmp_path, serial=True, progress=False, point_fn=fake_point)
    CALLS.clear()
    report = run_sweep(
        spec, tmp_path, serial=True, progress=False, resume=True, point_fn=fake_point
    )
    assert CALLS == [4, 5]  # only the missing points were computed
    assert report.complete and report.n_skipped == 4 and report.n_computed == 2
    rows = rows_of(tmp_path / "results.csv")
    assert [int(r["index"]) for r in rows] == list(range(6))
    assert [float(r["average"]) for r in rows] == [0.25 * k for k in range(6)]
    # resuming a complete sweep computes nothing
    CALLS.clear()
    again = run_sweep(
        spec, tmp_path, serial=True, progress=False, resume=True, point_fn=fake_point, plots=False
    )
    assert CALLS == [] and again.n_computed == 0 and len(rows_of(again.results)) == 6


def test_failed_point_records_error_and_sweep_finishes(tmp_path):
    """A failed point records its error and the sweep goes on to the end: it is finished (every
    point has its row, the maps are drawn) but not complete (not every point succeeded)."""
    spec = spec_from_dict(AXIAL_1D)
    report = run_sweep(spec, tmp_path, serial=True, progress=False, point_fn=failing_on({1, 4}))
    assert report.finished and not report.complete and report.n_failed == 2
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert (summary["finished"], summary["complete"], summary["failed"]) == (True, False, 2)
    rows = rows_of(tmp_path / "results.csv")
    assert [r["error"] for r in rows if r["error"]] == [
        "ValueError: point 1 broke | second line",
        "ValueError: point 4 broke | second line",
    ]
    assert all(r["average"] == "" for r in rows if r["error"])
    assert [float(r["average"]) for r in rows if not r["error"]] == [0.0, 0.5, 0.75, 1.25]
    assert sorted(p.name for p in report.plots) == sorted(f"{m}.png" for m in spec.metrics)
    # --retry-failed recomputes exactly the failed points
    CALLS.clear()
    run_sweep(
        spec,
        tmp_path,
        serial=True,
        progress=False,
        resume=True,
        retry_failed=True,
        point_fn=fake_point,
        plots=False,
    )
    assert sorted(CALLS) == [1, 4]
    rows = rows_of(tmp_path / "results.csv")
    assert [int(r["index"]) for r in rows] == list(range(6))
    assert not any(r["error"] for r in rows)
    assert json.loads((tmp_path / "summary.json").read_text())["complete"] is True


def test_resume_refuses_a_different_spec(tmp_path):
    run_sweep(spec_from_dict(AXIAL_1D), tmp_path, serial=True, progress=False, point_fn=fake_point)
    other = dict(AXIAL_1D, sweep=[{"param": "taubar_n", "start": 8.0, "stop": 20.0, "num": 6}])
    with pytest.raises(SweepError, match="different spec.*sweep"):
        run_sweep(spec_from_dict(other), tmp_path, serial=True, resume=True, progress=False)


def test_read_results_drops_partial_line_and_duplicates(tmp_path):
    spec = spec_from_dict(AXIAL_1D)
    header = columns(spec)
    path = tmp_path / "r.csv"
    line = "0,0,8.0,1.0,2.0,0.5,1,periodic,3.0,0.1,"
    path.write_text(",".join(header) + "\n" + line + "\n" + line + "\n" + "1,1,9.6,0.")
    rows, dirty = read_results(path, header)
    assert dirty and list(rows) == [0]
    with pytest.raises(SweepError, match="columns"):
        read_results(path, header[:-1])


# --------------------------------------------------------------------------------------------
# metrics against independent computations
# --------------------------------------------------------------------------------------------


def test_axial_stick_fraction_matches_sampled_modes():
    """Exact (event) stick time vs counting samples with mode == 1 every 1e-3: they differ by at
    most one sample interval per mode change."""
    r = simulate(
        REFERENCE, 4.0, initial={"dphi": -2.5}, dt_out=1e-3, options=EngineOptions(), progress=False
    )
    exact = r.axial_stick_fraction()
    sampled = float(np.mean(r.mode[:-1] == 1.0))
    n_changes = sum(1 for e in r.events if e.kind == "mode")
    assert n_changes > 10 and 0.05 < exact < 0.95
    assert abs(exact - sampled) <= n_changes * 1e-3 / 4.0 + 1e-12


def test_rightmost_nonzero_root_drops_only_the_origin():
    roots = np.array([0.1 + 1j, 0.1 - 1j, -3e-16 + 0j, -0.5])
    assert rightmost_nonzero_root(roots) == complex(0.1, 1.0)
    assert rightmost_nonzero_root(np.array([-0.2, -1.0])) == complex(-0.2, 0.0)


def test_closed_loop_with_the_paper_gain_file(tmp_path):
    """Fixed gains file (the paper's F) on a 1-D sweep of omega0 through the reference point:
    converges (Fig. 5); max |R - R0| is attained at tau = 0, where by hand
    R - R0 = R_ff + F1*dphi0 + F2*(-K0) (x = [0, dphi0, -K0, 0])."""
    d = axial_design(REFERENCE)
    gains = tl.gains_file(PAPER_F, d.A, d.taubar_crit, solver="paper", solver_status="published")
    K0 = 4 * 1.0 * 0.5 * d.A * (math.pi / 10 - d.taubar_crit / math.sqrt(1000.0))  # (27)
    assert K0 == pytest.approx(gains.K0, rel=1e-12) and gains.R_ff == -gains.K0
    write_gains(gains, tmp_path / "paper_gains.json")
    spec = spec_from_dict(
        {
            "study": "closed-loop",
            "base": "reference",
            "tau_end": 20.0,
            "sweep": [{"param": "omega0", "start": 5.0, "stop": 8.0, "num": 2}],
            "options": {"gains": "paper_gains.json"},
        },
        base_dir=tmp_path,
    )
    report = run_sweep(spec, tmp_path / "out", serial=True, progress=False)
    rows = rows_of(report.results)
    r0 = -K0 + PAPER_F[1] * (-2.5) + PAPER_F[2] * (-K0)
    for row in rows:
        assert row["error"] == "" and row["status"] == "ok"
        assert row["converged"] == "1"
        assert float(row["dphi_amplitude"]) < 0.05 * 2.5
        assert float(row["max_dR"]) == pytest.approx(abs(r0), rel=1e-12)
        assert float(row["abscissa_closed"]) < 0.0
        assert float(row["gain_norm"]) == pytest.approx(np.linalg.norm(PAPER_F), rel=1e-12)


def test_closed_loop_design_at_the_point_converges():
    out = closed_loop_metrics(REFERENCE, axial_design(REFERENCE), 20.0, ClosedLoopOptions())
    assert out["status"] == "ok" and out["converged"] == 1
    assert out["abscissa_closed"] < 0.0 and out["gain_norm"] <= 4.0e3


# --------------------------------------------------------------------------------------------
# spec files and validation
# --------------------------------------------------------------------------------------------


def test_points_row_major_log_scale_and_derived_params():
    spec = spec_from_dict(
        {
            "study": "open-loop",
            "base": "reference",
            "tau_end": 1.0,
            "sweep": [
                {"param": "gammabar", "start": 0.1, "stop": 0.4, "num": 3, "scale": "log"},
                {"param": "etabar2", "start": 0.05, "stop": 0.2, "num": 2},
            ],
        }
    )
    assert spec.shape == (3, 2) and spec.grid_index(3) == (1, 1)
    assert [spec.point_values(k)["gammabar"] for k in (0, 2, 4)] == pytest.approx([0.1, 0.2, 0.4])
    p = spec.point_params(3)
    assert p.gammabar == pytest.approx(0.2, rel=1e-14)
    assert p.etabar2 == pytest.approx(0.2, rel=1e-14)
    assert (p.psi, p.omega0) == (REFERENCE.psi, REFERENCE.omega0)
    assert spec.reference_values() == pytest.approx({"gammabar": 0.2, "etabar2": 0.1})


def test_toml_spec_with_physical_base_file(tmp_path):
    phys = PhysicalParams(
        M=8.0, I1=4.0, I2=12.0, C=1.0, K=50.0, D=2.0, n=3, a=1.0, eps=2.0, zeta=0.5,
        sigma_bar=10.0, l=0.3, mu=0.8, xi=0.5, V0=0.25, Omega0=1.5,
    )  # fmt: skip
    save_params(phys, tmp_path / "rig.toml")
    (tmp_path / "s.toml").write_text(
        'study = "open-loop"\nbase = "rig.toml"\ntau_end = 2.0\n'
        '[[sweep]]\nparam = "Omega0"\nstart = 1.5\nstop = 3.0\nnum = 2\n'
        "[options]\ndphi0 = -1.0\n"
    )
    spec = load_spec(tmp_path / "s.toml")
    # omega0 = Omega0 * t*, t* = sqrt(I1/C) = 2 (eq. (15))
    assert spec.point_params(1).omega0 == pytest.approx(6.0, rel=1e-14)
    assert spec.reference_values() == {"Omega0": 1.5}
    assert spec.to_dict()["base"]["kind"] == "physical"


BAD_SPECS = [
    ({**OPEN_3X3, "color": "red"}, "unknown key 'color'"),
    ({k: v for k, v in OPEN_3X3.items() if k != "study"}, "missing key 'study'"),
    ({**OPEN_3X3, "study": "open_loop"}, "study must be one of"),
    ({**OPEN_3X3, "base": "nominal"}, "base = 'nominal'"),
    ({**OPEN_3X3, "base": {"name": "reference", "file": "x.toml"}}, "give one of"),
    ({**OPEN_3X3, "tau_end": -1.0}, "tau_end must be > 0"),
    ({k: v for k, v in OPEN_3X3.items() if k != "tau_end"}, "missing key 'tau_end'"),
    ({**AXIAL_1D, "tau_end": 5.0}, "tau_end is not used"),
    ({**OPEN_3X3, "sweep": []}, "one or two axes"),
    ({**OPEN_3X3, "sweep": [{"param": "omega", "start": 1, "stop": 2, "num": 3}]}, "'omega'"),
    ({**OPEN_3X3, "sweep": [{"param": "v0", "start": 1, "stop": 2, "num": 1}]}, "num must be"),
    ({**OPEN_3X3, "sweep": [{"param": "v0", "start": 1, "stop": 2}]}, "missing key 'num'"),
    (
        {**OPEN_3X3, "sweep": [{"param": "v0", "start": 0, "stop": 2, "num": 3, "scale": "log"}]},
        "log scale needs start > 0",
    ),
    (
        {**OPEN_3X3, "sweep": [{"param": "v0", "start": 1, "stop": 2, "num": 3, "step": 1}]},
        "unknown key 'step' in sweep[0]",
    ),
    (
        {
            **OPEN_3X3,
            "sweep": [
                {"param": "gamma", "start": 1, "stop": 2, "num": 2},
                {"param": "gammabar", "start": 0.1, "stop": 0.2, "num": 2},
            ],
        },
        "conflict",
    ),
    (
        {**OPEN_3X3, "sweep": [{"param": "beta", "start": 0.5, "stop": 1.5, "num": 3}]},
        "beta must be in",
    ),
    (
        {**OPEN_3X3, "sweep": [{"param": "omega0", "start": 1.0, "stop": 5.0, "num": 3}]},
        "torsional stick",
    ),
    ({**OPEN_3X3, "options": {"gains": "design"}}, "unknown key 'gains' in options"),
    ({**OPEN_3X3, "options": {"h": 0.0}}, "options.h must be > 0"),
    ({**OPEN_3X3, "options": {"h": 0.1}}, "must not exceed options.dt_out"),
    ({**OPEN_3X3, "metrics": ["converged"]}, "unknown metric 'converged'"),
    ({**OPEN_3X3, "study": "closed-loop", "options": {"window": 9.0}}, "window = 9.0 exceeds"),
    ({**OPEN_3X3, "study": "closed-loop", "options": {"gains": "nope.json"}}, "options.gains"),
    ({**OPEN_3X3, "study": "closed-loop", "options": {"dphi0": 0}}, "dphi0 must be nonzero"),
    ({**AXIAL_1D, "sweep": [{"param": "omega0", "start": 1, "stop": 2, "num": 2}]}, "taubar_n"),
    (
        {**AXIAL_1D, "sweep": [{"param": "etabar2", "start": -0.1, "stop": 0.2, "num": 2}]},
        "etabar2 must be > 0",
    ),
]


@pytest.mark.parametrize(("data", "message"), BAD_SPECS)
def test_spec_validation_errors(data, message, tmp_path):
    with pytest.raises(SweepSpecError, match=message.replace("(", r"\(").replace("[", r"\[")):
        spec_from_dict(data, base_dir=tmp_path)


def test_spec_file_errors(tmp_path):
    (tmp_path / "bad.toml").write_text("study = \n")
    with pytest.raises(SweepSpecError, match="not valid toml"):
        load_spec(tmp_path / "bad.toml")
    with pytest.raises(SweepSpecError, match="suffix"):
        load_spec(tmp_path / "spec.yaml")
    with pytest.raises(SweepSpecError, match="cannot read"):
        load_spec(tmp_path / "missing.json")


# --------------------------------------------------------------------------------------------
# command line
# --------------------------------------------------------------------------------------------


def test_cli_serial_axial_sweep(tmp_path, capsys):
    spec = dict(AXIAL_1D, sweep=[{"param": "taubar_n", "start": 8.0, "stop": 16.0, "num": 3}])
    (tmp_path / "a.json").write_text(json.dumps(spec))
    out = tmp_path / "out"
    assert sweep_main([str(tmp_path / "a.json"), "--out", str(out), "--workers", "0",
                       "--no-progress"]) == 0  # fmt: skip
    rows = rows_of(out / "results.csv")
    assert [r["kind"] for r in rows] == ["periodic"] * 3
    avg = [float(r["average"]) for r in rows]
    # Fig. 4: the averaged contact force grows with the delay above taubar_crit
    assert 0 < avg[0] < avg[1] < avg[2]
    assert (out / "plots" / "average.png").exists()
    assert json.loads((out / "summary.json").read_text())["complete"] is True
    # a second run into the same folder without --resume is refused with a clear message
    assert sweep_main([str(tmp_path / "a.json"), "--out", str(out), "--workers", "0"]) == 2
    assert "--resume" in capsys.readouterr().err


def test_grid_size_is_checked_before_the_points(tmp_path, capsys):
    """A grid beyond the limit is refused from its axes alone, naming the sizes, the limit and
    the option that allows it (1e16 points: validating them one by one would never end); the
    limit is the caller's to raise."""
    huge = dict(AXIAL_1D, sweep=[{"param": "gammabar", "start": 0.1, "stop": 0.5,
                                  "num": 10**8},
                                 {"param": "taubar_n", "start": 8.0, "stop": 16.0,
                                  "num": 10**8}])  # fmt: skip
    message = (
        f"the grid has {10**16} points (sweep[0].num = {10**8} x sweep[1].num = {10**8}), "
        f"more than the limit of {MAX_POINTS} (drillstring sweep --max-points {10**16} allows it)"
    )
    with pytest.raises(SweepSpecError, match=re.escape(message)):
        spec_from_dict(huge)
    six = AXIAL_1D["sweep"][0]["num"]
    with pytest.raises(SweepSpecError, match=f"the grid has {six} points"):
        spec_from_dict(AXIAL_1D, max_points=six - 1)
    assert spec_from_dict(AXIAL_1D, max_points=six).n_points == six
    # on the command line: --max-points, exit 2 before anything is written
    (tmp_path / "a.json").write_text(json.dumps(AXIAL_1D))
    out = tmp_path / "out"
    argv = [str(tmp_path / "a.json"), "--out", str(out), "--workers", "0", "--no-progress"]
    assert sweep_main([*argv, "--max-points", str(six - 1)]) == 2
    assert f"more than the limit of {six - 1}" in capsys.readouterr().err
    assert not out.exists()
    assert sweep_main([*argv, "--max-points", "0"]) == 2
    assert "--max-points must be >= 1, got 0" in capsys.readouterr().err


def test_cli_sweep_whose_points_all_fail_exits_non_zero(tmp_path, capsys):
    """tau_end = 1e308 makes every point fail (its output grid cannot be built): the sweep
    finishes, is not complete, and exits 1 saying so."""
    spec = {**OPEN_3X3, "tau_end": 1e308, "metrics": ["root_real"],
            "sweep": [{"param": "omega0", "start": 4.0, "stop": 6.0, "num": 2}]}  # fmt: skip
    (tmp_path / "big.json").write_text(json.dumps(spec))
    out = tmp_path / "out"
    code = sweep_main([str(tmp_path / "big.json"), "--out", str(out), "--workers", "0",
                       "--no-progress", "--no-plots"])  # fmt: skip
    assert code == 1
    assert "every point failed" in capsys.readouterr().err
    rows = rows_of(out / "results.csv")
    assert len(rows) == 2 and all(r["error"] for r in rows)
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["finished"], summary["complete"], summary["failed"]) == (True, False, 2)


def test_cli_reports_spec_errors(tmp_path, capsys):
    (tmp_path / "s.json").write_text(json.dumps({**AXIAL_1D, "colour": 1}))
    assert sweep_main([str(tmp_path / "s.json"), "--out", str(tmp_path / "o")]) == 2
    assert "unknown key 'colour'" in capsys.readouterr().err
    assert sweep_main(["x.toml", "--out", "o", "--scheduler", "tcp://h:1", "--workers", "2"]) == 2
