"""Low-overhead access to an instantiated FMI 2.0 co-simulation unit (fmpy FMU2Slave).

fmpy's ``FMU2Slave.getReal``/``setReal``/``doStep`` build ctypes arrays and check the
status on every call. The master's stepping loop instead calls the FMU's C functions
(FMI 2.0 standard, sections 2.1.7 and 4.2.3) with buffers built once per run:
:class:`Instance` holds the raw functions of one unit, :class:`RealBatch` a batch of
value references with a preallocated value buffer that is also a numpy array.
:func:`make_callbacks` builds the ``fmi2CallbackFunctions`` whose logger hands every
FMU message to Python (through fmpy's native proxy that formats printf-style messages).
"""

from __future__ import annotations

import ctypes
import logging
from collections import deque
from collections.abc import Callable, Sequence

import numpy as np
from fmpy import calloc, free
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

__all__ = ["STATUS_NAMES", "Instance", "RealBatch", "make_callbacks", "VR"]

log = logging.getLogger(__name__)

#: fmi2Status codes 0..5
STATUS_NAMES = ("ok", "warning", "discard", "error", "fatal", "pending")
VR = ctypes.c_uint
_PVR = ctypes.POINTER(VR)
_PREAL = ctypes.POINTER(ctypes.c_double)
_PINT = ctypes.POINTER(ctypes.c_int)
_PSTATE = ctypes.POINTER(ctypes.c_void_p)
_MAX_MESSAGES = 1000


def _raw(fmu: FMU2Slave, name: str, argtypes: list, required: bool = True):
    """The FMU's C function ``name`` with explicit argument types, or None if absent."""
    try:
        f = getattr(fmu.dll, name)
    except AttributeError:
        if required:
            raise ValueError(f"{fmu.modelIdentifier}: shared library lacks {name}") from None
        return None
    f.argtypes = argtypes
    f.restype = ctypes.c_int
    return f


class Instance:
    """One unit of a run: fmpy object, raw C functions, FMU state slot, log messages.

    ``dead``: the unit returned fmi2Error (only fmi2FreeInstance is allowed);
    ``fatal``: fmi2Fatal (no call at all).
    """

    __slots__ = (
        "index",
        "name",
        "fmu",
        "comp",
        "do_step",
        "get_real",
        "set_real",
        "get_integer",
        "get_boolean",
        "get_state",
        "set_state",
        "free_state",
        "get_real_status",
        "state",
        "initialized",
        "dead",
        "fatal",
        "messages",
    )

    def __init__(self, index: int, name: str):
        self.index, self.name = index, name
        self.fmu: FMU2Slave | None = None
        self.state = ctypes.c_void_p()
        self.initialized = False
        self.dead = False
        self.fatal = False
        self.messages: deque[str] = deque(maxlen=_MAX_MESSAGES)

    def bind(self, fmu: FMU2Slave) -> None:
        """Resolve the C functions of an instantiated ``fmu``."""
        self.fmu = fmu
        self.comp = ctypes.c_void_p(fmu.component)
        c, p = ctypes.c_void_p, ctypes.c_size_t
        self.do_step = _raw(fmu, "fmi2DoStep", [c, ctypes.c_double, ctypes.c_double, ctypes.c_int])
        self.get_real = _raw(fmu, "fmi2GetReal", [c, _PVR, p, _PREAL])
        self.set_real = _raw(fmu, "fmi2SetReal", [c, _PVR, p, _PREAL])
        self.get_integer = _raw(fmu, "fmi2GetInteger", [c, _PVR, p, _PINT])
        self.get_boolean = _raw(fmu, "fmi2GetBoolean", [c, _PVR, p, _PINT])
        self.get_state = _raw(fmu, "fmi2GetFMUstate", [c, _PSTATE], required=False)
        self.set_state = _raw(fmu, "fmi2SetFMUstate", [c, c], required=False)
        self.free_state = _raw(fmu, "fmi2FreeFMUstate", [c, _PSTATE], required=False)
        self.get_real_status = _raw(fmu, "fmi2GetRealStatus", [c, ctypes.c_int, _PREAL], False)


class RealBatch:
    """A batched fmi2GetReal or fmi2SetReal of one unit, with preallocated buffers.

    ``buf`` is a ctypes double array (given, e.g. aliasing a slice of the master's value
    vector, or allocated here); ``view`` is ``buf`` as a numpy array. ``idx`` maps the
    batch to positions in the master's value vector (sources for sets, destinations for
    gets).
    """

    __slots__ = ("inst", "fn", "vr", "n", "buf", "view", "idx", "fname")

    def __init__(self, inst: Instance, get: bool, vrs: Sequence[int], idx, buf=None):
        self.inst = inst
        self.fn = inst.get_real if get else inst.set_real
        self.fname = "fmi2GetReal" if get else "fmi2SetReal"
        self.n = len(vrs)
        self.vr = (VR * self.n)(*vrs)
        self.buf = (ctypes.c_double * self.n)() if buf is None else buf
        self.view = np.ctypeslib.as_array(self.buf)
        self.idx = np.asarray(idx, dtype=np.intp)


def make_callbacks(
    on_message: Callable[[bytes, str, str, str], None],
) -> fmi2CallbackFunctions:
    """``fmi2CallbackFunctions`` whose logger calls ``on_message(instance name (bytes),
    status label, category, message)``. Keep the returned object alive as long as any
    instance created with it."""

    def logger(env, instance_name, status, category, message):  # called by the FMUs
        label = STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else str(status)
        on_message(
            instance_name or b"",
            label,
            (category or b"").decode("utf-8", "replace"),
            (message or b"").decode("utf-8", "replace"),
        )

    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(logger)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    try:  # native proxy formatting the printf-style message (as fmpy.simulate_fmu does)
        from fmpy.logging import addLoggerProxy

        addLoggerProxy(ctypes.byref(cb))
    except Exception as exc:  # pragma: no cover - fmpy ships the proxy
        log.warning("fmpy logger proxy unavailable, messages are unformatted: %s", exc)
    return cb
