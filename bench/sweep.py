"""Benchmark of the Dask sweep.

The same 64-point open-loop sweep (8 x 8 over omega0 in [8, 20], v0 in [0.5, 1], reference set,
tau_end = 100, h = 1e-4: about 1.5 s per point) on a LocalCluster with 1 and with 2 worker
processes. Timed: the sweep itself (cluster already up and warmed, the axial design task and all
points included) and end to end (cluster start included). Target: wall-time ratio >= 1.8 on a
2-core machine. The two runs must give identical results. Run: .venv/bin/python bench/sweep.py
"""

from __future__ import annotations

import argparse
import csv
import os
import tempfile
import time
from pathlib import Path

from drillstring.apps.sweep.runner import kernel_warmup, run_sweep
from drillstring.apps.sweep.spec import spec_from_dict


def bench_spec(tau_end: float, h: float, n: int) -> dict:
    return {
        "study": "open-loop",
        "base": "reference",
        "tau_end": tau_end,
        "sweep": [
            {"param": "omega0", "start": 8.0, "stop": 20.0, "num": n},
            {"param": "v0", "start": 0.5, "stop": 1.0, "num": n},
        ],
        "options": {"h": h},
    }


def run(spec, workers: int, out: Path) -> dict:
    from dask.distributed import Client, LocalCluster

    t0 = time.perf_counter()
    cluster = LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
    )
    client = Client(cluster)
    try:
        warm = client.run(kernel_warmup)
        t1 = time.perf_counter()
        report = run_sweep(spec, out, client=client, progress=False, plots=False)
        t2 = time.perf_counter()
    finally:
        client.close()
        cluster.close()
    with open(report.results, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {
        "startup": t1 - t0,
        "sweep": t2 - t1,
        "total": t2 - t0,
        "point_seconds": sum(float(r["seconds"]) for r in rows),
        "failed": report.n_failed,
        "compiled_on_workers": sum(1 for w in warm.values() if w.get("cache_misses")),
        "rows": [{k: v for k, v in r.items() if k != "seconds"} for r in rows],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--tau-end", type=float, default=100.0)
    ap.add_argument("--h", type=float, default=1e-4)
    ap.add_argument("--n", type=int, default=8, help="points per axis (default 8: 64 points)")
    args = ap.parse_args()
    spec = spec_from_dict(bench_spec(args.tau_end, args.h, args.n))
    print(f"{spec.n_points}-point open-loop sweep, tau_end = {args.tau_end}, h = {args.h:g}")
    print(f"cores: {os.cpu_count()}, load average before: {os.getloadavg()}")
    print(f"kernel warm-up in the parent: {kernel_warmup()}")
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for workers in (1, 2):
            results[workers] = r = run(spec, workers, Path(tmp) / f"w{workers}")
            print(
                f"{workers} worker(s): sweep {r['sweep']:7.2f} s (cluster start {r['startup']:.2f}"
                f" s, total {r['total']:.2f} s), sum of point times {r['point_seconds']:.1f} s, "
                f"failed points {r['failed']}, workers that compiled the kernel "
                f"{r['compiled_on_workers']}"
            )
    print(f"load average after: {os.getloadavg()}")
    same = results[1]["rows"] == results[2]["rows"]
    print(f"results identical with 1 and 2 workers: {same}")
    ratio = results[1]["sweep"] / results[2]["sweep"]
    ratio_total = results[1]["total"] / results[2]["total"]
    verdict = "meets" if ratio >= 1.8 else "misses"
    print(f"speed-up 2 vs 1 workers: {ratio:.2f}x sweep ({verdict} the 1.8x target), ", end="")
    print(f"{ratio_total:.2f}x end to end")


if __name__ == "__main__":
    main()
