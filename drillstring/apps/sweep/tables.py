"""The controllers study's tables beside ``results.csv``: how often each controller ends in
each outcome (``by_controller.csv``) and, on a physical base swept over the surface speed and the
nominal weight on bit, the results in SI (``map_si.csv``). :func:`~drillstring.apps.sweep.runner.
run_sweep` writes them when the sweep is finished (``docs/controllers.md``, "Maps")."""

from __future__ import annotations

import csv
import math
from collections import Counter
from pathlib import Path
from typing import Any

from drillstring.analysis.severity import OUTCOMES
from drillstring.apps.sweep.metrics import (
    CONTROLLER_METRICS,
    SI_DISPLAY,
    controller_column,
    si_factor,
)
from drillstring.apps.sweep.spec import PHYSICAL_DERIVED, SweepSpec
from drillstring.fileio import write_csv
from drillstring.model.params import PhysicalParams

__all__ = ["BY_CONTROLLER", "MAP_OUTCOMES", "MAP_SI", "count_outcomes", "write_tables"]

#: The per-controller table (:func:`count_outcomes`).
BY_CONTROLLER = "by_controller.csv"
#: The map's table in SI (:func:`write_map_si`); ``results.csv`` is the sweep's working file
#: (scaled metrics, what ``--resume`` reads).
MAP_SI = "map_si.csv"
#: The outcomes counted per controller in ``by_controller.csv`` (a stopped run counts under
#: ``stopped``, and also under its status code when that is reverse rotation or bit bouncing).
MAP_OUTCOMES = (*OUTCOMES, "no_design", "reverse_rotation", "bit_bounce")
#: The columns of ``by_controller.csv``.
BY_CONTROLLER_COLUMNS = ("controller", *MAP_OUTCOMES, "stopped", "failed_points", "best")
#: Column-name tokens of the SI units of :data:`~drillstring.apps.sweep.metrics.SI_DISPLAY`.
_UNIT_TOKENS = {"kN m": "kNm", "kW": "kW", "rpm": "rpm", "s": "s", "1/s": "per_s"}
#: Dimensionless controller metrics (no unit in their name).
_PLAIN = {"outcome", "utr", "severity", "stick_fraction", "stall", "saturated_fraction"}


def _read(results: Path) -> list[dict[str, str]]:
    with open(results, newline="", encoding="utf-8") as fh:
        return sorted(csv.DictReader(fh), key=lambda r: int(r["index"]))


def count_outcomes(spec: SweepSpec, results: Path) -> list[dict[str, Any]]:
    """Per controller of the study: how many points end in each outcome, stopped, failed, and
    how often it is the best.

    Parameters
    ----------
    spec : SweepSpec
        A controllers study.
    results : Path
        Its ``results.csv``.

    Returns
    -------
    list of dict
        One row per controller, keys :data:`BY_CONTROLLER_COLUMNS`.
    """
    rows = _read(results)
    best = Counter(r["best"] for r in rows if not r["error"])
    out = []
    for c in spec.options.controllers:
        outcomes = Counter(r[controller_column("outcome", c)] for r in rows if not r["error"])
        entry: dict[str, Any] = {"controller": c}
        for o in MAP_OUTCOMES:
            entry[o] = outcomes.pop(o, 0)
        entry["stopped"] = sum(entry[o] for o in MAP_OUTCOMES[len(OUTCOMES) + 1 :]) + sum(
            outcomes.values()
        )
        entry["failed_points"] = sum(1 for r in rows if r["error"])
        entry["best"] = best.get(c, 0)
        out.append(entry)
    return out


def write_map_si(spec: SweepSpec, results: Path, path: Path) -> Path:
    """The controller map's ``results.csv`` in SI, the unit in each column name.

    The axes (``rpm``, ``W0_kN``), the imposed speed and hook speed (``Omega0_rad_per_s``,
    ``V0_m_per_s``), the design inputs A and taubar_crit (``_scaled``: the paper's scaled
    slope and delay), the open loop's and each controller's linear abscissa [1/s], and per
    controller (``<metric>_<unit>.<controller>``) the severity metrics with each point's rig
    scales (peak torque in kN m, power in kW, table speed in rpm, times in s; outcome, UTR,
    severity, stick and saturated fractions and the stall flag have no unit); ``best``,
    ``wall_time_s``, ``error``.

    Parameters
    ----------
    spec : SweepSpec
        A controllers study on a physical base over the derived axes ``rpm``, ``W0_kN``.
    results : Path
        Its ``results.csv``.
    path : Path
        Where to write.

    Returns
    -------
    Path
    """
    rows = _read(results)
    names: list[tuple[str, str, str | None]] = []  # (out name, in name, metric or None)
    for m, _ in CONTROLLER_METRICS:
        for c in spec.options.controllers:
            if m in _PLAIN:
                names.append((controller_column(m, c), controller_column(m, c), None))
            else:
                token = _UNIT_TOKENS[SI_DISPLAY[m][2]]
                names.append((controller_column(f"{m}_{token}", c), controller_column(m, c), m))
    grid = ["i", "j"][: len(spec.axes)]
    header = [
        "index", *grid, *spec.names, "Omega0_rad_per_s", "V0_m_per_s", "A_scaled",
        "taubar_crit_scaled", "open_loop_abscissa_per_s", *(n for n, _, _ in names), "best",
        "wall_time_s", "error",
    ]  # fmt: skip

    def num(v: str) -> float:
        return float(v) if v not in ("", None) else math.nan

    out = []
    for r in rows:
        k = int(r["index"])
        sc = spec.point_scales(k)
        line: list[Any] = [k, *(r[g] for g in grid), *(r[n] for n in spec.names), r["Omega0"],
                           r["V0"], r["A"], r["taubar_crit"],
                           num(r["open_loop_abscissa_scaled"]) / sc.t_star]  # fmt: skip
        for _, src, metric in names:
            v = r.get(src, "")
            if metric is None:
                line.append(v)
            else:
                factor, _ = si_factor(metric, sc.C, sc.t_star)
                line.append(num(v) * factor)
        line += [r["best"], r["seconds"], r["error"]]
        out.append(line)
    return write_csv(path, header, out)


def write_tables(
    spec: SweepSpec, results: Path, out_dir: Path
) -> tuple[list[dict[str, Any]], dict[str, Path]]:
    """The controllers study's tables of a finished sweep: ``by_controller.csv`` and, on a
    physical base whose axes are the derived ``rpm``/``W0_kN``, ``map_si.csv``.

    Parameters
    ----------
    spec : SweepSpec
        A controllers study.
    results : Path
        Its ``results.csv``.
    out_dir : Path
        The sweep's folder.

    Returns
    -------
    rows : list of dict
        :func:`count_outcomes`.
    files : dict of str to Path
        ``"by_controller"`` and, where written, ``"si"``.
    """
    table = count_outcomes(spec, results)
    files = {
        "by_controller": write_csv(
            out_dir / BY_CONTROLLER,
            BY_CONTROLLER_COLUMNS,
            ([r[h] for h in BY_CONTROLLER_COLUMNS] for r in table),
        )
    }
    if isinstance(spec.base, PhysicalParams) and set(spec.names) <= set(PHYSICAL_DERIVED):
        files["si"] = write_map_si(spec, results, out_dir / MAP_SI)
    return table, files
