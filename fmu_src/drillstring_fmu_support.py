"""The lifecycle shared by every drillstring FMU (bundled into each FMU's ``resources/``).

An FMU script of the project holds only its variables and its physics call: it subclasses
:class:`FmuModel`, lists its :class:`Variable` s in ``VARIABLES`` and implements four methods,

* ``configure(values)`` -- build the model from the parameter values (raise ``ValueError`` for
  an inconsistent combination),
* ``output_values()`` -- the current outputs by name,
* ``advance(t, h)`` -- one communication step, returning a :class:`StepResult`,
* ``save()`` / ``restore(...)`` -- the model's part of an FMU state.

Everything else is here, written once: registration with pythonfmu, the checks of each value
(finite numbers, ranges, enumeration items, via :mod:`drillstring.validation` and the model's
own validators), the phases (instantiated, initialization, stepping, terminated), the step wrapper
(finite time and step, step size > 0, communication point = the FMU's time), FMU states and how
errors are reported.

**Division of labour with the front layer.** The FMU's binary ``binaries/linux64/<id>.so`` is the
project's C layer ``fmu_src/fmi_front/`` in front of pythonfmu's library; it checks the call
sequence of FMI 2.0 (section 4.2.4), value references, types and which variables may be set in
which state, before anything reaches Python. This module checks *values*. It never raises into
pythonfmu (that would be ``fmi2Fatal`` and destroy the instance): a rejected call logs a message
with status ``fmi2Error``, applies nothing and returns normally; the layer learns the call's
status from the log records of that call and returns ``fmi2Error`` from it. ``fmi2Warning`` and
``fmi2Discard`` (the model left its validity inside a step) work the same way; the message of a
discarded step hands the layer the time the FMU reached with it, a double in the same typed call,
for ``fmi2GetRealStatus(fmi2LastSuccessfulTime)``.

**Typed calls into the layer.** At ``fmi2Instantiate`` the layer gives the slave it is making the
addresses of two of its C functions (:class:`drillstring_fmu_boot.Front`); the slave calls them
through ctypes: its log messages go to the layer directly (pythonfmu 0.7.0 keeps a
reference to every message that passes its log queue, so each would live forever), and at the
end of each call while stepping it hands over the descriptor of its native fast path
(:class:`FastPath`) with its length, which the layer checks before using it. At
``fmi2FreeInstance`` the layer calls :meth:`FmuModel.release`.

Both FMUs run in one interpreter when a host loads them together; the first imported copy of this
module serves both, so it must stay backwards compatible within one build of the FMUs.
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import math
import os
import struct
import time as _time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import drillstring_fmu_boot as _boot
import numpy as np
from pythonfmu import (
    Boolean,
    DefaultExperiment,
    Fmi2Causality,
    Fmi2Initial,
    Fmi2Slave,
    Fmi2Variability,
    Integer,
    Real,
)
from pythonfmu.enums import Fmi2Status

from drillstring.model import native
from drillstring.model.kernel import jit as _jit
from drillstring.validation import check_int, check_real

CONFIG_FILE = "drillstring_fmu.json"
#: Category of the records meant for the front layer only (never forwarded to the host).
#: Log categories of every drillstring FMU (modelDescription.xml ``LogCategories``).
LOG_CATEGORIES: dict[str, str] = {
    "logStatusWarning": "Warnings (status fmi2Warning); always reported",
    "logStatusDiscard": "A step that left the model's validity (fmi2Discard); always reported",
    "logStatusError": "Rejected calls and values (status fmi2Error); always reported",
    "logStatusFatal": "Failures of the FMU itself (status fmi2Fatal); always reported",
    "logInfo": "Information: the Python that runs the FMU, the package cache, kernel compilation",
    "logAll": "All of the above",
}
PHASES = ("instantiated", "initialization", "stepping", "terminated")
_STATE_FORMAT = 2

__all__ = [
    "ARRAY_VR_BASE",
    "ARRAY_VR_STRIDE",
    "CONFIG_FILE",
    "ArrayOutput",
    "FmuModel",
    "FastPath",
    "FmuState",
    "LOG_CATEGORIES",
    "StepResult",
    "Variable",
    "enumeration",
    "output",
    "read_config",
]


def read_config(resources: str | os.PathLike[str] | None) -> dict[str, Any]:
    """Read ``drillstring_fmu.json`` from the FMU's resources folder.

    Raises ``FileNotFoundError`` or ``ValueError`` with the path when it is missing or unreadable:
    an FMU without it was not built by ``build_fmus.py``.
    """
    if resources is None:
        raise FileNotFoundError(f"no resources folder given; cannot read {CONFIG_FILE}")
    # a string, not a Path: pathlib (3.11) interns every part of a path it parses, and this runs
    # at every instantiation (see drillstring_fmu_boot._cache_folder)
    path = os.path.join(os.fspath(resources), CONFIG_FILE)
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as exc:
        raise FileNotFoundError(f"cannot read FMU build configuration {path}: {exc}") from exc
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"FMU build configuration {path} is not valid JSON: {exc}") from exc
    if not isinstance(data, dict):
        raise ValueError(f"FMU build configuration {path} must hold a JSON object")
    return data


# ------------------------------------------------------------------------------------------------
# variables
# ------------------------------------------------------------------------------------------------

_PYTHONFMU_TYPE = {"Real": Real, "Integer": Integer, "Enumeration": Integer, "Boolean": Boolean}
_CAUSALITY = {c.name: c for c in Fmi2Causality}
#: Smallest positive double: the ``min`` of a parameter that must be > 0 (FMI's min is inclusive).
POSITIVE = math.ulp(0.0)


@dataclass(frozen=True)
class Variable:
    """One FMU variable; ``build_fmus.py`` writes ``min``, ``max``, ``items`` and the
    dependencies into modelDescription.xml, the lifecycle checks values with ``check``.

    ``type`` is ``"Real"``, ``"Integer"``, ``"Enumeration"`` (values 1..n of ``items``, accessed
    with fmi2Get/SetInteger) or ``"Boolean"``; ``causality`` is ``"parameter"`` (fixed, initial
    exact), ``"input"`` or ``"output"`` (initial calculated, listed in InitialUnknowns).
    ``check(value)`` returns the value to store or raises ``ValueError`` naming the rule;
    ``depends_on`` lists the inputs an output depends on directly (ModelStructure). ``unit`` (a
    Real's unit, one of :data:`drillstring.model.units.UNITS`; default ``"1"``) and
    ``display_unit`` (one of that unit's display units) go into modelDescription.xml.
    """

    name: str
    type: str
    causality: str
    description: str
    start: Any = None
    min: float | None = None
    max: float | None = None
    items: tuple[tuple[str, str], ...] = ()
    type_name: str | None = None
    check: Callable[[Any], Any] | None = None
    depends_on: tuple[str, ...] = ()
    unit: str = "1"
    display_unit: str | None = None

    def __post_init__(self) -> None:
        if self.type not in _PYTHONFMU_TYPE:
            raise ValueError(f"variable {self.name}: unknown type {self.type!r}")
        if self.causality not in ("parameter", "input", "output"):
            raise ValueError(f"variable {self.name}: unknown causality {self.causality!r}")
        if (self.start is None) != (self.causality == "output"):
            raise ValueError(f"variable {self.name}: parameters and inputs need a start value")
        if self.type == "Enumeration" and not (self.items and self.type_name):
            raise ValueError(f"variable {self.name}: an Enumeration needs items and type_name")
        if self.type != "Real" and (self.unit != "1" or self.display_unit is not None):
            raise ValueError(f"variable {self.name}: only a Real has a unit")

    @property
    def variability(self) -> str:
        if self.causality == "parameter":
            return "fixed"
        return "continuous" if self.type == "Real" else "discrete"

    @property
    def initial(self) -> str | None:
        return {"parameter": "exact", "output": "calculated"}.get(self.causality)

    def item(self, code: int) -> str:
        """Name of the Enumeration item with value ``code`` (1-based)."""
        return self.items[code - 1][0]

    def validate(self, value: Any) -> Any:
        """The value to store for ``value``, or ``ValueError`` naming the rule it breaks."""
        if self.type == "Real":
            x = check_real(self.name, value)
        elif self.type == "Boolean":
            x = bool(value)
        else:
            x = check_int(self.name, value)
            if self.type == "Enumeration" and not 1 <= x <= len(self.items):
                names = ", ".join(f"{i + 1} ({n})" for i, (n, _) in enumerate(self.items))
                raise ValueError(f"{self.name} must be one of {names}, got {x!r}")
        if self.check is not None:
            x = self.check(x)
        if (self.min is not None and x < self.min) or (self.max is not None and x > self.max):
            lo = "-inf" if self.min is None else repr(self.min)
            hi = "inf" if self.max is None else repr(self.max)
            raise ValueError(f"{self.name} must be in its declared range [{lo}, {hi}], got {x!r}")
        return x


def enumeration(
    name: str, type_name: str, items: Sequence[tuple[str, str]], start: str, description: str
) -> Variable:
    """A fixed Enumeration parameter; ``start`` is the name of its start item."""
    names = [n for n, _ in items]
    return Variable(
        name,
        "Enumeration",
        "parameter",
        description,
        start=names.index(start) + 1,
        items=tuple(items),
        type_name=type_name,
    )


def output(
    name: str, type: str, description: str, depends_on: Sequence[str] = (), **kw: Any
) -> Variable:
    """An output computed from parameters, inputs and state (``initial="calculated"``)."""
    return Variable(name, type, "output", description, depends_on=tuple(depends_on), **kw)


#: The value references the FMI 3.0 front layer passes to fmi2GetReal for the elements of an
#: array output (:class:`ArrayOutput`): element ``i`` of ``ARRAYS[j]`` is
#: ``ARRAY_VR_BASE + j * ARRAY_VR_STRIDE + i``. No FMU variable has one, and the front layer of
#: an FMI 2.0 FMU refuses every value reference its model description does not declare before
#: pythonfmu sees it.
ARRAY_VR_BASE = 0x40000000
ARRAY_VR_STRIDE = 0x10000


@dataclass(frozen=True)
class ArrayOutput:
    """An array output of the FMU's FMI 3.0 twin (FMI 2.0 has no arrays, so the FMI 2.0 FMU does
    not declare it): a Float64 output of one dimension whose length is the value of the Integer
    parameter ``size`` (declared a structural parameter in FMI 3.0), with ``unit`` and
    ``display_unit`` as :class:`Variable`'s."""

    name: str
    description: str
    size: str
    unit: str = "1"
    display_unit: str | None = None


# ------------------------------------------------------------------------------------------------
# steps and states
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class StepResult:
    """Outcome of ``advance``: the time reached and, if any, a warning or the reason the model
    stopped inside the step (then ``reached`` is the time of the stop)."""

    reached: float
    warning: str | None = None
    stop: str | None = None


@dataclass
class FmuState:
    """An FMU state as pythonfmu stores it: the lifecycle's fields, the model's fields, an
    in-memory snapshot of the model (None for a deserialized state) and its bytes on demand."""

    fields: dict[str, Any]
    snapshot: Any = None
    make_payload: Callable[[], bytes] | None = None
    payload: bytes | None = None
    error: str | None = None

    def payload_bytes(self) -> bytes:
        if self.payload is None:
            self.payload = self.make_payload() if self.make_payload is not None else b""
        return self.payload


@dataclass
class FastPath:
    """What the front layer needs to serve calls natively (:mod:`drillstring.model.native`):
    the shared ``io`` block (float64), the addresses of the native ``step`` and ``outputs``
    functions (0: none) and of their ``args``, and the io slots of the inputs and outputs it
    serves. The layer checks every slot against the block's length."""

    io: np.ndarray
    step: int
    outputs: int
    inputs: Mapping[str, int]
    outputs_at: Mapping[str, int]
    args: np.ndarray | None = None


#: First entries of the descriptor a slave hands the front layer ("DSFP", version 2: with the io
#: block's length; fmu_src/fmi_front/fast.c).
_FAST_MAGIC = 0x44534650
_FAST_VERSION = 2
_FAST_TYPES = {"Real": 0, "Integer": 1}
#: The front layer's typed calls (:class:`drillstring_fmu_boot.Front`), called with the GIL held.
_FAST_CALL = ctypes.PYFUNCTYPE(ctypes.c_int32, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t)
_LOG_CALL = ctypes.PYFUNCTYPE(
    ctypes.c_int32,
    ctypes.c_void_p,
    ctypes.c_int32,
    ctypes.c_char_p,
    ctypes.c_char_p,
    ctypes.POINTER(ctypes.c_double),
)


def pack_state(state: FmuState) -> bytes:
    """Header length, JSON header (floats written by ``repr``: bit exact), then model bytes."""
    header = json.dumps(
        {"format": _STATE_FORMAT, "fields": state.fields}, sort_keys=True, separators=(",", ":")
    ).encode("utf-8")
    return struct.pack("<Q", len(header)) + header + state.payload_bytes()


def unpack_state(data: bytes) -> FmuState:
    """Inverse of :func:`pack_state`; a state with ``error`` set if the bytes are not one.

    The front layer has checked the bytes' origin (GUID) and integrity (checksum) already.
    """
    data = bytes(data)
    try:
        (n,) = struct.unpack("<Q", data[:8])
        header = json.loads(data[8 : 8 + n].decode("utf-8"))
        if header.get("format") != _STATE_FORMAT or not isinstance(header.get("fields"), dict):
            raise ValueError(f"unsupported state format {header.get('format')!r}")
    except (struct.error, UnicodeDecodeError, ValueError, AttributeError) as exc:
        return FmuState({}, error=f"cannot read the FMU state ({len(data)} bytes): {exc}")
    return FmuState(header["fields"], payload=data[8 + n :])


# ------------------------------------------------------------------------------------------------
# numba compile log
# ------------------------------------------------------------------------------------------------

_COMPILED: list[tuple[str, float]] = []


def _install_compile_listener() -> None:
    """Record numba compilations (not cache loads) so the FMU can log the first compile."""
    if not _jit.numba_available():
        return
    from numba.core import event

    class _Listener(event.Listener):
        depth = 0
        started = 0.0
        name = ""

        def on_start(self, ev: Any) -> None:
            if self.depth == 0:
                self.started = _time.perf_counter()
                func = getattr(ev.data.get("dispatcher"), "py_func", None)
                self.name = getattr(func, "__qualname__", "?")
            self.depth += 1

        def on_end(self, ev: Any) -> None:
            self.depth -= 1
            if self.depth == 0:
                _COMPILED.append((self.name, _time.perf_counter() - self.started))

    event.register("numba:compile", _Listener())


_install_compile_listener()


# ------------------------------------------------------------------------------------------------
# the lifecycle
# ------------------------------------------------------------------------------------------------


class _Rejected(Exception):
    """A call rejected by a check: its message is logged with status fmi2Error."""


class FmuModel(Fmi2Slave):
    """pythonfmu slave with the project's lifecycle; see the module docstring."""

    MODEL: ClassVar[str] = ""
    VARIABLES: ClassVar[tuple[Variable, ...]] = ()
    #: The array outputs of the FMI 3.0 twin (served by :meth:`array_values`).
    ARRAYS: ClassVar[tuple[ArrayOutput, ...]] = ()
    #: Time origin of every FMU of the project (the plant's history for tau <= 0 is the
    #: nominal motion, so the scaled time starts at 0).
    START_TIME: ClassVar[float] = 0.0
    #: Paragraphs of ``documentation/index.html``, "Validity of the model".
    VALIDITY: ClassVar[tuple[str, ...]] = ()
    #: The first paragraph of ``documentation/index.html``, "Time base and units".
    TIME_AND_UNITS: ClassVar[str] = (
        'All quantities are the paper\'s scaled, dimensionless quantities (unit "1"); time is the '
        "scaled time tau."
    )
    log_categories = LOG_CATEGORIES
    author = "drillstring project"
    license = "MIT"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=0.01)
    _front: _boot.Front | None = None
    _log_call: Any = None
    _fast_call: Any = None

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._front = _boot.attach(self.release)
        if self._front is not None:
            self._log_call = _LOG_CALL(self._front.log)
            self._fast_call = _FAST_CALL(self._front.fast)
        self.config = read_config(self.resources)
        self.version = str(self.config.get("version", "unknown"))
        self.phase = "instantiated"
        self.time = self.START_TIME
        self.values: dict[str, Any] = {
            v.name: v.start for v in self.VARIABLES if v.causality != "output"
        }
        self.dirty = True  # parameters changed since configure()
        self._by_vr: dict[int, Variable] = {}
        self._by_name: dict[str, Variable] = {}
        self._vr_of: dict[str, int] = {}
        #: kernel status of a step the front layer began natively and this call must finish
        self.fast_resume: int | None = None
        self._fast: FastPath | None = None  # the block the front layer was last given
        self._fast_used: FastPath | None = None  # the last one it was given (for its count)
        self._fast_depth = 0
        self._native = (
            self._fast_call is not None
            and native.AVAILABLE
            and os.environ.get("DRILLSTRING_FMU_NATIVE", "1") != "0"
        )
        self._python_steps = 0
        for var in self.VARIABLES:
            self._register(var)
        self._set(self.initial_values())

    # ----------------------------------------------------------------- model hooks
    def initial_values(self) -> Mapping[str, Any]:
        """Start values that come from the FMU's build configuration (``self.config``) rather
        than from ``VARIABLES``; they are the start values written to modelDescription.xml."""
        return {}

    def configure(self, values: Mapping[str, Any]) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def output_values(self) -> Mapping[str, Any]:  # pragma: no cover - abstract
        raise NotImplementedError

    def advance(self, t: float, h: float) -> StepResult:  # pragma: no cover - abstract
        raise NotImplementedError

    def save(self) -> tuple[dict[str, Any], Any, Callable[[], bytes]]:  # pragma: no cover
        """(JSON-able fields, in-memory snapshot, function making the bytes) of the model."""
        raise NotImplementedError

    @classmethod
    def array_vr(cls, j: int) -> int:
        """The slave's value reference of the first element of ``ARRAYS[j]`` (``ARRAY_VR_BASE``;
        the front layer of the FMI 3.0 twin asks for element i at this + i)."""
        if not 0 <= j < len(cls.ARRAYS):
            raise IndexError(f"{cls.__name__} has {len(cls.ARRAYS)} array outputs, not #{j}")
        return ARRAY_VR_BASE + j * ARRAY_VR_STRIDE

    def array_values(self, name: str) -> np.ndarray:  # pragma: no cover - abstract
        """The elements of the array output ``name`` (one of :attr:`ARRAYS`) now."""
        raise NotImplementedError

    def fast_path(self) -> FastPath | None:
        """The native fast path of the model in its current state, or None (the default: every
        call is served by Python). Called at the end of each call while stepping."""
        return None

    def fast_pull(self, io: np.ndarray) -> None:
        """Take the model's fields from ``io`` after the front layer served calls natively
        (the lifecycle takes the time and the inputs)."""

    def fast_push(self, io: np.ndarray) -> None:
        """Put the model's fields into ``io`` for the front layer (the inverse of
        :meth:`fast_pull`; the lifecycle puts the time and the inputs)."""

    def restore(self, fields: Mapping[str, Any], snapshot: Any, payload: bytes | None) -> None:
        """Inverse of :meth:`save` (``snapshot`` None: restore from ``payload``)."""
        raise NotImplementedError  # pragma: no cover

    # ----------------------------------------------------------------- registration
    def _register(self, var: Variable) -> None:
        kind = _PYTHONFMU_TYPE[var.type]
        kwargs: dict[str, Any] = {
            "causality": _CAUSALITY[var.causality],
            "variability": Fmi2Variability[var.variability],
            "description": var.description,
        }
        if var.initial is not None:
            kwargs["initial"] = Fmi2Initial[var.initial]
        if var.causality != "output":  # pythonfmu reads start values through the getter
            kwargs["getter"] = lambda: self.values[var.name]
        pf_var = kind(var.name, **kwargs)
        self.register_variable(pf_var)
        self._by_vr[pf_var.value_reference] = var
        self._vr_of[var.name] = pf_var.value_reference
        self._by_name[var.name] = var

    def release(self) -> None:
        """Drop the model and the reference cycles through the slave (its variables' getters and
        setters close over it), so that pythonfmu frees it at once, with its model, rather than
        some later run of the cyclic garbage collector; the front layer calls it at
        ``fmi2FreeInstance`` and ``fmi2Reset``, after which the slave is never called again."""
        for var in self.vars.values():
            var.getter = var.setter = None
        self.vars.clear()
        self.__dict__.clear()

    # ----------------------------------------------------------------- reporting
    def log(
        self,
        msg: str,
        status: Fmi2Status = Fmi2Status.ok,
        category: str | None = None,
        debug: Any = None,
        *,
        reached: float | None = None,
    ) -> None:
        """pythonfmu's ``log``, through the front layer's typed call when there is one (the
        module docstring says why); ``category`` defaults to pythonfmu's choice; ``reached``: the
        time the FMU reached in the step this message discards, for the layer's
        ``fmi2LastSuccessfulTime`` (without a layer, nobody asks for it)."""
        call, front = self._log_call, self._front
        if call is None or front is None:
            super().log(msg, status, category, debug)
            return
        if category is None:
            category = f"logStatus{status.name.capitalize()}"
            if category not in self.log_categories:
                category = "logAll"
        text = msg.encode("utf-8", "backslashreplace")
        time = None if reached is None else ctypes.byref(ctypes.c_double(reached))
        call(front.component, int(status), category.encode("utf-8"), text, time)

    def _error(self, msg: str) -> None:
        self.log(msg, Fmi2Status.error, "logStatusError")

    def _info(self, msg: str) -> None:
        self.log(msg, Fmi2Status.ok, "logInfo")

    @contextlib.contextmanager
    def _call(self, what: str) -> Iterator[None]:
        """Run one FMI call: a rejection or any exception becomes an fmi2Error log message.

        Around it, the native fast path: first what the front layer changed natively since the
        last call (time, inputs, the model's fields), at the end the block for the next ones.
        """
        self._fast_depth += 1
        try:
            if self._fast_depth == 1:
                self._fast_sync()
            yield
        except _Rejected as exc:
            self._error(f"{what}: {exc}")
        except Exception as exc:  # never into pythonfmu: that would be fmi2Fatal
            self._error(f"{what} failed: {type(exc).__name__}: {exc}")
        finally:
            self._fast_depth -= 1
            if self._fast_depth == 0:
                try:
                    self._fast_announce()
                except Exception as exc:  # the call stays served; the next ones by Python
                    self._error(f"{what}: the native fast path failed: {type(exc).__name__}: {exc}")
            if _COMPILED:
                total = sum(s for _, s in _COMPILED)
                names = ", ".join(sorted({n for n, _ in _COMPILED}))
                where = (
                    f"they are cached under {Path(_jit.__file__).parents[2]} for later processes"
                    if not _jit.UNCACHED
                    else "in memory only: numba has no writable cache folder (the package's "
                    "folder and HOME are read-only; set DRILLSTRING_FMU_CACHE or NUMBA_CACHE_DIR "
                    "to a writable folder to keep them), so each process compiles them anew"
                )
                self._info(
                    f"{what}: numba compiled {len(_COMPILED)} kernel function(s) in {total:.1f} s "
                    f"({names}); {where}"
                )
                _COMPILED.clear()

    # ----------------------------------------------------------------- native fast path
    def _fast_sync(self) -> None:
        """The FMU's state after natively served calls (the front layer sets ``IO_STALE``)."""
        fast = self._fast
        if fast is None:
            return
        io = fast.io
        if io[native.IO_STALE] != 0.0:
            self.time = float(io[native.IO_TIME])
            for name, slot in fast.inputs.items():
                self.values[name] = float(io[slot])
            self.fast_pull(io)
            io[native.IO_STALE] = 0.0
        if io[native.IO_RESUME] >= 0.0:
            self.fast_resume = int(io[native.IO_RESUME])
            io[native.IO_RESUME] = -1.0

    def _fast_announce(self) -> None:
        """Give the front layer the block for the next calls (a descriptor, through its typed
        call): it serves nothing natively until it receives one, and drops it at each Python
        call. A descriptor the layer refuses (it logs why) leaves this instance on the Python
        path."""
        self.fast_resume = None
        stepping = self._native and self.phase == "stepping" and not self.dirty
        fast = self.fast_path() if stepping else None
        self._fast = fast
        if fast is None:
            return
        self._fast_used = fast
        io = fast.io
        if io.dtype != np.float64 or not io.flags.c_contiguous:
            raise TypeError(f"the io block of the fast path must be contiguous float64: {io.dtype}")
        io[native.IO_TIME] = self.time
        for name, slot in fast.inputs.items():
            io[slot] = self.values[name]
        io[native.IO_RESUME] = -1.0
        self.fast_push(io)
        io[native.IO_STALE] = 0.0
        descriptor = self.fast_descriptor(fast)  # copied by the layer; io and args stay alive
        assert self._front is not None  # _native: there is a front layer
        if self._fast_call(self._front.component, descriptor.ctypes.data, descriptor.size) != 0:
            self._native = False
            self._fast = None

    def fast_descriptor(self, fast: FastPath) -> np.ndarray:
        """The descriptor of ``fast`` the front layer reads (``fmu_src/fmi_front/fast.c``):
        magic, version, the io block's address and length, the addresses of ``args``, ``step``
        and ``outputs``, the numbers of inputs and outputs, then (value reference, slot) of each
        input and (value reference, slot, type 0 Real / 1 Integer) of each output."""
        io = fast.io
        rows = [
            _FAST_MAGIC, _FAST_VERSION, io.ctypes.data, io.size,
            0 if fast.args is None else fast.args.ctypes.data, fast.step, fast.outputs,
            len(fast.inputs), len(fast.outputs_at),
        ]  # fmt: skip
        for name, slot in fast.inputs.items():
            rows += [self._vr_of[name], slot]
        for name, slot in fast.outputs_at.items():
            rows += [self._vr_of[name], slot, _FAST_TYPES[self._by_name[name].type]]
        return np.array(rows, dtype=np.uint64)

    # ----------------------------------------------------------------- values
    def _set(self, updates: Mapping[str, Any]) -> None:
        """Check every value first, then apply all of them (or none)."""
        checked = {}
        for name, value in updates.items():
            var = self._by_name[name]
            try:
                checked[name] = var.validate(value)
            except ValueError as exc:
                raise _Rejected(
                    f"{var.causality} {name} = {value!r} rejected: {exc}; the value is not applied"
                ) from None
        self.values.update(checked)
        if any(self._by_name[n].causality == "parameter" for n in checked):
            self.dirty = True

    def _setter(self, what: str, vrs: list[int], values: list[Any]) -> None:
        with self._call(what):
            self._set({self._by_vr[vr].name: x for vr, x in zip(vrs, values, strict=True)})

    def _ensure_configured(self) -> None:
        if self.dirty:
            try:
                self.configure(self.values)
            except (ValueError, TypeError) as exc:
                raise _Rejected(f"the parameters are inconsistent: {exc}") from None
            self.dirty = False

    def _getter(self, what: str, vrs: list[int], convert: type, fallback: Any) -> list[Any]:
        out = [fallback] * len(vrs)
        with self._call(what):
            vars_ = [self._by_vr[vr] for vr in vrs]
            outputs: Mapping[str, Any] = {}
            if any(v.causality == "output" for v in vars_):
                self._ensure_configured()
                outputs = self.output_values()
            out = [
                convert((outputs if v.causality == "output" else self.values)[v.name])
                for v in vars_
            ]
        return out

    def _array_getter(self, what: str, vrs: list[int]) -> list[float]:
        """The elements of array outputs the FMI 3.0 front layer asks for (``ARRAY_VR_BASE``)."""
        out = [math.nan] * len(vrs)
        with self._call(what):
            self._ensure_configured()
            arrays: dict[int, np.ndarray] = {}
            values = []
            for vr in vrs:
                j, i = divmod(vr - ARRAY_VR_BASE, ARRAY_VR_STRIDE)
                if not 0 <= j < len(self.ARRAYS):
                    raise _Rejected(f"no array output has value reference {vr}")
                if j not in arrays:
                    arrays[j] = np.asarray(self.array_values(self.ARRAYS[j].name), dtype=float)
                if not 0 <= i < arrays[j].size:
                    raise _Rejected(
                        f"{self.ARRAYS[j].name} has {arrays[j].size} elements, not element {i}"
                    )
                values.append(float(arrays[j][i]))
            out = values
        return out

    def get_real(self, vrs: list[int]) -> list[float]:
        if vrs and vrs[0] >= ARRAY_VR_BASE:
            return self._array_getter("fmi3GetFloat64", vrs)
        return self._getter("fmi2GetReal", vrs, float, math.nan)

    def get_integer(self, vrs: list[int]) -> list[int]:
        return self._getter("fmi2GetInteger", vrs, int, 0)

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        return self._getter("fmi2GetBoolean", vrs, bool, False)

    def get_string(self, vrs: list[int]) -> list[str]:
        return self._getter("fmi2GetString", vrs, str, "")

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        self._setter("fmi2SetReal", vrs, values)

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        self._setter("fmi2SetInteger", vrs, values)

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        self._setter("fmi2SetBoolean", vrs, values)

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        self._setter("fmi2SetString", vrs, values)

    # ----------------------------------------------------------------- phases
    def setup_experiment(self, start_time: float, stop_time: Any = None, tolerance: Any = None):
        with self._call("fmi2SetupExperiment"):
            if start_time != self.START_TIME:
                raise _Rejected(
                    f"start time must be {self.START_TIME!r} (the model's time origin: the "
                    f"history for tau <= 0 is the nominal motion), got {start_time!r}"
                )

    def enter_initialization_mode(self) -> None:
        with self._call("fmi2EnterInitializationMode"):
            self.phase = "initialization"

    def exit_initialization_mode(self) -> None:
        with self._call("fmi2ExitInitializationMode"):
            try:
                self._ensure_configured()
            except _Rejected as exc:
                raise _Rejected(
                    f"{exc}; the FMU stays in initialization mode: set valid values and call "
                    "fmi2ExitInitializationMode again"
                ) from None
            self.phase = "stepping"
            self.time = self.START_TIME

    def terminate(self) -> None:
        with self._call("fmi2Terminate"):
            self.phase = "terminated"
            used = self._fast_used
            native_steps = 0 if used is None else int(used.io[native.IO_NSTEPS])
            how = (
                "the native fast path is off"
                if not self._native
                else f"{native_steps} served natively by the front layer"
            )
            self._info(f"fmi2Terminate: {native_steps + self._python_steps} step(s), {how}")

    def do_step(self, current_time: float, step_size: float) -> bool:
        """The step wrapper: checks, the model's ``advance``, and what the layer must know."""
        t, h = current_time, step_size
        ok = True
        with self._call("fmi2DoStep"):
            if not (math.isfinite(t) and math.isfinite(h)):
                raise _Rejected(f"time and step size must be finite, got t = {t!r}, h = {h!r}")
            if h <= 0.0:
                raise _Rejected(f"step size must be > 0, got {h!r} at t = {t!r}")
            if abs(t - self.time) > 1e-9 * max(1.0, abs(self.time)):
                raise _Rejected(
                    f"communication point t = {t!r} is not the FMU's time {self.time!r}; "
                    "nothing was computed"
                )
            self._python_steps += 1
            result = self.advance(t, h)
            self.time = result.reached
            if result.warning is not None:
                self.log(f"fmi2DoStep: {result.warning}", Fmi2Status.warning, "logStatusWarning")
            if result.stop is not None:
                self.log(
                    f"fmi2DoStep: {result.stop}; the step [{t!r}, {t + h!r}] stopped at "
                    f"{result.reached!r} and the outputs hold the state there",
                    Fmi2Status.discard,
                    "logStatusDiscard",
                    reached=result.reached,
                )
                ok = False
        return ok

    # ----------------------------------------------------------------- FMU state
    def _get_fmu_state(self) -> FmuState:
        state = FmuState({})
        with self._call("fmi2GetFMUstate"):
            model, snapshot, make = self.save()
            fields = {
                "phase": self.phase,
                "time": self.time,
                "values": dict(self.values),
                "dirty": self.dirty,
                "model": model,
            }
            state = FmuState(fields, snapshot=snapshot, make_payload=make)
        return state

    def _set_fmu_state(self, state: Any) -> None:
        with self._call("fmi2SetFMUstate"):
            if not isinstance(state, FmuState):
                raise _Rejected(f"not an FMU state of {self.MODEL}: {type(state).__name__}")
            if state.error is not None:
                raise _Rejected(state.error)
            f = state.fields
            try:
                restored = self._check_state_fields(f)
            except ValueError as exc:
                raise _Rejected(f"the FMU state is refused: {exc}; nothing was changed") from None
            values = dict(self.values)
            self.values.update(restored)
            try:
                self.restore(f["model"], state.snapshot, state.payload)
            except Exception as exc:
                self.values = values
                if isinstance(exc, ValueError):
                    raise _Rejected(
                        f"the FMU state is refused: field model: {exc}; nothing was changed"
                    ) from None
                raise
            self.phase, self.time, self.dirty = f["phase"], float(f["time"]), f["dirty"]

    def _check_state_fields(self, f: Mapping[str, Any]) -> dict[str, Any]:
        """The variables' values of an FMU state's fields, each checked as a set value is;
        ``ValueError`` naming the field that does not fit this FMU (bytes behind a recomputed
        checksum can hold anything). The model's arrays are checked by its ``restore``."""
        missing = {"phase", "time", "values", "dirty", "model"} - set(f)
        if missing:
            raise ValueError(f"fields {sorted(missing)} missing")
        if f["phase"] not in PHASES:
            raise ValueError(f"field phase = {f['phase']!r} is not one of {PHASES}")
        check_real("field time", f["time"])
        if not isinstance(f["dirty"], bool):
            raise ValueError(f"field dirty = {f['dirty']!r} is not a boolean")
        if not isinstance(f["model"], dict):
            raise ValueError(f"field model is a {type(f['model']).__name__}, not an object")
        values = f["values"]
        if not isinstance(values, dict) or set(values) != set(self.values):
            names = sorted(values) if isinstance(values, dict) else type(values).__name__
            raise ValueError(f"field values holds {names}, not the variables of {self.MODEL}")
        checked = {}
        for name, value in values.items():
            try:
                checked[name] = self._by_name[name].validate(value)
            except (ValueError, TypeError) as exc:
                raise ValueError(f"field values.{name} = {value!r}: {exc}") from None
        return checked

    @staticmethod
    def _fmu_state_to_bytes(state: FmuState) -> bytes:
        return pack_state(state)

    @staticmethod
    def _fmu_state_from_bytes(data: bytes) -> FmuState:
        return unpack_state(data)
