"""Parameter tables: a controller part declares its parameters once, with their dimensions.

A control law (:mod:`drillstring.model.laws`), the top drive (:mod:`drillstring.model.topdrive`)
and the sensing (:mod:`drillstring.model.sensing`) each list their parameters as
:class:`Parameter` rows. From that one table come the checks of the values, the conversion to and
from SI units (each value scaled by its dimension, :data:`drillstring.model.units.DIMENSIONS`:
``value_SI = value * C**torque * t***time``, eqs. (15)-(16)) and the controller FMUs' variables.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from drillstring.model.units import DIMENSIONS, si_scale
from drillstring.validation import check_choice, check_real

__all__ = ["Parameter", "Scales", "check_names", "scales_of", "table_from_si", "table_to_si"]


class Scales(Protocol):
    """The two scales of Section II an SI conversion needs (a
    :class:`~drillstring.model.params.PhysicalParams` is one)."""

    @property
    def C(self) -> float:  # noqa: N802 - the paper's name
        """Torsional stiffness [N m/rad]: the torque scale (16)."""
        ...

    @property
    def t_star(self) -> float:
        """Characteristic time t* = sqrt(I1/C) [s]."""
        ...


@dataclass(frozen=True)
class Parameter:
    """One parameter, declared once.

    Attributes
    ----------
    name : str
        The parameter's name (a field, or ``F[1]`` ... for the affine law's gain).
    dimension : str
        A key of :data:`drillstring.model.units.DIMENSIONS` (``"1"`` for a choice).
    description : str
        What it is, with the paper's equation where there is one.
    lower : float or None
        Lower bound (None: any finite value); ``strict``: the bound excluded.
    choices : tuple of str
        The items of a choice parameter (empty for a number).
    """

    name: str
    dimension: str
    description: str
    lower: float | None = None
    strict: bool = False
    choices: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.dimension not in DIMENSIONS:
            raise ValueError(f"parameter {self.name}: unknown dimension {self.dimension!r}")

    def check(self, where: str, value: Any) -> Any:
        """The value to store, or ValueError naming ``where``, the parameter and the value."""
        if self.choices:
            return check_choice(f"{where}.{self.name}", value, self.choices)
        return check_real(f"{where}.{self.name}", value, lower=self.lower, strict=self.strict)


def scales_of(scales: Scales) -> tuple[float, float]:
    """(C, t*) of ``scales``, checked (both finite and > 0).

    Raises
    ------
    TypeError
        ``scales`` has no ``C`` or ``t_star``.
    ValueError
        One of them is not a finite positive number.
    """
    try:
        C, t = scales.C, scales.t_star
    except AttributeError:
        raise TypeError(
            f"scales must have C and t_star (e.g. a PhysicalParams), got {type(scales).__name__}"
        ) from None
    return check_real("scales C", C, lower=0.0), check_real("scales t_star", t, lower=0.0)


def check_names(where: str, table: Sequence[Parameter], values: Mapping[str, Any]) -> None:
    """Raise ValueError naming the keys of ``values`` that are not parameters of ``table``."""
    known = [p.name for p in table]
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ValueError(f"{where}: unknown parameter(s) {unknown} (known: {', '.join(known)})")


def table_to_si(
    table: Sequence[Parameter], values: Mapping[str, Any], scales: Scales
) -> dict[str, Any]:
    """The SI values of scaled ``values`` (choices unchanged, infinities stay infinite).

    Parameters
    ----------
    table : sequence of Parameter
        The parameters (their dimensions).
    values : mapping
        Name -> scaled value, names of ``table``.
    scales : PhysicalParams or any object with ``C`` and ``t_star``
        The rig's scales.

    Returns
    -------
    dict
        Name -> SI value, in the order of ``values``.
    """
    C, t = scales_of(scales)
    rows = {p.name: p for p in table}
    return {
        k: v if rows[k].choices else v * si_scale(rows[k].dimension, C, t)
        for k, v in values.items()
    }


def table_from_si(
    where: str, table: Sequence[Parameter], values: Mapping[str, Any], scales: Scales
) -> dict[str, Any]:
    """The scaled values of SI ``values``, the inverse of :func:`table_to_si`.

    Raises
    ------
    ValueError
        An unknown name, or a number that is not real (infinities are allowed: limits that are
        off); the message names ``where`` and the parameter.
    """
    C, t = scales_of(scales)
    check_names(where, table, values)
    rows = {p.name: p for p in table}
    out: dict[str, Any] = {}
    for k, v in values.items():
        if rows[k].choices:
            out[k] = v
            continue
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or v != v:
            raise ValueError(f"{where} {k} must be a real number, got {v!r}")
        out[k] = v / si_scale(rows[k].dimension, C, t)
    return out
