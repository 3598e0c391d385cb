"""Build the master's test FMUs with pythonfmu and state their true ModelStructure.

pythonfmu lists every output without a ``dependencies`` attribute, which in FMI 2.0
means "depends on all inputs": a master would then see false algebraic loops. Each
script here declares ``OUTPUT_DEPENDENCIES`` and :func:`build_test_fmus` writes it into
``ModelStructure/Outputs`` of the built FMU.
"""

from __future__ import annotations

import importlib.util
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

HERE = Path(__file__).resolve().parent
SCRIPTS = {
    "integrator": HERE / "msttest_integrator.py",
    "gain": HERE / "msttest_gain.py",
    "oscillator": HERE / "msttest_oscillator.py",
}


def _output_dependencies(script: Path) -> dict[str, list[str]]:
    spec = importlib.util.spec_from_file_location(f"_deps_{script.stem}", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.OUTPUT_DEPENDENCIES


def _patch_model_structure(fmu: Path, deps: dict[str, list[str]]) -> None:
    with zipfile.ZipFile(fmu) as z:
        entries = {info.filename: z.read(info.filename) for info in z.infolist()}
    root = ET.fromstring(entries["modelDescription.xml"])
    variables = root.find("ModelVariables").iter("ScalarVariable")
    index = {sv.get("name"): i + 1 for i, sv in enumerate(variables)}
    name_of = {v: k for k, v in index.items()}
    outputs = root.find("ModelStructure/Outputs")
    seen = set()
    for unknown in outputs.iter("Unknown"):
        name = name_of[int(unknown.get("index"))]
        seen.add(name)
        unknown.set("dependencies", " ".join(str(index[d]) for d in deps[name]))
        unknown.set("dependenciesKind", " ".join("fixed" for _ in deps[name]))
    if seen != set(deps):
        raise RuntimeError(f"{fmu.name}: OUTPUT_DEPENDENCIES {sorted(deps)} != {sorted(seen)}")
    # FMI 2.0 wants every output with initial="calculated" (the default) listed as an
    # initial unknown; no dependencies attribute = may depend on all start values.
    structure = root.find("ModelStructure")
    initial = ET.Element("InitialUnknowns")
    for unknown in outputs.iter("Unknown"):
        ET.SubElement(initial, "Unknown", index=unknown.get("index"))
    structure.insert(list(structure).index(outputs) + 1, initial)
    entries["modelDescription.xml"] = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
    tmp = fmu.with_suffix(".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in entries.items():
            z.writestr(name, data)
    tmp.replace(fmu)


def build_test_fmus(dest: Path) -> dict[str, Path]:
    """Build every test FMU into ``dest``; returns {short name: path to .fmu}."""
    from pythonfmu import FmuBuilder

    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    saved_path = list(sys.path)
    built = {}
    try:
        for name, script in SCRIPTS.items():
            fmu = FmuBuilder.build_FMU(
                script, dest=dest, canGetAndSetFMUstate=True, canSerializeFMUstate=True
            )
            _patch_model_structure(Path(fmu), _output_dependencies(script))
            built[name] = Path(fmu)
    finally:
        sys.path[:] = saved_path
    return built
