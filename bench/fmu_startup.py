"""Benchmark of the FMUs in independent hosts: cold start, cost per step, the front layer's cost.

1. **Cold start**: a fresh process on a freshly unpacked plant FMU, to the end of its first
   ``fmi2DoStep`` (the process's wall time for 10 steps, exit included: an upper bound; see
   ``COLD_STEPS``), in the project's C host
   (no Python in the process: the FMU starts it), fmpy (a Python process) and the ``ecos simulate``
   command line (which unpacks anew on every run). All in the clean environment of the tests
   (``env -i`` with PATH, HOME, LANG, OPENBLAS_*), after one run that compiled the kernel into
   that HOME's cache (its time is printed too). Target: <= 1.5 s.
2. **Cost per macro step** of the plant (H = 0.01, input 0, outputs read every step) in each
   host: the slope of wall time between runs of N1 and N2 steps (start-up cancels).
3. **What the front layer adds per fmi2DoStep**: ``bench/fmu_overhead.c`` steps two instances of
   the same FMU in one process, one through the front layer, one through pythonfmu's library
   directly, in alternating blocks. Target: <= 2 us.

Runs are interleaved (host A, B, C, A, B, C, ...) and medians quoted. Run:
``.venv/bin/python bench/fmu_startup.py [--rounds 7]``
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import fmu_testlib as tl  # noqa: E402  (the tests' helpers: build, hosts, clean environment)

H = 0.01
#: Steps of a cold-start run: the first step and nine more (a few ms): ``ecos simulate`` stops
#: with SIGFPE for fewer than 10 steps (it reports progress every numSteps / 10 steps).
COLD_STEPS = 10

FMPY_SCRIPT = textwrap.dedent(
    """
    import os, sys, tempfile
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    fmu, n = sys.argv[1], int(sys.argv[2])
    md = read_model_description(fmu)
    unzipped = extract(fmu, tempfile.mkdtemp())
    vrs = [v.valueReference for v in md.modelVariables
           if v.causality == "output" and v.type == "Real"]
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    for k in range(n):
        s.doStep(k * 0.01, 0.01)
        s.getReal(vrs)
    sys.stdout.flush()
    os._exit(0)
    """
)


def _wall(cmd: list[str], env: dict[str, str], cwd: Path) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd, timeout=900)
    elapsed = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{cmd[0]} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return elapsed


class Hosts:
    """The three hosts, each run on a fresh unpack (or a fresh copy the host unpacks itself)."""

    def __init__(self, built: tl.Built, work: Path, env: dict[str, str]) -> None:
        self.built, self.work, self.env = built, work, env
        self.host = tl.compile_c_host(work)
        self.n = 0

    def _fresh(self) -> Path:
        self.n += 1
        folder = self.work / f"run{self.n}"
        folder.mkdir()
        return folder

    def c_host(self, steps: int) -> float:
        folder = self._fresh()
        unzipped = tl.unpack(self.built.plant.fmu, folder / "plant")
        csv = folder / "out.csv"
        config = tl.host_config(self.built, {"plant": unzipped}, 10_000_000, steps, {}, csv)
        (folder / "host.cfg").write_text(config)
        return _wall([str(self.host), str(folder / "host.cfg")], self.env, folder)

    def fmpy(self, steps: int) -> float:
        folder = self._fresh()
        env = {**self.env, "TMPDIR": str(folder)}
        cmd = [sys.executable, "-c", FMPY_SCRIPT, str(self.built.plant.fmu), str(steps)]
        return _wall(cmd, env, folder)

    def ecos(self, steps: int) -> float:
        folder = self._fresh()
        env = {**self.env, "TMPDIR": str(folder)}
        stop = repr(steps * H + H / 2)  # Ecos steps while t + h <= stopTime
        cmd = tl.ecos_command(
            "simulate", "--path", str(self.built.plant.fmu), "--stepSize", repr(H),
            "--stopTime", stop,
        )  # fmt: skip
        return _wall(cmd, env, folder)


def _overhead(built: tl.Built, work: Path, unit: tl.Unit, blocks: int, steps: int):
    exe = work / "fmu_overhead"
    if not exe.exists():
        tl.compile_c_program(ROOT / "bench" / "fmu_overhead.c", work, "-std=gnu11", "-ldl")
    # a plain folder name: the direct calls give pythonfmu's library the resource URI as it is,
    # and it cannot decode a percent-encoded one (one of the things the layer is for)
    plain = work / "plain" / unit.model
    if not plain.exists():
        with zipfile.ZipFile(unit.fmu) as z:
            z.extractall(plain)
    out = subprocess.run(
        [str(exe), str(plain), unit.model, unit.guid, str(blocks), str(steps)],
        capture_output=True, text=True, check=True, timeout=900,
    ).stdout.split()  # fmt: skip
    pairs = list(zip(out[::2], out[1::2], strict=True))[2:]  # the first block pair warms up
    layer = [float(v) for k, v in pairs if k == "layer"]
    direct = [float(v) for k, v in pairs if k == "direct"]
    diffs = [a - b for a, b in zip(layer, direct, strict=True)]
    return statistics.median(layer), statistics.median(direct), statistics.median(diffs)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=7, help="interleaved rounds (default 7)")
    ap.add_argument("--n1", type=int, default=100, help="short run, steps (default 100)")
    ap.add_argument("--n2", type=int, default=20100, help="long run, steps (default 20100)")
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="fmu_startup_") as tmp:
        work = Path(tmp)
        built = tl.bench_build(work)
        home = work / "home"
        home.mkdir()
        hosts = Hosts(built, work, tl.clean_env(home))
        first = hosts.c_host(COLD_STEPS)
        print(
            f"first run on this machine (C host, empty cache: compiles the kernel): {first:.2f} s"
        )

        names = ("C host", "fmpy", "ecos CLI")
        runs = (hosts.c_host, hosts.fmpy, hosts.ecos)
        cold: dict[str, list[float]] = {n: [] for n in names}
        slope: dict[str, list[float]] = {n: [] for n in names}
        for _ in range(args.rounds):
            for name, run in zip(names, runs, strict=True):
                cold[name].append(run(COLD_STEPS))
            for name, run in zip(names, runs, strict=True):
                t1, t2 = run(args.n1), run(args.n2)
                slope[name].append((t2 - t1) / (args.n2 - args.n1))

        print(f"\nplant FMU, fresh process and fresh unpack, {args.rounds} interleaved rounds")
        print(f"{'host':<10} {'cold start to 1st step [s]':>27} {'per macro step [us]':>21}")
        for name in names:
            c = statistics.median(cold[name])
            s = 1e6 * statistics.median(slope[name])
            print(f"{name:<10} {c:>27.3f} {s:>21.1f}")
        print("target: cold start <= 1.5 s")

        print("\nfront layer vs pythonfmu's library directly, per fmi2DoStep (medians of blocks)")
        print(f"{'FMU':<20} {'layer [us]':>11} {'direct [us]':>12} {'added [us]':>11}")
        for unit, steps in ((built.controller, 4000), (built.plant, 1000)):
            layer, direct, added = _overhead(built, work, unit, 21, steps)
            print(
                f"{unit.model:<20} {layer / 1e3:>11.2f} {direct / 1e3:>12.2f} {added / 1e3:>11.3f}"
            )
        print("target: added <= 2 us")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
