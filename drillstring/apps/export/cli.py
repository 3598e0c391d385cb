"""Command line of the build: ``python build_fmus.py`` in a source checkout, ``drillstring fmus``
wherever the package is installed."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from drillstring.apps.export.build import DEFAULT_OUT, build_fmus
from drillstring.apps.export.specs import BuildError

__all__ = ["export_main"]


def export_main(argv: Sequence[str] | None = None) -> int:
    """Command line entry point; returns the exit status (0 ok, 1 build or validation error)."""
    ap = argparse.ArgumentParser(
        prog="build_fmus.py",
        description="Build, post-process and validate the drillstring plant and controller FMUs.",
    )
    ap.add_argument(
        "--gains",
        type=Path,
        default=None,
        help="gains file of the design (default: out/design/gains.json, designed if missing)",
    )
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder (default: build/)")
    ap.add_argument(
        "--self-contained",
        action="store_true",
        help="bundle the Python runtime and the compiled kernel into every FMU (about 100 MB "
        "each): they run on a Linux x86-64 machine without Python (docs/fmus.md)",
    )
    args = ap.parse_args(argv)
    try:
        built = build_fmus(args.out, args.gains, self_contained=args.self_contained)
    except BuildError as exc:
        print(f"build_fmus: error: {exc}", file=sys.stderr)
        return 1
    for path in built.values():
        check = "fmpy.validate_fmu" if path.suffix == ".fmu" else "SSP 1.0 schemas (fmpy's)"
        print(f"{path}: {check}: 0 problems")
    return 0
