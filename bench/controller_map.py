"""Benchmark of the controller maps (the controllers sweep study on Dask).

For each controller of drillstring.controller.lineup.CONTROLLERS, the 12 x 12 map over omega0 in
[2, 10] x v0 in [0.25, 2] (reference set, tau_end = 60, window 20, sample period 1e-3, the LMI
gain fixed from a gains file) on a LocalCluster of 1 and of 2 worker processes. Both clusters
are started, warmed (kernel loaded, axial design cached on every worker) and kept up, and the
runs are interleaved (controller by controller: 1 worker, then 2), so that the ratios compare
runs made side by side; with --repeat R each ratio is the median over R rounds. The 1- and
2-worker maps must be identical. From the measured point times, the projected wall time of the
30 x 30 x 4 reference map on a cluster of N workers: the serial point time divided by N and by
the parallel efficiency measured here (2-worker speed-up / 2), and never below the slowest
single point. Run: .venv/bin/python bench/controller_map.py --gains out/design/gains.json
"""

from __future__ import annotations

import argparse
import csv
import logging
import os
import statistics
import tempfile
import time
from pathlib import Path

from drillstring.apps.sweep.runner import kernel_warmup, run_sweep
from drillstring.apps.sweep.spec import spec_from_dict
from drillstring.apps.sweep.studies import axial_design
from drillstring.controller.lineup import CONTROLLERS


def spec_for(controller: str, gains: Path, n: int, tau_end: float, design: bool):
    return spec_from_dict(
        {
            "study": "controllers",
            "base": "reference",
            "tau_end": tau_end,
            "sweep": [
                {"param": "omega0", "start": 2.0, "stop": 10.0, "num": n},
                {"param": "v0", "start": 0.25, "stop": 2.0, "num": n},
            ],
            "options": {
                "controllers": [controller],
                "gains": "design" if design else str(gains.resolve()),
                "window": min(20.0, tau_end / 3.0),
            },
        }
    )


def start(workers: int, params):
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    client = Client(cluster)
    client.run(kernel_warmup)
    client.run(axial_design, params)  # the design task then hits every worker's cache
    return cluster, client


def timed(spec, client, out: Path) -> dict:
    t0 = time.perf_counter()
    report = run_sweep(spec, out, client=client, progress=False, plots=False)
    wall = time.perf_counter() - t0
    with open(report.results, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {
        "wall": wall,
        "point_seconds": [float(r["seconds"]) for r in rows],
        "failed": report.n_failed,
        "rows": [{k: v for k, v in r.items() if k != "seconds"} for r in rows],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--gains", type=Path, default=Path("out/design/gains.json"))
    ap.add_argument("--n", type=int, default=12, help="points per axis (default 12)")
    ap.add_argument("--tau-end", type=float, default=60.0)
    ap.add_argument("--repeat", type=int, default=1, help="rounds (medians over them)")
    ap.add_argument(
        "--lmi-design", action="store_true", help="also time the LMI law redesigned per point"
    )
    ap.add_argument("--project", type=int, default=30, help="points per axis of the projection")
    args = ap.parse_args()
    entries = [(c, False) for c in CONTROLLERS] + ([("lmi", True)] if args.lmi_design else [])
    specs = {(c, d): spec_for(c, args.gains, args.n, args.tau_end, d) for c, d in entries}
    first = next(iter(specs.values()))
    print(
        f"{args.n} x {args.n} map per controller, tau_end = {args.tau_end}, Ts = "
        f"{first.options['Ts']:g}, h = {first.options['h']:g}; rounds: {args.repeat}"
    )
    print(f"cores: {os.cpu_count()}, load average before: {os.getloadavg()}")
    print(f"kernel warm-up in the parent: {kernel_warmup()}")
    clusters = {}
    t0 = time.perf_counter()
    for w in (1, 2):
        clusters[w] = start(w, first.point_params(0))
    print(f"two clusters started and warmed in {time.perf_counter() - t0:.1f} s")
    results: dict = {key: {1: [], 2: []} for key in specs}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for rnd in range(args.repeat):
                for key, spec in specs.items():
                    for w in (1, 2):
                        out = Path(tmp) / f"{key[0]}-{int(key[1])}-{w}-{rnd}"
                        results[key][w].append(timed(spec, clusters[w][1], out))
                    r1, r2 = results[key][1][-1], results[key][2][-1]
                    label = key[0] + (" (designed per point)" if key[1] else "")
                    print(
                        f"round {rnd + 1}: {label:<28} 1 worker {r1['wall']:7.1f} s, "
                        f"2 workers {r2['wall']:7.1f} s, ratio {r1['wall'] / r2['wall']:.2f}, "
                        f"identical {r1['rows'] == r2['rows']}, failed {r1['failed']}",
                        flush=True,
                    )
    finally:
        for cluster, client in clusters.values():
            client.close()
            cluster.close()
    print(f"load average after: {os.getloadavg()}")
    print()
    print(
        f"{'controller':<28} {'1 worker [s]':>12} {'2 workers [s]':>13} {'ratio':>6} "
        f"{'point mean [s]':>14} {'point max [s]':>13}"
    )
    serial_per_point = 0.0
    slowest = 0.0
    ratios = []
    for key in specs:
        w1 = statistics.median(r["wall"] for r in results[key][1])
        w2 = statistics.median(r["wall"] for r in results[key][2])
        points = [s for r in results[key][1] for s in r["point_seconds"]]
        mean, peak = statistics.fmean(points), max(points)
        serial_per_point += mean
        slowest = max(slowest, peak)
        ratios.append(w1 / w2)
        label = key[0] + (" (designed per point)" if key[1] else "")
        print(f"{label:<28} {w1:12.1f} {w2:13.1f} {w1 / w2:6.2f} {mean:14.3f} {peak:13.2f}")
    efficiency = statistics.median(ratios) / 2.0
    n_ref = args.project**2
    serial = n_ref * serial_per_point
    print()
    print(
        f"projection: {args.project} x {args.project} x {len(specs)} map = {n_ref * len(specs)} "
        f"runs, {serial / 3600:.2f} h of point time on one worker (mean point time of each "
        f"controller above); parallel efficiency {efficiency:.2f} (median 2-worker ratio / 2); "
        f"floor: the slowest point, {slowest:.1f} s"
    )
    for n in (1, 2, 8, 32, 128, 512):
        t = max(serial / (n * (1.0 if n == 1 else efficiency)), slowest)
        print(f"  {n:4d} workers: {t / 60:8.1f} min")


if __name__ == "__main__":
    main()
