"""Python interpreters other than the FMUs' own, with fmpy, as hosts of the FMUs.

The FMUs run their Python model in the interpreter of a host that is itself Python (fmpy,
libcosimpy): ``tests/test_fmu_python_hosts.py`` runs them in a CPython of another minor version
and in one of the same minor version but another build, each with its own packages, and this
module provides both, on any Debian machine with pip and root (as CI has), by a fixed rule:

The caller asks for a *choice*: an interpreter's path, or minor versions in order of preference
("3.12,3.13"; the tests take ``DRILLSTRING_TEST_OTHER_PYTHON`` and
``DRILLSTRING_TEST_SAME_MINOR_PYTHON``, see there), optionally prefixed ``debian:`` to go to
point 2 at once. For minor versions:

1. a CPython of the first of them installed on this machine, other than the one running this
   module: Debian's ``/usr/bin/pythonX.Y``, then pyenv's versions (``$PYENV_ROOT``,
   ``~/.pyenv``), then ``pythonX.Y`` on PATH; else the second, ...;
2. else Debian's own CPython of the first of them that a Debian release has, in a Debian tree
   made here by ``mmdebstrap`` (installed with apt-get if missing): Debian 13 "trixie" has
   CPython 3.13, Debian 12 "bookworm" 3.11; the host then runs in that tree (``chroot``, as
   root).

Why a Debian tree and not a package from PyPI: no Python interpreter of another version can be
had from PyPI alone. uv's managed Pythons and the python-build-standalone installers published
there (pbs-installer and the like) download their interpreters from GitHub at run time, as does
the npm installer of portable-python in its postinstall script; the project's machines and CI
reach only the package registries (PyPI, Debian's archive, npm), and Debian's archive serves
whole interpreters.

The host's packages are installed with pip of the Python that runs this module, for the host's
interpreter: ``pip --python HOST install`` into a virtual environment made with ``venv
--without-pip`` (no ensurepip needed, which Debian ships separately), or, for an interpreter in
a Debian tree (which cannot run outside it), ``pip install --target`` with the tree's version
and platform into a folder that the host finds through ``PYTHONPATH``.

Usage (prints the host's command)::

    python tools/python_hosts.py CHOICE DEST [REQUIREMENT ...]
"""

from __future__ import annotations

import os
import pwd
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

#: Debian's release whose python3 is CPython X.Y (the fallback of the module docstring, point 3).
DEBIAN_PYTHON = {"3.13": "trixie", "3.11": "bookworm"}
#: Where the host's packages live inside a Debian tree.
TREE_SITE = "/opt/host-site"
#: The platform tags of the wheels a Debian tree's interpreter takes (x86-64, glibc >= 2.36).
TREE_PLATFORMS = ("manylinux_2_28_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64")


class HostError(RuntimeError):
    """A host that cannot be provided (the message says which step failed)."""


@dataclass(frozen=True)
class Host:
    """A Python host: its interpreter and the folder its file names are relative to."""

    #: the interpreter, as a path inside ``root``
    python: str
    #: "X.Y.Z"
    version: str
    #: "/" or the Debian tree it runs in
    root: Path = Path("/")
    #: the environment variables it needs (the tree's PYTHONPATH)
    env: dict[str, str] = field(default_factory=dict)
    #: the folder its packages are installed into, inside root ("": unknown)
    site: str = ""

    def command(self, *args: str) -> list[str]:
        """The command line that runs ``python ARGS`` in this host (file names inside root)."""
        if self.root == Path("/"):
            return [self.python, *args]
        return [shutil.which("chroot") or "/usr/sbin/chroot", str(self.root), self.python, *args]

    def outside(self, inside: str) -> Path:
        """The path, from outside, of a file the host sees as ``inside`` (an absolute path)."""
        return self.root / inside.lstrip("/")

    def inside(self, outside: Path) -> str:
        """The name the host sees for ``outside`` (a path under ``root``)."""
        if self.root == Path("/"):
            return str(outside)
        return "/" + str(Path(outside).resolve().relative_to(self.root.resolve()))


def _run(
    cmd: Sequence[str], what: str, timeout: float = 900, env: dict[str, str] | None = None
) -> str:
    proc = subprocess.run(list(cmd), capture_output=True, text=True, timeout=timeout, env=env)
    if proc.returncode != 0:
        raise HostError(f"{what} failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr}")
    return proc.stdout


def _version(python: Sequence[str]) -> str:
    return _run(
        [*python, "-c", "import platform; print(platform.python_version())"],
        "asking the interpreter its version",
    ).strip()


def _home() -> Path:
    """The user's real home (the tests run with another HOME)."""
    return Path(pwd.getpwuid(os.getuid()).pw_dir)


def candidates(minor: str) -> list[Path]:
    """CPython ``minor`` ("3.12") installed on this machine, in the order of the module
    docstring (point 2); pyenv's shims are skipped (they need pyenv's own environment)."""
    found = [Path(f"/usr/bin/python{minor}")]
    roots = [os.environ.get("PYENV_ROOT", ""), str(_home() / ".pyenv")]
    for root in dict.fromkeys(r for r in roots if r):
        versions = Path(root) / "versions"
        if versions.is_dir():
            for v in sorted(versions.iterdir(), reverse=True):
                if re.fullmatch(re.escape(minor) + r"\.\d+", v.name):
                    found.append(v / "bin" / f"python{minor}")
    for folder in os.environ.get("PATH", "").split(os.pathsep):
        if folder and "shims" not in Path(folder).parts:
            found.append(Path(folder) / f"python{minor}")
    return [p for p in dict.fromkeys(found) if p.is_file() and os.access(p, os.X_OK)]


def find_cpython(minor: str) -> Path | None:
    """The first of :func:`candidates` that is not the interpreter running this module."""
    this = Path(getattr(sys, "_base_executable", sys.executable)).resolve()
    for path in candidates(minor):
        if path.resolve() != this:
            return path
    return None


def debian_tree(suite: str, dest: Path) -> Path:
    """A Debian ``suite`` tree with python3 in ``dest`` (mmdebstrap; kept if it exists)."""
    if (dest / "usr" / "bin" / "python3").is_file():
        return dest
    if os.geteuid() != 0:
        raise HostError(f"a Debian {suite} tree needs root (mmdebstrap, chroot)")
    if shutil.which("mmdebstrap") is None:
        apt = ["apt-get", "install", "-y", "-qq", "mmdebstrap"]
        try:
            _run(apt, "apt-get install mmdebstrap")
        except HostError:
            _run(["apt-get", "update", "-qq"], "apt-get update")
            _run(apt, "apt-get install mmdebstrap")
    include = "python3,libstdc++6"  # libstdc++: pythonfmu's library in the FMUs
    tmp = dest.with_name(dest.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    _run(
        ["mmdebstrap", "--variant=essential", f"--include={include}", suite, str(tmp)],
        f"mmdebstrap {suite}",
    )
    tmp.rename(dest)
    return dest


def provide(choice: str, dest: Path, requirements: Sequence[str]) -> Host:
    """A host of the interpreter ``choice`` (see the module docstring) with fmpy and
    ``requirements`` installed, in the folder ``dest`` (created)."""
    dest.mkdir(parents=True, exist_ok=True)
    debian_only = choice.startswith("debian:")
    minors = choice.removeprefix("debian:").split(",")
    python: Path | None = None
    if os.sep in choice:
        python = Path(choice)
    elif not debian_only:
        python = next(filter(None, (find_cpython(m) for m in minors)), None)
    if python is not None:
        venv = dest / "venv"
        _run([str(python), "-m", "venv", "--without-pip", str(venv)], f"{python} -m venv")
        version = _version([str(venv / "bin" / "python")])
        site = venv / "lib" / f"python{version.rsplit('.', 1)[0]}" / "site-packages"
        host = Host(str(venv / "bin" / "python"), version, site=str(site))
        install(host, ["fmpy", *requirements])
        return host
    minor = next((m for m in minors if m in DEBIAN_PYTHON), None)
    if minor is None:
        raise HostError(
            f"no CPython {' or '.join(minors)} on this machine, and no Debian "
            f"release known to have one (known: {sorted(DEBIAN_PYTHON)})"
        )
    suite = DEBIAN_PYTHON[minor]
    root = debian_tree(suite, dest / f"debian-{suite}")
    python_in = f"/usr/bin/python{minor}"
    probe = Host(python_in, "", root)
    host = Host(python_in, _version(probe.command()), root, {"PYTHONPATH": TREE_SITE}, TREE_SITE)
    install(host, ["fmpy", *requirements])
    return host


def install(host: Host, requirements: Sequence[str]) -> None:
    """``pip install REQUIREMENTS`` for the host (with pip of this Python, see the module
    docstring); a requirement may be ``-r FILE``."""
    pip = [sys.executable, "-m", "pip"]
    if host.root == Path("/"):
        cmd = [*pip, "--python", host.python, "install", "-q", *requirements]
    else:
        major, minor = host.version.split(".")[:2]
        platforms = [a for p in TREE_PLATFORMS for a in ("--platform", p)]
        cmd = [
            *pip,
            "install",
            "-q",
            "--upgrade",
            "--target",
            str(host.outside(TREE_SITE)),
            "--python-version",
            f"{major}.{minor}",
            "--implementation",
            "cp",
            "--abi",
            f"cp{major}{minor}",
            *platforms,
            "--only-binary=:all:",
            *requirements,
        ]
    # pip runs `rustc --version` for its user agent, and rustup's rustc writes ~/.rustup: HOME
    # is a folder of its own (pip's cache stays where it was)
    env = dict(os.environ)
    if "PIP_CACHE_DIR" not in env and "XDG_CACHE_HOME" not in env:
        env["PIP_CACHE_DIR"] = str(Path(env.get("HOME", str(_home()))) / ".cache" / "pip")
    with tempfile.TemporaryDirectory(prefix="pip-home-") as home:
        env["HOME"] = home
        _run(cmd, f"pip install for the host {host.python}", env=env)


def main(argv: Sequence[str]) -> int:
    if len(argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    host = provide(argv[0], Path(argv[1]).resolve(), argv[2:])
    env = " ".join(f"{k}={v}" for k, v in host.env.items())
    print(f"{env} {' '.join(host.command())}".strip())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
