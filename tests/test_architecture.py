"""The package's layers point one way, and the user API is importable from the package root.

Layers, each importing only itself and those before it: the foundation modules (fileio,
validation, plotting, ccompiler), model, analysis, controller, orchestration, apps. The check
reads every module's import statements (an independent look at the source, not at what happens
to be imported at run time) and also rejects imports of project modules inside functions, which
would hide a cycle.
"""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

import drillstring as ds
import drillstring.model as model

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


@pytest.mark.parametrize(("module", "path"), MODULES, ids=[m for m, _ in MODULES])
def test_imports_point_one_way(module, path):
    layer = _layer(module)
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for target, in_function in _project_imports(tree):
        assert not in_function, f"{module} imports {target} inside a function"
        assert target != "drillstring", f"{module} imports the package root"
        assert _layer(target) <= layer, (
            f"{module} ({LAYERS[layer]}) imports {target} ({LAYERS[_layer(target)]})"
        )


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
        assert obj is getattr(model, name), f"drillstring.{name} is not drillstring.model.{name}"
        if inspect.isclass(obj) or inspect.isfunction(obj):
            doc = obj.__doc__ or ""
            assert doc.strip() and not doc.startswith(f"{name}("), f"{name} has no docstring"
        else:
            assert constants.get(name) == 1, f"{name}: no #: comment above its one definition"
