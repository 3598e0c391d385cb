"""The SSP 1.0 packages of the closed loop: valid, complete, and the same system in every host.

* validity: both packages (``build_fmus.py`` writes them) against the SSP 1.0 schemas that fmpy
  ships, by :func:`validate_ssp` and by fmpy's own reader; a broken description is reported;
* content: the named sets ``fig5``, ``fig6`` (the experiments, converted on the reference rig
  in SI), ``reference`` and ``gains`` (the FMUs' own start values), units, the default
  experiment and the fixed-step annotation; the archive is reproducible;
* :meth:`Master.from_ssp`: the scaled package with ``fig5`` is bit for bit the Python wiring of
  the loop; another FMU can take a component's place; bad requests fail with the reason;
* hosts of the SI package, none skipped: Ecos's Python API and the project's master with the
  same coupling (Jacobi, zero-order hold, exchange after all steps, accumulated time) to 1e-9;
  the ``ecos simulate`` command line in a clean environment to the resolution of its CSV;
  libcosim (it applies the first binding of each component and the fixed-step annotation) and
  the master on libcosim's grid to 1e-12; fmpy's ``simulate_ssp`` with an explicit parameter set
  equals the algorithm it documents (zero inputs before the first step, no initialization
  exchange) run by the test library's fmpy loop, and ignores the package's bindings;
* ``drillstring cosim`` and :func:`run_si_demo`.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import zipfile
from pathlib import Path

import fmu_testlib as tl
import numpy as np
import pytest
from fmpy import read_model_description

from drillstring.apps.cosim import cosim_main, run_si_demo, si_demo_lines
from drillstring.model.experiments import FIG5, FIG6
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.units import UNITS, UnitDef
from drillstring.orchestration.closed_loop import VARIANTS, closed_loop_master, kept_sys_path
from drillstring.orchestration.connections import declared_start_values
from drillstring.orchestration.hosts import ecos_command, run_ecos, run_fmpy_ssp
from drillstring.orchestration.loop_ssp import PACKAGE_SETS, write_loop_package
from drillstring.orchestration.master import Master
from drillstring.orchestration.ssp import SspError, read_ssp, validate_ssp, write_ssp

pytestmark = pytest.mark.fmu

TS = REFERENCE_RIG.t_star
H = 1e-3
#: Half a unit in the last place of Ecos's CSV numbers (std::to_string: "%f").
CSV_RESOLUTION = 5e-7 + 1e-12
ODD = "drill ü#%[x] 100%20"


def _plant_columns(data) -> list[str]:
    return [n for n in data.dtype.names if n.startswith("plant.")]


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = float(np.max(np.abs(b)))
    return float(np.max(np.abs(a - b)) / scale) if scale else float(np.max(np.abs(a - b)))


def _master_run(ssp, parameter_set, stop, **kw):
    with kept_sys_path(), Master.from_ssp(ssp, parameter_set) as m:
        res = m.run(stop, H, progress=False, **kw)
    assert res.completed, res.failure
    return res


# ------------------------------------------------------------------------------------------------
# validity and content
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("system", ["scaled", "si"])
def test_packages_are_valid_ssp_1_0(built, system):
    from fmpy.ssp.ssd import read_ssd

    ssp = getattr(built, system).ssp
    assert validate_ssp(ssp) == []
    ssd = read_ssd(str(ssp), validate=True)  # fmpy's reader, validating the SSD and each .ssv
    assert [c.name for c in ssd.system.elements] == ["plant", "controller"]
    assert ssd.version == "1.0"


def test_a_broken_description_is_reported(built, tmp_path):
    folder = tmp_path / "broken"
    with zipfile.ZipFile(built.si.ssp) as z:
        z.extractall(folder)
    ssd = folder / "SystemStructure.ssd"
    text = ssd.read_text()
    ssd.write_text(text.replace(' endConnector="table_torque"', "", 1))
    problems = validate_ssp(folder)
    assert problems and "endConnector" in problems[0], problems
    with pytest.raises(SspError, match="not a valid SSP 1.0 package.*endConnector"):
        read_ssp(folder)
    ssd.write_text(text)
    assert validate_ssp(folder) == []
    (folder / "resources" / "fig6.plant.ssv").unlink()
    assert any("resources/fig6.plant.ssv is not in the package" in p for p in validate_ssp(folder))


def test_si_package_content(built):
    p = read_ssp(built.si.ssp, unpack=False)
    assert p.parameter_set_names == PACKAGE_SETS
    assert [c.name for c in p.components] == ["plant", "controller"]
    assert [str(c) for c in p.connections] == [
        *(f"plant.{n} -> controller.{n}" for n in tl.FEEDBACK_SI),
        "controller.table_torque -> plant.table_torque",
    ]
    # the default experiment: Fig. 5 (tau in [0, 60]) in whole 1 ms steps; the fixed step
    assert (p.start_time, p.step) == (0.0, 1e-3)
    assert 60 * TS <= p.stop_time < 60 * TS + p.step
    assert p.units["N.m"] == {"kg": 1, "m": 2, "s": -2} and p.units["rad/s"] == {"s": -1, "rad": 1}
    plant, ctrl = p.components
    # every connector carries its unit, the units of the FMU's variables
    md = {v.name: v for v in read_model_description(str(built.si.plant.fmu)).modelVariables}
    for k in plant.connectors:
        assert k.unit == (md[k.name].unit if k.type == "Real" else None), k.name
    values = p.start_values("fig5")
    assert values["plant"]["dphi0"] == ("Real", pytest.approx(FIG5.dphi0 / TS, rel=1e-15))
    assert values["plant"]["h"] == ("Real", pytest.approx(FIG5.h * TS, rel=1e-15))
    assert values["plant"]["torsional_stick_model"] == ("Boolean", False)
    assert values["controller"] == {
        "t_on": ("Real", 0.0),
        "latch": ("Integer", 1),
        "enabled": ("Boolean", True),
    }
    six = p.start_values("fig6")
    assert six["plant"]["dphi0"][1] == pytest.approx(FIG6.dphi0 / TS, rel=1e-15)
    assert six["plant"]["torsional_stick_model"] == ("Boolean", True)
    assert six["controller"]["t_on"][1] == pytest.approx(FIG6.t_on * TS, rel=1e-15)
    assert six["controller"]["latch"] == ("Integer", 2)
    ref = {k: v for k, (_, v) in p.start_values("reference")["plant"].items()}
    assert ref == REFERENCE_RIG.to_dict()
    ctrl_md = declared_start_values(read_model_description(str(built.si.controller.fmu)))
    gains = {k: v for k, (_, v) in p.start_values("gains")["controller"].items()}
    assert gains == {k: ctrl_md[k] for k in gains} and set(gains) >= {"F[1]", "R_ff", "Omega0"}
    assert list(plant.parameter_sets) == ["fig5", "fig6", "reference"]
    assert list(ctrl.parameter_sets) == ["fig5", "fig6", "gains"]


def test_scaled_package_content_and_reproducible_archive(built, tmp_path):
    p = read_ssp(built.ssp, unpack=False)
    assert (p.stop_time, p.step) == (FIG5.tau_end, 1e-3)
    ref = {k: v for k, (_, v) in p.start_values("reference")["plant"].items()}
    assert ref == REFERENCE.to_dict()
    assert p.start_values("fig5")["plant"]["dphi0"] == ("Real", FIG5.dphi0)
    for name in ("DrillStringPlant.fmu", "TorsionalController.fmu"):
        shutil.copyfile(built.out / name, tmp_path / name)
    again = write_loop_package(tmp_path, VARIANTS["scaled"])
    assert again.read_bytes() == built.ssp.read_bytes()


# ------------------------------------------------------------------------------------------------
# the project's master
# ------------------------------------------------------------------------------------------------


def test_from_ssp_is_the_python_wiring_bit_for_bit(built):
    a = _master_run(built.ssp, "fig5", 2.0)
    with kept_sys_path(), closed_loop_master(built.out, FIG5) as m:
        b = m.run(2.0, H, progress=False)
    common = [n for n in b.data.dtype.names if n in a.data.dtype.names]
    assert len(common) >= 12
    for name in common:
        assert np.array_equal(a[name], b[name]), name
    assert np.ptp(a["plant.dphi"]) > 1.0  # a real run


def test_from_ssp_swaps_a_component_and_rejects_bad_requests(built, tmp_path):
    mine = tmp_path / "MyController.fmu"
    shutil.copyfile(built.si.controller.fmu, mine)
    a = _master_run(built.si.ssp, "fig5", 0.2)
    with kept_sys_path(), Master.from_ssp(built.si.ssp, "fig5", fmus={"controller": mine}) as m:
        assert m.system.units[1].fmu == mine
        b = m.run(0.2, H, progress=False)
    assert np.array_equal(a.data, b.data)
    with pytest.raises(ValueError, match="has no variable 'bit_angle'"):
        Master.from_ssp(built.si.ssp, "fig5", fmus={"controller": built.controller.fmu})
    with pytest.raises(SspError, match="no parameter set 'fig7'.*fig5, fig6, reference, gains"):
        Master.from_ssp(built.si.ssp, "fig7")
    with pytest.raises(SspError, match="no component 'pump'"):
        Master.from_ssp(built.si.ssp, "fig5", fmus={"pump": mine})
    with pytest.raises(SspError, match="does not exist"):
        Master.from_ssp(tmp_path / "none.ssp")


def test_connected_units_must_agree(built, tmp_path):
    p = read_ssp(built.si.ssp)
    try:
        plant, ctrl = p.components
        bad = tuple(
            dataclasses.replace(k, unit="rpm") if k.name == "bit_speed" else k
            for k in ctrl.connectors
        )
        comps = [plant, dataclasses.replace(ctrl, connectors=bad)]
        units = {**UNITS, "rpm": UnitDef("rpm", {"s": -1, "rad": 1})}
        out = write_ssp(
            tmp_path / "bad.ssp",
            name="bad",
            components=comps,
            fmus={"plant": p.fmu("plant"), "controller": p.fmu("controller")},
            connections=p.connections,
            units=units,
        )
    finally:
        shutil.rmtree(p.root, ignore_errors=True)
    with pytest.raises(SspError, match="units 'rad/s' and 'rpm' differ"):
        Master.from_ssp(out, "fig5")


# ------------------------------------------------------------------------------------------------
# Ecos
# ------------------------------------------------------------------------------------------------


def test_ecos_api_equals_the_master_with_the_same_coupling(built):
    """Fig. 6's set (not the first one): Ecos applies the set it is told to."""
    ref = _master_run(built.si.ssp, "fig6", 5.0, exchange="simple", grid="sum")
    names = _plant_columns(ref.data)
    got = run_ecos(built.si.ssp, "fig6", 5.0, H, names)
    assert len(got) == len(ref.time) - 1
    assert np.max(np.abs(got["time"] - ref.time[1:])) == 0.0  # the same accumulated grid
    worst = {n: _rel(got[n], ref[n][1:]) for n in names}
    print("Ecos API vs master, SI package, fig6:", max(worst.values()))
    assert max(worst.values()) <= 1e-9, worst
    assert np.ptp(got["plant.bit_speed"]) > 1.0


def test_ecos_command_line_in_a_clean_environment(built, tmp_path, clean_home):
    work = tmp_path / ODD
    work.mkdir()
    ssp = work / built.si.ssp.name
    shutil.copyfile(built.si.ssp, ssp)
    env = tl.clean_env(clean_home, TMPDIR=str(work))  # Ecos unpacks into $TMPDIR
    cmd = ecos_command(
        "simulate", "--path", str(ssp), "--stepSize", "0.001", "--stopTime", "2",
        "--parameterSet", "fig5",
    )  # fmt: skip
    proc = tl.run_clean(cmd, env, work)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    header, data = tl.read_ecos_csv(work / "DrillStringClosedLoopSI.csv")
    ref = _master_run(built.si.ssp, "fig5", 2.0, exchange="simple", grid="sum")
    k = min(len(data) - 1, len(ref.time) - 1)
    assert k >= 1999  # Ecos stops where t + h would pass stopTime in double
    for name in ("bit_speed", "table_speed", "bit_angle", "weight_on_bit", "torque_on_bit"):
        col = data[1 : k + 1, header.index(f"plant::{name}[REAL]")]
        err = np.max(np.abs(col - ref[f"plant.{name}"][1 : k + 1]))
        assert err <= CSV_RESOLUTION, (name, err)


# ------------------------------------------------------------------------------------------------
# libcosim
# ------------------------------------------------------------------------------------------------


def _libcosim(ssp: Path, n: int, names: list[str]) -> np.ndarray:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    with kept_sys_path():
        ex = CosimExecution.from_ssp_file(str(ssp))  # its step: the fixed-step annotation
        observer = CosimObserver.create_last_value()
        assert ex.add_observer(observer)
        plant = ex.slave_index_from_instance_name("plant")
        vr = {v.name.decode(): v.reference for v in ex.slave_variables(plant)}
        refs = [vr[n.split(".", 1)[1]] for n in names]
        rows = []
        for _ in range(n):
            assert ex.step(1)
            rows.append(observer.last_real_values(plant, refs))
    return np.array(rows)


def test_libcosim_runs_the_package_with_its_first_bindings(built, tmp_path):
    """libcosim applies the first binding of each component (fig5 in the package; fig6 in a copy
    with fig6 first) and steps with the fixed-step annotation; the master on libcosim's grid
    gives the same numbers."""
    names = ["plant.bit_speed", "plant.table_speed", "plant.bit_velocity", "plant.contact"]
    for first in ("fig5", "fig6"):
        ssp = built.si.ssp
        if first == "fig6":
            p = read_ssp(built.si.ssp)
            try:
                comps = [
                    dataclasses.replace(
                        c,
                        parameter_sets={
                            k: c.parameter_sets[k]
                            for k in ("fig6", "fig5", *list(c.parameter_sets)[2:])
                        },
                    )
                    for c in p.components
                ]
                ssp = write_ssp(
                    tmp_path / "fig6_first.ssp",
                    name="fig6_first",
                    components=comps,
                    fmus={c.name: p.fmu(c.name) for c in p.components},
                    connections=p.connections,
                    units=UNITS,
                    default_experiment=(0.0, p.stop_time, p.step),
                )
            finally:
                shutil.rmtree(p.root, ignore_errors=True)
        got = _libcosim(ssp, 1000, names)
        ref = _master_run(built.si.ssp, first, 1.0, exchange="simple", grid="ns")
        err = max(_rel(got[:, j], ref[n][1:]) for j, n in enumerate(names))
        print(f"libcosim vs master, first binding {first}: {err:.2e}")
        assert err <= 1e-12, (first, err)


# ------------------------------------------------------------------------------------------------
# fmpy.ssp
# ------------------------------------------------------------------------------------------------


def test_fmpy_ssp_with_an_explicit_parameter_set(built):
    si = built.si
    stop = 0.5
    got = run_fmpy_ssp(si.ssp, "fig6", stop, H)
    n = len(got)
    assert n in (500, 501)  # fmpy steps while its accumulated time is below the stop time
    starts = {
        c: {k: v for k, (_, v) in vals.items()}
        for c, vals in read_ssp(si.ssp, unpack=False).start_values("fig6").items()
    }
    with kept_sys_path():
        ref = tl.jacobi_fmpy(si, 0, n, starts, points=tl.ecos_grid(H, n), initial_exchange=False)
    names = [f"plant.{r}" for r in si.record]
    for j, name in enumerate(names):
        assert np.max(np.abs(got[name] - ref[:, 1 + j])) <= 1e-12 * np.max(np.abs(ref[:, 1 + j])), (
            name
        )
    # the package's bindings are not applied: without the explicit set the FMUs' own values
    plain = run_fmpy_ssp(si.ssp, None, stop, H)
    with kept_sys_path():
        defaults = tl.jacobi_fmpy(si, 0, n, {}, points=tl.ecos_grid(H, n), initial_exchange=False)
    assert (
        np.max(np.abs(plain["plant.bit_speed"] - defaults[:, 1 + si.record.index("bit_speed")]))
        <= 1e-12
    )
    assert np.max(np.abs(plain["plant.bit_speed"] - got["plant.bit_speed"])) > 0.1


# ------------------------------------------------------------------------------------------------
# the command line and the demo's SI step
# ------------------------------------------------------------------------------------------------


def test_cosim_command_writes_cross_check_csv_and_png(built, tmp_path, capsys):
    out = tmp_path / "si"
    with kept_sys_path():
        code = cosim_main(
            [str(built.si.ssp), "--out", str(out), "--stop-time", "0.2", "--no-progress"]
        )
    assert code == 0, capsys.readouterr().err
    lines = (out / "cosim.csv").read_text().splitlines()
    assert lines[0].startswith('"time","plant.bit_angle"')
    assert len(lines) == 1 + 201
    data = np.genfromtxt(out / "cosim.csv", delimiter=",", names=True)
    ref = _master_run(built.si.ssp, "fig5", 0.2)  # the first set, default coupling
    assert np.array_equal(data["plantbit_speed"], ref["plant.bit_speed"])
    assert (out / "speeds.png").stat().st_size > 10_000
    summary = json.loads((out / "cosim.json").read_text())
    assert summary["parameter_set"] == "fig5" and summary["unit_system"] == "si"
    # the scaled package, another set, its own step
    code = cosim_main(
        [str(built.ssp), "--out", str(tmp_path / "sc"), "--parameter-set", "fig6",
         "--stop-time", "0.5", "--step", "0.01", "--no-progress"]
    )  # fmt: skip
    assert code == 0 and (tmp_path / "sc" / "speeds.png").is_file()
    assert json.loads((tmp_path / "sc" / "cosim.json").read_text())["unit_system"] == "scaled"
    code = cosim_main([str(built.ssp), "--out", str(tmp_path / "x"), "--parameter-set", "fig7"])
    assert code == 2 and "no parameter set 'fig7'" in capsys.readouterr().err


def test_run_si_demo_agrees_with_ecos_and_the_monolithic_solver(built, tmp_path):
    s = run_si_demo(built.out, tmp_path, stop_time=1.0)
    assert s["steps"] == 1000
    assert s["ecos_vs_master"] <= 1e-9
    for host in ("master", "ecos"):
        # the coupling error of a zero-order hold at H = 1 ms: small, not zero
        for name, err in s["relative_error"][host].items():
            assert 1e-6 < err < 0.05, (host, name, err)
    assert Path(s["files"]["png"]).is_file()
    assert json.loads((tmp_path / "si_fig5.json").read_text())["steps"] == 1000
    lines = si_demo_lines(s)
    assert len(lines) == 4 and lines[-1].startswith("  Ecos vs master: max relative difference")
