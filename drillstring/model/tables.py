"""Parameter tables: a controller part declares its parameters once, with their dimensions.

A control law (:mod:`drillstring.model.laws`), the top drive (:mod:`drillstring.model.topdrive`),
the sensing (:mod:`drillstring.model.sensing`) and the controller's timing
(:mod:`drillstring.model.timing`) each list their parameters as :class:`Parameter` rows. From
that one table come the checks of the values, the conversion to and from SI units (each value
scaled by its dimension, :data:`drillstring.model.units.DIMENSIONS`: ``value_SI = value *
C**torque * t***time``, eqs. (15)-(16)), the controller FMUs' variables and the part's slots in
the digital controller's block (:func:`parameter_slots`).

A float64 block that compiled code reads (the digital controller's block, an FMU's io block) is
laid out by one convention, :func:`block_layout`: a table of (name, size) entries in order, the
offsets computed from it; no offset is written by hand.
"""

from __future__ import annotations

import collections
import numbers
import re
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from drillstring.model.units import DIMENSIONS, si_scale
from drillstring.validation import check_choice, check_real

__all__ = [
    "Parameter",
    "Scales",
    "block_layout",
    "check_names",
    "parameter_slots",
    "scales_of",
    "table_from_si",
    "table_to_si",
]


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


def block_layout(name: str, table: Sequence[tuple[str, int]], state: Collection[str] = ()) -> Any:
    """The offsets of the entries of a float64 block laid out as ``table``.

    Parameters
    ----------
    name : str
        The name of the layout (of its named-tuple class).
    table : sequence of (str, int)
        The block's entries in order: name (an identifier) and size (slots of float64, >= 1).
    state : collection of str
        The entries that are state (change while the block's owner runs); the others are its
        parameters and connectors.

    Returns
    -------
    namedtuple
        The offset of each entry by its name, and ``size``, the length of the block (numba
        reads such a tuple as constants). Its class holds the table (``SLOTS``) and the state
        entries (``STATE``, in the table's order).

    Raises
    ------
    ValueError
        A name that is not an identifier or is repeated, a size that is not a positive integer,
        or a state entry that is not in the table; the message names it.
    """
    names = [entry for entry, _ in table]
    for entry, size in table:
        if not entry.isidentifier() or entry.startswith("_") or entry == "size":
            raise ValueError(f"layout {name}: {entry!r} is not a name of an entry")
        if names.count(entry) > 1:
            raise ValueError(f"layout {name}: entry {entry!r} is repeated")
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise ValueError(
                f"layout {name}: entry {entry!r} has size {size!r}, not an integer >= 1"
            )
    unknown = sorted(set(state) - set(names))
    if unknown:
        raise ValueError(f"layout {name}: state entries {unknown} are not in its table")
    offsets, at = [], 0
    for _, size in table:
        offsets.append(at)
        at += size
    cls = collections.namedtuple(name, [*names, "size"])
    cls.SLOTS = tuple((entry, size) for entry, size in table)
    cls.STATE = tuple(entry for entry in names if entry in state)
    return cls(*offsets, at)


_VECTOR = re.compile(r"^(\w+)\[(\d+)\]$")


def parameter_slots(
    table: Sequence[Parameter], skip: Collection[str] = ()
) -> tuple[tuple[str, int], ...]:
    """The block entries of a parameter table: one slot per parameter, in the table's order.

    A vector declared element by element, ``F[1]`` ... ``F[n]`` (consecutive, from 1), is one
    entry ``F`` of size n. A choice takes one slot (its index in ``choices``).

    Parameters
    ----------
    table : sequence of Parameter
        The parameters.
    skip : collection of str
        Names of parameters that have their slot elsewhere (e.g. a law's switch-on time, in the
        controller's own entries).

    Returns
    -------
    tuple of (str, int)
        Entries for :func:`block_layout`.

    Raises
    ------
    ValueError
        A vector whose elements are not numbered 1, 2, ... in order.
    """
    out: list[tuple[str, int]] = []
    for p in table:
        if p.name in skip:
            continue
        match = _VECTOR.match(p.name)
        if match is None:
            out.append((p.name, 1))
            continue
        base, index = match.group(1), int(match.group(2))
        if out and out[-1][0] == base and index == out[-1][1] + 1:
            out[-1] = (base, index)
        elif index == 1:
            out.append((base, 1))
        else:
            raise ValueError(
                f"parameter {p.name}: the elements of {base} must be numbered 1, 2, ..."
            )
    return tuple(out)
