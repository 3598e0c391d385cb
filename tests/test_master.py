"""Tests of the FMI 2.0 co-simulation master on small pythonfmu FMUs (tests/fmus/).

Reference answers are independent of the master: hand-written discrete recurrences for
the bookkeeping of Jacobi/Gauss-Seidel, the closed-form solution of a linear two-mass
oscillator (matrix exponential) for the coupling error and its convergence order.
"""

from __future__ import annotations

import csv
import math
import re

import fmu_testlib as tl
import numpy as np
import pytest

from drillstring.orchestration import step_control as sc
from drillstring.orchestration.master import Connection, Master, StepControl, Unit

pytestmark = pytest.mark.fmu


# -- two integrators in a loop: a' = k_a * b, b' = k_b * a (fmu_testlib.integrator_loop) ------


@pytest.fixture(scope="module")
def loop(small_fmus):
    with tl.integrator_loop(small_fmus) as m:
        yield m


def recurrence(scheme: str, extrapolation: str, steps, ka=1.0, kb=-1.0, a0=1.0, b0=0.0):
    """The co-simulation of the integrator loop written out by hand.

    Each integrator is exact for the held input: x_{n+1} = x_n + k h u_held. Jacobi holds
    u at the exchanged value (zoh) or at the mean of the line through the last two
    exchanged values over the step (linear); Gauss-Seidel (A first) gives B the fresh
    a_{n+1} (zoh) or the mean of a_n and a_{n+1} (linear). First step: no history, hold.
    """
    a, b = [a0], [b0]
    h_prev = None
    for h in steps:
        if extrapolation == "linear" and h_prev is not None:
            b_held = b[-1] + (b[-1] - b[-2]) * 0.5 * h / h_prev
            a_held = a[-1] + (a[-1] - a[-2]) * 0.5 * h / h_prev
        else:
            b_held, a_held = b[-1], a[-1]
        a_new = a[-1] + ka * h * b_held
        if scheme == "gauss-seidel":
            a_held = a_new if extrapolation == "zoh" else 0.5 * (a[-1] + a_new)
        b_new = b[-1] + kb * h * a_held
        a.append(a_new)
        b.append(b_new)
        h_prev = h
    return np.array(a), np.array(b)


@pytest.mark.parametrize("scheme", ["jacobi", "gauss-seidel"])
@pytest.mark.parametrize("extrapolation", ["zoh", "linear"])
def test_bookkeeping_matches_hand_written_recurrence(loop, scheme, extrapolation):
    h, n = 0.1, 30
    res = loop.run(n * h, h, scheme=scheme, extrapolation=extrapolation, progress=False)
    assert res.completed and res.stats.accepted == n
    a, b = recurrence(scheme, extrapolation, [h] * n)
    np.testing.assert_allclose(res.time, h * np.arange(n + 1), rtol=0, atol=1e-14)
    np.testing.assert_allclose(res["A.x"], a, rtol=0, atol=1e-14)
    np.testing.assert_allclose(res["B.x"], b, rtol=0, atol=1e-14)
    # connected inputs carry the exchanged value of their source
    np.testing.assert_array_equal(res["A.u"], res["B.x"])
    np.testing.assert_array_equal(res["B.u"], res["A.x"])


def test_jacobi_and_gauss_seidel_invariants(loop):
    """Jacobi/ZOH on a' = b, b' = -a is explicit Euler: |z_n|^2 = (1 + h^2)^n exactly;
    Gauss-Seidel/ZOH is symplectic Euler: a^2 + b^2 + h a b is conserved exactly."""
    h, n = 0.05, 200
    jac = loop.run(n * h, h, progress=False)
    r2 = jac["A.x"] ** 2 + jac["B.x"] ** 2
    np.testing.assert_allclose(r2, (1 + h * h) ** np.arange(n + 1), rtol=1e-13)
    gs = loop.run(n * h, h, scheme="gauss-seidel", progress=False)
    a, b = gs["A.x"], gs["B.x"]
    np.testing.assert_allclose(a * a + b * b + h * a * b, 1.0, rtol=0, atol=1e-13)
    # and the two schemes really differ
    assert np.max(np.abs(jac["A.x"] - gs["A.x"])) > 0.1


def test_explicit_gauss_seidel_order(small_fmus):
    """gs_order=["B", "A"]: B steps first with a_n held, A gets the fresh b_{n+1}."""
    h, n = 0.1, 20
    with tl.integrator_loop(small_fmus, gs_order=["B", "A"]) as m:
        res = m.run(n * h, h, scheme="gauss-seidel", progress=False)
    b_ref, a_ref = recurrence("gauss-seidel", "zoh", [h] * n, ka=-1.0, kb=1.0, a0=0.0, b0=1.0)
    np.testing.assert_allclose(res["A.x"], a_ref, rtol=0, atol=1e-14)
    np.testing.assert_allclose(res["B.x"], b_ref, rtol=0, atol=1e-14)


def test_last_step_shortened_to_land_on_stop_time(loop):
    res = loop.run(1.05, 0.1, progress=False)
    steps = [0.1] * 10 + [1.05 - 1.0]
    assert res.time[-1] == 1.05 and len(res.time) == 12
    a, b = recurrence("jacobi", "zoh", steps)
    np.testing.assert_allclose(res["A.x"], a, rtol=0, atol=1e-14)
    np.testing.assert_allclose(res["B.x"], b, rtol=0, atol=1e-14)
    # the loop is time invariant: starting at t = 1 only shifts the time axis
    shifted = loop.run(2.05, 0.1, start_time=1.0, progress=False)
    np.testing.assert_allclose(shifted.time, 1.0 + res.time, rtol=0, atol=1e-14)
    np.testing.assert_allclose(shifted["A.x"], a, rtol=0, atol=1e-14)


def test_units_as_mapping(small_fmus):
    units = {
        "A": (small_fmus["integrator"], {"x0": 1.0}),
        "B": (small_fmus["integrator"], {"k": -1.0}),
    }
    with Master(units, [("A.x", "B.u"), ("B.x", "A.u")]) as m:
        res = m.run(1.0, 0.1, progress=False)
    a, b = recurrence("jacobi", "zoh", [0.1] * 10)
    np.testing.assert_allclose(res["A.x"], a, rtol=0, atol=1e-14)
    with pytest.raises(ValueError, match="listed under the name 'B'"):
        Master({"B": Unit("A", small_fmus["integrator"])}, [])


# -- initialization ----------------------------------------------------------------


def test_initialization_propagates_through_feedthrough_chain(small_fmus):
    """I.x -> G1 (y = -u + 0.5) -> G2 (y = 3u) -> I.u, listed against dependency order.

    At t = 0: x = 2, G1.y = -1.5, G2.y = I.u = -4.5, so the first step gives
    x = 2 - 0.45 = 1.55. With I.u left at its default 0 it would stay 2; one pass in
    listing order would give G2.y = 0 * 3 as well."""
    units = [
        Unit("G2", small_fmus["gain"], {"k": 3.0}),
        Unit("G1", small_fmus["gain"], {"k": -1.0, "b": 0.5}),
        Unit("I", small_fmus["integrator"], {"x0": 2.0}),
    ]
    conns = ["G2.y -> I.u", "G1.y -> G2.u", "I.x -> G1.u"]
    with Master(units, conns) as m:
        res = m.run(0.2, 0.1, progress=False)
    assert res["G1.y"][0] == -1.5
    assert res["G2.y"][0] == -4.5
    assert res["I.u"][0] == -4.5
    assert res["I.x"][1] == pytest.approx(1.55, abs=1e-15)
    # second step: x = 1.55, G2.y = 3 (0.5 - 1.55) = -3.15
    assert res["G2.y"][1] == pytest.approx(-3.15, abs=1e-14)
    assert res["I.x"][2] == pytest.approx(1.55 - 0.315, abs=1e-14)


# -- two-mass oscillator: coupling error against the closed form -----------------------

OSC = dict(m1=1.0, k1=10.0, m2=1.0, k2=30.0, kc=5.0, dc=2.0, x10=1.0, v10=0.0)


def oscillator_master(small_fmus, p=OSC) -> Master:
    units = [
        Unit(
            "M1",
            small_fmus["oscillator"],
            {"m": p["m1"], "k": p["k1"], "x0": p["x10"], "v0": p["v10"]},
        ),
        Unit(
            "M2",
            small_fmus["oscillator"],
            {"m": p["m2"], "k": p["k2"], "kc": p["kc"], "dc": p["dc"]},
        ),
    ]
    conns = ["M1.x -> M2.x_in", "M1.v -> M2.v_in", "M2.F_c -> M1.F_ext"]
    return Master(units, conns, record=["M2.x", "M2.v"])


def oscillator_exact(t: np.ndarray, p=OSC) -> np.ndarray:
    """z = (x1, v1, x2, v2) of the monolithic linear ODE, by eigen-decomposition."""
    m1, k1, m2, k2, kc, dc = (p[k] for k in ("m1", "k1", "m2", "k2", "kc", "dc"))
    a = np.array(
        [
            [0, 1, 0, 0],
            [-(k1 + kc) / m1, -dc / m1, kc / m1, dc / m1],
            [0, 0, 0, 1],
            [kc / m2, dc / m2, -(k2 + kc) / m2, -dc / m2],
        ]
    )
    lam, v = np.linalg.eig(a)
    c = np.linalg.solve(v, np.array([p["x10"], p["v10"], 0.0, 0.0]))
    return np.real((v[None, :, :] * (np.exp(np.outer(t, lam)) * c)[:, None, :]).sum(axis=2))


def coupling_error(res) -> float:
    z = oscillator_exact(res.time)
    return max(np.max(np.abs(res["M1.x"] - z[:, 0])), np.max(np.abs(res["M2.x"] - z[:, 2])))


@pytest.fixture(scope="module")
def osc(small_fmus):
    with oscillator_master(small_fmus) as m:
        yield m


def test_exact_solution_is_consistent():
    """The closed form used as reference solves the ODE (checked by finite differences)."""
    t = np.linspace(0, 2, 2001)
    z = oscillator_exact(t)
    p = OSC
    acc1 = np.gradient(z[:, 1], t)
    f1 = -p["k1"] * z[:, 0] + p["kc"] * (z[:, 2] - z[:, 0]) + p["dc"] * (z[:, 3] - z[:, 1])
    assert np.max(np.abs(acc1[1:-1] - f1[1:-1] / p["m1"])) < 1e-3
    np.testing.assert_allclose(np.gradient(z[:, 0], t)[1:-1], z[1:-1, 1], atol=1e-4)


@pytest.mark.parametrize(
    "scheme, extrapolation, lo, hi",
    [
        ("jacobi", "zoh", 0.9, 1.1),
        ("gauss-seidel", "zoh", 0.9, 1.1),
        ("jacobi", "linear", 1.85, 2.15),
        ("gauss-seidel", "linear", 1.85, 2.15),
    ],
)
def test_convergence_order_of_coupling_error(osc, scheme, extrapolation, lo, hi):
    hs = np.array([0.02, 0.01, 0.005, 0.0025])
    errs = np.array(
        [
            coupling_error(
                osc.run(4.0, h, scheme=scheme, extrapolation=extrapolation, progress=False)
            )
            for h in hs
        ]
    )
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    print(f"{scheme}/{extrapolation}: errors {errs}, fitted order {order:.3f}")
    assert lo < order < hi
    assert np.all(np.diff(errs) < 0)


def test_adaptive_needs_fewer_steps_than_fixed_for_same_error(osc):
    """Decaying transient: the adaptive master takes large steps once it has decayed.

    The fixed-step master is run on a refining grid until it is at least as accurate;
    the adaptive run must have computed fewer macro steps (rejected ones included)."""
    t_end = 20.0
    control = StepControl(rtol=0.0, atol=1e-4, h_min=1e-5, h_max=0.5, h_init=0.01)
    ad = osc.run(t_end, step_control=control, progress=False)
    err_ad = coupling_error(ad)
    n_ad = ad.stats.attempted
    assert ad.completed and ad.stats.rejected > 0 and ad.stats.forced == 0
    assert control.h_min <= ad.stats.h_min and ad.stats.h_max <= control.h_max
    assert ad.stats.h_max > 20 * ad.stats.h_min  # the step really adapts
    log = ad.step_log
    assert log["accepted"].sum() == ad.stats.accepted and (~log["accepted"]).sum() == n_ad - (
        ad.stats.accepted
    )
    np.testing.assert_allclose(np.diff(ad.time), log["h"][log["accepted"]], rtol=1e-12)
    n_fixed, err_fixed = None, None
    for n in (int(n_ad * f) for f in (1.0, 1.4, 2.0, 2.8, 4.0, 5.6, 8.0)):
        err = coupling_error(osc.run(t_end, t_end / n, progress=False))
        if err <= err_ad:
            n_fixed, err_fixed = n, err
            break
    print(f"adaptive: {n_ad} steps ({ad.stats.rejected} rejected), max error {err_ad:.3e}")
    print(f"fixed: {n_fixed} steps for max error {err_fixed}")
    assert n_fixed is not None and n_fixed > n_ad


def test_step_control_rules_by_hand():
    """The control's pure rules against values worked out by hand."""
    c = StepControl(rtol=0.0, atol=0.01, h_min=0.05, h_max=0.5, safety=0.9)
    assert sc.step_to_take(0.3, 0.0, 1.0, c.h_min) == 0.3
    assert sc.step_to_take(0.3, 0.75, 1.0, c.h_min) == 0.25  # lands on the stop time
    assert sc.step_to_take(0.23, 0.75, 1.0, c.h_min) == 0.125  # no sliver of 0.02 < h_min
    y_n, y = np.array([1.0, -2.0]), np.array([1.1, -2.0])
    # hold: impulse 1/2 h |defect| = 0.5 * 0.2 * 0.1 against atol 0.01
    assert sc.coupling_error(y, y_n, None, 0.2, 0.1, c) == (pytest.approx(1.0), 0)
    # the line through (t - 0.1, 0.9) and (t, 1.0) predicts 1.2 at t + 0.2: defect 0.1
    err, p = sc.coupling_error(y, y_n, np.array([0.9, -2.0]), 0.2, 0.1, c)
    assert (err, p) == (pytest.approx(5.0 / 12.0 * 0.2 * 0.1 / 0.01), 1)
    assert sc.accepts(1.0, 0.2, c) and not sc.accepts(1.01, 0.2, c) and sc.accepts(50.0, 0.05, c)
    assert sc.retry_step(0.5, 100.0, 0, c) == pytest.approx(0.5 * 0.2)  # shrink_min bounds it
    assert sc.retry_step(0.2, 100.0, 0, c) == 0.05  # and h_min
    assert sc.retry_step(0.2, 4.0, 0, c) == pytest.approx(0.2 * 0.9 / 2.0)
    assert sc.next_step(0.2, 0.0, 0, False, c) == pytest.approx(0.4)  # grow_max
    assert sc.next_step(0.4, 0.0, 0, False, c) == 0.5  # h_max
    assert sc.next_step(0.2, 1.0 / 8.0, 1, False, c) == pytest.approx(0.2 * 0.9 * 2.0)  # 8^(1/3)
    assert sc.next_step(0.2, 1.0 / 8.0, 1, True, c) == 0.2  # no growth after a rejection
    assert math.isinf(sc.coupling_error(np.array([math.nan]), y_n[:1], None, 0.2, 0.1, c)[0])


def test_adaptive_converges_with_tolerance(osc):
    """Rollback must restore the units exactly: error follows the tolerance down."""
    errs = []
    for atol in (1e-3, 1e-5):
        control = StepControl(rtol=0.0, atol=atol, h_min=1e-6, h_max=0.2, h_init=0.05)
        res = osc.run(3.0, extrapolation="linear", step_control=control, progress=False)
        assert res.stats.rejected > 0
        errs.append(coupling_error(res))
    print(f"adaptive linear errors for atol 1e-3, 1e-5: {errs}")
    assert errs[1] < errs[0] / 10


# -- failures --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "adaptive, fault, status, text",
    [
        (False, "t_fail", "discard", "t_fail=0.35 would be passed"),
        (True, "t_fail", "discard", "t_fail=0.35 would be passed"),
        # pythonfmu answers a Python exception in do_step with fmi2Fatal
        (False, "t_raise", "fatal", "integrator blew up at t=0.3"),
    ],
)
def test_fmu_failure_stops_cleanly_with_partial_results(
    small_fmus, loop, adaptive, fault, status, text, tmp_path
):
    h = 0.1
    control = StepControl(rtol=0, atol=10.0, h_min=h, h_max=h) if adaptive else None
    with tl.integrator_loop(small_fmus, a_extra={fault: 0.35}) as m:
        res = m.run(1.0, h, step_control=control, progress=False)
        again = m.run(0.3, h, progress=False)  # the failed run released its units
    assert not res.completed
    f = res.failure
    assert (f.unit, f.function, f.status) == ("A", "fmi2DoStep", status)
    assert f.time == pytest.approx(0.3, abs=1e-12) and f.step_size == pytest.approx(h)
    assert any(text in msg for msg in f.messages)
    assert "'A'" in str(f) and text in str(f)
    assert any(u == "A" and s == status for u, s, _, _ in res.log)
    # results up to the last good communication point, equal to an undisturbed run
    np.testing.assert_allclose(res.time, [0.0, 0.1, 0.2, 0.3], atol=1e-12)
    full = loop.run(1.0, h, progress=False)
    np.testing.assert_array_equal(res["A.x"], full["A.x"][:4])
    np.testing.assert_array_equal(res["B.x"], full["B.x"][:4])
    assert res.to_csv(tmp_path / "partial.csv").read_text().count("\n") == 5
    assert again.completed and len(again.time) == 4


# -- validation ------------------------------------------------------------------------


def test_validation_errors_name_the_culprit(small_fmus):
    integ, gain = small_fmus["integrator"], small_fmus["gain"]
    two = [Unit("A", integ), Unit("B", integ)]
    cases = [
        (two, ["A.x -> C.u"], "unknown unit 'C'"),
        (two, ["A.y -> B.u"], "no variable 'y'"),
        (two, ["A.u -> B.u"], "source 'A.u' has causality 'input'"),
        (two, ["A.x -> B.x"], "target 'B.x' has causality 'output'"),
        (two, ["A.x -> B.u", "B.x -> B.u"], "input 'B.u' is connected twice"),
        (two, ["A.x B.u"], "not of the form"),
        ([Unit("A", integ, {"nope": 1.0})], [], "no variable 'nope'"),
        ([Unit("A", integ, {"x": 1.0})], [], "cannot set a start value for 'x'"),
        ([Unit("A", integ, {"k": "big"})], [], "does not fit its type Real"),
        ([Unit("A", integ), Unit("A", gain)], [], "'A' is used more than once"),
        (
            [Unit("G1", gain), Unit("G2", gain)],
            ["G1.y -> G2.u", "G2.y -> G1.u"],
            "algebraic loop",
        ),
    ]
    for units, conns, message in cases:
        with pytest.raises(ValueError, match=message):
            Master(units, conns)
    with pytest.raises(ValueError, match="does not exist"):
        Unit("A", "/nonexistent/x.fmu")
    with pytest.raises(ValueError, match="without '.'"):
        Unit("A.b", integ)
    with pytest.raises(ValueError, match="Gauss-Seidel order"):
        Master(two, ["A.x -> B.u"], gs_order=["A"])
    with pytest.raises(ValueError, match="no variable 'zz'"):
        Master(two, ["A.x -> B.u"], record=["B.zz"])


def test_run_argument_errors(loop):
    for kwargs, message in [
        (dict(step=0.0), "step must be > 0, got 0.0"),
        (dict(step=math.nan), "step must be finite, got nan"),
        (dict(step=None), "fixed-step run needs a step"),
        (dict(step=0.1, scheme="gs"), "scheme"),
        (dict(step=0.1, extrapolation="cubic"), "extrapolation"),
        (dict(step=5.0, step_control=StepControl(h_min=0.1, h_max=1.0)), "outside"),
    ]:
        with pytest.raises(ValueError, match=message):
            loop.run(1.0, **kwargs)
    with pytest.raises(ValueError, match="stop_time must be > 0, got 0.0"):
        loop.run(0.0, 0.1)
    with pytest.raises(ValueError, match="h_min"):
        StepControl(h_min=0.2, h_max=0.1)


# -- results -------------------------------------------------------------------------


def test_csv_follows_cross_check_conventions(loop, tmp_path):
    res = loop.run(0.5, 0.1, progress=False)
    path = res.to_csv(tmp_path / "out.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == '"time","A.x","B.x","B.u","A.u"'
    with path.open() as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["time", "A.x", "B.x", "B.u", "A.u"]
    values = np.array(rows[1:], dtype=float)
    for j, name in enumerate(res.data.dtype.names):
        np.testing.assert_array_equal(values[:, j], res[name])  # round-trip precision
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]  # no temp file left
    res.to_csv(path)  # overwriting works


def test_recorded_extra_variables_and_progress_bar(small_fmus, capsys):
    with tl.integrator_loop(small_fmus, record=["A.k", "B.k", "A.x"]) as m:
        assert m.columns == ("time", "A.x", "B.x", "B.u", "A.u", "A.k", "B.k")
        res = m.run(0.3, 0.1, progress=True)
    np.testing.assert_array_equal(res["A.k"], 1.0)
    np.testing.assert_array_equal(res["B.k"], -1.0)
    assert "co-simulation" in capsys.readouterr().err


# -- units on connections -------------------------------------------------------------------

KNM = {"kN.m": 'kg="1" m="2" s="-2" factor="1000"', "N.m": 'kg="1" m="2" s="-2"'}


@pytest.mark.parametrize("scheme", ["jacobi", "gauss-seidel"])
@pytest.mark.parametrize("extrapolation", ["zoh", "linear"])
def test_connections_convert_between_units_of_one_dimension(
    small_fmus, tmp_path, scheme, extrapolation
):
    """Integrators whose state is declared in kN.m and input in N.m: every connection multiplies
    by 1000, so the loop is the hand-written recurrence with both gains times 1000 (the fixed-step
    Jacobi run is the Python loop: the C loop does not convert), and the recorded inputs are in
    N.m."""
    declared = {"x": "kN.m", "u": "N.m"}
    knm = tl.fmu_with_units(small_fmus["integrator"], tmp_path / "knm.fmu", declared, KNM)
    units = [Unit("A", knm, {"x0": 1.0, "k": 1e-3}), Unit("B", knm, {"x0": 0.0, "k": -1e-3})]
    with Master(units, ["A.x -> B.u", "B.x -> A.u"]) as m:
        conv = {
            k: (c.source, c.target, c.factor, c.offset) for k, c in m.system.conversions.items()
        }
        res = m.run(2.0, 0.1, scheme=scheme, extrapolation=extrapolation, progress=False)
    assert conv == dict.fromkeys(("B.u", "A.u"), ("kN.m", "N.m", 1000.0, 0.0))
    a, b = recurrence(scheme, extrapolation, [0.1] * 20, ka=1.0, kb=-1.0)
    assert np.allclose(res["A.x"], a, rtol=1e-13, atol=1e-15)
    assert np.allclose(res["B.x"], b, rtol=1e-13, atol=1e-15)
    assert np.array_equal(res["B.u"], res["A.x"] * 1000.0)
    assert np.ptp(res["B.x"]) > 0.5
    # without conversion (convert_units=False) the values pass as they are: gains 1e-3
    plain_links = [
        Connection(a, b, convert_units=False) for a, b in (("A.x", "B.u"), ("B.x", "A.u"))
    ]
    with Master(units, plain_links) as m:
        plain = m.run(2.0, 0.1, scheme=scheme, extrapolation=extrapolation, progress=False)
    a, b = recurrence(scheme, extrapolation, [0.1] * 20, ka=1e-3, kb=-1e-3)
    assert np.allclose(plain["B.x"], b, rtol=1e-13, atol=1e-15)


def test_connections_of_different_dimensions_are_refused(small_fmus, tmp_path):
    defs = {"rad/s": 's="-1" rad="1"', "N.m": KNM["N.m"]}
    bad = tl.fmu_with_units(
        small_fmus["integrator"], tmp_path / "bad.fmu", {"x": "rad/s", "u": "N.m"}, defs
    )
    with pytest.raises(
        ValueError,
        match=re.escape(
            "connection 'A.x -> B.u': the source's unit 'rad/s' (dimension s-1.rad) and the "
            "target's unit 'N.m' (dimension kg.m2.s-2) are of different dimensions: not "
            "convertible"
        ),
    ):
        Master([Unit("A", bad), Unit("B", bad)], ["A.x -> B.u", "B.x -> A.u"])  # fmt: skip
    # an end without a unit: refused, naming both ends; passed unchanged only on purpose
    plain = small_fmus["integrator"]
    refused = (
        f"connection 'A.x -> B.u': 'A.x' of bad.fmu is in 'rad/s' (dimension s-1.rad), 'B.u' "
        f"of {plain.name} declares no unit, so its values cannot be checked or converted"
    )
    with pytest.raises(ValueError, match=re.escape(refused)):
        Master([Unit("A", bad), Unit("B", plain)], ["A.x -> B.u"])
    with Master([Unit("A", bad), Unit("B", plain)], [Connection("A.x", "B.u", False)]) as m:
        assert m.system.conversions == {}
    # a dimensionless "1" (the scaled FMUs' unit) and no unit are the same plain number
    one = tl.fmu_with_units(plain, tmp_path / "one.fmu", {"x": "1"}, {"1": ""})
    with Master([Unit("A", one), Unit("B", plain)], ["A.x -> B.u"]) as m:
        assert m.system.conversions == {}
    # a unit of one name defined otherwise by the other FMU: converted by the definitions
    kilo = tl.fmu_with_units(plain, tmp_path / "kilo.fmu", {"x": "N.m", "u": "N.m"},
                             {"N.m": KNM["kN.m"]})  # fmt: skip
    newton = tl.fmu_with_units(plain, tmp_path / "newton.fmu", {"x": "N.m", "u": "N.m"},
                               {"N.m": KNM["N.m"]})  # fmt: skip
    with Master([Unit("A", kilo), Unit("B", newton)], ["A.x -> B.u", "B.x -> A.u"]) as m:
        conv = {k: (c.factor, c.offset) for k, c in m.system.conversions.items()}
    assert conv == {"B.u": (1000.0, 0.0), "A.u": (0.001, 0.0)}
