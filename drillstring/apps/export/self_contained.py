"""Self-contained FMUs (``build_fmus.py --self-contained``): the Python runtime bundled into each
FMU, so that it runs on a Linux x86-64 machine with a compatible glibc and no Python at all, and
starts without compiling.

A normal FMU starts the Python that built it, found at the paths of its record
(:mod:`drillstring.apps.export.python_runtime`). A self-contained FMU is the same FMU (the same
``modelDescription.xml``, GUID, binaries and ``drillstring`` package) with, in ``resources/``:

- ``python/``: the building CPython's shared library (debug information stripped), its standard
  library without what no FMU imports (tests, IDLE, Tk, ensurepip, ...; :data:`STDLIB_EXCLUDED`)
  and the distributions the FMUs compute with (:data:`DISTRIBUTIONS`: numpy, numba, llvmlite,
  tqdm; their test folders left out), all compiled to bytecode that is used without checking the
  sources' times (unpacking gives files new times);
- ``python/lib/fallback/``: the libraries of the bundle's binaries that are not part of glibc
  (libffi, libz, libstdc++, ...), loaded by the front layer only on a machine that has no library
  of that name;
- ``drillstring/**/__pycache__/``: numba's compiled kernel for a generic x86-64 CPU
  (:data:`NUMBA_CPU`), compiled by running the FMUs through their lifecycle at build time
  (:mod:`drillstring.apps.export.warmup_host`), and the package's bytecode;
- a record ``drillstring_fmu_python.cfg`` that says so: ``self-contained 1`` (paths relative to
  ``resources/``, the environment's ``DRILLSTRING_FMU_*`` overrides ignored), ``glibc`` (the
  newest glibc symbol version the FMU's own binaries and the bundle ask for, checked by the front
  layer), ``fallback`` lines and ``numba-cpu``.

A host that is itself Python lends its interpreter to a self-contained FMU as to any other (a
process holds one Python): the rules of :mod:`~drillstring.apps.export.python_runtime` apply.
"""

from __future__ import annotations

import compileall
import os
import py_compile
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from drillstring.apps.export.archive import validate
from drillstring.apps.export.python_runtime import RUNTIME_NAME, python_record
from drillstring.apps.export.specs import BuildError
from drillstring.fileio import write_zip

__all__ = [
    "BUNDLE",
    "COMPRESSLEVEL",
    "DISTRIBUTIONS",
    "NUMBA_CPU",
    "STDLIB_EXCLUDED",
    "Bundle",
    "compiled_kernel",
    "make_self_contained",
    "self_contained_fmus",
    "stage_runtime",
]

#: The folder of ``resources/`` that holds the bundled Python.
BUNDLE = "python"
#: The CPU numba compiles the bundled kernel for: any x86-64 runs it.
NUMBA_CPU = "generic"
#: The distributions the FMUs' Python code imports besides the standard library (numba needs
#: llvmlite and numpy; scipy and PyYAML, which numba uses when present, are not needed).
DISTRIBUTIONS = ("numpy", "numba", "llvmlite", "tqdm")
#: Top-level entries of the standard library no FMU imports.
STDLIB_EXCLUDED = frozenset(
    {
        "site-packages",
        "test",
        "idlelib",
        "tkinter",
        "turtledemo",
        "turtle.py",
        "ensurepip",
        "lib2to3",
        "pydoc_data",
        "venv",
    }
)
#: Extension modules of the standard library no FMU imports (tests, Tk, terminals, databases,
#: TLS): prefixes of their file names in ``lib-dynload``.
DYNLOAD_EXCLUDED = (
    "_test",
    "_ctypes_test",
    "_tkinter",
    "_xx",
    "xxlimited",
    "_curses",
    "readline",
    "nis",
    "spwd",
    "ossaudiodev",
    "_dbm",
    "_gdbm",
    "_sqlite3",
    "_ssl",
    "_crypt",
)
#: Libraries of glibc itself: the machine's, never bundled.
GLIBC_LIBRARIES = frozenset(
    {
        "linux-vdso.so.1",
        "ld-linux-x86-64.so.2",
        "libc.so.6",
        "libm.so.6",
        "libmvec.so.1",
        "libpthread.so.0",
        "libdl.so.2",
        "librt.so.1",
        "libutil.so.1",
        "libresolv.so.2",
        "libanl.so.1",
    }
)
_GLIBC_VERSION = re.compile(rb"GLIBC_(\d+)\.(\d+)(?:\.\d+)?\x00")
_IGNORED = shutil.ignore_patterns("__pycache__", "*.pyc", "tests", "test")


@dataclass(frozen=True)
class Bundle:
    """The runtime staged for self-contained FMUs (:func:`stage_runtime`).

    Attributes
    ----------
    root : Path
        The staged ``python/`` folder.
    record : str
        The FMU's ``drillstring_fmu_python.cfg``.
    glibc : str
        The oldest glibc the FMUs' binaries and the bundle run on ("2.34").
    fallback_glibc : str
        The oldest glibc the fallback libraries run on (needed only where they are loaded).
    fallbacks : tuple of str
        The fallback libraries (names), in the order the front layer loads them.
    versions : dict
        Python and the bundled distributions: name -> version.
    """

    root: Path
    record: str
    glibc: str
    fallback_glibc: str
    fallbacks: tuple[str, ...]
    versions: dict[str, str]

    def entries(self) -> dict[str, Path]:
        """Archive name (``resources/python/...``) -> staged file."""
        return {
            f"resources/{BUNDLE}/{p.relative_to(self.root).as_posix()}": p
            for p in sorted(self.root.rglob("*"))
            if p.is_file()
        }


#: zlib's level for a self-contained FMU: its 305 MB (the bundle, 178 MB of them llvmlite's
#: library) deflate in 3.1 s at level 1 against 9.0 s at the default 6, to 113 MB instead of
#: 101 MB; an FMU is written once per model and build, and unpacked as fast either way.
COMPRESSLEVEL = 1


def _is_elf(path: Path) -> bool:
    with path.open("rb") as f:
        return f.read(4) == b"\x7fELF"


def _dependencies(binary: Path) -> dict[str, Path | None]:
    """The shared libraries ``binary`` needs, as the dynamic loader finds them here (``ldd``):
    name -> path (None: not found)."""
    ldd = shutil.which("ldd")
    if ldd is None:
        raise BuildError("a self-contained build needs ldd (part of glibc's tools) on PATH")
    proc = subprocess.run([ldd, str(binary)], capture_output=True, text=True, check=False)
    if proc.returncode != 0 and "not a dynamic executable" not in proc.stdout + proc.stderr:
        raise BuildError(f"ldd {binary} failed: {proc.stderr.strip()}")
    found: dict[str, Path | None] = {}
    for line in proc.stdout.splitlines():
        parts = line.split()
        if len(parts) >= 3 and parts[1] == "=>":
            found[parts[0]] = None if parts[2] == "not" else Path(parts[2])
        elif parts and parts[0].startswith("/"):
            found[Path(parts[0]).name] = Path(parts[0])
    return found


def newest_glibc(binaries: Iterable[Path]) -> str:
    """The newest ``GLIBC_x.y`` symbol version that ``binaries`` ask for ("2.2.5" counts as 2.2).

    Parameters
    ----------
    binaries : iterable of Path
        ELF files.

    Returns
    -------
    str
        "major.minor", "2.2" if none asks for a version.
    """
    newest = (2, 2)
    for path in binaries:
        for major, minor in _GLIBC_VERSION.findall(path.read_bytes()):
            newest = max(newest, (int(major), int(minor)))
    return f"{newest[0]}.{newest[1]}"


def _copy_distributions(site: Path) -> dict[str, str]:
    """The files of :data:`DISTRIBUTIONS` (their tests and bytecode left out) into ``site``."""
    versions = {}
    for name in DISTRIBUTIONS:
        try:
            dist = metadata.distribution(name)
        except metadata.PackageNotFoundError:
            raise BuildError(
                f"a self-contained build bundles {name}, which this Python does not have "
                f"(pip install {name})"
            ) from None
        versions[name] = dist.version
        for file in dist.files or ():
            parts = file.parts
            if parts[0] == ".." or "__pycache__" in parts or file.suffix == ".pyc":
                continue  # scripts outside site-packages, bytecode
            if "tests" in parts[:-1]:
                continue
            source = Path(str(file.locate()))
            if not source.is_file():
                continue
            out = site / Path(*parts)
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, out)
    return versions


def _copy_stdlib(stdlib: Path, dest: Path) -> None:
    """The standard library without :data:`STDLIB_EXCLUDED` and :data:`DYNLOAD_EXCLUDED`."""
    dest.mkdir(parents=True)
    for entry in sorted(stdlib.iterdir()):
        if entry.name in STDLIB_EXCLUDED or entry.name.startswith("config-"):
            continue
        if entry.name == "__pycache__":
            continue
        if entry.name == "lib-dynload":
            (dest / entry.name).mkdir()
            for ext in sorted(entry.iterdir()):
                if not ext.name.startswith(DYNLOAD_EXCLUDED):
                    shutil.copy2(ext, dest / entry.name / ext.name)
        elif entry.is_dir():
            shutil.copytree(entry, dest / entry.name, ignore=_IGNORED)
        else:
            shutil.copy2(entry, dest / entry.name)


def _fallbacks(binaries: Sequence[Path], bundle: Path, dest: Path) -> list[str]:
    """Copy the libraries ``binaries`` need that are neither glibc's nor in ``bundle`` into
    ``dest``; returns their names, each after the fallback libraries it needs itself."""
    needs: dict[str, Path] = {}
    pending = list(binaries)
    seen: set[Path] = set()
    edges: dict[str, set[str]] = {}
    while pending:
        binary = pending.pop()
        if binary in seen:
            continue
        seen.add(binary)
        owner = binary.name
        for name, path in _dependencies(binary).items():
            if name in GLIBC_LIBRARIES or name.startswith("ld-linux"):
                continue
            if path is None:
                continue  # not loadable here either (numba's optional TBB layer): left out
            if bundle in path.resolve().parents:
                continue  # found in the bundle itself (numpy.libs, ...)
            needs[name] = path
            edges.setdefault(owner, set()).add(name)
            pending.append(path)
    dest.mkdir(parents=True, exist_ok=True)
    order: list[str] = []

    def visit(name: str, trail: tuple[str, ...]) -> None:
        if name in order or name in trail:
            return
        source = needs[name]
        for dep in sorted(edges.get(source.name, ())):
            visit(dep, (*trail, name))
        order.append(name)

    for name in sorted(needs):
        visit(name, ())
    for name in order:
        shutil.copy2(needs[name].resolve(), dest / name)
    return order


def _strip_debug(path: Path) -> None:
    """Debug information out of ``path`` (binutils' strip), if strip is installed."""
    strip = shutil.which("strip")
    if strip is not None:
        subprocess.run([strip, "--strip-debug", str(path)], check=True, capture_output=True)


def stage_runtime(work: Path, binaries: Sequence[Path] = ()) -> Bundle:
    """Stage the Python runtime of self-contained FMUs in ``work/python`` (see the module
    docstring).

    Parameters
    ----------
    work : Path
        An empty folder.
    binaries : sequence of Path
        The FMUs' own binaries (front layer, pythonfmu's library): their libraries are bundled
        as fallbacks and their glibc counts.

    Returns
    -------
    Bundle

    Raises
    ------
    BuildError
        If this Python has no shared library, a distribution is missing, or a library the
        bundle needs is not on this machine.
    """
    record = python_record()
    version = record["version"]
    root = work / BUNDLE
    lib = root / "lib"
    lib.mkdir(parents=True)
    libpython = lib / Path(record["libpython"]).name
    shutil.copy2(record["libpython"], libpython)
    _strip_debug(libpython)
    stdlib = lib / f"python{version}"
    _copy_stdlib(Path(sysconfig.get_paths()["stdlib"]), stdlib)
    site = stdlib / "site-packages"
    site.mkdir()
    versions = {"python": sys.version.split()[0], **_copy_distributions(site)}
    elf = [p for p in sorted(root.rglob("*")) if p.is_file() and _is_elf(p)]
    fallback_dir = lib / "fallback"
    fallbacks = _fallbacks([*elf, *binaries], root, fallback_dir)
    ok = compileall.compile_dir(
        root,
        quiet=2,
        workers=0,
        invalidation_mode=py_compile.PycInvalidationMode.UNCHECKED_HASH,
    )
    if not ok:
        raise BuildError(f"the bundled Python in {root} does not compile to bytecode")
    glibc = newest_glibc([*elf, *binaries])
    fallback_glibc = newest_glibc(fallback_dir / n for n in fallbacks)
    lines = [
        "# The Python bundled in this self-contained FMU (written by build_fmus.py "
        "--self-contained; read by its front layer). Paths are relative to resources/.",
        "self-contained 1",
        f"version {version}",
        f"abi {record['abi']}",
        f"libpython {BUNDLE}/lib/{libpython.name}",
        f"home {BUNDLE}",
        f"site {BUNDLE}/lib/python{version}/site-packages",
        f"glibc {glibc}",
        *(f"fallback {BUNDLE}/lib/fallback/{n}" for n in fallbacks),
        *(f"require {n} {v or 'none'}" for n, v in record["modules"].items()),
        f"numba-cpu {NUMBA_CPU}",
    ]
    return Bundle(root, "\n".join(lines) + "\n", glibc, fallback_glibc, tuple(fallbacks), versions)


def compiled_kernel(fmus: Sequence[Path], work: Path) -> dict[str, bytes]:
    """numba's cache of the ``drillstring`` package for :data:`NUMBA_CPU`, and the package's
    bytecode, compiled by running ``fmus`` (normal FMUs of this build) through their lifecycle
    in a fresh process (:mod:`drillstring.apps.export.warmup_host`).

    Returns
    -------
    dict
        Archive name (``resources/drillstring/.../__pycache__/...``) -> bytes.

    Raises
    ------
    BuildError
        If the warm-up fails or leaves no compiled kernel.
    """
    cache = work / "cache"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "DRILLSTRING_"))}
    env.update({"NUMBA_CPU_NAME": NUMBA_CPU, "DRILLSTRING_FMU_CACHE": str(cache)})
    script = Path(__file__).with_name("warmup_host.py")
    proc = subprocess.run(
        [sys.executable, str(script), *map(str, fmus)],
        capture_output=True,
        text=True,
        env=env,
        cwd=work,
        check=False,
    )
    if proc.returncode != 0:
        raise BuildError(f"the warm-up of the self-contained FMUs failed:\n{proc.stderr}")
    packages = sorted(cache.glob("pkg-*/drillstring"))
    if len(packages) != 1:
        raise BuildError(f"the warm-up left {len(packages)} package copies in {cache}, not 1")
    package = packages[0]
    compiled = {
        f"resources/drillstring/{p.relative_to(package).as_posix()}": p.read_bytes()
        for p in sorted(package.rglob("__pycache__/*"))
        if p.is_file()
    }
    if not any(name.endswith(".nbc") for name in compiled):
        raise BuildError("the warm-up compiled no numba kernel (is numba installed?)")
    return compiled


def _documentation(text: str, bundle: Bundle) -> str:
    """The FMU's ``documentation/index.html`` with a section on what the bundle is."""
    versions = ", ".join(f"{k} {v}" for k, v in bundle.versions.items())
    fallbacks = ", ".join(bundle.fallbacks) or "none"
    section = (
        "<h2>Self-contained</h2>\n"
        f"<p>This FMU carries its Python ({versions}) in <code>resources/{BUNDLE}/</code> "
        "and numba's compiled kernel for a generic x86-64 CPU: it runs on a Linux x86-64 machine "
        f"with glibc {bundle.glibc} or newer and no Python at all, and starts without compiling. "
        "It ignores the DRILLSTRING_FMU_LIBPYTHON, DRILLSTRING_FMU_PYTHONHOME and "
        "DRILLSTRING_FMU_SITE_PACKAGES variables. Libraries outside glibc that the bundle "
        f"needs are loaded from the system, or from the FMU where the system has none ({fallbacks}"
        f"; these copies need glibc {bundle.fallback_glibc}). A host that is itself Python "
        "lends the FMU its interpreter, with the same conditions as for the normal FMU "
        "(above).</p>\n"
    )
    return text.replace("</body>", section + "</body>", 1)


def make_self_contained(
    fmu: Path,
    dest: Path,
    bundle: Bundle,
    compiled: Mapping[str, bytes],
    source_date_epoch: int | None = None,
) -> Path:
    """Write the self-contained form of the normal FMU ``fmu`` to ``dest`` (see the module
    docstring) and validate it; the model description, GUID and binaries are ``fmu``'s.

    Raises
    ------
    BuildError
        If ``fmu`` is already self-contained or the result fails validation.
    """
    with zipfile.ZipFile(fmu) as z:
        entries: dict[str, bytes | Path] = {i.filename: z.read(i.filename) for i in z.infolist()}
    cfg = f"resources/{RUNTIME_NAME}"
    if b"self-contained 1" in entries[cfg]:
        raise BuildError(f"{fmu} is already self-contained")
    entries[cfg] = bundle.record.encode("utf-8")
    doc = "documentation/index.html"
    text = bytes(entries[doc]).decode("utf-8")  # type: ignore[arg-type]
    entries[doc] = _documentation(text, bundle).encode("utf-8")
    entries.update(compiled)
    entries.update(bundle.entries())
    write_zip(dest, entries, source_date_epoch, compresslevel=COMPRESSLEVEL)
    validate(dest)
    return dest


def _binaries_folder(z: zipfile.ZipFile) -> str:
    """The folder of an FMU's Linux x86-64 binaries: FMI 3.0's platform tuple, or FMI 2.0's."""
    fmi3 = any(n.startswith("binaries/x86_64-linux/") for n in z.namelist())
    return "binaries/x86_64-linux" if fmi3 else "binaries/linux64"


def self_contained_fmus(
    fmus: Mapping[str, Path],
    out_dir: Path,
    source_date_epoch: int | None = None,
    warmup: Sequence[Path] | None = None,
) -> dict[str, Path]:
    """The self-contained forms of the normal FMUs ``fmus`` (model identifier -> path; FMI 2.0
    FMUs or their FMI 3.0 twins) in ``out_dir``: one runtime bundle and one compiled kernel for
    all of them.

    ``warmup``: the FMI 2.0 FMUs of the same build the kernel is compiled by
    (:func:`compiled_kernel`; default: ``fmus``, which must then be FMI 2.0 FMUs): a twin runs
    the same slave, so it shares their compiled kernel.

    Returns
    -------
    dict
        Model identifier -> path of its self-contained FMU.
    """
    with tempfile.TemporaryDirectory(prefix="build_fmus_sc_") as tmp:
        work = Path(tmp)
        binaries = []
        for model, fmu in fmus.items():
            with zipfile.ZipFile(fmu) as z:
                folder = _binaries_folder(z)
                for name in (f"{model}.so", f"{model}_pythonfmu.so"):
                    target = work / "binaries" / model / name
                    target.parent.mkdir(parents=True, exist_ok=True)
                    target.write_bytes(z.read(f"{folder}/{name}"))
                    binaries.append(target)
        bundle = stage_runtime(work / "runtime", binaries)
        (work / "warmup").mkdir()
        hosts = list(fmus.values()) if warmup is None else list(warmup)
        compiled = compiled_kernel(hosts, work / "warmup")
        return {
            model: make_self_contained(fmu, out_dir / fmu.name, bundle, compiled, source_date_epoch)
            for model, fmu in fmus.items()
        }
