"""Gains file: the designed state feedback ``R_fb = F x`` and what it was designed for.

JSON layout (``format_version`` 1)::

    {
      "format": "drillstring-gains", "format_version": 1, "version": "<package version>",
      "F": [4 numbers], "K0": ..., "R_ff": ..., "alpha": ..., "A": ..., "taubar_crit": ...,
      "params": {ScaledParams.to_dict()}, "params_sha256": "<hex>",
      "certificate": {"lmi32_max_eig": ..., ...}, "spectral_abscissa": ...,
      "solver": "CLARABEL", "solver_status": "optimal",
      "constraint": null | {"u_max": ..., "peak_torque": ..., "decay": ..., "tau_max": ...,
                            "torque_limit": [R_min, R_max], "braking_limit": -R_min,
                            "top_drive": "<rating>", "states": <count>,
                            "experiment": "fig6", "S": [4 x 4], "switch_on_states": [k x 4]}
    }

``constraint`` (optional) records an input-constrained design
(:mod:`drillstring.controller.constrained`): the feedback torque budget ``u_max`` (units of C),
the certified peak feedback torque from the switch-on states, the required decay, the largest
delay covered, the drive's torque limit and rating, its braking limit (the most negative
torque it applies, as a positive number, units of C; 0: no braking; it must be -R_min of
``torque_limit``), and the ellipsoid ``S`` of the certificate
(E = {x : x^T S^-1 x <= 1}) with the switch-on states it holds, so that the certificate can be
checked again from the file (:func:`~drillstring.controller.constrained.recheck_constrained`);
``certificate`` then holds that design's margins. Reading checks that ``S`` is a finite,
symmetric, positive definite 4 x 4 matrix, the states finite rows of 4 (as many as ``states``
says) and, with ``S``, that the certificate's peak torque is sqrt(F S F^T); a file without
``S`` (written before it was recorded) is read, but cannot be re-checked.

``x = [phi, dphi/dtau, phi - theta - K0, dtheta/dtau]`` and ``R - R0 = R_ff + F x`` (31).
``params_sha256`` is the SHA-256 of the canonical JSON (sorted keys, no spaces) of the parameter
set; reading checks it, the field types, ``R_ff = -K0`` and that ``K0`` is the value (27) gives
for the stored parameters, ``A`` and ``taubar_crit``. Writing is atomic (temporary file in the same
folder, then ``os.replace``).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any, Self

import numpy as np

from drillstring.controller.averaged import AveragedModel, averaged_model
from drillstring.fileio import write_text
from drillstring.model.params import ParameterError, ScaledParams
from drillstring.validation import check_real

__all__ = [
    "DEFAULT_GAINS_PATH",
    "FORMAT",
    "FORMAT_VERSION",
    "PAPER_F",
    "GainsFile",
    "GainsFileError",
    "params_hash",
    "read_gains",
    "write_gains",
]

#: Gain published in Section V of the paper (Theorem 1 at its Table I), ``R_fb = F x``.
PAPER_F: tuple[float, float, float, float] = (-3448.5, -1574.7, 481.8, -89.0)
#: Where ``drillstring design`` writes the gains file by default (relative to the working
#: folder), and so where ``build_fmus.py`` and ``drillstring crosscheck`` look by default.
DEFAULT_GAINS_PATH = Path("out/design/gains.json")
FORMAT = "drillstring-gains"
FORMAT_VERSION = 1

_KEYS = (
    "format",
    "format_version",
    "version",
    "F",
    "K0",
    "R_ff",
    "alpha",
    "A",
    "taubar_crit",
    "params",
    "params_sha256",
    "certificate",
    "spectral_abscissa",
    "solver",
    "solver_status",
)


class GainsFileError(ValueError):
    """A gains file that cannot be read, is malformed, or does not match its parameter hash."""


def _package_version() -> str:
    try:
        return metadata.version("drillstring")
    except metadata.PackageNotFoundError:
        return "unknown"


def params_hash(params: ScaledParams) -> str:
    """SHA-256 (hex) of the canonical JSON of ``params.to_dict()`` (sorted keys, no spaces).

    Parameters
    ----------
    params : ScaledParams
        The parameter set.

    Returns
    -------
    str
        64 hexadecimal digits.
    """
    text = json.dumps(params.to_dict(), sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _real(name: str, value: Any) -> float:
    return check_real(f"gains file: {name}", value, error=GainsFileError)


def _matrix(name: str, value: Any, cols: int) -> list[list[float]]:
    """Rows of ``cols`` finite numbers (a JSON list of lists)."""
    if not isinstance(value, list | tuple) or not value:
        raise GainsFileError(f"gains file: constraint[{name!r}] must be a list of rows: {value!r}")
    rows = []
    for i, row in enumerate(value):
        if not isinstance(row, list | tuple) or len(row) != cols:
            raise GainsFileError(
                f"gains file: constraint[{name!r}][{i}] must be a row of {cols} numbers: {row!r}"
            )
        rows.append([_real(f"constraint[{name!r}][{i}][{j}]", v) for j, v in enumerate(row)])
    return rows


def _ellipsoid(value: Any, F: tuple[float, ...], peak: float | None) -> list[list[float]]:
    """The ellipsoid matrix S of a constrained design: 4 x 4, symmetric, positive definite;
    sqrt(F S F^T) is the certificate's peak torque (when recorded)."""
    S = _matrix("S", value, 4)
    if len(S) != 4:
        raise GainsFileError(f"gains file: constraint['S'] must be 4 x 4, got {len(S)} rows")
    for i in range(4):
        for j in range(i):
            a, b = S[i][j], S[j][i]
            if not math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12 * abs(S[i][i] * S[j][j]) ** 0.5):
                raise GainsFileError(
                    f"gains file: constraint['S'] is not symmetric: S[{i}][{j}] = {a!r}, "
                    f"S[{j}][{i}] = {b!r}"
                )
    smallest = float(np.linalg.eigvalsh(np.asarray(S))[0])
    if not smallest > 0.0:
        raise GainsFileError(
            f"gains file: constraint['S'] is not positive definite (smallest eigenvalue "
            f"{smallest!r})"
        )
    if peak is not None:
        Fv = np.asarray(F)
        found = math.sqrt(max(float(Fv @ np.asarray(S) @ Fv), 0.0))
        if not math.isclose(found, peak, rel_tol=1e-9):
            raise GainsFileError(
                f"gains file: sqrt(F S F^T) = {found!r} is not the certificate's peak torque "
                f"{peak!r}: S or F was changed"
            )
    return S


def _braking(record: dict[str, Any]) -> None:
    """The braking limit of a constrained design: a number >= 0, -R_min of the torque limit."""
    braking = _real("constraint['braking_limit']", record["braking_limit"])
    if braking < 0.0:
        raise GainsFileError(
            f"gains file: constraint['braking_limit'] must be >= 0, got {braking!r}"
        )
    limit = record.get("torque_limit")
    if limit is not None:
        if not isinstance(limit, list | tuple) or len(limit) != 2:
            raise GainsFileError(
                f"gains file: constraint['torque_limit'] must be [R_min, R_max]: {limit!r}"
            )
        R_min = _real("constraint['torque_limit'][0]", limit[0])
        if not math.isclose(-R_min, braking, rel_tol=1e-12, abs_tol=1e-15):
            raise GainsFileError(
                f"gains file: constraint['braking_limit'] = {braking!r} is not -R_min = "
                f"{-R_min!r} of the torque limit"
            )


def _states(value: Any, count: Any) -> list[list[float]]:
    """The switch-on states of a constrained design: rows of 4, ``count`` of them if given."""
    rows = _matrix("switch_on_states", value, 4)
    if count is not None and count != len(rows):
        raise GainsFileError(
            f"gains file: constraint['states'] = {count!r} but {len(rows)} switch-on states"
        )
    return rows


def _string_design(value: Any) -> dict[str, Any]:
    """The record of a string design (:mod:`drillstring.controller.string_design`): its torque
    gain, reduced chain, decay and Lyapunov matrix P (finite, symmetric, positive definite,
    2 (reduced_elements + 1) square)."""
    if not isinstance(value, Mapping):
        raise GainsFileError(f"gains file: string_design must be a mapping or null: {value!r}")
    record = dict(value)
    for key in ("torque_gain", "reduced_elements", "kappa", "decay", "P", "check_elements"):
        if key not in record:
            raise GainsFileError(f"gains file: string_design lacks {key!r}")
    for key in ("torque_gain", "kappa", "decay"):
        _real(f"string_design[{key!r}]", record[key])
    n = record["reduced_elements"]
    if not isinstance(n, int) or isinstance(n, bool) or n < 2:
        raise GainsFileError(f"gains file: string_design['reduced_elements'] must be >= 2: {n!r}")
    size = 2 * (n + 1)
    P = np.asarray(_matrix("P", record["P"], size), dtype=float)
    if P.shape != (size, size) or not np.allclose(P, P.T, rtol=1e-9, atol=0.0):
        raise GainsFileError(f"gains file: string_design['P'] must be symmetric {size} x {size}")
    if not float(np.linalg.eigvalsh(P)[0]) > 0.0:
        raise GainsFileError("gains file: string_design['P'] is not positive definite")
    return record


@dataclass(frozen=True)
class GainsFile:
    """Content of a gains file (see the module docstring for the JSON layout).

    Validated on construction: finite numbers, 4 entries in ``F``, ``alpha > 0``,
    ``R_ff = -K0`` (31), and ``K0`` equal to the value of the averaged model built from
    ``params``, ``A`` and ``taubar_crit``; any violation raises :class:`GainsFileError`.
    """

    F: tuple[float, float, float, float]
    K0: float
    R_ff: float
    alpha: float
    A: float
    taubar_crit: float
    params: ScaledParams
    certificate: Mapping[str, float]
    spectral_abscissa: float
    solver: str
    solver_status: str
    version: str = field(default_factory=_package_version)
    constraint: Mapping[str, Any] | None = None
    string_design: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        F = tuple(_real(f"F[{i}]", v) for i, v in enumerate(self.F))
        if len(F) != 4:
            raise GainsFileError(f"gains file: F must have 4 entries, got {len(F)}: {self.F!r}")
        object.__setattr__(self, "F", F)
        for name in ("K0", "R_ff", "alpha", "A", "taubar_crit", "spectral_abscissa"):
            object.__setattr__(self, name, _real(name, getattr(self, name)))
        if not isinstance(self.params, ScaledParams):
            raise GainsFileError(f"gains file: params must be ScaledParams, got {self.params!r}")
        if not isinstance(self.certificate, Mapping):
            raise GainsFileError(f"gains file: certificate must be a mapping: {self.certificate!r}")
        cert = {str(k): _real(f"certificate[{k!r}]", v) for k, v in self.certificate.items()}
        object.__setattr__(self, "certificate", cert)
        for name in ("solver", "solver_status", "version"):
            value = getattr(self, name)
            if not isinstance(value, str):
                raise GainsFileError(f"gains file: {name} must be a string, got {value!r}")
        if self.alpha <= 0.0:
            raise GainsFileError(f"gains file: alpha must be > 0, got {self.alpha!r}")
        if self.constraint is not None:
            if not isinstance(self.constraint, Mapping):
                raise GainsFileError(f"gains file: constraint must be a mapping or null, got "
                                     f"{self.constraint!r}")  # fmt: skip
            for key in ("u_max", "peak_torque", "decay", "tau_max"):
                if key not in self.constraint:
                    raise GainsFileError(f"gains file: constraint lacks {key!r}")
                _real(f"constraint[{key!r}]", self.constraint[key])
            if self.constraint["peak_torque"] > self.constraint["u_max"]:
                raise GainsFileError(
                    "gains file: the constraint's peak torque is above its u_max: the design "
                    "does not meet its own limit"
                )
            record = dict(self.constraint)
            if "braking_limit" in record:
                _braking(record)
            if "S" in record:
                record["S"] = _ellipsoid(record["S"], F, cert.get("peak_torque"))
            if "switch_on_states" in record:
                record["switch_on_states"] = _states(
                    record["switch_on_states"], record.get("states")
                )
            object.__setattr__(self, "constraint", record)
        if self.string_design is not None:
            object.__setattr__(self, "string_design", _string_design(self.string_design))
        if not math.isclose(self.R_ff, -self.K0, rel_tol=1e-12, abs_tol=1e-15):
            raise GainsFileError(f"gains file: R_ff = {self.R_ff!r} is not -K0 = {-self.K0!r} (31)")
        try:
            K0 = averaged_model(self.params, self.A, self.taubar_crit).K0
        except ValueError as exc:
            raise GainsFileError(f"gains file: A/taubar_crit do not fit params: {exc}") from None
        if not math.isclose(self.K0, K0, rel_tol=1e-9, abs_tol=1e-15):
            raise GainsFileError(
                f"gains file: K0 = {self.K0!r} differs from (27) with the stored params, A and "
                f"taubar_crit: {K0!r}"
            )

    @classmethod
    def of_model(
        cls, model: AveragedModel, params: ScaledParams, F: Sequence[float], **fields: Any
    ) -> Self:
        """The record of a gain ``F`` designed on ``model`` (27), built from ``params``: K0,
        R_ff (31), A and taubar_crit are the model's, ``fields`` the design's other fields
        (``alpha``, ``certificate``, ``solver``, ...); :class:`GainsFileError` as the
        constructor."""
        return cls(
            F=tuple(float(v) for v in F),  # type: ignore[arg-type]
            K0=model.K0,
            R_ff=model.R_ff,
            A=model.A,
            taubar_crit=model.taubar_crit,
            params=params,
            **fields,
        )

    @property
    def params_sha256(self) -> str:
        """:func:`params_hash` of ``params``."""
        return params_hash(self.params)

    def to_json_dict(self) -> dict[str, Any]:
        """The JSON object of the gains file (layout in the module docstring).

        Returns
        -------
        dict
            Plain JSON types (lists, floats, str, nested dicts), ready for :func:`json.dumps`;
            ``params_sha256`` is recomputed from ``params``.
        """
        return {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "version": self.version,
            "F": list(self.F),
            "K0": self.K0,
            "R_ff": self.R_ff,
            "alpha": self.alpha,
            "A": self.A,
            "taubar_crit": self.taubar_crit,
            "params": self.params.to_dict(),
            "params_sha256": self.params_sha256,
            "certificate": dict(self.certificate),
            "spectral_abscissa": self.spectral_abscissa,
            "solver": self.solver,
            "solver_status": self.solver_status,
            "constraint": None if self.constraint is None else dict(self.constraint),
            # only in a string design's file: the other files keep their layout
            **({} if self.string_design is None else {"string_design": dict(self.string_design)}),
        }

    @classmethod
    def from_json_dict(cls, data: Any, source: str = "gains file") -> GainsFile:
        """Validate a parsed JSON object (keys, types, hash) and build the dataclass.

        Parameters
        ----------
        data : object
            The parsed JSON document.
        source : str
            How error messages name the document (e.g. the file path).

        Returns
        -------
        GainsFile
            The validated content.

        Raises
        ------
        GainsFileError
            Not an object, unknown or missing keys, another format or version, a bad parameter
            set, a hash mismatch, or a value :class:`GainsFile` rejects.
        """
        if not isinstance(data, dict):
            raise GainsFileError(f"{source}: expected a JSON object, got {type(data).__name__}")
        unknown = sorted(set(data) - set(_KEYS) - {"constraint", "string_design"})
        missing = [k for k in _KEYS if k not in data]
        if unknown:
            raise GainsFileError(f"{source}: unknown key(s) {', '.join(unknown)}")
        if missing:
            raise GainsFileError(f"{source}: missing key(s) {', '.join(missing)}")
        if data["format"] != FORMAT or data["format_version"] != FORMAT_VERSION:
            raise GainsFileError(
                f"{source}: format {data['format']!r} version {data['format_version']!r} is not "
                f"{FORMAT!r} version {FORMAT_VERSION}"
            )
        if not isinstance(data["F"], list):
            raise GainsFileError(f"{source}: F must be a list of 4 numbers, got {data['F']!r}")
        try:
            params = ScaledParams.from_dict(data["params"])
        except ParameterError as exc:
            raise GainsFileError(f"{source}: bad parameter set: {exc}") from None
        expected = params_hash(params)
        if data["params_sha256"] != expected:
            raise GainsFileError(
                f"{source}: parameter hash mismatch: file says {data['params_sha256']!r}, "
                f"the stored parameter set hashes to {expected!r} (file edited or corrupted)"
            )
        try:
            return cls(
                F=tuple(data["F"]),  # type: ignore[arg-type]
                K0=data["K0"],
                R_ff=data["R_ff"],
                alpha=data["alpha"],
                A=data["A"],
                taubar_crit=data["taubar_crit"],
                params=params,
                certificate=data["certificate"],
                spectral_abscissa=data["spectral_abscissa"],
                solver=data["solver"],
                solver_status=data["solver_status"],
                version=data["version"],
                constraint=data.get("constraint"),
                string_design=data.get("string_design"),
            )
        except GainsFileError as exc:
            raise GainsFileError(f"{source}: {exc}") from None


def write_gains(gains: GainsFile, path: str | os.PathLike[str]) -> Path:
    """Write ``gains`` as JSON to ``path`` atomically (temp file + ``os.replace``).

    Parameters
    ----------
    gains : GainsFile
        The content.
    path : path-like
        Target file.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    text = json.dumps(gains.to_json_dict(), indent=2, allow_nan=False) + "\n"
    return write_text(path, text)


def read_gains(path: str | os.PathLike[str]) -> GainsFile:
    """Read and validate a gains file.

    Parameters
    ----------
    path : path-like
        The JSON gains file.

    Returns
    -------
    GainsFile
        The validated content.

    Raises
    ------
    GainsFileError
        The file cannot be read, is not JSON, or fails :meth:`GainsFile.from_json_dict`; the
        message names the file and what is wrong.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise GainsFileError(f"cannot read gains file {str(path)!r}: {exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise GainsFileError(f"gains file {str(path)!r} is not valid JSON: {exc}") from None
    return GainsFile.from_json_dict(data, source=f"gains file {str(path)!r}")
