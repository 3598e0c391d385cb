"""The ``drillstring`` command: simulate, axial analysis, controller design, co-simulation
cross-check, parameter sweeps and the demo pipeline.

Every subcommand writes CSV/JSON/PNG files into an output folder and exits with 0 on success,
2 on bad input (with a message naming the bad value); ``simulate`` exits with 1 when the run
stopped early, ``cosim`` when an FMU stopped it, ``sweep`` with 1 when points failed and with 130
when interrupted. Each subcommand's entry point (:data:`COMMANDS`) takes the arguments after
the subcommand's name (``argv``, default ``sys.argv[1:]``) and returns the exit code. A
subcommand's module is imported when it runs, so that ``drillstring -h`` does not load cvxpy,
dask and fmpy.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Sequence

import numpy as np

__all__ = ["COMMANDS", "main"]

#: subcommand -> (module, entry point taking argv, one-line description)
COMMANDS: dict[str, tuple[str, str, str]] = {
    "simulate": ("drillstring.apps.simulate", "simulate_main", "one run of the full model"),
    "axial": ("drillstring.apps.axial", "axial_main", "Section III: Figs. 2-4"),
    "design": ("drillstring.apps.design", "design_main", "Sections IV-V: LMI design, gains"),
    "modes": ("drillstring.apps.modes", "modes_main", "modes of the distributed string"),
    "string-spectrum": (
        "drillstring.apps.string_spectrum",
        "string_spectrum_main",
        "every law's linearised spectrum on the N-element string",
    ),
    "crosscheck": ("drillstring.apps.crosscheck", "crosscheck_main", "co-simulation vs monolithic"),
    "cosim": ("drillstring.apps.cosim", "cosim_main", "co-simulation of an SSP package"),
    "ecos": ("drillstring.apps.ecos", "ecos_main", "Ecos's command line (ecospy's ecos)"),
    "sweep": ("drillstring.apps.sweep.runner", "sweep_main", "parameter sweeps on Dask"),
    "controllers": ("drillstring.apps.controllers", "controllers_main", "industrial vs LMI"),
    "fmus": ("drillstring.apps.export.cli", "export_main", "build the FMUs and SSP packages"),
    "demo": ("drillstring.apps.demo", "demo_main", "the main job (make demo)"),
}


def _usage() -> str:
    lines = ["usage: drillstring COMMAND [options]   (drillstring COMMAND -h for help)", ""]
    width = max(len(name) for name in COMMANDS)
    lines += [f"  {name:<{width}}  {desc}" for name, (_, _, desc) in COMMANDS.items()]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``drillstring`` console script.

    Dispatches to the subcommand's entry point (:data:`COMMANDS`); no command, ``-h`` or
    ``--help`` prints the list of commands.

    Parameters
    ----------
    argv : sequence of str, optional
        The command and its arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The subcommand's exit code; 0 for the help text, 2 for an unknown command.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0
    if argv[0] not in COMMANDS:
        print(_usage())
        print(f"drillstring: unknown command {argv[0]!r}", file=sys.stderr)
        return 2
    module, func, _ = COMMANDS[argv[0]]
    np.seterr(all="ignore")
    return int(getattr(importlib.import_module(module), func)(argv[1:]))


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
