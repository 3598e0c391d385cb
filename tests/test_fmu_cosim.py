"""Plant and controller coupled by three independent masters (issue 5).

The closed loop (plant outputs phi, dphi, theta, dtheta -> controller -> R_minus_R0 -> plant),
fixed macro step H = 2e-3 over tau in [0, 2], controller switched on at t_on = 0.5 (bumpless
latch inside the run), is run by

* an fmpy fixed-step Jacobi loop written in ``fmu_testlib.jacobi_fmpy``,
* libcosim (libcosimpy), and
* the C program ``tests/c_host/host.c`` compiled here with the system's ``cc``, loading the FMUs'
  linux64 binaries through the FMI 2.0 C API in a process without Python.

All three exchange values the same way (libcosim's fixed_step_algorithm, see ``fmu_testlib``), so
their trajectories must agree to 1e-12; they are in fact bit-identical. The C host also checks
the two pythonfmu problems of this path: libpython must be in the global namespace (pythonfmu
#202: the ``libpython`` directive or ``LD_PRELOAD``) and the process must exit with status 0
(pythonfmu #228, worked around inside the FMUs: ``drillstring_fmu_support.guard_process_exit``).
"""

from __future__ import annotations

import fmu_testlib as tl
import numpy as np
import pytest

H_NS = 2_000_000
N_STEPS = 1000
STARTS = {"controller": {"t_on": 0.5}}


@pytest.fixture(scope="session")
def built(tmp_path_factory):
    return tl.built_fmus(tmp_path_factory)


@pytest.fixture(autouse=True)
def _sys_path():
    yield from tl.restore_sys_path()


@pytest.fixture(scope="module")
def jacobi(built):
    rows = tl.jacobi_fmpy(built, H_NS, N_STEPS, STARTS)
    assert rows.shape == (N_STEPS, 11)
    return rows


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    return tl.compile_c_host(tmp_path_factory.mktemp("c_host"))


def test_closed_loop_is_a_real_run(jacobi, built):
    """Guard against comparing trivial trajectories: feedback switched on, states moving."""
    g = built.gains_values
    R = jacobi[:, -1]
    before = jacobi[:, 0] < 0.5
    assert np.all(R[before] == g["R_ff"])  # only the feed-forward before t_on
    assert np.ptp(R[~before]) > 0.1
    assert np.ptp(jacobi[:, 4]) > 0.5  # dphi: from -2.5 towards 0
    assert np.all(np.isfinite(jacobi))


def test_libcosim_equals_fmpy_jacobi(built, jacobi):
    rows = tl.run_libcosim(built, H_NS, N_STEPS, STARTS)
    err = np.max(np.abs(rows - jacobi))
    print(f"libcosim vs fmpy Jacobi, {N_STEPS} steps of H = {H_NS / 1e9}: max |diff| = {err:.3g}")
    assert err <= 1e-12


def test_c_host_equals_fmpy_jacobi_and_exits_zero(built, jacobi, host, tmp_path):
    proc, rows = tl.run_c_host(host, built, H_NS, N_STEPS, STARTS, tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert rows is not None and rows.shape == (N_STEPS + 1, 11)
    assert rows[0, 0] == 0.0
    err = np.max(np.abs(rows[1:] - jacobi))
    print(f"C host vs fmpy Jacobi: max |diff| = {err:.3g}")
    assert err <= 1e-12


@pytest.mark.parametrize(
    ("how", "unload"),
    [("directive", False), ("LD_PRELOAD", True)],
    ids=["dlopen-RTLD_GLOBAL-no-unload", "LD_PRELOAD-unload"],
)
def test_c_host_recipes_exit_zero(built, jacobi, host, tmp_path, how, unload):
    """The recipes of docs/fmu_usage.md: exit status 0 whether or not the host unloads the FMUs
    (the abort of pythonfmu #228 happened in both cases without the FMUs' exit guard)."""
    n = 50
    proc, rows = tl.run_c_host(
        host,
        built,
        H_NS,
        n,
        STARTS,
        tmp_path,
        libpython_directive=how == "directive",
        ld_preload=how == "LD_PRELOAD",
        unload=unload,
    )
    assert proc.returncode == 0, proc.stderr
    assert np.max(np.abs(rows[1:] - jacobi[:n])) <= 1e-12


def test_c_host_without_libpython_fails_with_the_reason(built, host, tmp_path):
    """pythonfmu #202: the FMU binary is not linked to libpython; a host must provide it."""
    proc, rows = tl.run_c_host(
        host, built, H_NS, 5, STARTS, tmp_path, libpython_directive=False, ld_preload=False
    )
    assert proc.returncode == 2
    assert "undefined symbol: Py" in proc.stderr or "undefined symbol: _Py" in proc.stderr
    assert rows is None
