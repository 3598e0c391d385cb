"""The package's layers point one way, and the user API is importable from the package root.

Layers, each importing only itself and those before it: the foundation modules (fileio,
validation, plotting, ccompiler), model, analysis, controller, orchestration, apps. The check
reads every module's import statements (an independent look at the source, not at what happens
to be imported at run time) and also rejects imports of project modules inside functions, which
would hide a cycle.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import tomllib
from pathlib import Path

import drillstring as ds

ROOT = Path(__file__).resolve().parents[1]
#: folder -> package name (controller/ and orchestration/ are installed under drillstring)
PACKAGES = {
    ROOT / "drillstring": "drillstring",
    ROOT / "controller": "drillstring.controller",
    ROOT / "orchestration": "drillstring.orchestration",
}
LAYERS = ("foundation", "model", "analysis", "controller", "orchestration", "apps")
FOUNDATION = (
    "drillstring.fileio",
    "drillstring.validation",
    "drillstring.plotting",
    "drillstring.ccompiler",
)


def _layer(module: str) -> int:
    if module in FOUNDATION:
        return 0
    parts = module.split(".")
    if len(parts) >= 2 and parts[1] in LAYERS:
        return LAYERS.index(parts[1])
    raise AssertionError(f"module {module} belongs to no layer")


def _modules() -> list[tuple[str, Path]]:
    out = []
    for folder, package in PACKAGES.items():
        for path in sorted(folder.rglob("*.py")):
            rel = path.relative_to(folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            out.append((".".join([package, *parts]), path))
    return out


def _project_imports(tree: ast.AST) -> list[tuple[str, bool]]:
    """(imported module, inside a function) for every import of a drillstring module."""
    found: list[tuple[str, bool]] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            if isinstance(child, ast.ImportFrom) and child.module and child.level == 0:
                if child.module.split(".")[0] == "drillstring":
                    found.append((child.module, in_function))
            elif isinstance(child, ast.Import):
                for alias in child.names:
                    if alias.name.split(".")[0] == "drillstring":
                        found.append((alias.name, in_function))
            visit(child, inner)

    visit(tree, False)
    return found


MODULES = [m for m in _modules() if m[0] != "drillstring"]


def test_imports_point_one_way():
    """Every module imports only its own layer and those before it, never the package root and
    never inside a function; every offence is listed, not the first."""
    failures = []
    for module, path in MODULES:
        layer = _layer(module)
        for target, in_function in _project_imports(ast.parse(path.read_text(encoding="utf-8"))):
            if in_function:
                failures.append(f"{module} imports {target} inside a function")
            elif target == "drillstring":
                failures.append(f"{module} imports the package root")
            elif _layer(target) > layer:
                failures.append(
                    f"{module} ({LAYERS[layer]}) imports {target} ({LAYERS[_layer(target)]})"
                )
    assert failures == []


#: The files outside the package that import it: the build command, the FMU sources, the
#: benchmarks and the tests.
SCRIPTS = sorted(
    [ROOT / "build_fmus.py"]
    + [p for d in ("fmu_src", "bench", "tests") for p in (ROOT / d).rglob("*.py")]
)


def test_no_function_local_imports_outside_the_package():
    """No import of a project module inside a function anywhere: a hidden import hides a cycle
    and a slow import. Every offending file is listed."""
    failures = []
    for path in SCRIPTS:
        tree = ast.parse(path.read_text(encoding="utf-8"))
        local = [t for t, in_function in _project_imports(tree) if in_function]
        if local:
            failures.append(f"{path.relative_to(ROOT)} imports {local} inside a function")
    assert failures == []


BENCHES = sorted((ROOT / "bench").glob("*.py")) + [ROOT / "build_fmus.py"]


def test_scripts_import_names_that_exist():
    """The benchmarks and the build command are run by hand, not by the suite: every name they
    import from the package must exist (a module moved or a name renamed breaks them first)."""
    failures = []
    for path in BENCHES:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("drillstring"):
                module = importlib.import_module(node.module)
                missing = [a.name for a in node.names if not hasattr(module, a.name)]
                if missing:
                    failures.append(f"{path.name}: {node.module} has no {missing}")
    assert failures == []


def test_build_command_is_a_thin_command_over_the_builder():
    """``build_fmus.py`` holds no build logic: it imports the builder's command line and calls
    it."""
    tree = ast.parse((ROOT / "build_fmus.py").read_text(encoding="utf-8"))
    assert _project_imports(tree) == [("drillstring.apps.export.cli", False)]
    assert not [n for n in tree.body if isinstance(n, ast.FunctionDef | ast.ClassDef)]


def test_every_package_is_installed():
    """``pyproject.toml`` lists its packages by hand (controller/, orchestration/ and fmu_src/ are
    mapped under drillstring): every folder with an ``__init__.py`` must be among them, or an
    installed (non-editable) package lacks it."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    listed = set(config["tool"]["setuptools"]["packages"])
    mapping = config["tool"]["setuptools"]["package-dir"]
    found = set()
    for package, folder in mapping.items():
        for init in sorted((ROOT / folder).rglob("__init__.py")):
            rel = init.parent.relative_to(ROOT / folder).parts
            found.add(".".join([package, *rel]))
    assert sorted(found - listed) == []
    for package in listed - found:  # a data folder (package data, no modules)
        root = max((p for p in mapping if package.startswith(p)), key=len)
        folder = ROOT / mapping[root] / Path(*package[len(root) + 1 :].split("."))
        assert folder.is_dir() and not list(folder.glob("*.py")), package


def test_no_relative_imports():
    """Absolute imports only, so that a module reads the same wherever it is bundled."""
    for module, path in _modules():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        rel = [n.lineno for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.level > 0]
        assert not rel, f"{module}: relative imports on lines {rel}"


def test_user_api_from_the_package_root():
    r = ds.simulate(ds.REFERENCE, 2.0, initial={"dphi": ds.FIG5.dphi0})
    assert r.status.ok and r.tau[-1] == 2.0


def _documented_constants() -> dict[str, int]:
    """Module-level names of drillstring/model/ assigned right below a ``#:`` comment (Sphinx's
    doc comment), with the number of such definitions."""
    found: dict[str, int] = {}
    for path in sorted((ROOT / "drillstring" / "model").rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        for node in ast.parse(text).body:
            targets = node.targets if isinstance(node, ast.Assign) else []
            if isinstance(node, ast.AnnAssign):
                targets = [node.target]
            for target in targets:
                if isinstance(target, ast.Name) and lines[node.lineno - 2].startswith("#:"):
                    found[target.id] = found.get(target.id, 0) + 1
    return found


def test_package_root_exports_exactly_its_all_each_documented():
    """``drillstring.__all__`` is the root's whole public surface (no name imported there and
    left out, none listed that is not there), each name the model's own object (the root only
    re-exports), documented: classes and functions by a docstring of their own (not the one a
    dataclass generates), constants by a ``#:`` comment above their one definition."""
    public = {n for n, v in vars(ds).items() if not n.startswith("_") and not inspect.ismodule(v)}
    assert sorted(public ^ set(ds.__all__)) == []
    constants = _documented_constants()
    for name in ds.__all__:
        obj = getattr(ds, name)
        if inspect.isclass(obj) or inspect.isfunction(obj):
            assert obj.__module__.startswith("drillstring.model."), f"{name}: not the model's"
            doc = obj.__doc__ or ""
            assert doc.strip() and not doc.startswith(f"{name}("), f"{name} has no docstring"
        else:
            assert constants.get(name) == 1, f"{name}: no #: comment above its one definition"
