"""``drillstring demo``'s ``summary.json``: valid JSON (a number without a value is null) listing
every file the run wrote, and only those. The steps are stand-ins that write files as the real
ones do (atomically, some files not returned, the map into a staging folder that replaces the
previous map), so the test runs without FMUs or hosts; ``make demo`` runs the real ones."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import fmu_testlib as tl

import drillstring.apps.demo as demo
from drillstring.fileio import write_json, write_text
from drillstring.model.params import REFERENCE_RIG

calls: list[tuple] = []


def _stub_steps(monkeypatch) -> None:
    gains = SimpleNamespace(A=0.5, taubar_crit=2.4, F=(1.0, 2.0, 3.0, 4.0), K0=0.1, R_ff=-0.1,
                            alpha=math.nan, spectral_abscissa=-0.2, params=None)  # fmt: skip
    monkeypatch.setattr(demo, "read_gains", lambda path: gains)
    monkeypatch.setattr(demo, "read_average_points", lambda path: None)
    monkeypatch.setattr(demo, "_check_fmus_carry", lambda *a: None)

    def figure(name):
        def write(folder, **kw):
            return {"png": write_text(Path(folder) / f"{name}.png", "png"),
                    "csv": write_text(Path(folder) / f"{name}.csv", "csv")}  # fmt: skip

        return write

    monkeypatch.setattr(demo, "write_stability_diagram", figure("fig2"))
    monkeypatch.setattr(demo, "write_limit_cycle_figure", figure("fig3"))
    monkeypatch.setattr(demo, "write_average_figure", figure("fig4"))

    def cosim(name):
        def write(folder, fmus_dir, H):
            return {**figure(name)(folder), "max_abs_diff_du": math.nan, "late": math.inf}

        return write

    monkeypatch.setattr(demo, "write_fig5", cosim("fig5"))
    monkeypatch.setattr(demo, "write_fig6", cosim("fig6"))

    def si(fmus_dir, folder):
        files = figure("si_fig5")(folder)
        write_json(Path(folder) / "si_fig5.json", {"x": 1.0})  # written, not returned
        return {"files": {k: str(v) for k, v in files.items()}, "ecos_vs_master": math.nan}

    monkeypatch.setattr(demo, "run_si_demo", si)

    def string_fig6(folder, law):
        files = figure("fig6_string")(folder)
        run = {"status": "ok", "min_bit_speed_after_t_on_rpm": math.nan,
               "max_top_torque_after_t_on_kNm": 1.0}  # fmt: skip
        return {**files, "elements": 16, "one_mode": run, "string": run}

    def modes(argv):
        folder = Path(argv[argv.index("--out") + 1])
        write_json(folder / "modes.json", {"omega_rad_s": [1.0]})
        write_text(folder / "modes.png", "png")
        return 0

    monkeypatch.setattr(demo, "write_string_fig6", string_fig6)
    monkeypatch.setattr(demo, "modes_main", modes)

    def comparison(folder, *a, string=None, **kw):
        n = 1 if string is None else string.elements
        calls.append(("compare", n, kw.get("without_braking")))
        rows = [{"law": "pi", "peak": math.nan, "controller": "pi", "braking": "none",
                 "outcome": "steady" if n == 1 else "stick-slip"}]  # fmt: skip
        return SimpleNamespace(rows=rows, files=figure("comparison")(folder))

    monkeypatch.setattr(demo, "write_controller_comparison", comparison)
    monkeypatch.setattr(demo, "known_rig", lambda params: REFERENCE_RIG)

    def cmap(folder, gains_path, **kw):
        calls.append(("map", kw.get("elements"), kw.get("n")))
        write_text(Path(folder) / "results.csv", "index\n")  # written, not returned
        write_text(Path(folder) / "plots" / "outcome.png", "png")
        path = write_text(Path(folder) / "by_controller.csv", "csv")
        return SimpleNamespace(by_controller=[{"controller": "pi"}], files={"csv": path})

    monkeypatch.setattr(demo, "write_controller_map", cmap)


def test_summary_is_json_and_lists_every_file_the_run_wrote(tmp_path, monkeypatch):
    calls.clear()
    _stub_steps(monkeypatch)
    out = tmp_path / "out"
    # not the run's: the design beside it (make demo's out/design), a file of an earlier run
    write_text(out / "design" / "gains.json", "{}")
    write_text(out / "fig5" / "old_notes.txt", "mine")
    write_text(out / "controllers" / "map" / "stale.csv", "an earlier map")
    summary = demo.run_demo(out / "design", tmp_path / "fmus", out, workers=0, map_points=2,
                            log=lambda s: None)  # fmt: skip
    data = tl.strict_json((out / "summary.json").read_text())
    on_disk = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    mine = {"design/gains.json", "fig5/old_notes.txt"}
    assert data["files"] == summary.files == sorted(set(on_disk) - mine)
    assert "si/si_fig5.json" in data["files"] and "controllers/map/results.csv" in data["files"]
    assert "controllers/map/stale.csv" not in on_disk  # the map is replaced whole
    assert "summary.json" in data["files"]
    assert data["fig5"]["max_abs_diff_du"] is None and data["fig5"]["late"] is None
    assert data["design"]["alpha"] is None and data["controllers"][0]["peak"] is None
    # the comparison on the converged string and on the one-mode model, with and without
    # braking; the map on the string; what changed
    assert ("compare", 16, True) in calls and ("compare", 1, True) in calls
    assert ("map", 16, 2) in calls
    assert data["controller_changes"] == ["pi (without braking): steady -> stick-slip"]
    assert "controllers/string/comparison.png" in data["files"]
    assert "controllers/one-mode/comparison.png" in data["files"]


def test_comparison_changes_lists_the_outcomes_the_string_changes():
    one = [{"controller": "z-torque", "braking": "four-quadrant", "outcome": "steady"},
           {"controller": "lmi", "braking": "none", "outcome": "steady"}]  # fmt: skip
    string = [{"controller": "z-torque", "braking": "four-quadrant", "outcome": "steady"},
              {"controller": "lmi", "braking": "none", "outcome": "reverse_rotation"}]  # fmt: skip
    assert demo.comparison_changes(one, string) == [
        "lmi (without braking): steady -> reverse_rotation"
    ]
