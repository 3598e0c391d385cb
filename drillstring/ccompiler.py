"""The system's C compiler, as the project's native parts find it (the FMUs' front layer built by
``build_fmus.py``, the master's native loop of :mod:`drillstring.orchestration.native_loop`)."""

from __future__ import annotations

import os
import shlex
import shutil

__all__ = ["CompilerNotFound", "find_c_compiler"]


class CompilerNotFound(LookupError):
    """No usable C compiler (the message says where it was looked for)."""


def find_c_compiler() -> list[str]:
    """The C compiler command: ``$CC`` (split like a shell would), else ``cc``, ``gcc`` or
    ``clang`` on PATH.

    Returns
    -------
    list of str
        The command and its own arguments (from ``$CC``).

    Raises
    ------
    CompilerNotFound
        ``$CC`` names no program on PATH, or none of the three is there.
    """
    if os.environ.get("CC"):
        cmd = shlex.split(os.environ["CC"])
        if shutil.which(cmd[0]) is None:
            raise CompilerNotFound(f"CC={os.environ['CC']!r}: {cmd[0]} not found")
        return cmd
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path is not None:
            return [path]
    raise CompilerNotFound("no C compiler found (looked for $CC, cc, gcc, clang)")
