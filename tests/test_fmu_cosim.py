"""Plant and controller in independent hosts: fmpy, libcosim, the project's C host, the Ecos engine
(its command line and its Python API) and fmpy's command line.

The closed loop (plant outputs phi, dphi, theta, dtheta -> controller -> R_minus_R0 -> plant),
fixed macro step H = 2e-3 over tau in [0, 2], controller switched on at t_on = 0.5 (bumpless latch
inside the run), is run by

* an fmpy fixed-step Jacobi loop written in ``fmu_testlib.jacobi_fmpy`` (in this process),
* libcosim (libcosimpy, in this process),
* the C program ``tests/c_host/host.c`` in a clean environment (``fmu_testlib.clean_env``: no
  Python in the process, no LD_PRELOAD, PYTHONPATH, PYTHONHOME, VIRTUAL_ENV, DRILLSTRING_*): the
  FMUs start Python themselves,
* the ``ecos simulate`` command line of the ``ecospy`` wheel on an SSP folder, in a clean
  environment, and Ecos's Python API in this process.

fmpy, libcosim and the C host exchange values the same way (libcosim's fixed_step_algorithm) and
agree to 1e-12 (they are bit-identical); Ecos accumulates its time in double, so it is compared
with the fmpy loop on Ecos's grid: to 1e-9 through its API, and to the resolution of its CSV file
(``std::to_string``: 6 decimals) through its command line. Every folder the FMUs are unpacked to
is named so that its file URI needs percent-encoding (``ü``, ``#``, ``%``, ``[``, space).
"""

from __future__ import annotations

import re

import fmu_testlib as tl
import numpy as np
import pytest

pytestmark = pytest.mark.fmu

H_NS = 2_000_000
N_STEPS = 1000
STARTS = {"controller": {"t_on": 0.5}}
#: A folder name whose file URI needs percent-encoding ("%20" literally too: pythonfmu would read
#: it as a space, so the FMU hands pythonfmu a symbolic link).
ODD = "drill ü#%[x] 100%20"
#: Half a unit in the last place of Ecos's CSV numbers (std::to_string: "%f").
CSV_RESOLUTION = 5e-7 + 1e-12


@pytest.fixture(scope="module")
def jacobi(built):
    rows = tl.jacobi_fmpy(built, H_NS, N_STEPS, STARTS)
    assert rows.shape == (N_STEPS, 11)
    return rows


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    return tl.compile_c_host(tmp_path_factory.mktemp("c_host"))


def _dirs(built, root):
    return {
        "plant": tl.unpack(built.plant.fmu, root / ODD / "plant"),
        "controller": tl.unpack(built.controller.fmu, root / ODD / "controller"),
    }


def _run_host(host, built, root, env, n=N_STEPS, **kw):
    csv = root / ODD / "host.csv"
    config = tl.host_config(built, _dirs(built, root), H_NS, n, STARTS, csv, **kw)
    return tl.run_c_host(host, config, root, env, csv)


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


def test_c_host_in_a_clean_environment_equals_fmpy(built, jacobi, host, tmp_path, clean_home):
    """No Python in the host process: the FMUs load libpython and start it themselves."""
    proc, rows = _run_host(host, built, tmp_path, tl.clean_env(clean_home), logging=True)
    assert proc.returncode == 0, proc.stderr
    assert "started Python" in proc.stderr
    # both FMUs' steps served by the front layer's native fast path (compiled entry points)
    served = f"fmi2Terminate: {N_STEPS} step(s), {N_STEPS} served natively by the front layer"
    assert proc.stderr.count(served) == 2, proc.stderr
    assert rows is not None and rows.shape == (N_STEPS + 1, 11)
    assert rows[0, 0] == 0.0
    err = np.max(np.abs(rows[1:] - jacobi))
    print(f"C host (clean environment) vs fmpy Jacobi: max |diff| = {err:.3g}")
    assert err <= 1e-12


def test_first_compile_is_logged_and_later_unpacks_reuse_it(first_use):
    """The kernel is compiled once per machine (here: per fresh HOME, the session's clean HOME,
    see conftest), not per unpack folder."""
    first, again = first_use.first, first_use.again
    assert first.returncode == 0 and again.returncode == 0, first.stderr + again.stderr
    assert "numba compiled" in first.stderr and "(copied there now)" in first.stderr
    assert "numba compiled" not in again.stderr and "(found there)" in again.stderr
    cached = list(tl.package_cache(first_use.home).glob("pkg-*/drillstring/**/*.nbi"))
    assert cached, "no numba cache index in the package cache"


@pytest.mark.parametrize("unload", [0, 1])
def test_c_host_exits_zero_whether_or_not_it_unloads(
    built, jacobi, host, tmp_path, clean_home, unload
):
    """pythonfmu's abort at process exit (its interpreter guard) is handled by the front layer."""
    proc, rows = _run_host(
        host, built, tmp_path, tl.clean_env(clean_home), n=50, extra=(f"unload {unload}",)
    )
    assert proc.returncode == 0, proc.stderr
    assert np.max(np.abs(rows[1:] - jacobi[:50])) <= 1e-12


def test_c_host_that_preloads_libpython_itself(built, jacobi, host, tmp_path, clean_home):
    """A host that put a libpython into the global namespace (not started): the FMU starts it."""
    proc, rows = _run_host(
        host,
        built,
        tmp_path,
        tl.clean_env(clean_home),
        n=50,
        extra=(f"libpython {tl.libpython()}",),
    )
    assert proc.returncode == 0, proc.stderr
    assert np.max(np.abs(rows[1:] - jacobi[:50])) <= 1e-12


def test_plain_python_kernel_is_bit_identical(built, jacobi, host, tmp_path, clean_home):
    """DRILLSTRING_JIT=0 (the plain-Python kernel) in the same host: the same numbers, every
    call served by Python (no compiled entry points for the front layer's fast path)."""
    env = tl.clean_env(clean_home, DRILLSTRING_JIT="0")
    proc, rows = _run_host(host, built, tmp_path, env, n=200, logging=True)
    assert proc.returncode == 0, proc.stderr
    assert np.array_equal(rows[1:], jacobi[:200])
    off = "fmi2Terminate: 200 step(s), the native fast path is off"
    assert proc.stderr.count(off) == 2, proc.stderr


# ------------------------------------------------------------------------------------------------
# Ecos
# ------------------------------------------------------------------------------------------------


def _ecos_reference(built, n, units=("plant", "controller")):
    points = tl.ecos_grid(H_NS / 1e9, n)
    starts = STARTS if "controller" in units else {}
    return tl.jacobi_fmpy(built, H_NS, n, starts, points=points, units=units)


def _ecos_names(built, units):
    """Ecos's names of the recorded columns of ``fmu_testlib._columns``. Ecos reads every output
    again after moving the values along the connections, so the controller's output read there
    is already that of the next step's inputs; the value the plant was given, its input
    R_minus_R0, is the one the other masters record."""
    names = []
    for unit, vr in tl._columns(built):
        if unit in units:
            name = next(n for n, v in getattr(built, unit).vr.items() if v == vr)
            names.append(("plant", "R_minus_R0") if unit == "controller" else (unit, name))
    return names


def _ecos_columns(header, data, built, units):
    """Ecos's CSV columns in the order of ``fmu_testlib._columns``."""
    out = [data[:, header.index("time")]]
    for unit, name in _ecos_names(built, units):
        prefix = unit if len(units) > 1 else "instance"
        out.append(data[:, header.index(f"{prefix}::{name}[REAL]")])
    return np.column_stack(out)


def test_ecos_command_line_plant_alone(built, tmp_path, clean_home):
    work = tmp_path / ODD
    work.mkdir()
    fmu = work / built.plant.fmu.name
    fmu.write_bytes(built.plant.fmu.read_bytes())
    env = tl.clean_env(clean_home, TMPDIR=str(work))  # Ecos unpacks into $TMPDIR
    n = 500
    stop = repr(n * H_NS / 1e9)
    proc = tl.run_clean(
        tl.ecos_command("simulate", "--path", str(fmu), "--stepSize", "0.002", "--stopTime", stop),
        env,
        work,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    header, data = tl.read_ecos_csv(work / "DrillStringPlant.csv")
    got = _ecos_columns(header, data, built, ("plant",))
    ref = _ecos_reference(built, n, units=("plant",))
    k = min(len(got) - 1, len(ref))
    assert k >= n - 1
    err = np.max(np.abs(got[1 : k + 1, 1:] - ref[:k, 1:]))
    print(f"ecos simulate, plant alone: max |diff| = {err:.3g} (CSV resolution 5e-7)")
    assert err <= CSV_RESOLUTION


def test_ecos_command_line_closed_loop(built, tmp_path, clean_home):
    work = tmp_path / ODD
    tl.ssp_folder(built, work / "loop", STARTS)
    env = tl.clean_env(clean_home, TMPDIR=str(work))
    proc = tl.run_clean(
        tl.ecos_command(
            "simulate",
            "--path",
            str(work / "loop"),
            "--stepSize",
            "0.002",
            "--stopTime",
            "2",
            "--parameterSet",
            "initial",
        ),  # fmt: skip
        env,
        work,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    header, data = tl.read_ecos_csv(work / "loop.csv")
    got = _ecos_columns(header, data, built, ("plant", "controller"))
    ref = _ecos_reference(built, N_STEPS)
    k = len(got) - 1
    assert k >= N_STEPS - 1  # Ecos stops where t + h would pass stopTime in double
    err = np.max(np.abs(got[1:, 1:] - ref[:k, 1:]))
    print(f"ecos simulate, closed loop via SSP: max |diff| = {err:.3g} (CSV resolution 5e-7)")
    assert err <= CSV_RESOLUTION
    assert np.ptp(got[:, -1]) > 0.1  # the feedback acted


def test_ecos_api_closed_loop_equals_fmpy(built, tmp_path):
    """Ecos's engine through its Python API (in this process: it lends the FMUs its Python)."""
    ecospy = tl.load_ecospy()
    n = N_STEPS
    structure = ecospy.EcosSimulationStructure()
    structure.add_model("plant", str(built.plant.fmu))
    structure.add_model("controller", str(built.controller.fmu))
    for src, svr, dst, dvr in tl._links(built):
        sname = next(k for k, v in getattr(built, src).vr.items() if v == svr)
        dname = next(k for k, v in getattr(built, dst).vr.items() if v == dvr)
        structure.make_real_connection(f"{src}::{sname}", f"{dst}::{dname}")
    structure.add_parameter_set("initial", {"controller::t_on": 0.5})
    cols = _ecos_names(built, ("plant", "controller"))
    rows = []
    with (
        tl.kept_sys_path(),
        ecospy.EcosSimulation(structure=structure, step_size=H_NS / 1e9) as sim,
    ):
        sim.init(parameter_set="initial")
        for _ in range(n):
            sim.step()
            rows.append([sim.get_time()] + [sim.get_real(f"{u}::{name}") for u, name in cols])
        sim.terminate()
    got = np.array(rows)
    ref = _ecos_reference(built, n)
    err = np.max(np.abs(got - ref))
    print(f"Ecos API vs fmpy on Ecos's grid: max |diff| = {err:.3g}")
    assert err <= 1e-9


# ------------------------------------------------------------------------------------------------
# fmpy's command line
# ------------------------------------------------------------------------------------------------


def _fmpy_simulate(built, tmp_path, clean_home, *args):
    work = tmp_path / ODD
    work.mkdir(exist_ok=True)
    env = tl.clean_env(clean_home, TMPDIR=str(work))  # fmpy unpacks into $TMPDIR
    out = work / "result.csv"
    cmd = tl.fmpy_command(
        "simulate", str(built.plant.fmu), "--stop-time", "0.5", "--output-file", str(out), *args
    )
    return tl.run_clean(cmd, env, work), out


def test_fmpy_command_line_runs_and_equals_fmpy(built, tmp_path, clean_home):
    proc, out = _fmpy_simulate(built, tmp_path, clean_home)
    assert proc.returncode == 0, proc.stderr
    data = np.genfromtxt(out, delimiter=",", names=True)
    assert len(data) == 51
    # fmpy's own grid: t_k = k*0.01 and h = t_{k+1} - t_k (not libcosim's integer-ns grid,
    # whose points differ from these in the last bit at 6 of the 50 steps)
    points = [(k * 0.01, (k + 1) * 0.01 - k * 0.01) for k in range(50)]
    ref = tl.jacobi_fmpy(built, 10_000_000, 50, {}, points=points, units=("plant",))
    assert np.array_equal(data["dphi"][1:], ref[:, 4])


def test_fmpy_command_line_fails_on_an_invalid_parameter(built, tmp_path, clean_home):
    proc, _ = _fmpy_simulate(built, tmp_path, clean_home, "--start-values", "psi", "-1")
    assert proc.returncode != 0
    text = proc.stdout + proc.stderr
    assert "parameter psi = -1.0 rejected: ScaledParams.psi must be > 0, got -1.0" in text


def test_fmpy_command_line_fails_on_a_validity_stop(built, tmp_path, clean_home):
    """du/dtau(0) = -40 lifts the bit off the rock inside the second step: fmi2Discard."""
    proc, _ = _fmpy_simulate(built, tmp_path, clean_home, "--start-values", "du0", "-40")
    assert proc.returncode != 0
    text = proc.stdout + proc.stderr
    assert "bit bouncing: depth of cut d < 0, outside the model at tau = 0.0107" in text


def test_docs_c_host_example(built, jacobi, tmp_path, clean_home):
    """The C-host example of docs/fmus.md, run as it stands (with the session's FMUs): the closed
    loop of this module (2 ms steps, t_on = 0.5), so its last row is fmpy's."""
    doc = (tl.ROOT / "docs" / "fmus.md").read_text(encoding="utf-8")
    section = doc[doc.index("## Example: a C host") :]
    script = re.search(r"```sh\n(.*?)```", section, re.S).group(1)
    env = tl.clean_env(clean_home, FMUS=str(built.out))
    proc = tl.run_clean(["bash", "-e", "-c", script], env, tl.ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    t, dphi, r = (float(x) for x in proc.stdout.split()[-1].split(","))
    expected = jacobi[-1, [0, 1 + tl.RECORD_PLANT.index("dphi"), -1]]
    assert t == 2.0 and np.max(np.abs(np.array([t, dphi, r]) - expected)) <= 1e-12
    assert abs(r) > 0.1  # the controller acts
    assert "started Python" in proc.stderr


# ------------------------------------------------------------------------------------------------
# the SI FMUs in the independent hosts
# ------------------------------------------------------------------------------------------------


def test_si_loop_in_the_c_host_in_a_clean_environment_equals_fmpy(
    built, host, tmp_path, clean_home
):
    """The SI FMUs keep the front layer's guarantees: no Python in the host, the package cache
    found where the scaled FMUs put it (the same bundled package), bit-identical results."""
    si = built.si
    starts = {"controller": {"t_on": 0.5 * 0.9}}
    n = 500
    ref = tl.jacobi_fmpy(si, H_NS, n, starts)
    dirs = {
        "plant": tl.unpack(si.plant.fmu, tmp_path / ODD / "plant"),
        "controller": tl.unpack(si.controller.fmu, tmp_path / ODD / "controller"),
    }
    csv = tmp_path / ODD / "host.csv"
    config = tl.host_config(si, dirs, H_NS, n, starts, csv, logging=True)
    proc, rows = tl.run_c_host(host, config, tmp_path, tl.clean_env(clean_home), csv)
    assert proc.returncode == 0, proc.stderr
    assert "started Python" in proc.stderr and "drillstring package from the cache" in proc.stderr
    assert rows is not None and rows.shape == (n + 1, len(si.record) + 2)
    assert np.array_equal(rows[1:], ref)
    assert np.ptp(ref[:, -1]) > 1e3  # the table torque moved (N m)
