"""Optional numba acceleration of the stepping kernel.

The kernel functions are plain Python written in the subset numba compiles. ``jit_for(__name__)``
returns ``numba.njit`` when numba is importable (and ``DRILLSTRING_JIT`` is not ``0``), and the
identity otherwise, so the model is written once and runs with or without the accelerator.
Modules loaded under a name containing ``_pure`` are never compiled: that copy runs a Python
callable as control law inside the loop (see :mod:`drillstring.model.kernel.stepper`).

numba caches compiled code per function, keyed by the function's own source file; a function
compiled together with callees from other files (the stepper inlines the history look-up, the
contact law, the equations) keeps stale callees when only those files change. The cache of the
whole kernel is therefore dropped when any of its sources changes (:func:`refresh_cache`).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any, TypeVar

_KERNEL = Path(__file__).resolve().parent
_MODEL = _KERNEL.parent
_DIGITAL = _MODEL / "digital"
#: The source files of everything numba compiles: the kernel, the law (29)-(31) and the digital
#: controller (its parts, the tables their slots are laid out from, its assembly; its sampled
#: loop runs the kernel).
COMPILED_SOURCES = (
    *sorted(_KERNEL.glob("*.py")),
    *(_MODEL / f"{name}.py" for name in ("control", "tables", "laws", "topdrive", "sensing",
                                         "timing")),
    *(_DIGITAL / f"{name}.py" for name in ("layout", "block", "loop")),
)  # fmt: skip
_STAMP = "drillstring-kernel-sources.sha256"

F = TypeVar("F", bound=Callable[..., Any])


def _identity(func: F) -> F:
    return func


def numba_available() -> bool:
    """True when the compiled kernel is used (numba importable and not disabled)."""
    if os.environ.get("DRILLSTRING_JIT", "1") == "0":
        return False
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def sources_digest(sources: Iterable[Path]) -> str:
    """SHA-256 of the names and contents of ``sources``, in their order.

    Parameters
    ----------
    sources : iterable of Path
        The Python files a numba-compiled module depends on.

    Returns
    -------
    str
        The hex digest.

    Raises
    ------
    OSError
        A source cannot be read.
    """
    h = hashlib.sha256()
    for path in sources:
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


def drop_stale_cache(sources: Sequence[Path], compiled: Sequence[Path], stamp: Path) -> bool:
    """Drop numba's cache of the ``compiled`` modules when any of ``sources`` changed.

    numba keys a module's cache by that module's own file, not by the functions it inlines from
    other modules; the digest of all ``sources`` (:func:`sources_digest`) kept in ``stamp``
    tells when the cache is stale. Works on numba's default cache location (``__pycache__``
    next to each compiled module); safe with concurrent processes (entries already gone are
    skipped, the stamp is replaced atomically); on a read-only installation entries that
    cannot be deleted and a stamp that cannot be written are left as they are (its sources
    cannot change either).

    Parameters
    ----------
    sources : sequence of Path
        Every source the compiled code depends on.
    compiled : sequence of Path
        The modules whose ``__pycache__/<stem>.*.nbi``/``.nbc`` entries are dropped.
    stamp : Path
        The file holding the digest of the sources the cache was compiled from.

    Returns
    -------
    bool
        True when stale entries were removed.

    Raises
    ------
    OSError
        A source cannot be read.
    """
    digest = sources_digest(sources)
    try:
        if stamp.read_text().strip() == digest:
            return False
    except OSError:
        pass
    removed = False
    for path in compiled:
        for entry in (path.parent / "__pycache__").glob(f"{path.stem}.*.nb[ic]"):
            try:
                entry.unlink()
                removed = True
            except FileNotFoundError:
                pass
            except OSError:
                return removed  # read-only: leave the cache and the stamp alone
    try:
        stamp.parent.mkdir(exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=stamp.parent, prefix=".stamp.")
        with os.fdopen(fd, "w") as fh:
            fh.write(digest + "\n")
        os.replace(tmp, stamp)
    except OSError:
        pass  # a read-only installation: numba caches elsewhere or not at all
    return removed


def refresh_cache() -> bool:
    """Drop numba's cached kernel when any kernel source changed since it was compiled.

    With ``NUMBA_CACHE_DIR`` set, numba keys the cache by the same source paths, so a changed
    source there is the caller's business (:func:`drop_stale_cache`).

    Returns
    -------
    bool
        True when stale entries were removed.
    """
    return drop_stale_cache(COMPILED_SOURCES, COMPILED_SOURCES, _KERNEL / "__pycache__" / _STAMP)


#: Source files of functions numba cannot cache: it had no writable place for their cache (see
#: :func:`cached`); what it compiles for them stays in memory.
UNCACHED: set[str] = set()
_READ_ONLY_LOCATOR: list[type] = []


def _read_only_locator() -> type:
    """numba's in-tree cache locator for a ``__pycache__`` folder that exists but cannot be
    written (a read-only unpack folder of a self-contained FMU that ships its compiled kernel
    there), appended once to the end of numba's locators: chosen only where no other can be.
    Its cache is read, never written (:func:`cached`)."""
    if not _READ_ONLY_LOCATOR:
        from numba.core import caching

        class ReadOnlyInTreeCacheLocator(caching.InTreeCacheLocator):
            def ensure_cache_path(self) -> None:
                path = self.get_cache_path()
                if not (os.path.isdir(path) and os.access(path, os.R_OK | os.X_OK)):
                    raise OSError(f"no readable cache folder {path}")

        caching.CacheImpl._locator_classes = [
            *caching.CacheImpl._locator_classes,
            ReadOnlyInTreeCacheLocator,
        ]
        _READ_ONLY_LOCATOR.append(ReadOnlyInTreeCacheLocator)
    return _READ_ONLY_LOCATOR[0]


def _never_save(sig: Any, data: Any) -> None:
    """``save_overload`` of a cache that is only read."""


def cached(make: Callable[..., Callable[[F], F]], **options: Any) -> Callable[[F], F]:
    """numba's decorator ``make`` (``numba.njit``, ``numba.cfunc``) with ``cache=True`` where
    numba can cache, else without: compiled in memory at the first use in each process.

    numba caches next to a function's source file (``__pycache__``) or in the user's cache
    folder (``~/.cache/numba``), whichever it can write; with neither (a read-only installation
    or unpack folder of an FMU and a read-only HOME) ``cache=True`` raised "no locator
    available" when the function was decorated, so nothing could be imported. Now a
    ``__pycache__`` folder that is there but read-only is read as it is (the compiled kernel a
    self-contained FMU ships: used, not compiled again; what is not in it is compiled in memory
    and not saved), and without one the function is compiled in memory. Such files are recorded
    in :data:`UNCACHED`.
    """
    read_only = _read_only_locator()

    def decorate(func: F) -> F:
        where = getattr(getattr(func, "__code__", None), "co_filename", repr(func))
        try:
            compiled = make(cache=True, **options)(func)
        except RuntimeError as exc:
            if "no locator available" not in str(exc):
                raise
            UNCACHED.add(where)
            return make(**options)(func)
        cache = getattr(compiled, "_cache", None)
        if isinstance(getattr(getattr(cache, "_impl", None), "locator", None), read_only):
            cache.save_overload = _never_save  # type: ignore[union-attr]
            UNCACHED.add(where)
        return compiled

    return decorate


def jit_for(module_name: str, *, inline: bool = False) -> Callable[[F], F]:
    """Decorator compiling kernel functions of ``module_name`` when numba is available
    (cached by numba where it can write a cache, :func:`cached`).

    ``inline``: the function is inlined into its callers at numba's IR level (for the small
    functions of the hot path: a call with array arguments costs more than their work).
    """
    if "_pure" in module_name or not numba_available():
        return _identity
    import numba

    if inline:
        return cached(numba.njit, nogil=True, inline="always")
    return cached(numba.njit, nogil=True)


if numba_available():
    refresh_cache()
