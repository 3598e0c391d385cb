"""Fixtures shared by the test modules.

``built`` designs the controller and builds the FMUs and SSP packages once per test session
with the real command (``build_fmus.py`` in a subprocess without a gains file, so the synthesis
runs first, see :func:`fmu_testlib.built_fmus`); every FMU test module uses this one build.
Where a test needs a build of its own it builds only the FMUs it needs
(:func:`fmu_testlib.build_only`): ``other_gains`` (a controller of other gains beside the
session's plant: other gains give another closed loop) and the determinism test (the plant and
the controller from the installed package, compared with the session's). ``small_fmus`` are the
master's small test FMUs (``tests/fmus/``), built once for the three modules that use them. The
autouse ``_sys_path`` fixture puts ``sys.path`` back after each test: the FMUs promise to leave
it alone (tested), this is a second line of defence so that one failing FMU test cannot make the
next one import another copy of the package.

``clean_home`` is the HOME of the hosts outside this process (the clean-environment hosts of
``fmu_testlib.clean_env``, and the Python hosts given its package cache): one per session, made
by ``first_use`` (:func:`fmu_testlib.first_use`), the FMUs' first run on a fresh machine, which
copies the package into its cache and compiles numba's kernel there, once for all of them; the
test of the first compilation reads that run. The kernel's compilation into numba's cache
(the checkout's, as every use of the package from it keeps it), the build (after it: its design
runs the kernel), then the first use and the self-contained FMUs (``self_contained``) side by
side, run in threads beside the tests from the session's first test on (``_background``): they
are subprocesses, about 4 minutes of one core that the tests before their first user no longer
wait for; the tests are ordered so that those that need none of them run first (the kernel:
:data:`KERNEL_FREE`, ``_kernel_compiled``). Tests that use ``clean_home``, ``first_use``,
``self_contained`` or ``other_gains`` are marked ``slow`` here (they need that compilation or a
build of their own), and every user of a build ``fmu``; the markers are described in
``pyproject.toml``.

``make test`` runs the suite in two processes (pytest-xdist, ``--dist loadgroup``: the tests
that share a module's fixture on one worker, see ``pytest_collection_modifyitems``). Each
worker is a session of its own, so the session's builds and first runs (``built``,
``first_use``, ``self_contained``, ``other_gains``, ``small_fmus``) are made by the first
worker that asks, under a file lock in a folder the workers share, and loaded by the others
(:func:`_once`), the kernel among them. Without ``-n`` everything runs in this process as before.

Nothing is written outside pytest's temporary folders: for the whole session (autouse
``_session_folders``, set up before any test builds or loads anything) ``HOME`` is an empty folder
of the session, ``TMPDIR`` another (what this process and its children put in temporary folders,
Ecos's unpacked packages among them) and ``XDG_CACHE_HOME`` and ``XDG_CONFIG_HOME`` are folders of a
third, so the master's native loop (``orchestration/native_loop.py``) and the FMUs loaded in this
process keep their cache (``$XDG_CACHE_HOME/drillstring``) there; ``DRILLSTRING_FMU_CACHE`` is unset
so that this default applies. At the end of the session HOME must still be empty: anything there is
a path that would have gone into the user's real home; and that cache must hold no copy of the
package (an FMU in this process uses the package already imported; a copy there is a host outside
the process that compiled the kernel a second time instead of using ``clean_home``).

One thing is written elsewhere, on purpose: numba's cache of what this process compiles (the
kernel, the digital controller, the FMUs' entry points: ``*.nbi``/``*.nbc`` in the
``__pycache__`` folders of ``drillstring/model``, ignored by git), where every use of the package
from the checkout keeps it (``make demo``, the command line). numba keys that cache by the
source's folder, and ``NUMBA_CACHE_DIR`` only moves it: in a folder of the session every session
would compile again (``make test-fast`` took 193 s instead of 64 s on 2 shared cores); in a
folder that outlives the session it would still be written outside pytest's folders, and the
check that drops a stale kernel cache (:func:`drillstring.model.kernel.jit.refresh_cache`) knows
the default place only.
"""

from __future__ import annotations

import fcntl
import os
import pickle
import subprocess
import sys
import tempfile
import traceback
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import TypeVar

import fmu_testlib as tl
import pytest

T = TypeVar("T")

#: Test files that never run the kernel: they run first, beside its compilation
#: (``_background``'s ``kernel``), instead of waiting for it. A file listed here that does run it
#: compiles it once more in its worker: slower, not wrong.
KERNEL_FREE = {
    "test_averaged.py", "test_axial_stability.py", "test_fileio.py", "test_jit_cache.py",
    "test_layouts.py", "test_modes.py", "test_params.py", "test_reflection.py",
    "test_severity.py", "test_spectrum.py", "test_string_spectrum.py", "test_synthesis.py",
    "test_tuning.py", "test_units.py",
}  # fmt: skip
#: Files of a few long tests (a Python host each, made with its own virtual environment): the
#: first of their group, where they would be the last of it (the files with more tests go
#: first), and end the run on one worker while the other has nothing left.
LONG_FILES = {"test_fmu_python_hosts.py"}
#: Session fixtures that cost a numba compilation in a clean HOME or a build of their own.
SLOW_FIXTURES = {"clean_home", "first_use", "other_gains", "self_contained"}
#: Session fixtures of built FMUs.
FMU_FIXTURES = {"built", "small_fmus", *SLOW_FIXTURES}


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist's, which reads the xdist_group marks
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """``slow`` on the users of :data:`SLOW_FIXTURES`; ``fmu`` on the users of
    :data:`FMU_FIXTURES` too (the FMU modules carry it themselves: this keeps a test of a new
    module that forgot it out of ``make test-fast``). Then the order: the files that never run
    the kernel (:data:`KERNEL_FREE`) first, beside its compilation, then the other files whose
    tests need no build, those that need the session's build next, those with a test of a
    compilation in a clean HOME or a build of its own last, so that the builds run beside the
    tests that do not wait for them (``_background``); within a group :data:`LONG_FILES`, then
    the files with more tests first (the longer ones, as a rule: two workers end together when
    the short files come last), the tests of a file in their collection order. Under
    pytest-xdist (``--dist loadgroup``) the tests of a file that share a fixture of the module
    stay together on one worker (the fixture is made once), every other test goes to the first
    worker free (a file of long independent runs, ``test_ssp.py``'s, is shared out)."""

    def group(item: pytest.Item) -> int:
        names = set(getattr(item, "fixturenames", ()))
        if SLOW_FIXTURES & names:
            return 3
        if FMU_FIXTURES & names:
            return 2
        return 0 if item.path.name in KERNEL_FREE else 1

    for item in items:
        names = set(getattr(item, "fixturenames", ()))
        if SLOW_FIXTURES & names:
            item.add_marker(pytest.mark.slow)
        if FMU_FIXTURES & names:
            item.add_marker(pytest.mark.fmu)
    # a file's place is that of its last group (the tests of a file that share a module's
    # fixture run together under pytest-xdist); the sort is stable
    last: dict[Path, int] = {}
    count: dict[Path, int] = {}
    for item in items:
        last[item.path] = max(last.get(item.path, 0), group(item))
        count[item.path] = count.get(item.path, 0) + 1
    items.sort(
        key=lambda item: (last[item.path], item.path.name not in LONG_FILES, -count[item.path])
    )
    if config.pluginmanager.hasplugin("xdist"):
        for item in items:
            if _shares_a_module_fixture(item):
                item.add_marker(pytest.mark.xdist_group(name=item.nodeid.split("::")[0]))


def _shares_a_module_fixture(item: pytest.Item) -> bool:
    """Whether ``item`` uses a fixture made once per module (or class, or package)."""
    info = getattr(item, "_fixtureinfo", None)
    if info is None:
        return False
    return any(
        d.scope in ("module", "class", "package")
        for defs in info.name2fixturedefs.values()
        for d in defs
    )


@pytest.fixture(scope="session", autouse=True)
def _session_folders(tmp_path_factory: pytest.TempPathFactory):
    """HOME and the XDG folders in the session's temporary folder (see the module docstring)."""
    home = tmp_path_factory.mktemp("session_home")
    xdg = tmp_path_factory.mktemp("session_xdg")
    tmp = tmp_path_factory.mktemp("session_tmp")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("HOME", str(home))
        # temporary files of this process and its children: Ecos unpacks every SSP package it
        # opens into $TMPDIR/ecos_ssp_<uuid>/ and leaves it there, fmpy its FMUs, Dask its
        # scratch space
        mp.setenv("TMPDIR", str(tmp))
        mp.setattr(tempfile, "tempdir", None)  # tempfile reads TMPDIR again
        mp.setenv("XDG_CACHE_HOME", str(xdg / "cache"))
        mp.setenv("XDG_CONFIG_HOME", str(xdg / "config"))  # matplotlib's configuration folder
        mp.delenv("DRILLSTRING_FMU_CACHE", raising=False)
        yield
    written = sorted(str(p.relative_to(home)) for p in home.rglob("*"))
    assert not written, (
        f"the tests wrote into HOME ({home}), i.e. into the user's home outside a test run: "
        f"{written}"
    )
    copies = sorted(p.name for p in (xdg / "cache" / "drillstring").glob("pkg-*"))
    assert not copies, (
        f"an FMU host outside this process copied the package into {xdg / 'cache'} (and "
        f"compiled the kernel there once more): {copies}; give it clean_home's package cache"
    )


#: The session's work outside this process (the kernel's compilation, builds, first runs), named
#: as its fixtures, in the order it runs.
BACKGROUND = ("kernel", "built", "first_use", "self_contained")
#: Compiles the kernel into numba's cache (the cache of the checkout, where this process loads
#: it from).
_WARM_UP = "from drillstring.model.simulate import warm_up; warm_up()"


def _shared_folder(tmp_path_factory: pytest.TempPathFactory) -> Path | None:
    """The folder the workers of one ``pytest -n`` run share (``None`` without pytest-xdist):
    beside the workers' own base folders, named by the run's id, which every worker of the run
    gets and no other run has."""
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if run is None:
        return None
    folder = tmp_path_factory.getbasetemp().parent / f"shared-{run}"
    folder.mkdir(exist_ok=True)
    return folder


def _once(shared: Path | None, name: str, local: Path, make: Callable[[Path], T]) -> T:
    """``make(folder)``, once per run: without pytest-xdist in ``local``; under pytest-xdist the
    first worker to take the lock ``name.lock`` of the ``shared`` folder makes it in
    ``shared/name`` and leaves it there pickled (or its failure), the others wait for that lock
    and load it, so each build and first run costs its minutes once, not once per worker."""
    if shared is None:
        return make(local)
    with open(shared / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file is closed
        done, failed = shared / f"{name}.pickle", shared / f"{name}.failed"
        if failed.exists():
            raise AssertionError(f"{name} failed in another worker:\n{failed.read_text()}")
        if not done.exists():
            (shared / name).mkdir(exist_ok=True)
            try:
                value = make(shared / name)
            except BaseException:
                failed.write_text(traceback.format_exc())
                raise
            partial = done.with_suffix(".partial")
            partial.write_bytes(pickle.dumps(value))
            partial.replace(done)
        return pickle.loads(done.read_bytes())


@pytest.fixture(scope="session", autouse=True)
def _background(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory, _session_folders
) -> Iterator[Callable[[str], Future]]:
    """The session's kernel, builds and first runs, started at the session's first test, in threads
    beside the tests, as far as the collected tests need them (the kernel alone for ``make
    test-fast``): the kernel compiled into numba's cache, the FMU build, the first use in a clean
    HOME (a numba compilation) and the self-contained FMUs (a compilation for a generic CPU) are
    subprocesses that take about 4 minutes of one core, which the tests before their first user
    (the model, analysis and controller tiers) no longer wait for. Under pytest-xdist each is made
    once for all workers (:func:`_once`). The subprocesses get the environment as it is now
    (``_session_folders``'), so no test's monkeypatching reaches them. Yields ``start(name) ->
    Future`` of :data:`BACKGROUND`'s work (started on first call if no collected test needed it)."""
    environ = dict(os.environ)
    shared = _shared_folder(tmp_path_factory)
    # three threads: the kernel and the build (which waits for it) from the start; the first use
    # and the self-contained FMUs, both after the build, side by side (each a numba compilation
    # of one core), so their users wait for the longer alone
    pool = ThreadPoolExecutor(max_workers=3, thread_name_prefix="session-background")
    futures: dict[str, Future] = {}

    def start(name: str) -> Future:
        if name not in futures:
            if name == "kernel":

                def make(root: Path) -> None:
                    subprocess.run(
                        [sys.executable, "-c", _WARM_UP], env=environ, check=True, timeout=900
                    )

            elif name == "built":
                kernel = start("kernel")

                def make(root: Path) -> tl.Built:
                    kernel.result()  # its design runs the kernel: loaded, not compiled again
                    return tl.built_fmus(root, environ)

            elif name == "first_use":
                built = start("built")

                def make(root: Path) -> tl.FirstUse:
                    return tl.first_use(built.result(), root, tl.clean_env(root / "home"))

            elif name == "self_contained":
                built = start("built")

                def make(root: Path) -> tl.Built:
                    return tl.self_contained_units(built.result(), root, environ)

            else:
                raise KeyError(name)
            local = tmp_path_factory.mktemp(name)  # in this thread: the factory is not thread-safe
            futures[name] = pool.submit(_once, shared, name, local, make)
        return futures[name]

    needed = {n for item in request.session.items for n in getattr(item, "fixturenames", ())}
    if any(item.path.name not in KERNEL_FREE for item in request.session.items):
        needed.add("kernel")
    for name in BACKGROUND:
        if name in needed:
            start(name)
    yield start
    pool.shutdown(wait=True, cancel_futures=True)


@pytest.fixture(autouse=True)
def _kernel_compiled(request: pytest.FixtureRequest, _background) -> None:
    """The kernel in numba's cache before a test that may run it (every test outside
    :data:`KERNEL_FREE`): compiled once per run, in a process of its own, from the session's
    start (``_background``), so that the tests that do not run it go on meanwhile; without it
    each worker, and the build, would compile the same kernel, a minute of a core each."""
    if request.node.path.name not in KERNEL_FREE:
        _background("kernel").result()


@pytest.fixture(scope="session")
def built(_background: Callable[[str], Future]) -> tl.Built:
    """The FMUs of this session's build (both unit systems), their designed gains file and
    folder."""
    return _background("built").result()


@pytest.fixture(scope="session")
def other_gains(built: tl.Built, tmp_path_factory: pytest.TempPathFactory) -> tl.OtherGains:
    """The session's plant and a controller built from other gains than the session's."""
    return _once(
        _shared_folder(tmp_path_factory),
        "other_gains",
        tmp_path_factory.mktemp("other_gains"),
        lambda root: tl.other_gains_fmus(built, root),
    )


@pytest.fixture(scope="session")
def small_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The master's small test FMUs (integrator, gain, oscillator of ``tests/fmus/``), built once
    for test_master, test_native_loop and test_crosscheck."""
    return _once(
        _shared_folder(tmp_path_factory),
        "small_fmus",
        tmp_path_factory.mktemp("small_fmus"),
        tl.build_small_fmus,
    )


@pytest.fixture(autouse=True)
def _sys_path():
    yield from tl.restore_sys_path()


@pytest.fixture(scope="session")
def first_use(_background: Callable[[str], Future]) -> tl.FirstUse:
    """The FMUs' first run in a clean environment with an empty HOME (see the module docstring)."""
    return _background("first_use").result()


@pytest.fixture(scope="session")
def self_contained(_background: Callable[[str], Future]) -> tl.Built:
    """The session's scaled plant and LMI controller (and the plant's FMI 3.0 twin, in its
    ``out``) made self-contained (:func:`fmu_testlib.self_contained_units`), as a
    :class:`fmu_testlib.Built`."""
    return _background("self_contained").result()


@pytest.fixture(scope="session")
def clean_home(first_use: tl.FirstUse) -> Path:
    """HOME of the hosts outside this process, its package cache compiled by ``first_use``."""
    return first_use.home
