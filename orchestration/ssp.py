"""SSP 1.0 packages (System Structure and Parameterization): write, validate and read them.

An SSP package is a zip archive (``.ssp``) or a folder holding ``SystemStructure.ssd`` (the
system: components, their connectors and parameter bindings, the connections, the units, the
default experiment), optionally further ``.ssd`` files at its root (variants, each with a name
of its own; SSP 1.0, "System Structure Package": ``SystemStructure.ssd`` is the default
variant, a tool that knows no variants uses only it), the FMUs it references and its parameter
sets (``.ssv`` files) under ``resources/``, and documentation under ``documentation/`` (entry
``documentation/index.html``). This module writes packages with lxml (:func:`write_ssp`), checks
them against the SSP 1.0 schemas that fmpy ships (:func:`validate_ssp`: every root SSD, every
``.ssv``, the references, distinct variant names) and reads one SSD of a package back for the
master (:func:`read_ssp`; see :meth:`drillstring.orchestration.master.Master.from_ssp`).

Parameter bindings. SSP 1.0 applies every ParameterBinding of a component, in document order,
later ones taking priority; :meth:`SspPackage.parameters` with ``parameter_set=None`` does that.
The co-simulation tools read bindings otherwise: Ecos applies only the set whose
``ssv:ParameterSet`` has the name given by ``--parameterSet`` (none without it), libcosim the
first binding of each component, fmpy's ``simulate_ssp`` none. A package whose every SSD binds
one set per component, named after the SSD, means the same experiment in all of them (given
the set's name in Ecos); naming sets explicitly (``parameter_set=["fig6"]``) applies those sets
of the package, in the order asked, as Ecos's ``--parameterSet`` does. Enumeration parameters
are written as ``ssv:Integer`` (FMI 2.0 sets an Enumeration with ``fmi2SetInteger``; libcosim
and Ecos read no ``ssv:Enumeration``).

Units. A parameter's unit is resolved to its definition (``ssc:Unit`` with ``ssc:BaseUnit``
exponents, factor and offset) in its ``.ssv``'s ``ssv:Units``, else the SSD's ``ssd:Units``
(:attr:`SspParameter.unit_def`); the master converts the value into the FMU variable's unit.

The fixed-step annotation of the default experiment is the Open Simulation Platform's
(``com.opensimulationplatform``: ``osp:Algorithm/osp:FixedStepAlgorithm baseStepSize``), which
libcosim reads; the master reads it too (:attr:`SspPackage.step`).
"""

from __future__ import annotations

import functools
import os
import shutil
import tempfile
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import fmpy
from lxml import etree

from drillstring.fileio import write_zip
from drillstring.model.units import BASE_UNITS, UnitDef

__all__ = [
    "MAX_DESCRIPTION_BYTES",
    "MAX_MEMBERS",
    "MAX_MEMBER_BYTES",
    "MAX_UNPACKED_BYTES",
    "SSD_FILE",
    "NS",
    "SspComponent",
    "SspConnection",
    "SspConnector",
    "SspError",
    "SspPackage",
    "SspParameter",
    "SspVariant",
    "read_ssp",
    "validate_ssp",
    "write_ssp",
]

SSD_FILE = "SystemStructure.ssd"
DOC_INDEX = "documentation/index.html"
#: Limits on an archive, checked from its central directory before any member is read or
#: extracted: a small archive can declare gigabytes (a 4 MB package with a 3 GiB member). The
#: project's largest package, self-contained, holds two FMUs of 97 MiB (191 MiB in all).
MAX_MEMBER_BYTES = 1 << 30  # 1 GiB unpacked, per member
MAX_UNPACKED_BYTES = 4 << 30  # 4 GiB unpacked, the whole package
MAX_MEMBERS = 10_000
#: The descriptions read into memory (``.ssd``, ``.ssv``): each at most 16 MiB (the project's
#: are a few kB); of the other members only the names are read before extraction.
MAX_DESCRIPTION_BYTES = 16 << 20
_DESCRIPTIONS = (".ssd", ".ssv")
#: The namespaces, with the prefixes the tools expect (libcosim and Ecos match element names
#: with their prefixes, ``ssd:Component``, ``osp:Algorithm``).
NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
}
OSP_ANNOTATION = "com.opensimulationplatform"
FMU_TYPE = "application/x-fmu-sharedlibrary"
_SCHEMA_DIR = Path(fmpy.__file__).parent / "ssp" / "schema"
_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")


class SspError(ValueError):
    """An SSP package that is invalid, or that the master cannot run as it stands."""


def _q(prefix: str, tag: str) -> str:
    return f"{{{NS[prefix]}}}{tag}"


# ------------------------------------------------------------------------------------------------
# the description
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SspConnector:
    """A connector of a component: an FMU variable exposed to connections (``kind`` input or
    output), with its type and unit."""

    name: str
    kind: str
    type: str = "Real"
    unit: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("input", "output", "parameter", "calculatedParameter", "inout"):
            raise SspError(f"connector {self.name!r}: unknown kind {self.kind!r}")
        if self.type not in _TYPES:
            raise SspError(f"connector {self.name!r}: unknown type {self.type!r}")


@dataclass(frozen=True)
class SspParameter:
    """One parameter of a parameter set: FMU variable name, SSV type, value, unit (name and,
    when read, definition)."""

    name: str
    type: str
    value: Any
    unit: str | None = None
    #: the definition of ``unit`` that the ``.ssv`` or the ``.ssd`` gives (set by
    #: :func:`read_ssp`; None when the unit is not defined there, or for a parameter written)
    unit_def: UnitDef | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if self.type not in _TYPES:
            raise SspError(f"parameter {self.name!r}: unknown type {self.type!r}")

    def text(self) -> str:
        """The value as the ``value`` attribute of its ``ssv:<type>`` element.

        Returns
        -------
        str
            ``repr`` of the float for Real, ``"true"``/``"false"`` for Boolean, the ``int`` for
            Integer, else ``str(value)``.
        """
        if self.type == "Real":
            return repr(float(self.value))
        if self.type == "Boolean":
            return "true" if self.value else "false"
        if self.type == "Integer":
            return str(int(self.value))
        return str(self.value)


@dataclass(frozen=True)
class SspComponent:
    """An FMU component: instance name, source (path in the package), connectors and its
    parameter sets by name, in binding order."""

    name: str
    source: str
    connectors: tuple[SspConnector, ...]
    parameter_sets: Mapping[str, tuple[SspParameter, ...]] = field(default_factory=dict)


@dataclass(frozen=True)
class SspConnection:
    """``start_element.start_connector`` feeds ``end_element.end_connector``; with
    ``suppress_unit_conversion`` (SSP's ``suppressUnitConversion``) the value passes unconverted
    even where the two ends have different units."""

    start_element: str
    start_connector: str
    end_element: str
    end_connector: str
    suppress_unit_conversion: bool = False

    def __str__(self) -> str:
        return (
            f"{self.start_element}.{self.start_connector} -> "
            f"{self.end_element}.{self.end_connector}"
        )


@dataclass(frozen=True)
class SspVariant:
    """A further SSD of a package, at its root: a variant of the system (module docstring).

    Attributes
    ----------
    file : str
        Its file name in the package root (``"<name>.ssd"``; not ``SystemStructure.ssd``).
    name : str
        The ``name`` of its ``SystemStructureDescription``, distinct from every other SSD's.
    components : tuple of SspComponent
        Its components with their bindings (the FMUs are the package's).
    connections : tuple of SspConnection
        Its connections.
    default_experiment : (start, stop, step) or None
        Its default experiment.
    description : str
        Description of its system.
    """

    file: str
    name: str
    components: tuple[SspComponent, ...]
    connections: tuple[SspConnection, ...]
    default_experiment: tuple[float, float, float] | None = None
    description: str = ""

    def __post_init__(self) -> None:
        if "/" in self.file or not self.file.endswith(".ssd") or self.file == SSD_FILE:
            raise SspError(
                f"variant {self.name!r}: file {self.file!r} must be a .ssd at the package root "
                f"other than {SSD_FILE}"
            )


# ------------------------------------------------------------------------------------------------
# writing
# ------------------------------------------------------------------------------------------------


def _units_element(parent_tag: str, units: Mapping[str, UnitDef]) -> etree._Element:
    node = etree.Element(parent_tag)
    for name in sorted(units):
        unit = units[name]
        u = etree.SubElement(node, _q("ssc", "Unit"), name=name)
        attrib = {k: str(unit.exponents[k]) for k in BASE_UNITS if unit.exponents.get(k)}
        if unit.factor != 1.0:
            attrib["factor"] = repr(float(unit.factor))
        if unit.offset != 0.0:
            attrib["offset"] = repr(float(unit.offset))
        etree.SubElement(u, _q("ssc", "BaseUnit"), attrib)
    return node


def _read_units(node: etree._Element | None) -> dict[str, UnitDef]:
    """``ssc:Unit`` children of an ``ssd:Units`` or ``ssv:Units`` element as UnitDefs."""
    out: dict[str, UnitDef] = {}
    if node is None:
        return out
    for u in node.iterfind("ssc:Unit", NS):
        base = u.find("ssc:BaseUnit", NS)
        attrib = base.attrib if base is not None else {}
        try:
            out[u.get("name")] = UnitDef(
                u.get("name"),
                {k: int(attrib[k]) for k in BASE_UNITS if int(attrib.get(k, 0))},
                factor=float(attrib.get("factor", 1.0)),
                offset=float(attrib.get("offset", 0.0)),
            )
        except ValueError as exc:
            raise SspError(f"unit {u.get('name')!r}: {exc}") from None
    return out


def ssv_document(
    name: str, parameters: Sequence[SspParameter], units: Mapping[str, UnitDef]
) -> bytes:
    """The ``.ssv`` file of one parameter set (with the definitions of the units it uses).

    Parameters
    ----------
    name : str
        Name of the ``ssv:ParameterSet``.
    parameters : sequence of SspParameter
        Its parameters, in order; an Enumeration is written as ``ssv:Integer``, a unit only for
        a Real.
    units : mapping
        Unit name -> UnitDef, at least the units the Real parameters name.

    Returns
    -------
    bytes
        The UTF-8 XML document, with declaration (not validated here).

    Raises
    ------
    KeyError
        A Real parameter names a unit missing from ``units``.
    """
    root = etree.Element(
        _q("ssv", "ParameterSet"),
        nsmap={k: NS[k] for k in ("ssv", "ssc")},
        version="1.0",
        name=name,
    )
    params = etree.SubElement(root, _q("ssv", "Parameters"))
    used: dict[str, UnitDef] = {}
    for p in parameters:
        elem = etree.SubElement(params, _q("ssv", "Parameter"), name=p.name)
        # an Enumeration is written as its Integer item value (module docstring)
        kind = "Integer" if p.type == "Enumeration" else p.type
        attrib = {"value": p.text()}
        if p.unit is not None and p.type == "Real":
            attrib["unit"] = p.unit
            used[p.unit] = units[p.unit]
        etree.SubElement(elem, _q("ssv", kind), attrib)
    if used:
        root.append(_units_element(_q("ssv", "Units"), used))
    return _xml_bytes(root)


def ssd_document(
    name: str,
    components: Sequence[SspComponent],
    connections: Sequence[SspConnection],
    units: Mapping[str, UnitDef],
    sources: Mapping[tuple[str, str], str],
    default_experiment: tuple[float, float, float] | None,
    description: str = "",
    system: str | None = None,
) -> bytes:
    """An SSD document of a package (``SystemStructure.ssd`` or a variant).

    Parameters
    ----------
    name : str
        Name of the system structure (and of its system, unless ``system`` is given).
    components : sequence of SspComponent
        The components, their connectors (Enumerations as ``ssc:Integer``) and parameter
        bindings in the order of ``parameter_sets``.
    connections : sequence of SspConnection
        The connections.
    units : mapping
        Unit name -> UnitDef, at least the units the Real connectors name.
    sources : mapping
        (component name, set name) -> path of its ``.ssv`` in the package.
    default_experiment : (start, stop, step) or None
        ``ssd:DefaultExperiment`` with the OSP fixed-step annotation (module docstring).
    description : str
        Description of the system (omitted when empty).
    system : str, optional
        Name of the system (default ``name``).

    Returns
    -------
    bytes
        The UTF-8 XML document, with declaration (not validated here).

    Raises
    ------
    KeyError
        A bound set has no entry in ``sources``, or a connector's unit is missing from
        ``units``.
    """
    root = etree.Element(
        _q("ssd", "SystemStructureDescription"),
        nsmap={k: NS[k] for k in ("ssd", "ssc", "ssv", "osp")},
        version="1.0",
        name=name,
        generationTool="drillstring build_fmus.py",
    )
    sys_node = etree.SubElement(root, _q("ssd", "System"), name=system or name)
    if description:
        sys_node.set("description", description)
    elements = etree.SubElement(sys_node, _q("ssd", "Elements"))
    used: set[str] = set()
    for comp in components:
        c = etree.SubElement(
            elements, _q("ssd", "Component"), name=comp.name, type=FMU_TYPE, source=comp.source
        )
        conns = etree.SubElement(c, _q("ssd", "Connectors"))
        for con in comp.connectors:
            k = etree.SubElement(conns, _q("ssd", "Connector"), name=con.name, kind=con.kind)
            attrib = {}
            if con.unit is not None and con.type == "Real":
                attrib["unit"] = con.unit
                used.add(con.unit)
            # Enumerations are connected as their Integer values (libcosim knows no ssc:Enumeration)
            etree.SubElement(
                k, _q("ssc", "Integer" if con.type == "Enumeration" else con.type), attrib
            )
        if comp.parameter_sets:
            bindings = etree.SubElement(c, _q("ssd", "ParameterBindings"))
            for set_name in comp.parameter_sets:
                src = sources[(comp.name, set_name)]
                etree.SubElement(bindings, _q("ssd", "ParameterBinding"), source=src)
    links = etree.SubElement(sys_node, _q("ssd", "Connections"))
    for con in connections:
        link = etree.SubElement(
            links,
            _q("ssd", "Connection"),
            startElement=con.start_element,
            startConnector=con.start_connector,
            endElement=con.end_element,
            endConnector=con.end_connector,
        )
        if con.suppress_unit_conversion:
            link.set("suppressUnitConversion", "true")
    if used:
        root.append(_units_element(_q("ssd", "Units"), {u: units[u] for u in used}))
    if default_experiment is not None:
        start, stop, step = default_experiment
        de = etree.SubElement(
            root, _q("ssd", "DefaultExperiment"), startTime=repr(start), stopTime=repr(stop)
        )
        ann = etree.SubElement(
            etree.SubElement(de, _q("ssd", "Annotations")), _q("ssc", "Annotation")
        )
        ann.set("type", OSP_ANNOTATION)
        algorithm = etree.SubElement(ann, _q("osp", "Algorithm"))
        etree.SubElement(algorithm, _q("osp", "FixedStepAlgorithm"), baseStepSize=repr(step))
    return _xml_bytes(root)


def _xml_bytes(root: etree._Element) -> bytes:
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def _ssv_path(component: str, set_name: str) -> str:
    return f"resources/{set_name}.{component}.ssv"


def write_ssp(
    path: str | os.PathLike[str],
    *,
    name: str,
    components: Sequence[SspComponent],
    fmus: Mapping[str, str | os.PathLike[str]],
    connections: Sequence[SspConnection],
    units: Mapping[str, UnitDef],
    default_experiment: tuple[float, float, float] | None = None,
    description: str = "",
    system: str | None = None,
    variants: Sequence[SspVariant] = (),
    documentation: Mapping[str, str | bytes] | None = None,
    source_date_epoch: int | None = None,
) -> Path:
    """Write an SSP 1.0 archive, validated against the schemas, atomically.

    Parameters
    ----------
    path : path
        The ``.ssp`` file to write.
    name : str
        Name of the system structure ``SystemStructure.ssd`` (the default variant).
    components : sequence of SspComponent
        Its components; each ``source`` is the path of its FMU in the archive
        (``resources/<file>.fmu``), each parameter set becomes ``resources/<set>.<component>.ssv``
        bound to the component, in the order of ``parameter_sets``.
    fmus : mapping
        Component name -> the FMU file to put at its ``source``.
    connections : sequence of SspConnection
        Output -> input connections between the components' connectors.
    units : mapping
        The unit definitions (at least those the connectors and parameters name).
    default_experiment : (start, stop, step), optional
        ``ssd:DefaultExperiment`` with the fixed-step annotation (module docstring).
    description : str
        Description of the system.
    system : str, optional
        Name of the system in every SSD (default ``name``).
    variants : sequence of SspVariant
        Further SSDs at the root; their components' sources must be among ``components``'
        and a set of one name bound to one component must be the same in every SSD (it is
        one ``.ssv`` file).
    documentation : mapping, optional
        Path under ``documentation/`` -> content (text is written as UTF-8); must hold
        ``index.html`` (SSP 1.0: the documentation's entry point).
    source_date_epoch : int, optional
        Timestamp of the archive's entries (default: the earliest a zip file holds), so that
        the archive is reproducible.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    SspError
        If the documents do not validate, naming the file and the schema's messages; a set
        bound with different values in two SSDs; documentation without ``index.html``.
    """
    path = Path(path)
    entries: dict[str, bytes] = {}
    sources: dict[tuple[str, str], str] = {}
    written: dict[str, tuple[SspParameter, ...]] = {}
    for comp in components:
        entries[comp.source] = Path(fmus[comp.name]).read_bytes()
    ssds = [(SSD_FILE, name, components, connections, default_experiment, description)]
    ssds += [
        (v.file, v.name, v.components, v.connections, v.default_experiment, v.description)
        for v in variants
    ]
    for label, ssd_name, comps, links, experiment, text in ssds:
        if label in entries:
            raise SspError(f"{path.name}: two SSDs named {label}")
        for comp in comps:
            if comp.source not in entries:
                raise SspError(
                    f"{path.name}: {label}: component {comp.name!r} has source "
                    f"{comp.source!r}, which is no FMU of the package"
                )
            for set_name, params in comp.parameter_sets.items():
                src = _ssv_path(comp.name, set_name)
                if src in written and written[src] != tuple(params):
                    raise SspError(
                        f"{path.name}: parameter set {set_name!r} of component {comp.name!r} is "
                        "bound with different values in two SSDs (one .ssv file per set)"
                    )
                written[src] = tuple(params)
                sources[(comp.name, set_name)] = src
                entries[src] = ssv_document(set_name, params, units)
        entries[label] = ssd_document(
            ssd_name, comps, links, units, sources, experiment, text, system or name
        )
    if documentation:
        if "index.html" not in documentation:
            raise SspError(f"{path.name}: documentation without index.html (SSP 1.0)")
        for rel, content in documentation.items():
            data = content.encode("utf-8") if isinstance(content, str) else bytes(content)
            entries[f"documentation/{rel}"] = data
    problems = _validate_entries(entries)
    if problems:
        raise SspError(f"{path.name}: " + "; ".join(problems))
    return write_zip(path, entries, source_date_epoch)


# ------------------------------------------------------------------------------------------------
# validation
# ------------------------------------------------------------------------------------------------


@functools.cache
def _schema(name: str) -> etree.XMLSchema:
    return etree.XMLSchema(etree.parse(str(_SCHEMA_DIR / name)))


def _schema_problems(label: str, data: bytes, schema: str) -> list[str]:
    try:
        doc = etree.fromstring(data)
    except etree.XMLSyntaxError as exc:
        return [f"{label}: not well-formed XML: {exc}"]
    s = _schema(schema)
    if s.validate(doc):
        return []
    return [f"{label} (line {e.line}): {e.message}" for e in s.error_log]


def _root_ssds(entries: Mapping[str, bytes]) -> list[str]:
    """The SSD files at the root of a package, ``SystemStructure.ssd`` first."""
    others = sorted(n for n in entries if "/" not in n and n.endswith(".ssd") and n != SSD_FILE)
    return ([SSD_FILE] if SSD_FILE in entries else []) + others


def _validate_entries(entries: Mapping[str, bytes]) -> list[str]:
    if SSD_FILE not in entries:
        return [f"no {SSD_FILE}"]
    ssds = _root_ssds(entries)
    problems = []
    for name in ssds:
        problems += _schema_problems(name, entries[name], "SystemStructureDescription.xsd")
    for name in sorted(entries):
        if name.endswith(".ssv"):
            problems += _schema_problems(name, entries[name], "SystemStructureParameterValues.xsd")
    if problems:
        return problems
    seen: dict[str, str] = {}
    for file in ssds:
        ssd = etree.fromstring(entries[file])
        label = "" if file == SSD_FILE else f"{file}: "
        other = seen.setdefault(ssd.get("name"), file)
        if other != file:
            problems.append(
                f"{file} and {other} have the same name {ssd.get('name')!r} (SSP 1.0: every "
                "root SSD of a package has its own)"
            )
        for comp in ssd.iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
            refs = [comp.get("source")]
            refs += [b.get("source") for b in comp.iterfind("ssd:ParameterBindings/*", NS)]
            problems += [
                f"{label}component {comp.get('name')!r}: {ref} is not in the package"
                for ref in refs
                if ref is not None and ref not in entries
            ]
        problems += _system_problems(ssd, label)
    docs = [n for n in entries if n.startswith("documentation/")]
    if docs and DOC_INDEX not in entries:
        problems.append(f"documentation/ without its entry point {DOC_INDEX} (SSP 1.0)")
    return problems


def _system_problems(ssd: etree._Element, label: str) -> list[str]:
    """What the schema cannot see in an SSD's system: two elements of one name, a connection
    to an element or connector the system does not declare, a connector's unit that the SSD's
    ``ssd:Units`` do not define (SSP 1.0: a connector's unit refers to them)."""
    system = ssd.find("ssd:System", NS)
    defined = {u.get("name") for u in ssd.iterfind("ssd:Units/ssc:Unit", NS)}
    problems = []

    def connectors(element: etree._Element, what: str) -> set[str]:
        names = set()
        for k in element.iterfind("ssd:Connectors/ssd:Connector", NS):
            names.add(k.get("name"))
            for typ in k:
                unit = typ.get("unit") if etree.QName(typ).namespace == NS["ssc"] else None
                if unit is not None and unit not in defined:
                    problems.append(
                        f"{label}{what}: connector {k.get('name')!r} is in unit {unit!r}, which "
                        "the SSD's Units do not define"
                    )
        return names

    own = connectors(system, f"system {system.get('name')!r}")
    elements: dict[str, set[str]] = {}
    for element in system.iterfind("ssd:Elements/*", NS):
        name = element.get("name")
        kind = etree.QName(element).localname.lower()
        if name in elements:
            problems.append(
                f"{label}two elements of the system are named {name!r} (SSP 1.0: each element "
                "of a system has a name of its own)"
            )
        elements.setdefault(name, set()).update(connectors(element, f"{kind} {name!r}"))
    for e in system.iterfind("ssd:Connections/ssd:Connection", NS):
        con = (
            f"{e.get('startElement') or '<system>'}.{e.get('startConnector')} -> "
            f"{e.get('endElement') or '<system>'}.{e.get('endConnector')}"
        )
        for end in ("start", "end"):
            element, connector = e.get(f"{end}Element"), e.get(f"{end}Connector")
            if element is not None and element not in elements:
                problems.append(f"{label}connection {con}: the system has no element {element!r}")
            elif connector not in (own if element is None else elements[element]):
                whose = "the system" if element is None else f"component {element!r}"
                problems.append(
                    f"{label}connection {con}: {whose} declares no connector {connector!r}"
                )
    return problems


def _package_entries(path: Path) -> dict[str, bytes]:
    """Member name -> content for the descriptions (``.ssd``, ``.ssv``), ``b""`` for the other
    members (FMUs, documentation: only their names are needed to validate the package). An
    archive's directory is checked against the limits first (:func:`_check_archive`)."""
    if path.is_dir():
        entries = {}
        for p in sorted(path.rglob("*")):
            if p.is_file():
                name = p.relative_to(path).as_posix()
                entries[name] = b""
                if name.endswith(_DESCRIPTIONS):
                    _check_description(path.name, name, p.stat().st_size)
                    entries[name] = p.read_bytes()
        return entries
    try:
        with zipfile.ZipFile(path) as z:
            _check_archive(z, path.name)
            return {
                i.filename: z.read(i.filename) if i.filename.endswith(_DESCRIPTIONS) else b""
                for i in z.infolist()
                if not i.is_dir()
            }
    except (zipfile.BadZipFile, OSError) as exc:
        raise SspError(f"{path}: not an SSP archive ({exc})") from None


def _check_description(label: str, name: str, size: int) -> None:
    if size > MAX_DESCRIPTION_BYTES:
        raise SspError(
            f"{label}: {name!r} is {size} bytes, more than the limit of {MAX_DESCRIPTION_BYTES} "
            "bytes for a description (.ssd, .ssv)"
        )


def _check_archive(z: zipfile.ZipFile, label: str) -> None:
    """Refuse an archive whose directory declares more than the limits allow: too many
    members, a member or all of them together unpacking to more bytes (a member whose data
    is longer than declared fails its CRC on extraction: zipfile stops at the declared size)."""
    infos = z.infolist()
    if len(infos) > MAX_MEMBERS:
        raise SspError(f"{label}: {len(infos)} members, more than the limit of {MAX_MEMBERS}")
    total = 0
    for info in infos:
        size = info.file_size
        if size > MAX_MEMBER_BYTES:
            raise SspError(
                f"{label}: member {info.filename!r} unpacks to {size} bytes ({size / 2**20:.0f} "
                f"MiB), more than the limit of {MAX_MEMBER_BYTES} bytes per member; nothing "
                "was extracted"
            )
        if info.filename.endswith(_DESCRIPTIONS):
            _check_description(label, info.filename, size)
        total += size
        if total > MAX_UNPACKED_BYTES:
            raise SspError(
                f"{label}: unpacked, the members up to {info.filename!r} take {total} bytes "
                f"({total / 2**20:.0f} MiB), more than the limit of {MAX_UNPACKED_BYTES} bytes "
                "for a package; nothing was extracted"
            )


def validate_ssp(path: str | os.PathLike[str]) -> list[str]:
    """The problems of an SSP package against the SSP 1.0 schemas and its own references.

    The schemas are those fmpy ships (``SystemStructureDescription.xsd``,
    ``SystemStructureParameterValues.xsd``), for every SSD at the root and every ``.ssv``; the
    references: every FMU and ``.ssv`` an SSD names is in the package; the SSDs' names are
    distinct; each system's elements have distinct names, its connections join connectors
    its elements declare, its connectors' units are defined in the SSD's ``ssd:Units``;
    ``documentation/`` has its ``index.html``.

    Parameters
    ----------
    path : path
        An ``.ssp`` archive, a folder, or an ``.ssd`` in a folder (the folder's package).

    Returns
    -------
    list of str
        One message per problem, naming the file (and line for a schema error); ``[]`` for a
        valid package, ``["<path> does not exist"]`` for a missing path.

    Raises
    ------
    SspError
        ``path`` is a file that is not a readable zip archive.
    """
    path = Path(path)
    if not path.exists():
        return [f"{path} does not exist"]
    if path.is_file() and path.suffix == ".ssd":
        path = path.parent
    return _validate_entries(_package_entries(path))


# ------------------------------------------------------------------------------------------------
# reading
# ------------------------------------------------------------------------------------------------


def _parameter_value(kind: str, text: str) -> Any:
    if kind == "Real":
        return float(text)
    if kind == "Integer":
        return int(text)
    if kind == "Boolean":
        if text not in ("true", "false", "1", "0"):
            raise SspError(f"Boolean value {text!r} is not true, false, 1 or 0")
        return text in ("true", "1")
    return text


def _read_ssv(
    root: etree._Element, label: str, outer_units: Mapping[str, UnitDef]
) -> tuple[str, tuple[SspParameter, ...]]:
    """An ``ssv:ParameterSet``: its name and parameters, units resolved in its own
    ``ssv:Units``, else ``outer_units`` (the SSD's)."""
    units = {**outer_units, **_read_units(root.find("ssv:Units", NS))}
    params = []
    for p in root.iterfind("ssv:Parameters/ssv:Parameter", NS):
        value = next(iter(p), None)
        if value is None:
            raise SspError(f"{label}: parameter {p.get('name')!r} has no value")
        kind = etree.QName(value).localname
        if kind not in _TYPES:
            raise SspError(f"{label}: parameter {p.get('name')!r} of type {kind} is not supported")
        unit = value.get("unit")
        params.append(
            SspParameter(
                p.get("name"),
                kind,
                _parameter_value(kind, value.get("value")),
                unit,
                units.get(unit) if unit is not None else None,
            )
        )
    return root.get("name"), tuple(params)


@dataclass(frozen=True)
class SspPackage:
    """One SSD of an SSP package, read by :func:`read_ssp`.

    Attributes
    ----------
    path : Path
        The archive, folder or ``.ssd`` file given.
    root : Path
        The folder its files are in (the folder itself, or where the archive was unpacked).
    name : str
        The name of the SSD read (its ``SystemStructureDescription``).
    components : tuple of SspComponent
        Its FMU components, with their parameter bindings in document order.
    connections : tuple of SspConnection
        Its connections.
    units : dict
        Unit name -> :class:`~drillstring.model.units.UnitDef` (its ``ssd:Units``).
    start_time, stop_time, step : float or None
        Its default experiment and fixed step (OSP annotation), where given.
    file : str
        The SSD's file name in the package (``SystemStructure.ssd`` or a variant's).
    system : str
        The name of its system.
    description : str
        The system's description.
    variants : dict
        Every SSD at the package's root: name -> file name, ``SystemStructure.ssd`` first.
    sets : dict
        Every parameter set any SSD of the package binds: set name -> component -> its
        parameters (what :meth:`parameters` applies by name).
    documentation : tuple of str
        The package's files under ``documentation/``.
    """

    path: Path
    root: Path
    name: str
    components: tuple[SspComponent, ...]
    connections: tuple[SspConnection, ...]
    units: Mapping[str, UnitDef]
    start_time: float | None = None
    stop_time: float | None = None
    step: float | None = None
    file: str = SSD_FILE
    system: str = ""
    description: str = ""
    variants: Mapping[str, str] = field(default_factory=dict)
    sets: Mapping[str, Mapping[str, tuple[SspParameter, ...]]] = field(default_factory=dict)
    documentation: tuple[str, ...] = ()

    @property
    def bound_sets(self) -> tuple[str, ...]:
        """The names of the sets this SSD binds, in the order they are first bound."""
        names: dict[str, None] = {}
        for comp in self.components:
            names.update(dict.fromkeys(comp.parameter_sets))
        return tuple(names)

    def component(self, name: str) -> SspComponent:
        """The component called ``name``.

        Parameters
        ----------
        name : str
            The component's instance name.

        Returns
        -------
        SspComponent
            The first component of that name.

        Raises
        ------
        SspError
            No component has that name (the message lists the components).
        """
        for comp in self.components:
            if comp.name == name:
                return comp
        known = ", ".join(c.name for c in self.components)
        raise SspError(f"{self.path.name}: no component {name!r} (components: {known})")

    def fmu(self, name: str) -> Path:
        """The FMU file of component ``name``.

        Parameters
        ----------
        name : str
            The component's instance name.

        Returns
        -------
        Path
            ``root / source`` of the component (in the folder or the unpacked archive).

        Raises
        ------
        SspError
            No component has that name.
        """
        return self.root / self.component(name).source

    def parameters(
        self, parameter_set: str | Sequence[str] | None = None
    ) -> dict[str, dict[str, SspParameter]]:
        """Component -> variable -> the parameter that sets it (module docstring).

        Parameters
        ----------
        parameter_set : str, sequence of str or None
            None: this SSD's bindings, every binding of a component in document order, a later
            one overriding an earlier one's values (SSP 1.0). A name or names: those sets of
            the package (:attr:`sets`, whichever SSD binds them), applied in the order given;
            ``()``: none (the FMUs' start values).

        Returns
        -------
        dict
            Every component's name -> {variable name: SspParameter}; empty dicts for
            components nothing binds.

        Raises
        ------
        SspError
            A name that no SSD of the package binds (the message lists the sets and the
            variants), a set that binds a component this SSD does not have, or
            ``parameter_set`` is not a name or a sequence of names.
        """
        out: dict[str, dict[str, SspParameter]] = {c.name: {} for c in self.components}
        if parameter_set is None:
            for comp in self.components:
                for params in comp.parameter_sets.values():
                    out[comp.name].update((p.name, p) for p in params)
            return out
        names = _set_names(parameter_set)
        for n in names:
            if n not in self.sets:
                raise SspError(
                    f"{self.path.name}: no parameter set {n!r} (sets: "
                    f"{', '.join(self.sets) or 'none'}; variants: {', '.join(self.variants)})"
                )
            for comp, params in self.sets[n].items():
                if comp not in out:
                    raise SspError(
                        f"{self.path.name}: parameter set {n!r} binds component {comp!r}, which "
                        f"{self.file} does not have"
                    )
                out[comp].update((p.name, p) for p in params)
        return out

    def start_values(
        self, parameter_set: str | Sequence[str] | None = None
    ) -> dict[str, dict[str, tuple[str, Any]]]:
        """Component -> variable -> (SSV type, value) of :meth:`parameters`, as given (in the
        parameters' own units; the master converts them into the FMUs').

        Parameters
        ----------
        parameter_set : str, sequence of str or None
            As for :meth:`parameters`.

        Returns
        -------
        dict
            Every component's name -> {variable name: (SSV type, value)}.

        Raises
        ------
        SspError
            As :meth:`parameters`.
        """
        return {
            c: {n: (p.type, p.value) for n, p in params.items()}
            for c, params in self.parameters(parameter_set).items()
        }


def _set_names(parameter_set: str | Sequence[str]) -> tuple[str, ...]:
    if isinstance(parameter_set, str):
        return (parameter_set,)
    names = tuple(parameter_set)
    if not all(isinstance(n, str) for n in names):
        raise SspError(
            f"parameter_set must be a name or a sequence of names, got {parameter_set!r}"
        )
    return names


def _parse_ssd(data: bytes, file: str, entries: Mapping[str, bytes], label: str) -> dict[str, Any]:
    """One SSD of a package: what :class:`SspPackage` holds of it (see :func:`read_ssp`)."""
    ssd = etree.fromstring(data)
    system = ssd.find("ssd:System", NS)
    if system.find("ssd:Elements/ssd:System", NS) is not None:
        raise SspError(f"{label}: {file}: nested systems are not supported by the master")
    units = _read_units(ssd.find("ssd:Units", NS))
    components = []
    for c in system.iterfind("ssd:Elements/ssd:Component", NS):
        if c.get("type", FMU_TYPE) != FMU_TYPE:
            raise SspError(f"{label}: component {c.get('name')!r} is not an FMU ({c.get('type')})")
        connectors = []
        for k in c.iterfind("ssd:Connectors/ssd:Connector", NS):
            typ = next((e for e in k if etree.QName(e).namespace == NS["ssc"]), None)
            kind = etree.QName(typ).localname if typ is not None else "Real"
            unit = typ.get("unit") if typ is not None else None
            connectors.append(SspConnector(k.get("name"), k.get("kind"), kind, unit))
        sets: dict[str, tuple[SspParameter, ...]] = {}
        for b in c.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            if (src := b.get("source")) is not None:
                set_name, params = _read_ssv(etree.fromstring(entries[src]), src, units)
            else:
                inline = b.find("ssd:ParameterValues/ssv:ParameterSet", NS)
                if inline is None:
                    continue
                set_name, params = _read_ssv(inline, f"{file}: {c.get('name')} binding", units)
            sets[set_name] = sets.get(set_name, ()) + params
        components.append(SspComponent(c.get("name"), c.get("source"), tuple(connectors), sets))
    connections = []
    for e in system.iterfind("ssd:Connections/ssd:Connection", NS):
        con = SspConnection(
            e.get("startElement"),
            e.get("startConnector"),
            e.get("endElement"),
            e.get("endConnector"),
            e.get("suppressUnitConversion") in ("true", "1"),
        )
        if con.start_element is None or con.end_element is None:
            raise SspError(f"{label}: connection {con} uses a connector of the system itself")
        if any(etree.QName(x).localname.endswith("Transformation") for x in e):
            raise SspError(f"{label}: connection {con} has a transformation; not supported")
        connections.append(con)
    start = stop = step = None
    de = ssd.find("ssd:DefaultExperiment", NS)
    if de is not None:
        start = float(de.get("startTime")) if de.get("startTime") is not None else None
        stop = float(de.get("stopTime")) if de.get("stopTime") is not None else None
        for ann in de.iterfind("ssd:Annotations/ssc:Annotation", NS):
            fixed = ann.find("osp:Algorithm/osp:FixedStepAlgorithm", NS)
            if ann.get("type") == OSP_ANNOTATION and fixed is not None:
                step = float(fixed.get("baseStepSize"))
    return dict(
        name=ssd.get("name"),
        components=tuple(components),
        connections=tuple(connections),
        units=units,
        start_time=start,
        stop_time=stop,
        step=step,
        file=file,
        system=system.get("name"),
        description=system.get("description") or "",
    )


def read_ssp(
    path: str | os.PathLike[str],
    unpack_to: str | os.PathLike[str] | None = None,
    *,
    unpack: bool = True,
    variant: str | None = None,
) -> SspPackage:
    """Read one SSD of an SSP 1.0 package (archive or folder), validated like
    :func:`validate_ssp`.

    Parameters
    ----------
    path : path
        The ``.ssp`` archive, a folder with ``SystemStructure.ssd``, or an ``.ssd`` file in
        such a folder (that SSD is read, as a tool opening it does).
    unpack_to : path, optional
        Folder an archive is unpacked into (default: a new temporary folder, which the caller
        owns; :meth:`Master.from_ssp` removes it with the master).
    unpack : bool
        False: read the description only (an archive is not unpacked; :attr:`SspPackage.root`
        is then the archive and :meth:`SspPackage.fmu` names no file).
    variant : str, optional
        The SSD to read, by its name or its file name with or without ``.ssd`` (default:
        ``SystemStructure.ssd``, or the ``.ssd`` given as ``path``).

    Returns
    -------
    SspPackage
        The SSD, with the names of all the package's SSDs and sets.

    Raises
    ------
    SspError
        An invalid package (naming the schema's messages), an unknown variant (naming the
        package's), a hierarchy of systems, a component that is not an FMU, or a connection
        with a transformation (which the master does not apply).
    """
    path = Path(path)
    if not path.exists():
        raise SspError(f"SSP package {str(path)!r} does not exist")
    given = path
    chosen = None
    if path.is_file() and path.suffix == ".ssd":
        chosen = path.name
        path = path.parent
    entries = _package_entries(path)
    problems = _validate_entries(entries)
    if problems:
        raise SspError(f"{path.name} is not a valid SSP 1.0 package: " + "; ".join(problems))
    names = {etree.fromstring(entries[f]).get("name"): f for f in _root_ssds(entries)}
    if variant is not None:
        files = set(names.values())
        asked = names.get(variant) or next(
            (f for f in (variant, f"{variant}.ssd") if f in files), None
        )
        if asked is None:
            listing = ", ".join(f"{n} ({f})" for n, f in names.items())
            raise SspError(f"{path.name}: no variant {variant!r} (variants: {listing})")
        if chosen is not None and asked != chosen:
            raise SspError(f"{given} is not the variant {variant!r} ({asked}) asked for")
        chosen = asked
    chosen = chosen or SSD_FILE
    parsed = {f: _parse_ssd(entries[f], f, entries, path.name) for f in names.values()}
    sets: dict[str, dict[str, tuple[SspParameter, ...]]] = {}
    for ssd in parsed.values():
        for comp in ssd["components"]:
            for set_name, params in comp.parameter_sets.items():
                sets.setdefault(set_name, {}).setdefault(comp.name, params)
    if path.is_dir() or not unpack:
        root = path
    else:
        root = Path(unpack_to) if unpack_to is not None else Path(tempfile.mkdtemp(prefix="ssp_"))
        root.mkdir(parents=True, exist_ok=True)
        try:
            with zipfile.ZipFile(path) as z:
                _check_archive(z, path.name)  # the archive read above may have been replaced
                z.extractall(root)
        except Exception as exc:
            if unpack_to is None:
                shutil.rmtree(root, ignore_errors=True)
            if isinstance(exc, zipfile.BadZipFile):  # "Bad CRC-32 for file 'resources/...'"
                raise SspError(f"{path.name}: cannot be unpacked: {exc}") from None
            raise
    return SspPackage(
        path=given,
        root=root,
        variants=names,
        sets=sets,
        documentation=tuple(sorted(n for n in entries if n.startswith("documentation/"))),
        **parsed[chosen],
    )
