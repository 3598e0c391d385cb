"""Sweep description files: base parameter set, swept axes, study kind, run length and options.

TOML (``.toml``) or JSON (``.json``), chosen by suffix. Top-level keys (any other is an error)::

    study = "open-loop"            # "open-loop" | "closed-loop" | "axial" | "controllers"
    tau_end = 60.0                 # run length in scaled time (full-model studies only)
    base = "reference"             # a known set name or a parameter file (relative to this file),
                                   # or a table: {name = ...} | {file = ...} |
                                   # {kind = "scaled" | "physical", <all fields>}
    metrics = ["root_real", ...]   # optional: the metrics drawn as heat maps (default: all)

    [[sweep]]                      # one or two axes
    param = "omega0"               # see below
    start = 3.0
    stop = 8.0
    num = 11                       # >= 2
    scale = "linear"               # or "log" (start, stop > 0)

    [options]                      # optional, per study (drillstring.apps.sweep.options)
    h = 5e-4

Swept names: with a scaled base, the fields of :class:`~drillstring.model.params.ScaledParams`
(``lambda`` for the paper's lambda) or the derived ``gammabar`` (sets gamma = gammabar*sqrt(n*psi))
and ``etabar2`` (sets eta = sqrt(etabar2*n*psi)), eq. (18); with a physical base, the fields of
:class:`~drillstring.model.params.PhysicalParams` (each point is converted by eqs. (15)-(16)) or
the derived ``rpm`` (sets Omega0 = rpm*2*pi/60) and ``W0_kN`` (sets the hook speed V0 whose
nominal weight on bit at the point's speed is W0 = 1e3*W0_kN: W0 = n*a*zeta*eps*d0 +
n*a*l*sigma_bar with d0 = 2*pi*V0/(n*Omega0), eqs. (4), (7), (8); W0 must exceed the wearflat
contact part n*a*l*sigma_bar). The feed is always an imposed rate of penetration (the hook
speed); with ``W0_kN`` it is "chosen for the nominal WOB" (:attr:`SweepSpec.feed`, stated on
the plots, in ``spec.json`` and ``summary.json``). The axial study sweeps the fast-model
quantities ``gammabar``, ``etabar2``, ``taubar_n`` of (18); those not swept are the base set's
gammabar, etabar^2 and taubar_n0. The controllers study runs the digital controllers of
:func:`~drillstring.controller.lineup.rig_lineup` chosen by the option ``controllers``
(default :data:`~drillstring.controller.lineup.MAP_CONTROLLERS`) under one top drive (option
``top_drive``) at each point (sampled, torsional stick on) and records the severity metrics of
:mod:`drillstring.analysis.severity`; its natural axes are ``rpm`` and ``W0_kN`` on a physical
base (``drillstring controllers map``), or the surface speed and the feed (``omega0``/``v0``,
``Omega0``/``V0``).

Validation happens on load: every key, value and grid point is checked and any problem raises
:class:`SweepSpecError` (a ``ValueError``) naming the key and the value.
"""

from __future__ import annotations

import json
import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from drillstring.analysis.limit_cycles import fast_params
from drillstring.apps.sweep.metrics import plottable
from drillstring.apps.sweep.options import (
    AxialOptions,
    ClosedLoopOptions,
    ControllerOptions,
    OpenLoopOptions,
    StudyOptions,
    option_keys,
    options_from_table,
    options_table,
)
from drillstring.controller.gains import GainsFile, GainsFileError, read_gains
from drillstring.controller.lineup import CONSTRAINED_CONTROLLERS, INDUSTRIAL
from drillstring.controller.tuning import impedance
from drillstring.fileio import load_table
from drillstring.model.params import (
    KNOWN_PARAMS,
    KNOWN_PHYSICAL,
    ParameterError,
    PhysicalParams,
    ScaledParams,
    known_rig,
    read_params,
)
from drillstring.model.tables import Scales
from drillstring.model.topdrive import RPM, top_drive_from_spec
from drillstring.validation import check_choice, check_int, check_real, check_str, check_table

__all__ = [
    "AXIAL_NAMES",
    "AXIS_LABELS",
    "FEED_FOR_WOB",
    "FEED_IMPOSED",
    "MAX_POINTS",
    "PHYSICAL_DERIVED",
    "STUDIES",
    "STUDY_OPTIONS",
    "Axis",
    "SweepSpec",
    "SweepSpecError",
    "load_spec",
    "spec_from_dict",
]

#: The options of each study (the keys of the spec's ``[options]``, their defaults and checks).
STUDY_OPTIONS: dict[str, type] = {
    "open-loop": OpenLoopOptions,
    "closed-loop": ClosedLoopOptions,
    "axial": AxialOptions,
    "controllers": ControllerOptions,
}
STUDIES = tuple(STUDY_OPTIONS)
#: The largest grid a spec may describe unless the caller allows more (``drillstring sweep
#: --max-points``): 10 000 points, a 100 x 100 map, is some 4 hours of one core at 1.5 s per
#: full-model point; every point is validated on load and its row kept in memory, so a grid of
#: 1e16 points would never start.
MAX_POINTS = 10_000
#: The full-model studies (a parameter set per point, axial design inputs per point).
FULL_MODEL_STUDIES = ("open-loop", "closed-loop", "controllers")
SCALES = ("linear", "log")
DERIVED_NAMES = ("gammabar", "etabar2")
#: Derived axes of a physical base: the surface speed in rpm (sets Omega0) and the nominal
#: weight on bit in kN (sets the hook speed V0 that gives it at the point's speed, (4), (7), (8)).
PHYSICAL_DERIVED = ("rpm", "W0_kN")
SCALED_NAMES = ("n", "psi", "gamma", "eta", "lambda", "beta", "rho", "v0", "omega0")
PHYSICAL_NAMES = tuple(f.name for f in fields(PhysicalParams))
#: Axis labels of the maps (a name not listed is its own label).
AXIS_LABELS = {
    "rpm": "surface speed [rpm]",
    "W0_kN": "nominal weight on bit [kN]",
    "Omega0": "Omega0 [rad/s]",
    "V0": "hook speed V0 [m/s]",
}
#: How the full model is fed: the hook moves at the imposed speed (the paper's v0, V0) ...
FEED_IMPOSED = "feed: imposed rate of penetration (hook speed)"
#: ... and, with a W0_kN axis, that speed is the one whose nominal weight on bit is W0.
FEED_FOR_WOB = "feed: imposed rate of penetration (hook speed) chosen for the nominal WOB"
AXIAL_NAMES = ("gammabar", "etabar2", "taubar_n")
TOP_KEYS = ("study", "base", "sweep", "tau_end", "options", "metrics")
AXIS_KEYS = ("param", "start", "stop", "num", "scale")


class SweepSpecError(ValueError):
    """An invalid sweep description: unknown or missing key, bad value, unreadable file."""


# --------------------------------------------------------------------------------------------
# dataclasses
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Axis:
    """One swept parameter: ``num`` values from ``start`` to ``stop`` (both included)."""

    param: str
    start: float
    stop: float
    num: int
    scale: str = "linear"

    def values(self) -> np.ndarray:
        """The grid values of the axis.

        Returns
        -------
        ndarray
            ``num`` values from ``start`` to ``stop`` (both included): :func:`numpy.geomspace`
            on a log scale, else :func:`numpy.linspace`.
        """
        if self.scale == "log":
            return np.geomspace(self.start, self.stop, self.num)
        return np.linspace(self.start, self.stop, self.num)

    def to_dict(self) -> dict[str, Any]:
        """The axis as a table of the spec file.

        Returns
        -------
        dict
            ``param``, ``start``, ``stop``, ``num``, ``scale``.
        """
        return asdict(self)


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: see the module docstring. Points are numbered row-major:
    ``index = i*num_1 + j`` for the axis-0 index i and the axis-1 index j."""

    study: str
    base: ScaledParams | PhysicalParams
    base_label: str
    axes: tuple[Axis, ...]
    tau_end: float | None
    options: StudyOptions
    metrics: tuple[str, ...]
    source: str = "sweep spec"

    @property
    def shape(self) -> tuple[int, ...]:
        """Points per axis, ``(num_0,)`` or ``(num_0, num_1)``."""
        return tuple(a.num for a in self.axes)

    @property
    def n_points(self) -> int:
        """Number of points of the sweep (the product of :attr:`shape`)."""
        return math.prod(self.shape)

    @property
    def names(self) -> tuple[str, ...]:
        """The swept parameter names, in axis order."""
        return tuple(a.param for a in self.axes)

    @property
    def scaled_base(self) -> ScaledParams:
        """The base set in scaled form (a physical base converted by eqs. (15)-(16))."""
        return self.base.to_scaled() if isinstance(self.base, PhysicalParams) else self.base

    def grid_index(self, index: int) -> tuple[int, ...]:
        """The grid indices of point ``index``.

        Parameters
        ----------
        index : int
            Row-major point index, in ``0 .. n_points - 1``.

        Returns
        -------
        tuple of int
            ``(i,)`` or ``(i, j)``.

        Raises
        ------
        IndexError
            ``index`` is outside the sweep.
        """
        if not 0 <= index < self.n_points:
            raise IndexError(f"point index {index} outside 0..{self.n_points - 1}")
        return tuple(int(k) for k in np.unravel_index(index, self.shape))

    def point_values(self, index: int) -> dict[str, float]:
        """Swept parameter values at point ``index`` (row-major): each axis's ``param`` -> its
        value; IndexError outside the sweep.
        """
        ij = self.grid_index(index)
        return {a.param: float(a.values()[k]) for a, k in zip(self.axes, ij, strict=True)}

    def point_params(self, index: int) -> ScaledParams:
        """The scaled parameter set of point ``index`` (full-model studies): :meth:`params_at` of
        :meth:`point_values`, with their errors (and IndexError outside the sweep).
        """
        return self.params_at(self.point_values(index))

    def params_at(self, values: Mapping[str, float]) -> ScaledParams:
        """The scaled parameter set at any values of the swept names (e.g. between the grid points).

        A physical base takes the swept values (:meth:`physical_at`) and is converted by eqs.
        (15)-(16); a scaled base takes the swept fields, then ``gammabar`` (gamma =
        gammabar*sqrt(n*psi)) and ``etabar2`` (eta = sqrt(etabar2*n*psi)), eq. (18).

        Parameters
        ----------
        values : mapping of str to float
            A value for each swept name.

        Returns
        -------
        ScaledParams
            The set, validated.

        Raises
        ------
        ValueError
            For the axial study (no full parameter set per point).
        ParameterError
            The values make an invalid parameter set.
        """
        if self.study == "axial":
            raise ValueError("the axial study has no full parameter set per point")
        if isinstance(self.base, PhysicalParams):
            return self.physical_at(values).to_scaled()
        direct = {k: v for k, v in values.items() if k not in DERIVED_NAMES}
        p = self.base.replace(**direct) if direct else self.base
        changes: dict[str, float] = {}
        if "gammabar" in values:
            changes["gamma"] = values["gammabar"] * p.sqrt_npsi
        if "etabar2" in values:
            changes["eta"] = math.sqrt(values["etabar2"] * p.n * p.psi)
        return p.replace(**changes) if changes else p

    def physical_at(self, values: Mapping[str, float]) -> PhysicalParams:
        """The physical set of a physical base at values of the swept names.

        The swept fields are set, then ``rpm`` sets Omega0 = rpm*2*pi/60 and ``W0_kN`` the hook
        speed V0 whose nominal weight on bit at that Omega0 is W0 = 1e3*W0_kN
        (:meth:`~drillstring.model.params.PhysicalParams.hook_speed_for_weight`, eqs. (4), (7),
        (8)): the feed stays an imposed rate of penetration.

        Parameters
        ----------
        values : mapping of str to float
            A value for each swept name.

        Returns
        -------
        PhysicalParams

        Raises
        ------
        ValueError
            The base is not physical.
        ParameterError
            An invalid value (an rpm that is not > 0, a W0 not above the wearflat contact part),
            named.
        """
        if not isinstance(self.base, PhysicalParams):
            raise ValueError(f"the base {self.base_label!r} is not a physical parameter set")
        direct = {k: v for k, v in values.items() if k not in PHYSICAL_DERIVED}
        rig = self.base.replace(**direct) if direct else self.base
        if "rpm" in values:
            rpm = check_real("rpm", values["rpm"], lower=0.0, error=ParameterError)
            rig = rig.replace(Omega0=rpm * RPM)
        if "W0_kN" in values:
            rig = rig.replace(V0=rig.hook_speed_for_weight(1e3 * values["W0_kN"]))
        return rig

    def point_scales(self, index: int) -> Scales | None:
        """The rig's scales C, t* at point ``index``, for SI limits and times (top drive,
        telemetry).

        Returns
        -------
        PhysicalParams or None
            A physical base's point (:meth:`physical_at`); for a scaled base the known rig
            whose scaled set is the base (a scaled sweep leaves its C and I1, hence C and t*,
            as they are: any scaled point is that rig with other masses, damping, wearflat,
            friction, speed and feed); None when no known rig matches.
        """
        if isinstance(self.base, PhysicalParams):
            return self.physical_at(self.point_values(index))
        return known_rig(self.base)

    @property
    def feed(self) -> str:
        """How the full model is fed at every point: :data:`FEED_FOR_WOB` with a ``W0_kN`` axis,
        else :data:`FEED_IMPOSED`."""
        return FEED_FOR_WOB if "W0_kN" in self.names else FEED_IMPOSED

    def axial_point(self, index: int) -> tuple[float, float, float]:
        """The fast-model parameters of point ``index`` (axial study), eq. (18).

        Parameters
        ----------
        index : int
            Row-major point index.

        Returns
        -------
        tuple of 3 float
            (gammabar, etabar2, taubar_n): the swept values, the base set's (taubar_n0 for
            the delay) for those not swept.

        Raises
        ------
        IndexError
            ``index`` is outside the sweep.
        """
        ref = self.reference_values(AXIAL_NAMES)
        ref.update(self.point_values(index))
        return ref["gammabar"], ref["etabar2"], ref["taubar_n"]

    def reference_values(self, names: tuple[str, ...] | None = None) -> dict[str, float]:
        """The base set's value of each swept (or given) parameter: the reference point.

        Parameters
        ----------
        names : tuple of str, optional
            Parameter names (default: the swept ones); ``taubar_n`` gives taubar_n0, the
            derived ``gammabar``/``etabar2`` come from the scaled base, ``lambda`` is ``lam``.

        Returns
        -------
        dict of str to float
            Name -> value (SI for a physical base's fields).

        Raises
        ------
        AttributeError
            A name that is no parameter of the base set.
        """
        out: dict[str, float] = {}
        s = self.scaled_base
        for name in names or self.names:
            if name == "taubar_n":
                out[name] = s.taubar_n0
            elif name == "rpm":
                out[name] = float(self.base.surface_speed_rpm)
            elif name == "W0_kN":
                out[name] = float(self.base.W0) / 1e3
            elif name in DERIVED_NAMES:
                out[name] = float(getattr(s, name))
            elif isinstance(self.base, PhysicalParams):
                out[name] = float(getattr(self.base, name))
            else:
                out[name] = float(getattr(s, "lam" if name == "lambda" else name))
        return out

    def to_dict(self) -> dict[str, Any]:
        """Canonical JSON-able form (resolved base set): written next to the results and compared
        on ``--resume``.

        Returns
        -------
        dict
            ``study``, ``base`` (``kind`` and every field), ``base_label``, ``sweep`` (the
            axes), ``tau_end``, ``options`` (:func:`~drillstring.apps.sweep.options.
            options_table`), ``metrics``.
        """
        kind = "physical" if isinstance(self.base, PhysicalParams) else "scaled"
        return {
            "study": self.study,
            "base": {"kind": kind, **self.base.to_dict()},
            "base_label": self.base_label,
            "sweep": [a.to_dict() for a in self.axes],
            "tau_end": self.tau_end,
            "options": options_table(self.options),
            "metrics": list(self.metrics),
            **({"feed": self.feed} if self.study in FULL_MODEL_STUDIES else {}),
        }


# --------------------------------------------------------------------------------------------
# parsing
# --------------------------------------------------------------------------------------------


def _base(value: Any, base_dir: Path) -> tuple[ScaledParams | PhysicalParams, str]:
    def from_file(name: str) -> tuple[ScaledParams | PhysicalParams, str]:
        path = (base_dir / name).resolve()  # an absolute name stays as it is
        try:
            return read_params(path), str(path)
        except ParameterError as exc:
            raise SweepSpecError(f"base: {exc}") from None

    if isinstance(value, str):
        if value in KNOWN_PARAMS:
            return KNOWN_PARAMS[value], value
        if Path(value).suffix.lower() in (".toml", ".json"):
            return from_file(value)
        known = ", ".join(sorted(KNOWN_PARAMS))
        raise SweepSpecError(
            f"base = {value!r} is neither a known parameter set ({known}) nor a .toml/.json file"
        )
    if not isinstance(value, Mapping):
        raise SweepSpecError(f"base must be a set name, a file or a table, got {value!r}")
    data = dict(value)
    if "name" in data or "file" in data:
        if len(data) != 1:
            raise SweepSpecError(
                f"base: give one of 'name', 'file' or an inline set, got keys {sorted(data)}"
            )
        if "name" in data:
            known = sorted(KNOWN_PARAMS)
            name = check_choice("base.name", data["name"], known, error=SweepSpecError)
            return KNOWN_PARAMS[name], name
        return from_file(check_str("base.file", data["file"], error=SweepSpecError))
    kind = data.pop("kind", None)
    if kind not in ("scaled", "physical"):
        raise SweepSpecError(
            "base table needs 'name', 'file', or kind = \"scaled\" | \"physical\" with all "
            f"fields; got kind = {kind!r}"
        )
    cls = ScaledParams if kind == "scaled" else PhysicalParams
    try:
        params = cls.from_dict(data)
    except ParameterError as exc:
        raise SweepSpecError(f"base: {exc}") from None
    same = [name for name, p in (*KNOWN_PARAMS.items(), *KNOWN_PHYSICAL.items()) if p == params]
    return params, f"inline {kind}" + (f" ({same[0]})" if same else "")


def _axis(k: int, value: Any, allowed: tuple[str, ...]) -> Axis:
    where = f"sweep[{k}]"
    data = check_table(where, value, AXIS_KEYS, error=SweepSpecError)
    for key in ("param", "start", "stop", "num"):
        if key not in data:
            raise SweepSpecError(f"{where}: missing key {key!r}")
    param = check_str(f"{where}.param", data["param"], error=SweepSpecError)
    if param == "lam":
        param = "lambda"
    if param not in allowed:
        raise SweepSpecError(f"{where}.param must be one of {', '.join(allowed)}, got {param!r}")
    start = check_real(f"{where}.start", data["start"], error=SweepSpecError)
    stop = check_real(f"{where}.stop", data["stop"], error=SweepSpecError)
    num = check_int(f"{where}.num", data["num"], lower=2, error=SweepSpecError)
    scale = check_choice(
        f"{where}.scale", data.get("scale", "linear"), SCALES, error=SweepSpecError
    )
    if scale == "log" and not (start > 0 and stop > 0):
        raise SweepSpecError(
            f"{where}: a log scale needs start > 0 and stop > 0, got start={start!r}, stop={stop!r}"
        )
    if start == stop:
        raise SweepSpecError(f"{where}: start and stop are equal ({start!r}); nothing to sweep")
    return Axis(param=param, start=start, stop=stop, num=num, scale=scale)


def _options(study: str, value: Any, base_dir: Path) -> StudyOptions:
    cls = STUDY_OPTIONS[study]
    data = check_table(f"options (study {study!r})", value, option_keys(cls), error=SweepSpecError)
    try:
        options = options_from_table(cls, data)
    except ValueError as exc:
        raise SweepSpecError(str(exc)) from None
    loaded: dict[str, Any] = {}
    if study in ("closed-loop", "controllers") and options.gains != "design":
        loaded["gains_file"], loaded["gains"] = _gains_file(
            "options.gains", options.gains, base_dir
        )
    if study == "controllers":
        wanted = [c for c in options.controllers if c in CONSTRAINED_CONTROLLERS]
        if options.gains_constrained is not None:
            constrained, loaded["gains_constrained"] = _gains_file(
                "options.gains_constrained", options.gains_constrained, base_dir
            )
            if constrained.constraint is None:
                raise SweepSpecError(
                    f"options.gains_constrained = {loaded['gains_constrained']!r} holds no "
                    "input-constrained design (its 'constraint' record is null; drillstring "
                    "design --torque-limit DRIVE writes one)"
                )
            loaded["constrained_file"] = constrained
        elif wanted:
            raise SweepSpecError(
                f"options.controllers has {', '.join(wanted)}: options.gains_constrained must "
                "name the input-constrained design's gains file (drillstring design "
                "--torque-limit DRIVE writes gains_constrained.json)"
            )
    return replace(options, **loaded) if loaded else options


def _gains_file(where: str, name: str, base_dir: Path) -> tuple[GainsFile, str]:
    """A gains file by name (relative to ``base_dir``), read and checked; and its full path."""
    path = (base_dir / name).resolve()  # an absolute name stays as it is
    try:
        return read_gains(path), str(path)
    except GainsFileError as exc:
        raise SweepSpecError(f"{where}: {exc}") from None


def _check_top_drive(spec: SweepSpec) -> None:
    """The option ``top_drive`` at the base point: "none" or a spec that
    :func:`~drillstring.model.topdrive.top_drive_from_spec` accepts on the base's rig."""
    value = spec.options.top_drive
    if value == "none":
        return
    scales = spec.base if isinstance(spec.base, PhysicalParams) else known_rig(spec.base)
    try:
        top_drive_from_spec(value, spec.scaled_base.R0, scales)
    except ValueError as exc:
        hint = (
            " (the base is a scaled set of no known rig: give a physical base for a rating or "
            "a torque in N m)"
            if scales is None
            else ""
        )
        raise SweepSpecError(f"options.top_drive = {value!r}: {exc}{hint}") from None
    if scales is None and "lmi-telemetry" in spec.options.controllers:
        raise SweepSpecError(
            "options.controllers has lmi-telemetry, whose frames are timed in seconds: the "
            f"base {spec.base_label!r} is a scaled set of no known rig (give a physical base)"
        )
    industrial = any(c in INDUSTRIAL for c in spec.options.controllers)
    if spec.options.tuning.impedance == "pipe" and industrial and scales is None:
        raise SweepSpecError(
            "options.impedance = 'pipe' needs the rig's drill pipe: the base "
            f"{spec.base_label!r} is a scaled set of no known rig (give a physical base)"
        )


def spec_from_dict(
    data: Mapping[str, Any],
    source: str = "sweep spec",
    base_dir: str | os.PathLike[str] = ".",
    *,
    max_points: int = MAX_POINTS,
) -> SweepSpec:
    """Validate a parsed sweep description (layout in the module docstring).

    Every key, value and grid point is checked (each point's parameter set is built), after
    the grid's size has been checked against ``max_points`` from the axes alone.

    Parameters
    ----------
    data : mapping
        The parsed file's top-level table.
    source : str
        How error messages name the description (prefix).
    base_dir : path
        Folder relative file names (base set, gains file) are taken from.
    max_points : int
        The largest grid accepted (default :data:`MAX_POINTS`).

    Returns
    -------
    SweepSpec
        The validated sweep.

    Raises
    ------
    SweepSpecError
        An unknown or missing key, a bad value, an unreadable base or gains file, or an
        invalid grid point, naming the key and the value.
    """
    max_points = check_int("max_points", max_points, lower=1, error=SweepSpecError)
    try:
        return _spec_from_dict(data, source, Path(base_dir), max_points)
    except SweepSpecError as exc:
        raise SweepSpecError(f"{source}: {exc}") from None


def _spec_from_dict(
    data: Mapping[str, Any], source: str, base_dir: Path, max_points: int
) -> SweepSpec:

    data = check_table("top level", data, TOP_KEYS, error=SweepSpecError)
    for key in ("study", "base", "sweep"):
        if key not in data:
            raise SweepSpecError(f"missing key {key!r}")
    study = check_choice("study", data["study"], STUDIES, error=SweepSpecError)
    base, label = _base(data["base"], base_dir)

    if study == "axial":
        allowed = AXIAL_NAMES
    elif isinstance(base, PhysicalParams):
        allowed = PHYSICAL_NAMES + PHYSICAL_DERIVED
    else:
        allowed = SCALED_NAMES + DERIVED_NAMES
    sweep = data["sweep"]
    if isinstance(sweep, Mapping):
        sweep = [sweep]
    if not isinstance(sweep, list) or not 1 <= len(sweep) <= 2:
        raise SweepSpecError(f"sweep must be a list of one or two axes, got {sweep!r}")
    axes = tuple(_axis(k, a, allowed) for k, a in enumerate(sweep))
    n_points = math.prod(a.num for a in axes)
    if n_points > max_points:
        nums = " x ".join(f"sweep[{k}].num = {a.num}" for k, a in enumerate(axes))
        raise SweepSpecError(
            f"the grid has {n_points} points ({nums}), more than the limit of {max_points} "
            f"(drillstring sweep --max-points {n_points} allows it)"
        )
    if len(axes) == 2:
        a, b = axes[0].param, axes[1].param
        clash = {
            frozenset(("gamma", "gammabar")),
            frozenset(("eta", "etabar2")),
            frozenset(("Omega0", "rpm")),
            frozenset(("V0", "W0_kN")),
        }
        if a == b or frozenset((a, b)) in clash:
            raise SweepSpecError(f"sweep[0].param = {a!r} and sweep[1].param = {b!r} conflict")

    if study == "axial":
        if "tau_end" in data:
            raise SweepSpecError("tau_end is not used by the axial study (remove it)")
        tau_end = None
    else:
        if "tau_end" not in data:
            raise SweepSpecError(f"missing key 'tau_end' (run length of the {study} study)")
        tau_end = check_real("tau_end", data["tau_end"], lower=0.0, error=SweepSpecError)
    options = _options(study, data.get("options", {}), base_dir)
    if study == "closed-loop" and options.window > tau_end:
        raise SweepSpecError(f"options.window = {options.window!r} exceeds tau_end = {tau_end!r}")
    if study == "controllers":
        try:
            options.check_run(tau_end)
        except ValueError as exc:
            raise SweepSpecError(str(exc)) from None

    known = plottable(study)
    raw_metrics = data.get("metrics", list(known))
    if not isinstance(raw_metrics, list) or not raw_metrics:
        raise SweepSpecError(f"metrics must be a non-empty list of names, got {raw_metrics!r}")
    for m in raw_metrics:
        if m not in known:
            all_names = ", ".join(known)
            raise SweepSpecError(
                f"metrics: unknown metric {m!r} for study {study!r} (known: {all_names})"
            )
    spec = SweepSpec(
        study=study,
        base=base,
        base_label=label,
        axes=axes,
        tau_end=tau_end,
        options=options,
        metrics=tuple(raw_metrics),
        source=source,
    )
    if study == "controllers":
        _check_top_drive(spec)
    _check_points(spec)
    return spec


def _check_points(spec: SweepSpec) -> None:
    """Build every point's parameters so that a bad grid value fails now, not in a worker."""
    for index in range(spec.n_points):
        try:
            if spec.study == "axial":
                g, e2, tb = spec.axial_point(index)
                fast_params(g, e2, tb, spec.options.lam_over_vbar0)
            elif spec.study == "controllers":
                spec.point_params(index)
                pipe = spec.options.tuning.impedance == "pipe"
                if pipe and any(c in INDUSTRIAL for c in spec.options.controllers):
                    try:  # the pipe of the point's string (an axis may change C or I1)
                        impedance("pipe", spec.point_scales(index))
                    except ValueError as exc:
                        raise ValueError(f"options.impedance = 'pipe': {exc}") from None
            else:
                p = spec.point_params(index)
                if p.omega0 + spec.options.dphi0 <= 0.0:
                    raise ValueError(
                        f"omega0 + dphi0 = {p.omega0 + spec.options.dphi0!r} <= 0: the bit "
                        "would start in torsional stick"
                    )
        except ValueError as exc:
            values = ", ".join(f"{k} = {v!r}" for k, v in spec.point_values(index).items())
            raise SweepSpecError(f"sweep point {index} ({values}) is invalid: {exc}") from None


def load_spec(
    path: str | os.PathLike[str],
    *,
    max_points: int = MAX_POINTS,
    base_dir: str | os.PathLike[str] | None = None,
) -> SweepSpec:
    """Read and validate a sweep file (.toml or .json, chosen by suffix).

    Parameters
    ----------
    path : path
        The file.
    base_dir : path, optional
        The folder relative names in it (base set, gains files) are taken from (default: the
        file's).
    max_points : int
        The largest grid accepted (default :data:`MAX_POINTS`).

    Returns
    -------
    SweepSpec
        The validated sweep (:func:`spec_from_dict`).

    Raises
    ------
    SweepSpecError
        Another suffix, an unreadable or unparsable file, a top level that is not a table, or
        any problem :func:`spec_from_dict` finds.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".toml", ".json"):
        raise SweepSpecError(f"sweep spec {str(path)!r}: suffix must be .toml or .json")
    try:
        data = load_table(path)
    except OSError as exc:
        raise SweepSpecError(f"cannot read sweep spec {str(path)!r}: {exc}") from None
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise SweepSpecError(f"sweep spec {str(path)!r} is not valid {suffix[1:]}: {exc}") from None
    if not isinstance(data, dict):
        raise SweepSpecError(f"sweep spec {str(path)!r}: top level must be a table/object")
    return spec_from_dict(
        data,
        source=f"sweep spec {str(path)!r}",
        base_dir=path.parent if base_dir is None else base_dir,
        max_points=max_points,
    )
