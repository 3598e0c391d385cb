"""Independent FMU checkers on every FMU the session's build writes.

Three checkers, each one test that lists every finding of every ``*.fmu`` in the build folder
(whatever is there: the FMI 2.0 FMUs and any FMI 3.0 twin beside them), so that one failing FMU
does not hide the findings on the others:

* ``fmutool -check`` (fmu-manipulation-toolbox, the command line, run headless: no Qt, no
  display): its generic check validates the model description against the FMI 2.0 or 3.0 XSD it
  ships (with ``xmlschema``), its semantic check the standard's rules the schema cannot express
  (causality/variability/initial combinations, start values, ``ModelStructure`` against the
  outputs and their dependencies);
* fmpy's ``validate_fmu`` (its own rules, and the schema first: it stops there on a schema error);
* the schema of the model description's own FMI version, the XSDs fmpy ships, with lxml: every
  schema error, whatever fmpy's other rules say.

Each checker is shown to find a broken model description (an output left out of the
``ModelStructure``, a causality the standard does not know), so that a clean result means the
checker ran and found nothing, not that the harness lost its output.
"""

from __future__ import annotations

import os
import re
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import fmpy
import fmu_testlib as tl
import pytest
from fmpy.validation import validate_fmu
from lxml import etree

pytestmark = pytest.mark.fmu

#: fmutool of this environment (the test extra installs fmu-manipulation-toolbox)
FMUTOOL = Path(sys.executable).with_name("fmutool")
#: The XSD of each FMI version's model description, as fmpy ships them.
SCHEMAS = {
    "2.0": Path(fmpy.__file__).with_name("schema") / "fmi2" / "fmi2ModelDescription.xsd",
    "3.0": Path(fmpy.__file__).with_name("schema") / "fmi3" / "fmi3ModelDescription.xsd",
}
_ANSI = re.compile(r"\x1b\[[0-9;]*m")  # fmutool colours its log lines even into a pipe


def _model_description(fmu: Path) -> bytes:
    with zipfile.ZipFile(fmu) as z:
        return z.read("modelDescription.xml")


def _fmi_version(fmu: Path) -> str:
    return ET.fromstring(_model_description(fmu)).get("fmiVersion", "")


def fmutool_findings(fmu: Path) -> list[str]:
    """What ``fmutool -input FMU -check`` reports: its warnings and errors, a non-zero exit
    status, and the absence of either checker's verdict of compliance for the FMU's FMI version
    (so that a checker that did not run is a finding too)."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    run = tl.run_clean([str(FMUTOOL), "-input", str(fmu), "-check"], env, None, 300)
    lines = [_ANSI.sub("", line).strip() for line in run.stdout.splitlines()]
    findings = [
        line
        for line in lines
        if line.split("|", 1)[0].strip() in ("WARNING", "ERROR", "CRITICAL", "FATAL")
    ]
    if run.returncode != 0:
        findings.append(f"exit status {run.returncode} {run.stderr.strip()}".rstrip())
    version = _fmi_version(fmu)
    for verdict in (
        f"This FMU seems to be compliant with FMI-{version}.",
        f"No semantic error against the FMI-{version[:1]} standard.",
    ):
        if not any(line.endswith(verdict) for line in lines):
            findings.append(f"no verdict {verdict!r}")
    return findings


def schema_findings(fmu: Path) -> list[str]:
    """Every error of the model description against the XSD of its ``fmiVersion``."""
    root = etree.fromstring(_model_description(fmu))
    version = root.get("fmiVersion")
    if version not in SCHEMAS:
        return [f"fmiVersion {version!r} is neither of {sorted(SCHEMAS)}"]
    schema = etree.XMLSchema(file=str(SCHEMAS[version]))
    if schema.validate(root):
        return []
    return [f"line {e.line}: {e.message}" for e in schema.error_log]


def _build_fmus(built: tl.Built) -> list[Path]:
    fmus = sorted(built.out.glob("*.fmu"))
    # the FMI 2.0 FMUs of every build; any other FMU in the folder is checked as well
    six = {tl.PLANT, tl.CONTROLLER, tl.TOPDRIVE, tl.PLANT_SI, tl.CONTROLLER_SI, tl.TOPDRIVE_SI}
    assert six <= {f.stem for f in fmus}, fmus
    return fmus


def _report(check) -> dict[str, list[str]]:
    return {fmu.name: found for fmu, found in check.items() if found}


def test_fmutool_check_finds_nothing(built):
    findings = _report({fmu: fmutool_findings(fmu) for fmu in _build_fmus(built)})
    assert findings == {}


def test_fmpy_validate_finds_nothing(built):
    findings = _report({fmu: validate_fmu(str(fmu)) for fmu in _build_fmus(built)})
    assert findings == {}


def test_model_descriptions_are_valid_against_their_fmi_schema(built):
    fmus = _build_fmus(built)
    assert {_fmi_version(fmu) for fmu in fmus} <= set(SCHEMAS)
    findings = _report({fmu: schema_findings(fmu) for fmu in fmus})
    assert findings == {}


def test_each_checker_finds_a_broken_model_description(built, tmp_path):
    """The plant with its first output left out of ``ModelStructure/Outputs`` (schema-valid,
    against section 2.2.8 of FMI 2.0) and a parameter of causality "sometimes" (not in the
    schema's enumeration)."""
    broken = tmp_path / f"{tl.PLANT}.fmu"
    with tl.edited_model_description(built.plant.fmu, broken) as root:
        outputs = root.find("ModelStructure/Outputs")
        first = outputs[0]
        outputs.remove(first)
        svs = root.find("ModelVariables")
        output_name = svs[int(first.get("index")) - 1].get("name")
        parameter = next(sv for sv in svs if sv.get("causality") == "parameter")
        parameter.set("causality", "sometimes")

    found = fmutool_findings(broken)
    assert any(f"Output '{output_name}' is not listed in <Outputs>" in f for f in found), found
    assert any("sometimes" in f and f.startswith("ERROR") for f in found), found
    assert any(f.startswith("exit status 7") for f in found), found  # CHECK_FAILED
    assert any("sometimes" in p for p in validate_fmu(str(broken))), validate_fmu(str(broken))
    schema = schema_findings(broken)
    assert len(schema) == 1 and "'sometimes'" in schema[0], schema
