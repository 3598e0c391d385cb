"""One declaration per FMU variable, two unit systems (bundled into each FMU's ``resources/``).

Every FMU of the project exists in the paper's scaled quantities and in SI units. An FMU script
declares each variable once (:func:`declare`): its name in each unit system (``None``: the
variable exists in one of them only), its dimension (:data:`drillstring.model.units.DIMENSIONS`)
or its SI unit, its description and its scaled start value. :func:`variables` gives the
:class:`~drillstring_fmu_support.Variable` table of either unit system: in SI each start value
and bound is scaled by its dimension on the reference rig (``docs/reference_rig.md``) and the
unit (and display unit) is the dimension's; in scaled units every unit is "1", so the
description of every time-valued variable says that it is in the scaled time tau (in SI: in
seconds; :meth:`Declared.time_note`). ``build_fmus.py``
generates each variant's class from the script's one class: the unit system is a class
attribute (``UNIT_SYSTEM``), the rest is the same code.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import drillstring_fmu_support as fmu

from drillstring.model.params import REFERENCE_RIG
from drillstring.model.tables import Parameter
from drillstring.model.units import DIMENSIONS, SCALED_TIME, si_scale

__all__ = [
    "SCALED",
    "SI",
    "SYSTEMS",
    "Declared",
    "declare",
    "from_table",
    "name_in",
    "si_factor",
    "variables",
]

SCALED = "scaled"
SI = "si"
SYSTEMS = (SCALED, SI)


def si_factor(dimension: str) -> float:
    """The factor from scaled to SI values of ``dimension`` on the reference rig."""
    r = REFERENCE_RIG
    return si_scale(dimension, r.C, r.t_star, r.L_star)


@dataclass(frozen=True)
class Declared:
    """A variable declared once (see :func:`declare`)."""

    scaled: str | None
    si: str | None
    type: str
    causality: str
    description: str
    dimension: str = "1"
    start: Any = None
    si_start: Any = None
    si_unit: str | None = None
    si_display: str | None = None
    scaled_note: str = ""
    si_note: str = ""
    options: dict[str, Any] = field(default_factory=dict)

    def name(self, system: str) -> str | None:
        """The variable's name in ``system`` (None: absent there)."""
        return self.scaled if system == SCALED else self.si

    @property
    def time_valued(self) -> bool:
        """Whether the variable is a time (a Real whose SI unit is the second)."""
        return self.type == "Real" and (self.si_unit or DIMENSIONS[self.dimension].unit) == "s"

    def time_note(self, system: str) -> str:
        """What a time-valued variable's description says of its unit: in the scaled system the
        scaled time tau (:data:`~drillstring.model.units.SCALED_TIME`), which a tool cannot read
        from its unit "1", in SI seconds; "" for any other variable."""
        if not self.time_valued:
            return ""
        return f"; in the {SCALED_TIME}" if system == SCALED else "; in seconds"

    def variable(self, system: str) -> fmu.Variable | None:
        """The variable of ``system``, or None when it has no name there."""
        name = self.name(system)
        if name is None:
            return None
        kw = dict(self.options)
        si_check = kw.pop("si_check", None)
        if system == SI and si_check is not None:
            kw["check"] = si_check
        note = self.scaled_note if system == SCALED else self.si_note
        description = f"{self.description}{note}{self.time_note(system)}"
        start = self.start
        if system == SI and self.type == "Real":
            d = DIMENSIONS[self.dimension]
            kw["unit"] = self.si_unit or d.unit
            display = self.si_display if self.si_unit else d.display
            if display is not None:
                kw["display_unit"] = display
            if self.si_start is not None:
                start = self.si_start
            elif start is not None:
                start = start * si_factor(self.dimension)
            for bound in ("min", "max"):
                if kw.get(bound) not in (None, fmu.POSITIVE, 0.0):
                    kw[bound] = kw[bound] * si_factor(self.dimension)
        elif system == SI and self.si_start is not None:
            start = self.si_start
        if self.type == "Enumeration":
            items, type_name = kw.pop("items"), kw.pop("type_name")
            return fmu.enumeration(name, type_name, items, start, description)
        if self.causality == "output":
            return fmu.output(name, self.type, description, **kw)
        return fmu.Variable(name, self.type, self.causality, description, start=start, **kw)


def declare(
    names: str | tuple[str | None, str | None],
    type: str,
    causality: str,
    description: str,
    *,
    dimension: str = "1",
    start: Any = None,
    si_start: Any = None,
    si_unit: str | None = None,
    si_display: str | None = None,
    scaled_note: str = "",
    si_note: str = "",
    **options: Any,
) -> Declared:
    """Declare a variable for both unit systems.

    Parameters
    ----------
    names : str or (str or None, str or None)
        The name (the same in both systems), or (scaled name, SI name); None: absent there.
    type, causality, description
        As :class:`drillstring_fmu_support.Variable` (an Enumeration: ``items``,
        ``type_name`` and the start item's name).
    dimension : str
        A key of :data:`~drillstring.model.units.DIMENSIONS`: the SI unit and the factor of the
        start value and the bounds (``"1"``: the same in both).
    start : object
        The scaled start value (converted by the dimension for SI unless ``si_start``).
    si_start, si_unit, si_display : optional
        The SI start value, unit and display unit where they are not the dimension's (a total
        quantity: an angle with its offset, the absolute torque).
    scaled_note, si_note : str
        Appended to the description in that unit system.
    **options
        Other fields of :class:`~drillstring_fmu_support.Variable` (``min``, ``max``,
        ``check``, ``depends_on``, ``items``, ``type_name``); ``si_check``: the check in SI
        where it is not ``check`` (a check in the terms of the scaled model's classes).
    """
    pair = (names, names) if isinstance(names, str) else names
    return Declared(
        pair[0], pair[1], type, causality, description, dimension, start, si_start, si_unit,
        si_display, scaled_note, si_note, options,
    )  # fmt: skip


def name_in(declared: Iterable[Declared], system: str, name: str) -> str:
    """The name in ``system`` of the variable called ``name`` in either system."""
    for d in declared:
        if name in (d.scaled, d.si):
            found = d.name(system)
            if found is None:
                raise KeyError(f"{name} has no variable in the {system} unit system")
            return found
    raise KeyError(name)


def from_table(
    table: Sequence[Parameter],
    starts: dict[str, Any],
    type_names: dict[str, str],
    checks: dict[str, Callable[[Any], Any]] | None = None,
    rename: dict[str, str] | None = None,
) -> list[Declared]:
    """Parameter declarations of a law's, a top drive's or a sensor's table
    (:class:`drillstring.model.tables.Parameter`): numbers as Reals of their dimension, choices as
    Enumerations of type ``type_names[name]`` (items: the choices, start: ``starts[name]``)."""
    out = []
    checks = checks or {}
    rename = rename or {}
    for p in table:
        name = rename.get(p.name, p.name)
        if p.choices:
            items = tuple((c, c) for c in p.choices)
            out.append(
                declare(name, "Enumeration", "parameter", p.description, start=starts[p.name],
                        items=items, type_name=type_names[p.name])
            )  # fmt: skip
            continue
        kw: dict[str, Any] = {}
        if p.lower is not None:
            kw["min"] = fmu.POSITIVE if (p.strict and p.lower == 0.0) else p.lower
        if p.name in checks:
            kw["check"] = checks[p.name]
        out.append(
            declare(name, "Real", "parameter", p.description, dimension=p.dimension,
                    start=float(starts[p.name]), **kw)
        )  # fmt: skip
    return out


def variables(declared: Iterable[Declared], system: str) -> tuple[fmu.Variable, ...]:
    """The variables of ``system``, in declaration order (absent ones left out)."""
    if system not in SYSTEMS:
        raise ValueError(f"unknown unit system {system!r} (known: {', '.join(SYSTEMS)})")
    declared = tuple(declared)
    out = []
    for d in declared:
        v = d.variable(system)
        if v is None:
            continue
        if v.depends_on:  # declared by either system's names
            deps = tuple(name_in(declared, system, name) for name in v.depends_on)
            v = dataclasses.replace(v, depends_on=deps)
        out.append(v)
    return tuple(out)
