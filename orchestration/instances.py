"""The FMU instances of one co-simulation run: life cycle, fast FMI calls, failures, log.

fmpy's ``FMU2Slave`` loads each FMU's shared library and gives every FMI 2.0 function of the
standard its C signature (``fmu.dll.fmi2DoStep`` etc. carry ``argtypes`` and ``restype``).
The life-cycle calls (instantiate, set up, initialization, terminate, free) go through
``FMU2Slave``'s methods. The stepping loop instead calls those typed C functions directly with
buffers built once per run (:class:`RealBatch`: value references and a value buffer that is
also a numpy array), because ``FMU2Slave.getReal``/``setReal``/``doStep`` build ctypes arrays
and raise on every call.

:class:`Instances` holds the units of a run. Every FMI call that fails (``fmi2Discard``,
``fmi2Error`` or ``fmi2Fatal``) goes through :meth:`Instances.fail`, which marks what the
standard still allows for that unit (FMI 2.0, section 2.1.3) and raises :class:`UnitFailure`;
:meth:`Instances.describe` turns it into the :class:`~.results.FmuFailure` of the result. The
FMUs' log messages reach Python through the logger callback of :func:`make_callbacks`.
"""

from __future__ import annotations

import ctypes
import logging
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from typing import Any, NoReturn

import numpy as np
from fmpy import calloc, free
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2LastSuccessfulTime,
    fmi2ValueReference,
)
from fmpy.logging import addLoggerProxy

from drillstring.orchestration.connections import System
from drillstring.orchestration.results import FmuFailure

__all__ = [
    "STATUS_NAMES",
    "VR",
    "Instance",
    "Instances",
    "RealBatch",
    "UnitFailure",
    "make_callbacks",
]

log = logging.getLogger(__name__)

#: fmi2Status codes 0..5
STATUS_NAMES = ("ok", "warning", "discard", "error", "fatal", "pending")
VR = fmi2ValueReference
_MAX_MESSAGES = 1000  # per unit, kept for its failure report
_MAX_LOG = 100_000  # messages kept in CosimResult.log


def _typed(fmu: FMU2Slave, name: str, required: bool = True) -> Any:
    """fmpy's typed C function ``name`` of ``fmu``'s library, or None if absent and optional."""
    f = getattr(fmu.dll, name, None)
    if f is None:
        if required:
            raise ValueError(f"{fmu.modelIdentifier}: shared library lacks {name}")
        return None
    if f.argtypes is None or f.restype is not ctypes.c_int:
        raise RuntimeError(f"fmpy did not declare the C signature of {name}")
    return f


class Instance:
    """One unit of a run: fmpy object, typed C functions, FMU state slot, log messages.

    ``dead``: the unit returned fmi2Error (only fmi2FreeInstance is allowed);
    ``fatal``: fmi2Fatal (no call at all).
    """

    __slots__ = (
        "index",
        "name",
        "library",
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

    def __init__(self, index: int, name: str, library: str) -> None:
        self.index, self.name, self.library = index, name, library
        self.fmu: FMU2Slave | None = None
        self.state = ctypes.c_void_p()
        self.initialized = False
        self.dead = False
        self.fatal = False
        self.messages: deque[str] = deque(maxlen=_MAX_MESSAGES)

    def bind(self, fmu: FMU2Slave) -> None:
        """Take the typed C functions of an instantiated ``fmu``.

        Parameters
        ----------
        fmu : fmpy.fmi2.FMU2Slave
            The instantiated unit.
        """
        self.fmu = fmu
        self.comp = ctypes.c_void_p(fmu.component)
        self.do_step = _typed(fmu, "fmi2DoStep")
        self.get_real = _typed(fmu, "fmi2GetReal")
        self.set_real = _typed(fmu, "fmi2SetReal")
        self.get_integer = _typed(fmu, "fmi2GetInteger")
        self.get_boolean = _typed(fmu, "fmi2GetBoolean")
        self.get_state = _typed(fmu, "fmi2GetFMUstate", required=False)
        self.set_state = _typed(fmu, "fmi2SetFMUstate", required=False)
        self.free_state = _typed(fmu, "fmi2FreeFMUstate", required=False)
        self.get_real_status = _typed(fmu, "fmi2GetRealStatus", required=False)


class RealBatch:
    """A batched fmi2GetReal or fmi2SetReal of one unit, with preallocated buffers.

    ``buf`` is a ctypes double array (given, e.g. aliasing a slice of the master's value
    vector, or allocated here); ``view`` is ``buf`` as a numpy array. ``idx`` maps the
    batch to positions in the master's value vector (sources for sets, destinations for
    gets). ``conv`` (sets only): (position in the batch, unit conversion) of the inputs whose
    source has another unit (:attr:`~.connections.System.conversions`), applied to the
    gathered values before the call.
    """

    __slots__ = ("inst", "fn", "vr", "n", "buf", "view", "idx", "fname", "conv")

    def __init__(
        self,
        inst: Instance,
        get: bool,
        vrs: Sequence[int],
        idx: Sequence[int] | np.ndarray,
        buf: ctypes.Array[ctypes.c_double] | None = None,
        conv: Sequence[tuple[int, Any]] = (),
    ) -> None:
        self.inst = inst
        self.fn = inst.get_real if get else inst.set_real
        self.fname = "fmi2GetReal" if get else "fmi2SetReal"
        self.n = len(vrs)
        self.vr = (VR * self.n)(*vrs)
        self.buf = (ctypes.c_double * self.n)() if buf is None else buf
        self.view = np.ctypeslib.as_array(self.buf)
        self.idx = np.asarray(idx, dtype=np.intp)
        self.conv = tuple(conv)


def make_callbacks(
    on_message: Callable[[bytes, str, str, str], None],
) -> fmi2CallbackFunctions:
    """``fmi2CallbackFunctions`` whose logger hands every FMU message to Python.

    fmpy's native logger proxy formats the printf-style messages first (as
    ``fmpy.simulate_fmu`` does).

    Parameters
    ----------
    on_message : callable
        Called as ``on_message(instance name (bytes), status label, category, message)``.

    Returns
    -------
    fmpy.fmi2.fmi2CallbackFunctions
        The callbacks; keep them alive as long as any instance created with them.
    """

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
    try:
        addLoggerProxy(ctypes.byref(cb))
    except Exception as exc:  # pragma: no cover - fmpy ships the proxy
        log.warning("fmpy logger proxy unavailable, messages are unformatted: %s", exc)
    return cb


class UnitFailure(Exception):
    """An FMI call of unit ``unit`` (index) failed; :meth:`Instances.describe` reports it."""

    def __init__(self, unit: int, function: str, status: int, t: float, h: float | None) -> None:
        super().__init__(function)
        self.unit, self.function, self.status, self.t, self.h = unit, function, status, t, h


class Instances:
    """The units of one run, from instantiation to release (FMI 2.0, section 4.2.4).

    Parameters
    ----------
    system : System
        The validated system.
    libraries : sequence of str
        Per unit, the folder its FMU was extracted to (units of one FMU share it).
    log_categories : sequence of str or None
        Log categories to switch on (None: all, ``()``: logging off).
    """

    def __init__(
        self, system: System, libraries: Sequence[str], log_categories: Sequence[str] | None
    ) -> None:
        self.system = system
        self.log_categories = log_categories
        self.items = [
            Instance(i, u.name, lib)
            for i, (u, lib) in enumerate(zip(system.units, libraries, strict=True))
        ]
        self._by_name = {inst.name.encode("utf-8"): inst for inst in self.items}
        self.log: list[tuple[str, str, str, str]] = []
        self._callbacks = make_callbacks(self._on_message)

    def __iter__(self) -> Iterator[Instance]:
        return iter(self.items)

    def __getitem__(self, index: int) -> Instance:
        return self.items[index]

    def _on_message(self, instance_name: bytes, label: str, category: str, text: str) -> None:
        """Logger callback target: keep the message per unit and in the run's log."""
        inst = self._by_name.get(instance_name)
        if inst is not None:
            inst.messages.append(f"[{label}] {text}")
        if len(self.log) < _MAX_LOG:
            name = instance_name.decode("utf-8", "replace") if instance_name else "?"
            self.log.append((name, label, category, text))

    # -- failures ----------------------------------------------------------------------

    def fail(
        self, inst: Instance, function: str, status: int, t: float, h: float | None
    ) -> NoReturn:
        """Record what ``inst`` may still do after ``status`` and raise :class:`UnitFailure`.

        Parameters
        ----------
        inst : Instance
            The unit whose call failed.
        function : str
            The FMI function (as the report should name it).
        status : int
            The fmi2Status it returned.
        t : float
            Communication point at which the call started.
        h : float or None
            Macro step being attempted (None outside fmi2DoStep).
        """
        if status >= 3:
            inst.dead = True
        if status == 4:  # fmi2Fatal: every instance of that FMU is corrupted (FMI 2.0, 2.1.3)
            for other in self.items:
                if other.library == inst.library:
                    other.dead = other.fatal = True
        raise UnitFailure(inst.index, function, status, t, h)

    def call(self, inst: Instance, function: str, t: float, call: Callable, *args: Any) -> Any:
        """A life-cycle call through fmpy.

        Parameters
        ----------
        inst : Instance
            The unit called.
        function : str
            The FMI function (as a failure report should name it).
        t : float
            Current time (for failure reports).
        call : callable
            The fmpy method, called with ``*args``.

        Returns
        -------
        object
            What ``call`` returns; an FMI error raises :class:`UnitFailure` instead.
        """
        try:
            return call(*args)
        except FMICallException as exc:
            self.fail(inst, function, exc.status, t, None)

    def describe(self, f: UnitFailure) -> FmuFailure:
        """The failure as reported in the result, with the unit's log messages.

        Parameters
        ----------
        f : UnitFailure
            The failure raised by :meth:`fail`.

        Returns
        -------
        FmuFailure
            Unit, function, status, time, step and messages; after a discarded step also
            the unit's fmi2LastSuccessfulTime when it reports one.
        """
        inst = self.items[f.unit]
        last_ok = None
        get_status = getattr(inst, "get_real_status", None)
        if f.status == 2 and f.function == "fmi2DoStep" and get_status is not None:
            value = ctypes.c_double()  # optional for the FMU
            if get_status(inst.comp, fmi2LastSuccessfulTime, ctypes.byref(value)) == 0:
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

    # -- life cycle ----------------------------------------------------------------------

    def instantiate(self, t0: float, t_end: float) -> None:
        """Instantiate, set up the experiment and set the start values of every unit.

        Parameters
        ----------
        t0, t_end : float
            Start and stop time passed to fmi2SetupExperiment.
        """
        sysm = self.system
        for inst, unit, md in zip(self.items, sysm.units, sysm.model_descriptions, strict=True):
            cats = self.log_categories
            fmu = None
            try:
                fmu = FMU2Slave(
                    guid=md.guid,
                    unzipDirectory=inst.library,
                    modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=unit.name,
                )
                fmu.instantiate(callbacks=self._callbacks, loggingOn=cats != ())
            except Exception as exc:  # fmpy raises plain Exception for both
                inst.messages.append(f"[error] {exc}")
                if fmu is not None:
                    fmu.freeLibrary()
                self.fail(inst, "fmi2Instantiate", 3, t0, None)
            inst.bind(fmu)
            if cats:  # None: all categories (the FMI default for loggingOn=true)
                declared = {c.name for c in md.logCategories}
                cats = [c for c in cats if c in declared]
                on = bool(cats)  # none of them declared: logging off, not "all"
                self.call(inst, "fmi2SetDebugLogging", t0, fmu.setDebugLogging, on, cats)
            self.call(inst, "fmi2SetupExperiment", t0, fmu.setupExperiment, None, t0, t_end)
            for name, value in unit.start_values.items():
                ref = sysm.variables[inst.index][name]
                setter = {
                    "Real": fmu.setReal,
                    "Integer": fmu.setInteger,
                    "Enumeration": fmu.setInteger,
                    "Boolean": fmu.setBoolean,
                    "String": fmu.setString,
                }[ref.type]
                self.call(inst, f"fmi2Set{ref.type} ({name})", t0, setter, [ref.vr], [value])

    def enter_initialization(self, t0: float) -> None:
        """fmi2EnterInitializationMode of every unit.

        Parameters
        ----------
        t0 : float
            Start time (for failure reports).
        """
        for inst in self.items:
            self.call(inst, "fmi2EnterInitializationMode", t0, inst.fmu.enterInitializationMode)
            inst.initialized = True

    def exit_initialization(self, t0: float) -> None:
        """fmi2ExitInitializationMode of every unit.

        Parameters
        ----------
        t0 : float
            Start time (for failure reports).
        """
        for inst in self.items:
            self.call(inst, "fmi2ExitInitializationMode", t0, inst.fmu.exitInitializationMode)

    def check_rollback(self) -> None:
        """Raise ValueError unless every unit has fmi2Get/Set/FreeFMUstate."""
        for inst in self.items:
            if None in (inst.get_state, inst.set_state, inst.free_state):
                msg = "declares canGetAndSetFMUstate but lacks fmi2Get/Set/FreeFMUstate"
                raise ValueError(f"unit {inst.name!r} {msg}")

    def save_states(self, t: float) -> None:
        """fmi2GetFMUstate of every unit into its state slot (before a step that may be undone).

        Parameters
        ----------
        t : float
            Current communication point (for failure reports).
        """
        for inst in self.items:
            st = inst.get_state(inst.comp, ctypes.byref(inst.state))
            if st > 1:
                self.fail(inst, "fmi2GetFMUstate", st, t, None)

    def restore_states(self, t: float) -> None:
        """fmi2SetFMUstate of every unit from its state slot.

        Parameters
        ----------
        t : float
            The communication point rolled back to (for failure reports).
        """
        for inst in self.items:
            st = inst.set_state(inst.comp, inst.state)
            if st > 1:
                self.fail(inst, "fmi2SetFMUstate", st, t, None)

    def free_states(self) -> None:
        """fmi2FreeFMUstate of every unit's state slot."""
        for inst in self.items:
            inst.free_state(inst.comp, ctypes.byref(inst.state))
            inst.state = ctypes.c_void_p()

    def release(self) -> None:
        """Terminate and free every instance that can be (never raises)."""
        for inst in self.items:
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
