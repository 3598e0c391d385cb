"""Benchmark of the axial analysis (Section III, Fig. 4).

Wall time of one averaged-force point at taubar_n = 10 and of the whole Fig. 4 sweep
(3 gammabar x 25 delays, serial). Target: the whole sweep under 30 s on this machine.
Run: .venv/bin/python bench/axial.py
"""

from __future__ import annotations

import time

from drillstring.analysis.limit_cycles import (
    FIG4_ETABAR2,
    FIG4_GAMMABARS,
    default_fit_delays,
    limit_cycle,
)


def main() -> None:
    limit_cycle(0.2, FIG4_ETABAR2, 5.0, n_samples=0)  # warm-up: load the compiled kernel
    t0 = time.perf_counter()
    lc = limit_cycle(0.2, FIG4_ETABAR2, 10.0, n_samples=0)
    one = time.perf_counter() - t0
    print(f"one point (gammabar=0.2, taubar_n=10): {one:.3f} s, average {lc.average:.6f}")
    t0 = time.perf_counter()
    n = 0
    for g in FIG4_GAMMABARS:
        for tb in default_fit_delays(g, FIG4_ETABAR2, 25):
            limit_cycle(g, FIG4_ETABAR2, float(tb), n_samples=0)
            n += 1
    sweep = time.perf_counter() - t0
    verdict = "meets" if sweep < 30 else "misses"
    print(f"Fig. 4 sweep ({n} points, serial): {sweep:.2f} s -> {verdict} the 30 s target")


if __name__ == "__main__":
    main()
