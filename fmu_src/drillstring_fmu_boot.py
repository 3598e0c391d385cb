"""Start-up of a drillstring FMU's Python side, run by the FMU's front layer in ``fmi2Instantiate``.

Standard library only: this module runs before anything else of the FMU is imported. The front
layer (``fmu_src/fmi_front/runtime.c``) has loaded and configured the interpreter; it
saves ``sys.path`` before calling :func:`prepare` and restores it after pythonfmu's library has
instantiated the slave, so nothing here is left behind in the host's interpreter.

The layer then hands each instance the addresses of its typed calls (:func:`begin_instance`,
:class:`Front`, see :meth:`drillstring_fmu_support.FmuModel.__init__`) and releases the slave at
``fmi2FreeInstance`` (:func:`release`).

:func:`prepare` does four things and reports each as a log record for the layer to forward:

0. **The modules that compute the numbers, of the versions the FMU was built with.** The build
   records the versions of numpy and numba it imported (``require`` lines of
   ``drillstring_fmu_python.cfg``, "none" for a module it could not import). The interpreter the
   FMU runs in, the one the layer started or the host's own (a Python host: fmpy, libcosimpy),
   must import the same versions: a numpy or numba of another version, or one the build did not
   have, would compute with code the FMU was never built and tested with, so the instantiation
   is refused with the versions named (which the layer logs; pythonfmu never sees it). With
   ``DRILLSTRING_JIT=0`` numba is not used and not checked. The layer has checked the
   interpreter's own version and ABI before (``fmu_src/fmi_front/runtime.c``).
1. **The drillstring package from a per-user cache.** numba caches compiled code next to the
   source files and keys it by their path and modification time, so importing the package from
   each fresh unpack folder of the FMU would recompile the kernel (10-16 s) every time a tool
   unpacks the FMU anew. The bundled package is therefore copied once into a content-addressed
   folder ``<cache>/pkg-<sha256 of its files>/`` (written under a temporary name, files stamped
   with a fixed time, then renamed atomically) and imported from there: every unpack of the same
   build finds the same folder and numba's cache in it. ``<cache>`` is ``$DRILLSTRING_FMU_CACHE``,
   else ``$XDG_CACHE_HOME/drillstring``, else ``~/.cache/drillstring``. If the package is
   already imported (a Python host that uses the project itself), that one is used.
   A self-contained FMU (``build_fmus.py --self-contained``) carries numba's compiled kernel
   for a generic x86-64 CPU in its package's ``__pycache__`` folders: its package is cached
   under ``<cache>/pkg-<sha256>-<cpu>/`` with those files, and in the interpreter its front layer
   starts, ``NUMBA_CPU_NAME`` is set to that CPU (unless already set) before numba is imported,
   so that numba finds the compiled kernel instead of compiling it.
2. **A resources path pythonfmu can take.** pythonfmu 0.7.0 turns every ``%20`` of the location
   it is given into a space; a folder whose name really contains ``%20`` is given to it through a
   symbolic link in ``<cache>/links/`` (that read-only: in a private folder of the user in the
   temporary folder).
3. **The FMU's Python modules imported here**, so that a missing dependency (numpy, pythonfmu) is
   reported with its traceback instead of pythonfmu's bare "Fatal py exception".
"""

from __future__ import annotations

import hashlib
import importlib
import os
import sys
import tempfile
import traceback
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

#: fmi2Status codes of the records returned to the front layer
OK, WARNING, ERROR = 0, 1, 3
#: Modification time given to every cached file (numba keys its cache by it).
FIXED_MTIME = 315532800  # 1980-01-01, the earliest time a zip entry can hold
PACKAGE = "drillstring"
#: The FMU's record of the Python that built it (resources/, written by build_fmus.py).
RUNTIME_RECORD = "drillstring_fmu_python.cfg"
_IGNORED_PARTS = {"__pycache__"}

Record = tuple[int, str, str]


def cache_root() -> Path:
    """The per-user cache folder of the FMUs (see the module docstring)."""
    return Path(_cache_folder())


def _cache_folder() -> str:
    # strings where a function runs at every instantiation: pathlib (Python 3.11) interns every
    # part of every path it parses, and each interned string that dies takes a slot of the
    # interpreter's table of interned strings until the next resize of that (megabyte) table
    explicit = os.environ.get("DRILLSTRING_FMU_CACHE")
    if explicit:
        return explicit
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = xdg if xdg else os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "drillstring")


def _package_files(root: Path) -> list[Path]:
    files = []
    for path in sorted(root.rglob("*")):
        rel = path.relative_to(root)
        if path.is_file() and not _IGNORED_PARTS & set(rel.parts) and path.suffix != ".pyc":
            files.append(rel)
    return files


def _compiled_files(root: Path) -> list[Path]:
    """The files of the package's ``__pycache__`` folders (bytecode, numba's cache)."""
    return [p.relative_to(root) for p in sorted(root.rglob("__pycache__/*")) if p.is_file()]


def package_digest(root: Path) -> str:
    """SHA-256 over the relative names and contents of the package's files."""
    digest = hashlib.sha256()
    for rel in _package_files(root):
        digest.update(rel.as_posix().encode("utf-8") + b"\0")
        digest.update(hashlib.sha256((root / rel).read_bytes()).digest())
    return digest.hexdigest()


def _copy_package(source: Path, dest_parent: Path, compiled: bool = False) -> None:
    """Copy the package into ``dest_parent/drillstring`` with fixed modification times (and the
    files of its ``__pycache__`` folders if ``compiled``)."""
    target = dest_parent / PACKAGE
    for rel in _package_files(source):
        out = target / rel
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes((source / rel).read_bytes())
        os.utime(out, (FIXED_MTIME, FIXED_MTIME))
    for rel in _compiled_files(source) if compiled else ():
        out = target / rel
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes((source / rel).read_bytes())
    for folder in sorted({p for p in target.rglob("*") if p.is_dir()} | {target}):
        os.utime(folder, (FIXED_MTIME, FIXED_MTIME))


def cached_package(source: Path, root: Path, cpu: str = "") -> tuple[Path, bool]:
    """The cache folder holding a copy of ``source`` (created if needed); True if created now.

    ``cpu``: the CPU of the numba cache the package carries in its ``__pycache__`` folders (a
    self-contained FMU): copied with it into a folder of its own, ``pkg-<sha256>-<cpu>``.
    A folder whose files do not match its name (edited, half deleted) is replaced.
    """
    digest = package_digest(source)
    final = root / (f"pkg-{digest[:24]}-{cpu}" if cpu else f"pkg-{digest[:24]}")
    if final.is_dir() and package_digest(final / PACKAGE) == digest:
        return final, False
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".pkg-{digest[:24]}-", dir=root))
    try:
        _copy_package(source, tmp, compiled=bool(cpu))
        if package_digest(tmp / PACKAGE) != digest:
            raise OSError(f"the copy of {source} in {tmp} does not match its source")
        if final.exists():  # stale: move it away first, then take its place
            stale = Path(tempfile.mkdtemp(prefix=f".stale-{digest[:24]}-", dir=root))
            os.replace(final, stale / "old")
            _remove_tree(stale)
        try:
            os.replace(tmp, final)
        except OSError:
            if not (final.is_dir() and package_digest(final / PACKAGE) == digest):
                raise  # not another process that won the race
        return final, True
    finally:
        if tmp.exists():
            _remove_tree(tmp)


def _remove_tree(path: Path) -> None:
    for sub in sorted(path.rglob("*"), reverse=True):
        if sub.is_dir() and not sub.is_symlink():
            sub.rmdir()
        else:
            sub.unlink()
    path.rmdir()


def _links_folder(root: str) -> str:
    """``root/links``, or where that cannot be written (a read-only HOME) a private folder of
    this user in the temporary folder (created with mode 0700; refused unless it is a folder of
    this user that nobody else can write, since the links lead to code that is run)."""
    links = os.path.join(root, "links")
    try:
        os.makedirs(links, exist_ok=True)
        return links
    except OSError:
        private = os.path.join(tempfile.gettempdir(), f"drillstring-fmu-links-{os.getuid()}")
        os.makedirs(private, mode=0o700, exist_ok=True)
        st = os.lstat(private)
        if (
            not os.path.isdir(private)
            or os.path.islink(private)
            or st.st_uid != os.getuid()
            or (st.st_mode & 0o022)
        ):
            raise OSError(
                f"{links} cannot be written and {private} is not a private folder"
            ) from None
        return private


def pythonfmu_safe_path(resources: str, root: str) -> str:
    """``resources`` itself, or a symbolic link to it in ``root/links`` (or, that read-only, in
    the temporary folder: :func:`_links_folder`) if its name contains ``%20`` (strings: see
    ``_cache_folder``)."""
    if "%20" not in resources:
        return resources
    links = _links_folder(root)
    name = hashlib.sha256(os.fsencode(resources)).hexdigest()[:24]
    link = os.path.join(links, name)
    if os.path.islink(link) and os.readlink(link) == resources:
        return link
    tmp = os.path.join(links, f".{name}-{os.getpid()}")
    if os.path.islink(tmp):
        os.unlink(tmp)
    os.symlink(resources, tmp)
    os.replace(tmp, link)
    return link


def _record_lines(resources: str) -> list[list[str]]:
    with open(os.path.join(resources, RUNTIME_RECORD), encoding="utf-8") as f:
        return [line.split() for line in f if line.strip() and not line.startswith("#")]


def recorded_modules(resources: str) -> dict[str, str | None]:
    """The ``require NAME VERSION`` lines of the FMU's record (VERSION "none": None)."""
    found: dict[str, str | None] = {}
    for parts in _record_lines(resources):
        if len(parts) == 3 and parts[0] == "require":
            found[parts[1]] = None if parts[2] == "none" else parts[2]
    return found


def recorded_cpu(resources: str) -> str:
    """The CPU of the numba cache a self-contained FMU carries (``numba-cpu`` line), else \"\"."""
    for parts in _record_lines(resources):
        if len(parts) == 2 and parts[0] == "numba-cpu":
            return parts[1]
    return ""


def imported_version(name: str) -> tuple[str | None, str]:
    """``__version__`` of module ``name`` as this interpreter imports it (None: not importable)
    and where it comes from (or why it cannot be imported)."""
    try:
        module = importlib.import_module(name)
    except Exception as exc:  # an ImportError, or a module that fails while importing
        return None, f"{type(exc).__name__}: {exc}"
    return str(getattr(module, "__version__", "unknown")), str(getattr(module, "__file__", "?"))


def module_mismatch(resources: str, borrowed: bool) -> str | None:
    """Why the modules this interpreter imports are not those of the build (see the module
    docstring, point 0), or None if they are."""
    wanted = recorded_modules(resources)
    if os.environ.get("DRILLSTRING_JIT", "1") == "0":
        wanted.pop("numba", None)
    wrong = []
    for name, version in wanted.items():
        found, where = imported_version(name)
        if found == version:
            continue
        built = f"{name} {version}" if version else f"no {name}"
        here = f"{name} {found} ({where})" if found else f"no {name} ({where})"
        wrong.append((name, version, f"built with {built}, this Python imports {here}"))
    if not wrong:
        return None
    python = f"Python {sys.version.split()[0]} ({sys.executable or 'executable unknown'})"
    pins = " ".join(f"{n}=={v}" for n, v, _ in wrong if v)
    fixes = []
    if pins:
        where = "the host's environment" if borrowed else "site-packages of this Python"
        fixes.append(f"install them into {where} (pip install {pins})")
    if any(n == "numba" for n, _, _ in wrong):
        fixes.append("set DRILLSTRING_JIT=0 to run the plain-Python kernel without numba")
    if not borrowed:
        fixes.append("set DRILLSTRING_FMU_SITE_PACKAGES to site-packages that hold them")
    return (
        f"fmi2Instantiate: the FMU runs only with the versions of numpy and numba it was built "
        f"with (they compute its numbers), and {python} differs: "
        + "; ".join(text for _, _, text in wrong)
        + ". To run it: "
        + ", or ".join(fixes)
        + f" (all the FMU needs: {os.path.join(resources, 'requirements.txt')})"
    )


def _import_package(resources: str, records: list[Record], cpu: str) -> None:
    loaded = sys.modules.get(PACKAGE)
    if loaded is not None:
        where = list(getattr(loaded, "__path__", [])) or [getattr(loaded, "__file__", "?")]
        records.append((OK, "logInfo", f"using the {PACKAGE} package already imported: {where[0]}"))
        return
    source = Path(resources) / PACKAGE  # once per process
    root = cache_root()
    try:
        folder, created = cached_package(source, root, cpu)
    except OSError as exc:
        records.append(
            (
                WARNING,
                "logStatusWarning",
                f"cannot cache the {PACKAGE} package in {root} ({exc}); importing it from "
                f"{source}: the numba kernel is compiled anew for every unpack folder (set "
                "DRILLSTRING_FMU_CACHE to a writable folder)",
            )
        )
        folder = Path(resources)
    else:
        how = "copied there now" if created else "found there"
        records.append((OK, "logInfo", f"{PACKAGE} package from the cache {folder} ({how})"))
    sys.path.insert(0, str(folder))
    importlib.import_module(PACKAGE)


def prepare(resources: str, module: str, borrowed: int = 0) -> tuple[str | None, list[Record]]:
    """Make the FMU's Python side importable; returns (path for pythonfmu or None, records).
    ``borrowed``: the interpreter is the host's (not started by the front layer).

    Never raises: a failure is an error record (with the traceback) and ``None``.
    """
    records: list[Record] = []
    step = "checking the resources folder"
    try:
        cpu = recorded_cpu(resources)
        if cpu and not borrowed and "numba" not in sys.modules:
            os.environ.setdefault("NUMBA_CPU_NAME", cpu)  # read by numba when first imported
        step = "checking the versions of numpy and numba"
        mismatch = module_mismatch(resources, bool(borrowed))
        if mismatch is not None:
            records.append((ERROR, "logStatusError", mismatch))
            return None, _printable(records)
        step = f"importing the {PACKAGE} package"
        _import_package(resources, records, cpu)
        step = f"importing the FMU's module {module}"
        sys.path.insert(0, resources)
        importlib.import_module(module)
        step = "preparing a resources path for pythonfmu"
        safe = pythonfmu_safe_path(resources, _cache_folder())
    except BaseException as exc:  # reported to the host, never raised into the C layer
        text = "".join(traceback.format_exception(exc)).rstrip()
        records.append(
            (
                ERROR,
                "logStatusError",
                f"fmi2Instantiate: {step} failed: {type(exc).__name__}: {exc} "
                f"(Python {sys.version.split()[0]}, sys.path = {sys.path})\n{text}",
            )
        )
        return None, _printable(records)
    return str(safe), _printable(records)


def _printable(records: list[Record]) -> list[Record]:
    """Records whose text is valid UTF-8 (file names may carry undecodable bytes)."""
    return [(s, c, m.encode("utf-8", "backslashreplace").decode("utf-8")) for s, c, m in records]


# ------------------------------------------------------------------------------------------------
# the front layer's typed calls
# ------------------------------------------------------------------------------------------------


class Front(NamedTuple):
    """What the front layer gives the slave of one instance: the instance (its ``Component``) and
    the addresses of two C functions of the layer (``fmu_src/fmi_front``), to be called through
    ctypes with the GIL held: ``fast(component, descriptor, length)`` (``ds_front_fast``: the
    native fast path) and ``log(component, status, category, message, reached)``
    (``ds_front_log``; ``reached``: NULL or the time a discarded step reached)."""

    component: int
    fast: int
    log: int


_pending: Front | None = None
#: component -> the release of its slave (weakly: an instance pythonfmu dropped is not kept)
_releases: dict[int, weakref.WeakMethod] = {}


def begin_instance(component: int, fast: int, log: int) -> None:
    """Called by the front layer (under its process lock) before pythonfmu makes the slave of
    ``component``, in ``fmi2Instantiate`` and ``fmi2Reset``."""
    global _pending
    _pending = Front(component, fast, log)


def end_instance(component: int) -> None:
    """Called by the front layer after pythonfmu made (or failed to make) the slave."""
    global _pending
    _pending = None


def attach(release: Callable[[], None]) -> Front | None:
    """The :class:`Front` of the instance being made, None outside the layer's instantiation (a
    slave made by the build or directly in Python); ``release`` (a bound method of the slave) is
    called at the instance's ``fmi2FreeInstance`` or ``fmi2Reset``."""
    front = _pending
    if front is not None:
        _releases[front.component] = weakref.WeakMethod(release)  # type: ignore[arg-type]
    return front


def release(component: int) -> None:
    """Called by the front layer before pythonfmu frees (or replaces) the slave of ``component``."""
    ref = _releases.pop(component, None)
    method = ref() if ref is not None else None
    if method is not None:
        method()
