"""The FMI 3.0 model description of an FMU's twin, from the same declaration of each variable
(``drillstring_fmu_support.Variable``) and the same start values as its FMI 2.0 one
(:mod:`drillstring.apps.export.model_description`), beside the final FMI 2.0 description for what
pythonfmu decided there (value references, the model's attributes, the log categories, the
default experiment).

FMI 3.0 names the types by their width (Real -> ``Float64``, Integer -> ``Int32``; an Enumeration
is an ``Enumeration`` of an ``EnumerationType``, accessed as Int64), lists ``Output`` and
``InitialUnknown`` by value reference, and wants exactly one independent variable: ``time``
(value reference after the slave's), whose unit states the time base a tool cannot read from an
FMI 2.0 FMU (s, or "1" for the scaled time tau). The ``instantiationToken`` is derived from the
FMI 2.0 GUID and this description's content. What FMI 2.0 cannot declare comes last: the slave's
array outputs (``ArrayOutput``, the plant's along-string profile), each a ``Float64`` with a
``Dimension`` that names the Integer parameter holding its length, which becomes a
``structuralParameter``.
"""

from __future__ import annotations

import copy
import hashlib
import re
import uuid
from collections.abc import Sequence
from types import SimpleNamespace
from typing import Any
from xml.etree import ElementTree as ET

from drillstring.apps.export.model_description import (
    restore_generation_date,
    scaled_time,
    time_base,
    type_attributes,
    unit_definitions,
    xml_bytes,
)
from drillstring.apps.export.specs import BuildError
from drillstring.model.units import SCALED_TIME

__all__ = [
    "FMI3_SUFFIX",
    "TIME_VARIABLE",
    "fmi3_model_description",
    "fmi3_model_identifier",
    "fmi3_words",
]

#: The FMI 3.0 twin of an FMU ``X`` is ``X3`` (``DrillStringPlant3.fmu``).
FMI3_SUFFIX = "3"
#: The name of the independent variable of every FMI 3.0 twin.
TIME_VARIABLE = "time"
#: The FMI 3.0 type element of each declared type.
_FMI3_TYPE = {
    "Real": "Float64",
    "Integer": "Int32",
    "Enumeration": "Enumeration",
    "Boolean": "Boolean",
}
#: Attribute order of the variable elements in the FMI 3.0 schema (kept for readability).
_ATTRIBUTE_ORDER = (
    "name",
    "valueReference",
    "description",
    "causality",
    "variability",
    "initial",
    "declaredType",
    "unit",
    "displayUnit",
    "min",
    "max",
    "start",
)
#: The root's attributes carried over from the FMI 2.0 description, in the FMI 3.0 schema's order.
_ROOT_ATTRIBUTES = (
    "modelName",
    "description",
    "author",
    "version",
    "copyright",
    "license",
    "generationTool",
    "generationDateAndTime",
    "variableNamingConvention",
)
#: Namespace of the instantiation tokens.
_TOKEN_NAMESPACE = uuid.UUID("3c8e51b2-7f0a-5d4e-8b19-0e6f2a9d4c73")


def fmi3_model_identifier(model: str) -> str:
    """The model identifier of the FMI 3.0 twin of the FMU ``model``."""
    return model + FMI3_SUFFIX


def _time_unit(variables: Sequence[Any]) -> str:
    return "1" if scaled_time(variables) else "s"


def _time_variable(variables: Sequence[Any], vr: int) -> ET.Element:
    scaled = scaled_time(variables)
    description = f"Time: the {SCALED_TIME}" if scaled else "Time in seconds"
    return ET.Element(
        "Float64",
        {
            "name": TIME_VARIABLE,
            "valueReference": str(vr),
            "description": description,
            "causality": "independent",
            "variability": "continuous",
            "unit": _time_unit(variables),
        },
    )


#: A status named in a declaration's text, as FMI 2.0 names it.
_FMI2_STATUS = re.compile(r"\bfmi2(OK|Warning|Discard|Error|Fatal)\b")


def fmi3_words(text: str) -> str:
    """A declaration's text in the twin's words: the status FMI 2.0 calls ``fmi2Discard`` is
    ``fmi3Discard`` (and so on) for the FMI 3.0 front, which returns that status for the same
    cause."""
    return _FMI2_STATUS.sub(r"fmi3\1", text)


def fmi3_model_description(
    fmi2_root: ET.Element,
    variables: Sequence[Any],
    starts: dict[str, Any],
    model: str,
    arrays: Sequence[Any] = (),
) -> ET.Element:
    """The FMI 3.0 co-simulation model description of the twin of the FMU ``fmi2_root`` describes.

    Parameters
    ----------
    fmi2_root : xml.etree.ElementTree.Element
        The final FMI 2.0 model description of the FMU (post-processed, with its GUID).
    variables : sequence of drillstring_fmu_support.Variable
        The FMU's variable declarations.
    starts : dict
        The start values by name (those of the FMI 2.0 description).
    model : str
        The twin's model identifier (:func:`fmi3_model_identifier`).
    arrays : sequence of drillstring_fmu_support.ArrayOutput
        The twin's array outputs (value references after ``time``'s). The Integer parameter
        that holds an array's length becomes a structural parameter, set in Configuration Mode:
        FMI 3.0 sizes an array only by a constant or by a structural parameter's value.

    Returns
    -------
    xml.etree.ElementTree.Element
        The root ``fmiModelDescription`` (``fmiVersion="3.0"``).

    Raises
    ------
    BuildError
        If the FMI 2.0 description does not declare exactly the variables given.
    """
    svs = list(fmi2_root.find("ModelVariables") or [])
    by_name = {v.name: v for v in variables}
    names = sorted(sv.get("name", "") for sv in svs)
    if set(names) != set(by_name):
        raise BuildError(f"variables {sorted(by_name)} but modelDescription has {names}")
    vr = {sv.get("name"): int(sv.get("valueReference", "-1")) for sv in svs}
    root = ET.Element("fmiModelDescription", fmiVersion="3.0")
    for key in _ROOT_ATTRIBUTES:
        if key == "description":
            root.set(key, _fmi3_time_base_description(fmi2_root, variables))
        elif fmi2_root.get(key) is not None:
            root.set(key, fmi2_root.get(key, ""))
        if key == "modelName":
            root.set("instantiationToken", "")
    cs2 = fmi2_root.find("CoSimulation")
    assert cs2 is not None
    ET.SubElement(
        root,
        "CoSimulation",
        {
            "modelIdentifier": model,
            "needsExecutionTool": cs2.get("needsExecutionTool", "false"),
            "canBeInstantiatedOnlyOncePerProcess": cs2.get(
                "canBeInstantiatedOnlyOncePerProcess", "false"
            ),
            "canGetAndSetFMUState": "true",
            "canSerializeFMUState": "true",
            "canHandleVariableCommunicationStepSize": cs2.get(
                "canHandleVariableCommunicationStepSize", "false"
            ),
            "hasEventMode": "false",
        },
    )
    time = SimpleNamespace(type="Real", unit=_time_unit(variables), display_unit=None)
    as_reals = [
        SimpleNamespace(type="Real", unit=a.unit, display_unit=a.display_unit) for a in arrays
    ]
    root.append(unit_definitions([*variables, time, *as_reals]))
    sizes = {a.size for a in arrays}
    if sizes - {v.name for v in variables if v.type == "Integer" and v.causality == "parameter"}:
        raise BuildError(f"array sizes {sorted(sizes)} must be Integer parameters")
    enumerations = {v.type_name: v for v in variables if v.type == "Enumeration"}
    if enumerations:
        types = ET.SubElement(root, "TypeDefinitions")
        for name, var in sorted(enumerations.items()):
            enum = ET.SubElement(types, "EnumerationType", name=name)
            for i, (item, desc) in enumerate(var.items):
                ET.SubElement(
                    enum, "Item", name=item, value=str(i + 1), description=fmi3_words(desc)
                )
    for tag in ("LogCategories", "DefaultExperiment"):
        node = fmi2_root.find(tag)
        if node is not None:
            node = copy.deepcopy(node)
            for element in node.iter():
                if element.get("description") is not None:
                    element.set("description", fmi3_words(element.get("description", "")))
            root.append(node)

    model_variables = ET.SubElement(root, "ModelVariables")
    time_vr = max(vr.values()) + 1
    model_variables.append(_time_variable(variables, time_vr))
    array_vr = {a.name: time_vr + 1 + j for j, a in enumerate(arrays)}
    for sv in sorted(svs, key=lambda e: vr[e.get("name", "")]):
        var = by_name[sv.get("name")]
        attrib = {
            "name": var.name,
            "valueReference": str(vr[var.name]),
            "causality": "structuralParameter" if var.name in sizes else var.causality,
            "variability": var.variability,
        }
        if sv.get("description") is not None:
            attrib["description"] = fmi3_words(sv.get("description", ""))
        if var.initial is not None:
            attrib["initial"] = var.initial
        attrib.update(type_attributes(var, starts))
        ordered = {k: attrib[k] for k in _ATTRIBUTE_ORDER if k in attrib}
        ET.SubElement(model_variables, _FMI3_TYPE[var.type], ordered)
    for a in arrays:
        attrib = {
            "name": a.name,
            "valueReference": str(array_vr[a.name]),
            "description": a.description,
            "causality": "output",
            "variability": "continuous",
            "initial": "calculated",
            "unit": a.unit,
        }
        if a.display_unit is not None:
            attrib["displayUnit"] = a.display_unit
        element = ET.SubElement(model_variables, "Float64", attrib)
        ET.SubElement(element, "Dimension", valueReference=str(vr[a.size]))

    structure = ET.SubElement(root, "ModelStructure")
    outputs = sorted((v for v in variables if v.causality == "output"), key=lambda v: vr[v.name])
    for var in outputs:
        deps = [str(vr[d]) for d in var.depends_on]
        attrib = {"valueReference": str(vr[var.name]), "dependencies": " ".join(deps)}
        if deps:
            attrib["dependenciesKind"] = " ".join("dependent" for _ in deps)
        ET.SubElement(structure, "Output", attrib)
    for a in arrays:  # the profile is the state's: no direct feedthrough
        ET.SubElement(structure, "Output", valueReference=str(array_vr[a.name]), dependencies="")
    # initial="calculated": computed in initialization mode; no dependencies attribute = may
    # depend on all the parameters and inputs
    for ref in [*(vr[v.name] for v in outputs), *array_vr.values()]:
        ET.SubElement(structure, "InitialUnknown", valueReference=str(ref))
    _set_token(root, fmi2_root.get("guid", ""))
    return root


def _fmi3_time_base_description(fmi2_root: ET.Element, variables: Sequence[Any]) -> str:
    """The FMI 2.0 description with its time-base sentence
    (:func:`~drillstring.apps.export.model_description.time_base`) as FMI 3.0 states it, with
    what FMI 3.0 adds: the unit of the independent variable ``time``."""
    described = fmi2_root.get("description") or ""
    old = time_base(variables)
    if old not in described:
        raise BuildError("the FMI 2.0 model description does not state its time base")
    cut = old.find(" (FMI 2.0 gives")
    # FMI 3.0 gives the scaled time a unit: the unit of the variable time
    new = old if cut < 0 else old[:cut] + ' (the unit of the variable time is "1").'
    return described.replace(old, new)


def _set_token(root: ET.Element, guid: str) -> None:
    """The instantiation token from the FMI 2.0 GUID (which covers the FMU's files) and this
    description without token and date."""
    generated = root.attrib.pop("generationDateAndTime", None)
    digest = hashlib.sha256(guid.encode("utf-8") + b"\0" + xml_bytes(root)).hexdigest()
    root.set("instantiationToken", "{" + str(uuid.uuid5(_TOKEN_NAMESPACE, digest)) + "}")
    restore_generation_date(root, generated)
