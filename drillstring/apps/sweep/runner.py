"""Parameter sweeps on Dask: ``drillstring sweep SPEC --out DIR``.

One task per point of the sweep (:mod:`drillstring.apps.sweep.spec`); the point functions are in
:mod:`drillstring.apps.sweep.studies`. The axial design inputs A, taubar_crit of (22), which
depend on (gammabar, etabar^2) only, are one task per distinct pair; the point tasks depend on it.

Execution: a ``dask.distributed.LocalCluster`` (processes, one thread each) by default,
``--scheduler ADDRESS`` for an existing cluster, or serially in this process (``--workers 0``,
:func:`run_sweep` with ``serial=True``). The numba kernel is loaded (or compiled and cached) once
in this process before the workers start, so that they load it from numba's cache instead of
compiling it each (``summary.json`` records what every worker did).

Output in DIR:

* ``results.csv``: one row per point, appended (and flushed) as each point finishes, so an
  interrupted sweep keeps what it finished; ``--resume`` skips the points already in the file
  (``--retry-failed`` also recomputes the points that recorded an error). Columns: ``index``
  (row-major point number), the grid indices ``i`` (and ``j``), the swept values, with a derived
  physical axis (``rpm``, ``W0_kN``) the speed ``Omega0`` [rad/s] and hook speed ``V0`` [m/s]
  it imposes, the study's metrics, ``seconds`` (wall time of the point) and ``error`` (empty, or
  the exception of a failed point). When the sweep completes, the file is rewritten sorted by
  index.
* ``spec.json``: the validated spec (a resume must use the same one); ``summary.json`` (with the
  feed, :attr:`~drillstring.apps.sweep.spec.SweepSpec.feed`).
* ``plots/<metric>.png``: heat map (2-D) or line plot (1-D) per metric, reference point marked;
  for the controllers study a panel per controller (a physical base's torques, power, speed and
  times in kN m, kW, rpm and s), its linearised stability boundary overlaid and
  ``plots/boundary.csv`` with the abscissae on the finer grid it was drawn from.
* for the controllers study, ``by_controller.csv`` (how often each controller ends in each
  outcome and is the best) and, on a physical base over ``rpm`` and ``W0_kN``, ``map_si.csv``
  (the results in SI, the unit in each column name): :mod:`drillstring.apps.sweep.tables`.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import textwrap
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from drillstring.analysis.severity import OUTCOMES
from drillstring.apps.colors import CONTROLLER_COLORS, OUTCOME_COLORS
from drillstring.apps.sweep.metrics import (
    CONTROLLER_METRICS,
    METRICS,
    controller_column,
    si_factor,
)
from drillstring.apps.sweep.plots import Overlay, sweep_figure
from drillstring.apps.sweep.spec import (
    AXIS_LABELS,
    MAX_POINTS,
    PHYSICAL_DERIVED,
    SweepSpec,
    SweepSpecError,
    load_spec,
)
from drillstring.apps.sweep.studies import (
    OPEN_LOOP,
    DesignInputs,
    axial_design,
    boundary_model,
    design_key,
    evaluate_point,
    linear_boundary,
)
from drillstring.apps.sweep.tables import write_tables
from drillstring.controller.lineup import RIG_CONTROLLERS, sensing_note
from drillstring.fileio import save_figure, write_csv, write_json
from drillstring.model import laws as model_laws
from drillstring.model import sensing as model_sensing
from drillstring.model import timing as model_timing
from drillstring.model import topdrive as model_topdrive
from drillstring.model.digital import block as digital_block
from drillstring.model.digital import loop as digital_loop
from drillstring.model.digital.controller import DigitalController
from drillstring.model.laws import SpeedPI
from drillstring.model.params import REFERENCE, PhysicalParams
from drillstring.model.sampled import simulate_sampled
from drillstring.model.sensing import Sensing
from drillstring.model.simulate import cache_counts, warm_up
from drillstring.model.topdrive import TopDrive

__all__ = [
    "PointFunction",
    "SweepError",
    "SweepReport",
    "columns",
    "compute_row",
    "kernel_warmup",
    "read_results",
    "run_sweep",
    "shown_values",
    "sweep_main",
    "write_plots",
]

RESULTS = "results.csv"
SPEC = "spec.json"
SUMMARY = "summary.json"
PLOTS = "plots"
MAX_ERROR_CHARS = 4000

#: ``f(spec, index, design) -> {metric: value}``; the default is ``evaluate_point``.
PointFunction = Callable[[SweepSpec, int, DesignInputs | None], dict[str, Any]]


class SweepError(RuntimeError):
    """The sweep cannot run: output folder in use, mismatching resume, bad results file."""


# --------------------------------------------------------------------------------------------
# rows and the results file
# --------------------------------------------------------------------------------------------


def columns(spec: SweepSpec) -> list[str]:
    """Header of ``results.csv`` (module docstring).

    Parameters
    ----------
    spec : SweepSpec
        The sweep.

    Returns
    -------
    list of str
        ``index``, ``i`` (and ``j``), the swept names, the imposed speed and feed ``Omega0``,
        ``V0`` (SI) when a derived axis (``rpm``, ``W0_kN``) sets them, the study's metrics,
        ``seconds``, ``error``.
    """
    grid = ["i", "j"][: len(spec.axes)]
    return [
        "index",
        *grid,
        *spec.names,
        *_imposed(spec),
        *(m for m, _ in METRICS[spec.study]),
        "seconds",
        "error",
    ]


def _imposed(spec: SweepSpec) -> tuple[str, ...]:
    """The physical speed and hook speed a derived axis sets (columns of ``results.csv``)."""
    return ("Omega0", "V0") if any(n in PHYSICAL_DERIVED for n in spec.names) else ()


def _fmt(value: Any) -> str:
    if isinstance(value, bool):
        return str(int(value))
    if isinstance(value, float):
        return repr(value)
    if value is None:
        return ""
    return str(value)


def _error(exc: BaseException) -> str:
    """The ``error`` column of a failed point: the exception on one line, shortened."""
    text = f"{type(exc).__name__}: {exc}"
    text = " | ".join(line.strip() for line in text.splitlines() if line.strip())
    return text if len(text) <= MAX_ERROR_CHARS else text[: MAX_ERROR_CHARS - 3] + "..."


def compute_row(
    spec: SweepSpec,
    index: int,
    design: DesignInputs | None,
    point_fn: PointFunction | None = None,
) -> list[str]:
    """Evaluate one point and format its CSV row (the task a Dask worker runs).

    Parameters
    ----------
    spec : SweepSpec
        The sweep.
    index : int
        The point's index (row-major), in ``0 .. spec.n_points - 1``.
    design : DesignInputs or None
        The point's axial design inputs (None for the axial study).
    point_fn : callable, optional
        Replaces :func:`~drillstring.apps.sweep.studies.evaluate_point`.

    Returns
    -------
    list of str
        The row in the order of :func:`columns`. An exception of the point function becomes
        the ``error`` column (one line, at most ``MAX_ERROR_CHARS``) with empty metrics.

    Raises
    ------
    IndexError
        ``index`` is outside the sweep (raised while formatting, not caught).
    """
    t0 = time.perf_counter()
    metrics: dict[str, Any] = {}
    error = ""
    try:
        metrics = (point_fn or evaluate_point)(spec, index, design)
    except Exception as exc:  # a failed point is a result, not the end of the sweep
        error = _error(exc)
    seconds = time.perf_counter() - t0
    return _row(spec, index, metrics, seconds, error)


def _row(
    spec: SweepSpec, index: int, metrics: dict[str, Any], seconds: float, error: str
) -> list[str]:
    ij = spec.grid_index(index)
    values = spec.point_values(index)
    out = [str(index), *(str(k) for k in ij), *(repr(values[n]) for n in spec.names)]
    if _imposed(spec):
        rig = spec.physical_at(values)
        out += [repr(rig.Omega0), repr(rig.V0)]
    out += [_fmt(metrics.get(m)) if not error else "" for m, _ in METRICS[spec.study]]
    out += [f"{seconds:.3f}", error]
    return out


def read_results(path: str | os.PathLike[str], header: Sequence[str]) -> tuple[dict, bool]:
    """Rows of a results file by point index, and whether the file needs a clean rewrite.

    A last line without its newline (the run was killed while writing it) is dropped; a point
    present twice keeps its first row.

    Parameters
    ----------
    path : path
        The ``results.csv``.
    header : sequence of str
        The expected header (:func:`columns`).

    Returns
    -------
    rows : dict of int to list of str
        Each point's row (all fields as strings), by index.
    dirty : bool
        True if a truncated last line or a duplicate was dropped, or the file is empty.

    Raises
    ------
    SweepError
        The header differs, a line has the wrong number of fields or a bad point index.
    OSError
        The file cannot be read.
    """
    text = Path(path).read_text(encoding="utf-8")
    dirty = False
    if text and not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
        dirty = True
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        return {}, True
    if rows[0] != list(header):
        raise SweepError(
            f"{path}: columns {rows[0]} differ from this sweep's columns {list(header)}"
        )
    out: dict[int, list[str]] = {}
    for k, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise SweepError(f"{path}: line {k} has {len(row)} fields, expected {len(header)}")
        try:
            index = int(row[0])
        except ValueError:
            raise SweepError(f"{path}: line {k}: bad point index {row[0]!r}") from None
        if index in out:
            dirty = True
            continue
        out[index] = row
    return out, dirty


# --------------------------------------------------------------------------------------------
# execution
# --------------------------------------------------------------------------------------------


def kernel_warmup() -> dict[str, Any]:
    """Load (or compile) the numba kernel and the compiled sampled loop in this process, for
    the sweep's summary.

    Returns
    -------
    dict
        ``pid`` and what :func:`drillstring.model.simulate.warm_up` reports (``jit`` and,
        with the compiled kernel, ``cache_hits``, ``cache_misses``: nonzero when it was
        compiled here rather than loaded from numba's cache, and ``seconds``); with the
        compiled kernel also ``sampled_cache_hits``, ``sampled_cache_misses`` and
        ``sampled_seconds`` of a tiny run of the sampled loop (a digital controller with a top
        drive and the torque from the motor: the controllers study's code).
    """
    info = {"pid": os.getpid(), **warm_up()}
    if info.get("jit"):
        t0 = time.perf_counter()
        law = SpeedPI(kp=1.0, ki=1.0)
        drive = TopDrive(R_min=-100.0, R_max=100.0, lag=0.01)
        controller = DigitalController(law, drive, Sensing(torque="motor"))
        simulate_sampled(REFERENCE, controller, 0.01, 1e-3, dt_out=0.01)
        hits, misses = cache_counts((digital_loop, digital_block, model_laws, model_topdrive,
                                     model_sensing, model_timing))  # fmt: skip
        info.update(
            sampled_cache_hits=hits,
            sampled_cache_misses=misses,
            sampled_seconds=time.perf_counter() - t0,
        )
    return info


def _design_params(spec: SweepSpec, todo: Sequence[int]) -> dict[int, Any]:
    """For each point, the parameter set whose design key it uses (full-model studies)."""
    return {} if spec.study == "axial" else {k: spec.point_params(k) for k in todo}


def _serial_rows(
    spec: SweepSpec, todo: Sequence[int], point_fn: PointFunction | None
) -> Iterator[list[str]]:
    from threadpoolctl import threadpool_limits

    params = _design_params(spec, todo)
    with threadpool_limits(1):  # as on a worker (one thread, OMP/BLAS threads 1)
        for index in todo:
            design = axial_design(params[index]) if index in params else None
            yield compute_row(spec, index, design, point_fn)


def _dask_rows(
    spec: SweepSpec, todo: Sequence[int], client: Any, point_fn: PointFunction | None
) -> Iterator[list[str]]:
    from dask.distributed import as_completed

    token = uuid.uuid4().hex[:8]
    params = _design_params(spec, todo)
    designs: dict[tuple[float, float], Any] = {}
    for p in params.values():
        key = design_key(p)
        if key not in designs:
            designs[key] = client.submit(
                axial_design, p, key=f"axial-design-{len(designs)}-{token}", pure=False, priority=10
            )
    futures = {}
    for index in todo:
        dep = designs[design_key(params[index])] if index in params else None
        fut = client.submit(
            compute_row, spec, index, dep, point_fn, key=f"point-{index}-{token}", pure=False
        )
        futures[fut.key] = (index, fut)
    try:
        for fut in as_completed([f for _, f in futures.values()]):
            index = futures[fut.key][0]
            try:
                row = fut.result()
            except Exception as exc:  # worker lost, cancelled, unpicklable result, ...
                row = _row(spec, index, {}, math.nan, _error(exc))
            futures.pop(fut.key)
            fut.release()
            yield row
    finally:
        pending = [f for _, f in futures.values()] + list(designs.values())
        if pending:
            client.cancel(pending)


@contextmanager
def _dask_client(scheduler: str | None, workers: int | None) -> Iterator[tuple[Any, dict]]:
    from dask.distributed import Client, LocalCluster

    info: dict[str, Any] = {"parent": kernel_warmup()}
    if scheduler:
        client = Client(scheduler)
        cluster = None
    else:
        n = workers or os.cpu_count() or 1
        cluster = LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = Client(cluster)
    try:
        info["scheduler"] = client.scheduler.address
        info["workers"] = client.run(kernel_warmup)
        compiled = {
            w: r
            for w, r in info["workers"].items()
            if r.get("cache_misses") or r.get("sampled_cache_misses")
        }
        if compiled:
            print(
                f"drillstring sweep: warning: the numba kernel was compiled (not loaded from the "
                f"cache) on {len(compiled)} worker(s): {', '.join(compiled)}",
                file=sys.stderr,
            )
        yield client, info
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


@dataclass
class SweepReport:
    """What a :func:`run_sweep` call did.

    ``finished``: every point of the sweep has its row (the results are sorted and the maps
    drawn); ``complete``: finished and no point failed.
    """

    out_dir: Path
    results: Path
    n_points: int
    n_skipped: int
    n_computed: int
    n_failed: int
    finished: bool
    wall_time: float
    plots: list[Path] = field(default_factory=list)
    execution: dict[str, Any] = field(default_factory=dict)
    #: The controllers study's tables (:func:`~drillstring.apps.sweep.tables.write_tables`):
    #: the rows of ``by_controller.csv`` and the files by name.
    by_controller: list[dict[str, Any]] = field(default_factory=list)
    tables: dict[str, Path] = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        """Every point of the sweep computed without an error."""
        return self.finished and self.n_failed == 0


def _canonical(obj: Any) -> Any:
    return json.loads(json.dumps(obj, sort_keys=True))


def _prepare(
    spec: SweepSpec, out: Path, resume: bool, retry_failed: bool
) -> tuple[dict[int, list[str]], list[str]]:
    header = columns(spec)
    results = out / RESULTS
    spec_path = out / SPEC
    if results.exists() and results.stat().st_size > 0:
        if not resume:
            raise SweepError(
                f"{results} already holds results: pass --resume to continue that sweep, or "
                "choose another output folder"
            )
        if spec_path.exists():
            old = json.loads(spec_path.read_text(encoding="utf-8"))
            new = _canonical(spec.to_dict())
            if old != new:
                diff = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
                raise SweepError(
                    f"cannot resume: the sweep in {out} was run with a different spec "
                    f"(differs in: {', '.join(diff)})"
                )
        rows, dirty = read_results(results, header)
        bad = [k for k in rows if not 0 <= k < spec.n_points]
        if bad:
            raise SweepError(f"{results}: point indices {bad[:5]} are outside this sweep")
        if retry_failed:
            failed = [k for k, r in rows.items() if r[-1]]
            for k in failed:
                del rows[k]
            dirty = dirty or bool(failed)
        if dirty:
            write_csv(results, header, (rows[k] for k in sorted(rows)))
    else:
        rows = {}
    out.mkdir(parents=True, exist_ok=True)
    write_json(spec_path, spec.to_dict())
    return rows, header


def run_sweep(
    spec: SweepSpec,
    out_dir: str | os.PathLike[str],
    *,
    serial: bool = False,
    scheduler: str | None = None,
    workers: int | None = None,
    resume: bool = False,
    retry_failed: bool = False,
    progress: bool = True,
    plots: bool = True,
    point_fn: PointFunction | None = None,
    client: Any = None,
) -> SweepReport:
    """Run (or resume) a sweep into ``out_dir``; see the module docstring.

    Parameters
    ----------
    spec : SweepSpec
        The validated sweep.
    out_dir : path
        Output folder (created); ``results.csv`` is appended row by row as points finish.
    serial : bool
        Run in this process, without Dask.
    scheduler : str, optional
        Address of an existing Dask scheduler (used when ``serial`` is false and no
        ``client`` is given).
    workers : int, optional
        Processes of a new LocalCluster (default: the CPU count).
    resume : bool
        Continue a sweep in ``out_dir`` with the same spec, skipping its finished points.
    retry_failed : bool
        With ``resume``: recompute the points that recorded an error.
    progress : bool
        Show a progress bar.
    plots : bool
        Draw the maps (:func:`write_plots`) once every point is done.
    point_fn : callable, optional
        Replaces the study's point function (tests); on Dask it must be importable by the
        workers.
    client : dask.distributed.Client, optional
        An existing client (takes precedence over ``scheduler`` and ``workers``).

    Returns
    -------
    SweepReport
        Counts of points (skipped, computed, failed), completeness, wall time, plots and the
        execution details also written to ``summary.json``.

    Raises
    ------
    SweepError
        ``out_dir`` holds results and ``resume`` is false, the spec differs from the one
        resumed, or the results file is malformed or holds indices outside the sweep.
    OSError
        A file cannot be read or written.
    """
    t0 = time.perf_counter()
    out = Path(out_dir)
    done, header = _prepare(spec, out, resume, retry_failed)
    results = out / RESULTS
    todo = [k for k in range(spec.n_points) if k not in done]
    n_failed_before = sum(1 for r in done.values() if r[-1])
    execution: dict[str, Any] = {"mode": "serial" if serial else "dask"}
    n_computed = n_failed = 0
    bar = tqdm(
        total=spec.n_points,
        initial=len(done),
        desc=f"sweep {spec.study}",
        unit="pt",
        disable=not progress,
        smoothing=0.0,
    )
    try:
        with results.open("a", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh, lineterminator="\n")
            if fh.tell() == 0:
                writer.writerow(header)
                fh.flush()

            def consume(rows: Iterator[list[str]]) -> None:
                nonlocal n_computed, n_failed
                for row in rows:
                    writer.writerow(row)
                    fh.flush()
                    done[int(row[0])] = row
                    n_computed += 1
                    n_failed += bool(row[-1])
                    bar.update(1)
                    if n_failed:
                        bar.set_postfix(failed=n_failed + n_failed_before, refresh=False)

            if not todo:
                pass
            elif serial:
                consume(_serial_rows(spec, todo, point_fn))
            elif client is not None:
                execution["scheduler"] = client.scheduler.address
                consume(_dask_rows(spec, todo, client, point_fn))
            else:
                with _dask_client(scheduler, workers) as (cl, info):
                    execution.update(info)
                    consume(_dask_rows(spec, todo, cl, point_fn))
    finally:
        bar.close()
    finished = len(done) == spec.n_points
    if finished:
        write_csv(results, header, (done[k] for k in sorted(done)))
    report = SweepReport(
        out_dir=out,
        results=results,
        n_points=spec.n_points,
        n_skipped=spec.n_points - len(todo),
        n_computed=n_computed,
        n_failed=n_failed + n_failed_before,
        finished=finished,
        wall_time=time.perf_counter() - t0,
        execution=execution,
    )
    if finished and spec.study == "controllers":
        report.by_controller, report.tables = write_tables(spec, results, out)
    if plots and finished:
        report.plots = write_plots(spec, done, out / PLOTS)
    write_json(
        out / SUMMARY,
        {
            "points": report.n_points,
            "skipped_as_done": report.n_skipped,
            "computed": report.n_computed,
            "failed": report.n_failed,
            "finished": report.finished,  # every point has its row
            "complete": report.complete,  # ... and none failed
            "wall_time_s": report.wall_time,
            **({"feed": spec.feed} if spec.study != "axial" else {}),
            "execution": _canonical(execution),
        },
    )
    return report


# --------------------------------------------------------------------------------------------
# plots
# --------------------------------------------------------------------------------------------


def write_plots(spec: SweepSpec, rows: dict[int, list[str]], out_dir: Path) -> list[Path]:
    """Draw the maps of a finished sweep: one PNG per metric of ``spec.metrics``.

    Over the swept plane (or line); for the controllers study one figure per severity metric
    with a panel per controller on a shared colour scale, and the map of the best controller.

    Parameters
    ----------
    spec : SweepSpec
        The sweep.
    rows : dict of int to list of str
        The results rows by point index (as :func:`read_results` gives them); missing points
        and empty fields are drawn as failed.
    out_dir : Path
        Folder of the PNGs (``<metric>.png``, written atomically).

    Returns
    -------
    list of Path
        The PNG files, in the order of ``spec.metrics``.
    """
    kinds = dict(METRICS[spec.study])
    reference = spec.reference_values()
    title_base = f"{spec.study} sweep, base {Path(spec.base_label).name}"
    if spec.study == "controllers":
        return _controller_plots(spec, rows, out_dir, title_base)
    paths = []
    for metric in spec.metrics:
        raw = _column(spec, rows, metric)
        kind = kinds[metric]
        values: list[Any] = raw if kind == "str" else [float(v) if v else None for v in raw]
        fig = sweep_figure(
            metric,
            kind,
            {"": values},
            spec.axes,
            reference,
            f"{title_base}: {metric}",
            axis_labels=AXIS_LABELS,
            note=spec.feed if spec.study != "axial" else "",
        )
        paths.append(save_figure(fig, out_dir / f"{metric}.png"))
    return paths


def _column(spec: SweepSpec, rows: dict[int, list[str]], name: str) -> list[str]:
    col = columns(spec).index(name)
    return [rows[k][col] if k in rows else "" for k in range(spec.n_points)]


#: The style of a controller's linearised boundary (the unstable side hatched).
UNSTABLE = {"ls": "-", "lw": 1.4, "hatch": "///"}


def _boundary_overlays(
    spec: SweepSpec, rows: dict[int, list[str]], out_dir: Path
) -> dict[str, list[Overlay]]:
    """The linearised stability boundaries of a 2-D controllers map, per panel.

    On a grid four times finer than the map's (:func:`~drillstring.apps.sweep.studies.
    linear_boundary`, also written to ``boundary.csv``) when the design inputs A, taubar_crit
    are the same at every point; else, and for a gain designed at each point, from the
    abscissae the points recorded. The open loop's boundary is on every panel.
    """
    if len(spec.axes) != 2:
        return {}
    ok = [k for k in range(spec.n_points) if k in rows and not rows[k][-1]]
    if not ok:
        return {}
    a_col, t_col = columns(spec).index("A"), columns(spec).index("taubar_crit")
    inputs = {(rows[k][a_col], rows[k][t_col]) for k in ok}
    fine: dict[str, np.ndarray] = {}
    x, y = spec.axes[0].values(), spec.axes[1].values()
    xf, yf = x, y
    model = boundary_model(spec.options.elements)
    if len(inputs) == 1:
        A, tc = (float(v) for v in inputs.pop())
        boundary = linear_boundary(spec, DesignInputs(math.nan, math.nan, A=A, taubar_crit=tc))
        fine, xf, yf = boundary.abscissa, boundary.x, boundary.y
        names = list(fine)
        X, Y = np.meshgrid(xf, yf, indexing="ij")
        write_csv(
            out_dir / "boundary.csv",
            [spec.axes[0].param, spec.axes[1].param, *(f"abscissa.{n}" for n in names)],
            zip(X.ravel(), Y.ravel(), *(fine[n].ravel() for n in names), strict=True),
        )

    def coarse(column: str) -> np.ndarray:
        raw = _column(spec, rows, column)
        return np.array([float(v) if v else math.nan for v in raw]).reshape(x.size, y.size)

    ol_label = f"open loop: stability boundary of the {model}"
    open_loop = (
        Overlay(xf, yf, fine[OPEN_LOOP], ol_label, {"ls": ":", "lw": 1.5})
        if OPEN_LOOP in fine
        else Overlay(x, y, coarse("open_loop_abscissa_scaled"), ol_label, {"ls": ":", "lw": 1.5})
    )
    open_loop = replace(open_loop, subject="open loop, linearised")
    out = {}
    own_label = f"hatched: unstable in the {model} (not the runs' outcome)"
    for c in spec.options.controllers:
        if c in fine:
            own = Overlay(xf, yf, fine[c], own_label, UNSTABLE, "closed loop, linearised")
        else:
            own = Overlay(x, y, coarse(controller_column("linear_abscissa", c)),
                          own_label + " (map points)", UNSTABLE,
                          "closed loop, linearised")  # fmt: skip
        out[c] = [own, open_loop]
    return out


#: Metrics shown only where the run settled (steady): elsewhere they have no meaning.
SETTLED_ONLY = ("settling_time",)
#: A controller's outcomes of a complete run; any other (a status code) is a stopped run.
_COMPLETE = (*OUTCOMES, "no_design")


def shown_values(metric: str, raw: Sequence[str], outcomes: Sequence[str]) -> list[float | None]:
    """The values of a controller's numeric metric its map colours (None: grey).

    A run that stopped (its outcome a status code: reverse rotation, bit bounce, ...) is grey
    on every numeric map (its stall flag would read 0 and its severity is of a run cut short);
    the settling time (:data:`SETTLED_ONLY`) is coloured only where the run ended steady.

    Parameters
    ----------
    metric : str
        A name of :data:`~drillstring.apps.sweep.metrics.CONTROLLER_METRICS`.
    raw : sequence of str
        The metric's column of ``results.csv`` per point ("" for no value).
    outcomes : sequence of str
        The same controller's outcome per point.

    Returns
    -------
    list of float or None
    """
    return [
        float(v) if v and o in _COMPLETE and (metric not in SETTLED_ONLY or o == "steady") else None
        for v, o in zip(raw, outcomes, strict=True)
    ]


def _controller_plots(
    spec: SweepSpec, rows: dict[int, list[str]], out_dir: Path, title_base: str
) -> list[Path]:
    kinds = dict(CONTROLLER_METRICS)
    reference = spec.reference_values()
    drive = spec.options.top_drive
    sensing = textwrap.wrap(sensing_note(spec.options.controllers), 120, break_on_hyphens=False)
    elements = spec.options.elements
    string = (
        "the paper's one-mode string"
        if elements == 1
        else f"the distributed string, {elements} elements"
    )
    braking = "with braking" if spec.options.braking == "four-quadrant" else "without braking"
    note = "\n".join(
        [
            f"{spec.feed}; {string}; top drive: {drive}, {braking}; grey: a run that stopped "
            "(reverse rotation, bit bounce) or failed",
            *sensing,
        ]
    )
    overlays = _boundary_overlays(spec, rows, out_dir)
    scales = (
        [spec.point_scales(k) for k in range(spec.n_points)]
        if isinstance(spec.base, PhysicalParams)
        else None
    )
    paths = []
    for metric in spec.metrics:
        if metric == "best":
            values = _column(spec, rows, "best")
            fig = sweep_figure(
                "best",
                "str",
                {"": values},
                spec.axes,
                reference,
                f"{title_base}: best controller (of the runs neither stopped nor stalled, the "
                f"lowest severity; within {spec.options.tie:g} of it the lowest peak torque)",
                categories=RIG_CONTROLLERS,
                palette=CONTROLLER_COLORS,
                axis_labels=AXIS_LABELS,
                note=note,
            )
        else:
            kind = kinds[metric]
            label = metric
            panels: dict[str, list[Any]] = {}
            for c in spec.options.controllers:
                raw = _column(spec, rows, controller_column(metric, c))
                if kind == "str":
                    panels[c] = raw
                    continue
                outcome = _column(spec, rows, controller_column("outcome", c))
                values = shown_values(metric, raw, outcome)
                if scales is not None:  # a physical base: SI units
                    for k, v in enumerate(values):
                        factor, unit = si_factor(metric, scales[k].C, scales[k].t_star)
                        values[k] = None if v is None else v * factor
                    label = f"{metric} [{unit}]" if unit else metric
                panels[c] = values
            if metric in SETTLED_ONLY:
                label += " (steady runs only)"
            fig = sweep_figure(
                label,
                kind,
                panels,
                spec.axes,
                reference,
                f"{title_base}: {metric}",
                log=metric == "peak_torque",
                categories=(*OUTCOMES, "no_design") if metric == "outcome" else None,
                palette=OUTCOME_COLORS,
                axis_labels=AXIS_LABELS,
                note=note,
                overlays=overlays,
            )
        paths.append(save_figure(fig, out_dir / f"{metric}.png"))
    return paths


# --------------------------------------------------------------------------------------------
# command line
# --------------------------------------------------------------------------------------------


def build_parser(prog: str = "drillstring sweep") -> argparse.ArgumentParser:
    """Argument parser of the ``sweep`` subcommand.

    Parameters
    ----------
    prog : str
        Program name shown in usage and error messages.

    Returns
    -------
    argparse.ArgumentParser
        ``spec`` and the options ``--out`` (required), ``--scheduler``, ``--workers``,
        ``--base-dir``, ``--resume``, ``--retry-failed``, ``--no-plots``, ``--no-progress``,
        ``--max-points``.
    """
    ap = argparse.ArgumentParser(
        prog=prog,
        description="Parameter sweep on Dask: open-loop / closed-loop / axial / controllers maps "
        "(one task per point, results streamed to CSV, heat maps).",
    )
    ap.add_argument("spec", type=Path, help="sweep description (.toml or .json)")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument(
        "--scheduler",
        default=None,
        help="address of an existing Dask scheduler (default: a LocalCluster on this machine)",
    )
    ap.add_argument(
        "--workers",
        type=int,
        default=None,
        help="worker processes of the LocalCluster (default: CPU count); 0 runs serially in "
        "this process without Dask",
    )
    ap.add_argument(
        "--base-dir",
        type=Path,
        default=None,
        help="folder the spec's relative file names (base set, gains files) are taken from "
        "(default: the spec's folder)",
    )
    ap.add_argument("--resume", action="store_true", help="skip the points already in the output")
    ap.add_argument(
        "--retry-failed", action="store_true", help="with --resume: recompute failed points too"
    )
    ap.add_argument("--no-plots", action="store_true", help="do not draw the metric maps")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    ap.add_argument(
        "--max-points",
        type=int,
        default=MAX_POINTS,
        help=f"the largest grid accepted (default {MAX_POINTS}, checked before anything runs)",
    )
    return ap


def sweep_main(argv: Sequence[str] | None = None) -> int:
    """Run the ``sweep`` subcommand: load the spec, :func:`run_sweep`, print the counts.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after ``sweep`` (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit code: 0 complete (every point computed without an error), 1 finished with failed
        points (their errors are in ``results.csv``; ``--resume --retry-failed`` recomputes
        them), 2 bad input (options, spec, a grid larger than ``--max-points``, resume mismatch,
        files; also argparse's code for bad options, raised as ``SystemExit``), 130
        interrupted (the finished points are kept for ``--resume``).
    """
    args = build_parser().parse_args(argv)
    prog = "drillstring sweep"
    if args.workers is not None and args.workers < 0:
        print(f"{prog}: --workers must be >= 0, got {args.workers}", file=sys.stderr)
        return 2
    if args.scheduler and args.workers is not None:
        print(
            f"{prog}: --workers applies to the local cluster, not to --scheduler", file=sys.stderr
        )
        return 2
    if args.retry_failed and not args.resume:
        print(f"{prog}: --retry-failed needs --resume", file=sys.stderr)
        return 2
    if args.max_points < 1:
        print(f"{prog}: --max-points must be >= 1, got {args.max_points}", file=sys.stderr)
        return 2
    try:
        spec = load_spec(args.spec, max_points=args.max_points, base_dir=args.base_dir)
        report = run_sweep(
            spec,
            args.out,
            serial=args.workers == 0,
            scheduler=args.scheduler,
            workers=args.workers,
            resume=args.resume,
            retry_failed=args.retry_failed,
            progress=not args.no_progress,
            plots=not args.no_plots,
        )
    except (SweepSpecError, SweepError, OSError) as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            f"{prog}: interrupted; finished points are in {args.out / RESULTS}, "
            "continue with --resume",
            file=sys.stderr,
        )
        return 130
    print(
        f"{report.n_points} points ({report.n_skipped} already done, {report.n_computed} computed,"
        f" {report.n_failed} failed) in {report.wall_time:.1f} s; results: {report.results}"
    )
    if report.plots:
        print(f"maps: {report.out_dir / PLOTS} ({len(report.plots)} PNG)")
    if report.n_failed:
        what = "every point" if report.n_failed == report.n_points else f"{report.n_failed} points"
        print(
            f"{prog}: {what} failed (the error column of {report.results}; recompute them with "
            "--resume --retry-failed)",
            file=sys.stderr,
        )
        return 1
    return 0
