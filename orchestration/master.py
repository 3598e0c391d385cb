"""A general FMI 2.0 co-simulation master on fmpy.

:class:`Master` couples FMI 2.0 co-simulation units (fmpy ``FMU2Slave``) described by
a list of :class:`~drillstring.orchestration.connections.Unit` and a connection list
``"unit.output -> unit.input"`` (validated by
:func:`~drillstring.orchestration.connections.build_system`). It is not tied to the
drill-string FMUs.

Run, in FMI 2.0 terms (standard section 4.2.4, state machine of a co-simulation slave):

1. instantiate, ``fmi2SetupExperiment``, start values, ``fmi2EnterInitializationMode``;
2. *exchange*: outputs read and inputs written in dependency order (the schedule of
   :mod:`.connections`), so every input holds the value of its source before the first
   step -- none starts at a default 0 the system never had; ``fmi2ExitInitializationMode``
   and exchange again;
3. macro steps ``t_n -> t_n + H``:

   * ``scheme="jacobi"``: every unit steps with inputs from ``t_n``;
   * ``scheme="gauss-seidel"``: units step one after the other (default order: units
     whose connected outputs have no direct feedthrough first); a unit whose source
     has already stepped receives that source's fresh value at ``t_n + H``;
   * ``extrapolation="zoh"`` holds an input at its exchanged value over the step;
     ``"linear"`` uses the line through the last two exchanged values (Gauss-Seidel:
     the line between ``t_n`` and the fresh value for already-stepped sources).
     FMI 2.0 units hold inputs constant over a step unless they can interpolate, so the
     master gives the *mean* of that line over the step (its value at ``t_n + H/2``),
     which reproduces its integral exactly: a second-order coupling;
   * after the step, exchange at ``t_n + H`` and record one row. ``exchange="propagate"``
     (default) uses the dependency-ordered schedule of step 2, so an output with direct
     feedthrough is read only after its inputs received their values at ``t_n + H``.
     ``exchange="simple"`` is libcosim's ``fixed_step_algorithm`` (and that of many
     simple fixed-step masters): every connected output is read once, right after the step,
     and only then are all inputs written from those values. A feedthrough output read
     this way was computed from the inputs its unit had *during* the step (those of
     ``t_n``), so a signal passing through a feedthrough unit reaches its target one
     macro step late; with a memoryless controller between two plant outputs and the
     plant input that is a loop delay of ``H`` on top of the hold, an ``O(H)`` change of
     the result. Initialization is the same in both modes (step 2: consistent inputs,
     as libcosim's N rounds of set/read/transfer give for an acyclic system).
     ``grid="ns"`` puts the communication points on libcosim's integer-nanosecond time
     grid, ``t_k = (t0_ns + k*H_ns)/1e9`` with ``H_ns = round(H*1e9)``, ``t0_ns =
     round(t0*1e9)`` (integers, then one division: exactly what libcosim passes to
     ``fmi2DoStep``), step ``t_{k+1} - t_k`` in double; ``grid="float"`` (default) uses
     ``t_k = t0 + k*H`` and passes the nominal ``H``. Both together reproduce a libcosim
     run bit for bit (tests/test_crosscheck.py). A shortened last step ends on the stop
     time in both grids.

4. Step-size control (``step_control=StepControl(...)``): before a step every unit's
   state is saved (``fmi2GetFMUstate``). After it the local coupling error is estimated
   from the exchanged signals alone, at no extra FMU cost: the defect
   ``d = y(t_n+H) - P(t_n+H)`` of the extrapolation polynomial ``P`` (constant for
   ``"zoh"``, the line through the last two values for ``"linear"``) gives the
   input-error impulse a receiving unit integrated over the step,
   ``int |u_held - u| dt ~ c_p H |d|`` (``c_0 = 1/2``, ``c_1 = 5/12``), which is
   ``O(H^(p+2))`` and drives its state error. ``err = max_i c_p H |d_i| /
   (atol + rtol |y_i|)``: above 1 the step is rejected, the units are rolled back
   (``fmi2SetFMUstate``, inputs re-set) and the step retried with
   ``H*max(shrink_min, safety*err**(-1/(p+2)))``; otherwise it is accepted and the next
   step is ``H*clip(safety*err**(-1/(p+2)), shrink_min, grow_max)`` (no growth right
   after a rejection), always within ``[h_min, h_max]``. A constant error per step is
   what minimizes the number of steps for a given global error (to leading order). A
   step at ``h_min`` is accepted even above tolerance (counted as ``forced``). Gauss-
   Seidel uses the same estimate, conservative for inputs that receive fresh values.

FMU failures (a call returning fmi2Discard, fmi2Error or fmi2Fatal, or failing to
instantiate) stop the run cleanly: the returned :class:`CosimResult` holds the
trajectories up to the last good communication point and a :class:`FmuFailure` naming
the unit, the FMI function, the time and the unit's log messages (captured through the
fmpy logger callback).

The stepping loop works on preallocated ctypes buffers that alias numpy arrays and calls
the FMUs' C functions directly (value references resolved once), so the master's own
overhead per macro step is a few microseconds plus the FMI calls.
"""

from __future__ import annotations

import ctypes
import logging
import math
import shutil
import tempfile
import time as _time
import weakref
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from fmpy import extract
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from tqdm import tqdm

from drillstring.orchestration.connections import Connection, System, Unit, build_system
from drillstring.orchestration.fmi_binding import (
    STATUS_NAMES,
    VR,
    Instance,
    RealBatch,
    make_callbacks,
)
from drillstring.orchestration.results import CosimResult, FmuFailure, StepStats

__all__ = [
    "Master",
    "StepControl",
    "Unit",
    "Connection",
    "CosimResult",
    "FmuFailure",
    "StepStats",
]

log = logging.getLogger(__name__)

Scheme = Literal["jacobi", "gauss-seidel"]
Extrapolation = Literal["zoh", "linear"]
Exchange = Literal["propagate", "simple"]

_MAX_LOG = 100_000  # messages kept in CosimResult.log


@dataclass(frozen=True)
class StepControl:
    """Macro-step control: tolerances on the coupling-error estimate and step limits.

    A step is accepted when the estimated input-error impulse of every exchanged signal,
    ``c_p H |defect_i|``, is at most ``atol + rtol*|y_i|`` (see the module docstring);
    ``h_init`` defaults to ``h_max``. ``safety``, ``grow_max`` and ``shrink_min`` shape
    the step-size update.
    """

    rtol: float = 1e-3
    atol: float = 1e-6
    h_min: float = 1e-6
    h_max: float = 0.1
    h_init: float | None = None
    safety: float = 0.9
    grow_max: float = 2.0
    shrink_min: float = 0.2

    def __post_init__(self) -> None:
        for name in ("rtol", "atol"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"StepControl.{name} must be finite and >= 0, got {v!r}")
        if self.rtol == 0 and self.atol == 0:
            raise ValueError("StepControl: rtol and atol cannot both be 0")
        if not (math.isfinite(self.h_min) and 0 < self.h_min <= self.h_max):
            raise ValueError(
                f"StepControl needs 0 < h_min <= h_max, got h_min={self.h_min!r}, "
                f"h_max={self.h_max!r}"
            )
        if not math.isfinite(self.h_max):
            raise ValueError(f"StepControl.h_max must be finite, got {self.h_max!r}")
        if self.h_init is not None and not (self.h_min <= self.h_init <= self.h_max):
            raise ValueError(
                f"StepControl.h_init={self.h_init!r} outside [h_min, h_max] = "
                f"[{self.h_min!r}, {self.h_max!r}]"
            )
        if not 0 < self.safety <= 1:
            raise ValueError(f"StepControl.safety must be in (0, 1], got {self.safety!r}")
        if not self.grow_max > 1:
            raise ValueError(f"StepControl.grow_max must be > 1, got {self.grow_max!r}")
        if not 0 < self.shrink_min < 1:
            raise ValueError(f"StepControl.shrink_min must be in (0, 1), got {self.shrink_min!r}")


class _Failure(Exception):
    """Internal: an FMI call of unit ``unit`` failed (turned into :class:`FmuFailure`)."""

    def __init__(self, unit: int, function: str, status: int, t: float, h: float | None):
        super().__init__(function)
        self.unit, self.function, self.status, self.t, self.h = unit, function, status, t, h


class Master:
    """Co-simulation master for FMI 2.0 co-simulation units (see module docstring).

    ``units``: sequence of :class:`Unit`, or mapping name -> :class:`Unit`, FMU path or
    (FMU path, start values);
    ``connections``: ``"a.y -> b.u"`` strings, ``(source, target)`` pairs or
    :class:`Connection`; ``record``: extra ``"unit.var"`` to record (Real, Integer,
    Boolean; connected variables are always recorded); ``gs_order``: unit names in
    Gauss-Seidel order (default from the declared dependencies); ``log_categories``:
    FMU log categories to switch on (``fmi2SetDebugLogging``); None (default) switches
    on all of them so that a failing FMU's message is never filtered away (pythonfmu,
    for one, reports Python exceptions with an empty category); ``()`` switches logging
    off.

    FMUs are extracted once, into a temporary directory removed by :meth:`close` (or
    on garbage collection); each :meth:`run` instantiates fresh units and frees them.
    """

    def __init__(
        self,
        units: Sequence[Unit] | Mapping[str, Unit | str | Path | tuple[str | Path, Mapping]],
        connections: Iterable[Connection | tuple[str, str] | str],
        *,
        record: Sequence[str] = (),
        gs_order: Sequence[str] | None = None,
        log_categories: Sequence[str] | None = None,
    ):
        self.system: System = build_system(units, connections, gs_order)
        sysm = self.system
        connected = set(sysm.outputs) | set(sysm.input_source)
        extra: list[str] = []
        for key in record:
            ref = sysm.resolve(key)
            if ref.type not in ("Real", "Integer", "Boolean", "Enumeration"):
                raise ValueError(f"cannot record {key!r}: type {ref.type} is not numeric")
            if key not in connected and key not in extra:
                extra.append(key)
        self.record: tuple[str, ...] = tuple(extra)
        if isinstance(log_categories, str):
            raise ValueError(f"log_categories must be a sequence of names, got {log_categories!r}")
        self.log_categories = None if log_categories is None else tuple(log_categories)

        seen: dict[str, str] = {}
        for unit, md in zip(sysm.units, sysm.model_descriptions, strict=True):
            path = str(Path(unit.fmu).resolve())
            if md.coSimulation.canBeInstantiatedOnlyOncePerProcess and path in seen:
                raise ValueError(
                    f"units {seen[path]!r} and {unit.name!r} use {unit.fmu}, which can be "
                    "instantiated only once per process"
                )
            seen.setdefault(path, unit.name)

        self._tmp = tempfile.mkdtemp(prefix="cosim_master_")
        self._finalizer = weakref.finalize(self, shutil.rmtree, self._tmp, True)
        self._unzipdirs: list[str] = []
        extracted: dict[str, str] = {}
        for i, unit in enumerate(sysm.units):
            path = str(Path(unit.fmu).resolve())
            if path not in extracted:
                extracted[path] = extract(path, unzipdir=Path(self._tmp, f"{i}_{unit.name}"))
            self._unzipdirs.append(str(extracted[path]))

    # -- lifecycle -------------------------------------------------------------------

    def close(self) -> None:
        """Remove the extracted FMUs."""
        self._finalizer()

    def __enter__(self) -> Master:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- public API ------------------------------------------------------------------

    @property
    def columns(self) -> tuple[str, ...]:
        """Field names of the result: time, connected outputs, connected inputs, record."""
        return ("time", *self.system.outputs, *self.system.input_source, *self.record)

    def run(
        self,
        stop_time: float,
        step: float | None = None,
        *,
        start_time: float = 0.0,
        scheme: Scheme = "jacobi",
        extrapolation: Extrapolation = "zoh",
        step_control: StepControl | None = None,
        progress: bool | None = None,
        exchange: Exchange = "propagate",
        grid: Literal["float", "ns"] = "float",
    ) -> CosimResult:
        """Co-simulate from ``start_time`` to ``stop_time``.

        Fixed macro step ``step`` (the last step is shortened to land on ``stop_time``),
        or adaptive with ``step_control`` (``step`` then is the initial step, default
        ``step_control.h_init`` or ``h_max``). ``progress``: tqdm bar (None: only on a
        terminal). ``exchange`` and ``grid``: exchange at communication points and time
        grid of fixed-step runs (module docstring; ``"simple"`` with ``"ns"`` is
        libcosim's fixed-step algorithm). Never raises for FMU failures: see
        :attr:`CosimResult.failure`.
        """
        if not (math.isfinite(start_time) and math.isfinite(stop_time) and stop_time > start_time):
            raise ValueError(
                f"need finite start_time < stop_time, got {start_time!r}, {stop_time!r}"
            )
        if scheme not in ("jacobi", "gauss-seidel"):
            raise ValueError(f"scheme must be 'jacobi' or 'gauss-seidel', got {scheme!r}")
        if extrapolation not in ("zoh", "linear"):
            raise ValueError(f"extrapolation must be 'zoh' or 'linear', got {extrapolation!r}")
        if exchange not in ("propagate", "simple"):
            raise ValueError(f"exchange must be 'propagate' or 'simple', got {exchange!r}")
        if grid not in ("float", "ns"):
            raise ValueError(f"grid must be 'float' or 'ns', got {grid!r}")
        if grid == "ns":
            if step_control is not None:
                raise ValueError("grid='ns' is for fixed-step runs, not with step_control")
            if step is None or not (math.isfinite(step) and round(step * 1e9) >= 1):
                raise ValueError(f"grid='ns' needs a step of at least 1 ns, got {step!r}")
            for name, v in (("step", step), ("start_time", start_time)):
                if abs(round(v * 1e9) - v * 1e9) > 1e-6 + 1e-12 * abs(v) * 1e9:
                    raise ValueError(
                        f"grid='ns' needs a {name} that is a whole number of ns, got {v!r}"
                    )
        if step_control is None:
            if step is None or not (math.isfinite(step) and step > 0):
                raise ValueError(f"fixed-step run needs a finite step > 0, got {step!r}")
        else:
            if not isinstance(step_control, StepControl):
                raise ValueError(f"step_control must be a StepControl, got {step_control!r}")
            if step is None:
                step = step_control.h_init or step_control.h_max
            if not step_control.h_min <= step <= step_control.h_max:
                raise ValueError(
                    f"initial step {step!r} outside [h_min, h_max] = "
                    f"[{step_control.h_min!r}, {step_control.h_max!r}]"
                )
        variable_steps = step_control is not None or not _n_steps(stop_time - start_time, step)[1]
        for unit, md in zip(self.system.units, self.system.model_descriptions, strict=True):
            cs = md.coSimulation
            if step_control is not None and not cs.canGetAndSetFMUstate:
                raise ValueError(
                    f"step-size control needs rollback, but unit {unit.name!r} cannot get and "
                    "set its FMU state (canGetAndSetFMUstate=false)"
                )
            if variable_steps and not cs.canHandleVariableCommunicationStepSize:
                raise ValueError(
                    f"unit {unit.name!r} cannot handle variable communication step sizes; use "
                    "a fixed step that divides stop_time - start_time"
                )
        run = _Run(self, start_time, stop_time, scheme, extrapolation, exchange, grid == "ns")
        return run.execute(step, step_control, progress)


def _flat(op: RealBatch, idx: np.ndarray | None) -> tuple:
    """A batch as a flat tuple for the exchange loop (idx None: a get into y)."""
    return (op.fn, op.inst.comp, op.vr, op.n, op.buf, idx, op.view, op.inst, op.fname)


def _n_steps(span: float, h: float) -> tuple[int, bool]:
    """Number of fixed steps to cover ``span`` and whether they are all equal to h
    (to 1e-9 h); otherwise the last one is shorter."""
    n = round(span / h)
    if n >= 1 and abs(n * h - span) <= 1e-9 * h:
        return n, True
    return max(1, math.ceil(span / h)), False


class _Run:
    """State of one co-simulation run (buffers, instances); used once by Master.run."""

    def __init__(
        self,
        master: Master,
        t0: float,
        t_end: float,
        scheme: str,
        extrapolation: str,
        exchange: str = "propagate",
        ns_grid: bool = False,
    ):
        self.master = master
        self.sys = master.system
        self.t0, self.t_end = float(t0), float(t_end)
        self.gauss_seidel = scheme == "gauss-seidel"
        self.linear = extrapolation == "linear"
        self.simple = exchange == "simple"
        self.ns_grid = ns_grid
        self.instances = [Instance(i, u.name) for i, u in enumerate(self.sys.units)]
        self.by_name = {inst.name.encode("utf-8"): inst for inst in self.instances}
        self.log: list[tuple[str, str, str, str]] = []
        self._callbacks = make_callbacks(self._on_message)
        self.rec = np.empty((0, 0))  # replaced by _prepare once the units are up
        self.n_rec = 0

    # -- FMU log messages ----------------------------------------------------------------

    def _on_message(self, instance_name: bytes, label: str, category: str, text: str) -> None:
        """Logger callback target: keep the message per unit and in the run's log."""
        inst = self.by_name.get(instance_name)
        if inst is not None:
            inst.messages.append(f"[{label}] {text}")
        if len(self.log) < _MAX_LOG:
            name = instance_name.decode("utf-8", "replace") if instance_name else "?"
            self.log.append((name, label, category, text))

    # -- buffers and schedules ----------------------------------------------------------

    def _batch(self, inst: Instance, get: bool, keys: Sequence[str], idx, buf=None) -> RealBatch:
        return RealBatch(inst, get, [self.sys.resolve(k).vr for k in keys], idx, buf)

    def _prepare(self) -> None:
        """Value vector, exchange schedule and per-unit batches, built once per run."""
        sysm, insts = self.sys, self.instances
        src_of = sysm.input_source
        # value vector y: connected outputs, laid out in exchange-schedule order so every
        # exchange get writes one contiguous slice of y (its ctypes buffer aliases y)
        layout = [k for rnd in sysm.schedule for _, keys in rnd.gets for k in keys]
        self.yidx = yidx = {k: j for j, k in enumerate(layout)}
        ny = len(layout)
        self.y = np.zeros(ny)
        base = self.y.ctypes.data
        self.xops = []  # flat tuples for the hot loop; gets have idx None
        for rnd in sysm.schedule:
            for i, keys in rnd.gets:
                pos = yidx[keys[0]]
                buf = (ctypes.c_double * len(keys)).from_address(base + 8 * pos)
                op = self._batch(insts[i], True, keys, range(pos, pos + len(keys)), buf)
                self.xops.append(_flat(op, None))
            for i, keys in rnd.sets:
                op = self._batch(insts[i], False, keys, [yidx[src_of[k]] for k in keys])
                self.xops.append(_flat(op, op.idx))
        # exchange after a step: the schedule, or (simple) all reads, then all writes
        self.step_xops = self.xops
        if self.simple:
            gets = [op for op in self.xops if op[5] is None]
            self.step_xops = gets + [op for op in self.xops if op[5] is not None]

        # per unit: all its connected inputs (set) and connected outputs (get)
        self.input_ops: list[RealBatch | None] = []
        self.output_ops: list[RealBatch | None] = []
        for inst in insts:
            ins = [k for k in src_of if k.split(".", 1)[0] == inst.name]
            outs = [k for k in sysm.outputs if k.split(".", 1)[0] == inst.name]
            self.input_ops.append(
                self._batch(inst, False, ins, [yidx[src_of[k]] for k in ins]) if ins else None
            )
            self.output_ops.append(
                self._batch(inst, True, outs, [yidx[k] for k in outs]) if outs else None
            )

        # Gauss-Seidel: (unit, its inputs, reads a source stepped before it,
        # its outputs, feeds a unit stepped after it)
        order = [insts[i].name for i in sysm.gs_order]
        self.gs_steps = []
        for k, i in enumerate(sysm.gs_order):
            name = insts[i].name
            links = [(t.split(".", 1)[0], s.split(".", 1)[0]) for t, s in src_of.items()]
            fresh = any(t == name and s in order[:k] for t, s in links)
            feeds_later = any(s == name and t in order[k + 1 :] for t, s in links)
            step = (insts[i], self.input_ops[i], fresh, self.output_ops[i], feeds_later)
            self.gs_steps.append(step)

        # recorded extra variables, batched by unit and type
        self.n_cols = 1 + ny + len(self.master.record)
        self.extra_ops: list[tuple] = []
        groups: dict[tuple[int, str], list[tuple[int, int]]] = {}
        for j, key in enumerate(self.master.record):
            ref = sysm.resolve(key)
            kind = ref.type if ref.type in ("Real", "Boolean") else "Integer"
            groups.setdefault((ref.unit, kind), []).append((ref.vr, 1 + ny + j))
        for (i, kind), items in groups.items():
            inst = insts[i]
            fn = {"Real": inst.get_real, "Integer": inst.get_integer, "Boolean": inst.get_boolean}
            ctype = ctypes.c_double if kind == "Real" else ctypes.c_int
            n = len(items)
            buf = (ctype * n)()
            cols = np.array([c for _, c in items], dtype=np.intp)
            vrs = (VR * n)(*[v for v, _ in items])
            self.extra_ops.append((fn[kind], inst, vrs, n, buf, np.ctypeslib.as_array(buf), cols))
        self.rec = np.empty((256, self.n_cols))
        self.n_rec = 0

    # -- FMI calls ----------------------------------------------------------------------

    def _fail(self, inst: Instance, function: str, status: int, t: float, h: float | None):
        if status >= 3:
            inst.dead = True
        if status == 4:  # fmi2Fatal: every instance of that FMU is corrupted (FMI 2.0, 2.1.3)
            for other in self.instances:
                if self.master._unzipdirs[other.index] == self.master._unzipdirs[inst.index]:
                    other.dead = other.fatal = True
        raise _Failure(inst.index, function, status, t, h)

    def _exchange(self, t: float, ops: list | None = None) -> None:
        """Read outputs / write inputs in schedule order (all inputs fresh at t), or in
        the order of ``ops`` (``step_xops``: the exchange after a step)."""
        take = self.y.take
        for fn, comp, vr, n, buf, idx, view, inst, fname in self.xops if ops is None else ops:
            if idx is not None:  # a set: gather its source values from y
                take(idx, out=view)
            st = fn(comp, vr, n, buf)
            if st > 1:
                self._fail(inst, fname, st, t, None)

    def _set_inputs(self, op: RealBatch, values: np.ndarray, t: float) -> None:
        values.take(op.idx, out=op.view)
        st = op.fn(op.inst.comp, op.vr, op.n, op.buf)
        if st > 1:
            self._fail(op.inst, op.fname, st, t, None)

    def _record(self, t: float) -> None:
        k = self.n_rec
        if k == len(self.rec):
            self.rec = np.concatenate([self.rec, np.empty_like(self.rec)])
        row = self.rec[k]
        row[0] = t
        row[1 : 1 + len(self.y)] = self.y
        for fn, inst, vrs, n, buf, view, cols in self.extra_ops:
            st = fn(inst.comp, vrs, n, buf)
            if st > 1:
                self._fail(inst, "fmi2Get (recorded variables)", st, t, None)
            row[cols] = view
        self.n_rec = k + 1

    def _call(self, inst: Instance, function: str, t: float, call, *args):
        """A lifecycle call through fmpy; FMI errors become _Failure."""
        try:
            return call(*args)
        except FMICallException as exc:
            self._fail(inst, function, exc.status, t, None)

    # -- initialization ------------------------------------------------------------------

    def _instantiate(self) -> None:
        """Instantiate, set up the experiment and set the start values of every unit."""
        sysm, t0 = self.sys, self.t0
        for inst, unit, md, unzipdir in zip(
            self.instances, sysm.units, sysm.model_descriptions, self.master._unzipdirs, strict=True
        ):
            cats = self.master.log_categories
            fmu = None
            try:
                fmu = FMU2Slave(
                    guid=md.guid,
                    unzipDirectory=unzipdir,
                    modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=unit.name,
                )
                fmu.instantiate(callbacks=self._callbacks, loggingOn=cats != ())
            except Exception as exc:  # fmpy raises plain Exception for both
                inst.messages.append(f"[error] {exc}")
                if fmu is not None:
                    fmu.freeLibrary()
                self._fail(inst, "fmi2Instantiate", 3, t0, None)
            inst.fmu = fmu
            inst.bind(fmu)
            if cats:  # None: all categories (the FMI default for loggingOn=true)
                declared = {c.name for c in md.logCategories}
                cats = [c for c in cats if c in declared]
                on = bool(cats)  # none of them declared: logging off, not "all"
                self._call(inst, "fmi2SetDebugLogging", t0, fmu.setDebugLogging, on, cats)
            self._call(inst, "fmi2SetupExperiment", t0, fmu.setupExperiment, None, t0, self.t_end)
            for name, value in unit.start_values.items():
                ref = sysm.variables[inst.index][name]
                setter = {
                    "Real": fmu.setReal,
                    "Integer": fmu.setInteger,
                    "Enumeration": fmu.setInteger,
                    "Boolean": fmu.setBoolean,
                    "String": fmu.setString,
                }[ref.type]
                self._call(inst, f"fmi2Set{ref.type} ({name})", t0, setter, [ref.vr], [value])

    def _initialize(self) -> None:
        """Initialization mode with the exchange of outputs to inputs (FMI 2.0, 4.2.4)."""
        t0 = self.t0
        for inst in self.instances:
            self._call(inst, "fmi2EnterInitializationMode", t0, inst.fmu.enterInitializationMode)
            inst.initialized = True
        self._exchange(t0)
        for inst in self.instances:
            self._call(inst, "fmi2ExitInitializationMode", t0, inst.fmu.exitInitializationMode)
        self._exchange(t0)

    # -- one macro step --------------------------------------------------------------

    def _advance(self, t: float, h: float, y_prev: np.ndarray | None, h_prev: float, nsp: int):
        """Step every unit from t to t + h and exchange at t + h (y: values at t).

        ``y_prev``: exchanged values at t - h_prev for linear extrapolation (None: hold).
        """
        y = self.y
        if self.linear and y_prev is not None:
            held = y + (y - y_prev) * (0.5 * h / h_prev)  # line's mean over [t, t+h]
        else:
            held = None
        if not self.gauss_seidel:
            if held is not None:
                for op in self.input_ops:
                    if op is not None:
                        self._set_inputs(op, held, t)
            for inst in self.instances:
                st = inst.do_step(inst.comp, t, h, nsp)
                if st > 1:
                    self._fail(inst, "fmi2DoStep", st, t, h)
        else:
            z = y.copy() if held is None else held
            for inst, in_op, fresh, out_op, feeds_later in self.gs_steps:
                if in_op is not None and (fresh or held is not None):
                    self._set_inputs(in_op, z, t)
                st = inst.do_step(inst.comp, t, h, nsp)
                if st > 1:
                    self._fail(inst, "fmi2DoStep", st, t, h)
                if feeds_later:
                    st = out_op.fn(inst.comp, out_op.vr, out_op.n, out_op.buf)
                    if st > 1:
                        self._fail(inst, "fmi2GetReal", st, t + h, None)
                    if self.linear:  # mean of the line from y(t) to the fresh y(t+h)
                        z[out_op.idx] = 0.5 * (y[out_op.idx] + out_op.view)
                    else:
                        z[out_op.idx] = out_op.view
        self._exchange(t + h, self.step_xops)

    # -- the run -----------------------------------------------------------------------

    def execute(self, h: float, control: StepControl | None, progress: bool | None) -> CosimResult:
        wall = _time.perf_counter()
        failure: FmuFailure | None = None
        self.stats = dict(accepted=0, rejected=0, forced=0, h_min=math.inf, h_max=0.0)
        self.step_log: list[tuple[float, float, float, bool]] | None = (
            [] if control is not None else None
        )
        bar = tqdm(
            total=self.t_end - self.t0,
            disable=None if progress is None else not progress,
            desc="co-simulation",
            unit="s(sim)",
            leave=False,
            bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} [{elapsed}<{remaining}]",
        )
        self.bar = bar
        try:
            self._instantiate()
            self._prepare()
            self._initialize()
            self._record(self.t0)
            if control is None:
                self._run_fixed(h)
            else:
                self._run_adaptive(h, control)
        except _Failure as f:
            failure = self._describe(f)
            log.warning("co-simulation stopped: %s", failure)
        finally:
            bar.close()
            self._release()
        s = self.stats
        if control is None and self.n_rec > 1:
            steps = np.diff(self.rec[: self.n_rec, 0])
            s["h_min"], s["h_max"] = float(steps.min()), float(steps.max())
        stats = StepStats(
            accepted=s["accepted"],
            rejected=s["rejected"],
            forced=s["forced"],
            h_min=s["h_min"] if s["accepted"] else math.nan,
            h_max=s["h_max"] if s["accepted"] else math.nan,
            wall_time=_time.perf_counter() - wall,
        )
        log.info(
            "co-simulation %s: %d accepted, %d rejected steps, %.3g s wall",
            "completed" if failure is None else "failed",
            stats.accepted,
            stats.rejected,
            stats.wall_time,
        )
        step_log = None
        if self.step_log is not None:
            step_log = np.array(
                self.step_log,
                dtype=[("time", float), ("h", float), ("error", float), ("accepted", bool)],
            )
        return CosimResult(
            data=self._assemble(),
            stats=stats,
            failure=failure,
            log=tuple(self.log),
            step_log=step_log,
        )

    def _progress(self, t: float) -> None:
        bar = self.bar
        bar.update(t - self.t0 - bar.n)

    def _run_fixed(self, h: float) -> None:
        t0, span = self.t0, self.t_end - self.t0
        n_steps, exact = _n_steps(span, h)
        need_prev = self.linear
        y = self.y
        y_prev = np.empty_like(y) if need_prev else None
        y_save = np.empty_like(y) if need_prev else None
        have_prev = False
        h_prev = h
        t = t0
        rec = np.empty((n_steps + 1, self.n_cols))  # exact size: no growth in the loop
        rec[0] = self.rec[0]
        self.rec = rec
        record, advance, stats = self._record, self._advance, self.stats
        ns_grid, h_ns, t0_ns = self.ns_grid, round(h * 1e9), round(t0 * 1e9)
        for n in range(1, n_steps + 1):
            # communication points t0 + n h; every full step passes the nominal h to
            # the units (as masters on an integer time grid do), a last partial step
            # the remainder
            if ns_grid and (n < n_steps or exact):  # libcosim: integer ns, then double
                t_next = (t0_ns + n * h_ns) / 1e9
                hn = t_next - t
            else:
                t_next = t0 + n * h if n < n_steps else self.t_end
                hn = h if n < n_steps or exact else t_next - t
            if need_prev:
                np.copyto(y_save, y)
            advance(t, hn, y_prev if have_prev else None, h_prev, 1)
            if need_prev:
                np.copyto(y_prev, y_save)
                have_prev = True
            h_prev = hn
            t = t_next
            stats["accepted"] = n
            record(t)
            if n & 255 == 0:
                self._progress(t)
        self._progress(t)

    def _run_adaptive(self, h: float, c: StepControl) -> None:
        insts = self.instances
        for inst in insts:
            if None in (inst.get_state, inst.set_state, inst.free_state):
                msg = "declares canGetAndSetFMUstate but lacks fmi2Get/Set/FreeFMUstate"
                raise ValueError(f"unit {inst.name!r} {msg}")
        y = self.y
        y_n = np.empty_like(y)
        y_prev = np.empty_like(y)
        have_prev = False
        h_prev = h
        t, t_end = self.t0, self.t_end
        stats, step_log = self.stats, self.step_log
        eps = 1e-12 * max(abs(t_end), 1.0)
        while t < t_end - eps:
            for inst in insts:
                st = inst.get_state(inst.comp, ctypes.byref(inst.state))
                if st > 1:
                    self._fail(inst, "fmi2GetFMUstate", st, t, None)
            np.copyto(y_n, y)
            rejected_here = False
            while True:
                # land on t_end without leaving a sliver below h_min; never lengthen h,
                # so that rejections always shrink the step
                remaining = t_end - t
                if h >= remaining:
                    hs = remaining
                elif remaining - h < c.h_min:
                    hs = 0.5 * remaining
                else:
                    hs = h
                self._advance(t, hs, y_prev if have_prev else None, h_prev, 0)
                # input-error impulse from the extrapolation defect (module docstring)
                if self.linear and have_prev:
                    p, c_p = 1, 5.0 / 12.0
                    pred = y_n + (y_n - y_prev) * (hs / h_prev)
                else:
                    p, c_p = 0, 0.5
                    pred = y_n
                scale = c.atol + c.rtol * np.maximum(np.abs(y), np.abs(y_n))
                err = c_p * hs * float(np.max(np.abs(y - pred) / scale)) if len(y) else 0.0
                if not math.isfinite(err):
                    err = math.inf
                accept = err <= 1.0 or hs <= c.h_min * (1 + 1e-12)
                step_log.append((t, hs, err, accept))
                if accept:
                    break
                stats["rejected"] += 1
                rejected_here = True
                for inst in insts:  # roll back to t
                    st = inst.set_state(inst.comp, inst.state)
                    if st > 1:
                        self._fail(inst, "fmi2SetFMUstate", st, t, None)
                np.copyto(y, y_n)
                for op in self.input_ops:
                    if op is not None:
                        self._set_inputs(op, y, t)
                factor = max(c.shrink_min, c.safety * err ** (-1.0 / (p + 2)))
                h = max(c.h_min, min(hs * factor, hs))
            if err > 1.0:
                stats["forced"] += 1
            for inst in insts:
                inst.free_state(inst.comp, ctypes.byref(inst.state))
                inst.state = ctypes.c_void_p()
            np.copyto(y_prev, y_n)
            have_prev = True
            h_prev = hs
            t = t + hs if t_end - (t + hs) > eps else t_end
            stats["accepted"] += 1
            stats["h_min"] = min(stats["h_min"], hs)
            stats["h_max"] = max(stats["h_max"], hs)
            self._record(t)
            if stats["accepted"] % 64 == 0:
                self._progress(t)
            # next step size (no growth right after a rejection)
            factor = c.grow_max if err == 0 else c.safety * err ** (-1.0 / (p + 2))
            factor = min(c.grow_max, max(c.shrink_min, factor))
            if rejected_here:
                factor = min(factor, 1.0)
            h = min(c.h_max, max(c.h_min, hs * factor))
        self._progress(t)

    # -- failure and cleanup ----------------------------------------------------------

    def _describe(self, f: _Failure) -> FmuFailure:
        inst = self.instances[f.unit]
        last_ok = None
        get_status = getattr(inst, "get_real_status", None)
        if f.status == 2 and f.function == "fmi2DoStep" and get_status is not None:
            value = ctypes.c_double()  # fmi2LastSuccessfulTime = 2; optional for the FMU
            if get_status(inst.comp, 2, ctypes.byref(value)) == 0:
                last_ok = value.value
        status = STATUS_NAMES[f.status] if 0 <= f.status < len(STATUS_NAMES) else str(f.status)
        return FmuFailure(
            unit=inst.name,
            function=f.function,
            status=status,
            time=f.t,
            step_size=f.h,
            messages=tuple(inst.messages),
            last_successful_time=last_ok,
        )

    def _release(self) -> None:
        """Terminate and free every instance that can be (never raises)."""
        for inst in self.instances:
            fmu = inst.fmu
            if fmu is None:
                continue
            try:
                if not inst.dead:
                    if inst.state.value:
                        inst.free_state(inst.comp, ctypes.byref(inst.state))
                    if inst.initialized:
                        fmu.terminate()
            except Exception as exc:
                log.debug("terminate of %s failed: %s", inst.name, exc)
            try:
                if not inst.fatal:
                    fmu.freeInstance()
            except Exception as exc:
                log.debug("freeInstance of %s failed: %s", inst.name, exc)
            inst.fmu = None

    def _assemble(self) -> np.ndarray:
        names = self.master.columns
        dtype = np.dtype([(n, np.float64) for n in names])
        out = np.empty(self.n_rec, dtype=dtype)
        if self.n_rec == 0:
            return out
        rec = self.rec[: self.n_rec]
        ny = len(self.y)
        out["time"] = rec[:, 0]
        for k in self.sys.outputs:
            out[k] = rec[:, 1 + self.yidx[k]]
        for k, s in self.sys.input_source.items():
            out[k] = rec[:, 1 + self.yidx[s]]
        for j, k in enumerate(self.master.record):
            out[k] = rec[:, 1 + ny + j]
        return out
