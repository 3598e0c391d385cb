"""A command run as on another machine (this module is not collected): in a mount namespace of
its own (``unshare -m``; ``unshare -rm``, a user namespace, when not root), with empty folders
bind-mounted over every Python installation of this machine, the virtual environment, the
project's checkout and the user caches, and empty files over chosen libraries.

Inside, no Python runs (the script checks that ``python3`` fails, and refuses to run the command
otherwise: exit status :data:`PYTHON_STILL_RUNS`), and nothing of the build is reachable: what
the command finds is what it brings.
"""

from __future__ import annotations

import os
import pwd
import shutil
import subprocess
import sys
import sysconfig
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Exit status of the namespace's script when a Python still runs inside it.
PYTHON_STILL_RUNS = 97

_SCRIPT = f"""set -e
empty_dir=$1; empty_file=$2; shift 2
while [ "$1" != "--" ]; do
  if [ -d "$1" ]; then mount --bind "$empty_dir" "$1"; else mount --bind "$empty_file" "$1"; fi
  shift
done
shift
while [ "$1" != "--" ]; do
  mount --bind "$1" "$1"; mount -o remount,bind,ro "$1" "$1"; shift
done
shift
for py in python3 python3.11 python; do
  if command -v "$py" >/dev/null 2>&1 && "$py" -c pass >/dev/null 2>&1; then
    echo "isolation: $py still runs" >&2; exit {PYTHON_STILL_RUNS}
  fi
done
exec "$@"
"""


def python_installations() -> list[Path]:
    """The folders of every Python installation this machine has that a process could find:
    the building Python, the virtual environment, pyenv's root, the system's and /usr/local's
    standard libraries."""
    found = {Path(sys.base_prefix).resolve(), Path(sys.prefix).resolve()}
    for parent in Path(sys.base_prefix).resolve().parents:
        if parent.name == ".pyenv":
            found.add(parent)
    for base in (Path("/usr/lib"), Path("/usr/local/lib")):
        found.update(p for p in base.glob("python3*") if p.is_dir())
    return sorted(found)


def python_libraries() -> list[Path]:
    """Shared libpython files of the system outside those folders."""
    libs = set()
    for base in (
        Path("/usr/lib/x86_64-linux-gnu"),
        Path("/lib/x86_64-linux-gnu"),
        Path("/usr/lib"),
    ):
        libs.update(p.resolve() for p in base.glob("libpython3*.so*") if p.exists())
    return sorted(libs)


def user_caches(*homes: Path) -> list[Path]:
    """The cache folders of the given HOMEs, of the real user and ``$XDG_CACHE_HOME``."""
    caches = [Path(pwd.getpwuid(os.getuid()).pw_dir) / ".cache", *(h / ".cache" for h in homes)]
    if os.environ.get("XDG_CACHE_HOME"):
        caches.append(Path(os.environ["XDG_CACHE_HOME"]))
    return [c for c in caches if c.is_dir()]


def system_library(name: str) -> Path:
    """The file of the system's library ``name`` (``libffi.so.8``), as the dynamic loader finds
    it for this interpreter's ``_ctypes``."""
    module = Path(sysconfig.get_paths()["stdlib"]) / "lib-dynload"
    for ext in module.glob("_ctypes.*.so"):
        out = subprocess.run(["ldd", str(ext)], capture_output=True, text=True, check=True)
        for line in out.stdout.splitlines():
            parts = line.split()
            if parts and parts[0] == name and len(parts) >= 3:
                return Path(parts[2]).resolve()
    raise AssertionError(f"no system library {name} found for _ctypes")


def isolated(
    cmd: Sequence[str],
    work: Path,
    hide: Sequence[Path],
    hide_files: Sequence[Path] = (),
    read_only: Sequence[Path] = (),
) -> list[str]:
    """``cmd`` run in a mount namespace where ``hide`` (folders) and ``hide_files`` are empty
    and the folders ``read_only`` cannot be written (read-only bind mounts of themselves: root
    ignores permission bits, a mount does not).

    Parameters
    ----------
    cmd : sequence of str
        The command; its program must lie outside ``hide``.
    work : Path
        A folder outside ``hide`` for the empty folder and file mounted over them.
    hide, hide_files : sequence of Path
        What the command must not see.
    read_only : sequence of Path
        Folders (outside ``hide``) the command sees but cannot write.

    Returns
    -------
    list of str
        The argument list for :mod:`subprocess`.
    """
    unshare = shutil.which("unshare")
    if unshare is None:
        raise AssertionError("unshare (util-linux) is needed to run a command in isolation")
    empty_dir, empty_file = work / "empty-dir", work / "empty-file"
    empty_dir.mkdir(exist_ok=True)
    empty_file.touch()
    flags = "-m" if os.geteuid() == 0 else "-rm"
    folders = [Path(p) for p in hide]
    # what lies inside a hidden folder is hidden with it (and could not be mounted over after it)
    outer = [p for p in dict.fromkeys([*folders, *map(Path, hide_files)])
             if not any(f in p.parents for f in folders)]  # fmt: skip
    return [
        unshare,
        flags,
        "--",
        "sh",
        "-c",
        _SCRIPT,
        "isolated",
        str(empty_dir),
        str(empty_file),
        *map(str, outer),
        "--",
        *map(str, read_only),
        "--",
        *cmd,
    ]
