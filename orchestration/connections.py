"""System description for the co-simulation master: units, connections, validation.

A system is a list of :class:`Unit` (instance name -> FMU file + start values) and a
list of :class:`Connection` (``"unit.output" -> "unit.input"``). :func:`build_system`
checks them against the FMUs' model descriptions (FMI 2.0 standard, section 2.2) and
derives what the master needs before any FMU is instantiated: the direct dependencies of
the connected outputs on the connected inputs (``ModelStructure/Outputs``, FMI 2.0,
section 2.2.8; an output without a ``dependencies`` attribute depends on all inputs), and
from them the exchange schedule and the default Gauss-Seidel order (:mod:`.schedule`).

Units. Where both ends of a connection declare a unit (FMI 2.0 ``unit`` with its
``UnitDefinitions``), their definitions are compared, not their names: units of other factors
or offsets convert the value on the way (:func:`~drillstring.model.units.unit_conversion`: a
torque output in kN.m into an input in N.m is multiplied by 1000, and so is one from an FMU
that defines its "N.m" with factor 1000); units of different dimensions are refused, naming the
connection, both units and their dimensions. Where only one end declares a unit, the other's
values are in a unit nobody can check: the connection is refused, naming both ends, their FMUs
and the unit, unless that unit is dimensionless with factor 1 (``"1"``, the scaled FMUs'). A
connection made with ``convert_units=False`` (SSP's ``suppressUnitConversion="true"``) passes
values unchanged and is not checked: the explicit way to couple such ends.
"""

from __future__ import annotations

import zipfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fmpy import read_model_description

from drillstring.model.units import (
    BASE_UNITS,
    Conversion,
    UnitDef,
    UnitMismatch,
    unit_conversion,
)
from drillstring.orchestration.schedule import (
    ExchangeRound,
    exchange_schedule,
    gauss_seidel_order,
)

__all__ = [
    "read_fmu_description",
    "Unit",
    "Connection",
    "VarRef",
    "System",
    "build_system",
    "parse_connection",
    "declared_start_values",
    "effective_start_values",
    "StartValue",
    "unit_definitions",
    "variable_unit",
]

StartValue = float | int | bool | str

_SETTABLE_INITIAL = ("exact", "approx")


@dataclass(frozen=True)
class Unit:
    """One FMU instance in the system.

    Attributes
    ----------
    name : str
        Instance name (no dots: ``"unit.variable"`` is split at the first dot).
    fmu : str or Path
        Path of the ``.fmu`` file.
    start_values : mapping
        Variable name -> start value set before initialization (parameters, inputs,
        ``initial="exact"`` or ``"approx"`` variables), replacing the one the model
        description declares.
    description : fmpy ModelDescription, optional
        The FMU's model description where the caller has read it already (it is then not read
        again: :func:`build_system`, :func:`effective_start_values`).
    """

    name: str
    fmu: str | Path
    start_values: Mapping[str, StartValue] = field(default_factory=dict)
    description: Any = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or "." in self.name:
            raise ValueError(f"unit name must be a non-empty string without '.', got {self.name!r}")
        if not Path(self.fmu).is_file():
            raise ValueError(f"unit {self.name!r}: FMU file {str(self.fmu)!r} does not exist")


@dataclass(frozen=True)
class Connection:
    """``source`` (``"unit.output"``) feeds ``target`` (``"unit.input"``); the value is
    converted between the two FMUs' units unless ``convert_units`` is False (module
    docstring)."""

    source: str
    target: str
    convert_units: bool = True


def parse_connection(spec: Connection | tuple[str, str] | str) -> Connection:
    """A :class:`Connection` from any of the accepted spellings.

    Parameters
    ----------
    spec : Connection, (str, str) or str
        A :class:`Connection`, a ``(source, target)`` pair or ``"a.y -> b.u"``.

    Returns
    -------
    Connection
        The connection.

    Raises
    ------
    ValueError
        For any other form.
    """
    if isinstance(spec, Connection):
        return spec
    if isinstance(spec, str):
        parts = [p.strip() for p in spec.split("->")]
        if len(parts) != 2 or not all(parts):
            raise ValueError(f"connection {spec!r} is not of the form 'unit.output -> unit.input'")
        return Connection(parts[0], parts[1])
    if isinstance(spec, tuple) and len(spec) == 2 and all(isinstance(s, str) for s in spec):
        return Connection(spec[0], spec[1])
    raise ValueError(f"connection {spec!r}: expected 'a.y -> b.u', (source, target) or Connection")


@dataclass(frozen=True)
class VarRef:
    """A resolved variable: unit index, name, value reference, FMI type, causality,
    variability and initial (None when the model description gives none)."""

    unit: int
    name: str
    vr: int
    type: str
    causality: str
    variability: str
    initial: str | None


@dataclass(frozen=True)
class System:
    """A validated system: what the master needs to run it (see :func:`build_system`)."""

    units: tuple[Unit, ...]
    model_descriptions: tuple[Any, ...]
    variables: tuple[Mapping[str, VarRef], ...]
    connections: tuple[Connection, ...]
    #: connected outputs, "unit.var", each once, in unit then declaration order
    outputs: tuple[str, ...]
    #: connected inputs "unit.var" -> source output "unit.var"
    input_source: Mapping[str, str]
    schedule: tuple[ExchangeRound, ...]
    #: default Gauss-Seidel order (unit indices)
    gs_order: tuple[int, ...]
    #: unit index -> True if a connected output depends directly on a connected input
    feedthrough: tuple[bool, ...]
    #: connected input "unit.var" -> the conversion of its source's value into its unit
    #: (only the inputs whose source has another unit of the same dimension)
    conversions: Mapping[str, Conversion] = field(default_factory=dict)

    def resolve(self, key: str) -> VarRef:
        """The variable ``"unit.variable"``.

        Parameters
        ----------
        key : str
            ``"unit.variable"``.

        Returns
        -------
        VarRef
            The resolved variable.

        Raises
        ------
        ValueError
            Naming an unknown unit or variable.
        """
        return _resolve(self.units, self.variables, key)


def _resolve(units: Sequence[Unit], variables: Sequence[Mapping[str, VarRef]], key: str) -> VarRef:
    unit_name, var = _split(key)
    names = [u.name for u in units]
    if unit_name not in names:
        raise ValueError(f"unknown unit {unit_name!r} in {key!r}; units are {names}")
    try:
        return variables[names.index(unit_name)][var]
    except KeyError:
        raise ValueError(f"unit {unit_name!r} has no variable {var!r} (in {key!r})") from None


def _unit_from_mapping(name: str, spec: object) -> Unit:
    """``name -> Unit | fmu path | (fmu path, start values)``."""
    if isinstance(spec, Unit):
        if spec.name != name:
            raise ValueError(f"unit {spec.name!r} listed under the name {name!r}")
        return spec
    if isinstance(spec, str | Path):
        return Unit(name, spec)
    if isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[1], Mapping):
        return Unit(name, spec[0], spec[1])
    raise ValueError(
        f"unit {name!r}: expected a Unit, an FMU path or (FMU path, start values), got {spec!r}"
    )


def _split(key: str) -> tuple[str, str]:
    unit_name, _, var = key.partition(".") if isinstance(key, str) else ("", "", "")
    if not unit_name or not var:
        raise ValueError(f"variable {key!r} is not of the form 'unit.variable'")
    return unit_name, var


def read_fmu_description(what: str, fmu: str | Path, shown: str | None = None) -> Any:
    """The model description of an FMU file, or a ``ValueError`` naming ``what`` uses it.

    Parameters
    ----------
    what : str
        Who uses the FMU, as the message should name it (``"unit 'plant'"``, ``"component
        'plant'"``).
    fmu : path
        The FMU file.
    shown : str, optional
        How the message names the file (default: its path), e.g. its path in an SSP package.

    Returns
    -------
    fmpy.model_description.ModelDescription
        As ``fmpy.read_model_description`` returns it.

    Raises
    ------
    ValueError
        The file is missing, not a zip archive, has no readable ``modelDescription.xml``
        (fmpy raises ``BadZipFile``, ``KeyError``, XML errors or a plain ``Exception``).
    """
    try:
        return read_model_description(str(fmu))
    except Exception as exc:  # noqa: BLE001 -- fmpy's errors are of many kinds, re-raised named
        reason = "not a zip archive" if isinstance(exc, zipfile.BadZipFile) else str(exc)
        name = repr(str(fmu)) if shown is None else shown
        raise ValueError(f"{what}: {name} is not a readable FMU: {reason}") from exc


def _load(unit: Unit) -> tuple[Any, dict[str, Any]]:
    md = unit.description
    if md is None:
        md = read_fmu_description(f"unit {unit.name!r}", unit.fmu)
    if md.fmiVersion != "2.0":
        raise ValueError(f"unit {unit.name!r}: FMI version {md.fmiVersion!r}, need 2.0")
    if md.coSimulation is None:
        raise ValueError(f"unit {unit.name!r}: {unit.fmu} has no CoSimulation interface")
    return md, {v.name: v for v in md.modelVariables}


def _check_start_value(unit: Unit, var: VarRef, value: object) -> None:
    settable = var.causality in ("parameter", "input") or (
        var.initial in _SETTABLE_INITIAL and var.causality != "independent"
    )
    if var.variability == "constant" or not settable:
        raise ValueError(
            f"unit {unit.name!r}: cannot set a start value for {var.name!r} "
            f"(causality {var.causality!r}, variability {var.variability!r}, "
            f"initial {var.initial!r})"
        )
    ok = {
        "Real": isinstance(value, int | float) and not isinstance(value, bool),
        "Integer": isinstance(value, int) and not isinstance(value, bool),
        "Enumeration": isinstance(value, int) and not isinstance(value, bool),
        "Boolean": isinstance(value, bool),
        "String": isinstance(value, str),
    }.get(var.type, False)
    if not ok:
        raise ValueError(
            f"unit {unit.name!r}: start value {value!r} for {var.name!r} does not fit its "
            f"type {var.type}"
        )


def variable_unit(var: Any) -> str | None:
    """The unit of an fmpy ScalarVariable: its own, else its declared type's (FMI 2.0, 2.2.3).

    Parameters
    ----------
    var : fmpy ScalarVariable
        A variable of a model description.

    Returns
    -------
    str or None
        The unit name, None when neither declares one.
    """
    if var.unit is not None:
        return var.unit
    declared = getattr(var, "declaredType", None)
    return getattr(declared, "unit", None)


def unit_definitions(model_description: Any) -> dict[str, UnitDef]:
    """The ``UnitDefinitions`` of a model description (FMI 2.0, section 2.2.2) as UnitDefs.

    Parameters
    ----------
    model_description : fmpy ModelDescription
        As returned by ``fmpy.read_model_description``.

    Returns
    -------
    dict
        Unit name -> :class:`~drillstring.model.units.UnitDef` (base-unit exponents, factor,
        offset; a unit without ``BaseUnit`` is dimensionless with factor 1).
    """
    out = {}
    for u in model_description.unitDefinitions:
        b = u.baseUnit
        if b is None:
            out[u.name] = UnitDef(u.name)
            continue
        exps = {k: int(getattr(b, k)) for k in BASE_UNITS if int(getattr(b, k))}
        out[u.name] = UnitDef(u.name, exps, factor=float(b.factor), offset=float(b.offset))
    return out


def _plain_number(unit: UnitDef) -> bool:
    """A dimensionless unit of factor 1 and offset 0 (``"1"``): a value without one is in it."""
    return not any(unit.exponents.values()) and unit.factor == 1.0 and unit.offset == 0.0


def _conversion(
    label: str,
    ends: tuple[str, str],
    src: Any,
    dst: Any,
    src_units: Mapping[str, UnitDef],
    dst_units: Mapping[str, UnitDef],
) -> Conversion | None:
    """The conversion of a connection from the FMUs' unit definitions (module docstring), None
    for none; ``ends`` names the source and the target with their FMUs (fmpy's reader has
    checked that every unit a variable names is defined)."""
    a, b = variable_unit(src), variable_unit(dst)
    if a is None and b is None:
        return None
    if a is None or b is None:
        declared = src_units[a] if a is not None else dst_units[b]
        if _plain_number(declared):
            return None
        bare, other = (ends[0], ends[1]) if a is None else (ends[1], ends[0])
        raise ValueError(
            f"{label}: {other} is in {declared.name!r} (dimension {declared.dimension}), "
            f"{bare} declares no unit, so its values cannot be checked or converted; declare "
            "the unit in its model description, or pass the values unchanged on purpose with "
            'suppressUnitConversion="true" on the SSD\'s connection '
            "(Connection(..., convert_units=False))"
        )
    ua, ub = src_units[a], dst_units[b]
    same_name = " (one name, two definitions)" if a == b else ""
    try:
        conv = unit_conversion(ua, ub)
    except UnitMismatch:
        raise ValueError(
            f"{label}: the source's unit {a!r} (dimension {ua.dimension}) and the target's unit "
            f"{b!r} (dimension {ub.dimension}) are of different dimensions{same_name}: not "
            "convertible"
        ) from None
    return None if conv.identity else conv


def build_system(
    units: Sequence[Unit] | Mapping[str, Unit | str | Path | tuple[str | Path, Mapping]],
    connections: Iterable[Connection | tuple[str, str] | str],
    gs_order: Sequence[str] | None = None,
) -> System:
    """Validate units and connections against the model descriptions.

    Parameters
    ----------
    units : sequence of Unit, or mapping
        The units, or name -> :class:`Unit`, FMU path or (FMU path, start values).
    connections : iterable
        ``"a.y -> b.u"`` strings, ``(source, target)`` pairs or :class:`Connection`.
    gs_order : sequence of str, optional
        Unit names in Gauss-Seidel order (default: from the declared dependencies).

    Returns
    -------
    System
        What the master needs to run the system.

    Raises
    ------
    ValueError
        Naming the offending unit, variable or connection for: duplicate unit names,
        unknown units or variables, a source that is not an output, a target that is not
        an input, non-Real connections, an input connected twice, unsettable or ill-typed
        start values, an algebraic loop, a bad ``gs_order``, connected units of different
        dimensions, a connection of which only one end declares a unit (not ``"1"``) and
        ``convert_units`` is True (module docstring).
    """
    if isinstance(units, Mapping):
        units = [_unit_from_mapping(name, spec) for name, spec in units.items()]
    units = tuple(units)
    if not units:
        raise ValueError("a system needs at least one unit")
    names = tuple(u.name for u in units)
    for name in names:
        if names.count(name) > 1:
            raise ValueError(f"unit name {name!r} is used more than once")

    mds, variables, mvars_of, unit_defs = [], [], [], []
    for i, unit in enumerate(units):
        md, mvars = _load(unit)
        mvars_of.append(mvars)
        unit_defs.append(unit_definitions(md))
        refs = {
            n: VarRef(i, n, v.valueReference, v.type, v.causality, v.variability, v.initial)
            for n, v in mvars.items()
        }
        for vname, value in unit.start_values.items():
            if vname not in refs:
                raise ValueError(f"unit {unit.name!r} has no variable {vname!r} (start values)")
            _check_start_value(unit, refs[vname], value)
        mds.append(md)
        variables.append(refs)

    conns = tuple(parse_connection(c) for c in connections)
    input_source: dict[str, str] = {}
    conversions: dict[str, Conversion] = {}
    for c in conns:
        label = f"connection '{c.source} -> {c.target}'"
        src, dst = _resolve(units, variables, c.source), _resolve(units, variables, c.target)
        if src.causality != "output":
            raise ValueError(
                f"{label}: source {c.source!r} has causality {src.causality!r}, expected 'output'"
            )
        if dst.causality != "input":
            raise ValueError(
                f"{label}: target {c.target!r} has causality {dst.causality!r}, expected 'input'"
            )
        if src.type != "Real" or dst.type != "Real":
            raise ValueError(
                f"{label}: only Real -> Real connections are supported "
                f"(got {src.type} -> {dst.type})"
            )
        if c.target in input_source:
            raise ValueError(
                f"input {c.target!r} is connected twice: from {input_source[c.target]!r} "
                f"and from {c.source!r}"
            )
        input_source[c.target] = c.source
        if c.convert_units:
            ends = (
                f"{c.source!r} of {Path(units[src.unit].fmu).name}",
                f"{c.target!r} of {Path(units[dst.unit].fmu).name}",
            )
            conv = _conversion(
                label,
                ends,
                mvars_of[src.unit][src.name],
                mvars_of[dst.unit][dst.name],
                unit_defs[src.unit],
                unit_defs[dst.unit],
            )
            if conv is not None:
                conversions[c.target] = conv

    # connected outputs, in unit and declaration order
    used = set(input_source.values())
    outputs = tuple(
        f"{u.name}.{v.name}"
        for u, md in zip(units, mds, strict=True)
        for v in md.modelVariables
        if f"{u.name}.{v.name}" in used
    )

    # direct dependencies of each connected output on connected inputs (FMI 2.0, 2.2.8)
    connected_inputs = [[k for k in input_source if k.split(".", 1)[0] == u.name] for u in units]
    deps: dict[str, set[str]] = {}
    for i, (u, md) in enumerate(zip(units, mds, strict=True)):
        declared = {o.variable.name: o.dependencies for o in md.outputs}
        for key in outputs:
            if key.split(".", 1)[0] != u.name:
                continue
            d = declared.get(key.split(".", 1)[1])
            own = set(connected_inputs[i])
            # an absent attribute (or an output missing from ModelStructure): all of them
            deps[key] = own if d is None else own & {f"{u.name}.{v.name}" for v in d}
    feedthrough = tuple(
        any(deps[k] for k in outputs if k.split(".", 1)[0] == u.name) for u in units
    )

    schedule = exchange_schedule(names, outputs, deps, input_source)
    order = gauss_seidel_order(names, outputs, deps, input_source, feedthrough, gs_order)
    return System(
        units=units,
        model_descriptions=tuple(mds),
        variables=tuple(variables),
        connections=conns,
        outputs=outputs,
        input_source=input_source,
        schedule=schedule,
        gs_order=order,
        feedthrough=feedthrough,
        conversions=conversions,
    )


def _typed_start(var: Any) -> StartValue:
    """A model description's start string as a value of the variable's FMI type."""
    if var.type == "Real":
        return float(var.start)
    if var.type in ("Integer", "Enumeration"):
        return int(var.start)
    if var.type == "Boolean":
        return var.start in ("true", "1")
    return str(var.start)


def declared_start_values(model_description: Any) -> dict[str, StartValue]:
    """The start values a model description declares, typed (FMI 2.0, section 2.2.7).

    Parameters
    ----------
    model_description : fmpy ModelDescription
        As returned by ``fmpy.read_model_description``.

    Returns
    -------
    dict
        Variable name -> start value (float, int, bool or str) of every variable with a
        ``start`` attribute.
    """
    return {
        v.name: _typed_start(v) for v in model_description.modelVariables if v.start is not None
    }


def effective_start_values(unit: Unit) -> dict[str, StartValue]:
    """The start values a unit begins with: the FMU's declared ones, replaced by the unit's own.

    Parameters
    ----------
    unit : Unit
        The unit (its FMU's model description is read unless the unit carries it).

    Returns
    -------
    dict
        Variable name -> start value.

    Raises
    ------
    ValueError
        If the unit sets a variable the FMU does not have.
    """
    md, _ = _load(unit)
    values = declared_start_values(md)
    unknown = sorted(set(unit.start_values) - {v.name for v in md.modelVariables})
    if unknown:
        raise ValueError(f"unit {unit.name!r} has no variable(s) {unknown} (start values)")
    values.update(unit.start_values)
    return values
