"""Fixtures shared by the test modules.

``built`` builds both FMUs once per test session with the real command (``build_fmus.py`` in a
subprocess, see :func:`fmu_testlib.built_fmus`); every FMU test module uses the same build. The
autouse ``_sys_path`` fixture puts ``sys.path`` back after each test: the FMUs promise to leave
it alone (tested), this is a second line of defence so that one failing FMU test cannot make the
next one import another copy of the package. ``clean_home`` is the HOME of the clean-environment
hosts (``fmu_testlib.clean_env``): one per session, so the FMUs' package cache (and numba's
compiled kernel in it) is made once for all of them; the test of the first compilation makes its
own fresh one.
"""

from __future__ import annotations

import fmu_testlib as tl
import pytest


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
