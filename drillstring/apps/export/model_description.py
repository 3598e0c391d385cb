"""Post-processing of the ``modelDescription.xml`` that pythonfmu writes, where it cannot express
the truth: each variable's causality, variability and initial; outputs ``initial="calculated"``
without start values, listed in ``InitialUnknowns``; the true ``ModelStructure`` (each
variable's ``depends_on``); ``min``/``max`` of every parameter with a range; Enumeration types
(``TypeDefinitions``); each Real's unit and display unit, with ``UnitDefinitions`` giving their
SI base-unit exponents (:data:`drillstring.model.units.UNITS`; "1" throughout the scaled FMUs);
the time base at the end of the FMU's ``description`` (:func:`time_base`: the scaled FMUs' numbers
of time are tau = t/t*, which their unit "1" cannot tell a tool; the SI FMUs' are seconds);
start values written exactly (17 digits); a GUID derived from the content; a pinned
``generationDateAndTime`` when ``SOURCE_DATE_EPOCH`` is set.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import uuid
from collections.abc import Sequence
from typing import Any
from xml.etree import ElementTree as ET

from drillstring.apps.export.specs import BuildError
from drillstring.model.units import BASE_UNITS, SCALED_TIME, UNITS

__all__ = [
    "fix_model_description",
    "format_bound",
    "format_start",
    "generation_time",
    "restore_generation_date",
    "scaled_time",
    "set_guid",
    "time_base",
    "type_attributes",
    "unit_definitions",
    "xml_bytes",
]

#: Attribute order of the type elements in the FMI 2.0 schema (kept for readability).
_ATTRIBUTE_ORDER = ("declaredType", "unit", "displayUnit", "min", "max", "start")
#: Namespace of the content-derived GUIDs.
_GUID_NAMESPACE = uuid.UUID("6f1c2a8e-1d5b-5d3e-9a7c-2b4f0e8d9c11")


def format_start(value: Any, kind: str) -> str:
    if kind == "Real":
        return repr(float(value))
    if kind == "Boolean":
        return "true" if value else "false"
    return str(int(value))


def format_bound(value: float, kind: str) -> str:
    return repr(float(value)) if kind == "Real" else str(int(value))


def scaled_time(variables: Sequence[Any]) -> bool:
    """Whether an FMU's numbers of time are the paper's scaled time tau rather than seconds.

    Parameters
    ----------
    variables : sequence of drillstring_fmu_support.Variable
        The FMU's variables.

    Returns
    -------
    bool
        True for the scaled FMUs (every Real of unit "1"); an SI FMU declares SI units.
    """
    return not any(v.type == "Real" and v.unit not in (None, "1") for v in variables)


def time_base(variables: Sequence[Any]) -> str:
    """The sentence on the FMU's time base that ends its model description's ``description``.

    FMI 2.0 (section 2.2.7) makes the time of an FMU without an independent variable a variable
    ``time`` in ``s``, so a tool shows the scaled FMUs' time as seconds; the sentence says what it
    is (t = t* tau, Section II of the paper).

    Parameters
    ----------
    variables : sequence of drillstring_fmu_support.Variable
        The FMU's variables (:func:`scaled_time` tells the unit system).

    Returns
    -------
    str
        The sentence.
    """
    if not scaled_time(variables):
        return (
            "Time base: seconds: the FMU's time, its default experiment, its step sizes and its "
            "time-valued variables are in s."
        )
    return (
        f"Time base: the {SCALED_TIME}, not seconds: the FMU's time, its default experiment, "
        "its step sizes and its time-valued variables are in tau, every rate is per unit of tau "
        "(FMI 2.0 gives this time no unit a tool can read: tools show it as s)."
    )


def type_attributes(var: Any, starts: dict[str, Any]) -> dict[str, str]:
    """What a variable's declaration says of its type, in the schema's order: declared type,
    unit and display unit (Reals), min and max, and the exact start value (not for outputs,
    which are ``calculated``). The same in FMI 2.0 (the type element) and FMI 3.0 (the variable).

    Parameters
    ----------
    var : drillstring_fmu_support.Variable
        The variable's declaration.
    starts : dict
        The start values by name.

    Returns
    -------
    dict
        Attribute -> text.
    """
    attrib: dict[str, str] = {}
    if var.type == "Enumeration":
        attrib["declaredType"] = var.type_name
    if var.type == "Real":
        attrib["unit"] = var.unit
        if var.display_unit is not None:
            attrib["displayUnit"] = var.display_unit
    if var.min is not None:
        attrib["min"] = format_bound(var.min, var.type)
    if var.max is not None:
        attrib["max"] = format_bound(var.max, var.type)
    if var.causality != "output":
        attrib["start"] = format_start(starts[var.name], var.type)
    return {k: attrib[k] for k in _ATTRIBUTE_ORDER if k in attrib}


def fix_model_description(root: ET.Element, variables: Sequence[Any], starts: dict[str, Any]):
    """Types, units, ranges, exact start values, the time base in the ``description`` and the
    true ModelStructure (module docstring)."""
    described = (root.get("description") or "").rstrip(". ")
    root.set(
        "description", f"{described}. {time_base(variables)}" if described else time_base(variables)
    )
    svs = list(root.find("ModelVariables") or [])
    index = {sv.get("name"): i + 1 for i, sv in enumerate(svs)}
    by_name = {v.name: v for v in variables}
    if set(index) != set(by_name):
        raise BuildError(f"variables {sorted(by_name)} but modelDescription has {sorted(index)}")
    enumerations: dict[str, Any] = {}
    for sv in svs:
        var = by_name[sv.get("name")]
        for child in list(sv):
            sv.remove(child)
        sv.set("causality", var.causality)
        sv.set("variability", var.variability)
        if var.initial is None:
            sv.attrib.pop("initial", None)
        else:
            sv.set("initial", var.initial)
        if var.type == "Enumeration":
            enumerations[var.type_name] = var
        ET.SubElement(sv, var.type, type_attributes(var, starts))

    position = list(root).index(root.find("CoSimulation")) + 1
    root.insert(position, unit_definitions(variables))
    if enumerations:
        types = ET.Element("TypeDefinitions")
        for name, var in sorted(enumerations.items()):
            simple = ET.SubElement(types, "SimpleType", name=name)
            enum = ET.SubElement(simple, "Enumeration")
            for i, (item, desc) in enumerate(var.items):
                ET.SubElement(enum, "Item", name=item, value=str(i + 1), description=desc)
        root.insert(position + 1, types)

    structure = root.find("ModelStructure")
    assert structure is not None
    for child in list(structure):
        structure.remove(child)
    outputs = [v for v in variables if v.causality == "output"]
    out_node = ET.SubElement(structure, "Outputs")
    for var in sorted(outputs, key=lambda v: index[v.name]):
        deps = [index[d] for d in var.depends_on]
        attrib = {"index": str(index[var.name]), "dependencies": " ".join(map(str, deps))}
        if deps:
            attrib["dependenciesKind"] = " ".join("dependent" for _ in deps)
        ET.SubElement(out_node, "Unknown", attrib)
    # initial="calculated": computed from the parameters (and inputs) in initialization mode; no
    # dependencies attribute = may depend on all of them
    node = ET.SubElement(structure, "InitialUnknowns")
    for var in sorted(outputs, key=lambda v: index[v.name]):
        ET.SubElement(node, "Unknown", index=str(index[var.name]))


def unit_definitions(variables: Sequence[Any]) -> ET.Element:
    """``UnitDefinitions`` of the units the Real variables use, with their ``BaseUnit``
    exponents and the display units they name (:data:`drillstring.model.units.UNITS`)."""
    used: dict[str, set[str]] = {}
    for var in variables:
        if var.type == "Real":
            if var.unit not in UNITS:
                raise BuildError(f"variable {var.name}: unit {var.unit!r} is not defined")
            shown = used.setdefault(var.unit, set())
            if var.display_unit is not None:
                UNITS[var.unit].display_unit(var.display_unit)  # raises if it is not defined
                shown.add(var.display_unit)
    node = ET.Element("UnitDefinitions")
    for name in sorted(used):
        unit = UNITS[name]
        elem = ET.SubElement(node, "Unit", name=name)
        exponents = {k: str(unit.exponents[k]) for k in BASE_UNITS if unit.exponents.get(k)}
        ET.SubElement(elem, "BaseUnit", exponents)
        for display in unit.display:
            if display.name in used[name]:
                attrib = {"name": display.name, "factor": repr(display.factor)}
                if display.offset:
                    attrib["offset"] = repr(display.offset)
                ET.SubElement(elem, "DisplayUnit", attrib)
    return node


def xml_bytes(root: ET.Element) -> bytes:
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def generation_time(source_date_epoch: int | None) -> str | None:
    if source_date_epoch is None:
        return None
    t = _dt.datetime.fromtimestamp(source_date_epoch, tz=_dt.UTC)
    return t.strftime("%Y-%m-%dT%H:%M:%SZ")


def restore_generation_date(root: ET.Element, generated: str | None) -> None:
    """Put back ``generationDateAndTime`` (taken out while a hash is computed, None: there was
    none) right after ``generationTool``, in the attribute order of the FMI schema's listing."""
    if generated is None:
        return
    attrib = dict(root.attrib)
    root.attrib.clear()
    for key, value in attrib.items():
        root.set(key, value)
        if key == "generationTool":
            root.set("generationDateAndTime", generated)


def set_guid(root: ET.Element, entries: dict[str, bytes], extra: bytes) -> None:
    """GUID from the model description (without GUID and date), the non-binary entries and
    ``extra`` (the front layer's sources and pythonfmu's library): the binaries are made from
    exactly these, and the front layer's binary contains the GUID, so it cannot be hashed."""
    generated = root.get("generationDateAndTime")
    root.set("guid", "")
    root.attrib.pop("generationDateAndTime", None)
    digest = hashlib.sha256(xml_bytes(root))
    for name in sorted(entries):
        if not name.startswith("binaries/"):
            digest.update(name.encode("utf-8") + b"\0" + hashlib.sha256(entries[name]).digest())
    digest.update(extra)
    root.set("guid", "{" + str(uuid.uuid5(_GUID_NAMESPACE, digest.hexdigest())) + "}")
    restore_generation_date(root, generated)
