"""``drillstring cosim``: a co-simulation from an SSP package with the project's master.

Examples::

    drillstring cosim build/DrillStringClosedLoopSI.ssp --out out/cosim            # Fig. 5, SI
    drillstring cosim build/DrillStringClosedLoop.ssp --out out/fig6 --variant fig6
    drillstring cosim build/DrillStringTopDrive.ssp --out out/zt --variant fig6-z-torque
    drillstring cosim my_loop.ssp --out out/mine --stop-time 10 --step 1e-3

The SSD of the package (``SystemStructure.ssd``, or the variant named) makes the system: its
components, connections and parameter bindings as SSP 1.0 applies them, or the parameter sets
named with ``--parameter-set``
(:meth:`~drillstring.orchestration.master.Master.from_ssp`); the stop time and step default to
the SSD's default experiment. Writes ``cosim.csv`` (FMI
Cross-Check layout: ``"time"`` first, every connected variable and output connector),
``speeds.png`` (bit and table speeds, in rpm for the SI package) and ``cosim.json``. Either unit
system: the variant is recognised by the connections.

:func:`run_si_demo` is the demo's SI step: Fig. 5 from the SI package in Ecos and in the
project's master with the same coupling, each compared with the monolithic solver in SI.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from drillstring.fileio import remove_temporary_folders, save_figure, write_json
from drillstring.model.units import SCALED_UNITS, SI_UNITS, UNITS
from drillstring.orchestration.closed_loop import (
    SI,
    VARIANTS,
    LoopVariant,
    kept_sys_path,
    loop_model_of,
)
from drillstring.orchestration.figures import actuator_note
from drillstring.orchestration.hosts import run_ecos
from drillstring.orchestration.master import Master
from drillstring.orchestration.monolithic import run_monolithic
from drillstring.orchestration.results import CosimResult
from drillstring.orchestration.ssp import SspError
from drillstring.plotting import new_figure
from drillstring.validation import check_out_folder

__all__ = ["cosim_main", "plot_speeds", "run_si_demo", "si_demo_lines", "variant_of"]

#: The speed plot's factor and axis labels in each unit system (SI: rpm over seconds).
_SPEED_AXES = {
    SCALED_UNITS.name: (1.0, r"$\dot\varphi(\tau)$", r"$\dot\theta(\tau)$", r"$\tau$"),
    SI_UNITS.name: (
        UNITS["rad/s"].display_unit("rpm").factor,
        "bit speed [rpm]",
        "table speed [rpm]",
        "t [s]",
    ),
}


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="drillstring cosim",
        description="Co-simulate the system of an SSP 1.0 package with the project's master.",
    )
    ap.add_argument("ssp", type=Path, help="the .ssp archive or an SSP folder")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument(
        "--variant",
        default=None,
        help="the SSD of the package to run, by name or file, e.g. fig6 (default: "
        "SystemStructure.ssd)",
    )
    ap.add_argument(
        "--parameter-set",
        default=None,
        help="parameter set(s) of the package to apply instead of the SSD's bindings, "
        "comma-separated and applied in that order (default: the SSD's bindings; 'none': none)",
    )
    ap.add_argument("--stop-time", type=float, default=None, help="default: the package's")
    ap.add_argument("--step", type=float, default=None, help="macro step (default: the package's)")
    ap.add_argument(
        "--exchange",
        choices=("propagate", "simple"),
        default="propagate",
        help="exchange after a step (simple: libcosim's and Ecos's; default propagate)",
    )
    ap.add_argument("--extrapolation", choices=("zoh", "linear"), default="zoh")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    return ap


def variant_of(connections: Sequence[str]) -> LoopVariant | None:
    """The closed-loop variant whose connections these are.

    Parameters
    ----------
    connections : sequence of str
        Connections as ``"unit.var -> unit.var"`` (spaces are ignored).

    Returns
    -------
    LoopVariant or None
        The first variant of :data:`~drillstring.orchestration.closed_loop.VARIANTS` all of
        whose connections are among ``connections``; None for another system.
    """
    given = {c.replace(" ", "") for c in connections}
    for variant in VARIANTS.values():
        if {c.replace(" ", "") for c in variant.connections} <= given:
            return variant
    return None


def plot_speeds(
    path: str | Path, runs: Sequence[tuple[str, Any]], variant: LoopVariant, title: str = ""
) -> Path:
    """Bit and table speeds of one or more runs against time (SI: rpm over seconds).

    Parameters
    ----------
    path : path
        The PNG (written atomically).
    runs : sequence of (label, result)
        Each result is indexable by ``"time"``, ``"plant.<speed>"``.
    variant : LoopVariant
        The unit system (names and units of the speeds).
    title : str
        Figure title.

    Returns
    -------
    Path
        The PNG.
    """
    bit, table = variant.feedback[1], variant.feedback[3]
    factor, bit_label, table_label, time_label = _SPEED_AXES[variant.units.name]
    fig = new_figure((8.0, 5.0))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    for i, (label, r) in enumerate(runs):
        ls = ("-", "--", ":", "-.")[i % 4]
        ax1.plot(r["time"], factor * np.asarray(r[f"plant.{bit}"]), ls, lw=1.0, label=label)
        ax2.plot(r["time"], factor * np.asarray(r[f"plant.{table}"]), ls, lw=1.0, label=label)
    ax1.set_ylabel(bit_label)
    ax2.set_ylabel(table_label)
    ax2.set_xlabel(time_label)
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
    if len(runs) > 1:
        ax1.legend(fontsize=8)
    if title:
        ax1.set_title(title, fontsize="small" if "\n" in title else None)
    fig.tight_layout()
    return save_figure(fig, path)


def cosim_main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``drillstring cosim``: run an SSP package on the project's master.

    Writes ``cosim.csv``, ``cosim.json`` (the run's summary) and, for a closed-loop package,
    ``speeds.png`` into ``--out``, and prints a one-line summary.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after ``cosim`` (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit code: 0 completed, 1 an FMU stopped the run (the partial results are written),
        2 bad input (package, values or files, an FMU that is not one, or an FMU refusing a
        value before the first step: a parameter, its GUID; the results up to there are
        written; also argparse's code for bad options, raised as ``SystemExit``), each with
        one line naming the component, the variable and the value; 130 interrupted (Ctrl-C;
        a SIGTERM ends it as the signal does, 143), the extracted package and FMUs removed.
    """
    args = _parser().parse_args(argv)
    # a unit's failure is reported here, on one line: not also as the master's log warning
    master_log = logging.getLogger(Master.__module__)
    level = master_log.level
    master_log.setLevel(logging.ERROR)
    try:
        with _ctrl_c_ends_the_command():
            return _cosim(args)
    except KeyboardInterrupt:  # the extracted files are removed on the way out
        print("drillstring cosim: interrupted", file=sys.stderr)
        return 130
    finally:
        master_log.setLevel(level)


@contextmanager
def _ctrl_c_ends_the_command() -> Iterator[None]:
    """Ctrl-C ends the command at once, exit status 130, with the extracted package and FMUs
    removed. Python's KeyboardInterrupt cannot do that here: raised in the FMUs' own Python
    code it becomes an FMU error (``fmi2Fatal`` naming KeyboardInterrupt), in a ctypes callback
    it is lost and the run goes on. From the main thread only (elsewhere: Python's handling)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupted(signum: int, frame: Any) -> None:
        remove_temporary_folders()
        sys.stdout.flush()
        print("drillstring cosim: interrupted", file=sys.stderr, flush=True)
        os._exit(130)

    previous = signal.signal(signal.SIGINT, interrupted)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _cosim(args: argparse.Namespace) -> int:
    try:
        check_out_folder("--out", args.out)
        names: str | list[str] | tuple[()] | None = None
        if args.parameter_set == "none":
            names = ()
        elif args.parameter_set is not None:
            given = [n.strip() for n in args.parameter_set.split(",")]
            names = given[0] if len(given) == 1 else given  # several: applied in this order
        with kept_sys_path():
            master = Master.from_ssp(args.ssp, names, variant=args.variant)
        package = master.ssp
        assert package is not None
        applied = package.bound_sets if names is None else _set_list(names)
        stop = args.stop_time if args.stop_time is not None else package.stop_time
        step = args.step if args.step is not None else package.step
        if stop is None or step is None:
            raise ValueError(
                f"{args.ssp.name} has no default experiment with a fixed step: give --stop-time "
                "and --step"
            )
        start = package.start_time or 0.0
        with master, kept_sys_path():
            result = master.run(
                stop,
                step,
                start_time=start,
                exchange=args.exchange,
                extrapolation=args.extrapolation,
                progress=not args.no_progress,
            )
            columns = master.columns
    except (SspError, ValueError, OSError) as exc:
        print(f"drillstring cosim: {exc}", file=sys.stderr)
        return 2
    out = args.out
    result.to_csv(out / "cosim.csv")
    variant = variant_of([f"{c.source} -> {c.target}" for c in master.system.connections])
    files = {"csv": str(out / "cosim.csv")}
    if variant is not None and len(result.time) > 1:
        files["png"] = str(
            plot_speeds(
                out / "speeds.png",
                [("master", result)],
                variant,
                title=f"{package.system} {package.name}",
            )
        )
    summary = {
        "ssp": str(args.ssp),
        "variant": package.name,
        "ssd": package.file,
        "parameter_set": list(names) if isinstance(names, tuple) else names,
        "sets_applied": list(applied),
        "start_time": start,
        "stop_time": stop,
        "step": step,
        "exchange": args.exchange,
        "extrapolation": args.extrapolation,
        "unit_system": variant.name if variant is not None else None,
        "completed": result.completed,
        "failure": None if result.failure is None else str(result.failure),
        "time_reached": float(result.time[-1]) if len(result.time) else None,
        "steps": result.stats.accepted,
        "wall_time": result.stats.wall_time,
        "columns": list(columns),
        "files": files,
    }
    write_json(out / "cosim.json", summary)
    failure = result.failure
    if failure is not None and failure.in_setup:  # an input the FMU refused: bad input
        print(f"drillstring cosim: {package.file}: {failure.line('component')}", file=sys.stderr)
        return 2
    what = "completed" if failure is None else f"stopped: {failure.line('component')}"
    reached = "" if not len(result.time) else f" to {summary['time_reached']:.6g}"
    print(
        f"drillstring cosim: {package.system} {package.name} ({package.file}), parameter sets "
        f"{', '.join(applied) or 'none'}, {result.stats.accepted} "
        f"steps of {step:g}{reached}: {what}; wrote {out}"
    )
    return 0 if failure is None else 1


def _set_list(names: str | Sequence[str]) -> tuple[str, ...]:
    return (names,) if isinstance(names, str) else tuple(names)


# ------------------------------------------------------------------------------------------------
# the demo's SI step
# ------------------------------------------------------------------------------------------------

#: The plant outputs compared with the monolithic solver (bit speed, axial bit velocity).
_COMPARED = ("bit_speed", "bit_velocity")


def _errors(got: Any, ref: dict[str, np.ndarray], rows: slice) -> dict[str, float]:
    return {
        n: float(np.max(np.abs(np.asarray(got[f"plant.{n}"])[rows] - ref[n]))) for n in _COMPARED
    }


def run_si_demo(
    fmus_dir: str | Path,
    out_dir: str | Path,
    *,
    parameter_set: str = "fig5",
    stop_time: float | None = None,
) -> dict[str, Any]:
    """Fig. 5 from the SI package in Ecos and in the project's master, against the monolithic
    solver in SI.

    Both hosts run the package's default experiment (stop time, fixed step) with the same
    coupling, Ecos's: Jacobi, zero-order hold, every output read after all steps and then
    written, the time accumulated (the master's ``exchange="simple", grid="sum"``). The
    monolithic solver runs the same loop (the package's FMUs' start values with the parameter
    set, converted to the scaled model) with the controller evaluated continuously, sampled at
    the master's communication points and converted to SI
    (:class:`~drillstring.model.units.SIScaling`).

    Parameters
    ----------
    fmus_dir : path
        ``build_fmus.py``'s output folder (with ``DrillStringClosedLoopSI.ssp``).
    out_dir : path
        Where ``si_fig5.csv`` (the master's run), ``si_fig5.png`` (bit and table speeds of the
        three) and ``si_fig5.json`` (the returned numbers) go.
    parameter_set : str
        The package's parameter set (default ``fig5``).
    stop_time : float, optional
        End of the run instead of the package's (a whole number of its steps).

    Returns
    -------
    dict
        ``max_error``: per host (``master``, ``ecos``), the largest absolute difference from the
        monolithic solution of ``bit_speed`` [rad/s] and ``bit_velocity`` [m/s];
        ``relative_error``: the same divided by the largest magnitude of the monolithic signal;
        ``ecos_vs_master``: the largest difference between the two hosts over the plant's
        variables (outputs and the torque it was given), relative to their magnitudes; the
        experiment (``stop_time``, ``step``, ``steps``) and the wall times.
    """
    ssp = Path(fmus_dir) / SI.ssp
    out = Path(out_dir)
    if not ssp.is_file():
        raise ValueError(f"no {SI.ssp} in {str(fmus_dir)!r} (build it with python build_fmus.py)")
    wall: dict[str, float] = {}
    with kept_sys_path(), Master.from_ssp(ssp, parameter_set) as master:
        package = master.ssp
        assert package is not None and package.stop_time is not None and package.step is not None
        stop, step = package.stop_time if stop_time is None else stop_time, package.step
        model = loop_model_of(master, SI)
        t0 = time.perf_counter()
        res: CosimResult = master.run(stop, step, exchange="simple", grid="sum", progress=False)
        wall["master"] = time.perf_counter() - t0
    if not res.completed:
        raise RuntimeError(f"the master's run of {ssp.name} stopped: {res.failure}")
    recorded = [n for n in res.data.dtype.names if n != "time"]
    t0 = time.perf_counter()
    ecos = run_ecos(ssp, parameter_set, stop, step, recorded)
    wall["ecos"] = time.perf_counter() - t0
    scaling = model.scaling
    t0 = time.perf_counter()
    taus = scaling.tau(np.asarray(res.time))
    mono = run_monolithic(model, float(taus[-1]), times=taus)
    wall["monolithic"] = time.perf_counter() - t0
    if not mono.status.ok:
        raise RuntimeError(f"the monolithic run stopped: {mono.status.message}")
    ref = scaling.plant_outputs(mono.data, mono.tau)
    actuator, assumes = actuator_note(model.params, mono)
    n = len(ecos)
    master_err = _errors(res, {k: ref[k] for k in _COMPARED}, slice(None))
    ecos_err = _errors(ecos, {k: ref[k][1 : n + 1] for k in _COMPARED}, slice(None))
    scale = {k: float(np.max(np.abs(ref[k]))) for k in _COMPARED}
    # the plant's variables (outputs and the torque it was given): Ecos reads the outputs again
    # after moving the values along the connections, so its controller output is already the
    # next step's
    diff = {
        name: float(
            np.max(np.abs(ecos[name] - res[name][1 : n + 1]))
            / max(float(np.max(np.abs(res[name]))), 1e-300)
        )
        for name in recorded
        if name.startswith("plant.")
    }
    out.mkdir(parents=True, exist_ok=True)
    res.to_csv(out / "si_fig5.csv")
    mono_rows = {"time": res.time, **{f"plant.{k}": v for k, v in ref.items()}}
    png = plot_speeds(
        out / "si_fig5.png",
        [("master", res), ("Ecos", ecos), ("monolithic", mono_rows)],
        SI,
        title=f"Fig. 5 in SI from {ssp.name} (H = {step:g} s)\n{assumes}",
    )
    summary = {
        "ssp": str(ssp),
        "parameter_set": parameter_set,
        "stop_time": stop,
        "step": step,
        "steps": int(res.stats.accepted),
        "coupling": "Jacobi, zero-order hold, exchange after all steps, accumulated time (Ecos's; "
        "master exchange='simple', grid='sum')",
        "max_error": {"master": master_err, "ecos": ecos_err},
        "relative_error": {
            "master": {k: v / scale[k] for k, v in master_err.items()},
            "ecos": {k: v / scale[k] for k, v in ecos_err.items()},
        },
        "ecos_vs_master": max(diff.values()),
        "ecos_vs_master_by_variable": diff,
        "actuator": actuator,
        "wall_time": wall,
        "files": {"csv": str(out / "si_fig5.csv"), "png": str(png)},
    }
    write_json(out / "si_fig5.json", summary)
    return summary


def si_demo_lines(summary: dict[str, Any]) -> list[str]:
    """The lines the demo prints for :func:`run_si_demo`'s summary.

    Parameters
    ----------
    summary : dict
        As :func:`run_si_demo` returns it (``ssp``, ``parameter_set``, ``steps``, ``step``,
        ``stop_time``, ``coupling``, ``max_error``, ``relative_error``, ``ecos_vs_master``).

    Returns
    -------
    list of str
        One heading line, one line per host (master, Ecos) with its error against the
        monolithic run in SI units, and the Ecos-vs-master difference.
    """
    err, rel = summary["max_error"], summary["relative_error"]
    lines = [
        f"Fig. 5 in SI from {Path(summary['ssp']).name} ({summary['parameter_set']}): "
        f"{summary['steps']} steps of {summary['step']:g} s to {summary['stop_time']:g} s, "
        f"{summary['coupling']}",
    ]
    for host in ("master", "ecos"):
        lines.append(
            f"  {host:<6} vs monolithic: max |error| bit speed {err[host]['bit_speed']:.3e} rad/s "
            f"({rel[host]['bit_speed']:.2e} of its max), axial bit velocity "
            f"{err[host]['bit_velocity']:.3e} m/s ({rel[host]['bit_velocity']:.2e})"
        )
    lines.append(f"  Ecos vs master: max relative difference {summary['ecos_vs_master']:.3e}")
    return lines
