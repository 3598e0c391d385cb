"""The controllers sweep study (drillstring.apps.sweep, study "controllers") and the map.

A map on Dask equals the serial run point by point; a row equals the metrics of the runs done
directly; the derived axes (rpm, nominal WOB) by hand; the classification of a slowly decaying
run; the linearised boundary against the eigenvalues of a hand-derived characteristic
polynomial; resume works like in the other studies; the options are validated.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import pickle

import fmu_testlib as tl
import numpy as np
import pytest

from drillstring.analysis.severity import (
    MIN_WINDOW_PERIODS,
    SLOWEST_PERIOD,
    axial_average,
    axial_period,
    severity_metrics,
)
from drillstring.apps.controllers import (
    COMPARISON_COLUMNS,
    COMPARISON_TAU_END,
    COMPARISON_WINDOW,
    controller_map_spec,
    controllers_main,
    wob_range,
    write_controller_comparison,
)
from drillstring.apps.sweep.metrics import controller_column
from drillstring.apps.sweep.options import ControllerOptions
from drillstring.apps.sweep.runner import run_sweep
from drillstring.apps.sweep.spec import FEED_FOR_WOB, SweepSpecError, spec_from_dict
from drillstring.apps.sweep.studies import (
    OPEN_LOOP,
    axial_design,
    evaluate_point,
    linear_boundary,
    lineup_at,
    point_gains,
)
from drillstring.controller.averaged import averaged_model
from drillstring.controller.design import design_constrained
from drillstring.controller.gains import PAPER_F, write_gains
from drillstring.controller.lineup import (
    MAP_CONTROLLERS,
    RIG_CONTROLLERS,
    SENSING,
    TIMED_CONTROLLERS,
    LmiGain,
    lmi_gain,
    rig_lineup,
    sensing_note,
)
from drillstring.model.engine import EngineOptions
from drillstring.model.experiments import Experiment
from drillstring.model.kernel.jit import numba_available
from drillstring.model.params import REFERENCE, REFERENCE_RIG, get_physical
from drillstring.model.sampled import simulate_sampled
from drillstring.model.topdrive import TDS_11SA, top_drive

RIG = {"kind": "physical", **REFERENCE_RIG.to_dict()}
#: The reference rig's own speed and nominal WOB (the map's point 0 below).
RPM0 = REFERENCE_RIG.surface_speed_rpm
W0_KN = REFERENCE_RIG.W0 / 1e3


def _design_gains(F, constraint=None):
    d = axial_design(REFERENCE)
    if constraint is None:
        return tl.gains_file(F, d.A, d.taubar_crit, solver="paper", solver_status="published")
    return tl.gains_file(F, d.A, d.taubar_crit, constraint=constraint)


@pytest.fixture(scope="module")
def paper_gains(tmp_path_factory):
    gains = _design_gains(PAPER_F)
    return gains, write_gains(gains, tmp_path_factory.mktemp("gains") / "paper.json")


@pytest.fixture(scope="module")
def constrained_gains(tmp_path_factory):
    # a gain of the constrained design's size (drillstring design --torque-limit tds-11sa
    # gives one of norm 124); the record is an input here, not a result under test
    record = {"u_max": 212.0, "peak_torque": 147.0, "decay": 0.0, "tau_max": 0.63}
    gains = _design_gains((-88.16, -65.50, 52.86, -19.72), record)
    return gains, write_gains(gains, tmp_path_factory.mktemp("gains") / "constrained.json")


def _spec(paper, constrained, *, tau_end=20.0, sweep=None, **options):
    return spec_from_dict(
        {
            "study": "controllers",
            "base": RIG,
            "tau_end": tau_end,
            "sweep": sweep
            or [
                {"param": "rpm", "start": RPM0, "stop": 90.0, "num": 2},
                {"param": "W0_kN", "start": W0_KN, "stop": 22.0, "num": 2},
            ],
            "options": {
                "gains": str(paper[1]),
                "gains_constrained": str(constrained[1]),
                "window": 5.0,
                "min_periods": 0.0,  # short runs: the mechanics, not the classification
                **options,
            },
        }
    )


def _lineup(spec, params, scales):
    """The study's controllers at a point (its gains, drive and tuning), not run."""
    d = axial_design(params)
    model = averaged_model(params, d.A, d.taubar_crit)
    paper, constrained, names, _ = point_gains(model, spec.options)
    return lineup_at(params, model, paper, constrained, spec.options, scales, names)


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def serial_map(paper_gains, constrained_gains, tmp_path_factory):
    spec = _spec(paper_gains, constrained_gains)
    out = tmp_path_factory.mktemp("serial")
    return spec, run_sweep(spec, out, serial=True, progress=False, plots=False)


@pytest.mark.slow  # a local Dask cluster of worker processes
def test_controller_map_on_dask_equals_the_serial_run(serial_map, tmp_path):
    """The suite's one Dask-equals-serial run (the runner is the same for every study; a failed
    point is a row the point function writes in either mode, tests/test_sweep.py)."""
    spec, serial = serial_map
    assert spec.options.controllers == MAP_CONTROLLERS
    report = run_sweep(spec, tmp_path, workers=2, progress=False)
    assert report.complete and serial.complete and report.n_failed == 0
    a, b = _rows(serial.results), _rows(report.results)
    assert [int(r["index"]) for r in b] == list(range(len(a)))  # sorted, every point once
    # the workers loaded the compiled kernel from numba's cache instead of compiling it
    workers = report.execution["workers"]
    assert len(workers) == 2
    if numba_available():
        assert all(w["cache_misses"] == 0 and w["cache_hits"] > 0 for w in workers.values())
    outcomes = set()
    for ra, rb in zip(a, b, strict=True):
        ra.pop("seconds"), rb.pop("seconds")
        assert ra == rb  # bit-identical, point by point, every metric of every controller
        outcomes |= {ra[f"outcome.{c}"] for c in MAP_CONTROLLERS}
        for c in MAP_CONTROLLERS:
            if ra[f"outcome.{c}"] in ("steady", "settling", "vibration", "stick-slip"):
                assert math.isfinite(float(ra[controller_column("rms_torque_late", c)]))
    # the runs differ between controllers: the equality is not that of empty rows
    assert len(outcomes) >= 3
    names = sorted(p.name for p in report.plots)
    assert names == sorted(f"{m}.png" for m in spec.metrics)
    assert all(p.stat().st_size > 1000 for p in report.plots)
    assert (tmp_path / "plots" / "boundary.csv").exists()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["feed"] == FEED_FOR_WOB == spec.feed


def test_a_map_row_is_the_metrics_of_the_runs(serial_map, paper_gains, constrained_gains):
    spec, serial = serial_map
    row = _rows(serial.results)[3]  # 90 rpm, 22 kN
    p = spec.point_params(3)
    rig = spec.point_scales(3)
    assert (rig.surface_speed_rpm, rig.W0) == (pytest.approx(90.0), pytest.approx(22e3))
    d = axial_design(p)
    model = averaged_model(p, d.A, d.taubar_crit)
    paper = lmi_gain(model, paper_gains[0], feedforward="point")
    constrained = lmi_gain(model, constrained_gains[0], feedforward="point")
    controllers = rig_lineup(
        p,
        model,
        paper=paper,
        constrained=constrained,
        top_drive=top_drive(TDS_11SA, rig),
        scales=rig,
        Ts=1e-3,
        names=MAP_CONTROLLERS,
    )
    for name in MAP_CONTROLLERS:
        r = simulate_sampled(
            p,
            controllers[name],
            20.0,
            1e-3,
            initial={"dphi": -0.5 * p.omega0},
            options=EngineOptions(torsional_stick=True),
        )
        s = severity_metrics(r, 5.0)
        assert row[f"outcome.{name}"] == s.outcome
        for metric in ("utr", "peak_torque", "rms_torque_late", "peak_power"):
            value = getattr(s, metric)
            col = controller_column(metric, name)  # "_scaled" for a dimensional metric
            assert (row[col] == "nan") if math.isnan(value) else (float(row[col]) == value)
    assert row["best"] in MAP_CONTROLLERS
    assert float(row["lmi_gain_norm"]) == pytest.approx(math.hypot(*PAPER_F), rel=1e-12)
    assert float(row["V0"]) == rig.V0 and float(row["Omega0"]) == rig.Omega0


def _late_period(run, params, t0):
    """Median period of the bit speed averaged over the axial cycle over [t0, end]: the time
    between its upward crossings of its mean (the torsional oscillation, stick-slip or not)."""
    period = axial_period(run.events, t0, run.tau[-1], 2.0 * math.pi / params.eta)
    ta, wa = axial_average(run.tau, params.omega0 + run.dphi, period)
    late = ta >= t0
    t, x = ta[late], wa[late] - np.mean(wa[late])
    up = t[1:][(x[:-1] < 0.0) & (x[1:] >= 0.0)]
    gaps = np.diff(up)
    gaps = gaps[gaps > 2.0]  # crossings of the axial ripple's remainder within one period
    assert len(gaps) >= 10, gaps
    return float(np.median(gaps))


def test_the_map_window_holds_five_periods_of_the_slowest_stick_slip(paper_gains, tmp_path):
    """The default window holds MIN_WINDOW_PERIODS periods of the slowest oscillation the map
    classifies: the stiff PI's stick-slip, measured at the map's slow corner (30 rpm, the top
    of the default WOB range: the longest period over the map) and at the reference rig's own
    point; a shorter window is refused naming its value, and the trend test's two windows fit
    after the switch-on."""
    spec = controller_map_spec(paper_gains[1], n=2, controllers=["stiff-pi"])
    window, tau_end = spec.options.window, spec.tau_end
    assert window == COMPARISON_WINDOW and 2.0 * window <= tau_end - spec.options.t_on
    rig = REFERENCE_RIG
    points = {"slow corner": {"rpm": 30.0, "W0_kN": wob_range(rig)[1]},
              "reference": {"rpm": RPM0, "W0_kN": W0_KN}}  # fmt: skip
    periods = {}
    for label, values in points.items():
        p = spec.params_at(values)
        pi = _lineup(spec, p, spec.physical_at(values))["stiff-pi"]
        r = simulate_sampled(
            p, pi, tau_end, 1e-3, initial={"dphi": -0.5 * p.omega0},
            options=EngineOptions(torsional_stick=True),
        )  # fmt: skip
        assert r.status.ok, (label, r.status)
        periods[label] = _late_period(r, p, tau_end / 2.0)
    # slower than the string with the table held (2 pi), within the bound the check uses
    for label, T in periods.items():
        assert 2.0 * math.pi < T <= SLOWEST_PERIOD, (label, T)
        assert window / T >= MIN_WINDOW_PERIODS, (label, T, window / T)
    assert periods["slow corner"] > periods["reference"]
    # a window of 30 (4.3 periods) is refused, in the map and in the comparison
    with pytest.raises(SweepSpecError, match=r"options.window = 30.0 holds 4.29 periods"):
        controller_map_spec(paper_gains[1], n=2, controllers=["stiff-pi"], window=30.0)
    with pytest.raises(ValueError, match=r"window = 30.0 holds 4.29 periods"):
        write_controller_comparison(
            tmp_path, paper_gains[0], options=ControllerOptions(window=30.0), log=None
        )
    # the comparison's two windows follow Fig. 6's switch-on at tau = 25
    assert 2.0 * COMPARISON_WINDOW <= COMPARISON_TAU_END - 25.0


def test_the_derived_axes_by_hand():
    # the reference rig (docs/reference_rig.md): n = 4, a = 0.10795 m, zeta = 0.6,
    # eps = sigma_bar = 60 MPa, l = 0.637 mm
    r = REFERENCE_RIG
    contact = 4 * 0.10795 * r.l * 60e6
    assert r.contact_weight == pytest.approx(contact, rel=1e-14)
    assert contact == pytest.approx(16.51e3, rel=1e-3)
    spec = spec_from_dict(
        {
            "study": "open-loop",
            "base": RIG,
            "tau_end": 1.0,
            "sweep": [
                {"param": "rpm", "start": 30.0, "stop": 150.0, "num": 2},
                {"param": "W0_kN", "start": 17.5, "stop": 23.0, "num": 2},
            ],
        }
    )
    assert spec.feed == FEED_FOR_WOB
    for index, (rpm, wob) in enumerate([(30, 17.5), (30, 23.0), (150, 17.5), (150, 23.0)]):
        rig = spec.point_scales(index)
        omega = rpm * 2.0 * math.pi / 60.0
        # W0 = n a zeta eps d0 + n a l sigma_bar, d0 = 2 pi V0/(n Omega0): solved for V0
        V0 = (wob * 1e3 - contact) * omega / (2.0 * math.pi * 0.10795 * 0.6 * 60e6)
        assert rig.Omega0 == pytest.approx(omega, rel=1e-15)
        assert rig.V0 == pytest.approx(V0, rel=1e-12)
        d0 = 2.0 * math.pi * V0 / (4 * omega)
        assert 4 * 0.10795 * 0.6 * 60e6 * d0 + contact == pytest.approx(wob * 1e3, rel=1e-12)
        assert rig.W0 == pytest.approx(wob * 1e3, rel=1e-12)
        p = spec.point_params(index)
        assert p.omega0 == pytest.approx(omega * r.t_star, rel=1e-14)
        assert p.v0 == pytest.approx(V0 * r.t_star / r.L_star, rel=1e-12)
    assert spec.reference_values() == pytest.approx({"rpm": 51.756, "W0_kN": 19.7926}, rel=1e-4)
    # the default map's WOB range: v0 = 0.25 and 2 at the reference speed
    lo, hi = wob_range(r)
    cutting = r.W0 - contact  # at v0 = 1, proportional to v0
    assert (lo, hi) == (pytest.approx((contact + 0.25 * cutting) / 1e3, rel=1e-12),
                        pytest.approx((contact + 2.0 * cutting) / 1e3, rel=1e-12))  # fmt: skip


@pytest.mark.parametrize(
    ("sweep", "message"),
    [
        (
            [{"param": "W0_kN", "start": 16.0, "stop": 20.0, "num": 2}],
            r"W0_kN = 16.0\) is invalid: W0 = 16000.0 N is not above the wearflat contact part",
        ),
        ([{"param": "rpm", "start": 0.0, "stop": 60.0, "num": 2}], "rpm must be > 0, got 0.0"),
        (
            [
                {"param": "rpm", "start": 30.0, "stop": 60.0, "num": 2},
                {"param": "Omega0", "start": 3.0, "stop": 6.0, "num": 2},
            ],
            "'rpm' and sweep\\[1\\].param = 'Omega0' conflict",
        ),
        (
            [
                {"param": "V0", "start": 1e-4, "stop": 1e-3, "num": 2},
                {"param": "W0_kN", "start": 18.0, "stop": 20.0, "num": 2},
            ],
            "conflict",
        ),
    ],
)
def test_derived_axis_errors_name_the_value(sweep, message):
    with pytest.raises(SweepSpecError, match=message):
        spec_from_dict({"study": "open-loop", "base": RIG, "tau_end": 1.0, "sweep": sweep})
    with pytest.raises(SweepSpecError, match="must be one of"):  # a scaled base has no rpm
        spec_from_dict(
            {
                "study": "open-loop",
                "base": "reference",
                "tau_end": 1.0,
                "sweep": [{"param": "rpm", "start": 30.0, "stop": 60.0, "num": 2}],
            }
        )


def test_a_slowly_decaying_run_is_settling_not_vibration(
    serial_map, paper_gains, constrained_gains
):
    # at the reference point SoftSpeed's linearised closed loop decays slowly (abscissa
    # -0.011) and the full model's bit speed, from dphi/dtau(0) = -omega0/2, still varies by
    # more than 5 % over tau in [15, 20], half as much as over [10, 15]: settling; the stiff PI
    # (abscissa +0.10) grows: vibration; a longer run of the same SoftSpeed is steady
    spec, serial = serial_map
    row = _rows(serial.results)[0]
    assert spec.point_values(0) == {"rpm": RPM0, "W0_kN": W0_KN}
    assert float(row["linear_abscissa_scaled.soft-speed"]) == pytest.approx(-0.0107, abs=5e-4)
    assert float(row["linear_abscissa_scaled.stiff-pi"]) == pytest.approx(0.101, abs=5e-3)
    assert row["outcome.soft-speed"] == "settling"
    assert float(row["severity.soft-speed"]) > 0.05
    assert row["outcome.stiff-pi"] == "vibration"
    assert row["outcome.z-torque"] == "steady"
    longer = _spec(paper_gains, constrained_gains, tau_end=40.0, controllers=["soft-speed"])
    p = longer.point_params(0)
    assert evaluate_point(longer, 0, axial_design(p))["outcome.soft-speed"] == "steady"


def _soft_speed_abscissa(nu: float, rho: float, kp: float, ki: float) -> float:
    """The rightmost root of (s^2 - nu s + 1)(rho s^2 + kp s + ki + 1) - 1, the SoftSpeed loop
    on (13), (27) derived by hand (docs/controllers.md): the bit's phi'' - nu phi' + phi - theta
    = 0, the table's rho theta'' = phi - theta - kp theta' - ki theta (integral of -theta')."""
    poly = np.polymul([1.0, -nu, 1.0], [rho, kp, ki + 1.0])
    poly[-1] -= 1.0  # the integrator's theta replaces phi: no rigid-body root here
    return float(np.max(np.roots(poly).real))


def test_the_overlaid_boundary_is_where_the_eigenvalues_cross(paper_gains, constrained_gains):
    spec = _spec(
        paper_gains,
        constrained_gains,
        sweep=[
            {"param": "rpm", "start": 30.0, "stop": 100.0, "num": 3},
            {"param": "W0_kN", "start": 18.0, "stop": 23.0, "num": 3},
        ],
    )
    p0 = spec.point_params(0)
    d = axial_design(p0)
    b = linear_boundary(spec, d, refine=10)
    assert b.abscissa["soft-speed"].shape == (21, 21)
    assert np.all(b.abscissa[OPEN_LOOP] > 0.0)  # nu > 0: the free table never damps
    z = b.abscissa["soft-speed"]
    crossings = 0
    for i in (4, 12):  # two speeds, the boundary crosses the WOB axis between grid points
        j = int(np.nonzero(np.diff(np.sign(z[i])))[0][0])
        w = b.y[j] - z[i, j] * (b.y[j + 1] - b.y[j]) / (z[i, j + 1] - z[i, j])
        values = {"rpm": float(b.x[i]), "W0_kN": float(w)}
        p = spec.params_at(values)
        m = averaged_model(p, d.A, d.taubar_crit)
        law = rig_lineup(p, m, paper=LmiGain((0, 0, 0, 0), m.K0, m.R_ff, math.nan),
                         constrained=None, top_drive=None, scales=REFERENCE_RIG, Ts=1e-3,
                         names=("soft-speed",))["soft-speed"].law  # fmt: skip
        nu = -m.c * m.tau_n0
        # the drawn boundary (linear interpolation on a grid of 0.25 kN) is where the
        # hand-derived polynomial's rightmost root has real part 0, to the interpolation
        assert abs(_soft_speed_abscissa(nu, p.rho, law.kp, law.ki)) < 2e-4
        # and at the grid points on either side the signs are the polynomial's
        for jj in (j, j + 1):
            pj = spec.params_at({"rpm": float(b.x[i]), "W0_kN": float(b.y[jj])})
            mj = averaged_model(pj, d.A, d.taubar_crit)
            ref = _soft_speed_abscissa(-mj.c * mj.tau_n0, pj.rho, law.kp, law.ki)
            assert z[i, jj] == pytest.approx(ref, abs=1e-9)
        crossings += 1
    assert crossings == 2


def test_the_study_options_pickle_for_the_workers(serial_map):
    """The spec a Dask worker receives: its typed options, the tuning as one object and the
    gains files read, as the submitting process has them."""
    spec, _ = serial_map
    back = pickle.loads(pickle.dumps(spec))
    assert back.options == spec.options and back.options.tuning == spec.options.tuning
    assert back.options.gains_file.F == spec.options.gains_file.F
    assert back.options.constrained_file.F == spec.options.constrained_file.F


def test_controller_map_resumes(paper_gains, constrained_gains, tmp_path):
    spec = _spec(paper_gains, constrained_gains)
    calls = []

    def point(spec_, index, design):
        calls.append(index)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return {"best": "lmi"}

    with pytest.raises(KeyboardInterrupt):
        run_sweep(spec, tmp_path, serial=True, progress=False, point_fn=point)
    calls.clear()
    report = run_sweep(
        spec, tmp_path, serial=True, progress=False, resume=True, point_fn=point, plots=False
    )
    assert calls == [2, 3] and report.complete and report.n_skipped == 2


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"Ts": 1e-4}, "options.h = 0.0005 must not exceed options.Ts = 0.0001"),
        ({"dt_out": 0.0125, "Ts": 0.01}, "options.dt_out = 0.0125 is not a multiple"),
        ({"dphi0_rel": -1.0}, "options.dphi0_rel must be > -1, got -1.0"),
        ({"t_on": 11.0}, r"options.t_on = 11.0 must lie in \[0, tau_end - 2 window\] = \[0, 10"),
        ({"latch": "twist"}, "options.latch must be one of"),
        ({"tie": -0.1}, "options.tie must be >= 0"),
        ({"Ts": 0.007, "h": 1e-3, "dt_out": 0.007}, "tau_end = 20.0 is not a multiple"),
        ({"top_drive": "tds-12"}, "options.top_drive = 'tds-12': top drive 'tds-12'"),
        ({"top_drive": "-3R0"}, "options.top_drive = '-3r0'"),
        ({"gains_constrained": None}, "options.controllers has lmi-constrained, lmi-telemetry: "),
        ({"impedance": "wave"}, "options.impedance must be one of 'lumped', 'pipe', got 'wave'"),
        ({"soft_speed": "stiff"}, "options.soft_speed must be one of 'two-mass', 'impedance'"),
        ({"z_matching": -0.5}, "options.z_matching must be >= 0, got -0.5"),
        ({"min_periods": -1}, "options.min_periods must be >= 0, got -1"),
    ],
)
def test_controller_spec_errors(paper_gains, constrained_gains, options, message):
    with pytest.raises(SweepSpecError, match=message):
        _spec(paper_gains, constrained_gains, **options)


def test_the_constrained_gains_file_must_hold_a_constrained_design(paper_gains, tmp_path):
    with pytest.raises(SweepSpecError, match="holds no input-constrained design"):
        _spec(paper_gains, paper_gains)
    # a scaled base of no known rig takes a drive in multiples of R0, not a rating
    base = {"kind": "scaled", **REFERENCE.replace(psi=300.0).to_dict()}
    sweep = [{"param": "omega0", "start": 4.0, "stop": 6.0, "num": 2}]
    data = {"study": "controllers", "base": base, "tau_end": 20.0, "sweep": sweep}
    options = {
        "gains": str(paper_gains[1]),
        "controllers": ["soft-speed"],
        "window": 5.0,
        "min_periods": 0.0,
    }
    with pytest.raises(SweepSpecError, match="a scaled set of no known rig"):
        spec_from_dict({**data, "options": options})
    spec = spec_from_dict({**data, "options": {**options, "top_drive": "50R0"}})
    assert spec.point_scales(0) is None


def test_a_subset_of_controllers_leaves_the_others_empty(
    paper_gains, constrained_gains, serial_map, tmp_path
):
    spec = _spec(paper_gains, constrained_gains, controllers=["soft-speed", "stiff-pi"])
    assert spec.options.controllers == ("stiff-pi", "soft-speed")
    report = run_sweep(spec, tmp_path, serial=True, progress=False, plots=False)
    full = _rows(serial_map[1].results)
    for row, ref in zip(_rows(report.results), full, strict=True):
        for c in ("stiff-pi", "soft-speed"):
            assert row[f"utr.{c}"] == ref[f"utr.{c}"]  # the same runs as with every controller
        assert row["utr.lmi"] == row["outcome.z-torque"] == row["lmi_gain_norm"] == ""
        assert row["lmi_constrained_gain_norm"] == ""
        assert row["best"] in ("stiff-pi", "soft-speed")
    with pytest.raises(SweepSpecError, match="lists a controller twice"):
        _spec(paper_gains, constrained_gains, controllers=["lmi", "lmi"])
    with pytest.raises(SweepSpecError, match=r"options.controllers\[0\] must be one of"):
        _spec(paper_gains, constrained_gains, controllers=["pid"])


# --------------------------------------------------------------------------------------------
# drillstring controllers compare / map (drillstring.apps.controllers)
# --------------------------------------------------------------------------------------------

SHORT_FIG6 = Experiment(
    "fig6-short", dphi0=-4.9, tau_end=8.0, t_on=6.0, latch="angle", torsional_stick=True
)


@pytest.fixture(scope="module")
def designed_constrained(paper_gains, tmp_path_factory):
    """The input-constrained design for the reference rig's top drive (a short alpha grid)."""
    g = paper_gains[0]
    m = averaged_model(REFERENCE, g.A, g.taubar_crit)
    drive = top_drive(TDS_11SA, REFERENCE_RIG)
    c = design_constrained(REFERENCE, m, drive, alphas=(0.4, 0.63, 1.0), label="tds-11sa")
    return write_gains(c.gains, tmp_path_factory.mktemp("gains") / "constrained.json")


def test_comparison_starts_every_controller_from_the_same_state(
    paper_gains, designed_constrained, tmp_path
):
    result = write_controller_comparison(
        tmp_path, paper_gains[0], designed_constrained, experiment=SHORT_FIG6, tau_end=8.0,
        options=ControllerOptions(window=1.0, min_periods=0.0), log=None,
    )  # fmt: skip
    names = [r["controller"] for r in result.rows]
    # the timing of a real drive: the rows of TIMED_CONTROLLERS after the rig's controllers
    assert names == ["open-loop", *RIG_CONTROLLERS, *TIMED_CONTROLLERS, "lmi-unlimited"]
    for name, (of, period) in TIMED_CONTROLLERS.items():
        timing = result.laws[name]["timing_s"]
        assert timing == pytest.approx({"period": period, "latency": period}, rel=1e-12)
        assert result.laws[name]["scaled"] == result.laws[of]["scaled"]
    with open(result.files["table"], newline="") as fh:
        table = list(csv.DictReader(fh))
    assert [r["controller"] for r in table] == names and list(table[0]) == list(COMPARISON_COLUMNS)
    assert result.files["figure"].stat().st_size > 10_000
    # until the switch-on every run is the open loop (the same held R_ff), to the event
    # location's rounding (see test_laws: the held torque equals the monolithic run)
    ol = result.runs["open-loop"]
    before = ol.tau < 6.0
    for name in RIG_CONTROLLERS:
        r = result.runs[name]
        np.testing.assert_allclose(r.tau[before], ol.tau[before], atol=1e-12)
        np.testing.assert_allclose(r.dphi[before], ol.dphi[before], atol=1e-8)
    # the reference rig is found for the reference set: torques in kN m are C R0 times
    rows = {r["controller"]: r for r in result.rows}
    rig = get_physical("reference-rig")
    kNm = rows["z-torque"]["peak_torque_over_R0"] * REFERENCE.R0 * rig.C / 1e3
    assert rows["z-torque"]["peak_torque_kNm"] == pytest.approx(kNm, rel=1e-12)
    assert result.laws["soft-speed"]["si"]["kp"] == pytest.approx(
        result.laws["soft-speed"]["scaled"]["kp"] * rig.C * math.sqrt(200.0 / 235.0), rel=1e-12
    )
    # every controller under the drive stays within its rating (50.8 kN m); the paper's set-up
    # without a drive asks for about 1200 R0
    rating = TDS_11SA.torque / 1e3
    for name in RIG_CONTROLLERS:
        if math.isfinite(rows[name]["peak_torque_kNm"]):
            assert rows[name]["peak_torque_kNm"] <= rating * (1 + 1e-12), name
    assert rows["lmi-unlimited"]["peak_torque_over_R0"] > 500.0
    assert rows["lmi"]["top_drive"] == "tds-11sa" and rows["lmi-unlimited"]["top_drive"] == "none"
    # the late window's torque (tau in [7, 8]), by hand from the rows: the RMS of R0 + (R - R0)
    # there, the peak at least the rows' largest (it is sample-exact) and at most the peak from
    # the switch-on on
    C = rig.C / 1e3
    checked = 0
    for name in ("open-loop", *RIG_CONTROLLERS, "lmi-unlimited"):
        r, row = result.runs[name], rows[name]
        if not r.status.ok:
            assert math.isnan(row["peak_torque_late_kNm"]) and math.isnan(
                row["rms_torque_late_kNm"]
            )
            continue
        late = r.tau >= 8.0 - 1.0 - 1e-9
        R = REFERENCE.R0 + r.R_minus_R0[late]
        assert row["rms_torque_late_kNm"] == pytest.approx(C * np.sqrt(np.mean(R**2)), rel=1e-12)
        assert C * np.max(R) <= row["peak_torque_late_kNm"] * (1 + 1e-12)
        assert row["peak_torque_late_kNm"] <= row["peak_torque_kNm"] * (1 + 1e-12)
        checked += 1
    assert checked >= 5


def test_sampled_lmi_without_a_drive_is_the_continuous_law(paper_gains, tmp_path):
    result = write_controller_comparison(
        tmp_path, paper_gains[0], experiment=SHORT_FIG6, tau_end=8.0,
        options=ControllerOptions(window=1.0, min_periods=0.0, top_drive="none"), log=None,
    )  # fmt: skip
    rows = {r["controller"]: r for r in result.rows}
    assert "lmi-constrained" not in rows  # no constrained design given
    assert rows["lmi"]["peak_torque_over_R0"] == pytest.approx(
        rows["lmi-unlimited"]["peak_torque_over_R0"], rel=1e-2
    )
    with pytest.raises(
        ValueError, match=r"options.t_on = 6.0 must lie in \[0, tau_end - 2 window\] = \[0, 4.0\]"
    ):
        options = ControllerOptions(window=2.0, min_periods=0.0)
        write_controller_comparison(
            tmp_path, paper_gains[0], experiment=SHORT_FIG6, tau_end=8.0, options=options, log=None
        )
    # the controllers are evaluated with the torsional-stick model on, as at a map's points
    no_stick = dataclasses.replace(SHORT_FIG6, torsional_stick=False)
    with pytest.raises(ValueError, match="'fig6-short' has the torsional-stick model off"):
        write_controller_comparison(tmp_path, paper_gains[0], experiment=no_stick, log=None)


@pytest.mark.slow  # an end-to-end run of several seconds: make test, not test-fast
def test_the_tuning_choices_reach_the_map_and_the_comparison(
    paper_gains, constrained_gains, tmp_path, capsys
):
    """The options impedance, soft_speed, z_matching (and --impedance, --soft-speed,
    --z-matching) select the industrial rules: with the pipe's impedance of the point's rig
    (the reference string: 296.5 N m s/rad over sqrt(235*200) = 216.8) and the field rule,
    SoftSpeed's kp is that impedance and Z-Torque's gain a quarter of its inverse."""
    Zp = 296.5 / math.sqrt(235.0 * 200.0)
    choices = {"impedance": "pipe", "soft_speed": "impedance", "z_matching": 0.25}
    spec = _spec(paper_gains, constrained_gains, **choices)
    p = spec.point_params(3)
    laws = _lineup(spec, p, spec.point_scales(3))
    assert laws["soft-speed"].law.kp == pytest.approx(Zp, abs=2e-4)
    assert laws["z-torque"].law.z_gain == pytest.approx(0.25 / Zp, rel=1e-3)
    rig = spec.point_scales(3)
    default = _lineup(_spec(paper_gains, constrained_gains), p, rig)
    assert default["soft-speed"].law.kp == pytest.approx(2.0 * math.sqrt(5.0), rel=1e-12)
    # a scaled base of no known rig has no pipe
    base = {"kind": "scaled", **REFERENCE.replace(psi=300.0).to_dict()}
    data = {"study": "controllers", "base": base, "tau_end": 20.0,
            "sweep": [{"param": "omega0", "start": 4.0, "stop": 6.0, "num": 2}]}  # fmt: skip
    options = {"gains": str(paper_gains[1]), "controllers": ["soft-speed"], "window": 5.0,
               "min_periods": 0.0, "top_drive": "50R0"}  # fmt: skip
    assert spec_from_dict({**data, "options": options}).options.tuning.impedance == "lumped"
    with pytest.raises(SweepSpecError, match="options.impedance = 'pipe' needs the rig's drill"):
        spec_from_dict({**data, "options": {**options, "impedance": "pipe"}})
    # nor a point whose string (C) is of no known rig
    other = {"study": "controllers", "base": RIG, "tau_end": 20.0,
             "sweep": [{"param": "C", "start": 235.0, "stop": 470.0, "num": 2}]}  # fmt: skip
    options = {**options, "top_drive": "tds-11sa", "impedance": "pipe"}
    with pytest.raises(SweepSpecError, match=r"point 1 \(C = 470.0\) is invalid: options.imp"):
        spec_from_dict({**other, "options": options})
    # the command line: compare (a short run: the switch-on at 25, windows of 1) and map
    args = ["--gains", str(paper_gains[1]), "--window", "1", "--min-periods", "0",
            "--impedance", "pipe", "--soft-speed", "impedance", "--z-matching", "0.25"]  # fmt: skip
    out = tmp_path / "compare"
    assert controllers_main(["compare", *args, "--tau-end", "27", "--out", str(out)]) == 0
    summary = json.loads((out / "comparison.json").read_text())
    assert summary["tuning"] == {**choices, "pipe": None}
    assert summary["laws"]["soft-speed"]["scaled"]["kp"] == pytest.approx(Zp, abs=2e-4)
    assert summary["laws"]["soft-speed"]["si"]["kp"] == pytest.approx(296.5, abs=0.05)
    assert summary["laws"]["z-torque"]["scaled"]["z_gain"] == pytest.approx(0.25 / Zp, 1e-3)
    capsys.readouterr()
    bad = ["compare", *args, "--z-matching", "-1", "--out", str(out)]
    assert controllers_main(bad) == 2
    assert "Tuning.z_matching must be >= 0, got -1.0" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        controllers_main(["map", *args, "--impedance", "wave", "--out", str(out)])
    assert exc.value.code == 2 and "invalid choice: 'wave'" in capsys.readouterr().err
    # the map's command line with these choices: test_cli_compare_and_map


@pytest.mark.slow  # an end-to-end run of several seconds: make test, not test-fast
def test_cli_compare_and_map(paper_gains, constrained_gains, tmp_path, capsys):
    assert (
        controllers_main(
            ["compare", "--gains", str(tmp_path / "none.json"), "--out", str(tmp_path)]
        )
        == 2
    )
    assert "cannot read gains file" in capsys.readouterr().err
    base = [
        "map",
        "--gains",
        str(paper_gains[1]),
        "--gains-constrained",
        str(constrained_gains[1]),
        "--n",
        "2",
        "--tau-end",
        "2",
        "--window",
        "1",
        "--min-periods",
        "0",
        "--workers",
        "0",
        "--no-progress",
        "--elements",  # the one-mode model (the default is the 16-element string)
        "1",
        *("--impedance", "pipe", "--soft-speed", "impedance", "--z-matching", "0.25"),
    ]
    assert controllers_main([*base, "--out", str(tmp_path / "bad"), "--wob", "15", "20"]) == 2
    assert "W0 = 15000.0 N is not above the wearflat contact part" in capsys.readouterr().err
    out = tmp_path / "map"
    assert controllers_main([*base, "--out", str(out)]) == 0
    with open(out / "by_controller.csv", newline="") as fh:
        counts = list(csv.DictReader(fh))
    assert [r["controller"] for r in counts] == list(MAP_CONTROLLERS)
    assert sum(int(r["best"]) for r in counts) == 4  # one best per point
    for r in counts:
        kinds = ("steady", "settling", "vibration", "stick-slip", "stall", "no_design", "stopped")
        assert sum(int(r[o]) for o in kinds) == 4
    assert (out / "plots" / "best.png").exists()
    spec = json.loads((out / "spec.json").read_text())
    assert [a["param"] for a in spec["sweep"]] == ["rpm", "W0_kN"]
    assert spec["sweep"][1]["start"] == pytest.approx(wob_range(REFERENCE_RIG)[0])
    assert spec["feed"] == FEED_FOR_WOB
    # the tuning options reach the map's spec
    choices = {"impedance": "pipe", "soft_speed": "impedance", "z_matching": 0.25}
    assert {k: spec["options"][k] for k in choices} == choices


def test_the_sensing_labels_say_what_each_controller_measures(paper_gains, constrained_gains):
    """The labels of the tables and map notes (SENSING) agree with the Sensing of each
    controller of the rig lineup: exact downhole only where the law gets the bit's angle and
    speed exactly, the mud-pulse period and latency those of its telemetry in seconds."""
    rig = REFERENCE_RIG
    d = axial_design(REFERENCE)
    model = averaged_model(REFERENCE, d.A, d.taubar_crit)
    controllers = rig_lineup(
        REFERENCE, model,
        paper=lmi_gain(model, paper_gains[0]), constrained=lmi_gain(model, constrained_gains[0]),
        top_drive=top_drive(TDS_11SA, rig), scales=rig, Ts=1e-3,
    )  # fmt: skip
    assert set(SENSING) == set(RIG_CONTROLLERS) | set(TIMED_CONTROLLERS)
    assert set(RIG_CONTROLLERS) == set(controllers)
    for name, c in controllers.items():
        s, label = c.sensing, SENSING[name]
        assert (label == "exact downhole") == (s.downhole == "ideal" and name.startswith("lmi"))
        if s.downhole == "telemetry":
            period, latency = s.period * rig.t_star, s.latency * rig.t_star
            assert label == f"mud pulse {period:.3g} s, {latency:.3g} s late", label
            # noisy frames: 2 degrees on the angle, 1 rpm on the speed, a fixed seed
            si = s.to_si(rig)
            assert si["noise_phi"] == pytest.approx(2.0 * math.pi / 180.0, rel=1e-12)
            assert si["noise_dphi"] == pytest.approx(2.0 * math.pi / 60.0, rel=1e-12)
            assert s.seed == 1
        assert (label == "observer (surface)") == (s.downhole == "observer")
        # the torque from the motor where a law uses the string torque (Z-Torque, the observer)
        assert ("motor" in label) == (name == "z-torque")
    note = sensing_note(["stiff-pi", "lmi", "soft-speed"])
    assert note == "sensing: stiff-pi, soft-speed: table speed; lmi: exact downhole"
