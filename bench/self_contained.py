"""Benchmark of the self-contained FMUs (``build_fmus.py --self-contained``) against the normal
ones: size, unpacking, cold start on a machine without Python, cost per step.

1. **Size** of the plant FMU, archive and unpacked.
2. **Unpacking** the archive (``fmpy.extract``), which a host does once per FMU (``ecos
   simulate`` on every run).
3. **Cold start to the first step**: a fresh process on a freshly unpacked plant FMU, to the end
   of the process after 10 steps (an upper bound), in the project's C host; the unpacking is not
   included (item 2). The normal FMU runs in the tests' clean environment with its kernel
   compiled before (a machine it was built on); the self-contained one in isolation
   (``tests/isolation.py``: no Python installation, virtual environment, checkout or cache
   visible) with an empty HOME on every run (its package is copied into the cache and the
   bundled kernel loaded: the first run on a new machine) and with the HOME of the run before
   (a later run). Target: <= 2 s for the first run on a new machine.
4. **Cost per macro step** (H = 0.01, plant alone): the slope of wall time between runs of N1 and
   N2 steps; the self-contained kernel is compiled for a generic x86-64 CPU.

Runs are interleaved and medians quoted. Run: ``.venv/bin/python bench/self_contained.py
[--rounds 5]`` (builds the FMUs first, then compiles the generic kernel: a few minutes).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import fmu_testlib as tl  # noqa: E402  (the tests' helpers: build, hosts, clean environment)
import isolation  # noqa: E402  (a command run as on another machine)

from drillstring.apps.export.self_contained import self_contained_fmus  # noqa: E402

COLD_STEPS = 10


def _size(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


class Runner:
    """Fresh unpack folders and C host runs of one plant FMU."""

    def __init__(self, unit: tl.Unit, work: Path, isolated: bool) -> None:
        self.unit, self.work, self.isolated = unit, work, isolated
        work.mkdir(parents=True)
        self.exe = tl.compile_c_host(work)
        self.n = 0
        self.unpack_times: list[float] = []
        self.home = work / "home"
        self.home.mkdir()

    def run(self, steps: int, fresh_home: bool, may_compile: bool = False) -> float:
        self.n += 1
        folder = self.work / f"run{self.n}"
        t0 = time.perf_counter()
        unzipped = tl.unpack(self.unit.fmu, folder / "plant")
        self.unpack_times.append(time.perf_counter() - t0)
        built = tl.Built(plant=self.unit, controller=self.unit, gains=folder, out=folder)
        csv = folder / "out.csv"
        config = tl.host_config(
            built, {"plant": unzipped}, 10_000_000, steps, {}, csv, logging=True
        )
        (folder / "host.cfg").write_text(config)
        home = folder / "home" if fresh_home else self.home
        home.mkdir(exist_ok=True)
        cmd = [str(self.exe), str(folder / "host.cfg")]
        if self.isolated:
            hidden = [*isolation.python_installations(), isolation.ROOT]
            cmd = isolation.isolated(cmd, folder, [*hidden, *isolation.user_caches()])
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, env=tl.clean_env(home))
        elapsed = time.perf_counter() - t0
        compiled = "numba compiled" in proc.stdout + proc.stderr
        if proc.returncode != 0 or (compiled and not may_compile):
            raise RuntimeError(f"run {self.n} failed or compiled:\n{proc.stderr[-3000:]}")
        return elapsed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5, help="interleaved rounds (default 5)")
    ap.add_argument("--n1", type=int, default=100, help="short run, steps (default 100)")
    ap.add_argument("--n2", type=int, default=20100, help="long run, steps (default 20100)")
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="self_contained_") as tmp:
        work = Path(tmp)
        built = tl.bench_build(work)
        t0 = time.perf_counter()
        fmus = self_contained_fmus(
            {u.model: u.fmu for u in (built.plant, built.controller)}, work / "sc"
        )
        print(f"self-contained plant and controller made in {time.perf_counter() - t0:.0f} s")
        units = {
            "normal": built.plant,
            "self-contained": tl._unit(tl.PLANT, fmus[tl.PLANT], work / "u-sc"),
        }
        for kind, unit in units.items():
            print(
                f"{kind:<15} archive {unit.fmu.stat().st_size / 2**20:7.1f} MiB, "
                f"unpacked {_size(unit.unzipped) / 2**20:7.1f} MiB"
            )
        runners = {
            "normal": Runner(units["normal"], work / "normal", isolated=False),
            "self-contained": Runner(units["self-contained"], work / "sc-run", isolated=True),
        }
        first = runners["normal"].run(COLD_STEPS, fresh_home=False, may_compile=True)
        print(f"normal plant, first run on this machine (compiles the kernel): {first:.1f} s")
        for steps in (args.n1, args.n2):  # the Python path's step too (the normal FMU compiles)
            runners["normal"].run(steps, fresh_home=False, may_compile=True)
        runners["self-contained"].run(COLD_STEPS, fresh_home=False)  # fills its HOME's cache
        rows = {"normal": [], "self-contained, new machine": [], "self-contained, later run": []}
        slope: dict[str, list[float]] = {"normal": [], "self-contained": []}
        for _ in range(args.rounds):
            rows["normal"].append(runners["normal"].run(COLD_STEPS, fresh_home=False))
            sc = runners["self-contained"]
            rows["self-contained, new machine"].append(sc.run(COLD_STEPS, fresh_home=True))
            rows["self-contained, later run"].append(sc.run(COLD_STEPS, fresh_home=False))
            for kind, runner in runners.items():
                t1 = runner.run(args.n1, fresh_home=False)
                t2 = runner.run(args.n2, fresh_home=False)
                slope[kind].append((t2 - t1) / (args.n2 - args.n1))

        print(f"\nplant FMU in the C host, {args.rounds} interleaved rounds (medians)")
        for kind, runner in runners.items():
            print(f"unpacking ({kind}): {statistics.median(runner.unpack_times):.2f} s")
        print(f"{'run':<30} {'cold start to the 1st step [s]':>31}")
        for name, times in rows.items():
            print(f"{name:<30} {statistics.median(times):>31.3f}")
        print("target: <= 2 s on a new machine")
        print(f"\n{'FMU':<30} {'per macro step [us]':>31}")
        for kind, values in slope.items():
            print(f"{kind:<30} {1e6 * statistics.median(values):>31.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
