"""Command line of the build: ``python build_fmus.py`` in a source checkout, ``drillstring fmus``
wherever the package is installed."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from drillstring.apps.export.build import DEFAULT_OUT, build_fmus
from drillstring.apps.export.specs import BuildError
from drillstring.controller.gains import DEFAULT_GAINS_PATH
from drillstring.validation import check_out_folder

__all__ = ["export_main"]

#: The values of ``--fmi``: the FMI versions built.
_FMI_CHOICES = {"2": (2,), "3": (3,), "both": (2, 3)}


def export_main(argv: Sequence[str] | None = None, prog: str = "drillstring fmus") -> int:
    """Command line entry point of the build.

    Parameters
    ----------
    argv : sequence of str, optional
        The options (default: ``sys.argv[1:]``).
    prog : str
        The command as its usage names it (``build_fmus.py`` in a checkout).

    Returns
    -------
    int
        The exit status: 0 built, 1 build or validation error, 2 bad input (a ``--gains`` file
        that does not exist without ``--design``, an ``--out`` that is a file).
    """
    ap = argparse.ArgumentParser(
        prog=prog,
        description="Build, post-process and validate the drillstring plant and controller FMUs.",
    )
    ap.add_argument(
        "--gains",
        type=Path,
        default=None,
        help=f"gains file of the design (default: {DEFAULT_GAINS_PATH}, designed if missing); "
        "a file given here must exist unless --design is given",
    )
    ap.add_argument(
        "--design",
        action="store_true",
        help="design the controller into the --gains file when it does not exist (the LMI "
        "synthesis; drillstring design does the same with its options)",
    )
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder (default: build/)")
    ap.add_argument(
        "--self-contained",
        action="store_true",
        help="bundle the Python runtime and the compiled kernel into every FMU (about 100 MB "
        "each): they run on a Linux x86-64 machine without Python (docs/fmus.md)",
    )
    ap.add_argument(
        "--fmi",
        choices=sorted(_FMI_CHOICES),
        default=None,
        help="the FMI versions built: 2 (the FMI 2.0 FMUs and SSP packages), 3 (the FMI 3.0 "
        "twins, X3.fmu) or both (default; 2 with --self-contained, whose FMUs are 100 MB each)",
    )
    args = ap.parse_args(argv)
    fmi = _FMI_CHOICES[args.fmi or ("2" if args.self_contained else "both")]
    try:
        check_out_folder("--out", args.out)
        if args.gains is not None and not args.design and not args.gains.is_file():
            raise ValueError(
                f"--gains {str(args.gains)!r}: no such file (give --design to design the "
                "controller into it, or drillstring design --out DIR to write DIR/gains.json)"
            )
    except ValueError as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2
    try:
        built = build_fmus(args.out, args.gains, self_contained=args.self_contained, fmi=fmi)
    except BuildError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 1
    for path in built.values():
        check = "fmpy.validate_fmu" if path.suffix == ".fmu" else "SSP 1.0 schemas (fmpy's)"
        print(f"{path}: {check}: 0 problems")
    return 0
