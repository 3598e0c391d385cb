"""Benchmark of the stepping engine.

Reference set, open loop from dphi/dtau(0) = -2.5 over tau in [0, 60]: wall time, steps, events
and the max error of du/dtau and dphi/dtau (sampled every 0.01) against a run with a 16x finer
step. Target: error below 1e-6 in under 2 s of wall time. Run: .venv/bin/python bench/engine.py
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from drillstring.model.engine import EngineOptions
from drillstring.model.kernel.jit import numba_available
from drillstring.model.params import REFERENCE
from drillstring.model.simulate import simulate


def run(h: float, tau_end: float):
    t0 = time.perf_counter()
    r = simulate(
        REFERENCE, tau_end, initial={"dphi": -2.5}, options=EngineOptions(h=h), progress=False
    )
    return r, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--tau-end", type=float, default=60.0)
    ap.add_argument("--steps", type=float, nargs="+", default=[1e-3, 5e-4, 2.5e-4])
    args = ap.parse_args()
    print(f"numba kernel: {numba_available()}")
    run(1e-3, 0.1)  # warm-up: load/compile the kernel outside the timings
    h_ref = min(args.steps) / 16
    ref, t_ref = run(h_ref, args.tau_end)
    print(f"reference h = {h_ref:.3e}: {t_ref:.2f} s, {ref.counters['steps']} steps")
    print(f"{'h':>10} {'wall s':>8} {'steps':>8} {'events':>7} {'err du':>10} {'err dphi':>10}")
    for h in args.steps:
        r, wall = run(h, args.tau_end)
        e_du = float(np.max(np.abs(r.du - ref.du)))
        e_dphi = float(np.max(np.abs(r.dphi - ref.dphi)))
        print(
            f"{h:10.3e} {wall:8.3f} {r.counters['steps']:8d} {r.counters['events']:7d} "
            f"{e_du:10.2e} {e_dphi:10.2e}"
        )
        if e_du < 1e-6 and e_dphi < 1e-6:
            verdict = "meets" if wall < 2.0 else "misses"
            print(f"  -> error < 1e-6 in {wall:.2f} s: {verdict} the 2 s target")


if __name__ == "__main__":
    main()
