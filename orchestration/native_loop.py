"""The fixed-step Jacobi loop in C: the master's hot path without Python.

:func:`run_native` hands ``native_loop.c`` (one function, ``ds_master_loop``) what the Python
loop of :func:`~drillstring.orchestration.fixed.run_fixed` uses: the units' ``fmi2DoStep`` and
components, the exchange's batches after a step (:attr:`.Exchange.step_xops`: the schedule's
order for ``exchange="propagate"``, gets then sets for ``"simple"``), the recorded variables'
batches, each unit's input batch (linear extrapolation), the value vector ``y``, the
recorder's preallocated rows and the communication grid
(:func:`~drillstring.orchestration.fixed.grid_points`, so every ``grid`` option gives the Python
loop's points). The C loop makes the same FMI calls in the same order with the same arguments and
buffers, and only copies values (linear extrapolation: numpy's operations of
:meth:`.JacobiStep._held` on the same doubles, compiled with ``-ffp-contract=off``), so the rows
are the Python loop's bits. It runs in chunks of
:data:`CHUNK` steps; the progress bar advances between them. The first call that fails stops it;
the failure is then reported through :meth:`.Instances.fail` with the function, status, time and
step the Python loop would name, after the same rows and step count.

The Python loop runs instead (:func:`supported` is False) for Gauss-Seidel, step-size control
(:mod:`.adaptive` never calls this module), a system whose connections convert units (the C loop
only copies values; :attr:`.Exchange.converts`), without a C compiler, when the compilation
fails, or with ``DRILLSTRING_MASTER_NATIVE=0``. (Connections are Real -> Real by construction:
:func:`~.connections.build_system` refuses others.)

When it is compiled: at its first use, into a per-user cache (``$XDG_CACHE_HOME/drillstring`` or
``~/.cache/drillstring``), under a name keyed by the hash of the C source, the compiler command
and the flags, written atomically (:func:`drillstring.fileio.atomic_write`). Not at install time:
the package is installed as pure Python (an editable install in development) with no build step
of its own, and a library built beside the sources could be stale after an edit or belong to
another machine; a hash-keyed cache can never load a library of another source, costs one
compilation (about 0.1 s) per user and source change, and a process that runs no fixed-step
co-simulation compiles nothing.
"""

from __future__ import annotations

import ctypes
import hashlib
import logging
import os
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from drillstring.ccompiler import CompilerNotFound, find_c_compiler
from drillstring.fileio import atomic_write
from drillstring.orchestration.run import Run
from drillstring.orchestration.step import JacobiStep

__all__ = ["CHUNK", "ENV", "SOURCE", "library", "run_native", "supported"]

log = logging.getLogger(__name__)

#: The C loop.
SOURCE = Path(__file__).with_name("native_loop.c")
#: Switch: ``DRILLSTRING_MASTER_NATIVE=0`` runs the Python loop.
ENV = "DRILLSTRING_MASTER_NATIVE"
#: Steps per call of the C loop (the progress bar advances between calls).
CHUNK = 1000
_CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-fPIC", "-shared")
_OP_WORDS = 7  # words of a batch, as native_loop.c reads them
_GET_REAL, _SET_REAL, _GET_INT = 0, 1, 2
_DO_STEP, _EXCHANGE, _RECORD, _INPUTS = 1, 2, 3, 4  # phases of a failure

_loaded: dict[str, ctypes._CFuncPtr | None] = {}


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "drillstring"


def _compile() -> ctypes._CFuncPtr:
    """Compile (or find in the cache) and load the C loop; raises on any failure."""
    cc = find_c_compiler()
    source = SOURCE.read_bytes()
    key = hashlib.sha256(b"\0".join([source, *(s.encode() for s in (*cc, *_CFLAGS))]))
    path = _cache_dir() / f"native_loop-{key.hexdigest()[:20]}.so"
    if not path.is_file():
        with tempfile.TemporaryDirectory(prefix="ds_native_loop_") as tmp:
            out = Path(tmp) / "native_loop.so"
            cmd = [*cc, *_CFLAGS, "-o", str(out), str(SOURCE)]
            proc = subprocess.run(cmd, capture_output=True, text=True)
            if proc.returncode != 0:
                raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stdout}{proc.stderr}")
            data = out.read_bytes()
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda fh: fh.write(data))
    fn = ctypes.CDLL(str(path)).ds_master_loop
    p, i64, i32 = ctypes.c_void_p, ctypes.c_int64, ctypes.c_int
    fn.argtypes = [
        *(p, i64) * 4,  # units, xops, rops, iops and their counts
        i32, p, p, p, i64,  # linear, y_prev, held, y, ny
        p, p, i64, i64,  # t, h, k0, k1
        p, i64, i64, i32, p,  # rows, row0, n_cols, nsp, fail
    ]  # fmt: skip
    fn.restype = i64
    return fn


def library() -> ctypes._CFuncPtr | None:
    """The loaded C loop, compiled at the first call of the process; None without a compiler or
    when compiling fails (logged once; the Python loop runs)."""
    if "fn" not in _loaded:
        try:
            _loaded["fn"] = _compile()
        except (CompilerNotFound, OSError, RuntimeError) as exc:
            log.info("the master's native loop is unavailable, the Python loop runs: %s", exc)
            _loaded["fn"] = None
    return _loaded["fn"]


def supported(step: JacobiStep) -> bool:
    """Can :func:`run_native` run this fixed-step run (module docstring)?

    Parameters
    ----------
    step : JacobiStep or GaussSeidelStep
        The run's macro step.

    Returns
    -------
    bool
        True for a Jacobi step without unit conversions, the switch not off and the C loop
        loaded.
    """
    if os.environ.get(ENV, "1").strip() == "0":
        return False
    return type(step) is JacobiStep and not step.converts and library() is not None


def _address(fn: ctypes._CFuncPtr) -> int:
    return ctypes.cast(fn, ctypes.c_void_p).value


def _batches(ops: list[tuple[int, int, int, int, int, int, int]]) -> np.ndarray:
    return np.array(ops, dtype=np.uint64).reshape(-1, _OP_WORDS)


def run_native(run: Run, times: np.ndarray, steps: np.ndarray) -> None:
    """The fixed-step loop of :func:`~.fixed.run_fixed` in C (:func:`supported` must be True).

    Parameters
    ----------
    run : Run
        The run: its macro step (its units, exchange and value vector), its recorder (the row
        of ``times[0]`` recorded, room reserved for one row per point of ``times``) and its
        progress callback (called with the simulated time after each chunk); ``run.accepted``
        counts the steps taken.
    times, steps : numpy.ndarray
        Communication points ``t_0 .. t_N`` and the steps ``h_0 .. h_{N-1}`` passed to
        ``fmi2DoStep`` (:func:`~.fixed.grid_points`).

    Raises
    ------
    UnitFailure
        Through :meth:`.Instances.fail`, for the first call that returns more than fmi2Warning,
        after the rows and the step count of the steps done.
    """
    step, recorder = run.step, run.recorder
    loop = library()
    items = step._items
    units = np.array(
        [(_address(inst.do_step), inst.comp.value or 0) for inst in items], dtype=np.uint64
    )
    xops = step._step_xops
    x = [
        (
            _address(fn),
            comp.value or 0,
            ctypes.addressof(vr),
            n,
            ctypes.addressof(buf),
            0 if idx is None else idx.ctypes.data,
            _GET_REAL if idx is None else _SET_REAL,
        )
        for fn, comp, vr, n, buf, idx, _, _, _, _ in xops
    ]
    cols_kept = []
    r = []
    for fn, inst, vrs, n, buf, _, cols in recorder.extra_ops:
        kind = _GET_REAL if fn is inst.get_real else _GET_INT  # fmi2Integer, fmi2Boolean: int
        cols = np.ascontiguousarray(cols, dtype=np.int64)
        cols_kept.append(cols)
        r.append(
            (
                _address(fn),
                inst.comp.value or 0,
                ctypes.addressof(vrs),
                n,
                ctypes.addressof(buf),
                cols.ctypes.data,
                kind,
            )
        )
    iops = step._input_ops
    i = [
        (
            _address(op.fn),
            op.inst.comp.value or 0,
            ctypes.addressof(op.vr),
            op.n,
            ctypes.addressof(op.buf),
            op.idx.ctypes.data,
            _SET_REAL,
        )
        for op in iops
    ]
    xarr, rarr, iarr = _batches(x), _batches(r), _batches(i)
    y, rows = step.y, recorder.rows
    y_prev, held = np.empty_like(y), np.empty_like(y)
    times = np.ascontiguousarray(times, dtype=np.float64)
    steps = np.ascontiguousarray(steps, dtype=np.float64)
    fail = np.zeros(3, dtype=np.int64)
    n_total = len(steps)
    k = 0
    while k < n_total:
        k1 = min(k + CHUNK, n_total)
        done = loop(
            units.ctypes.data, len(items), xarr.ctypes.data, len(x), rarr.ctypes.data, len(r),
            iarr.ctypes.data, len(i), int(step.linear), y_prev.ctypes.data, held.ctypes.data,
            y.ctypes.data, len(y), times.ctypes.data, steps.ctypes.data, k, k1,
            rows.ctypes.data, recorder.n, rows.shape[1], 1, fail.ctypes.data,
        )  # fmt: skip
        recorder.n += done
        k += done
        run.accepted = k
        if fail[0]:
            _report(run, xops, iops, int(fail[0]), int(fail[1]), int(fail[2]),
                    float(times[k]), float(steps[k]), float(times[k + 1]))  # fmt: skip
        run.progress(float(times[k]))


def _report(run: Run, xops, iops, phase, i, status, t, h, t_next) -> None:
    """Raise the failure of step ``t -> t + h`` as the Python loop does."""
    step = run.step
    if phase == _INPUTS:
        step._fail(iops[i].inst, iops[i].fname, status, t, None)
    if phase == _DO_STEP:
        step._fail(step._items[i], "fmi2DoStep", status, t, h)
    if phase == _EXCHANGE:
        op = xops[i]
        step._fail(op[7], op[8], status, t + h, None)
    run.accepted += 1  # the Python loop counts a step before recording its row
    inst = run.recorder.extra_ops[i][1]
    run.recorder.instances.fail(inst, "fmi2Get (recorded variables)", status, t_next, None)
