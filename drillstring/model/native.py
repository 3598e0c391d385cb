"""C entry points of the engine's step and of the control law, for native callers.

The FMUs' front layer (``fmu_src/fmi_front/drillstring_fmi2.c``) serves ``fmi2SetReal`` of the
inputs, ``fmi2DoStep`` and ``fmi2GetReal``/``fmi2GetInteger`` of the outputs without entering
Python: it calls the compiled functions below (numba ``cfunc``, their ``.address``), which run the
same compiled kernel (:func:`drillstring.model.kernel.stepper.advance`; its ``write_sample`` for
the outputs), the same SI conversions (:mod:`drillstring.model.units`) and the same control law
(:func:`drillstring.model.control.feedback_torque`, :func:`~drillstring.model.control.
switch_on_references`) as the Python path of the FMUs, so both give the same bits.

Every function takes ``(io, args, t, h)``: ``io`` is a float64 block shared by the Python slave
and the front layer (layout: the ``IO_*`` and ``PLANT_*``/``CTRL_*`` slots below), ``args`` the
addresses of the kernel's arrays (:class:`~drillstring.model.kernel.state.KernelState` order,
for the plant; unused by the controller). A step returns :data:`DONE` (served: the outputs are in
``io``), :data:`NOT_STARTED` (nothing changed: the Python path serves the call, with its checks
and messages) or :data:`RESUME` (the kernel returned ``io[IO_RESUME]``, a status the Python path
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

from drillstring.model import control as _control
from drillstring.model import params as _params
from drillstring.model import units as _units
from drillstring.model.kernel import jit as _jit
from drillstring.model.kernel import state as S
from drillstring.model.kernel import stepper as _stepper

__all__ = [
    "AVAILABLE",
    "CTRL_IO_SIZE",
    "DONE",
    "NOT_STARTED",
    "PLANT_IO_SIZE",
    "RESUME",
    "controller_functions",
    "plant_functions",
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

# --- the plant's io -----------------------------------------------------------------------------
PLANT_SI = IO_BASE  # 1: SI units (DrillStringPlantSI), 0: scaled
PLANT_HCAP = IO_BASE + 1  # columns of the history buffer
PLANT_ECAP = IO_BASE + 2  # rows of the event log
PLANT_INPUT = IO_BASE + 3  # the FMU's input (R - R0 scaled, or the table torque R in N m)
PLANT_K = IO_BASE + 4  # SIScaling.plant_constants (12 slots)
N_K = 12
PLANT_TAU = PLANT_K + N_K  # the engine's time (the OUT_TAU column of a kernel sample)
PLANT_OUT = PLANT_TAU + 1  # the outputs, in the order of PLANT_SCALED_KEYS / PLANT_SI_KEYS
#: Output slots of the scaled plant: Engine.outputs() keys, in order.
PLANT_SCALED_KEYS = (
    "u", "du", "phi", "dphi", "theta", "dtheta", "d", "g", "tau_n", "R_minus_R0",
    "mode", "stick_events", "bit_bounce", "torsional_stick",
)  # fmt: skip
#: Output slots of the SI plant: units.PLANT_SI names, then the counters.
PLANT_SI_KEYS = (
    *(q.name for q in _units.PLANT_SI), "mode", "stick_events", "bit_bounce", "torsional_stick"
)  # fmt: skip
PLANT_IO_SIZE = PLANT_OUT + max(len(PLANT_SCALED_KEYS), len(PLANT_SI_KEYS))
_BOUNCE_SCALED = PLANT_OUT + PLANT_SCALED_KEYS.index("bit_bounce")
_BOUNCE_SI = PLANT_OUT + PLANT_SI_KEYS.index("bit_bounce")
_N_SI = len(_units.PLANT_SI)
assert S.OUTPUT_COLUMNS == ("tau", *PLANT_SCALED_KEYS[: S.OUT_SIZE - 1]), "a kernel sample's layout"

# --- the controller's io ------------------------------------------------------------------------
CTRL_SI = IO_BASE  # 1: SI (errors from the set point Omega0), 0: scaled
CTRL_IN = IO_BASE + 1  # the four measured inputs
CTRL_OUT = IO_BASE + 5  # the output
CTRL_LATCHED = IO_BASE + 6
CTRL_REF = IO_BASE + 7  # phi_ref, twist_ref
CTRL_ENABLED = IO_BASE + 9
CTRL_TON = IO_BASE + 10  # the law's t_on
CTRL_TON_EFF = IO_BASE + 11  # t_on, or inf when the feedback is disabled
CTRL_F = IO_BASE + 12  # F[0..3]
CTRL_K0 = IO_BASE + 16
CTRL_RFF = IO_BASE + 17
CTRL_LATCH = IO_BASE + 18  # latch code
CTRL_OMEGA0 = IO_BASE + 19  # set point (SI)
CTRL_IO_SIZE = IO_BASE + 20

_HERE = Path(__file__).resolve()
#: Every source the functions below compile (the kernel's, and the conversions and the law).
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
        _CFUNCS[name] = numba.cfunc(_SIG, cache=True, nogil=True)(_ENTRY_POINTS[name])
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
    """(step, outputs) addresses of the controller's native functions.

    The outputs function evaluates the law (29)-(31)
    (:func:`~drillstring.model.control.feedback_torque`); the step latches the switch-on
    references (``docs/model.md``, "Bumpless switch-on"). Both are compiled (or loaded from
    numba's cache) at the first call.

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
        _units.setpoint_errors,
    ):
        register_jitable(_f)
    _SIG = types.int32(types.CPointer(types.float64), types.CPointer(types.voidptr),
                       types.float64, types.float64)  # fmt: skip
    _F64, _I64 = np.float64, np.int64

    @numba.njit(cache=True, nogil=True)
    def kernel_state(args, hcap, ecap):
        return S.KernelState(
            carray(args[0], (S.P_SIZE,), dtype=_F64),
            carray(args[1], (S.O_SIZE,), dtype=_F64),
            carray(args[2], (S.C_SIZE,), dtype=_F64),
            carray(args[3], (S.X_SIZE,), dtype=_F64),
            carray(args[4], (S.Y_SIZE,), dtype=_F64),
            carray(args[5], (S.I_SIZE,), dtype=_I64),
            carray(args[6], (S.D_SIZE,), dtype=_F64),
            carray(args[7], (S.H_ROWS, hcap), dtype=_F64),
            carray(args[8], (ecap, S.E_COLS), dtype=_F64),
            carray(args[9], (S.K_ROWS, S.Y_SIZE), dtype=_F64),
        )

    def plant_step(io_p, args, t, h):
        # DrillStringPlant.advance and Engine.set_input/advance, for a held input (the FMU's)
        io = carray(io_p, (PLANT_IO_SIZE,))
        si = io[PLANT_SI] != 0.0
        s = kernel_state(args, int(io[PLANT_HCAP]), int(io[PLANT_ECAP]))
        K = (io[PLANT_K], io[PLANT_K + 1], io[PLANT_K + 2], io[PLANT_K + 3], io[PLANT_K + 4],
             io[PLANT_K + 5], io[PLANT_K + 6], io[PLANT_K + 7], io[PLANT_K + 8],
             io[PLANT_K + 9], io[PLANT_K + 10], io[PLANT_K + 11])  # fmt: skip
        x = io[PLANT_INPUT]
        r = _units.si_torque_deviation(K[5], K[4], x) if si else x
        target = _units.si_to_tau(K[2], t + h) if si else t + h
        C, X, I, D = s.control, s.clock, s.ints, s.diag  # noqa: E741
        if not (math.isfinite(r) and math.isfinite(target)) or target < X[S.X_TAU]:
            return NOT_STARTED  # the Python path names the error
        if int(C[S.C_KIND]) != S.CTRL_HELD:
            return NOT_STARTED
        if r != C[S.C_R]:
            C[S.C_R] = r
            _stepper.refresh(s, None)
        while True:
            st = _stepper.advance(s, target, None)
            I[S.I_ENUM] = 0  # the event log drained (the FMU keeps no events)
            if st != S.ST_EVLOG_FULL:
                break
        if st != S.ST_OK:
            io[IO_RESUME] = st
            return RESUME
        bounces = float(I[S.I_NBOUNCE])
        if bounces > io[_BOUNCE_SI if si else _BOUNCE_SCALED]:
            io[IO_RESUME] = st  # a warning for the Python path to log
            return RESUME
        # the engine's outputs (tau, then Engine.outputs() up to the mode) as the kernel writes
        # them for a sample; then the counters, or the SI values of the scaled ones
        _stepper.write_sample(s, io[PLANT_TAU : PLANT_TAU + S.OUT_SIZE])
        o = PLANT_OUT + S.OUT_SIZE - 1
        if si:
            o = PLANT_OUT
            v = _units.si_plant_values(K, io[PLANT_TAU], io[o], io[o + 1], io[o + 2], io[o + 3],
                                       io[o + 4], io[o + 5], D[S.D_D], D[S.D_G], D[S.D_TAUN],
                                       D[S.D_TOB])  # fmt: skip
            for i in range(_N_SI):
                io[o + i] = v[i]
            o += _N_SI
            io[o] = float(I[S.I_MODE])
            o += 1
        io[o] = float(I[S.I_NSTICK])
        io[o + 1] = bounces
        io[o + 2] = float(I[S.I_NTSTICK])
        return DONE

    @numba.njit(cache=True, nogil=True)
    def measured(io):
        a, b, c, d = io[CTRL_IN], io[CTRL_IN + 1], io[CTRL_IN + 2], io[CTRL_IN + 3]
        if io[CTRL_SI] != 0.0:
            return _units.setpoint_errors(io[CTRL_OMEGA0], io[IO_TIME], a, b, c, d)
        return a, b, c, d

    @numba.njit(cache=True, nogil=True)
    def candidate_references(io):
        phi, _, theta, _ = measured(io)
        return _control.switch_on_references(int(io[CTRL_LATCH]), phi, theta, io[CTRL_K0])

    def ctrl_outputs(io_p, args, t, h):
        # TorsionalController.output_values
        io = carray(io_p, (CTRL_IO_SIZE,))
        if io[CTRL_LATCHED] != 0.0:
            phi_ref, twist_ref = io[CTRL_REF], io[CTRL_REF + 1]
        else:
            phi_ref, twist_ref = candidate_references(io)
        phi, dphi, theta, dtheta = measured(io)
        F = (io[CTRL_F], io[CTRL_F + 1], io[CTRL_F + 2], io[CTRL_F + 3])
        io[CTRL_OUT] = _control.feedback_torque(
            io[IO_TIME], phi, dphi, theta, dtheta, F, io[CTRL_K0], io[CTRL_RFF],
            io[CTRL_TON_EFF], phi_ref, twist_ref,
        )  # fmt: skip
        return DONE

    def ctrl_step(io_p, args, t, h):
        # TorsionalController.advance
        io = carray(io_p, (CTRL_IO_SIZE,))
        if io[CTRL_LATCHED] == 0.0 and io[CTRL_ENABLED] != 0.0 and t >= io[CTRL_TON]:
            phi_ref, twist_ref = candidate_references(io)
            io[CTRL_REF] = phi_ref
            io[CTRL_REF + 1] = twist_ref
            io[CTRL_LATCHED] = 1.0
        return DONE

    _ENTRY_POINTS.update(plant_step=plant_step, ctrl_outputs=ctrl_outputs, ctrl_step=ctrl_step)
