"""The paper's closed loop (Section V) as a co-simulated system, and its monolithic twin.

Two FMI 2.0 units, ``DrillStringPlant`` (model (11)-(14), (17)) and ``TorsionalController``
(law (29)-(31)), coupled by :class:`~drillstring.orchestration.master.Master`::

    plant.phi, plant.dphi, plant.theta, plant.dtheta -> controller (same names)
    controller.R_minus_R0 -> plant.R_minus_R0

Both units get their parameters from one gains file as start values (the plant the scaled
parameter set stored with the gains, the controller ``F``, ``K0``, ``R_ff``), so a co-simulation
and :func:`~drillstring.orchestration.monolithic.run_monolithic` always describe the same
system, whatever gains the FMUs were built with. :func:`errors_on_grid` compares the two at
the co-simulation's communication points, which must lie on the monolithic output grid.
"""

from __future__ import annotations

import contextlib
import math
import os
import subprocess
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drillstring.controller.gains import GainsFile, read_gains
from drillstring.model.control import LATCH_MODES
from drillstring.model.engine import Engine, EngineOptions
from drillstring.model.params import ScaledParams
from drillstring.model.simulate import SimulationResult
from drillstring.orchestration.master import Master, Unit
from drillstring.orchestration.monolithic import closed_loop_law, run_monolithic
from drillstring.orchestration.results import CosimResult

__all__ = [
    "PLANT_FMU",
    "CONTROLLER_FMU",
    "CONNECTIONS",
    "RECORD",
    "LoopSetup",
    "load_gains",
    "fmu_paths",
    "build_fmus_into",
    "plant_start_values",
    "controller_start_values",
    "closed_loop_master",
    "run_cosim",
    "run_reference",
    "reference_at",
    "grid_indices",
    "errors_on_grid",
]

PLANT_FMU = "DrillStringPlant.fmu"
CONTROLLER_FMU = "TorsionalController.fmu"
FEEDBACK = ("phi", "dphi", "theta", "dtheta")
CONNECTIONS: tuple[str, ...] = (
    *(f"plant.{n} -> controller.{n}" for n in FEEDBACK),
    "controller.R_minus_R0 -> plant.R_minus_R0",
)
#: plant outputs recorded besides the connected ones
RECORD: tuple[str, ...] = (
    "plant.u",
    "plant.du",
    "plant.d",
    "plant.g",
    "plant.tau_n",
    "plant.mode",
    "plant.stick_events",
    "plant.torsional_stick",
    "plant.bit_bounce",
)
_ROOT = Path(__file__).resolve().parents[1]
#: ScaledParams field -> plant FMU parameter name
_PARAM_NAMES = {
    "n": "n",
    "psi": "psi",
    "gamma": "gamma",
    "eta": "eta",
    "lam": "lambda",
    "beta": "beta",
    "rho": "rho",
    "v0": "v0",
    "omega0": "omega0",
}


@dataclass(frozen=True)
class LoopSetup:
    """One closed-loop experiment: initial bit velocity perturbation ``dphi0``, controller
    switch-on ``t_on`` with bumpless ``latch`` (NOTES.md section 7), ``enabled`` (False:
    R_ff only), the torsional-stick model of the plant and the engine's RK4 step ``h``."""

    dphi0: float = -2.5
    t_on: float = 0.0
    latch: str = "none"
    enabled: bool = True
    torsional_stick: bool = False
    h: float = 5e-4

    def __post_init__(self) -> None:
        for name in ("dphi0", "t_on", "h"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v)):
                raise ValueError(f"LoopSetup.{name} must be a finite number, got {v!r}")
        if self.h <= 0:
            raise ValueError(f"LoopSetup.h (engine step) must be > 0, got {self.h!r}")
        if self.latch not in LATCH_MODES:
            raise ValueError(f"LoopSetup.latch must be one of {LATCH_MODES}, got {self.latch!r}")
        EngineOptions(h=self.h)  # same validation as the engine

    def engine_options(self) -> EngineOptions:
        return EngineOptions(h=self.h, torsional_stick=self.torsional_stick)


def load_gains(gains: GainsFile | str | os.PathLike[str]) -> GainsFile:
    return gains if isinstance(gains, GainsFile) else read_gains(gains)


def fmu_paths(fmus_dir: str | os.PathLike[str]) -> tuple[Path, Path]:
    """(plant, controller) FMU files in ``fmus_dir``; a clear error when one is missing."""
    d = Path(fmus_dir)
    paths = (d / PLANT_FMU, d / CONTROLLER_FMU)
    missing = [p.name for p in paths if not p.is_file()]
    if missing:
        raise ValueError(
            f"no {' or '.join(missing)} in {str(d)!r} (build them with `python build_fmus.py "
            f"--gains GAINS.json --out {d}`)"
        )
    return paths


def build_fmus_into(out_dir: str | os.PathLike[str], gains: str | os.PathLike[str]) -> Path:
    """Build both FMUs with ``build_fmus.py`` (a subprocess, so the builder does not touch
    this process) into ``out_dir``; returns ``out_dir``."""
    script = _ROOT / "build_fmus.py"
    if not script.is_file():
        raise ValueError(f"{script} not found: pass a folder of prebuilt FMUs instead")
    cmd = [sys.executable, str(script), "--gains", str(gains), "--out", str(out_dir)]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=_ROOT, timeout=900)
    if proc.returncode != 0:
        raise RuntimeError(f"build_fmus.py failed ({proc.returncode}):\n{proc.stderr.strip()}")
    fmu_paths(out_dir)
    return Path(out_dir)


def plant_start_values(params: ScaledParams, setup: LoopSetup) -> dict[str, Any]:
    """Plant FMU start values: the scaled parameter set, dphi/dtau(0), engine options."""
    values: dict[str, Any] = {fmu: getattr(params, f) for f, fmu in _PARAM_NAMES.items()}
    values["dphi0"] = float(setup.dphi0)
    values["h"] = float(setup.h)
    values["torsional_stick_model"] = bool(setup.torsional_stick)
    return values


def controller_start_values(gains: GainsFile, setup: LoopSetup) -> dict[str, Any]:
    """Controller FMU start values: F, K0, R_ff of the gains file, switch-on, latch."""
    values: dict[str, Any] = {f"F[{i + 1}]": float(f) for i, f in enumerate(gains.F)}
    values.update(
        K0=float(gains.K0),
        R_ff=float(gains.R_ff),
        t_on=float(setup.t_on),
        enabled=bool(setup.enabled),
        # an Enumeration of the FMU: item values 1, 2, 3 in the order of LATCH_MODES
        latch=LATCH_MODES.index(setup.latch) + 1,
    )
    return values


def closed_loop_master(
    fmus_dir: str | os.PathLike[str],
    gains: GainsFile | str | os.PathLike[str],
    setup: LoopSetup | None = None,
    *,
    record: Sequence[str] = RECORD,
) -> Master:
    """A :class:`Master` of plant and controller with the parameters of the gains file."""
    g = load_gains(gains)
    setup = setup or LoopSetup()
    plant, controller = fmu_paths(fmus_dir)
    units = [
        Unit("plant", plant, plant_start_values(g.params, setup)),
        Unit("controller", controller, controller_start_values(g, setup)),
    ]
    return Master(units, CONNECTIONS, record=record)


@contextlib.contextmanager
def kept_sys_path() -> Iterator[None]:
    """Undo the ``sys.path`` entries pythonfmu adds on every instantiation (the FMU's
    resources): processes started later must import the repository's ``drillstring``."""
    saved = list(sys.path)
    try:
        yield
    finally:
        sys.path[:] = saved


def run_cosim(master: Master, tau_end: float, H: float | None, **kwargs: Any) -> CosimResult:
    """``master.run(tau_end, H, progress=False, **kwargs)`` keeping ``sys.path``."""
    kwargs.setdefault("progress", False)
    with kept_sys_path():
        return master.run(tau_end, H, **kwargs)


def run_reference(
    gains: GainsFile | str | os.PathLike[str],
    setup: LoopSetup,
    tau_end: float,
    dt_out: float,
) -> SimulationResult:
    """The monolithic closed loop (law evaluated continuously), sampled every ``dt_out``."""
    g = load_gains(gains)
    return run_monolithic(
        g,
        tau_end,
        initial={"dphi": setup.dphi0},
        t_on=setup.t_on,
        latch=setup.latch,
        enabled=setup.enabled,
        params=g.params,
        options=setup.engine_options(),
        dt_out=dt_out,
        progress=False,
    )


def reference_at(
    gains: GainsFile | str | os.PathLike[str],
    setup: LoopSetup,
    times: np.ndarray,
    names: Sequence[str] = ("du", "dphi"),
) -> dict[str, np.ndarray]:
    """The monolithic closed loop (same engine and law as :func:`run_reference`) landing
    exactly on the increasing ``times`` (e.g. an adaptive run's communication points);
    NaN after an early stop."""
    g = load_gains(gains)
    law = closed_loop_law(g, setup.t_on, setup.latch) if setup.enabled else g.R_ff
    engine = Engine(
        g.params, options=setup.engine_options(), initial={"dphi": setup.dphi0}, control=law
    )
    out = {n: np.full(len(times), np.nan) for n in names}
    for i, t in enumerate(np.asarray(times, dtype=float)):
        if t > engine.tau and not engine.advance(t).ok:
            break
        values = engine.outputs()
        for n in names:
            out[n][i] = values[n]
    return out


def grid_indices(times: np.ndarray, dt: float, n: int) -> np.ndarray:
    """Indices k with ``times == k*dt`` (to 1e-9 dt) on a grid of ``n`` points; an error
    names the first time that is not on it."""
    k = np.rint(np.asarray(times) / dt).astype(np.int64)
    bad = (np.abs(k * dt - times) > 1e-9 * dt) | (k < 0) | (k >= n)
    if np.any(bad):
        t = float(np.asarray(times)[np.argmax(bad)])
        raise ValueError(f"communication point {t!r} is not on the monolithic grid of step {dt!r}")
    return k


def errors_on_grid(
    res: CosimResult, mono: SimulationResult, dt: float, names: Sequence[str] = ("du", "dphi")
) -> dict[str, float]:
    """Max |cosim - monolithic| of ``plant.<name>`` over the common communication points
    (the co-simulated ones that the monolithic run also reached)."""
    t = res.time
    t = t[t <= mono.tau[-1] + 1e-9 * dt]
    k = grid_indices(t, dt, len(mono.tau))
    out = {}
    for name in names:
        diff = res[f"plant.{name}"][: len(k)] - getattr(mono, name)[k]
        out[name] = float(np.max(np.abs(diff))) if len(diff) else math.nan
    return out
