"""SSP 1.0 packages (System Structure and Parameterization): write, validate and read them.

An SSP package is a zip archive (``.ssp``) or a folder holding ``SystemStructure.ssd`` (the
system: components, their connectors and parameter bindings, the connections, the units, the
default experiment), the FMUs it references and its parameter sets (``.ssv`` files). This module
writes packages with lxml (:func:`write_ssp`), checks them against the SSP 1.0 schemas that fmpy
ships (:func:`validate_ssp`) and reads them back for the master (:func:`read_ssp`; see
:meth:`drillstring.orchestration.master.Master.from_ssp`).

Parameter sets. SSP 1.0 binds parameter sources to a component (``ssd:ParameterBinding``); its
text applies every binding of a component in document order, later ones taking priority. The
co-simulation tools that select a named set instead read each binding as one named alternative:
Ecos applies the set whose ``ssv:ParameterSet`` has the name given by ``--parameterSet`` to every
component that binds it, libcosim applies the first binding of each component. The packages
written here follow the tools: every binding of a component is its own ``.ssv`` file with the
set's name, and :meth:`SspPackage.start_values` applies the named sets asked for, in the order
asked. Enumeration parameters are written as ``ssv:Integer`` (FMI 2.0 sets an Enumeration with
``fmi2SetInteger``; libcosim and Ecos read no ``ssv:Enumeration``).

The fixed-step annotation of the default experiment is the Open Simulation Platform's
(``com.opensimulationplatform``: ``osp:Algorithm/osp:FixedStepAlgorithm baseStepSize``), which
libcosim reads; the master reads it too (:attr:`SspPackage.step`).
"""

from __future__ import annotations

import datetime as _dt
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

from drillstring.model.units import BASE_UNITS, UnitDef

__all__ = [
    "SSD_FILE",
    "NS",
    "SspComponent",
    "SspConnection",
    "SspConnector",
    "SspError",
    "SspPackage",
    "SspParameter",
    "read_ssp",
    "validate_ssp",
    "write_ssp",
]

SSD_FILE = "SystemStructure.ssd"
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
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)
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
    """One parameter of a parameter set: FMU variable name, SSV type, value, unit."""

    name: str
    type: str
    value: Any
    unit: str | None = None

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
    """``start_element.start_connector`` feeds ``end_element.end_connector``."""

    start_element: str
    start_connector: str
    end_element: str
    end_connector: str

    def __str__(self) -> str:
        return (
            f"{self.start_element}.{self.start_connector} -> "
            f"{self.end_element}.{self.end_connector}"
        )


# ------------------------------------------------------------------------------------------------
# writing
# ------------------------------------------------------------------------------------------------


def _units_element(parent_tag: str, units: Mapping[str, UnitDef]) -> etree._Element:
    node = etree.Element(parent_tag)
    for name in sorted(units):
        unit = units[name]
        u = etree.SubElement(node, _q("ssc", "Unit"), name=name)
        exps = {k: str(unit.exponents[k]) for k in BASE_UNITS if unit.exponents.get(k)}
        etree.SubElement(u, _q("ssc", "BaseUnit"), exps)
    return node


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
) -> bytes:
    """The ``SystemStructure.ssd`` document of a package.

    Parameters
    ----------
    name : str
        Name of the system structure and of its system.
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
    system = etree.SubElement(root, _q("ssd", "System"), name=name)
    if description:
        system.set("description", description)
    elements = etree.SubElement(system, _q("ssd", "Elements"))
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
                etree.SubElement(
                    bindings,
                    _q("ssd", "ParameterBinding"),
                    source=sources[(comp.name, set_name)],
                )
    links = etree.SubElement(system, _q("ssd", "Connections"))
    for con in connections:
        etree.SubElement(
            links,
            _q("ssd", "Connection"),
            startElement=con.start_element,
            startConnector=con.start_connector,
            endElement=con.end_element,
            endConnector=con.end_connector,
        )
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
    source_date_epoch: int | None = None,
) -> Path:
    """Write an SSP 1.0 archive, validated against the schemas, atomically.

    Parameters
    ----------
    path : path
        The ``.ssp`` file to write.
    name : str
        Name of the system structure and of its system.
    components : sequence of SspComponent
        The components; each ``source`` is the path of its FMU in the archive
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
        If the documents do not validate, naming the file and the schema's messages.
    """
    path = Path(path)
    entries: dict[str, bytes] = {}
    sources: dict[tuple[str, str], str] = {}
    for comp in components:
        entries[comp.source] = Path(fmus[comp.name]).read_bytes()
        for set_name, params in comp.parameter_sets.items():
            src = _ssv_path(comp.name, set_name)
            sources[(comp.name, set_name)] = src
            entries[src] = ssv_document(set_name, params, units)
    entries[SSD_FILE] = ssd_document(
        name, components, connections, units, sources, default_experiment, description
    )
    problems = _validate_entries(entries)
    if problems:
        raise SspError(f"{path.name}: " + "; ".join(problems))
    date_time = _ZIP_EPOCH
    if source_date_epoch is not None:
        t = _dt.datetime.fromtimestamp(max(source_date_epoch, 315532800), tz=_dt.UTC)
        date_time = (t.year, t.month, t.day, t.hour, t.minute, t.second)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    with zipfile.ZipFile(tmp, "w") as z:
        for entry in sorted(entries):
            info = zipfile.ZipInfo(entry, date_time=date_time)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            info.create_system = 3
            z.writestr(info, entries[entry])
    tmp.replace(path)
    return path


# ------------------------------------------------------------------------------------------------
# validation
# ------------------------------------------------------------------------------------------------

_SCHEMAS: dict[str, etree.XMLSchema] = {}


def _schema(name: str) -> etree.XMLSchema:
    if name not in _SCHEMAS:
        _SCHEMAS[name] = etree.XMLSchema(etree.parse(str(_SCHEMA_DIR / name)))
    return _SCHEMAS[name]


def _schema_problems(label: str, data: bytes, schema: str) -> list[str]:
    try:
        doc = etree.fromstring(data)
    except etree.XMLSyntaxError as exc:
        return [f"{label}: not well-formed XML: {exc}"]
    s = _schema(schema)
    if s.validate(doc):
        return []
    return [f"{label} (line {e.line}): {e.message}" for e in s.error_log]


def _validate_entries(entries: Mapping[str, bytes]) -> list[str]:
    if SSD_FILE not in entries:
        return [f"no {SSD_FILE}"]
    problems = _schema_problems(SSD_FILE, entries[SSD_FILE], "SystemStructureDescription.xsd")
    for name in sorted(entries):
        if name.endswith(".ssv"):
            problems += _schema_problems(name, entries[name], "SystemStructureParameterValues.xsd")
    if problems:
        return problems
    ssd = etree.fromstring(entries[SSD_FILE])
    for comp in ssd.iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
        refs = [comp.get("source")]
        refs += [b.get("source") for b in comp.iterfind("ssd:ParameterBindings/*", NS)]
        problems += [
            f"component {comp.get('name')!r}: {ref} is not in the package"
            for ref in refs
            if ref is not None and ref not in entries
        ]
    return problems


def _package_entries(path: Path) -> dict[str, bytes]:
    if path.is_dir():
        return {
            p.relative_to(path).as_posix(): p.read_bytes()
            for p in sorted(path.rglob("*"))
            if p.is_file()
        }
    try:
        with zipfile.ZipFile(path) as z:
            return {i.filename: z.read(i.filename) for i in z.infolist() if not i.is_dir()}
    except (zipfile.BadZipFile, OSError) as exc:
        raise SspError(f"{path}: not an SSP archive ({exc})") from None


def validate_ssp(path: str | os.PathLike[str]) -> list[str]:
    """The problems of an SSP package against the SSP 1.0 schemas and its own references.

    The schemas are those fmpy ships (``SystemStructureDescription.xsd``,
    ``SystemStructureParameterValues.xsd``); the references: every FMU and ``.ssv`` the
    ``.ssd`` names is in the package.

    Parameters
    ----------
    path : path
        An ``.ssp`` archive or a folder.

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


def _read_ssv(data: bytes, label: str) -> tuple[str, tuple[SspParameter, ...]]:
    root = etree.fromstring(data)
    params = []
    for p in root.iterfind("ssv:Parameters/ssv:Parameter", NS):
        value = next(iter(p), None)
        if value is None:
            raise SspError(f"{label}: parameter {p.get('name')!r} has no value")
        kind = etree.QName(value).localname
        if kind not in _TYPES:
            raise SspError(f"{label}: parameter {p.get('name')!r} of type {kind} is not supported")
        params.append(
            SspParameter(
                p.get("name"), kind, _parameter_value(kind, value.get("value")), value.get("unit")
            )
        )
    return root.get("name"), tuple(params)


@dataclass(frozen=True)
class SspPackage:
    """An SSP package read by :func:`read_ssp`.

    Attributes
    ----------
    path : Path
        The archive or folder.
    root : Path
        The folder its files are in (the folder itself, or where the archive was unpacked).
    name : str
        The system structure's name.
    components : tuple of SspComponent
        The FMU components.
    connections : tuple of SspConnection
        The connections.
    units : dict
        Unit name -> base-unit exponents (``ssd:Units``).
    start_time, stop_time, step : float or None
        The default experiment and its fixed step (OSP annotation), where given.
    """

    path: Path
    root: Path
    name: str
    components: tuple[SspComponent, ...]
    connections: tuple[SspConnection, ...]
    units: Mapping[str, Mapping[str, int]]
    start_time: float | None = None
    stop_time: float | None = None
    step: float | None = None

    @property
    def parameter_set_names(self) -> tuple[str, ...]:
        """The names of the parameter sets, in the order they are first bound."""
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

    def start_values(
        self, parameter_set: str | Sequence[str] | None
    ) -> dict[str, dict[str, tuple[str, Any]]]:
        """Component -> variable -> (SSV type, value) of the named set(s), applied in order.

        Parameters
        ----------
        parameter_set : str, sequence of str or None
            The set name(s); a later set overrides an earlier one's values. None: no set.

        Returns
        -------
        dict
            Every component's name -> {variable name: (SSV type, value)}; empty dicts for
            components the sets do not bind.

        Raises
        ------
        SspError
            A name that no component binds, or ``parameter_set`` is not a name or a sequence of
            names.
        """
        names = _set_names(parameter_set)
        known = self.parameter_set_names
        for n in names:
            if n not in known:
                raise SspError(
                    f"{self.path.name}: no parameter set {n!r} (sets: {', '.join(known) or 'none'})"
                )
        out: dict[str, dict[str, tuple[str, Any]]] = {c.name: {} for c in self.components}
        for n in names:
            for comp in self.components:
                for p in comp.parameter_sets.get(n, ()):
                    out[comp.name][p.name] = (p.type, p.value)
        return out


def _set_names(parameter_set: str | Sequence[str] | None) -> tuple[str, ...]:
    if parameter_set is None:
        return ()
    if isinstance(parameter_set, str):
        return (parameter_set,)
    names = tuple(parameter_set)
    if not all(isinstance(n, str) for n in names):
        raise SspError(
            f"parameter_set must be a name or a sequence of names, got {parameter_set!r}"
        )
    return names


def read_ssp(
    path: str | os.PathLike[str],
    unpack_to: str | os.PathLike[str] | None = None,
    *,
    unpack: bool = True,
) -> SspPackage:
    """Read an SSP 1.0 package (archive or folder), validated like :func:`validate_ssp`.

    Parameters
    ----------
    path : path
        The ``.ssp`` archive or a folder with ``SystemStructure.ssd``.
    unpack_to : path, optional
        Folder an archive is unpacked into (default: a new temporary folder, which the caller
        owns; :meth:`Master.from_ssp` removes it with the master).
    unpack : bool
        False: read the description only (an archive is not unpacked; :attr:`SspPackage.root`
        is then the archive and :meth:`SspPackage.fmu` names no file).

    Returns
    -------
    SspPackage
        The package.

    Raises
    ------
    SspError
        An invalid package (naming the schema's messages), a hierarchy of systems, a
        component that is not an FMU, or a connection with a transformation (which the master
        does not apply).
    """
    path = Path(path)
    if not path.exists():
        raise SspError(f"SSP package {str(path)!r} does not exist")
    entries = _package_entries(path)
    problems = _validate_entries(entries)
    if problems:
        raise SspError(f"{path.name} is not a valid SSP 1.0 package: " + "; ".join(problems))
    if path.is_dir() or not unpack:
        root = path
    else:
        root = Path(unpack_to) if unpack_to is not None else Path(tempfile.mkdtemp(prefix="ssp_"))
        root.mkdir(parents=True, exist_ok=True)
        try:
            with zipfile.ZipFile(path) as z:
                z.extractall(root)
        except Exception:
            if unpack_to is None:
                shutil.rmtree(root, ignore_errors=True)
            raise
    ssd = etree.fromstring(entries[SSD_FILE])
    system = ssd.find("ssd:System", NS)
    if system.find("ssd:Elements/ssd:System", NS) is not None:
        raise SspError(f"{path.name}: nested systems are not supported by the master")
    components = []
    for c in system.iterfind("ssd:Elements/ssd:Component", NS):
        if c.get("type", FMU_TYPE) != FMU_TYPE:
            raise SspError(
                f"{path.name}: component {c.get('name')!r} is not an FMU ({c.get('type')})"
            )
        connectors = []
        for k in c.iterfind("ssd:Connectors/ssd:Connector", NS):
            typ = next((e for e in k if etree.QName(e).namespace == NS["ssc"]), None)
            kind = etree.QName(typ).localname if typ is not None else "Real"
            unit = typ.get("unit") if typ is not None else None
            connectors.append(SspConnector(k.get("name"), k.get("kind"), kind, unit))
        sets: dict[str, tuple[SspParameter, ...]] = {}
        for b in c.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            if b.get("source") is not None:
                set_name, params = _read_ssv(entries[b.get("source")], b.get("source"))
            else:
                inline = b.find("ssd:ParameterValues/ssv:ParameterSet", NS)
                if inline is None:
                    continue
                set_name, params = _read_ssv(etree.tostring(inline), f"{c.get('name')} binding")
            sets[set_name] = sets.get(set_name, ()) + params
        components.append(SspComponent(c.get("name"), c.get("source"), tuple(connectors), sets))
    connections = []
    for e in system.iterfind("ssd:Connections/ssd:Connection", NS):
        con = SspConnection(
            e.get("startElement"),
            e.get("startConnector"),
            e.get("endElement"),
            e.get("endConnector"),
        )
        if con.start_element is None or con.end_element is None:
            raise SspError(f"{path.name}: connection {con} uses a connector of the system itself")
        if any(etree.QName(x).localname.endswith("Transformation") for x in e):
            raise SspError(f"{path.name}: connection {con} has a transformation; not supported")
        connections.append(con)
    units = {}
    for u in ssd.iterfind("ssd:Units/ssc:Unit", NS):
        base = u.find("ssc:BaseUnit", NS)
        attrib = base.attrib if base is not None else {}
        units[u.get("name")] = {k: int(v) for k, v in attrib.items() if k in BASE_UNITS}
    start = stop = step = None
    de = ssd.find("ssd:DefaultExperiment", NS)
    if de is not None:
        start = float(de.get("startTime")) if de.get("startTime") is not None else None
        stop = float(de.get("stopTime")) if de.get("stopTime") is not None else None
        for ann in de.iterfind("ssd:Annotations/ssc:Annotation", NS):
            fixed = ann.find("osp:Algorithm/osp:FixedStepAlgorithm", NS)
            if ann.get("type") == OSP_ANNOTATION and fixed is not None:
                step = float(fixed.get("baseStepSize"))
    return SspPackage(
        path=path,
        root=root,
        name=ssd.get("name"),
        components=tuple(components),
        connections=tuple(connections),
        units=units,
        start_time=start,
        stop_time=stop,
        step=step,
    )
