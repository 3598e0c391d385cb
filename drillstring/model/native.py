"""The plant FMU's step on its io block, and the C entry points of the FMUs' native fast path.

The FMUs' front layer (``fmu_src/fmi_front/``, ``fast.c``) serves ``fmi2SetReal`` of the
inputs, ``fmi2DoStep`` and ``fmi2GetReal``/``fmi2GetInteger`` of the outputs without entering
Python: it calls the compiled functions below (numba ``cfunc``, their ``.address``).

The plant's step is written once, :func:`plant_io_step`: the unit conversions
(:mod:`drillstring.model.units`), the kernel's held-input step
(:func:`drillstring.model.kernel.stepper.held_step`) and the outputs, on the io block of the plant
(:data:`PLANT`). The front layer runs it through the ``cfunc`` :func:`plant_step`, the plant's
Python path (``fmu_src/drillstring_plant.py``) through :func:`plant_step_from`, on the same
block; without numba (or with ``DRILLSTRING_JIT=0``) it is the same source run as plain Python.
The controller's entry points run the digital controller's own functions
(:func:`drillstring.model.digital.block.fmu_step`, :func:`~drillstring.model.digital.block.
fmu_output`) on its block, as the controller FMU's Python path does.

Every entry point takes ``(io, args, t, h)``: ``io`` is a float64 block shared by the Python
slave and the front layer (layout: :data:`PLANT` for the plant, the digital controller's block
:data:`drillstring.model.digital.layout.BLOCK` for the controller; the four ``IO_*`` slots begin
every block; both laid out by :func:`drillstring.model.tables.block_layout`), ``args`` the
addresses of the kernel's arrays (:class:`~drillstring.model.kernel.state.KernelState` order,
for the plant; unused by the controller). A step returns :data:`DONE` (served: the outputs are
in ``io``), :data:`NOT_STARTED` (nothing changed: the Python path serves the call, with its
checks and messages) or :data:`RESUME` (``io[IO_RESUME]`` is a kernel status the Python path
must finish: a full history buffer, a stop of the model, a warning to log).

The entry points are compiled at their first use (a process that never steps an FMU compiles
nothing). numba caches compiled code keyed by this file alone; the cache of this module is
dropped when any source it compiles changes (:func:`refresh_cache`). Without numba (or
``DRILLSTRING_JIT=0``) :data:`AVAILABLE` is False and nothing is compiled: the FMUs run their
Python path only.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from drillstring.model import params as _params
from drillstring.model import units as _units
from drillstring.model.digital import block as _block
from drillstring.model.digital.layout import BLOCK as _BLOCK
from drillstring.model.kernel import jit as _jit
from drillstring.model.kernel import state as S
from drillstring.model.kernel import stepper as _stepper
from drillstring.model.tables import block_layout

__all__ = [
    "AVAILABLE",
    "DONE",
    "NOT_STARTED",
    "PLANT",
    "RESUME",
    "controller_functions",
    "plant_functions",
    "plant_io_step",
    "plant_step_from",
    "refresh_cache",
]

AVAILABLE = _jit.numba_available()

# --- results of a step ------------------------------------------------------------------------
DONE = 0
NOT_STARTED = 1
RESUME = 2

# --- io slots every FMU has (the front layer knows these four) --------------------------------
IO_STALE = 0  # 1: the native side changed the FMU's state since Python last saw it
IO_RESUME = 1  # kernel status of a step begun natively that Python must finish; -1: none
IO_TIME = 2  # the FMU's time
IO_NSTEPS = 3  # steps the front layer served natively (a count for the FMU's report)
IO_BASE = 4

# --- the plant's io ---------------------------------------------------------------------------


#: Entries of the io block that every FMU's begins with (the ``IO_*`` slots).
COMMON_IO = (("stale", 1), ("resume", 1), ("time", 1), ("nsteps", 1))
N_K = 12
#: Output slots of the scaled plant: Engine.outputs() keys, in order.
PLANT_SCALED_KEYS = (
    "u", "du", "phi", "dphi", "theta", "dtheta", "d", "g", "tau_n", "R_minus_R0",
    "mode", "top_torque_minus_R0", "stick_events", "bit_bounce", "torsional_stick",
)  # fmt: skip
#: Output slots of the SI plant: units.PLANT_SI names, then the counters.
PLANT_SI_KEYS = (
    *(q.name for q in _units.PLANT_SI), "mode", "stick_events", "bit_bounce", "torsional_stick"
)  # fmt: skip
#: The plant's io block, entry by entry.
PLANT = block_layout(
    "PlantIO",
    (
        *COMMON_IO,
        ("si", 1),  # 1: SI units (DrillStringPlantSI), 0: scaled
        ("hcap", 1),  # columns of the history buffer (what the native step reads of it)
        ("ecap", 1),  # rows of the event log
        ("input", 1),  # the FMU's input (R - R0 scaled, or the table torque R in N m)
        ("k", N_K),  # the unit system's constants (SIScaling.plant_constants; zeros when scaled)
        ("tau", 1),  # the engine's time (the OUT_TAU column of a kernel sample)
        ("out", max(len(PLANT_SCALED_KEYS), len(PLANT_SI_KEYS))),  # the outputs, by *_KEYS
    ),
)
assert PLANT[: len(COMMON_IO)] == (IO_STALE, IO_RESUME, IO_TIME, IO_NSTEPS) == tuple(range(IO_BASE))
assert PLANT.out == PLANT.tau + 1, "a kernel sample (tau, then the outputs) is written at tau"
_BOUNCE_SCALED = PLANT.out + PLANT_SCALED_KEYS.index("bit_bounce")
_BOUNCE_SI = PLANT.out + PLANT_SI_KEYS.index("bit_bounce")
_N_SI = len(_units.PLANT_SI)
assert S.OUTPUT_COLUMNS == ("tau", *PLANT_SCALED_KEYS[: S.OUT_SIZE - 1]), "a kernel sample's layout"

# --- the controller's io: the block of drillstring.model.digital.layout (its first four entries are
# the IO_* slots above)
assert (_BLOCK.stale, _BLOCK.resume, _BLOCK.time, _BLOCK.nsteps) == (
    IO_STALE,
    IO_RESUME,
    IO_TIME,
    IO_NSTEPS,
), "the controller's block starts with the io slots every FMU has"

_HERE = Path(__file__).resolve()
#: Every source the functions of this module compile (the kernel's, the conversions, the law).
SOURCES = (*_jit.COMPILED_SOURCES, _HERE, Path(_units.__file__), Path(_params.__file__))
_STAMP = "drillstring-native-sources.sha256"


def refresh_cache() -> bool:
    """Drop numba's cache of this module when any source in :data:`SOURCES` changed since it was
    compiled (numba keys it by this file only): :func:`~drillstring.model.kernel.jit.
    drop_stale_cache` with the stamp in ``__pycache__``.

    Returns
    -------
    bool
        True when cache entries of this module were removed; False when the stamp matched or
        there was nothing to remove.

    Raises
    ------
    OSError
        A file of :data:`SOURCES` cannot be read.
    """
    return _jit.drop_stale_cache(SOURCES, (_HERE,), _HERE.parent / "__pycache__" / _STAMP)


def array_addresses(arrays: S.KernelState) -> np.ndarray | None:
    """The addresses of the kernel's arrays (``args`` of the plant's step), or None when one of
    them is not what the compiled step reads (C-contiguous, aligned, writable, its dtype).

    Parameters
    ----------
    arrays : KernelState
        The kernel's arrays, e.g. :meth:`drillstring.model.engine.Engine.kernel_arrays`.

    Returns
    -------
    ndarray or None
        The data addresses (dtype ``uintp``), one per array in
        :class:`~drillstring.model.kernel.state.KernelState` order; None when an array is not
        C-contiguous, aligned and writable, or its dtype is not int64 (``ints``) or float64
        (the others).
    """
    for name, a in zip(S.KernelState._fields, arrays, strict=True):
        dtype = np.int64 if name == "ints" else np.float64
        if a.dtype != dtype or not (a.flags.c_contiguous and a.flags.aligned and a.flags.writeable):
            return None
    return np.array([a.ctypes.data for a in arrays], dtype=np.uintp)


_CFUNCS: dict[str, Any] = {}


def _address(name: str) -> int:
    """The address of the compiled entry point ``name``, compiled (or loaded from numba's cache)
    at its first use: a process that never steps an FMU compiles nothing."""
    if not AVAILABLE:
        raise RuntimeError("the native entry points need numba (and DRILLSTRING_JIT != 0)")
    if name not in _CFUNCS:
        _CFUNCS[name] = _jit.cached(numba.cfunc, sig=_SIG, nogil=True)(_ENTRY_POINTS[name])
    return int(_CFUNCS[name].address)


def plant_functions() -> tuple[int, int]:
    """(step, outputs) addresses of the plant's native functions (outputs 0: the plant's
    outputs only change in a step).

    The step is compiled (or loaded from numba's cache) at the first call.

    Returns
    -------
    tuple of int
        The address of the plant's step, a C function ``int32 (double *io, void **args, double
        t, double h)`` (module docstring), and 0.

    Raises
    ------
    RuntimeError
        :data:`AVAILABLE` is False (no numba, or ``DRILLSTRING_JIT=0``).
    """
    return _address("plant_step"), 0


def controller_functions() -> tuple[int, int]:
    """(step, outputs) addresses of the controller FMUs' native functions.

    The controller's io block is the digital controller's block
    (:data:`drillstring.model.digital.layout.BLOCK`); the step is
    :func:`drillstring.model.digital.block.fmu_step`, the outputs function
    :func:`~drillstring.model.digital.block.fmu_output`, the very functions the controller FMU's
    Python path calls. Both are compiled (or loaded from numba's cache) at the first call.

    Returns
    -------
    tuple of int
        The addresses of the controller's step and of its outputs function, C functions
        ``int32 (double *io, void **args, double t, double h)`` (module docstring).

    Raises
    ------
    RuntimeError
        :data:`AVAILABLE` is False (no numba, or ``DRILLSTRING_JIT=0``).
    """
    return _address("ctrl_step"), _address("ctrl_outputs")


# --- the plant's step -------------------------------------------------------------------------
jit = _jit.jit_for(__name__)
inline = _jit.jit_for(__name__, inline=True)


@inline
def plant_constants(io):
    """The unit system's constants of the plant's io block (``PLANT.k``) as a tuple."""
    k = PLANT.k
    return (io[k], io[k + 1], io[k + 2], io[k + 3], io[k + 4], io[k + 5], io[k + 6], io[k + 7],
            io[k + 8], io[k + 9], io[k + 10], io[k + 11])  # fmt: skip


@inline
def write_plant_outputs(io, s, si, K):
    """The plant's outputs at the kernel state ``s`` into ``io``: the engine's time, then the
    scaled outputs (a kernel sample) and the counters, or their SI values
    (:func:`~drillstring.model.units.si_plant_values` with the constants ``K``)."""
    I, D = s.ints, s.diag  # noqa: E741
    _stepper.write_sample(s, io[PLANT.tau : PLANT.tau + S.OUT_SIZE])
    o = PLANT.out + S.OUT_SIZE - 1
    if si:
        o = PLANT.out
        v = _units.si_plant_values(K, io[PLANT.tau], io[o], io[o + 1], io[o + 2], io[o + 3],
                                   io[o + 4], io[o + 5], D[S.D_D], D[S.D_G], D[S.D_TAUN],
                                   D[S.D_TOB], io[PLANT.out + S.OUT_TOP - 1])  # fmt: skip
        for i in range(_N_SI):
            io[o + i] = v[i]
        o += _N_SI
        io[o] = float(I[S.I_MODE])
        o += 1
    io[o] = float(I[S.I_NSTICK])
    io[o + 1] = float(I[S.I_NBOUNCE])
    io[o + 2] = float(I[S.I_NTSTICK])


@inline
def plant_io_step(io, s, t, h):
    """The plant FMU's step from t to t + h on its io block :data:`PLANT`, its input held.

    The FMU's input and time in the engine's units, the kernel's held-input step
    (:func:`~drillstring.model.kernel.stepper.held_step`: the input held, refreshed only when
    it changed; the engine advanced to t + h; the event log drained, the FMU keeps no events),
    the outputs written (``PLANT.tau``, ``PLANT.out``).

    Parameters
    ----------
    io : ndarray
        The plant's io block (:data:`PLANT`).
    s : KernelState
        The engine's kernel state.
    t, h : float
        The communication point and step size, in the FMU's time.

    Returns
    -------
    int
        :data:`DONE`; :data:`NOT_STARTED`, nothing changed (an input or a time the engine would
        refuse, a law that is not a held input, a run stopped before); or :data:`RESUME` with
        ``io[IO_RESUME]`` the kernel status for Python to finish: ``ST_HIST_FULL`` (outputs
        untouched: grow the history, then step again), a stop of the model (the outputs at the
        stop), or ``ST_OK`` (the outputs written; a new bit-bounce episode to warn of).
    """
    si = io[PLANT.si] != 0.0
    K = plant_constants(io)
    x = io[PLANT.input]
    r = _units.si_torque_deviation(K[5], K[4], x) if si else x
    target = _units.si_to_tau(K[2], t + h) if si else t + h
    if not (math.isfinite(r) and math.isfinite(target)) or target < s.clock[S.X_TAU]:
        return NOT_STARTED  # the Python path names the error
    if int(s.control[S.C_KIND]) != S.CTRL_HELD or s.ints[S.I_STATUS] != S.ST_OK:
        return NOT_STARTED
    reported = io[_BOUNCE_SI if si else _BOUNCE_SCALED]
    st, bounced = _stepper.held_step(s, r, target, False, reported)
    if st == S.ST_HIST_FULL:
        io[IO_RESUME] = st
        return RESUME
    write_plant_outputs(io, s, si, K)
    if st != S.ST_OK or bounced:
        io[IO_RESUME] = st
        return RESUME
    return DONE


@jit
def plant_step_from(io, params, options, control, clock, y, ints, diag, history, events, stages,
                    chain, t, h):  # fmt: skip
    """:func:`plant_io_step` on the kernel state made of these arrays (the plant's Python path:
    numba dispatches arrays fast, a named tuple slowly)."""
    s = S.KernelState(
        params, options, control, clock, y, ints, diag, history, events, stages, chain
    )
    return plant_io_step(io, s, t, h)


_ENTRY_POINTS: dict[str, Any] = {}
if AVAILABLE:
    import numba
    from numba import carray, types
    from numba.extending import register_jitable

    refresh_cache()
    # the conversions and the law are plain functions; compiled here as they are
    for _f in (
        _params.weight_on_bit,
        _units.si_plant_values,
        _units.si_to_tau,
        _units.si_torque_deviation,
        S.chain_columns,
    ):
        register_jitable(_f)
    _SIG = types.int32(types.CPointer(types.float64), types.CPointer(types.voidptr),
                       types.float64, types.float64)  # fmt: skip
    _F64, _I64 = np.float64, np.int64

    @_jit.cached(numba.njit, nogil=True)
    def kernel_state(args, hcap, ecap):
        params = carray(args[0], (S.P_SIZE,), dtype=_F64)
        zcols = S.chain_columns(int(params[S.P_NT]), int(params[S.P_NA]))
        return S.KernelState(
            params,
            carray(args[1], (S.O_SIZE,), dtype=_F64),
            carray(args[2], (S.C_SIZE,), dtype=_F64),
            carray(args[3], (S.X_SIZE,), dtype=_F64),
            carray(args[4], (S.Y_SIZE,), dtype=_F64),
            carray(args[5], (S.I_SIZE,), dtype=_I64),
            carray(args[6], (S.D_SIZE,), dtype=_F64),
            carray(args[7], (S.H_ROWS, hcap), dtype=_F64),
            carray(args[8], (ecap, S.E_COLS), dtype=_F64),
            carray(args[9], (S.K_ROWS, S.Y_SIZE), dtype=_F64),
            carray(args[10], (S.Z_ROWS, zcols), dtype=_F64),
        )

    def plant_step(io_p, args, t, h):
        # plant_io_step on the block and the kernel's arrays at these addresses
        io = carray(io_p, (PLANT.size,))
        s = kernel_state(args, int(io[PLANT.hcap]), int(io[PLANT.ecap]))
        return plant_io_step(io, s, t, h)

    def ctrl_outputs(io_p, args, t, h):
        # ControllerFmu.output_values: the block's fmu_output
        _block.fmu_output(carray(io_p, (_BLOCK.size,)))
        return DONE

    def ctrl_step(io_p, args, t, h):
        # ControllerFmu.advance: the block's fmu_step
        _block.fmu_step(carray(io_p, (_BLOCK.size,)), t, h)
        return DONE

    _ENTRY_POINTS.update(plant_step=plant_step, ctrl_outputs=ctrl_outputs, ctrl_step=ctrl_step)
