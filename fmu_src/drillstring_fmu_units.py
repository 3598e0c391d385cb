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

from drillstring.model.tables import Parameter
from drillstring.model.units import DIMENSIONS, SCALED_UNITS, SI_UNITS, UNIT_SYSTEMS, UnitSystem

__all__ = [
    "SCALED",
    "SI",
    "Declared",
    "declare",
    "from_table",
    "name_in",
    "system",
    "variables",
]

SCALED = SCALED_UNITS.name
SI = SI_UNITS.name


def system(name: str) -> UnitSystem:
    """The unit system called ``name`` (a generated class's ``UNIT_SYSTEM``)."""
    if name not in UNIT_SYSTEMS:
        raise ValueError(f"unknown unit system {name!r} (known: {', '.join(UNIT_SYSTEMS)})")
    return UNIT_SYSTEMS[name]


@dataclass(frozen=True)
class Declared:
    """A variable declared once (see :func:`declare`): what is common to both unit systems,
    and per system (``own``, by its name) what is its own: ``name`` (None: absent there),
    ``start``, ``unit``, ``display``, ``note``, ``check``."""

    type: str
    causality: str
    description: str
    dimension: str = "1"
    start: Any = None
    own: dict[str, dict[str, Any]] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def scaled(self) -> str | None:
        """The name in the scaled system."""
        return self.own[SCALED]["name"]

    @property
    def si(self) -> str | None:
        """The name in SI."""
        return self.own[SI]["name"]

    def name(self, system: UnitSystem) -> str | None:
        """The variable's name in ``system`` (None: absent there)."""
        return self.own[system.name]["name"]

    @property
    def time_valued(self) -> bool:
        """Whether the variable is a time (a Real whose SI unit is the second)."""
        unit = self.own[SI].get("unit") or DIMENSIONS[self.dimension].unit
        return self.type == "Real" and unit == "s"

    def time_note(self, system: UnitSystem) -> str:
        """What a time-valued variable's description says of its unit (the system's
        :attr:`~drillstring.model.units.UnitSystem.time_note`); "" for any other variable."""
        return system.time_note if self.time_valued else ""

    def variable(self, system: UnitSystem) -> fmu.Variable | None:
        """The variable of ``system``, or None when it has no name there."""
        own = self.own[system.name]
        name = own["name"]
        if name is None:
            return None
        kw = dict(self.options)
        if "check" in own:
            kw["check"] = own["check"]
        description = f"{self.description}{own.get('note', '')}{self.time_note(system)}"
        start = own.get("start", self.start)
        if self.type == "Real":
            d = DIMENSIONS[self.dimension]
            unit = own.get("unit", d.unit)
            kw |= system.declared_unit(unit, own.get("display") if "unit" in own else d.display)
            factor = system.factor(self.dimension)
            if "start" not in own and start is not None:
                start = start * factor
            for bound in ("min", "max"):
                if kw.get(bound) not in (None, fmu.POSITIVE, 0.0):
                    kw[bound] = kw[bound] * factor
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
    si_check: Callable[[Any], Any] | None = None,
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
    si_check : callable, optional
        The check in SI where it is not ``check`` (a check in the terms of the scaled model's
        classes).
    **options
        Other fields of :class:`~drillstring_fmu_support.Variable` (``min``, ``max``,
        ``check``, ``depends_on``, ``items``, ``type_name``).
    """
    scaled, si = (names, names) if isinstance(names, str) else names
    own_si: dict[str, Any] = {"name": si, "note": si_note}
    for key, value in (("start", si_start), ("unit", si_unit), ("check", si_check)):
        if value is not None:
            own_si[key] = value
    if si_unit is not None:
        own_si["display"] = si_display
    own = {SCALED: {"name": scaled, "note": scaled_note}, SI: own_si}
    return Declared(type, causality, description, dimension, start, own, options)


def name_in(declared: Iterable[Declared], system: UnitSystem, name: str) -> str:
    """The name in ``system`` of the variable called ``name`` in either system."""
    for d in declared:
        if name in (d.scaled, d.si):
            found = d.name(system)
            if found is None:
                raise KeyError(f"{name} has no variable in the {system.name} unit system")
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


def variables(declared: Iterable[Declared], system: UnitSystem) -> tuple[fmu.Variable, ...]:
    """The variables of ``system``, in declaration order (absent ones left out)."""
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
