"""Benchmark of the controller maps: the time of a map point against a monolithic run.

The map is ``drillstring controllers map``'s (:func:`drillstring.apps.controllers.
controller_map_spec`: rpm x nominal WOB on the design's rig, every controller under the
TDS-11SA, tau_end = 200, window 35, sample period 1e-3, h = 5e-4, output every 1e-2), on the
converged string of --elements (16, the command's default; 1: the paper's one-mode model).

1. Per map point and controller, in this process: the study's point function with that
   controller alone (setup, the sampled run of the compiled digital controller, the severity
   metrics, the linearised abscissa) against a monolithic run of the same length at the same
   point (:func:`drillstring.model.simulate.simulate` with the held torque R_ff, the same h,
   the same output grid, the torsional-stick model on, the same string); interleaved point by
   point, each the best of --repeat runs. The target: a controller run at most about twice
   the monolithic run.
2. The --dask-n x --dask-n map with every controller on a LocalCluster of 1 and of 2 worker
   processes (both started, warmed and kept up, the runs interleaved); the two maps must be
   identical.
3. From the measured times, the projected wall time of a --project x --project map with
   every law (25 x 25 by default) on 1, 2, 8 and 32 workers: the mean time per point (all
   controllers) times the points, over N and the parallel efficiency measured in 2. (2-worker
   speed-up / 2), never below the slowest point.

Run: .venv/bin/python bench/controller_map.py --gains out/design/gains.json
(the constrained design's gains_constrained.json beside it: drillstring design --torque-limit).
"""

from __future__ import annotations

import argparse
import csv
import logging
import os
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from drillstring.analysis.severity import OUTCOMES, SLOWEST_PERIOD
from drillstring.apps.controllers import controller_map_spec
from drillstring.apps.sweep.options import MAP_WINDOW
from drillstring.apps.sweep.runner import kernel_warmup, run_sweep
from drillstring.apps.sweep.studies import axial_design, evaluate_point, point_string
from drillstring.controller.averaged import averaged_model
from drillstring.model.engine import EngineOptions
from drillstring.model.simulate import simulate


def single(spec, controller):
    """The spec with one controller (its other options, the constrained gains read or not)."""
    return replace(spec, options=replace(spec.options, controllers=(controller,)))


def best_of(f, repeat):
    """(best time of ``repeat`` calls, the last result)."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = f()
        times.append(time.perf_counter() - t0)
    return min(times), result


def point_times(spec, points, repeat):
    """(monolithic, {controller: time}) per point, interleaved."""
    names = spec.options.controllers
    specs = {c: single(spec, c) for c in names}
    opts = spec.options
    out = []
    for index in points:
        p = spec.point_params(index)
        design = axial_design(p)
        model = averaged_model(p, design.A, design.taubar_crit)
        options = EngineOptions(h=opts.h, torsional_stick=True, on_invalid=opts.on_invalid)
        string = point_string(spec.point_scales(index), opts.elements)

        def mono(p=p, model=model, options=options, string=string):
            return simulate(p, spec.tau_end, control=float(model.R_ff),
                            initial={"dphi": opts.dphi0_rel * p.omega0},
                            dt_out=opts.dt_out, options=options, progress=False,
                            string=string)  # fmt: skip

        t, res = best_of(mono, repeat)
        row = {"mono": t}
        complete = {"mono": res.status.ok}
        for c in names:
            row[c], metrics = best_of(
                lambda c=c, index=index, design=design: evaluate_point(specs[c], index, design),
                repeat,
            )
            complete[c] = metrics[f"outcome.{c}"] in OUTCOMES
        out.append((row, complete))
        where = {k: round(v, 2) for k, v in spec.point_values(index).items()}
        mark = {k: "" if v else " stopped" for k, v in complete.items()}
        print(
            f"  point {index:4d} {where}: monolithic {row['mono']:.3f} s{mark['mono']}"
            + (f" at tau = {res.tau[-1]:.1f} ({res.status.code})" if not res.status.ok else "")
            + "; "
            + ", ".join(
                f"{c} {row[c]:.3f} s ({row[c] / row['mono']:.2f}x){mark[c]}" for c in names
            ),
            flush=True,
        )
    return out


def start(workers, params):
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


def timed(spec, client, out):
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
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--gains", type=Path, default=Path("out/design/gains.json"))
    ap.add_argument("--n", type=int, default=25, help="points per axis of the map (default 25)")
    ap.add_argument("--tau-end", type=float, default=200.0)
    ap.add_argument("--points", type=int, default=3, help="points per axis timed in 1. (3)")
    ap.add_argument("--repeat", type=int, default=2, help="best of R runs in 1. (2)")
    ap.add_argument("--dask-n", type=int, default=4, help="points per axis of 2. (4)")
    ap.add_argument("--project", type=int, default=25, help="points per axis of 3. (25)")
    ap.add_argument("--elements", type=int, default=16, help="elements of the string (16)")
    args = ap.parse_args()
    logging.getLogger("distributed").setLevel(logging.WARNING)
    window = min(MAP_WINDOW, args.tau_end / 4.0)
    # a shorter run times the points, it does not classify: its window may hold fewer periods
    periods = {"window": window, "min_periods": min(5.0, window / SLOWEST_PERIOD)}
    periods["elements"] = args.elements
    spec = controller_map_spec(args.gains, n=args.n, tau_end=args.tau_end, **periods)
    names = spec.options.controllers
    print(
        f"map: {args.n} x {args.n} over {spec.axes[0].start:g}-{spec.axes[0].stop:g} rpm x "
        f"{spec.axes[1].start:.4g}-{spec.axes[1].stop:.4g} kN, controllers {', '.join(names)}, "
        f"top drive {spec.options.top_drive}; tau_end = {spec.tau_end:g}, window "
        f"{spec.options.window:g}, Ts = {spec.options.Ts:g}, h = {spec.options.h:g}, "
        f"dt_out = {spec.options.dt_out:g}, string of {spec.options.elements} element(s)"
    )
    print(f"cores: {os.cpu_count()}, load average before: {os.getloadavg()}")
    print(f"kernel warm-up in this process: {kernel_warmup()}")
    k = args.points
    picks = sorted({round(i * (args.n - 1) / max(k - 1, 1)) for i in range(k)})
    points = [i * args.n + j for i in picks for j in picks]
    print(f"1. per point and controller (best of {args.repeat}), {len(points)} points:")
    timed_points = point_times(spec, points, args.repeat)
    print()
    print("runs to tau_end only (a run that stops early is shorter; so is the monolithic run "
          "where the open loop stops):")  # fmt: skip
    print(f"{'run':<16} {'runs':>5} {'mean [s]':>9} {'median [s]':>10} {'max [s]':>8} "
          f"{'mean ratio':>10} {'max ratio':>9}")  # fmt: skip
    both = [(r, ok) for r, ok in timed_points if ok["mono"]]
    all_ratios = []
    for c in ("mono", *names):
        sel = [r for r, ok in both if ok[c]]
        if not sel:
            print(f"{c:<16} {0:5d}   (every run stopped early)")
            continue
        t = [r[c] for r in sel]
        ratio = [r[c] / r["mono"] for r in sel]
        if c != "mono":
            all_ratios += ratio
        label = "monolithic" if c == "mono" else c
        print(f"{label:<16} {len(sel):5d} {statistics.fmean(t):9.3f} {statistics.median(t):10.3f} "
              f"{max(t):8.3f} {statistics.fmean(ratio):10.2f} {max(ratio):9.2f}")  # fmt: skip
    if all_ratios:
        print(f"a controller run to tau_end: {statistics.fmean(all_ratios):.2f} x the monolithic "
              f"run on average, {statistics.median(all_ratios):.2f} median, "
              f"{max(all_ratios):.2f} at most ({len(all_ratios)} runs)")  # fmt: skip

    small = controller_map_spec(args.gains, n=args.dask_n, tau_end=args.tau_end, **periods)
    print()
    print(f"2. the {args.dask_n} x {args.dask_n} map with every controller on 1 and 2 workers:")
    clusters = {}
    t0 = time.perf_counter()
    for w in (1, 2):
        clusters[w] = start(w, small.point_params(0))
    print(f"  two clusters started and warmed in {time.perf_counter() - t0:.1f} s")
    try:
        with tempfile.TemporaryDirectory() as tmp:
            runs = {w: timed(small, clusters[w][1], Path(tmp) / f"w{w}") for w in (1, 2)}
    finally:
        for cluster, client in clusters.values():
            client.close()
            cluster.close()
    w1, w2 = runs[1]["wall"], runs[2]["wall"]
    points_1 = runs[1]["point_seconds"]
    print(f"  1 worker {w1:.1f} s ({w1 / small.n_points:.2f} s per point), 2 workers {w2:.1f} s, "
          f"speed-up {w1 / w2:.2f}, identical {runs[1]['rows'] == runs[2]['rows']}, failed "
          f"{runs[1]['failed']}; point time on 1 worker: mean {statistics.fmean(points_1):.2f} s, "
          f"max {max(points_1):.2f} s")  # fmt: skip
    print(f"load average after: {os.getloadavg()}")

    efficiency = min(1.0, (w1 / w2) / 2.0)
    point = statistics.fmean(points_1)
    slowest = max(points_1)
    n_ref = args.project**2
    serial = n_ref * point
    print()
    print(
        f"3. projection: {args.project} x {args.project} x {len(names)} map = "
        f"{n_ref * len(names)} runs, {serial / 3600:.2f} h of point time on one worker (mean "
        f"point time {point:.2f} s of 2.); parallel efficiency {efficiency:.2f}; floor: the "
        f"slowest point, {slowest:.1f} s"
    )
    for n in (1, 2, 8, 32):
        t = max(serial / (n * (1.0 if n == 1 else efficiency)), slowest)
        print(f"  {n:4d} workers: {t / 60:8.1f} min")


if __name__ == "__main__":
    main()
