"""The SSP 1.0 packages of the closed loop: valid, one experiment per SSD, the same run in every
host, units honoured by the project's master.

* validity: the four packages (``build_fmus.py`` writes them) against the SSP 1.0 schemas that
  fmpy ships, every root SSD and every ``.ssv``, by :func:`validate_ssp`, by lxml directly and by
  fmpy's own reader; broken packages are reported (a schema error, a missing ``.ssv``, two SSDs
  of one name, documentation without ``index.html``);
* content: one SSD per experiment (``SystemStructure.ssd`` is Fig. 5), exactly one binding per
  component, named like the SSD and complete (every FMU parameter), the experiment's values
  (converted on the reference rig in SI), the tunings, a default experiment per SSD; a
  ``documentation/index.html`` per package listing its SSDs; the archive is reproducible;
* every SSD of every package in the project's master, in Ecos (its Python API on the variant
  laid out as a folder) and in libcosim (given the SSD's path): the parameter values each host
  applied are the SSD's, and the plant signals agree to 1e-9, absolute and relative to their
  largest magnitude, with the same coupling (the master's ``exchange="simple"`` with
  ``grid="sum"`` for Ecos, ``grid="ns"`` for libcosim), Fig. 6's runs past the switch-on with
  the law acting;
* the ``ecos simulate`` command line in a clean environment on a variant folder, to the
  resolution of its CSV, and the Ecos behaviours the packages' documentation warns of (each
  pinned: the path of an ``.ssd`` crashes it, a misspelt set is ignored, the stop time is 1 s
  without ``--stopTime``, fewer than 10 steps crash it, a controller-only set runs the plant
  from its start values, and after the plant leaves its model (at 2.824 s, the controller-only
  set asking for a slow table) Ecos runs on with the plant frozen, says nothing and exits with
  code 0);
* units: parameter values given in rpm (defined in the ``.ssv``), ms (defined in the ``.ssd``)
  and inline in the SSD are converted (hand-computed), an undefined or incompatible unit is
  refused naming parameter, unit and dimension; a controller FMU that speaks kN.m swapped into
  the N.m loop gives the N.m loop's run (parameters and table torque converted), also where it
  calls its kN.m "N.m" (definitions decide, not names); one whose torque output is in rad/s is
  refused naming the connection, both units and their dimensions, one that declares no unit
  there is refused naming both ends unless the connection suppresses unit conversion;
* fmpy's ``simulate_ssp`` with an explicit parameter set equals the algorithm it documents and
  ignores the bindings; ``drillstring cosim`` (``--variant``, ``--parameter-set``) and
  :func:`run_si_demo`.
"""

from __future__ import annotations

import html
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import fmpy
import fmu_testlib as tl
import numpy as np
import pytest
from fmpy import read_model_description
from lxml import etree

from drillstring.apps.cosim import cosim_main, run_si_demo, si_demo_lines
from drillstring.model.experiments import FIG5, FIG6
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.units import UNITS, SIScaling, UnitDef
from drillstring.orchestration.closed_loop import (
    SCALED,
    SI,
    TOPDRIVE,
    TOPDRIVE_SI,
    VARIANTS,
    experiment_start_values,
    kept_sys_path,
)
from drillstring.orchestration.connections import declared_start_values, effective_start_values
from drillstring.orchestration.hosts import (
    ecos_command,
    load_ecospy,
    run_ecos,
    run_fmpy_ssp,
    variant_folder,
)
from drillstring.orchestration.loop_ssp import (
    LMI_EXPERIMENTS,
    loop_default_experiment,
    loop_experiments,
    topdrive_tunings,
    write_loop_package,
)
from drillstring.orchestration.master import Master
from drillstring.orchestration.ssp import (
    MAX_DESCRIPTION_BYTES,
    MAX_MEMBER_BYTES,
    MAX_MEMBERS,
    MAX_UNPACKED_BYTES,
    NS,
    SSD_FILE,
    SspComponent,
    SspConnection,
    SspConnector,
    SspError,
    SspParameter,
    SspVariant,
    read_ssp,
    validate_ssp,
    write_ssp,
)

pytestmark = pytest.mark.fmu

SC = SIScaling(REFERENCE_RIG)
TS = REFERENCE_RIG.t_star
H = 1e-3
#: Length of the cross-host runs of Fig. 5 (2000 steps): the hosts are compared, not the
#: experiments run. The runs of Fig. 6 go past its switch-on (:func:`_cross_host_stop`).
STOP = 2.0
#: How far past Fig. 6's switch-on the cross-host runs go, in units of the package's time (tau,
#: or t* seconds in SI): long enough that every law has visibly acted on the plant.
AFTER_T_ON = 3.0
#: Where Ecos stops without --stopTime, whatever the package's default experiment [s].
ECOS_DEFAULT_STOP = 1.0
#: Half a unit in the last place of Ecos's CSV numbers (std::to_string: "%f").
CSV_RESOLUTION = 5e-7 + 1e-12
ODD = "drill ü#%[x] 100%20"
ROOT = Path(__file__).resolve().parents[1]
SCHEMAS = Path(fmpy.__file__).parent / "ssp" / "schema"
#: package id -> (its file in a build, its loop variant)
PACKAGES = {
    "lmi-scaled": (lambda b: b.ssp, SCALED),
    "lmi-si": (lambda b: b.si.ssp, SI),
    "topdrive-scaled": (lambda b: b.topdrive_ssp, TOPDRIVE),
    "topdrive-si": (lambda b: b.si.topdrive_ssp, TOPDRIVE_SI),
}
CASES = [(pkg, e.name) for pkg, (_, v) in PACKAGES.items() for e in loop_experiments(v)]
#: The cases libcosim runs to the end; in the others it runs one step, for the parameters it
#: applied. libcosim takes 0.3 ms a step (28,000 steps of Fig. 6: 9 s, its own time: the FMUs
#: step in 10 us): a package's variants are parameter sets of the same system (the same FMUs and
#: connections, values that differ only in Reals, each checked as applied), so one Fig. 6
#: variant of each package runs beside every Fig. 5; the master and Ecos run every case.
LIBCOSIM_RUNS = {
    *((pkg, v) for pkg, v in CASES if not v.startswith("fig6")),
    ("lmi-scaled", "fig6"),
    ("lmi-si", "fig6"),
    ("topdrive-scaled", "fig6-soft-speed-string"),
    ("topdrive-si", "fig6-stiff-pi"),
}
assert LIBCOSIM_RUNS <= set(CASES), LIBCOSIM_RUNS - set(CASES)


def _plant_columns(data) -> list[str]:
    return [n for n in data.dtype.names if n.startswith("plant.")]


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = float(np.max(np.abs(b)))
    return float(np.max(np.abs(a - b)) / scale) if scale else float(np.max(np.abs(a - b)))


def _abs(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a, float) - np.asarray(b, float))))


def _master_run(ssp, parameter_set=None, stop=STOP, variant=None, fmus=None, **kw):
    with kept_sys_path(), Master.from_ssp(ssp, parameter_set, variant=variant, fmus=fmus) as m:
        res = m.run(stop, H, progress=False, **kw)
    assert res.completed, res.failure
    return res


def _unpack(ssp: Path, folder: Path) -> Path:
    with zipfile.ZipFile(ssp) as z:
        z.extractall(folder)
    return folder


def _ssd_file(ssp: Path, variant: str) -> str:
    return read_ssp(ssp, unpack=False, variant=variant).file


# ------------------------------------------------------------------------------------------------
# validity
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("package", PACKAGES)
def test_packages_are_valid_ssp_1_0(built, package):
    from fmpy.ssp.ssd import read_ssd

    ssp = PACKAGES[package][0](built)
    assert validate_ssp(ssp) == []
    ssd_schema = etree.XMLSchema(etree.parse(str(SCHEMAS / "SystemStructureDescription.xsd")))
    ssv_schema = etree.XMLSchema(etree.parse(str(SCHEMAS / "SystemStructureParameterValues.xsd")))
    with zipfile.ZipFile(ssp) as z:
        names = z.namelist()
        ssds = [n for n in names if "/" not in n and n.endswith(".ssd")]
        ssvs = [n for n in names if n.endswith(".ssv")]
        assert len(ssds) == len(loop_experiments(PACKAGES[package][1])) and SSD_FILE in ssds
        for n in ssds:
            assert ssd_schema.validate(etree.fromstring(z.read(n))), (n, ssd_schema.error_log)
        for n in ssvs:
            assert ssv_schema.validate(etree.fromstring(z.read(n))), (n, ssv_schema.error_log)
        # SSP 1.0: the root SSDs' names are distinct
        roots = [etree.fromstring(z.read(n)).get("name") for n in ssds]
        assert len(set(roots)) == len(roots)
    ssd = read_ssd(str(ssp), validate=True)  # fmpy's reader: SystemStructure.ssd and its .ssv
    assert [c.name for c in ssd.system.elements] == ["plant", "controller"]
    assert ssd.version == "1.0"


def test_broken_packages_are_reported(built, tmp_path):
    folder = _unpack(built.si.ssp, tmp_path / "broken")
    ssd = folder / SSD_FILE
    text = ssd.read_text()
    ssd.write_text(text.replace(' endConnector="table_torque"', "", 1))
    problems = validate_ssp(folder)
    assert problems and "endConnector" in problems[0], problems
    with pytest.raises(SspError, match="not a valid SSP 1.0 package.*endConnector"):
        read_ssp(folder)
    ssd.write_text(text)
    assert validate_ssp(folder) == []
    # a variant that binds a missing .ssv
    (folder / "resources" / "fig6.plant.ssv").unlink()
    assert any("fig6.ssd: component 'plant': resources/fig6.plant.ssv is not in the package" in p
               for p in validate_ssp(folder))  # fmt: skip
    shutil.rmtree(folder)
    # two root SSDs of one name
    folder = _unpack(built.si.ssp, tmp_path / "twice")
    six = folder / "fig6.ssd"
    six.write_text(six.read_text().replace('name="fig6"', 'name="fig5"', 1))
    assert any("the same name 'fig5'" in p for p in validate_ssp(folder)), validate_ssp(folder)
    six.write_text(six.read_text().replace('name="fig5"', 'name="fig6"', 1))
    (folder / "documentation" / "index.html").rename(folder / "documentation" / "main.html")
    assert validate_ssp(folder) == [
        "documentation/ without its entry point documentation/index.html (SSP 1.0)"
    ]


def _declare_size(archive: Path, member: str, size: int) -> None:
    """Forge the unpacked size the archive's central directory declares for ``member`` (the
    data and the local header stay as they are): what a zip bomb's directory says."""
    data = bytearray(archive.read_bytes())
    at = 0
    while (at := data.find(b"PK\x01\x02", at)) >= 0:
        n = int.from_bytes(data[at + 28 : at + 30], "little")
        if data[at + 46 : at + 46 + n].decode() == member:
            data[at + 24 : at + 28] = size.to_bytes(4, "little")
            archive.write_bytes(bytes(data))
            return
        at += 46
    raise AssertionError(f"{member} not in {archive}")


def _small_archive(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as z:
        for name, data in members.items():
            z.writestr(name, data)
    return path


def test_archives_beyond_the_limits_are_refused_before_anything_is_unpacked(tmp_path, capsys):
    """The central directory is checked before any member is read or extracted: a member
    declaring 3 GiB (in an archive of a few kB), members that together declare more than the
    package's limit, and too many members are refused naming the member and the limit."""
    ssd = b"<not read: the directory is refused first/>"
    bomb = _small_archive(tmp_path / "bomb.ssp",
                          {SSD_FILE: ssd, "resources/Plant.fmu": b"\0" * 4096})  # fmt: skip
    _declare_size(bomb, "resources/Plant.fmu", 3 << 30)
    assert bomb.stat().st_size < 10_000
    message = (f"bomb.ssp: member 'resources/Plant.fmu' unpacks to {3 << 30} bytes (3072 MiB), "
               f"more than the limit of {MAX_MEMBER_BYTES} bytes per member")  # fmt: skip
    unpacked = tmp_path / "unpacked"
    with pytest.raises(SspError, match=re.escape(message)):
        read_ssp(bomb, unpack_to=unpacked)
    assert not unpacked.exists()
    with pytest.raises(SspError, match=re.escape(message)):
        validate_ssp(bomb)
    with pytest.raises(SspError, match=re.escape(message)):
        Master.from_ssp(bomb)
    assert cosim_main([str(bomb), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    assert message in capsys.readouterr().err and not (tmp_path / "out").exists()
    # each member at the limit, all of them (with the SSD's bytes) beyond the package's
    n = MAX_UNPACKED_BYTES // MAX_MEMBER_BYTES
    many = _small_archive(tmp_path / "many.ssp", {
        SSD_FILE: ssd, **{f"resources/F{k}.fmu": b"\0" * 64 for k in range(n)}})  # fmt: skip
    for k in range(n):
        _declare_size(many, f"resources/F{k}.fmu", MAX_MEMBER_BYTES)
    with pytest.raises(SspError, match=re.escape(
            f"many.ssp: unpacked, the members up to 'resources/F{n - 1}.fmu' take "
            f"{n * MAX_MEMBER_BYTES + len(ssd)} bytes")):  # fmt: skip
        read_ssp(many, unpack_to=unpacked)
    # a description larger than a description can sensibly be
    big = _small_archive(tmp_path / "big.ssp", {SSD_FILE: ssd})
    _declare_size(big, SSD_FILE, MAX_DESCRIPTION_BYTES + 1)
    with pytest.raises(SspError, match=f"'{SSD_FILE}' is {MAX_DESCRIPTION_BYTES + 1} bytes"):
        read_ssp(big)
    # too many members
    crowd = _small_archive(tmp_path / "crowd.ssp",
                           {f"m{k}": b"" for k in range(MAX_MEMBERS + 1)})  # fmt: skip
    with pytest.raises(SspError, match=f"{MAX_MEMBERS + 1} members, more than the limit"):
        read_ssp(crowd)
    assert not unpacked.exists()


def test_a_member_longer_than_declared_is_refused_on_unpacking(built, tmp_path):
    """A member whose data is longer than its directory entry says is cut at the declared size
    and fails its CRC: the package is refused naming the member, nothing is left behind."""
    forged = tmp_path / "forged.ssp"
    shutil.copyfile(built.ssp, forged)
    member = f"resources/{built.plant.fmu.name}"
    _declare_size(forged, member, 1000)
    with pytest.raises(SspError, match=re.escape(
            f"forged.ssp: cannot be unpacked: Bad CRC-32 for file '{member}'")):  # fmt: skip
        read_ssp(forged, unpack_to=tmp_path / "unpacked")
    before = set(Path(tempfile.gettempdir()).glob("cosim_ssp_*"))
    with pytest.raises(SspError, match="Bad CRC-32"):
        Master.from_ssp(forged)
    assert set(Path(tempfile.gettempdir()).glob("cosim_ssp_*")) == before


def test_inconsistent_systems_are_refused_naming_the_element(built, tmp_path):
    """What the schema lets through is refused by validate_ssp, read_ssp and the master, naming
    the element: a connection to a connector its component does not declare (the FMU has the
    variable: the run would go on), a connector's unit defined nowhere, two components of one
    name (which the master reported as a missing FMU variable of the second)."""

    def edited(name: str, edit) -> Path:
        folder = _unpack(built.si.ssp, tmp_path / name)
        ssd = etree.parse(str(folder / SSD_FILE))
        edit(ssd.getroot())
        ssd.write(str(folder / SSD_FILE), xml_declaration=True, encoding="UTF-8")
        return folder

    def component(root, name):
        (c,) = root.findall(f"ssd:System/ssd:Elements/ssd:Component[@name='{name}']", NS)
        return c

    def undeclare(root):
        c = component(root, "controller")
        (k,) = c.findall("ssd:Connectors/ssd:Connector[@name='bit_angle']", NS)
        k.getparent().remove(k)

    def undefined_unit(root):
        c = component(root, "plant")
        (k,) = c.findall("ssd:Connectors/ssd:Connector[@name='bit_speed']/ssc:Real", NS)
        k.set("unit", "rpm")

    def twice(root):
        component(root, "controller").set("name", "plant")

    cases = {
        "undeclared": (undeclare, "connection plant.bit_angle -> controller.bit_angle: "
                       "component 'controller' declares no connector 'bit_angle'"),
        "unit": (undefined_unit, "component 'plant': connector 'bit_speed' is in unit 'rpm', "
                 "which the SSD's Units do not define"),
        "twice": (twice, "two elements of the system are named 'plant'"),
    }  # fmt: skip
    for name, (edit, message) in cases.items():
        folder = edited(name, edit)
        problems = validate_ssp(folder)
        assert any(message in p for p in problems), (name, problems)
        with pytest.raises(SspError, match=re.escape(message)):
            read_ssp(folder, unpack=False)
        with pytest.raises(SspError, match=re.escape(message)):
            Master.from_ssp(folder)


def test_write_ssp_refuses_what_would_be_invalid(built, tmp_path):
    p = read_ssp(built.si.ssp)
    try:
        comps = list(p.components)
        fmus = {c.name: p.fmu(c.name) for c in comps}
        args = dict(name="x", components=comps, fmus=fmus, connections=p.connections, units=UNITS)
        with pytest.raises(SspError, match="documentation without index.html"):
            write_ssp(tmp_path / "a.ssp", documentation={"readme.html": "<p/>"}, **args)
        other = [
            SspComponent(
                c.name, c.source, c.connectors, {"fig5": (SspParameter("h", "Real", 1.0),)}
            )
            for c in comps
        ]
        with pytest.raises(SspError, match="'fig5' of component 'plant' is bound with different"):
            write_ssp(tmp_path / "b.ssp", variants=[SspVariant("v.ssd", "v", tuple(other),
                      tuple(p.connections))], **args)  # fmt: skip
        with pytest.raises(SspError, match="must be a .ssd at the package root"):
            SspVariant(SSD_FILE, "v", (), ())
    finally:
        shutil.rmtree(p.root, ignore_errors=True)
    assert not list(tmp_path.glob("*.ssp*"))  # nothing half-written


# ------------------------------------------------------------------------------------------------
# content
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("package", PACKAGES)
def test_one_experiment_per_ssd_with_complete_sets(built, package):
    ssp, variant = PACKAGES[package][0](built), PACKAGES[package][1]
    si = variant.name == "si"
    experiments = loop_experiments(variant)
    default = read_ssp(ssp, unpack=False)
    names = [e.name for e in experiments]
    # the default, then by file
    assert list(default.variants) == [names[0], *sorted(names[1:], key=lambda n: f"{n}.ssd")]
    assert default.variants[names[0]] == SSD_FILE and names[0] == "fig5"
    assert all(default.variants[n] == f"{n}.ssd" for n in names[1:])
    assert tuple(default.sets) == tuple(default.variants)
    assert default.documentation == ("documentation/index.html",)
    fmus = {"plant": variant.plant_fmu, "controller": variant.controller_fmu}
    mds = {c: read_model_description(str(built.out / f)) for c, f in fmus.items()}
    tunings = topdrive_tunings(variant) if variant.controller == "topdrive" else {}
    for e in experiments:
        p = read_ssp(ssp, unpack=False, variant=e.name)
        assert (p.name, p.system) == (e.name, default.system)
        assert [str(c) for c in p.connections] == list(variant.connections)
        # exactly one binding per component, named like the SSD
        ssd = etree.fromstring(zipfile.ZipFile(ssp).read(p.file))
        for comp in ssd.iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
            bindings = comp.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS)
            assert [b.get("source") for b in bindings] == [
                f"resources/{e.name}.{comp.get('name')}.ssv"
            ]
        assert p.bound_sets == (e.name,)
        # SSP 1.0's all-bindings-in-order, the first binding (libcosim) and the named set
        # (Ecos) are the same values
        assert p.parameters() == p.parameters(e.name) == p.parameters([e.name, e.name])
        # complete: every parameter of each FMU, its start value unless the experiment (the
        # whole initial state, in SI converted on the reference rig), the tuning or the SSD's
        # plant parameters set it
        given = experiment_start_values(e.experiment, variant, full_initial=True)
        given["controller"].update(tunings.get(e.tuning, {}))
        given["plant"].update(dict(e.plant))  # the string's elements of its SSD
        for comp, md in mds.items():
            params = [v.name for v in md.modelVariables if v.causality == "parameter"]
            values = {k: v for k, (_, v) in p.start_values()[comp].items()}
            assert list(values) == params, comp
            starts = declared_start_values(md)
            assert values == {k: given[comp].get(k, starts[k]) for k in params}, comp
        plant = p.start_values()["plant"]
        assert plant["dphi0"][1] == pytest.approx(e.experiment.dphi0 / (TS if si else 1.0),
                                                  rel=1e-15)  # fmt: skip
        assert plant["torsional_stick_model"] == ("Boolean", e.experiment.torsional_stick)
        t_on = p.start_values()["controller"]["t_on"][1]
        assert t_on == pytest.approx(e.experiment.t_on * (TS if si else 1.0), rel=1e-15)
        # its own default experiment, whole steps
        assert (p.start_time, p.stop_time, p.step) == loop_default_experiment(variant, e.experiment)
        stop = 60 * TS if si else 60.0
        assert stop <= p.stop_time < stop + p.step
    if variant.controller == "lmi":
        six = read_ssp(ssp, unpack=False, variant="fig6").start_values()["controller"]
        assert six["latch"] == ("Integer", 2) and default.start_values()["controller"]["latch"] == (
            "Integer",
            1,
        )
        assert tuple(e.name for e in LMI_EXPERIMENTS) == ("fig5", "fig6")


def test_si_package_units_and_the_reference_rig(built):
    p = read_ssp(built.si.ssp, unpack=False)
    assert p.units["N.m"].exponents == {"kg": 1, "m": 2, "s": -2}
    assert p.units["rad/s"].exponents == {"s": -1, "rad": 1}
    plant, _ = p.components
    md = {v.name: v for v in read_model_description(str(built.si.plant.fmu)).modelVariables}
    for k in plant.connectors:
        assert k.unit == (md[k.name].unit if k.type == "Real" else None), k.name
    values = p.parameters()
    ref = {k: values["plant"][k].value for k in REFERENCE_RIG.to_dict()}
    assert ref == REFERENCE_RIG.to_dict()
    assert values["plant"]["dphi0"].unit == "rad/s" and values["plant"]["h"].unit == "s"
    ctrl = declared_start_values(read_model_description(str(built.si.controller.fmu)))
    gains = {k: values["controller"][k].value for k in ("F[1]", "F[4]", "K0", "R_ff", "Omega0")}
    assert gains == {k: ctrl[k] for k in gains}


def test_scaled_package_content_and_reproducible_archive(built, tmp_path):
    p = read_ssp(built.ssp, unpack=False)
    assert (p.stop_time, p.step) == (FIG5.tau_end, 1e-3)
    ref = {k: p.parameters()["plant"][k].value for k in ("psi", "gamma", "rho", "omega0")}
    assert ref == {k: REFERENCE.to_dict()[k] for k in ref}
    assert p.start_values()["plant"]["dphi0"] == ("Real", FIG5.dphi0)
    assert read_ssp(built.ssp, unpack=False, variant="fig6").start_values()["plant"]["dphi0"] == (
        "Real",
        FIG6.dphi0,
    )
    for name in ("DrillStringPlant.fmu", "TorsionalController.fmu"):
        shutil.copyfile(built.out / name, tmp_path / name)
    again = write_loop_package(tmp_path, VARIANTS["scaled"])
    assert again.read_bytes() == built.ssp.read_bytes()


@pytest.mark.parametrize("package", PACKAGES)
def test_documentation_folder_says_what_each_ssd_is(built, package):
    ssp, variant = PACKAGES[package][0](built), PACKAGES[package][1]
    with zipfile.ZipFile(ssp) as z:
        page = z.read("documentation/index.html").decode()
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    kind = "SI units and seconds" if variant.name == "si" else "the paper&#x27;s scaled quantities"
    assert f"closed loop, in {kind}. SSP 1.0 package written by" in page  # no experiment's "Fig."
    for i, e in enumerate(loop_experiments(variant)):
        assert f"<code>{SSD_FILE if i == 0 else e.name + '.ssd'}</code>" in page
        assert html.escape(e.summary) in page
    for caveat in ("misspelt", "--stopTime", "controller-only", "exits with code 0", "139"):
        assert caveat in page, caveat
    assert ("seconds" if variant.name == "si" else "tau = t/t*") in page


#: tool (the start of its row in the README's table) -> how every package's
#: documentation/index.html says what it applies
README_TOOLS = {
    "the project's master": "applies the SSD's bindings as SSP 1.0 does (every binding of a "
    "component in order",
    "libcosim": "applies the first binding of each component",
    "Ecos": "applies only the parameter set named by <code>--parameterSet</code>",
    "fmpy": "applies none of its bindings: pass the set as its <code>parameter_set</code> argument",
}
#: What Ecos does not tell, as every package's documentation says it (the README's bullets say
#: it in its own words); each is pinned by the Ecos tests above (:data:`ECOS_DEFAULT_STOP`,
#: exit code 0).
README_ECOS = (
    "A misspelt <code>--parameterSet</code> (or none) is ignored without a word: the FMUs' "
    "start values run",
    "The default experiment is ignored: without <code>--stopTime</code> the run stops at "
    "{stop:g} s",
    "A set that binds only one component leaves the other at its start values",
    "goes on stepping with the plant's outputs frozen (the controller computes on) and exits "
    "with code 0",
)


def _readme_ssp_section() -> str:
    text = (ROOT / "README.md").read_text()
    start = text.index("The closed loops are SSP 1.0 packages")
    return text[start : text.index("\n## ", start)]


def test_readme_states_what_the_packages_documentation_says(built):
    """The README's SSP section and every package's documentation/index.html agree in facts,
    not wording: the README names the SSDs there are and has a table row per tool, whose
    behaviour each page states (what it applies; what Ecos does not tell, with the numbers the
    Ecos tests pin), and a command line whose step and set are the SI package's default
    experiment's and Fig. 5's, whose stop time lies in that experiment, named beside it with
    the experiment's own stop time."""
    section = _readme_ssp_section()
    flat = " ".join(section.split())
    pages = []
    for make, variant in PACKAGES.values():
        with zipfile.ZipFile(make(built)) as z:
            pages.append(
                " ".join(html.unescape(z.read("documentation/index.html").decode()).split())
            )
        names = [SSD_FILE if i == 0 else f"{e.name}.ssd"
                 for i, e in enumerate(loop_experiments(variant))]  # fmt: skip
        assert names[0] in flat and all(
            n in flat or (n.startswith("fig6-") and "`fig6-<law>.ssd`" in flat) for n in names
        ), names
    rows = [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in section.splitlines() if line.startswith("|")]  # fmt: skip
    assert rows[0] == ["tool", "reads", "applies", "also"] and set(rows[1][0]) == {"-"}
    assert [r[0].split(" (")[0] for r in rows[2:]] == list(README_TOOLS)
    says = [*README_TOOLS.values(), *(s.format(stop=ECOS_DEFAULT_STOP) for s in README_ECOS)]
    for page in pages:
        for text in says:
            assert " ".join(html.unescape(text).split()) in page, text
    assert "documentation/index.html" in flat
    # the command lines run what they say (the Ecos one runs verbatim:
    # test_readme_ecos_command_runs_as_printed)
    (cmd,) = re.findall(r"`drillstring ecos simulate ([^`]*)`", flat)
    args = dict(zip(cmd.split()[::2], cmd.split()[1::2], strict=True))
    _, stop, step = loop_default_experiment(SI, FIG5)
    assert Path(args["--path"]).name == SI.ssp
    assert float(args["--stepSize"]) == step
    assert ECOS_DEFAULT_STOP < float(args["--stopTime"]) <= stop
    (whole,) = re.findall(r"the whole of it is `--stopTime ([^`]*)`, the default experiment", flat)
    assert whole == f"{stop:g}"
    assert args["--parameterSet"] == read_ssp(built.si.ssp, unpack=False).bound_sets[0] == "fig5"
    (cosim,) = re.findall(r"`drillstring cosim ([^`]*)`", flat)
    variant = cosim.split("--variant ")[1].split()[0]
    assert variant in read_ssp(built.si.ssp, unpack=False).variants


def test_readme_ecos_command_runs_as_printed(built, tmp_path, clean_home):
    """The README's Ecos command, exactly as printed, in a shell whose PATH has the project's
    environment (as after ``make demo`` or activating ``.venv``) and nothing else of this
    process's, in a folder with ``build/`` of the session's build: it runs Fig. 5 in SI from its
    initial state to the stop time it gives (not Ecos's default, 1 s: the option is honoured) and
    writes its CSV into that folder (there is no ``ecos`` on any PATH: ``drillstring ecos``
    starts ecospy's binary through the loader). The README prints the first 2 s of Fig. 5, not
    the whole (55,352 steps, about 20 s of a core for the same checks: the run starts, honours the
    stop time and exits 0; the agreement of the whole run is ``make demo``'s)."""
    flat = " ".join(_readme_ssp_section().split())
    (command,) = re.findall(r"`(drillstring ecos simulate [^`]*)`", flat)
    (tmp_path / "build").mkdir()
    shutil.copyfile(built.si.ssp, tmp_path / "build" / built.si.ssp.name)
    env = tl.clean_env(clean_home, TMPDIR=str(tmp_path))
    env["PATH"] = f"{Path(sys.executable).parent}:{env['PATH']}"
    assert shutil.which("ecos", path=env["PATH"]) is None
    proc = tl.run_clean(["bash", "-c", command], env, tmp_path)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    header, data = tl.read_ecos_csv(tmp_path / f"{built.si.ssp.stem}.csv")
    _, _, step = loop_default_experiment(SI, FIG5)
    stop = float(command.split("--stopTime ")[1].split()[0])
    assert stop != ECOS_DEFAULT_STOP
    assert data[-1, header.index("time")] == pytest.approx(stop, abs=2 * step)
    assert data[0, header.index("plant::dphi0[REAL]")] == pytest.approx(FIG5.dphi0 / TS, abs=1e-6)


# ------------------------------------------------------------------------------------------------
# every SSD in three hosts
# ------------------------------------------------------------------------------------------------


def _libcosim(ssd: Path, n: int, names: list[str], params: list[str]):
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    with kept_sys_path():
        ex = CosimExecution.from_ssp_file(str(ssd))  # its step: the fixed-step annotation
        observer = CosimObserver.create_last_value()
        assert ex.add_observer(observer)
        index = {c: ex.slave_index_from_instance_name(c) for c in ("plant", "controller")}
        vr = {
            c: {v.name.decode(): v.reference for v in ex.slave_variables(i)}
            for c, i in index.items()
        }
        refs = [vr["plant"][n.split(".", 1)[1]] for n in names]
        rows = []
        for _ in range(n):
            assert ex.step(1)
            rows.append(observer.last_real_values(index["plant"], refs))
        applied = {}
        for key in params:
            c, v = key.split(".", 1)
            applied[key] = observer.last_real_values(index[c], [vr[c][v]])[0]
    return np.array(rows), applied


def _cross_host_stop(t_on: float, si: bool) -> float:
    """The stop time of a cross-host run: :data:`STOP` for Fig. 5 (``t_on = 0``: the controller
    acts from the start), for Fig. 6 the first whole time unit at least :data:`AFTER_T_ON` units
    (tau, or t* seconds in SI) past the package's own switch-on ``t_on``."""
    if t_on == 0.0:
        return STOP
    return float(math.ceil(t_on + AFTER_T_ON * (TS if si else 1.0)))


def _controller_acted(res, output: str, t_on: float) -> float:
    """The largest change of the controller's output after ``t_on`` from its value just before
    (before the switch-on it puts out the feed-forward R_ff alone)."""
    u = res[output]
    before = res.time < t_on
    assert res.time[-1] > t_on, f"the run ends at {res.time[-1]}, before the switch-on {t_on}"
    assert np.ptp(u[before]) == 0.0, "the controller acted before its switch-on"
    return float(np.max(np.abs(u[~before] - u[before][-1])))


@pytest.mark.parametrize("package, variant", CASES, ids=[f"{p}-{v}" for p, v in CASES])
def test_every_ssd_runs_the_same_in_master_ecos_and_libcosim(built, tmp_path, package, variant):
    """The SSD's experiment in three hosts: the parameters each applied are the SSD's, and every
    plant signal agrees with the master's under that host's coupling to 1e-9 both absolute (in
    the signal's unit) and relative to the signal's largest magnitude in the master's run
    (measured: 0.0 for both hosts in every SSD). Fig. 5 runs 2000 steps; Fig. 6 runs past its
    switch-on (tau = 25, 23.06 s in SI) to tau = 28 (26 s), and the controller's output must
    have changed after the switch-on by more than half the nominal torque R0: the hosts agree
    while the law acts on the plant. Ecos runs every case to the end, libcosim the cases of
    :data:`LIBCOSIM_RUNS` (in the others its first step)."""
    ssp, loop = PACKAGES[package][0](built), PACKAGES[package][1]
    p = read_ssp(ssp, unpack=False, variant=variant)
    t_on = p.parameters()["controller"]["t_on"].value
    stop = _cross_host_stop(t_on, loop.name == "si")
    reals = [
        f"{c}.{n}"
        for c, params in p.parameters().items()
        for n, q in params.items()
        if q.type == "Real"
    ]
    expect = {k: p.parameters()[k.split(".")[0]][k.split(".", 1)[1]].value for k in reals}
    # the project's master, Ecos's coupling
    with kept_sys_path(), Master.from_ssp(ssp, variant=variant) as m:
        assert m.ssp.file == p.file
        for unit in m.system.units:
            starts = effective_start_values(unit)
            for k in reals:
                if k.startswith(unit.name + "."):
                    assert starts[k.split(".", 1)[1]] == expect[k], k
        ref = m.run(stop, H, progress=False, exchange="simple", grid="sum")
        ref_ns = m.run(stop, H, progress=False, exchange="simple", grid="ns")
    assert ref.completed and ref_ns.completed
    names = _plant_columns(ref.data)
    if t_on > 0.0:
        acted = _controller_acted(ref, f"controller.{loop.torque}", t_on)
        assert acted > 0.5 * abs(expect["controller.R0"]), acted
    # Ecos: the variant as a folder whose SystemStructure.ssd it is, its set named
    got = run_ecos(ssp, variant, stop, H, names, variant=variant)
    assert len(got) == len(ref.time) - 1
    assert np.max(np.abs(got["time"] - ref.time[1:])) == 0.0  # the same accumulated grid
    ecos = max(_rel(got[n], ref[n][1:]) for n in names)
    ecos_abs = max(_abs(got[n], ref[n][1:]) for n in names)
    ecospy = load_ecospy()
    folder = variant_folder(ssp, variant, tmp_path / "ecos")
    with kept_sys_path(), ecospy.EcosSimulation(ssp_path=str(folder), step_size=H) as sim:
        sim.init(parameter_set=variant)
        ecos_applied = {k: sim.get_real(k.replace(".", "::", 1)) for k in reals}
        sim.terminate()
    assert ecos_applied == expect
    # libcosim: the SSD's path in the unpacked package; its first (= only) bindings
    unpacked = _unpack(ssp, tmp_path / "lib")
    real_names = [n for n in names if n.split(".", 1)[1] in _real_outputs(built, package)]
    steps = round(stop / H) if (package, variant) in LIBCOSIM_RUNS else 1
    rows, lib_applied = _libcosim(unpacked / p.file, steps, real_names, reals)
    assert lib_applied == expect
    assert len(rows) == steps
    lib = max(_rel(rows[:, j], ref_ns[c][1 : steps + 1]) for j, c in enumerate(real_names))
    lib_abs = max(_abs(rows[:, j], ref_ns[c][1 : steps + 1]) for j, c in enumerate(real_names))
    print(
        f"{package} {variant} to {stop}: Ecos vs master {ecos:.2e} relative ({ecos_abs:.2e} "
        f"absolute), libcosim vs master {lib:.2e} relative ({lib_abs:.2e} absolute)"
    )
    assert max(ecos, ecos_abs, lib, lib_abs) <= 1e-9, (ecos, ecos_abs, lib, lib_abs)
    assert np.ptp(ref[names[1]]) > 0.0  # a real run


def _real_outputs(built, package) -> set[str]:
    variant = PACKAGES[package][1]
    md = read_model_description(str(built.out / variant.plant_fmu))
    return {v.name for v in md.modelVariables if v.type == "Real" and v.causality == "output"}


def test_the_variants_differ(built):
    """Fig. 5 and Fig. 6 are different runs (the hosts above are not comparing one experiment
    under several names), and so are the top-drive laws after the switch-on."""
    a = _master_run(built.si.ssp, stop=0.5)
    b = _master_run(built.si.ssp, variant="fig6", stop=0.5)
    assert np.max(np.abs(a["plant.bit_speed"] - b["plant.bit_speed"])) > 1.0
    t = 25.5
    runs = {v: _master_run(built.topdrive_ssp, variant=f"fig6-{v}", stop=t)
            for v in ("stiff-pi", "z-torque")}  # fmt: skip
    ra, rb = (r["controller.R_minus_R0"] for r in runs.values())
    before = runs["stiff-pi"].time < FIG6.t_on
    assert np.array_equal(ra[before], rb[before]) and np.max(np.abs(ra - rb)) > 0.01


# ------------------------------------------------------------------------------------------------
# the ecos command line
# ------------------------------------------------------------------------------------------------


def _ecos(args, work: Path, home: Path):
    env = tl.clean_env(home, TMPDIR=str(work))  # Ecos unpacks into $TMPDIR
    return tl.run_clean(ecos_command("simulate", *args), env, work)


def test_ecos_command_line_runs_a_variant_folder(built, tmp_path, clean_home):
    """``ecos simulate --path FOLDER --parameterSet fig6`` on Fig. 6's SSD laid out as the
    folder's SystemStructure.ssd, in a clean environment, equals the master's run of the SSD to
    the resolution of Ecos's CSV."""
    work = tmp_path / ODD
    work.mkdir()
    folder = variant_folder(built.si.ssp, "fig6", work / "fig6")
    proc = _ecos(["--path", str(folder), "--stepSize", "0.001", "--stopTime", "2",
                  "--parameterSet", "fig6"], work, clean_home)  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    header, data = tl.read_ecos_csv(work / "fig6.csv")  # named after the folder
    ref = _master_run(built.si.ssp, variant="fig6", stop=2.0, exchange="simple", grid="sum")
    k = min(len(data) - 1, len(ref.time) - 1)
    assert k >= 1999  # Ecos stops where t + h would pass stopTime in double
    assert data[0, header.index("plant::dphi0[REAL]")] == pytest.approx(FIG6.dphi0 / TS, abs=1e-6)
    for name in ("bit_speed", "table_speed", "bit_angle", "weight_on_bit", "torque_on_bit"):
        col = data[1 : k + 1, header.index(f"plant::{name}[REAL]")]
        err = np.max(np.abs(col - ref[f"plant.{name}"][1 : k + 1]))
        assert err <= CSV_RESOLUTION, (name, err)


def test_ecos_pitfalls_the_documentation_names(built, tmp_path, clean_home):
    """What ecospy 0.7.2 does, as the packages' documentation says: the path of an .ssd crashes
    it (SIGSEGV), a misspelt --parameterSet runs the FMUs' start values without a word, without
    --stopTime it stops at 1 s (the default experiment is not read), and a run of fewer than 10
    steps dies of SIGFPE."""
    work = tmp_path / "pitfalls"
    work.mkdir()
    unpacked = _unpack(built.si.ssp, work / "pkg")
    proc = _ecos(["--path", str(unpacked / "fig6.ssd"), "--stepSize", "0.001", "--stopTime",
                  "0.02", "--parameterSet", "fig6"], work, clean_home)  # fmt: skip
    assert proc.returncode in (-signal.SIGSEGV, 128 + signal.SIGSEGV), proc.returncode
    folder = variant_folder(built.si.ssp, "fig6", work / "fig6")
    proc = _ecos(["--path", str(folder), "--stepSize", "0.001", "--parameterSet", "fig_6"],
                 work, clean_home)  # fmt: skip
    assert proc.returncode == 0 and "warn" not in (proc.stdout + proc.stderr).lower()
    header, data = tl.read_ecos_csv(work / "fig6.csv")
    dphi0 = data[:, header.index("plant::dphi0[REAL]")]
    start = declared_start_values(read_model_description(str(built.si.plant.fmu)))["dphi0"]
    assert dphi0[0] == pytest.approx(start, abs=1e-6) and start != pytest.approx(FIG6.dphi0 / TS)
    assert data[-1, header.index("time")] == pytest.approx(
        ECOS_DEFAULT_STOP, abs=2e-3
    )  # not 55.352
    proc = _ecos(["--path", str(folder), "--stepSize", "0.001", "--stopTime", "0.009",
                  "--parameterSet", "fig6"], work, clean_home)  # fmt: skip
    assert proc.returncode in (-signal.SIGFPE, 128 + signal.SIGFPE), proc.returncode


#: The Enumeration variables Ecos ignores, by package kind, as docs/ssp.md names them.
ECOS_IGNORED = {
    "lmi": {("controller", n) for n in ("latch", "on_saturation", "braking", "downhole", "torque")}
    | {("plant", "on_invalid")},
    "topdrive": {("controller", n) for n in ("anti_windup", "braking", "downhole", "torque")}
    | {("plant", "on_invalid")},
}


def _ecos_paragraph() -> str:
    text = (ROOT / "docs" / "ssp.md").read_text()
    start = text.index("Both Ecos and libcosim ignore FMI 2.0 Enumeration variables")
    return " ".join(text[start:].split("\n\n")[0].split())


@pytest.mark.parametrize("package", list(PACKAGES))
def test_ecos_warns_of_the_enumerations_the_documentation_names(
    built, tmp_path, clean_home, package
):
    """Ecos warns of every Enumeration a set gives (it sets none of them), exactly those that
    docs/ssp.md lists for the package; each keeps the FMU's start value, which is the set's own
    but for Fig. 5's latch (``none``, the same run: docs/ssp.md)."""
    make, variant = PACKAGES[package]
    ssp = make(built)
    work = tmp_path / "enum"
    work.mkdir()
    proc = _ecos(["--path", str(ssp), "--stepSize", "0.001", "--stopTime", "0.02",
                  "--parameterSet", "fig5"], work, clean_home)  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    warned = re.findall(r"No variable named '(\w+)' of type int registered for instance '(\w+)'",
                        proc.stdout + proc.stderr)  # fmt: skip
    kind = "topdrive" if package.startswith("topdrive") else "lmi"
    assert {(unit, name) for name, unit in warned} == ECOS_IGNORED[kind]
    assert len(warned) == len(ECOS_IGNORED[kind])  # once each
    said = _ecos_paragraph()
    count = {"lmi": "six times for the LMI packages", "topdrive": "five times for the top-drive"}
    assert count[kind] in said
    listed = said.split(count[kind])[1].split(")")[0]
    assert {n for _, n in ECOS_IGNORED[kind]} == set(re.findall(r"`(\w+)`", listed))
    # what the sets give (ssv:Integer, as FMI 2.0 sets an Enumeration): the FMUs' start values,
    # but Fig. 5's latch
    folder = _unpack(ssp, work / "pkg")
    for unit, name in ECOS_IGNORED[kind]:
        fmu = folder / read_ssp(folder).component(unit).source
        (var,) = [v for v in read_model_description(str(fmu)).modelVariables if v.name == name]
        assert var.type == "Enumeration", (unit, name)
        items = {int(i.value): i.name for i in var.declaredType.items}
        for e in loop_experiments(variant):
            given = read_ssp(folder, unpack=False, variant=e.name).parameters()[unit][name]
            if (unit, name, e.name) == ("controller", "latch", "fig5"):
                assert (items[int(given.value)], items[int(var.start)]) == ("none", "angle")
            else:
                assert int(given.value) == int(var.start), (unit, name, e.name)


#: The table speed the controller-only set asks for (rad/s; the set's own is 5.42): slow enough
#: that the bit stops and the plant leaves its model early, at 2.824 s.
SLOW_TABLE = 1.5
#: The stop time of the controller-only run: past the plant's validity stop (2.824 s), with a
#: second of the plant frozen after it.
ECOS_STOP = 4.0


def test_ecos_runs_a_controller_only_set_on_past_the_plant_leaving_its_model(
    built, tmp_path, clean_home
):
    """The Ecos pitfalls of the documentation that need a run past a validity stop: a set that
    binds the controller alone (the stiff PI tuning from t = 0 at a slow table speed: Fig. 6's
    stiff-PI SSD with ``t_on = 0``, ``Omega0`` = :data:`SLOW_TABLE` and the plant's binding
    removed) leaves the plant at the FMU's start values, Fig. 5's state with the torsional-stick
    model off. The controller slows the table, and the plant leaves its model at 2.824 s (the
    bit stops: ``fmi2Discard``, which the project's master reports and stops at; with the set's
    own table speed that comes only at 54.017 s, a run of a minute in Ecos); Ecos runs the same
    run up to there (to its CSV's resolution), says nothing of the stop, goes on to the stop
    time with every plant output frozen while the controller computes on, and exits with code
    0."""
    ssp = built.si.topdrive_ssp
    work = tmp_path / "controller_only"
    work.mkdir()
    folder = variant_folder(ssp, "fig6-stiff-pi", work / "stiff")
    ssd = etree.parse(str(folder / SSD_FILE))
    (plant,) = ssd.findall("ssd:System/ssd:Elements/ssd:Component[@name='plant']", NS)
    plant.remove(plant.find("ssd:ParameterBindings", NS))
    ssd.write(str(folder / SSD_FILE), xml_declaration=True, encoding="UTF-8")
    ssv = etree.parse(str(folder / "resources" / "fig6-stiff-pi.controller.ssv"))
    ssv.find("ssv:Parameters/ssv:Parameter[@name='t_on']/ssv:Real", NS).set("value", "0.0")
    omega0 = ssv.find("ssv:Parameters/ssv:Parameter[@name='Omega0']/ssv:Real", NS)
    assert float(omega0.get("value")) > 3 * SLOW_TABLE  # the set's own: the rig's 52 rpm
    omega0.set("value", repr(SLOW_TABLE))
    ssv.write(str(folder / "resources" / "fig6-stiff-pi.controller.ssv"), xml_declaration=True,
              encoding="UTF-8")  # fmt: skip
    assert validate_ssp(folder) == []
    with kept_sys_path(), Master.from_ssp(folder) as m:
        assert m.ssp.bound_sets == ("fig6-stiff-pi",)  # the controller's only
        ref = m.run(ECOS_STOP, H, progress=False, exchange="simple", grid="sum")
    failure = str(ref.failure)
    assert not ref.completed and "torsional stick: outside the model" in failure, failure
    stop = float(re.search(r"\(t = ([0-9.]+) s\)", failure).group(1))
    assert round(stop, 3) == 2.824
    proc = _ecos(["--path", str(folder), "--stepSize", "0.001", "--stopTime", str(ECOS_STOP),
                  "--parameterSet", "fig6-stiff-pi"], work, clean_home)  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    said = [line for line in (proc.stdout + proc.stderr).splitlines()
            if "[warning]" in line or "[error]" in line or "[critical]" in line]  # fmt: skip
    assert said and all("No variable named" in line for line in said), said  # the enumerations
    header, data = tl.read_ecos_csv(work / "stiff.csv")

    def col(name: str) -> np.ndarray:
        return data[:, header.index(name)]

    t = col("time")
    assert t[-1] == pytest.approx(ECOS_STOP, abs=2e-3)
    # the plant at the FMU's start values, the controller at the set's
    starts = declared_start_values(read_model_description(str(built.si.plant.fmu)))
    assert starts["torsional_stick_model"] is False
    assert starts["dphi0"] == pytest.approx(FIG5.dphi0 / TS, rel=1e-12)
    assert col("plant::dphi0[REAL]")[0] == pytest.approx(starts["dphi0"], abs=1e-6)
    stiff = read_ssp(ssp, unpack=False, variant="fig6-stiff-pi").parameters()["controller"]
    soft = declared_start_values(read_model_description(str(built.si.topdrive.fmu)))["kp"]
    assert col("controller::kp[REAL]")[0] == pytest.approx(stiff["kp"].value, abs=1e-6)
    assert abs(stiff["kp"].value - soft) > 1.0 and col("controller::t_on[REAL]")[0] == 0.0
    # up to the stop the master's run; after it the plant frozen, the controller on
    k = int(np.count_nonzero(t < stop - H))  # rows from t = 0, as the master's
    after = t > stop + H
    assert k > 2_800 and len(ref.time) >= k
    assert np.max(np.abs(t[:k] - ref.time[:k])) <= CSV_RESOLUTION
    for name in ("bit_speed", "table_speed", "bit_position", "weight_on_bit", "torque_on_bit"):
        got = col(f"plant::{name}[REAL]")
        err = np.max(np.abs(got[:k] - ref[f"plant.{name}"][:k]))
        assert err <= CSV_RESOLUTION, (name, err)
        assert np.ptp(got[after]) == 0.0, name
    assert col("plant::bit_speed[REAL]")[-1] == pytest.approx(0.0, abs=1e-6)  # the bit stopped
    assert np.ptp(col("controller::table_torque[REAL]")[after]) > 100.0  # N m


# ------------------------------------------------------------------------------------------------
# the project's master: the Python wiring, swapped components, units
# ------------------------------------------------------------------------------------------------


def test_from_ssp_runs_the_same_ssd_however_it_is_named(built):
    a = _master_run(built.ssp)
    assert np.ptp(a["plant.dphi"]) > 1.0  # a real run
    # the SSD given as a path, the variant by file name, a named set: the same run
    folder = _unpack(built.ssp, built.out.parent / "unpacked_scaled")
    try:
        for kw in ({"ssp": folder / SSD_FILE}, {"variant": "SystemStructure.ssd"},
                   {"parameter_set": "fig5"}):  # fmt: skip
            ssp = kw.pop("ssp", built.ssp)
            assert np.array_equal(_master_run(ssp, **kw).data, a.data)
        six = _master_run(built.ssp, variant="fig6")
        assert np.array_equal(_master_run(folder / "fig6.ssd").data, six.data)
        assert np.array_equal(_master_run(built.ssp, "fig6").data, six.data)
        with pytest.raises(SspError, match="is not the variant 'fig5'"):
            Master.from_ssp(folder / "fig6.ssd", variant="fig5")
    finally:
        shutil.rmtree(folder)


def test_from_ssp_swaps_a_component_and_rejects_bad_requests(built, tmp_path):
    mine = tmp_path / "MyController.fmu"
    shutil.copyfile(built.si.controller.fmu, mine)
    a = _master_run(built.si.ssp, stop=0.2)
    with kept_sys_path(), Master.from_ssp(built.si.ssp, fmus={"controller": mine}) as m:
        assert m.system.units[1].fmu == mine
        b = m.run(0.2, H, progress=False)
    assert np.array_equal(a.data, b.data)
    with pytest.raises(ValueError, match="has no variable 'bit_angle'"):
        Master.from_ssp(built.si.ssp, (), fmus={"controller": built.controller.fmu})
    with pytest.raises(SspError, match=r"no parameter set 'z-torque' \(sets: fig5, fig6; "
                       r"variants: fig5, fig6\)"):  # fmt: skip
        Master.from_ssp(built.si.ssp, "z-torque")
    with pytest.raises(SspError, match=r"no variant 'fig7' \(variants: fig5 \(SystemStructure"
                       r"\.ssd\), fig6 \(fig6\.ssd\)\)"):  # fmt: skip
        Master.from_ssp(built.si.ssp, variant="fig7")
    with pytest.raises(SspError, match="no component 'pump'"):
        Master.from_ssp(built.si.ssp, fmus={"pump": mine})
    with pytest.raises(SspError, match="does not exist"):
        Master.from_ssp(tmp_path / "none.ssp")


def _edit(path: Path, old: str, new: str, count: int = 1) -> None:
    text = path.read_text()
    assert text.count(old) >= count, (path, old)
    path.write_text(text.replace(old, new, count))


RPM = '<ssc:Unit name="rpm"><ssc:BaseUnit s="-1" rad="1" factor="0.10471975511965977"/></ssc:Unit>'


def test_parameter_values_in_other_units_are_converted(built, tmp_path):
    """Omega0 = 51.756 rpm (unit defined in the .ssv) is set as 51.756 pi/30 = 5.41987 rad/s,
    t_on = 250 ms (unit defined in the .ssd) as 0.25 s, and dphi0 = -25.878 rpm given inline in
    the SSD as -25.878 pi/30 rad/s; the run is the run of those values in the FMUs' units."""
    folder = _unpack(built.si.ssp, tmp_path / "units")
    ctrl = folder / "resources" / "fig5.controller.ssv"
    omega0 = read_ssp(built.si.ssp, unpack=False).parameters()["controller"]["Omega0"].value
    _edit(ctrl, f'<ssv:Real value="{omega0!r}" unit="rad/s"/>',
          '<ssv:Real value="51.756" unit="rpm"/>')  # fmt: skip
    _edit(ctrl, "</ssv:Units>", RPM + "</ssv:Units>")
    _edit(ctrl, '<ssv:Real value="0.0" unit="s"/>', '<ssv:Real value="250.0" unit="ms"/>')
    ssd = folder / SSD_FILE
    _edit(
        ssd,
        "</ssd:Units>",
        '<ssc:Unit name="ms"><ssc:BaseUnit s="1" factor="0.001"/></ssc:Unit></ssd:Units>',
    )
    # the plant's binding inline, with its own unit definitions
    plant_ssv = etree.parse(str(folder / "resources" / "fig5.plant.ssv")).getroot()
    dphi0 = plant_ssv.find("ssv:Parameters/ssv:Parameter[@name='dphi0']/ssv:Real", NS)
    dphi0.set("value", "-25.878")
    dphi0.set("unit", "rpm")
    plant_ssv.find("ssv:Units", NS).append(etree.fromstring(RPM.replace(
        "<ssc:Unit", f'<ssc:Unit xmlns:ssc="{NS["ssc"]}"', 1)))  # fmt: skip
    inline = etree.tostring(plant_ssv).decode()
    _edit(ssd, '<ssd:ParameterBinding source="resources/fig5.plant.ssv"/>',
          f"<ssd:ParameterBinding><ssd:ParameterValues>{inline}</ssd:ParameterValues>"
          "</ssd:ParameterBinding>")  # fmt: skip
    assert validate_ssp(folder) == []
    with kept_sys_path(), Master.from_ssp(folder) as m:
        plant, controller = (effective_start_values(u) for u in m.system.units)
        got = m.run(0.5, H, progress=False)
    assert controller["Omega0"] == pytest.approx(51.756 * math.pi / 30.0, rel=1e-15)
    assert controller["Omega0"] == pytest.approx(5.41987, abs=1e-5)
    assert controller["t_on"] == pytest.approx(0.25, rel=1e-15)
    assert plant["dphi0"] == pytest.approx(-25.878 * math.pi / 30.0, rel=1e-15)
    # the same run as the FMUs given the hand-converted values (and the rest of the set)
    sets = read_ssp(built.si.ssp, unpack=False).start_values()
    units = {c: {k: v for k, (_, v) in sets[c].items()} for c in sets}
    units["plant"]["dphi0"] = -25.878 * math.pi / 30.0
    units["controller"].update(Omega0=51.756 * math.pi / 30.0, t_on=0.25)
    fmus = {"plant": built.si.plant.fmu, "controller": built.si.controller.fmu}
    with kept_sys_path(), Master({c: (fmus[c], units[c]) for c in fmus}, SI.connections) as m:
        ref = m.run(0.5, H, progress=False)
    assert np.array_equal(got["plant.bit_speed"], ref["plant.bit_speed"])


def test_incompatible_or_undefined_parameter_units_are_refused(built, tmp_path):
    folder = _unpack(built.si.ssp, tmp_path / "refused")
    ctrl = folder / "resources" / "fig5.controller.ssv"
    text = ctrl.read_text()
    omega0 = read_ssp(built.si.ssp, unpack=False).parameters()["controller"]["Omega0"].value
    _edit(ctrl, f'<ssv:Real value="{omega0!r}" unit="rad/s"/>',
          '<ssv:Real value="51.756" unit="N.m"/>')  # fmt: skip
    with pytest.raises(SspError, match=re.escape(
        "component 'controller': parameter 'Omega0' = 51.756 given in 'N.m' (dimension "
        "kg.m2.s-2): Omega0 of TorsionalControllerSI.fmu is in 'rad/s', a unit of dimension "
        "s-1.rad; not convertible")):  # fmt: skip
        Master.from_ssp(folder)
    ctrl.write_text(text)
    _edit(ctrl, f'<ssv:Real value="{omega0!r}" unit="rad/s"/>',
          '<ssv:Real value="51.756" unit="rpm"/>')  # fmt: skip
    with pytest.raises(SspError, match="unit 'rpm' is defined neither in its .ssv nor in the .ssd"):
        Master.from_ssp(folder)
    # a variable that declares no unit takes no value in a unit
    _edit(ctrl, "</ssv:Units>", RPM + "</ssv:Units>")
    bare = tl.fmu_with_units(built.si.controller.fmu, tmp_path / "Bare.fmu", {"Omega0": None}, {})
    with pytest.raises(SspError, match="Bare.fmu declares no unit for Omega0: cannot convert it"):
        Master.from_ssp(folder, fmus={"controller": bare})


KNM = {
    "kN.m": 'kg="1" m="2" s="-2" factor="1000"',
    "kN.m.s/rad": 'kg="1" m="2" s="-1" rad="-1" factor="1000"',
    "kN.m/rad": 'kg="1" m="2" s="-2" rad="-1" factor="1000"',
    "rad/(kN.m.s)": 'kg="-1" m="-2" s="1" rad="1" factor="0.001"',
    "t.m2": 'kg="1" m="2" factor="1000"',  # kN.m.s2: the inertias in the same kilo-units
    "kN.m/s": 'kg="1" m="2" s="-3" factor="1000"',
    "kW": 'kg="1" m="2" s="-3" factor="1000"',
}
#: Every torque-valued parameter of the SI top-drive controller in kilo-units: its gains, its
#: feed-forward and nominal torque, the string's stiffness and inertias (so t* = sqrt(I1/C) is
#: unchanged) and the top drive's limits.
KILO = {"table_torque": "kN.m", "kp": "kN.m.s/rad", "ki": "kN.m/rad", "R_ff": "kN.m",
        "C": "kN.m/rad", "z_gain": "rad/(kN.m.s)", "R0": "kN.m", "I1": "t.m2", "I2": "t.m2",
        "R_min": "kN.m", "R_max": "kN.m", "rate": "kN.m/s", "P_max": "kW"}  # fmt: skip


#: The SI units of :data:`KILO`'s variables, each defined as its kilo-unit of :data:`KNM`.
SI_NAMES = {
    "N.m": "kN.m",
    "N.m.s/rad": "kN.m.s/rad",
    "N.m/rad": "kN.m/rad",
    "rad/(N.m.s)": "rad/(kN.m.s)",
    "kg.m2": "t.m2",
    "N.m/s": "kN.m/s",
    "W": "kW",
}


def _fmu_defining_units(src: Path, dst: Path, defs: dict[str, str]) -> Path:
    """A copy of an FMU whose ``UnitDefinitions`` define the units named in ``defs`` otherwise
    (unit name -> the attributes of its ``BaseUnit`` as XML text, without display units); the
    variables keep their unit names (not their display units), the FMU's code is unchanged."""
    with tl.edited_model_description(src, dst) as root:
        for name, base in defs.items():
            (unit,) = root.findall(f"UnitDefinitions/Unit[@name='{name}']")
            for child in list(unit):
                unit.remove(child)
            unit.append(ET.fromstring(f"<BaseUnit {base}/>"))
        for real in root.iterfind("ModelVariables/ScalarVariable/Real"):
            if real.get("unit") in defs:
                real.attrib.pop("displayUnit", None)
    return dst


@pytest.mark.parametrize("named", ["kilo-names", "si-names"])
@pytest.mark.parametrize("variant", ["fig5", "fig6-z-torque"])
def test_a_controller_in_kilonewton_metres_closes_the_newton_metre_loop(
    built, tmp_path, variant, named
):
    """The SI top-drive controller declared in kN.m (torque output and every torque-valued
    parameter, :data:`KILO`): the master sets its parameters from the package's N.m values
    divided by 1000 (z_gain times 1000), so that it computes in kN.m, and multiplies its torque
    by 1000 on the way to the plant. The run is the N.m package's to rounding (asserted 1e-12
    relative; Jacobi in C is not used when a connection converts, so the Python loop runs), also
    under Gauss-Seidel with linear extrapolation. The same where the FMU keeps the SI names and
    defines them as the kilo-units (``si-names``: the definitions decide, not the names, both
    on the connection and for the parameters, whose ``.ssv`` defines its N.m as N.m)."""
    if named == "kilo-names":
        knm = tl.fmu_with_units(built.si.topdrive.fmu, tmp_path / "TopDriveKNm.fmu", KILO, KNM)
        source = "kN.m"
    else:
        defs = {si: KNM[kilo] for si, kilo in SI_NAMES.items()}
        knm = _fmu_defining_units(built.si.topdrive.fmu, tmp_path / "TopDriveKNm.fmu", defs)
        source = "N.m"
    ssp = built.si.topdrive_ssp
    stop = 24.0 if variant == "fig6-z-torque" else STOP  # past the switch-on at 23.06 s
    n_m = read_ssp(ssp, unpack=False, variant=variant).parameters()["controller"]
    assert n_m["kp"].unit_def.factor == 1.0 and n_m["kp"].unit == "N.m.s/rad"
    for kw in ({}, {"scheme": "gauss-seidel", "extrapolation": "linear"}):
        with kept_sys_path(), Master.from_ssp(ssp, variant=variant, fmus={"controller": knm}) as m:
            (conv,) = m.system.conversions.values()
            assert list(m.system.conversions) == ["plant.table_torque"]
            assert (conv.source, conv.target, conv.factor, conv.offset) == (
                source, "N.m", 1000.0, 0.0)  # fmt: skip
            starts = effective_start_values(m.system.units[1])
            got = m.run(stop, H, progress=False, **kw)
        assert got.completed, got.failure
        assert starts["kp"] == pytest.approx(n_m["kp"].value / 1000.0, rel=1e-15)
        assert starts["R_ff"] == pytest.approx(n_m["R_ff"].value / 1000.0, rel=1e-15)
        assert starts["z_gain"] == pytest.approx(n_m["z_gain"].value * 1000.0, rel=1e-15)
        assert starts["Omega0"] == n_m["Omega0"].value  # rad/s in both
        ref = _master_run(ssp, variant=variant, stop=stop, **kw)
        # the plant's input in N.m, the controller's output in kN.m
        assert np.allclose(got["plant.table_torque"], 1000.0 * got["controller.table_torque"],
                           rtol=1e-15, atol=0)  # fmt: skip
        worst = {n: _rel(got[n], ref[n]) for n in _plant_columns(ref.data)}
        print(
            f"kN.m controller ({named}) in the N.m loop, {variant} {kw}: max relative difference",
            max(worst.values()),
        )
        assert max(worst.values()) <= 1e-12, worst
        assert np.ptp(got["plant.table_torque"]) > 10.0


def test_a_connection_of_different_dimensions_is_refused(built, tmp_path):
    bad = tl.fmu_with_units(built.si.topdrive.fmu, tmp_path / "TopDriveRadS.fmu",
                        {"table_torque": "rad/s"}, {})  # fmt: skip
    with pytest.raises(ValueError, match=re.escape(
        "connection 'controller.table_torque -> plant.table_torque': the source's unit 'rad/s' "
        "(dimension s-1.rad) and the target's unit 'N.m' (dimension kg.m2.s-2) are of different "
        "dimensions: not convertible")):  # fmt: skip
        Master.from_ssp(built.si.topdrive_ssp, fmus={"controller": bad})
    # connectors of different dimensions in the SSD itself
    folder = _unpack(built.si.ssp, tmp_path / "connectors")
    ssd = folder / SSD_FILE
    text = ssd.read_text()
    i = text.index('<ssd:Connector name="bit_speed" kind="input">')
    ssd.write_text(text[:i] + text[i:].replace('unit="rad/s"', 'unit="N.m"', 1))
    with pytest.raises(
        SspError,
        match=re.escape(
            "connection plant.bit_speed -> controller.bit_speed: the connectors' units 'rad/s' "
            "(dimension s-1.rad) and 'N.m' (dimension kg.m2.s-2) are of different dimensions"
        ),
    ):
        Master.from_ssp(folder)  # fmt: skip


def test_a_connection_of_which_one_end_declares_no_unit_is_refused(built, tmp_path):
    """A controller FMU whose torque output declares no unit, swapped into the N.m loop: its
    numbers may be N m, kN m or the scaled torque, and nothing tells, so the master refuses the
    connection naming both ends, their FMUs and the one unit (also the other way round, a plant
    whose input declares none). ``suppressUnitConversion="true"`` on the connection is the
    explicit opt-in: the values pass unchanged (here they are N m: the package's run). A
    dimensionless "1" against no unit is the same plain number and passes."""
    ssp = built.si.topdrive_ssp
    torque = {"table_torque": None}
    bare = tl.fmu_with_units(built.si.topdrive.fmu, tmp_path / "TopDriveBare.fmu", torque, {})
    with pytest.raises(ValueError, match=re.escape(
        "connection 'controller.table_torque -> plant.table_torque': 'plant.table_torque' of "
        "DrillStringPlantSI.fmu is in 'N.m' (dimension kg.m2.s-2), 'controller.table_torque' of "
        "TopDriveBare.fmu declares no unit, so its values cannot be checked or converted; "
        "declare the unit in its model description, or pass the values unchanged on purpose "
        'with suppressUnitConversion="true"')):  # fmt: skip
        Master.from_ssp(ssp, fmus={"controller": bare})
    plant = tl.fmu_with_units(built.si.plant.fmu, tmp_path / "PlantBare.fmu", torque, {})
    with pytest.raises(ValueError, match=re.escape(
        "'controller.table_torque' of TopDriveControllerSI.fmu is in 'N.m' (dimension "
        "kg.m2.s-2), 'plant.table_torque' of PlantBare.fmu declares no unit")):  # fmt: skip
        Master.from_ssp(ssp, fmus={"plant": plant})
    folder = _unpack(ssp, tmp_path / "opted_in")
    _edit(
        folder / SSD_FILE,
        'endElement="plant" endConnector="table_torque"',
        'endElement="plant" endConnector="table_torque" suppressUnitConversion="true"',
    )
    with kept_sys_path(), Master.from_ssp(folder, fmus={"controller": bare}) as m:
        assert m.system.conversions == {}
        a = m.run(0.1, H, progress=False)
    b = _master_run(ssp, stop=0.1)
    assert np.array_equal(a["plant.bit_speed"], b["plant.bit_speed"])
    one = tl.fmu_with_units(built.si.topdrive.fmu, tmp_path / "TopDriveOne.fmu",
                            {"table_torque": "1"}, {"1": ""})  # fmt: skip
    with kept_sys_path(), Master.from_ssp(ssp, fmus={"plant": plant, "controller": one}) as m:
        assert m.system.conversions == {}


def test_suppress_unit_conversion_passes_values_unconverted(built, tmp_path):
    knm = tl.fmu_with_units(built.si.topdrive.fmu, tmp_path / "TopDriveKNm.fmu",
                        {"table_torque": "kN.m"}, {"kN.m": KNM["kN.m"]})  # fmt: skip
    folder = _unpack(built.si.topdrive_ssp, tmp_path / "suppressed")
    _edit(
        folder / SSD_FILE,
        'endElement="plant" endConnector="table_torque"',
        'endElement="plant" endConnector="table_torque" suppressUnitConversion="true"',
    )
    assert validate_ssp(folder) == []
    p = read_ssp(folder, unpack=False)
    assert [c.suppress_unit_conversion for c in p.connections] == [False] * 4 + [True]
    with kept_sys_path(), Master.from_ssp(folder, fmus={"controller": knm}) as m:
        assert m.system.conversions == {}
        a = m.run(0.1, H, progress=False)
    b = _master_run(built.si.topdrive_ssp, stop=0.1)
    assert np.array_equal(a["plant.bit_speed"], b["plant.bit_speed"])


# ------------------------------------------------------------------------------------------------
# fmpy.ssp
# ------------------------------------------------------------------------------------------------


def test_fmpy_ssp_with_an_explicit_parameter_set(built, tmp_path):
    si = built.si
    stop = 0.5
    got = run_fmpy_ssp(si.ssp, "fig6", stop, H)
    n = len(got)
    assert n in (500, 501)  # fmpy steps while its accumulated time is below the stop time
    starts = {
        c: {k: v for k, (_, v) in vals.items()}
        for c, vals in read_ssp(si.ssp, unpack=False).start_values("fig6").items()
    }
    with kept_sys_path():
        ref = tl.jacobi_fmpy(si, 0, n, starts, points=tl.ecos_grid(H, n), initial_exchange=False)
    names = [f"plant.{r}" for r in si.record]
    for j, name in enumerate(names):
        assert np.max(np.abs(got[name] - ref[:, 1 + j])) <= 1e-12 * np.max(np.abs(ref[:, 1 + j])), (
            name
        )
    # fmpy applies none of the bindings: Fig. 6's SSD as the default of an archive of its own
    # runs the FMUs' start values unless the set is given explicitly
    folder = variant_folder(si.ssp, "fig6", tmp_path / "fig6")
    archive = Path(shutil.make_archive(str(tmp_path / "fig6"), "zip", folder))
    plain = run_fmpy_ssp(archive, None, stop, H)
    with kept_sys_path():
        defaults = tl.jacobi_fmpy(si, 0, n, {}, points=tl.ecos_grid(H, n), initial_exchange=False)
    assert (
        np.max(np.abs(plain["plant.bit_speed"] - defaults[:, 1 + si.record.index("bit_speed")]))
        <= 1e-12
    )
    assert np.max(np.abs(plain["plant.bit_speed"] - got["plant.bit_speed"])) > 0.1


# ------------------------------------------------------------------------------------------------
# the command line and the demo's SI step
# ------------------------------------------------------------------------------------------------


def test_cosim_command_writes_cross_check_csv_and_png(built, tmp_path, capsys):
    out = tmp_path / "si"
    with kept_sys_path():
        code = cosim_main(
            [str(built.si.ssp), "--out", str(out), "--stop-time", "0.2", "--no-progress"]
        )
    assert code == 0, capsys.readouterr().err
    lines = (out / "cosim.csv").read_text().splitlines()
    assert lines[0].startswith('"time","plant.bit_angle"')
    assert len(lines) == 1 + 201
    data = np.genfromtxt(out / "cosim.csv", delimiter=",", names=True)
    ref = _master_run(built.si.ssp, stop=0.2)  # SystemStructure.ssd, default coupling
    assert np.array_equal(data["plantbit_speed"], ref["plant.bit_speed"])
    assert (out / "speeds.png").stat().st_size > 10_000
    summary = json.loads((out / "cosim.json").read_text())
    assert (summary["variant"], summary["ssd"], summary["parameter_set"]) == (
        "fig5", SSD_FILE, None)  # fmt: skip
    assert summary["sets_applied"] == ["fig5"] and summary["unit_system"] == "si"
    # the scaled package, a variant, its own step
    code = cosim_main(
        [str(built.ssp), "--out", str(tmp_path / "sc"), "--variant", "fig6",
         "--stop-time", "0.5", "--step", "0.01", "--no-progress"]
    )  # fmt: skip
    assert code == 0 and (tmp_path / "sc" / "speeds.png").is_file()
    summary = json.loads((tmp_path / "sc" / "cosim.json").read_text())
    assert (summary["unit_system"], summary["ssd"], summary["sets_applied"]) == (
        "scaled", "fig6.ssd", ["fig6"])  # fmt: skip
    data = np.genfromtxt(tmp_path / "sc" / "cosim.csv", delimiter=",", names=True)
    assert data["plantdphi"][0] == FIG6.dphi0
    capsys.readouterr()
    code = cosim_main([str(built.ssp), "--out", str(tmp_path / "x"), "--variant", "fig7"])
    assert code == 2 and "no variant 'fig7'" in capsys.readouterr().err
    code = cosim_main([str(built.ssp), "--out", str(tmp_path / "x"), "--parameter-set", "gains"])
    assert code == 2 and "no parameter set 'gains'" in capsys.readouterr().err


def _forge_guid(fmu: Path) -> str:
    """Rewrite the GUID in ``fmu``'s modelDescription.xml (the FMU's binary keeps its own);
    returns the forged GUID."""
    with zipfile.ZipFile(fmu) as z:
        members = {i.filename: z.read(i) for i in z.infolist()}
    md = members["modelDescription.xml"].decode()
    guid = re.search(r'guid="([^"]+)"', md).group(1)
    forged = "{00000000-0000-0000-0000-000000000000}"
    assert guid != forged
    members["modelDescription.xml"] = md.replace(guid, forged).encode()
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in members.items():
            z.writestr(name, data)
    return forged


def test_cosim_refused_input_exits_2_with_one_line(built, tmp_path, capsys):
    """Whatever the FMUs or the command refuse before the first step is bad input: exit status 2
    and one line naming the component, the variable and the value (no traceback), the results
    up to there written (``cosim.json`` says the run did not complete)."""

    def refused(package: Path, out: Path) -> str:
        capsys.readouterr()
        with kept_sys_path():
            code = cosim_main([str(package), "--out", str(out), "--stop-time", "0.1",
                               "--no-progress"])  # fmt: skip
        err = capsys.readouterr().err
        assert code == 2, err
        assert len(err.strip().splitlines()) == 1, err
        return err

    # a negative psi in the plant's .ssv: the FMU refuses it at t = 0
    folder = _unpack(built.ssp, tmp_path / "psi")
    ssv = folder / "resources" / "fig5.plant.ssv"
    text = ssv.read_text()
    psi = re.search(r'name="psi">\s*<ssv:Real value="([^"]+)"', text).group(1)
    _edit(ssv, f'name="psi">\n      <ssv:Real value="{psi}"', 'name="psi">\n      '
          '<ssv:Real value="-1.5"')  # fmt: skip
    err = refused(folder, tmp_path / "out_psi")
    assert "component 'plant'" in err and "psi = -1.5" in err, err
    summary = json.loads((tmp_path / "out_psi" / "cosim.json").read_text())
    assert summary["completed"] is False and "psi = -1.5" in summary["failure"]
    # a GUID that is not the FMU's
    folder = _unpack(built.ssp, tmp_path / "guid")
    forged = _forge_guid(folder / "resources" / built.plant.fmu.name)
    err = refused(folder, tmp_path / "out_guid")
    assert "component 'plant'" in err and f"GUID {forged}" in err, err
    # an FMU that is not a zip archive, in a folder and in an archive
    folder = _unpack(built.ssp, tmp_path / "notzip")
    member = f"resources/{built.controller.fmu.name}"
    (folder / member).write_text("not a zip archive")
    err = refused(folder, tmp_path / "out_notzip")
    assert f"component 'controller': '{member}' of notzip is not a readable FMU: not a zip" in err
    archive = tmp_path / "notzip.ssp"
    with zipfile.ZipFile(archive, "w") as z:
        for f in sorted(folder.rglob("*")):
            z.write(f, f.relative_to(folder).as_posix())
    err = refused(archive, tmp_path / "out_notzip_ssp")
    assert f"component 'controller': '{member}' of notzip.ssp is not a readable FMU" in err, err
    # --out naming an existing file, or a folder in one
    (tmp_path / "a_file").write_text("")
    err = refused(built.ssp, tmp_path / "a_file")
    assert f"--out '{tmp_path / 'a_file'}' is a file, not a folder" in err, err
    err = refused(built.ssp, tmp_path / "a_file" / "sub")
    assert f"'{tmp_path / 'a_file'}' is a file, not a folder" in err, err


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_cosim_removes_its_temporary_folders_when_terminated(built, tmp_path, signum):
    """``drillstring cosim`` killed with SIGTERM (or interrupted) in the middle of a run removes
    the unpacked package and FMUs (``cosim_ssp_*``, ``cosim_master_*``) as on a normal exit;
    SIGTERM still ends it as the signal does, Ctrl-C with status 130."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    cmd = [sys.executable, "-m", "drillstring.apps.cli", "cosim", str(built.si.ssp), "--out",
           str(tmp_path / "out"), "--stop-time", "1e5", "--no-progress"]  # fmt: skip
    proc = subprocess.Popen(cmd, env={**os.environ, "TMPDIR": str(tmp)}, cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while len({p.name.split("_")[1] for p in tmp.glob("cosim_*")}) < 2:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no temporary folders within 120 s"
            time.sleep(0.05)
        time.sleep(1.0)  # in the run (the folders are made before it starts)
        assert proc.poll() is None
        proc.send_signal(signum)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    expected = -signal.SIGTERM if signum == signal.SIGTERM else 130
    assert proc.returncode == expected, (proc.returncode, err)
    if signum == signal.SIGINT:
        assert err.strip().splitlines()[-1] == "drillstring cosim: interrupted", err
    assert sorted(p.name for p in tmp.iterdir()) == []


def test_cosim_parameter_sets_apply_in_order(built, tmp_path, capsys):
    """``--parameter-set A,B``: B's values win where both set one (complete sets: B's run)."""
    ssp = built.topdrive_ssp
    runs = {}
    for sets in ("fig5,fig6-z-torque", "fig6-z-torque,fig5", "none"):
        out = tmp_path / sets.replace(",", "_")
        code = cosim_main([str(ssp), "--out", str(out), "--parameter-set", sets,
                           "--stop-time", "1.0", "--no-progress"])  # fmt: skip
        assert code == 0, capsys.readouterr().err
        runs[sets] = np.genfromtxt(out / "cosim.csv", delimiter=",", names=True)
        summary = json.loads((out / "cosim.json").read_text())
        assert summary["sets_applied"] == ([] if sets == "none" else sets.split(","))
    z = _master_run(ssp, variant="fig6-z-torque", stop=1.0)
    five = _master_run(ssp, stop=1.0)
    assert np.array_equal(runs["fig5,fig6-z-torque"]["plantdphi"], z["plant.dphi"])
    assert np.array_equal(runs["fig6-z-torque,fig5"]["plantdphi"], five["plant.dphi"])
    assert np.array_equal(runs["none"]["plantdphi"], five["plant.dphi"])  # fig5: start values
    assert runs["fig5,fig6-z-torque"]["plantdphi"][0] == FIG6.dphi0


def test_run_si_demo_agrees_with_ecos_and_the_monolithic_solver(built, tmp_path):
    s = run_si_demo(built.out, tmp_path, stop_time=1.0)
    assert s["steps"] == 1000
    assert s["ecos_vs_master"] <= 1e-9
    for host in ("master", "ecos"):
        # the coupling error of a zero-order hold at H = 1 ms: small, not zero
        for name, err in s["relative_error"][host].items():
            assert 1e-6 < err < 0.05, (host, name, err)
    assert Path(s["files"]["png"]).is_file()
    assert json.loads((tmp_path / "si_fig5.json").read_text())["steps"] == 1000
    lines = si_demo_lines(s)
    assert len(lines) == 4 and lines[-1].startswith("  Ecos vs master: max relative difference")


def test_write_ssp_round_trips_unit_factors_and_suppression(built, tmp_path):
    """A package written with a unit of factor and offset and a suppressed connection reads
    back with them (the writer and the reader agree on SSP's BaseUnit)."""
    p = read_ssp(built.si.ssp)
    try:
        comps = []
        for c in p.components:
            sets = (
                {"s": (SspParameter("t_on", "Real", 250.0, "ms"),)}
                if c.name == "controller"
                else {}
            )
            comps.append(SspComponent(c.name, c.source, c.connectors, sets))
        cons = [SspConnection(*[getattr(c, f) for f in ("start_element", "start_connector",
                "end_element", "end_connector")], suppress_unit_conversion=i == 0)
                for i, c in enumerate(p.connections)]  # fmt: skip
        units = {**UNITS, "ms": UnitDef("ms", {"s": 1}, factor=1e-3, offset=0.5)}
        out = write_ssp(tmp_path / "u.ssp", name="u", components=comps,
                        fmus={c.name: p.fmu(c.name) for c in comps}, connections=cons,
                        units=units)  # fmt: skip
    finally:
        shutil.rmtree(p.root, ignore_errors=True)
    q = read_ssp(out, unpack=False)
    t_on = q.parameters()["controller"]["t_on"]
    assert (t_on.unit_def.factor, t_on.unit_def.offset) == (1e-3, 0.5)
    assert [c.suppress_unit_conversion for c in q.connections] == [True, False, False, False, False]
    assert isinstance(q.components[0].connectors[0], SspConnector)
