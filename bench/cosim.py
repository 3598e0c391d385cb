"""Benchmark of the co-simulation master.

1. Wall time per macro step of the fmpy master (:mod:`drillstring.orchestration.master`: its
   native loop, :mod:`drillstring.orchestration.native_loop`, and its Python loop) against
   libcosim (libcosimpy, in this process) on the same two FMUs, same connections, same start
   values and the same macro step H, side by side in one run. The per-step time is the slope of
   wall time against the number of steps (runs of N and 2N steps; instantiation and
   initialization cancel), the median over rounds that run them side by side. The last is a
   bare loop of the same FMI calls from Python (set, doStep, get through ctypes, no master
   logic): the FMUs' cost seen from Python, so that ``per-step time - bare loop`` is each
   master's overhead (negative for the native loop: it makes the same calls without ctypes).
2. The costs inside one macro step, from the bare loop with a timer around each call (the
   timer's own cost subtracted), over the second half of a run of 2N steps: the plant's
   ``fmi2DoStep`` against the engine's own advance over the same interval (the slope between N
   and 2N intervals, the same window): ``Engine.advance`` to each point of the grid of H from
   Python (the target's measure), and, for information, ``Engine.sample`` on that grid (the
   kernel filling the output rows, as the monolithic solver does); the controller's
   ``fmi2DoStep``, and the master's overhead per step (master - bare loop).
3. Total co-simulation time of the Fig. 5 case (tau in [0, 60], H = 1e-3), on the master's
   native loop and on its Python loop (``DRILLSTRING_MASTER_NATIVE=0``), against the monolithic
   twin of the same loop (sampled every 1e-3 and every 1e-2), interleaved rounds (the ratio to
   the monolithic run: the median of each round's ratio); and the same loop in the project's
   plain-C master (``tests/c_host/host.c``, a separate process: the time of its macro steps as
   it reports them, and of its whole process), which shows what the FMUs cost without a Python
   master.

Targets: per-step master overhead no worse than libcosim's; at H = 1e-3 a plant
``fmi2DoStep`` <= 2x the engine's advance over the same interval; the controller's
``fmi2DoStep`` <= 5 us; the Fig. 5 co-simulation <= 1.5x the monolithic run sampled at H. Run:
``.venv/bin/python bench/cosim.py [--fmus DIR | --gains G] [--H 1e-3] [--steps 2000]``
(without ``--fmus`` the FMUs are built into a temporary folder from ``--gains``, or from a gains
file designed first).
"""

from __future__ import annotations

import argparse
import ctypes
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from drillstring.apps.design import design_main
from drillstring.apps.export import build_fmus_into
from drillstring.model.engine import Engine
from drillstring.model.experiments import FIG5
from drillstring.orchestration import native_loop
from drillstring.orchestration.closed_loop import (
    SCALED,
    closed_loop_master,
    experiment_start_values,
    fmu_paths,
    kept_sys_path,
    read_loop_model,
    run_cosim,
)
from drillstring.orchestration.monolithic import run_monolithic


def _typed(md, starts: dict) -> list[tuple[str, int, object]]:
    """(FMI type, value reference, value) of each start value."""
    variables = {v.name: v for v in md.modelVariables}
    return [(variables[k].type, variables[k].valueReference, v) for k, v in starts.items()]


def libcosim_time(fmus: dict[str, Path], starts: dict[str, dict], H: float, n: int) -> float:
    """Wall time of a libcosim run of ``n`` steps (create, add, connect, initialize, step)."""
    from fmpy import read_model_description
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.ERROR)
    mds = {name: read_model_description(str(p)) for name, p in fmus.items()}
    vr = {name: {v.name: v.valueReference for v in md.modelVariables} for name, md in mds.items()}
    t0 = time.perf_counter()
    with kept_sys_path():
        ex = CosimExecution.from_step_size(step_size=round(H * 1e9))
        idx = {
            name: ex.add_local_slave(CosimLocalSlave(fmu_path=str(p), instance_name=name))
            for name, p in fmus.items()
        }
        for conn in SCALED.connections:
            src, dst = (s.strip().split(".", 1) for s in conn.split("->"))
            status = ex.connect_real_variables(
                idx[src[0]], vr[src[0]][src[1]], idx[dst[0]], vr[dst[0]][dst[1]]
            )
            if status != 0:
                raise RuntimeError(f"libcosim: cannot connect {conn}")
        setters = {
            "Real": ex.real_initial_value,
            "Integer": ex.integer_initial_value,
            "Boolean": ex.boolean_initial_value,
            "String": ex.string_initial_value,
        }
        for name, values in starts.items():
            for kind, ref, value in _typed(mds[name], values):
                if kind == "Enumeration":
                    continue  # libcosim sets no Enumeration; the latch does not change the cost
                if not setters[kind](idx[name], ref, value):
                    raise RuntimeError(f"libcosim: cannot set {name} vr {ref} = {value!r}")
        if not ex.step(n):
            raise RuntimeError("libcosim: step failed")
        del ex
    return time.perf_counter() - t0


HOST_C = Path(__file__).resolve().parents[1] / "tests" / "c_host" / "host.c"


def compile_c_host(out_dir: Path) -> Path | None:
    """The project's plain-C master (``tests/c_host/host.c``) compiled with ``cc -O2``, or None
    without a C compiler."""
    cc = shutil.which("cc")
    if cc is None:
        return None
    exe = out_dir / "host"
    subprocess.run([cc, "-std=c99", "-O2", "-o", str(exe), str(HOST_C), "-ldl"], check=True)
    return exe


def c_host_config(fmus: dict[str, Path], starts: dict[str, dict], H: float, work: Path) -> str:
    """The C host's configuration of the closed loop (no steps line: see :func:`c_host_time`),
    the FMUs unpacked under ``work``, ``dphi`` recorded."""
    from fmpy import extract, read_model_description

    lines = []
    vr = {}
    for name, path in fmus.items():
        md = read_model_description(str(path))
        folder = work / name
        if not folder.exists():
            extract(str(path), str(folder))
        lines.append(f"fmu {name} {md.coSimulation.modelIdentifier} {md.guid} {folder}")
        vr[name] = {v.name: v.valueReference for v in md.modelVariables}
        for kind, ref, value in _typed(md, starts.get(name, {})):
            word = {"Real": "real", "Integer": "integer", "Enumeration": "integer"}.get(kind)
            lines.append(f"{word or 'boolean'} {name} {ref} {float(value)!r}")
    for conn in SCALED.connections:
        src, dst = (s.strip().split(".", 1) for s in conn.split("->"))
        lines.append(f"connect {src[0]} {vr[src[0]][src[1]]} {dst[0]} {vr[dst[0]][dst[1]]}")
    lines += [
        f"record plant {vr['plant']['dphi']} dphi",
        f"step_ns {round(H * 1e9)}",
        f"csv {work / 'host.csv'}",
        "logging 0",
    ]
    return "\n".join(lines) + "\n"


def c_host_time(exe: Path, config: str, n: int, work: Path) -> tuple[float, float]:
    """(wall time of the C host's process, of its ``n`` macro steps as it reports them) [s]."""
    path = work / f"host_{n}.cfg"
    path.write_text(config + f"steps {n}\ntiming 1\n", encoding="utf-8")
    t0 = time.perf_counter()
    proc = subprocess.run([str(exe), str(path)], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    found = re.search(r"host: (\d+) macro steps in (\S+) s", proc.stderr)
    if proc.returncode != 0 or found is None or int(found.group(1)) != n:
        raise RuntimeError(f"C host failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return wall, float(found.group(2))


#: Calls timed one by one in the bare loop (``bare_loop``'s ``parts``).
PARTS = ("plant get", "controller set", "controller get", "plant set", "plant step",
         "controller step")  # fmt: skip


def _timer_cost(n: int = 20000) -> float:
    """Cost of one ``perf_counter_ns`` pair around nothing [s] (subtracted from each part)."""
    clock = time.perf_counter_ns
    total = 0
    for _ in range(n):
        t0 = clock()
        total += clock() - t0
    return total * 1e-9 / n


def bare_loop(master, H: float, n: int, timed_from: int | None = None):
    """``n`` Jacobi steps of the bare FMI calls (get x, set x, get R, set R, two doSteps
    through ctypes) on fresh instances of the master's extracted FMUs.

    Returns the wall time of the loop and, if ``timed_from`` is given, the summed time of each
    call of :data:`PARTS` over the steps ``k >= timed_from`` (each call then between two
    ``perf_counter_ns``; the caller subtracts :func:`_timer_cost`).
    """
    from fmpy.fmi2 import FMU2Slave

    sysm = master.system
    slaves = []
    with kept_sys_path():
        for i, (unit, md, unzip) in enumerate(
            zip(sysm.units, sysm.model_descriptions, master._unzipdirs, strict=True)
        ):
            fmu = FMU2Slave(
                guid=md.guid,
                unzipDirectory=unzip,
                modelIdentifier=md.coSimulation.modelIdentifier,
                instanceName=unit.name + "_bare",
            )
            fmu.instantiate()
            for name, value in unit.start_values.items():
                ref = sysm.variables[i][name]
                setter = "Integer" if ref.type == "Enumeration" else ref.type  # FMI 2.0
                getattr(fmu, f"set{setter}")([ref.vr], [value])
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            slaves.append(fmu)
        plant, ctrl = slaves
        P = sysm.variables[0]
        C = sysm.variables[1]
        vr_out = (ctypes.c_uint * 4)(*[P[n].vr for n in ("phi", "dphi", "theta", "dtheta")])
        vr_in = (ctypes.c_uint * 4)(*[C[n].vr for n in ("phi", "dphi", "theta", "dtheta")])
        vr_r = (ctypes.c_uint * 1)(C["R_minus_R0"].vr)
        vr_pr = (ctypes.c_uint * 1)(P["R_minus_R0"].vr)
        x = (ctypes.c_double * 4)()
        r = (ctypes.c_double * 1)()
        pc, cc = ctypes.c_void_p(plant.component), ctypes.c_void_p(ctrl.component)
        p_step, c_step = plant.dll.fmi2DoStep, ctrl.dll.fmi2DoStep  # typed by fmpy
        p_get, c_set = plant.dll.fmi2GetReal, ctrl.dll.fmi2SetReal
        c_get, p_set = ctrl.dll.fmi2GetReal, plant.dll.fmi2SetReal
        parts = dict.fromkeys(PARTS, 0)
        clock = time.perf_counter_ns
        first = n if timed_from is None else timed_from
        t0 = time.perf_counter()
        for k in range(first):
            t = k * H
            p_get(pc, vr_out, 4, x)
            c_set(cc, vr_in, 4, x)
            c_get(cc, vr_r, 1, r)
            p_set(pc, vr_pr, 1, r)
            if p_step(pc, t, H, 1) > 1 or c_step(cc, t, H, 1) > 1:
                raise RuntimeError(f"bare loop: doStep failed at t = {t}")
        for k in range(first, n):
            t = k * H
            a = clock()
            p_get(pc, vr_out, 4, x)
            b = clock()
            c_set(cc, vr_in, 4, x)
            c = clock()
            c_get(cc, vr_r, 1, r)
            d = clock()
            p_set(pc, vr_pr, 1, r)
            e = clock()
            sp = p_step(pc, t, H, 1)
            f = clock()
            sc = c_step(cc, t, H, 1)
            g = clock()
            if sp > 1 or sc > 1:
                raise RuntimeError(f"bare loop: doStep failed at t = {t}")
            parts["plant get"] += b - a
            parts["controller set"] += c - b
            parts["controller get"] += d - c
            parts["plant set"] += e - d
            parts["plant step"] += f - e
            parts["controller step"] += g - f
        wall = time.perf_counter() - t0
        for fmu in slaves:
            fmu.terminate()
            fmu.freeInstance()
    return wall, {name: v * 1e-9 for name, v in parts.items()}


def bare_loop_time(master, H: float, n: int) -> float:
    """Wall time of :func:`bare_loop` (no timers)."""
    return bare_loop(master, H, n)[0]


def use_loop(native: bool) -> None:
    """Make the master's next runs take its native loop or its Python loop."""
    os.environ[native_loop.ENV] = "1" if native else "0"


def _engine(model) -> Engine:
    return Engine(model.params, options=model.options, initial=model.initial, control=model.control)


def engine_advance_time(model, H: float, n: int) -> float:
    """Wall time of ``Engine.advance`` to ``H, 2H, ..., nH`` of the closed loop (the LMI law
    evaluated in the kernel), one call per interval, on a fresh engine (not timed)."""
    eng = _engine(model)
    advance = eng.advance
    t0 = time.perf_counter()
    for k in range(1, n + 1):
        status = advance(k * H)
    wall = time.perf_counter() - t0
    if not status.ok:
        raise RuntimeError(f"engine: {status.message}")
    return wall


def engine_sample_time(model, H: float, n: int) -> float:
    """Wall time of ``Engine.sample`` over the grid ``H, 2H, ..., nH`` of the closed loop (the
    kernel filling the output rows: the monolithic solver's own advance), on a fresh engine."""
    times = H * np.arange(1, n + 1)
    eng = _engine(model)
    t0 = time.perf_counter()
    _, status = eng.sample(times)
    wall = time.perf_counter() - t0
    if not status.ok:
        raise RuntimeError(f"engine: {status.message}")
    return wall


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gains", type=Path, default=None)
    ap.add_argument("--fmus", type=Path, default=None)
    ap.add_argument("--H", type=float, default=1e-3, help="macro step")
    ap.add_argument("--steps", type=int, default=2000, help="N (runs of N and 2N steps)")
    ap.add_argument("--repeat", type=int, default=7, help="interleaved rounds (median)")
    ap.add_argument("--fig5-repeat", type=int, default=3, help="rounds of the Fig. 5 totals")
    ap.add_argument("--tau-end", type=float, default=60.0, help="Fig. 5 horizon")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory(prefix="bench_cosim_") as tmp:
        fmus_dir = args.fmus
        if fmus_dir is None:
            gains_path = args.gains
            if gains_path is None:
                print("designing gains ...", flush=True)
                design_dir = Path(tmp) / "design"
                if design_main(["--out", str(design_dir)]) != 0:
                    return 1
                gains_path = design_dir / "gains.json"
            print("building the FMUs ...", flush=True)
            fmus_dir = build_fmus_into(Path(tmp) / "fmus", gains_path)
        H, n = args.H, args.steps
        plant_fmu, ctrl_fmu = fmu_paths(fmus_dir)
        fmus = {"plant": plant_fmu, "controller": ctrl_fmu}
        starts = experiment_start_values(FIG5)
        model = read_loop_model(fmus_dir, FIG5)
        T = args.tau_end
        with closed_loop_master(fmus_dir, FIG5, record=()) as master:
            run_cosim(master, 10 * H, H)  # warm-up (imports, numba kernel)
            libcosim_time(fmus, starts, H, 10)
            engine_advance_time(model, H, 10)
            engine_sample_time(model, H, 10)
            bare_loop(master, H, 20, timed_from=10)

            def master_time(k: int, native: bool = True) -> float:
                use_loop(native)
                return run_cosim(master, k * H, H).stats.wall_time

            use_loop(False)
            run_cosim(master, 10 * H, H)
            if native_loop.library() is None:
                print("no C compiler: the native loop's rows are the Python loop's")

            # 1. per macro step: the three side by side, and the engine's own advance
            rows = {
                "master": master_time,
                "master (Python loop)": lambda k: master_time(k, False),
                "libcosim": lambda k: libcosim_time(fmus, starts, H, k),
                "bare FMI": lambda k: bare_loop_time(master, H, k),
                "engine advance": lambda k: engine_advance_time(model, H, k),
                "engine sample": lambda k: engine_sample_time(model, H, k),
            }
            # 2. the calls inside a macro step (second half of runs of 2N steps), in the same
            # rounds: a load spike on the shared machine hits one round, not one contestant
            tick = _timer_cost()
            slopes: dict[str, list[float]] = {name: [] for name in rows}
            part_runs: dict[str, list[float]] = {name: [] for name in PARTS}
            for _ in range(args.repeat):
                for name, fn in rows.items():
                    t1, t2 = fn(n), fn(2 * n)
                    slopes[name].append((t2 - t1) / n)
                _, parts = bare_loop(master, H, 2 * n, timed_from=n)
                for name in PARTS:
                    part_runs[name].append(parts[name] / n - tick)
            per_step = {name: statistics.median(v) for name, v in slopes.items()}
            part = {name: statistics.median(v) for name, v in part_runs.items()}
            bare = per_step["bare FMI"]
            eng, eng_grid = per_step["engine advance"], per_step["engine sample"]

            print(
                f"\nper macro step, H = {H:g}, slope over {n} -> {2 * n} steps, median of "
                f"{args.repeat} interleaved rounds:"
            )
            print(f"{'':>20} {'us/step':>9} {'overhead us':>12}")
            for name in ("master", "master (Python loop)", "libcosim"):
                print(
                    f"{name:>20} {per_step[name] * 1e6:9.1f} {(per_step[name] - bare) * 1e6:12.1f}"
                )
            print(f"{'bare FMI':>20} {bare * 1e6:9.1f} {0.0:12.1f}")
            over_l = per_step["libcosim"] - bare
            for name in ("master", "master (Python loop)"):
                over = per_step[name] - bare
                verdict = "meets" if over <= over_l else "misses"
                print(
                    f"{name} / libcosim per step: {per_step[name] / per_step['libcosim']:.3f}; "
                    f"overhead {over * 1e6:.1f} us vs libcosim {over_l * 1e6:.1f} us: {verdict} "
                    "the target"
                )

            print(
                f"\ninside a macro step (each call timed, timer cost {tick * 1e9:.0f} ns "
                f"subtracted; steps {n} -> {2 * n}, median of {args.repeat} rounds):"
            )
            for name in PARTS:
                print(f"{name:>16} {part[name] * 1e6:8.2f} us")
            print(f"{'engine advance':>16} {eng * 1e6:8.2f} us  (Engine.advance per interval H)")
            print(
                f"{'engine sample':>16} {eng_grid * 1e6:8.2f} us  (Engine.sample, per interval H)"
            )
            p_ratio = part["plant step"] / eng
            print(
                f"plant fmi2DoStep / Engine.advance = {p_ratio:.2f} (target <= 2: "
                f"{'meets' if p_ratio <= 2.0 else 'misses'}); / Engine.sample = "
                f"{part['plant step'] / eng_grid:.2f}"
            )
            c_us = part["controller step"] * 1e6
            print(
                f"controller fmi2DoStep = {c_us:.2f} us (target <= 5 us: "
                f"{'meets' if c_us <= 5.0 else 'misses'})"
            )
            over_py = per_step["master (Python loop)"] - bare
            print(
                f"the Python loop's overhead per step = {over_py * 1e6:.1f} us = "
                f"{over_py / per_step['master (Python loop)']:.0%} of its step; the native loop's "
                f"whole step {per_step['master'] * 1e6:.2f} us"
            )

            # 3. Fig. 5 totals, interleaved with the monolithic runs and the C host's
            n_fig5 = round(T / H)
            work = Path(tmp) / "c_host"
            work.mkdir()
            exe = compile_c_host(work)
            config = c_host_config(fmus, starts, H, work) if exe is not None else ""
            if exe is not None:
                c_host_time(exe, config, 10, work)  # warm-up
            walls: dict[str, list[float]] = {
                key: []
                for key in ("cosim", "cosim Py", "mono H", "mono 1e-2", "C host", "C host steps")
            }
            steps = 0
            for _ in range(args.fig5_repeat):
                for key, native in (("cosim", True), ("cosim Py", False)):
                    use_loop(native)
                    res = run_cosim(master, T, H)
                    if not res.completed:
                        print(f"Fig. 5 co-simulation failed: {res.failure}", file=sys.stderr)
                        return 1
                    walls[key].append(res.stats.wall_time)
                    steps = res.stats.accepted
                for key, dt in (("mono H", H), ("mono 1e-2", 1e-2)):
                    t0 = time.perf_counter()
                    run_monolithic(model, T, dt_out=dt)
                    walls[key].append(time.perf_counter() - t0)
                if exe is not None:
                    process, loop = c_host_time(exe, config, n_fig5, work)
                    walls["C host"].append(process)
                    walls["C host steps"].append(loop)
        w = {key: statistics.median(v) for key, v in walls.items() if v}
        cos, py = w["cosim"], w["cosim Py"]
        print(
            f"\nFig. 5, tau in [0, {T:g}], H = {H:g}, median of {args.fig5_repeat} interleaved "
            f"rounds: co-simulation on the native loop {cos:.3f} s ({steps} steps, "
            f"{cos / steps * 1e6:.2f} us/step), on the Python loop {py:.3f} s "
            f"({py / steps * 1e6:.2f} us/step)"
        )
        for key, dt in (("mono H", H), ("mono 1e-2", 1e-2)):
            print(
                f"  monolithic sampled every {dt:g}: {w[key]:.3f} s -> co-simulation / "
                f"monolithic = {cos / w[key]:.2f} (native loop), {py / w[key]:.2f} (Python loop)"
            )
        # ratios of the same round first (a load spike hits both runs of a round), then medians
        r5 = statistics.median(c / m for c, m in zip(walls["cosim"], walls["mono H"], strict=True))
        r5py = statistics.median(
            c / m for c, m in zip(walls["cosim Py"], walls["mono H"], strict=True)
        )
        print(
            f"Fig. 5 co-simulation / monolithic at the same sampling, median of the rounds' "
            f"ratios = {r5:.2f} on the native loop (target <= 1.5: "
            f"{'meets' if r5 <= 1.5 else 'misses'}), {r5py:.2f} on the Python loop"
        )
        if "C host" in w:
            loop = w["C host steps"]
            rc = loop / w["mono H"]
            print(
                f"the same loop in the plain-C master (tests/c_host/host.c, macro steps timed by "
                f"the host): {loop:.3f} s, {loop / n_fig5 * 1e6:.2f} us/step -> / monolithic = "
                f"{rc:.2f} ({'meets' if rc <= 1.5 else 'misses'} 1.5); its whole process "
                f"{w['C host']:.2f} s (Python started, packages imported, the FMUs set up)"
            )
        else:
            print("no C compiler (cc): the plain-C master's row is not measured")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
