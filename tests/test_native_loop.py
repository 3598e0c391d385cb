"""The master's native loop (``orchestration/native_loop.c``) against its Python loop.

The reference is the Python loop of ``run_fixed`` (``DRILLSTRING_MASTER_NATIVE=0``) on the same
master: every recorded row, the step statistics, the failure report and the units' log must be
the same, bit for bit, on

* the closed loops of Figs. 5 and 6 (scaled and SI; zero-order hold and linear extrapolation)
  and the top-drive controller's package;
* every grid option, with both exchanges, a stop time on and off the grid;
* stops mid-run: a validity stop of the plant (fmi2Discard), a unit's fmi2Discard and fmi2Fatal
  in fmi2DoStep after several chunks, an fmi2Error of fmi2GetReal in the exchange and in the
  recorded variables;

and each run is checked to have gone through the loop it claims (a spy on ``run_native``). The
fallbacks (Gauss-Seidel, step-size control, the switch off, no compiler, a
failing compilation) run the Python loop.
"""

from __future__ import annotations

import ctypes
import dataclasses

import fmu_testlib as tl
import numpy as np
import pytest
from fmpy.fmi2 import fmi2Real, fmi2ValueReference

from drillstring.model.experiments import FIG5, FIG6
from drillstring.model.params import REFERENCE_RIG
from drillstring.orchestration import fixed, instances, native_loop
from drillstring.orchestration import master as master_module
from drillstring.orchestration.closed_loop import (
    SCALED,
    SI,
    closed_loop_master,
    kept_sys_path,
)
from drillstring.orchestration.master import Master, StepControl

pytestmark = pytest.mark.fmu

TS = REFERENCE_RIG.t_star


@pytest.fixture
def spy(monkeypatch):
    """Counts the runs that went through the C loop."""
    calls = []
    real = native_loop.run_native

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(native_loop, "run_native", counted)
    return calls


def both(master: Master, monkeypatch, spy, stop: float, step: float | None, **kw):
    """The run on the native loop and on the Python loop (checked to be so)."""
    runs = {}
    for flag in ("1", "0"):
        monkeypatch.setenv(native_loop.ENV, flag)
        before = len(spy)
        with kept_sys_path():
            runs[flag] = master.run(stop, step, progress=False, **kw)
        assert len(spy) - before == (flag == "1"), f"{native_loop.ENV}={flag}"
    return runs["1"], runs["0"]


def assert_same(a, b) -> None:
    assert a.data.dtype == b.data.dtype
    for name in a.data.dtype.names:
        assert np.array_equal(a.data[name], b.data[name], equal_nan=True), name
    sa, sb = dataclasses.asdict(a.stats), dataclasses.asdict(b.stats)
    sa.pop("wall_time"), sb.pop("wall_time")
    assert sa == sb
    assert a.failure == b.failure
    assert _steady(a.log) == _steady(b.log)


def _steady(log):
    """The log without the kernel's compile-once message (the first run of a process has it)."""
    return [entry for entry in log if "numba compiled" not in entry[3]]


def test_native_loop_is_compiled_and_used():
    assert native_loop.library() is not None, "no C compiler: the native loop is not tested"


# -- the closed loops ----------------------------------------------------------------------------


@pytest.mark.parametrize("extrapolation", ["zoh", "linear"])
@pytest.mark.parametrize("experiment", [FIG5, FIG6], ids=["fig5", "fig6"])
@pytest.mark.parametrize("variant", [SCALED, SI], ids=["scaled", "si"])
def test_closed_loops_bit_identical(built, experiment, variant, extrapolation, monkeypatch, spy):
    scale = TS if variant is SI else 1.0
    H = 1e-2 * scale
    with closed_loop_master(built.out, experiment, variant=variant) as m:
        a, b = both(m, monkeypatch, spy, experiment.tau_end * scale, H, extrapolation=extrapolation)
    assert a.completed and len(a.time) == 6001
    assert_same(a, b)
    torque = a[f"controller.{variant.torque}"]
    assert np.ptp(torque) > 0.0  # a real run: the controller acts


def test_fmus_on_their_python_path(built, monkeypatch, spy):
    # the front layer hands every call to the FMUs' Python (it takes the GIL the C loop released)
    monkeypatch.setenv("DRILLSTRING_FMU_NATIVE", "0")
    with closed_loop_master(built.out, FIG6) as m:
        a, b = both(m, monkeypatch, spy, 30.0, 1e-2)
    assert a.completed and any("the native fast path is off" in e[3] for e in a.log)
    assert_same(a, b)


@pytest.mark.parametrize("system", ["scaled", "si"])
def test_topdrive_package_bit_identical(built, system, monkeypatch, spy):
    b = built if system == "scaled" else built.si
    stop = 10.0 * (TS if system == "si" else 1.0)
    with kept_sys_path(), Master.from_ssp(b.topdrive_ssp, variant="fig6-z-torque") as m:
        for kw in ({}, {"exchange": "simple", "grid": "sum"}):
            x, y = both(m, monkeypatch, spy, stop, m.ssp.step, **kw)
            assert x.completed
            assert_same(x, y)


@pytest.mark.parametrize("variant", [SCALED, SI], ids=["scaled", "si"])
@pytest.mark.parametrize(
    "overrides, cause",
    [
        ({"plant.torsional_stick_model": False}, "torsional stick"),  # tau = 5.57, step 5574
        ({"plant.du0": -40.0}, "bit bouncing"),  # in the second step
    ],
    ids=["stick", "bounce"],
)
def test_validity_stop_of_the_plant(built, variant, overrides, cause, monkeypatch, spy):
    scale = TS if variant is SI else 1.0
    if variant is SI and "plant.du0" in overrides:
        overrides = {"plant.du0": -40.0 * REFERENCE_RIG.L_star / TS}
    with closed_loop_master(built.out, FIG6, overrides=overrides, variant=variant) as m:
        a, b = both(m, monkeypatch, spy, 10.0 * scale, 1e-3 * scale)
    f = a.failure
    assert (f.unit, f.function, f.status) == ("plant", "fmi2DoStep", "discard")
    assert cause in f.messages[-1] and f.last_successful_time is not None
    if cause == "torsional stick":  # mid-run: after several chunks
        assert a.stats.accepted > 5 * native_loop.CHUNK
    assert_same(a, b)


# -- the grid options ----------------------------------------------------------------------------


@pytest.mark.parametrize("grid", ["float", "ns", "sum"])
@pytest.mark.parametrize("exchange", ["propagate", "simple"])
@pytest.mark.parametrize("extrapolation", ["zoh", "linear"])
@pytest.mark.parametrize("stop", [2.5, 2.5004], ids=["on-grid", "off-grid"])
def test_every_grid_option(small_fmus, grid, exchange, extrapolation, stop, monkeypatch, spy):
    # 2500 steps from 0.1: the sum grid drifts from k*h, several chunks, a short last step (and
    # linear extrapolation over steps of different sizes)
    kw = dict(start_time=0.1, grid=grid, exchange=exchange, extrapolation=extrapolation)
    with tl.integrator_loop(small_fmus, record=["A.k"]) as m:
        a, b = both(m, monkeypatch, spy, stop, 1e-3, **kw)
    assert a.completed and a.time[-1] == pytest.approx(stop, abs=1e-9)
    assert_same(a, b)


def _literal_grid(t0, t_end, h, ns_grid, sum_grid):
    """The points of each grid (``fixed``'s module docstring), written out step by step as the
    Python loop of run_fixed computed them before both loops took grid_points."""
    n_total, exact = fixed.n_steps(t_end - t0, h)
    h_ns, t0_ns = round(h * 1e9), round(t0 * 1e9)
    t, times, steps = t0, [t0], []
    for n in range(1, n_total + 1):
        if ns_grid and (n < n_total or exact):
            t_next = (t0_ns + n * h_ns) / 1e9
            hn = t_next - t
        elif sum_grid and (n < n_total or exact):
            t_next, hn = t + h, h
        else:
            t_next = t0 + n * h if n < n_total else t_end
            hn = h if n < n_total or exact else t_next - t
        times.append(t_next)
        steps.append(hn)
        t = t_next
    return np.array(times), np.array(steps)


@pytest.mark.parametrize("ns_grid, sum_grid", [(False, False), (True, False), (False, True)])
@pytest.mark.parametrize(
    "t0, t_end, h", [(0.0, 60.0, 1e-3), (0.1, 2.5004, 1e-3), (3.0, 3.7, 0.1), (0.0, 1e-3, 1e-3)]
)
def test_grid_points_are_the_grids_step_by_step(t0, t_end, h, ns_grid, sum_grid):
    times, steps = fixed.grid_points(t0, t_end, h, ns_grid, sum_grid)
    ref_t, ref_h = _literal_grid(t0, t_end, h, ns_grid, sum_grid)
    assert times.tobytes() == ref_t.tobytes() and steps.tobytes() == ref_h.tobytes()


# -- stops mid-run -------------------------------------------------------------------------------


@pytest.mark.parametrize("fault, status", [("t_fail", "discard"), ("t_raise", "fatal")])
def test_unit_failure_after_several_chunks(small_fmus, fault, status, monkeypatch, spy):
    with tl.integrator_loop(small_fmus, a_extra={fault: 0.3505}, record=["B.k"]) as m:
        a, b = both(m, monkeypatch, spy, 1.0, 1e-4)
    assert (a.failure.unit, a.failure.function, a.failure.status) == ("A", "fmi2DoStep", status)
    assert abs(a.stats.accepted - 3505) <= 1 and len(a.time) == a.stats.accepted + 1
    assert_same(a, b)


def _failing(monkeypatch, unit: str, function: str, vr: int, after: int) -> None:
    """Units named ``unit`` get an fmi2GetReal or fmi2SetReal (``function``) that returns
    fmi2Error from its ``after``-th call on value reference ``vr`` (the same callable on both
    loops, counting from the start of the run)."""
    proto = ctypes.CFUNCTYPE(
        ctypes.c_int,
        ctypes.c_void_p,
        ctypes.POINTER(fmi2ValueReference),
        ctypes.c_size_t,
        ctypes.POINTER(fmi2Real),
    )
    real_typed = instances._typed
    keep = []

    def typed(fmu, name, required=True):
        f = real_typed(fmu, name, required)
        if name != function or fmu.instanceName != unit:
            return f
        count = [0]

        def failing(comp, vrs, n, values):
            st = f(comp, vrs, n, values)
            if vrs[0] == vr:
                count[0] += 1
                if count[0] >= after:
                    return 3
            return st

        wrapped = proto(failing)
        keep.append(wrapped)
        return wrapped

    monkeypatch.setattr(instances, "_typed", typed)


@pytest.mark.parametrize(
    "function, var, after, extrapolation, reported, step, time",
    [
        # A.x read: twice at t0, then once per step (in the exchange)
        ("fmi2GetReal", "A.x", 1502, "zoh", "fmi2GetReal", 1500, 0.15),
        # A.k recorded: once at t0, then once per step (the row)
        ("fmi2GetReal", "A.k", 1502, "zoh", "fmi2Get (recorded variables)", 1501, 0.1501),
        # B.u set: twice at t0, in step 1 in the exchange, then extrapolated and in the exchange
        ("fmi2SetReal", "B.u", 3000, "linear", "fmi2SetReal", 1500, 0.1499),
        ("fmi2SetReal", "B.u", 3001, "linear", "fmi2SetReal", 1500, 0.15),
    ],
    ids=["exchange-get", "recorder", "extrapolated-set", "exchange-set"],
)
def test_error_outside_do_step_after_several_chunks(
    small_fmus, function, var, after, extrapolation, reported, step, time, monkeypatch, spy
):
    unit, name = var.split(".")
    with tl.integrator_loop(small_fmus, record=["A.k"]) as m:
        vr = m.system.variables["AB".index(unit)][name].vr
        _failing(monkeypatch, unit, function, vr, after)
        a, b = both(m, monkeypatch, spy, 0.3, 1e-4, extrapolation=extrapolation)
    f = a.failure
    assert (f.unit, f.function, f.status, f.step_size) == (unit, reported, "error", None)
    assert f.time == pytest.approx(time, abs=1e-12)
    # the step that failed counts when only its row is missing (the Python loop's count)
    assert a.stats.accepted == (step if reported.startswith("fmi2Get (") else step - 1)
    assert len(a.time) == step
    assert_same(a, b)


# -- progress, fallbacks, the cache --------------------------------------------------------------


def test_progress_bar_advances_between_chunks(small_fmus, monkeypatch, spy):
    updates = []

    class Bar:
        def __init__(self, **kwargs):
            self.n = 0.0

        def update(self, dn):
            self.n += dn
            updates.append(self.n)

        def close(self):
            pass

    monkeypatch.setattr(master_module, "tqdm", Bar)
    monkeypatch.setattr(native_loop, "CHUNK", 40)
    with tl.integrator_loop(small_fmus) as m:
        res = m.run(1.0, 1e-2, progress=True)
    assert len(spy) == 1 and res.completed
    np.testing.assert_allclose(updates, [0.4, 0.8, 1.0], rtol=1e-12)


@pytest.mark.parametrize(
    "kw",
    [
        {"scheme": "gauss-seidel"},
        {"scheme": "gauss-seidel", "extrapolation": "linear"},
        {"step_control": StepControl(rtol=0, atol=10.0, h_min=0.01, h_max=0.01)},
    ],
    ids=["gauss-seidel", "gauss-seidel-linear", "step-control"],
)
def test_unsupported_runs_take_the_python_loop(small_fmus, kw, monkeypatch, spy):
    monkeypatch.setenv(native_loop.ENV, "1")
    with tl.integrator_loop(small_fmus) as m:
        assert m.run(0.5, 0.01, progress=False, **kw).completed
    assert spy == []


@pytest.mark.parametrize("cc", [None, "cc --no-such-option"], ids=["no-compiler", "bad-compile"])
def test_without_a_working_compiler_the_python_loop_runs(
    small_fmus, cc, tmp_path, monkeypatch, spy, caplog
):
    monkeypatch.setenv(native_loop.ENV, "1")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(native_loop, "_loaded", {})
    if cc is None:
        monkeypatch.setenv("PATH", str(tmp_path))
        monkeypatch.delenv("CC", raising=False)
    else:
        monkeypatch.setenv("CC", cc)
    with tl.integrator_loop(small_fmus) as m, caplog.at_level("INFO", logger=native_loop.__name__):
        ref = m.run(0.5, 0.01, progress=False)
    assert ref.completed and spy == []
    assert "the Python loop runs" in caplog.text
    assert not list((tmp_path / "cache").glob("**/*.so"))


def test_compiled_once_into_a_cache_keyed_by_the_source(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(native_loop, "_loaded", {})
    assert native_loop.library() is not None
    (lib,) = (tmp_path / "drillstring").glob("native_loop-*.so")
    stamp = lib.stat().st_mtime_ns
    monkeypatch.setattr(native_loop, "_loaded", {})
    assert native_loop.library() is not None
    assert lib.stat().st_mtime_ns == stamp  # found, not compiled again
    source = tmp_path / "native_loop.c"
    source.write_text(native_loop.SOURCE.read_text() + "\n/* changed */\n")
    monkeypatch.setattr(native_loop, "SOURCE", source)
    monkeypatch.setattr(native_loop, "_loaded", {})
    assert native_loop.library() is not None
    assert len(list((tmp_path / "drillstring").glob("native_loop-*.so"))) == 2
