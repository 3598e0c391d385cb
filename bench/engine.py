"""Benchmark of the stepping engine: kernel, work-precision, sampling, plain Python, prehistory.

Run: ``.venv/bin/python bench/engine.py`` (about 3 minutes; ``--quick`` for a shorter pass).
Every comparison is measured side by side in this run (interleaved rounds, medians):

1. Kernel per RK4 step against a minimal compiled loop of the same work (``minimal_loop.py``),
   on a smooth run without mode events: the stable axial set (taubar_n0 = 0.5 taubar_crit, the
   axial kick of ``tests/test_engine.py``), u(0) = 1e-4, dphi/dtau(0) = -0.5, tau in [0, 20],
   h = 5e-4. Target: ratio <= 2. Also the RK4 trials per event location (target <= 8).
   The ratio depends on the machine's load: on the shared 2-core machine a whole process
   sees either about 1.55 (kernel ~275 ns, minimal loop ~178 ns) or, while other jobs run,
   up to 2.0 (kernel ~370 ns, the minimal loop nearly unchanged); it is not the memory
   layout (the same with address randomisation off and a fixed hash seed).
2. Work-precision of Fig. 5 (``drillstring.model.experiments.FIG5``, tau in [0, 60]) closed
   with the paper's gain and K0 of the averaged model at A = 0.3855 (``docs/model.md``,
   "Equation (30)"), and open (R = R0): max error of du/dtau and dphi/dtau on the output grid
   (every 0.01) against a run at h = 2.5e-5/4, and wall time of ``simulate``, for h from 8e-3
   to 2.5e-5; the same for v0.1 (commit ``OLD_COMMIT``, run from ``git archive`` in a subprocess
   of this interpreter). Target: at each accuracy from 1e-4 to 1e-8 (log-log interpolation of
   the curves) the engine is at least 1.5x faster than v0.1. The engine lands on every output
   sample, so for h > 0.005 both take two steps per sample.
3. Sampling: overhead per output sample, the run of 1. sampled every h against one sample.
   Target: <= 1 us.
4. Plain Python (``DRILLSTRING_JIT=0``): cost per step and bit-identity with the compiled
   kernel on a short Fig. 5 closed-loop run with events.
5. Prehistory: building the engine at h = 1.25e-5 (nominal history).
6. The distributed string (``docs/model.md``, "The distributed string"): cost per step and per
   Fig. 6 open-loop run (dphi/dtau(0) = -4.9, torsional stick, tau in [0, 60], R - R0 = 0: the
   stick-slip before the switch-on, throughout) for N = 1, 4, 16, 64 and for the N at which the
   second torsional mode is within 1 % of the continuous string's (``drillstring.analysis.
   modes``), interleaved rounds, medians, each against N = 1. Targets: cost linear in N, the
   run at the 1 % N at most 5x the N = 1 run.

v0.1 is run live from the repository's history in a subprocess of this interpreter (its
sources only; it needs nothing this environment lacks), so every run prints both side by side.
For reference, v0.1 as measured by this script on the shared 2-core machine (1 Dec 2026, medians
of 3; error: max of du/dtau, dphi/dtau against h = 6.25e-6):

=========  ==================  ==================
h          Fig. 5 closed loop  open loop
           wall s   error      wall s   error
=========  ==================  ==================
8e-3       0.120    8.83e-3    0.175    4.37e-2
4e-3       0.104    1.71e-3    0.199    5.88e-3
2e-3       0.210    2.31e-4    0.211    6.60e-4
1e-3       0.279    1.52e-5    0.222    4.07e-5
5e-4       0.507    9.73e-7    0.287    2.48e-6
2.5e-4     0.811    6.72e-8    0.531    2.19e-7
1.25e-4    1.542    4.84e-9    1.617    4.92e-8
5e-5       3.772    1.87e-8    3.781    1.64e-7
2.5e-5     4.700    4.55e-8    8.022    6.46e-7
=========  ==================  ==================

and: 10.6 us of overhead per output sample, Engine() at h = 1.25e-5 in 62 ms. (v0.1's errors
grow again below h = 1.25e-4: it labels each step's end tau + h, rounded, so the rounding
accumulates; the engine computes each step's end from the interval's end.)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from minimal_loop import minimal_loop

from drillstring.analysis.axial_stability import critical_delay
from drillstring.analysis.modes import torsional_elements_needed
from drillstring.controller.averaged import averaged_model
from drillstring.controller.gains import PAPER_F
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import Engine, EngineOptions
from drillstring.model.experiments import FIG5
from drillstring.model.kernel.jit import numba_available
from drillstring.model.kernel.state import H_ROWS, I_HEND, I_KHINT, K_NOW
from drillstring.model.params import REFERENCE, ScaledParams
from drillstring.model.pipe import REFERENCE_KAPPA, StringParams
from drillstring.model.prehistory import build_prehistory, nominal_history
from drillstring.model.simulate import SimulationResult, simulate

REPO = Path(__file__).resolve().parent.parent
#: v0.1: the version before the speed work, compared side by side.
OLD_COMMIT = "9cc60e0"
#: Slope of the averaged contact force at the reference set (docs/model.md, "Equation (30)").
A_REF = 0.3855
STEPS = (8e-3, 4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4, 5e-5, 2.5e-5)
H_REFERENCE = 2.5e-5 / 4
ACCURACIES = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
#: The smooth run of sections 1 and 3.
SMOOTH_T, SMOOTH_H, SMOOTH_INITIAL = 20.0, 5e-4, {"u": 1e-4, "dphi": -0.5}


def stable_axial_set() -> ScaledParams:
    """The reference set with omega0 such that taubar_n0 = 0.5 taubar_crit (no stick-slip)."""
    p = REFERENCE
    taubar = 0.5 * critical_delay(p.gammabar, p.etabar2)
    return p.replace(omega0=2 * math.pi / (p.n * taubar / p.sqrt_npsi))


def fig5_law() -> AffineFeedback:
    """The paper's gain with K0 of the averaged model, feed-forward R_ff = -K0 (31)."""
    p = REFERENCE
    K0 = averaged_model(p, A_REF, critical_delay(p.gammabar, p.etabar2)).K0
    return AffineFeedback(PAPER_F, K0, -K0)


def median_of(fn: Callable[[], float], rounds: int) -> float:
    return float(np.median([fn() for _ in range(rounds)]))


# ------------------------------------------------------------------ 1. kernel vs minimal loop
#: Chunks of the smooth run timed one by one (about 0.3 ms each: the median over chunks is
#: robust to the other processes of a shared machine).
CHUNK = 0.5


def kernel_vs_minimal(rounds: int) -> float:
    """Time the kernel and the minimal loop chunk by chunk, interleaved; returns the ratio.

    Both start from the kernel's state after the first chunk (past the delayed discontinuity
    of the joint at tau = 0, which only the kernel handles), and must then agree bit for bit.
    """
    p = stable_axial_set()
    opts = EngineOptions(h=SMOOTH_H)
    pm = (float(p.n), p.n * p.psi, p.gamma, p.eta, p.v0, p.d0, p.rho, 2 * math.pi / p.n)
    n_chunks = int(round(SMOOTH_T / CHUNK))
    t_min, t_ker = [], []
    identical = True
    gap = 0.0
    for _ in range(rounds + 1):  # the first round loads the code
        engine = Engine(p, opts, initial=SMOOTH_INITIAL)
        engine.advance(CHUNK)
        s = engine._s
        end, hint = int(s.ints[I_HEND]), int(s.ints[I_KHINT])
        # the whole buffer written before the timing (as the kernel's reused buffer is)
        H = np.full((H_ROWS, end + int(SMOOTH_T / SMOOTH_H) + 16), np.nan)
        H[:, :end] = s.history[:, :end]
        y0 = tuple(float(v) for v in s.y)
        f0 = tuple(float(v) for v in s.stages[K_NOW])
        state = (engine.tau, y0, f0, end, hint)
        per_min, per_ker = [], []
        for j in range(2, n_chunks + 1):
            t0 = time.perf_counter()
            state, steps = minimal_loop(pm, H, state, j * CHUNK, SMOOTH_H)
            t1 = time.perf_counter()
            before = engine.counters["steps"]
            engine.advance(j * CHUNK)
            t2 = time.perf_counter()
            per_min.append((t1 - t0) / steps)
            per_ker.append((t2 - t1) / (engine.counters["steps"] - before))
            y_min = np.array(state[1])
            identical &= state[0] == engine.tau and np.array_equal(y_min, engine.total_state())
            gap = max(gap, float(np.max(np.abs(y_min - engine.total_state()))))
        t_min.append(per_min)
        t_ker.append(per_ker)
    m, k = np.median(t_min[1:]), np.median(t_ker[1:])
    c = engine.counters
    print("\n1. Kernel per RK4 step against the minimal loop of the same work")
    print(
        f"   smooth run: {c['steps']} steps, {c['events']} mode events, "
        f"{c['event_locations']} delayed discontinuity located (in the first chunk); medians "
        f"over {rounds} x {n_chunks - 1} chunks of {int(CHUNK / SMOOTH_H)} steps"
    )
    print(
        f"   minimal loop {m * 1e9:6.1f} ns/step, kernel {k * 1e9:6.1f} ns/step: "
        f"ratio {k / m:.2f} (target <= 2)"
    )
    print(
        f"   same trajectory from tau = {CHUNK:g}: state at every chunk end bit-identical: "
        f"{identical} (max difference {gap:.1e})"
    )
    return float(k / m)


def trials_per_location(result) -> str:
    c = result.counters
    return f"{c['event_trials'] / max(c['event_locations'], 1):.2f}"


# ------------------------------------------------------------------ 2. work-precision
WORKER = r"""
import json, sys, time
import numpy as np
import drillstring
assert drillstring.__file__.startswith(sys.argv[1]), drillstring.__file__
from drillstring.control_law import AffineFeedback
from drillstring.engine import Engine, EngineOptions
from drillstring.params import ScaledParams
from drillstring.simulate import simulate

for line in sys.stdin:
    req = json.loads(line)
    p = ScaledParams(**req["params"])
    opts = EngineOptions(h=req["h"])
    if req["kind"] == "engine":
        t0 = time.perf_counter()
        Engine(p, opts, initial=req["initial"])
        print(json.dumps({"wall": time.perf_counter() - t0}), flush=True)
        continue
    law = req["law"]
    control = None if law is None else AffineFeedback(tuple(law[0]), law[1], law[2])
    t0 = time.perf_counter()
    r = simulate(p, req["tau_end"], control=control, initial=req["initial"],
                 dt_out=req["dt_out"], options=opts, progress=False)
    wall = time.perf_counter() - t0
    np.save(req["out"], np.vstack([r.tau, r.du, r.dphi]))
    print(json.dumps({"wall": wall, "status": r.status.code, "steps": r.counters["steps"]}),
          flush=True)
"""


class OldEngine:
    """v0.1's engine in a subprocess (``git archive OLD_COMMIT drillstring``)."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        archive = subprocess.run(
            ["git", "-C", str(REPO), "archive", OLD_COMMIT, "drillstring"],
            check=True,
            capture_output=True,
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(folder)], input=archive, check=True)
        env = {**os.environ, "PYTHONPATH": str(folder)}
        self.proc = subprocess.Popen(
            [sys.executable, "-c", WORKER, str(folder)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env=env,
            cwd=folder,
        )
        self.n = 0

    def request(self, **req) -> dict:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(json.dumps(req) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError("the v0.1 engine worker died")
        return json.loads(line)

    def simulate(self, case: dict, h: float, dt_out: float) -> tuple[float, np.ndarray | None]:
        self.n += 1
        out = self.folder / f"run{self.n}.npy"
        reply = self.request(kind="simulate", h=h, dt_out=dt_out, out=str(out), **case)
        data = np.load(out) if reply["status"] == "ok" else None
        return reply["wall"], data

    def close(self) -> None:
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        self.proc.wait(timeout=60)


def new_simulate(case: dict, h: float, dt_out: float) -> tuple[float, np.ndarray | None, object]:
    law = case["law"]
    control = None if law is None else AffineFeedback(tuple(law[0]), law[1], law[2])
    t0 = time.perf_counter()
    r = simulate(
        ScaledParams(**case["params"]),
        case["tau_end"],
        control=control,
        initial=case["initial"],
        dt_out=dt_out,
        options=EngineOptions(h=h),
        progress=False,
    )
    wall = time.perf_counter() - t0
    data = np.vstack([r.tau, r.du, r.dphi]) if r.status.ok else None
    return wall, data, r


def error(data: np.ndarray | None, ref: np.ndarray) -> float:
    if data is None or data.shape != ref.shape:
        return math.inf
    return float(max(np.max(np.abs(data[1] - ref[1])), np.max(np.abs(data[2] - ref[2]))))


def wall_at(accuracy: float, errs: list[float], walls: list[float]) -> float:
    """Wall time to reach ``accuracy``, interpolated log-log along the curve (h decreasing).

    The curve is made monotone (the best error so far); an accuracy above the coarsest error
    costs the coarsest run; one never reached is inf.
    """
    e = np.minimum.accumulate(np.asarray(errs, dtype=float))
    w = np.asarray(walls, dtype=float)
    if accuracy >= e[0]:
        return float(w[0])
    for i in range(1, len(e)):
        if e[i] <= accuracy:
            if not math.isfinite(e[i - 1]) or e[i - 1] == e[i]:
                return float(w[i])
            x = (math.log(accuracy) - math.log(e[i - 1])) / (math.log(e[i]) - math.log(e[i - 1]))
            return float(math.exp(math.log(w[i - 1]) + x * (math.log(w[i]) - math.log(w[i - 1]))))
    return math.inf


def work_precision(
    old: OldEngine | None, steps: tuple[float, ...], rounds: int
) -> tuple[float, float]:
    """Print the work-precision tables; return the smallest speed-up over v0.1 at the
    accuracies of ``ACCURACIES`` (nan without v0.1) and the mean RK4 trials per event
    location over all runs."""
    params = {f.name: getattr(REFERENCE, f.name) for f in dataclasses.fields(REFERENCE)}
    law = fig5_law()
    base = {"params": params, "tau_end": FIG5.tau_end, "initial": dict(FIG5.initial())}
    cases = {
        "Fig. 5 closed loop": {**base, "law": [list(law.F), law.K0, law.R_ff]},
        "open loop": {**base, "law": None},
    }
    dt_out = 1e-2
    print(
        f"\n2. Work-precision over tau in [0, {FIG5.tau_end:g}]: max error of du/dtau, dphi/dtau "
        f"(every {dt_out:g}) against h = {H_REFERENCE:.3g}; wall s = median of {rounds}"
    )
    speedups: list[float] = []
    trials = locations = 0
    for name, case in cases.items():
        _, ref, rref = new_simulate(case, H_REFERENCE, dt_out)
        trials += rref.counters["event_trials"]
        locations += rref.counters["event_locations"]
        assert ref is not None, rref.status
        rows = []
        for h in steps:
            walls, walls_old = [], []
            for _ in range(rounds):
                w, data, r = new_simulate(case, h, dt_out)
                walls.append(w)
                trials += r.counters["event_trials"]
                locations += r.counters["event_locations"]
                if old is not None:
                    w_old, data_old = old.simulate(case, h, dt_out)
                    walls_old.append(w_old)
            rows.append(
                (
                    h,
                    float(np.median(walls)),
                    error(data, ref),
                    r.counters["steps"],
                    trials_per_location(r),
                    float(np.median(walls_old)) if old else math.nan,
                    error(data_old, ref) if old else math.nan,
                )
            )
        print(
            f"\n   {name} (trials per event location in the engine: "
            f"{trials_per_location(rref)} at h = {H_REFERENCE:.3g})"
        )
        print(
            f"   {'h':>8} {'steps':>8} {'trials':>6} {'wall s':>8} {'error':>9}"
            f" |  v0.1: {'wall s':>8} {'error':>9}"
        )
        for h, w, e, n, tr, wo, eo in rows:
            print(f"   {h:8.3g} {n:8d} {tr:>6} {w:8.3f} {e:9.2e} |        {wo:8.3f} {eo:9.2e}")
        if old is None:
            continue
        print(f"   {'accuracy':>8} {'wall s':>8} {'v0.1':>8} {'speed-up':>9}  (target >= 1.5)")
        for acc in ACCURACIES:
            a = wall_at(acc, [r[2] for r in rows], [r[1] for r in rows])
            b = wall_at(acc, [r[6] for r in rows], [r[5] for r in rows])
            ratio = b / a if math.isfinite(b) else math.inf
            speedups.append(ratio)
            label = f"{ratio:8.2f}x" if math.isfinite(ratio) else " not reached by v0.1"
            print(f"   {acc:8.0e} {a:8.3f} {b:8.3f} {label}")
    return (min(speedups) if speedups else math.nan), trials / max(locations, 1)


# ------------------------------------------------------------------ 3. sampling
def sampling(old: OldEngine | None, rounds: int) -> float:
    """Print and return the overhead per output sample of ``simulate`` (seconds)."""
    p = stable_axial_set()
    opts = EngineOptions(h=SMOOTH_H)
    n = int(round(SMOOTH_T / SMOOTH_H))

    def run(dt_out: float) -> float:
        t0 = time.perf_counter()
        simulate(p, SMOOTH_T, initial=SMOOTH_INITIAL, dt_out=dt_out, options=opts, progress=False)
        return time.perf_counter() - t0

    run(SMOOTH_H)
    dense, single = [], []
    for _ in range(rounds):
        dense.append(run(SMOOTH_H))
        single.append(run(SMOOTH_T))
    per = (np.median(dense) - np.median(single)) / n
    print(f"\n3. Sampling: the run of 1. sampled every h ({n} samples) against one sample")
    print(
        f"   {np.median(dense):.4f} s against {np.median(single):.4f} s: "
        f"{per * 1e6:.3f} us per sample (target <= 1)"
    )
    if old is not None:
        params = {f.name: getattr(p, f.name) for f in dataclasses.fields(p)}
        case = {"params": params, "tau_end": SMOOTH_T, "initial": SMOOTH_INITIAL, "law": None}
        d = median_of(lambda: old.simulate(case, SMOOTH_H, SMOOTH_H)[0], max(rounds // 2, 1))
        s1 = median_of(lambda: old.simulate(case, SMOOTH_H, SMOOTH_T)[0], max(rounds // 2, 1))
        print(f"   v0.1:  {d:.4f} s against {s1:.4f} s: {(d - s1) / n * 1e6:.3f} us per sample")
    return float(per)


# ------------------------------------------------------------------ 4. plain Python
PLAIN = r"""
import sys, time
import numpy as np
from drillstring.model.kernel.jit import numba_available
assert not numba_available()
sys.path.insert(0, sys.argv[1])
import engine as bench
from drillstring.model.engine import EngineOptions
from drillstring.model.experiments import FIG5
from drillstring.model.params import REFERENCE
from drillstring.model.simulate import simulate
t0 = time.perf_counter()
r = simulate(REFERENCE, float(sys.argv[2]), control=bench.fig5_law(), initial=FIG5.initial(),
             options=EngineOptions(h=5e-4), progress=False)
wall = time.perf_counter() - t0
np.save(sys.argv[3], np.vstack([r.data[c] for c in r.data]))
print(wall, r.counters["steps"], r.counters["events"])
"""


def plain_python(tau_end: float) -> tuple[float, bool]:
    """Print and return the plain-Python kernel's cost per step (s) and its bit-identity."""
    law = fig5_law()

    def run() -> SimulationResult:
        opts = EngineOptions(h=5e-4)
        return simulate(REFERENCE, tau_end, control=law, initial=FIG5.initial(), options=opts,
                        progress=False)  # fmt: skip

    r = run()
    compiled = np.vstack([r.data[c] for c in r.data])
    t0 = time.perf_counter()
    run()
    wall_c = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "plain.npy"
        env = {**os.environ, "DRILLSTRING_JIT": "0"}
        bench_dir = str(Path(__file__).resolve().parent)
        res = subprocess.run(
            [sys.executable, "-c", PLAIN, bench_dir, repr(tau_end), str(out)],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        wall_p, steps, events = res.stdout.split()
        plain = np.load(out)
    same = plain.shape == compiled.shape and np.array_equal(plain, compiled)
    steps_n = int(steps)
    print(
        f"\n4. Plain Python (DRILLSTRING_JIT=0): Fig. 5 closed loop, tau in [0, {tau_end:g}], "
        f"h = 5e-4 ({steps_n} steps, {events} events)"
    )
    print(
        f"   {float(wall_p) / steps_n * 1e6:.0f} us/step against {wall_c / steps_n * 1e6:.2f} "
        f"us/step compiled ({float(wall_p) / wall_c:.0f}x); outputs bit-identical: {same}"
    )
    return float(wall_p) / steps_n, bool(same)


# ------------------------------------------------------------------ 5. prehistory
def wavy_history(tau: float) -> tuple[float, float, float, float]:
    """A perturbed past for the prehistory timing (a Python function, called once per node)."""
    return (
        1e-3 * math.sin(3 * tau),
        3e-3 * math.cos(3 * tau),
        0.2 * math.sin(tau),
        0.2 * math.cos(tau),
    )


def prehistory(old: OldEngine | None, rounds: int) -> float:
    """Print the prehistory and engine construction times; return Engine()'s (seconds)."""
    h = 1.25e-5
    _, nodes = build_prehistory(REFERENCE, nominal_history, h, 2048)
    build = median_of(
        lambda: _timed(lambda: build_prehistory(REFERENCE, nominal_history, h, 2048)), rounds
    )
    wavy = median_of(
        lambda: _timed(lambda: build_prehistory(REFERENCE, wavy_history, h, 2048)), rounds
    )
    init = dict(FIG5.initial())
    engine = median_of(lambda: _timed(lambda: Engine(REFERENCE, EngineOptions(h=h), init)), rounds)
    print(f"\n5. Prehistory at h = {h:g} ({nodes} nodes)")
    print(
        f"   nominal: build_prehistory {build * 1e3:.2f} ms, Engine() {engine * 1e3:.2f} ms; "
        f"a Python history function: {wavy * 1e3:.1f} ms ({wavy / nodes * 1e6:.2f} us per node, "
        "its calls)"
    )
    if old is not None:
        params = {f.name: getattr(REFERENCE, f.name) for f in dataclasses.fields(REFERENCE)}
        w = median_of(
            lambda: old.request(kind="engine", params=params, h=h, initial=init)["wall"], rounds
        )
        print(f"   v0.1: Engine() {w * 1e3:.2f} ms")
    return engine


def string_cost(rounds: int) -> tuple[int, float, float]:
    """Section 6: cost per step and per Fig. 6 open-loop run against N."""
    n_mode2 = torsional_elements_needed(REFERENCE_KAPPA, REFERENCE.rho, mode=2, rel_tol=0.01)
    sizes = sorted({1, 4, 16, 64, n_mode2})
    opts = EngineOptions(torsional_stick=True)

    def run(n: int) -> tuple[float, int]:
        t0 = time.perf_counter()
        r = simulate(
            REFERENCE,
            60.0,
            initial={"dphi": -4.9},
            options=opts,
            string=StringParams(elements=n),
            progress=False,
        )
        return time.perf_counter() - t0, r.counters["steps"]

    walls: dict[int, list[float]] = {n: [] for n in sizes}
    steps: dict[int, int] = {}
    for n in sizes:
        run(n)  # compiled and warm
    for _ in range(rounds):
        for n in sizes:  # interleaved: each round runs every N once
            w, steps[n] = run(n)
            walls[n].append(w)
    print(f"\n6. The distributed string: Fig. 6 open loop, tau in [0, 60], medians of {rounds}")
    print(
        f"   {'N':>4}  {'run s':>8}  {'ns/step':>8}  {'run / N=1':>9}  {'(run/N=1 - 1)/(N-1)':>20}"
    )
    base = float(np.median(walls[1]))
    for n in sizes:
        w = float(np.median(walls[n]))
        slope = (w / base - 1.0) / (n - 1) if n > 1 else float("nan")
        print(f"   {n:4d}  {w:8.3f}  {w / steps[n] * 1e9:8.0f}  {w / base:9.2f}  {slope:20.4f}")
    ratio = float(np.median(walls[n_mode2])) / base
    growth = float(np.median(walls[64])) / float(np.median(walls[16]))
    print(f"   second mode within 1 % at N = {n_mode2}: {ratio:.2f}x the N = 1 run (target <= 5)")
    print(f"   run(64) / run(16) = {growth:.2f} (linear in N: at most 4)")
    return n_mode2, ratio, growth


def _timed(fn: Callable[[], object]) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer rounds and steps")
    ap.add_argument("--no-v01", action="store_true", help="skip v0.1")
    ap.add_argument(
        "--v01-dir",
        type=Path,
        help="folder for v0.1 (kept, so its numba cache survives; default: temporary)",
    )
    args = ap.parse_args()
    start = time.perf_counter()
    if not numba_available():
        sys.exit("bench/engine.py measures the compiled kernel: numba is not available")
    rounds = 1 if args.quick else 3
    steps = STEPS[::2] if args.quick else STEPS
    simulate(REFERENCE, 0.1, initial={"dphi": -2.5}, progress=False)  # load the kernel
    with tempfile.TemporaryDirectory() as tmp:
        old = None
        if not args.no_v01:
            folder = args.v01_dir or Path(tmp)
            folder.mkdir(parents=True, exist_ok=True)
            old = OldEngine(folder)
            t0 = time.perf_counter()
            case = {"params": dataclasses.asdict(REFERENCE), "tau_end": 0.1, "law": None}
            old.simulate({**case, "initial": {"dphi": -2.5}}, 1e-3, 1e-2)
            print(
                f"v0.1: commit {OLD_COMMIT} in a subprocess from {folder} "
                f"(loaded or compiled in {time.perf_counter() - t0:.1f} s)"
            )
        try:
            ratio = kernel_vs_minimal(2 if args.quick else 5)
            speedup, trials = work_precision(old, steps, rounds)
            per_sample = sampling(old, 3 if args.quick else 7)
            plain, identical = plain_python(0.5 if args.quick else 2.0)
            build = prehistory(old, 3 if args.quick else 7)
            n_mode2, string_ratio, growth = string_cost(3 if args.quick else 7)
        finally:
            if old is not None:
                old.close()
    print(f"\nSummary ({time.perf_counter() - start:.0f} s)")
    print(f"   kernel / minimal loop per step     {ratio:8.2f}   (target <= 2)")
    print(f"   RK4 trials per event location      {trials:8.2f}   (target <= 8)")
    print(f"   smallest speed-up over v0.1        {speedup:8.2f}x  (target >= 1.5, 1e-4..1e-8)")
    print(f"   overhead per output sample         {per_sample * 1e6:8.3f}   us (target <= 1)")
    print(
        f"   plain Python per step              {plain * 1e6:8.1f}   us, bit-identical: {identical}"
    )
    print(f"   Engine() at h = 1.25e-5            {build * 1e3:8.2f}   ms")
    print(
        f"   string at N = {n_mode2} (mode 2 to 1 %)      {string_ratio:8.2f}x  the N = 1 run "
        f"(target <= 5); run(64)/run(16) {growth:.2f} (<= 4)"
    )


if __name__ == "__main__":
    main()
