"""``drillstring ecos ARGS``: Ecos's command line (ecospy's ``ecos``), as a user can type it.

pip installs the ecospy wheel's ``ecos`` binary inside the package, without its executable bit
and without the tbb library on the loader's path, and puts no ``ecos`` on ``PATH``. This command
starts it the one way that works, through the dynamic loader with the tbb wheel's library folder
(:func:`~drillstring.orchestration.hosts.ecos_command`), and replaces itself with it: the
arguments, the output, the exit status and the signals are Ecos's own. Example (the README's)::

    drillstring ecos simulate --path build/DrillStringClosedLoopSI.ssp --stepSize 0.001 \\
        --stopTime 55.352 --parameterSet fig5
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from drillstring.orchestration.hosts import ecos_command

__all__ = ["ecos_main"]


def ecos_main(argv: Sequence[str] | None = None) -> int:
    """Run ``ecos ARGS`` in place of this process (``os.execv``: it does not return).

    Parameters
    ----------
    argv : sequence of str, optional
        Ecos's arguments (default: ``sys.argv[1:]``), e.g. ``["simulate", "--path", ...]``;
        ``-h`` is Ecos's help.

    Returns
    -------
    int
        Only when Ecos cannot be started: 1 (ecospy or tbb not installed, or the loader or the
        binary missing), with the reason on stderr.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    try:
        cmd = ecos_command(*args)
    except RuntimeError as exc:
        print(f"drillstring ecos: {exc}", file=sys.stderr)
        return 1
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        os.execv(cmd[0], cmd)
    except OSError as exc:
        print(f"drillstring ecos: cannot start {cmd[0]} for {cmd[3]}: {exc}", file=sys.stderr)
        return 1
    return 1  # pragma: no cover (execv does not return)
