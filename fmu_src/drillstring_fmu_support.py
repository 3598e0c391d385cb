"""Runtime support shared by the drillstring FMUs (bundled into each FMU's ``resources/``).

Both FMU scripts (``drillstring_plant.py``, ``torsional_controller.py``) import this module. It
holds no model code: the physics lives in the ``drillstring`` package that ``build_fmus.py``
bundles next to it. What it provides:

* :func:`read_config` -- the build configuration ``resources/drillstring_fmu.json`` written by
  ``build_fmus.py`` (package version, controller gains and where they came from);
* :func:`get_values` / :func:`set_values` -- fmi2Get*/fmi2Set* by value reference with clear
  errors (a wrong type, an unknown reference, a variable that cannot be set);
* :func:`pack_state` / :func:`unpack_state` -- the byte format of serialized FMU states;
* :func:`guard_process_exit` -- the workaround for the abort at process exit of pythonfmu FMUs in
  non-Python hosts (pythonfmu issue #228, see the function and ``docs/fmu_usage.md``).

Both FMUs run in one interpreter when a host loads them together; the first imported copy of this
module serves both, so it must stay backwards compatible within one build of the two FMUs.
"""

from __future__ import annotations

import ctypes
import json
import math
import os
import struct
import sys
from pathlib import Path
from typing import Any

from pythonfmu import Boolean, Integer, Real, String

CONFIG_FILE = "drillstring_fmu.json"
STATE_MAGIC = b"DSFMUSTATE\x00"
STATE_FORMAT = 1

__all__ = [
    "CONFIG_FILE",
    "StateError",
    "get_values",
    "guard_process_exit",
    "is_finite_real",
    "pack_state",
    "read_config",
    "set_values",
    "unpack_state",
]


class StateError(ValueError):
    """A serialized FMU state that cannot be read (wrong model, format or corrupted bytes)."""


def read_config(resources: str | os.PathLike[str] | None) -> dict[str, Any]:
    """Read ``drillstring_fmu.json`` from the FMU's resources folder.

    Raises ``FileNotFoundError`` or ``ValueError`` with the path when it is missing or unreadable:
    an FMU without it was not built by ``build_fmus.py``.
    """
    if resources is None:
        raise FileNotFoundError(f"no resources folder given; cannot read {CONFIG_FILE}")
    path = Path(resources) / CONFIG_FILE
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise FileNotFoundError(f"cannot read FMU build configuration {path}: {exc}") from exc
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"FMU build configuration {path} is not valid JSON: {exc}") from exc
    if not isinstance(data, dict):
        raise ValueError(f"FMU build configuration {path} must hold a JSON object")
    return data


def is_finite_real(value: Any) -> bool:
    """True for a finite real number (bool excluded)."""
    if isinstance(value, bool):
        return False
    try:
        return math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def _variable(slave: Any, kind: type, vr: int) -> Any:
    var = slave.vars.get(vr)
    if var is None or not isinstance(var, kind):
        raise ValueError(f"no {kind.__name__} variable with value reference {vr}")
    return var


_CONVERT = {"Real": float, "Integer": int, "Boolean": bool, "String": str}


def get_values(slave: Any, kind: type, vrs: list[int]) -> list[Any]:
    """Values of the variables ``vrs`` of type ``kind`` (pythonfmu Real/Integer/Boolean/String),
    converted to the Python type the pythonfmu C++ layer reads."""
    convert = _CONVERT[kind.__name__]
    return [convert(_variable(slave, kind, vr).getter()) for vr in vrs]


def set_values(slave: Any, kind: type, vrs: list[int], values: list[Any]) -> None:
    """Call the setters of the variables ``vrs``; a variable without a setter is an error."""
    for vr, value in zip(vrs, values, strict=True):
        var = _variable(slave, kind, vr)
        if var.setter is None:
            causality = getattr(var.causality, "name", var.causality)
            raise ValueError(f"variable {var.name} (causality {causality}) cannot be set")
        var.setter(value)


def pack_state(model: str, fields: dict[str, Any], payload: bytes = b"") -> bytes:
    """Serialize an FMU state: magic, header length, JSON header, then the engine's own bytes.

    ``fields`` must be JSON-serializable; Python's JSON writes floats with ``repr`` so they round
    trip bit for bit. ``payload`` is opaque (the engine's ``serialize_state()``).
    """
    header = json.dumps(
        {"model": model, "format": STATE_FORMAT, "fields": fields},
        sort_keys=True,
        separators=(",", ":"),
    ).encode("utf-8")
    return STATE_MAGIC + struct.pack("<Q", len(header)) + header + bytes(payload)


def unpack_state(model: str, data: bytes) -> tuple[dict[str, Any], bytes]:
    """Inverse of :func:`pack_state`; raises :class:`StateError` naming what is wrong."""
    data = bytes(data)
    n_magic = len(STATE_MAGIC)
    if len(data) < n_magic + 8 or data[:n_magic] != STATE_MAGIC:
        raise StateError(f"not a serialized drillstring FMU state ({len(data)} bytes)")
    (n_header,) = struct.unpack("<Q", data[n_magic : n_magic + 8])
    start = n_magic + 8
    if start + n_header > len(data):
        raise StateError(f"truncated FMU state: header of {n_header} bytes, {len(data)} in total")
    try:
        header = json.loads(data[start : start + n_header].decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise StateError(f"corrupted FMU state header: {exc}") from exc
    if not isinstance(header, dict) or header.get("format") != STATE_FORMAT:
        raise StateError(f"unsupported FMU state format {header.get('format')!r}")
    if header.get("model") != model:
        raise StateError(f"FMU state of model {header.get('model')!r} given to model {model!r}")
    fields = header.get("fields")
    if not isinstance(fields, dict):
        raise StateError("FMU state header lacks its fields")
    return fields, data[start + n_header :]


# ------------------------------------------------------------------------------------------------
# pythonfmu issue #228: abort at process exit in non-Python hosts
# ------------------------------------------------------------------------------------------------

_GUARDED: set[str] = set()


def guard_process_exit(resources: str | os.PathLike[str] | None, model_identifier: str) -> str:
    """Make the pythonfmu export library of this FMU safe at process exit (pythonfmu issue #228).

    Cause (pythonfmu 0.7.0, ``pythonfmu-export``): the library keeps its Python-interpreter guard in
    a namespace-scope ``std::shared_ptr`` and also resets that pointer from an ELF destructor
    (``__attribute__((destructor))``). When the host process exits without really unloading the
    library, ``exit()`` first runs the C++ static destructors (which free the shared pointer's
    control block and finalize Python) and only then the ELF destructors, so the reset decrements a
    freed control block. That corrupts the heap; the next ``free()`` that checks the bin aborts the
    process ("free(): corrupted unsorted chunks"). numpy's bundled libgfortran frees memory in its
    own destructor, which is why the abort shows when the FMU imports numpy. A host cannot avoid
    it by ``dlclose()``: the first loaded copy of the library binds C++ unique symbols and glibc
    never unloads it.

    Workaround, from inside the FMU: pin the library (``RTLD_NODELETE``, so it stays mapped) and
    register its exported ``finalizePythonInterpreter`` with ``__cxa_atexit``. Handlers run in
    reverse order of registration, so this one runs before the library's static destructors and
    resets the pointer while it is still alive; what runs after it then finds an empty pointer.

    Returns a short note of what was done, for the FMU's log. Linux only; a no-op elsewhere, at
    build time (library not loaded) and for a library without the hook (another pythonfmu).
    """
    if not sys.platform.startswith("linux") or resources is None:
        return "exit guard: not needed on this platform"
    binary = Path(resources).resolve().parent / "binaries" / "linux64" / f"{model_identifier}.so"
    key = str(binary)
    if key in _GUARDED:
        return f"exit guard: already installed for {binary}"
    mode = os.RTLD_NOW | os.RTLD_NOLOAD | os.RTLD_NODELETE
    try:
        lib = ctypes.CDLL(key, mode=mode)
    except OSError:
        return f"exit guard: {binary} is not loaded in this process (build time?)"
    try:
        hook = lib["finalizePythonInterpreter"]
    except AttributeError:
        return f"exit guard: {binary} has no finalizePythonInterpreter; nothing to do"
    libc = ctypes.CDLL(None)
    cxa_atexit = libc["__cxa_atexit"]
    cxa_atexit.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
    cxa_atexit.restype = ctypes.c_int
    if cxa_atexit(ctypes.cast(hook, ctypes.c_void_p), None, None) != 0:
        return f"exit guard: __cxa_atexit failed for {binary}"
    _GUARDED.add(key)
    return f"exit guard: installed for {binary}"


class GuardedAccessors:
    """fmi2Get*/fmi2Set* for a pythonfmu slave that never raise into pythonfmu (which would turn
    any exception into fmi2Fatal): a failure is logged as an error and remembered in
    ``self._call_error``; the next fmi2DoStep refuses with fmi2Discard. The slave provides
    ``_error(msg)``; ``_before_get()`` is a hook run before every read."""

    _call_error: str | None

    def _error(self, msg: str) -> None:  # pragma: no cover - provided by the slave
        raise NotImplementedError

    def _guarded(self, what: str, fn: Any, *args: Any) -> Any:
        try:
            return fn(*args)
        except Exception as exc:
            self._call_error = f"{what} failed: {exc}"
            self._error(self._call_error)
            return None

    def _before_get(self) -> None:
        return None

    def _get(self, kind: type, vrs: list[int], fallback: Any) -> list[Any]:
        self._before_get()
        out = self._guarded(f"fmi2Get{kind.__name__}", get_values, self, kind, vrs)
        return out if out is not None else [fallback] * len(vrs)

    def get_real(self, vrs: list[int]) -> list[float]:
        return self._get(Real, vrs, math.nan)

    def get_integer(self, vrs: list[int]) -> list[int]:
        return self._get(Integer, vrs, 0)

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        return self._get(Boolean, vrs, False)

    def get_string(self, vrs: list[int]) -> list[str]:
        return self._get(String, vrs, "")

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        self._guarded("fmi2SetReal", set_values, self, Real, vrs, values)

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        self._guarded("fmi2SetInteger", set_values, self, Integer, vrs, values)

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        self._guarded("fmi2SetBoolean", set_values, self, Boolean, vrs, values)

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        self._guarded("fmi2SetString", set_values, self, String, vrs, values)
