"""Self-contained FMUs (``build_fmus.py --self-contained``, drillstring.apps.export.self_contained)
as another machine sees them: no Python installation, no virtual environment, no checkout, no
cache (``tests/isolation.py``), and the system's libffi replaced by an empty file.

The session's plant and LMI controller are made self-contained once (conftest's
``self_contained``, beside the earlier tests: its warm-up compiles numba's kernel for a generic
x86-64 CPU); the C host and ``ecos simulate`` then run them in isolation, against the same hosts
running the normal FMUs in the clean environment of the other host tests.
"""

from __future__ import annotations

import dataclasses
import shutil
import time
import zipfile
from importlib import metadata
from pathlib import Path

import fmu_testlib as tl
import isolation
import numpy as np
import pytest
from packaging.requirements import Requirement

from drillstring.apps.export.self_contained import DISTRIBUTIONS

pytestmark = pytest.mark.slow

H_NS = 2_000_000
N_STEPS = 1000
STARTS = {"controller": {"t_on": 0.5}}
ODD = "drill ü#%[x] 100%20"  # a folder whose URI needs percent-encoding


def _hidden(*homes: Path) -> list[Path]:
    return [*isolation.python_installations(), isolation.ROOT, *isolation.user_caches(*homes)]


def _c_host_run(built: tl.Built, work: Path, env: dict[str, str], wrap=None):
    work.mkdir(parents=True, exist_ok=True)
    exe = tl.compile_c_host(work)
    dirs = {n: tl.unpack(getattr(built, n).fmu, work / ODD / n) for n in ("plant", "controller")}
    csv = work / "host.csv"
    config = tl.host_config(built, dirs, H_NS, N_STEPS, STARTS, csv, logging=True)
    cfg = work / "host.cfg"
    cfg.write_text(config, encoding="utf-8")
    cmd = [str(exe), str(cfg)]
    t0 = time.perf_counter()
    proc = tl.run_clean(wrap(cmd) if wrap else cmd, env, work)
    elapsed = time.perf_counter() - t0
    data = np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2) if csv.exists() else None
    return proc, data, elapsed


def test_the_bundle_holds_every_distribution_the_bundled_ones_require():
    """Each requirement of a bundled distribution that applies here (not an extra, not another
    platform) is bundled too: the bundle imports nothing it does not carry."""
    for name in DISTRIBUTIONS:
        for text in metadata.requires(name) or ():
            req = Requirement(text)
            if req.marker is None or req.marker.evaluate({"extra": ""}):
                assert req.name.lower() in DISTRIBUTIONS, f"{name} requires {text!r}, not bundled"


def test_the_self_contained_fmu_is_the_normal_fmu_plus_its_runtime(built, self_contained):
    """Same model description, binaries and package; the record names the bundle."""
    for normal, bundled in (
        (built.plant, self_contained.plant),
        (built.controller, self_contained.controller),
    ):
        with zipfile.ZipFile(normal.fmu) as a, zipfile.ZipFile(bundled.fmu) as b:
            names_a, names_b = set(a.namelist()), set(b.namelist())
            assert names_a < names_b
            for name in names_a - {"resources/drillstring_fmu_python.cfg"}:
                if name != "documentation/index.html":
                    assert a.read(name) == b.read(name), name
            record = b.read("resources/drillstring_fmu_python.cfg").decode()
            extra = names_b - names_a
        assert "self-contained 1" in record and "numba-cpu generic" in record
        assert any(n.startswith("resources/python/lib/libpython3") for n in extra)
        assert any(n.endswith(".nbc") and "/__pycache__/" in n for n in extra)
        assert "fallback python/lib/fallback/libffi.so.8" in record
        print(f"{bundled.fmu.name}: {bundled.fmu.stat().st_size / 2**20:.1f} MiB")


def test_c_host_runs_the_self_contained_fmus_where_no_python_is(
    built, self_contained, tmp_path, clean_home
):
    """The closed loop in the C host: the normal FMUs in the clean environment (their kernel
    compiled in clean_home), the self-contained ones in isolation with bogus overrides of the
    Python they would use, libffi missing; the same numbers bit for bit, nothing compiled."""
    normal, ref, _ = _c_host_run(built, tmp_path / "normal", tl.clean_env(clean_home))
    assert normal.returncode == 0, normal.stderr
    work = tmp_path / "isolated"
    home = work / "home"
    home.mkdir(parents=True)
    env = tl.clean_env(home, **tl.BOGUS_PYTHON)
    libffi = isolation.system_library("libffi.so.8")

    def wrap(cmd):
        return isolation.isolated(cmd, work, _hidden(clean_home, home), [libffi])

    proc, got, elapsed = _c_host_run(self_contained, work, env, wrap)
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log
    unpacked = work / ODD / "plant" / "resources" / "python"
    assert "started Python 3.11" in log and f"from {unpacked}/lib/libpython3.11.so" in log
    assert "libffi.so.8: not on this machine, the FMU's copy loaded" in log
    assert "-generic (copied there now)" in log
    assert "numba compiled" not in log  # the bundled kernel was found, nothing compiled
    assert np.array_equal(got, ref)
    assert np.ptp(got[:, -1]) > 0.1  # the feedback acted
    print(f"self-contained closed loop, {N_STEPS} steps, in isolation: {elapsed:.2f} s")


def test_self_contained_fmus_run_from_a_read_only_unpack_folder_and_home(
    built, self_contained, tmp_path, clean_home
):
    """HOME and the unpack folder read-only, in isolation: no package cache can
    be written (warned), and numba, with no writable folder for its cache, reads the kernel the
    FMU ships in its read-only __pycache__ folders as it is: nothing compiled (numba's "no
    locator available" stopped every FMU at fmi2Instantiate before), the same numbers as the
    normal FMUs, nothing written into either folder."""
    normal, ref, _ = _c_host_run(built, tmp_path / "normal", tl.clean_env(clean_home))
    assert normal.returncode == 0, normal.stderr
    work = tmp_path / "read-only"
    home = work / "home"
    home.mkdir(parents=True)
    (work / ODD).mkdir()

    def wrap(cmd):
        hidden = _hidden(clean_home, home)
        return isolation.isolated(cmd, work, hidden, read_only=[home, work / ODD])

    proc, got, elapsed = _c_host_run(self_contained, work, tl.clean_env(home), wrap)
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log[-4000:]
    assert "no locator" not in log
    assert "cannot cache the drillstring package" in log  # HOME is read-only: warned
    assert "numba compiled" not in log  # the shipped kernel was read, nothing compiled
    assert list(home.iterdir()) == []
    assert not list((work / ODD).rglob("*.tmp.*"))
    assert np.array_equal(got, ref)
    print(f"self-contained closed loop from read-only folders: {elapsed:.2f} s")


def test_ecos_runs_the_self_contained_fmus_like_the_normal_ones(
    built, self_contained, tmp_path, clean_home
):
    """``ecos simulate`` on an SSP folder of the normal FMUs (clean environment) and of the
    self-contained ones (in isolation, the Ecos binary and libtbb copied out of the hidden
    virtual environment): the same CSV byte for byte."""
    cmd = tl.ecos_command("simulate")
    loader, exe, tbb = cmd[0], Path(cmd[3]), Path(cmd[2]) / "libtbb.so.12"
    args = ["--stepSize", "0.002", "--stopTime", "2", "--parameterSet", "initial"]
    csvs = []
    for kind, units in (("normal", built), ("isolated", self_contained)):
        work = tmp_path / kind
        tl.ssp_folder(units, work / "loop", STARTS)
        if kind == "normal":
            env = tl.clean_env(clean_home, TMPDIR=str(work))
            run = tl.ecos_command("simulate", "--path", str(work / "loop"), *args)
        else:
            home = work / "home"
            home.mkdir()
            bin_dir = work / "ecos"
            bin_dir.mkdir()
            shutil.copy2(exe, bin_dir / "ecos")
            shutil.copy2(tbb, bin_dir / "libtbb.so.12")
            env = tl.clean_env(home, TMPDIR=str(work))
            run = isolation.isolated(
                [loader, "--library-path", str(bin_dir), str(bin_dir / "ecos"), "simulate",
                 "--path", str(work / "loop"), *args],
                work,
                _hidden(clean_home, home),
            )  # fmt: skip
        proc = tl.run_clean(run, env, work)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        csvs.append((work / "loop.csv").read_bytes())
    assert csvs[0] == csvs[1]
    header, data = tl.read_ecos_csv(tmp_path / "isolated" / "loop.csv")
    assert len(data) >= 999 and np.ptp(data[:, header.index("plant::dphi[REAL]")]) > 0.1


def test_isolation_leaves_no_python(tmp_path):
    """The namespace the tests above run in has no working Python: the script refuses to run a
    command while one starts (checked here by hiding nothing)."""
    proc = tl.run_clean(
        isolation.isolated(["true"], tmp_path, []), tl.clean_env(tmp_path), tmp_path
    )
    assert proc.returncode == isolation.PYTHON_STILL_RUNS, proc.stderr
    hidden = _hidden(tmp_path)
    proc = tl.run_clean(
        isolation.isolated(["true"], tmp_path, hidden), tl.clean_env(tmp_path), tmp_path
    )
    assert proc.returncode == 0, proc.stderr


def test_an_older_glibc_is_refused_with_both_versions_named(self_contained, tmp_path):
    """A machine whose glibc is older than the bundle needs: a logged NULL from fmi2Instantiate
    naming both versions (the record's version raised to one no machine has)."""
    bundled = dataclasses.replace(
        self_contained.plant, unzipped=tl.unpack(self_contained.plant.fmu, tmp_path / "plant")
    )
    cfg = bundled.unzipped / "resources" / "drillstring_fmu_python.cfg"
    text = cfg.read_text()
    cfg.write_text(
        "\n".join("glibc 9.99" if x.startswith("glibc ") else x for x in text.splitlines())
    )
    exe = tl.compile_c_host(tmp_path)
    csv = tmp_path / "host.csv"
    units = dataclasses.replace(self_contained, plant=bundled)
    config = tl.host_config(units, {"plant": bundled.unzipped}, H_NS, 2, {}, csv, logging=True)
    proc, _ = tl.run_c_host(exe, config, tmp_path, tl.clean_env(tmp_path), csv)
    assert proc.returncode != 0
    assert "is older than glibc 9.99, the oldest the self-contained FMU's bundled Python" in (
        proc.stdout + proc.stderr
    )
