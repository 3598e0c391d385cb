"""Other hosts of an SSP package: the Ecos co-simulation engine and fmpy's SSP simulator.

The project's master runs an SSP package with :meth:`Master.from_ssp
<drillstring.orchestration.master.Master.from_ssp>`; the same package runs in

* **Ecos** (the ``ecospy`` wheel, a test dependency): :func:`run_ecos` drives its Python API in
  this process (``EcosSimulation(ssp_path=...)``, ``init(parameter_set=...)``, fixed steps;
  Ecos accumulates its time, ``t_{k+1} = t_k + h``), :func:`ecos_command` is its ``ecos``
  command line (``ecos simulate --path PKG --parameterSet NAME``). Its library needs
  ``libtbb.so.12``, which the ``tbb`` wheel installs into the environment's ``lib`` folder.
  Ecos (0.7.2) reads only ``SystemStructure.ssd`` of the archive or folder it is given (the
  path of an ``.ssd`` file makes it crash, segmentation fault, exit code 139);
  :func:`variant_folder` lays a variant out as a folder whose ``SystemStructure.ssd`` it is;
* **fmpy** (``fmpy.ssp.simulation.simulate_ssp``): :func:`run_fmpy_ssp`. fmpy reads the
  package's parameter bindings but does not apply them: it applies only the parameter set it is
  given, with names ``component.variable``, which :func:`fmpy_parameter_set` makes from the
  package's named sets. Its loop starts every connector at 0 (no initialization exchange: the
  first step of each FMU sees zero inputs), steps the components in the package's order with
  the inputs of the previous communication point, and accumulates its time like Ecos.
"""

from __future__ import annotations

import ctypes
import importlib.util
import os
import shutil
import sys
import tempfile
import zipfile
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from drillstring.orchestration.closed_loop import kept_sys_path
from drillstring.orchestration.ssp import SSD_FILE, SspError, SspPackage, read_ssp

__all__ = [
    "ecos_command",
    "fmpy_parameter_set",
    "load_ecospy",
    "run_ecos",
    "run_fmpy_ssp",
    "tbb_library_dir",
    "variant_folder",
]


def tbb_library_dir() -> Path:
    """The folder of ``libtbb.so.12`` (the ``tbb`` wheel installs it into ``<prefix>/lib``).

    Returns
    -------
    Path
        ``<sys.prefix>/lib`` or ``<sys.base_prefix>/lib``, the first that holds the library.

    Raises
    ------
    RuntimeError
        If it is not installed (``pip install tbb``, part of the project's test extra).
    """
    for folder in (Path(sys.prefix) / "lib", Path(sys.base_prefix) / "lib"):
        if (folder / "libtbb.so.12").exists():
            return folder
    raise RuntimeError("libtbb.so.12 not found: Ecos needs the tbb wheel (pip install tbb)")


def load_ecospy() -> ModuleType:
    """``ecospy`` in this process (its library needs ``libtbb.so.12`` loaded first).

    Returns
    -------
    module
        The imported ``ecospy`` module, with ``libtbb.so.12`` loaded globally before it.

    Raises
    ------
    RuntimeError
        If ecospy or tbb is not installed.
    """
    ctypes.CDLL(str(tbb_library_dir() / "libtbb.so.12"), mode=ctypes.RTLD_GLOBAL)
    try:
        import ecospy
    except ImportError as exc:
        raise RuntimeError(
            f"Ecos is not installed (pip install 'drillstring[hosts]', or ecospy and tbb): {exc}"
        ) from exc
    return ecospy


def ecos_command(*args: str) -> list[str]:
    """``ecos ARGS``: the ecospy wheel's command line, as an argument list for :mod:`subprocess`.

    It is started through the dynamic loader with the tbb wheel's library folder (no
    ``LD_LIBRARY_PATH`` needed; pip installs the wheel's binary without the executable bit).
    ecospy is located, not imported.

    Parameters
    ----------
    *args : str
        The ``ecos`` arguments (``"simulate"``, ``"--path"``, PKG, ...).

    Returns
    -------
    list of str
        ``[/lib64/ld-linux-x86-64.so.2, --library-path, <tbb folder>, <ecos binary>, *args]``.

    Raises
    ------
    RuntimeError
        ecospy or tbb is not installed.
    """
    spec = importlib.util.find_spec("ecospy")  # not imported: its library needs libtbb first
    if spec is None or spec.origin is None:
        raise RuntimeError(
            "Ecos is not installed (pip install 'drillstring[hosts]', or ecospy and tbb)"
        )
    exe = Path(spec.origin).parent / "binaries" / "ecos"
    loader = "/lib64/ld-linux-x86-64.so.2"
    return [loader, "--library-path", str(tbb_library_dir()), str(exe), *args]


def _structured(columns: Sequence[str], rows: list[list[float]]) -> np.ndarray:
    table = np.array(rows, dtype=float).reshape(len(rows), len(columns))
    out = np.empty(len(rows), dtype=[(c, np.float64) for c in columns])
    for j, c in enumerate(columns):
        out[c] = table[:, j]
    return out


def variant_folder(
    ssp: str | os.PathLike[str], variant: str, folder: str | os.PathLike[str]
) -> Path:
    """A variant of a package as an SSP folder of its own: ``SystemStructure.ssd`` is the
    variant's SSD, with the package's ``resources/`` and ``documentation/`` (and no other SSD).

    For a tool that reads only ``SystemStructure.ssd`` (Ecos; the module docstring).

    Parameters
    ----------
    ssp : path
        The package (archive or folder).
    variant : str
        The SSD, by name or file name (:func:`~drillstring.orchestration.ssp.read_ssp`).
    folder : path
        The folder to make (it must not exist).

    Returns
    -------
    Path
        ``folder``, a valid SSP 1.0 package folder.

    Raises
    ------
    SspError
        An unknown variant (naming the package's), or ``folder`` exists.
    """
    file = read_ssp(ssp, unpack=False, variant=variant).file
    out = Path(folder)
    if out.exists():
        raise SspError(f"{out} exists; variant_folder makes a new folder")
    src = Path(ssp)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        if src.is_dir():
            shutil.copytree(src, tmp, dirs_exist_ok=True)
        else:
            with zipfile.ZipFile(src) as z:
                z.extractall(tmp)
        for f in tmp.iterdir():
            if f.is_file() and f.suffix == ".ssd" and f.name not in (file, SSD_FILE):
                f.unlink()
        if file != SSD_FILE:
            (tmp / file).replace(tmp / SSD_FILE)
        tmp.replace(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def run_ecos(
    ssp: str | os.PathLike[str],
    parameter_set: str | None,
    stop_time: float,
    step: float,
    variables: Sequence[str],
    *,
    variant: str | None = None,
) -> np.ndarray:
    """Run an SSP package in Ecos (its Python API, in this process) with a fixed step.

    Parameters
    ----------
    ssp : path
        The package.
    parameter_set : str or None
        The set Ecos applies (``init(parameter_set=...)``); None: none (Ecos then applies no
        binding at all: the FMUs' start values run).
    stop_time : float
        End of the run; Ecos takes ``round(stop_time / step)`` steps from 0.
    step : float
        The fixed step.
    variables : sequence of str
        ``"component.variable"`` to record after every step (Real or Integer).
    variant : str, optional
        Run this SSD of the package (laid out by :func:`variant_folder` in a temporary folder)
        instead of ``SystemStructure.ssd``.

    Returns
    -------
    numpy.ndarray
        Structured array: ``time`` (Ecos's, accumulated), then the variables; one row per step.
    """
    ecospy = load_ecospy()
    package = read_ssp(ssp, unpack=False, variant=variant)
    kinds = {f"{c.name}.{k.name}": k.type for c in package.components for k in c.connectors}
    for v in variables:
        if v not in kinds:
            raise SspError(f"{v!r} is not a connector of {Path(ssp).name}")
    n = int(round(stop_time / step))
    rows: list[list[float]] = []
    with tempfile.TemporaryDirectory(prefix="ecos_variant_") as tmp:
        path = Path(ssp) if variant is None else variant_folder(ssp, variant, Path(tmp) / "ssp")
        with kept_sys_path(), ecospy.EcosSimulation(ssp_path=str(path), step_size=step) as sim:
            sim.init(parameter_set=parameter_set)
            getters = [
                (sim.get_real if kinds[v] == "Real" else sim.get_integer, v.replace(".", "::", 1))
                for v in variables
            ]
            for _ in range(n):
                sim.step()
                rows.append([sim.get_time()] + [float(get(name)) for get, name in getters])
            sim.terminate()
    return _structured(("time", *variables), rows)


def fmpy_parameter_set(package: SspPackage, parameter_set: str | Sequence[str]) -> Any:
    """The named set(s) of a package as the explicit parameter set of fmpy's ``simulate_ssp``.

    fmpy applies only this argument (not the package's bindings) and matches names of the form
    ``component.variable``. Its value conversion for Booleans is ``value != 0.0``, which makes a
    string ``"false"`` true, so the values are given as Python values of their types.

    Parameters
    ----------
    package : SspPackage
        The package (:func:`~drillstring.orchestration.ssp.read_ssp`).
    parameter_set : str or sequence of str
        The named set(s), applied in order (:meth:`SspPackage.start_values`).

    Returns
    -------
    fmpy.ssp.ssd.ParameterSet
        Named after the set(s) (joined by ``+``), one ``component.variable`` parameter per value.

    Raises
    ------
    SspError
        A name that no component of the package binds.
    """
    from fmpy.ssp.ssd import Parameter, ParameterSet

    values = package.start_values(parameter_set)
    name = parameter_set if isinstance(parameter_set, str) else "+".join(parameter_set)
    out = ParameterSet(name=name)
    for component, params in values.items():
        for var, (kind, value) in params.items():
            out.parameters.append(Parameter(name=f"{component}.{var}", type=kind, value=value))
    return out


def run_fmpy_ssp(
    ssp: str | os.PathLike[str],
    parameter_set: str | Sequence[str] | None,
    stop_time: float,
    step: float,
) -> np.ndarray:
    """Run an SSP package with ``fmpy.ssp.simulation.simulate_ssp`` (module docstring).

    Parameters
    ----------
    ssp : path
        The package.
    parameter_set : str, sequence of str or None
        The package's set(s), passed as fmpy's explicit parameter set (:func:`fmpy_parameter_set`).
    stop_time, step : float
        End of the run and fixed step.

    Returns
    -------
    numpy.ndarray
        fmpy's result: ``time`` (the communication point *before* each step) and every
        connector as ``component.connector`` after that step.
    """
    from fmpy.ssp.simulation import simulate_ssp

    package = read_ssp(ssp, unpack=False)
    ps = None if parameter_set is None else fmpy_parameter_set(package, parameter_set)
    with kept_sys_path():
        return simulate_ssp(str(ssp), stop_time=stop_time, step_size=step, parameter_set=ps)
