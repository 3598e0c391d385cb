"""Fixtures shared by the test modules.

``built`` builds both FMUs once per test session with the real command (``build_fmus.py`` in a
subprocess, see :func:`fmu_testlib.built_fmus`); every FMU test module uses the same build. The
autouse ``_sys_path`` fixture puts ``sys.path`` back after each test: the FMUs promise to leave
it alone (tested), this is a second line of defence so that one failing FMU test cannot make the
next one import another copy of the package. ``clean_home`` is the HOME of the clean-environment
hosts (``fmu_testlib.clean_env``): one per session, so the FMUs' package cache (and numba's
compiled kernel in it) is made once for all of them; the test of the first compilation makes its
own fresh one.

Nothing is written outside pytest's temporary folders: for the whole session (autouse
``_session_folders``, set up before any test builds or loads anything) ``HOME`` is an empty
folder of the session, and ``XDG_CACHE_HOME`` and ``XDG_CONFIG_HOME`` are folders of another, so
the master's native loop (``orchestration/native_loop.py``) and the FMUs loaded in this process
keep their cache (``$XDG_CACHE_HOME/drillstring``) there; ``DRILLSTRING_FMU_CACHE`` is unset so
that this default applies. At the end of the session HOME must still be empty: anything there is
a path that would have gone into the user's real home.
"""

from __future__ import annotations

import fmu_testlib as tl
import pytest


@pytest.fixture(scope="session", autouse=True)
def _session_folders(tmp_path_factory: pytest.TempPathFactory):
    """HOME and XDG_CACHE_HOME in the session's temporary folder (see the module docstring)."""
    home = tmp_path_factory.mktemp("session_home")
    xdg = tmp_path_factory.mktemp("session_xdg")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("HOME", str(home))
        mp.setenv("XDG_CACHE_HOME", str(xdg / "cache"))
        mp.setenv("XDG_CONFIG_HOME", str(xdg / "config"))  # matplotlib's configuration folder
        mp.delenv("DRILLSTRING_FMU_CACHE", raising=False)
        yield
    written = sorted(str(p.relative_to(home)) for p in home.rglob("*"))
    assert not written, (
        f"the tests wrote into HOME ({home}), i.e. into the user's home outside a test run: "
        f"{written}"
    )


@pytest.fixture(scope="session")
def built(tmp_path_factory: pytest.TempPathFactory) -> tl.Built:
    """Both FMUs of this session's build (plant, controller), their gains file and folder."""
    return tl.built_fmus(tmp_path_factory)


@pytest.fixture(autouse=True)
def _sys_path():
    yield from tl.restore_sys_path()


@pytest.fixture(scope="session")
def clean_home(tmp_path_factory: pytest.TempPathFactory):
    """HOME of the clean-environment hosts, shared by the session (see the module docstring)."""
    return tmp_path_factory.mktemp("home")
