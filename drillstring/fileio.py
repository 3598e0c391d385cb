"""Atomic file output: results are never half-written (temp file in the folder, then rename);
temporary folders that are removed also when the process is terminated."""

from __future__ import annotations

import csv
import datetime as _dt
import io
import json
import math
import os
import shutil
import signal
import tempfile
import threading
import tomllib
import zipfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path, PurePath
from typing import IO, Any

import numpy as np


def load_table(path: Path) -> Any:
    """Parse a TOML or JSON file, chosen by its suffix.

    A ``.toml`` suffix (any case) is read as TOML, anything else as JSON: the caller has checked
    the suffix, and reports the exceptions below with its own error type.

    Parameters
    ----------
    path : Path
        The file to read.

    Returns
    -------
    object
        The parsed document (a ``dict`` for TOML; whatever the JSON holds otherwise).

    Raises
    ------
    OSError
        The file cannot be read.
    tomllib.TOMLDecodeError, json.JSONDecodeError
        The file is not valid TOML or JSON.
    """
    if path.suffix.lower() == ".toml":
        with path.open("rb") as fh:
            return tomllib.load(fh)
    with path.open(encoding="utf-8") as fh:
        return json.load(fh)


def atomic_write(path: str | os.PathLike[str], write: Callable[[IO[bytes]], Any]) -> Path:
    """Call ``write(fh)`` on a temporary binary file next to ``path``, then rename it.

    The temporary file is flushed and fsynced before :func:`os.replace` puts it in place, so
    ``path`` holds either its old content or the complete new one. Missing parent folders are
    created; on any exception the temporary file is removed and the exception propagates.

    Parameters
    ----------
    path : path-like
        The file to write.
    write : callable
        Called once with the open binary file handle; writes the whole content.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.chmod(tmp, 0o644)  # mkstemp creates 0600; results are ordinary files
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write UTF-8 text atomically (see :func:`atomic_write`).

    Parameters
    ----------
    path : path-like
        The file to write.
    text : str
        Its content.

    Returns
    -------
    Path
        ``path``.
    """
    data = text.encode("utf-8")
    return atomic_write(path, lambda fh: fh.write(data))


def write_csv(
    path: str | os.PathLike[str], header: Sequence[str], rows: Iterable[Sequence[Any]]
) -> Path:
    """Write a CSV atomically; floats are written with ``repr`` (round-trip exact).

    Parameters
    ----------
    path : path-like
        The file to write.
    header : sequence of str
        The first row.
    rows : iterable of sequences
        The data rows; ``float`` cells (numpy floats included) are written with ``repr``, all
        other cells as the :mod:`csv` module writes them.

    Returns
    -------
    Path
        ``path``.
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in rows:
        w.writerow([repr(float(x)) if isinstance(x, float) else x for x in row])
    data = buf.getvalue().encode()
    return atomic_write(path, lambda fh: fh.write(data))


def write_zip(
    path: str | os.PathLike[str],
    entries: Mapping[str, bytes | Path],
    source_date_epoch: int | None = None,
    compresslevel: int | None = None,
) -> Path:
    """Write a zip archive atomically (see :func:`atomic_write`) and reproducibly.

    The entries are written in sorted order, deflated (at zlib's ``compresslevel``, 1-9; its
    default, 6, if None), as Unix files (mode 0755 for a ``.so``,
    else 0644), all dated ``source_date_epoch`` (UTC, no earlier than 1980, the earliest a zip
    file holds; default 1980-01-01), so that the same entries give the same bytes.

    Parameters
    ----------
    path : path-like
        The archive to write.
    entries : mapping
        Name in the archive -> its bytes, or the file that holds them.
    source_date_epoch : int, optional
        Timestamp of the entries (seconds since 1970, ``SOURCE_DATE_EPOCH``).
    compresslevel : int, optional
        zlib's level, 1 (fastest) to 9 (smallest).

    Returns
    -------
    Path
        ``path``.
    """
    date_time = (1980, 1, 1, 0, 0, 0)
    if source_date_epoch is not None:
        t = _dt.datetime.fromtimestamp(max(source_date_epoch, 315532800), tz=_dt.UTC)
        date_time = (t.year, t.month, t.day, t.hour, t.minute, t.second)

    def write(fh: IO[bytes]) -> None:
        with zipfile.ZipFile(fh, "w") as z:
            for name in sorted(entries):
                info = zipfile.ZipInfo(name, date_time=date_time)
                info.compress_type = zipfile.ZIP_DEFLATED
                mode = 0o755 if name.endswith(".so") else 0o644
                info.external_attr = mode << 16
                info.create_system = 3  # unix, so external_attr is read as permissions
                data = entries[name]
                content = data.read_bytes() if isinstance(data, Path) else data
                z.writestr(info, content, compresslevel=compresslevel)

    return atomic_write(path, write)


def write_json(path: str | os.PathLike[str], obj: Any) -> Path:
    """Write ``obj`` as indented JSON with sorted keys, atomically.

    JSON has no NaN or infinity (Python's ``json`` would write the bare words ``NaN`` and
    ``Infinity``, which ``JSON.parse`` and other strict readers refuse): a float that is not
    finite (a metric without a value) is written as ``null``.

    Parameters
    ----------
    path : path-like
        The file to write.
    obj : object
        A JSON-serialisable object.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TypeError
        ``obj`` is not JSON-serialisable (nothing is written).
    """
    data = (json.dumps(json_types(obj), indent=2, sort_keys=True, allow_nan=False) + "\n").encode()
    return atomic_write(path, lambda fh: fh.write(data))


def json_types(obj: Any) -> Any:
    """``obj`` in plain JSON types: keys as strings, tuples as lists, paths as strings, numpy
    scalars as Python numbers, and every float that is not finite as None (JSON has no NaN)."""
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): json_types(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [json_types(v) for v in obj]
    if isinstance(obj, PurePath):
        return str(obj)
    return obj


def save_figure(fig: Any, path: str | os.PathLike[str], **kwargs: Any) -> Path:
    """Save a matplotlib figure as PNG atomically.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : path-like
        The PNG to write.
    **kwargs
        Passed to :meth:`~matplotlib.figure.Figure.savefig` (``format`` is always ``"png"``).

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write(path, lambda fh: fig.savefig(fh, format="png", **kwargs))


def replace_dir(staging: str | os.PathLike[str], target: str | os.PathLike[str]) -> Path:
    """Put the finished folder ``staging`` in the place of ``target``.

    The previous ``target`` (if any) is renamed aside first and deleted only once ``staging``
    is in place, so a failure leaves either the old or the new folder, never a mixture.

    Parameters
    ----------
    staging : path
        A complete folder, on the same file system as ``target``.
    target : path
        Where it goes.

    Returns
    -------
    Path
        ``target``.

    Raises
    ------
    OSError
        A rename failed (the old ``target`` is then back in place).
    """
    staging, target = Path(staging), Path(target)
    aside = target.with_name(f".{target.name}.old")
    if aside.exists():
        shutil.rmtree(aside)
    had_old = target.exists()
    if had_old:
        os.replace(target, aside)
    try:
        os.replace(staging, target)
    except OSError:
        if had_old:
            os.replace(aside, target)
        raise
    if had_old:
        shutil.rmtree(aside, ignore_errors=True)
    return target


# ------------------------------------------------------------------------------------------------
# temporary folders removed on exit, on SIGTERM too
# ------------------------------------------------------------------------------------------------

#: The temporary folders of :func:`temporary_folder` not removed yet (an insertion-ordered set).
_TEMPORARY: dict[str, None] = {}
#: The SIGTERM disposition found when :func:`temporary_folder` installed its handler.
_PREVIOUS_SIGTERM: Any = None
_LOCK = threading.Lock()


def temporary_folder(prefix: str) -> tuple[Path, Callable[[], None]]:
    """A new temporary folder and the function that removes it.

    The caller removes it (a context manager's exit, a ``weakref.finalize`` that also runs at
    a normal exit, and on Ctrl-C, which ends the process by an exception); a SIGTERM, whose
    default is to end the process at once, removes every such folder first: the handler
    installed here (from the main thread, once) removes them and then does what the previous
    disposition did (the default: the process ends by the signal, exit status 143).

    Parameters
    ----------
    prefix : str
        The folder's name starts with it (in ``tempfile.gettempdir()``).

    Returns
    -------
    (Path, callable)
        The folder, and the function that removes it (idempotent).
    """
    path = tempfile.mkdtemp(prefix=prefix)
    with _LOCK:
        _TEMPORARY[path] = None
    _handle_sigterm()

    def remove() -> None:
        with _LOCK:
            _TEMPORARY.pop(path, None)
        shutil.rmtree(path, ignore_errors=True)

    return Path(path), remove


def _handle_sigterm() -> None:
    global _PREVIOUS_SIGTERM
    if threading.current_thread() is not threading.main_thread():
        return  # signal handlers are the main thread's; a folder made here is removed as usual
    current = signal.getsignal(signal.SIGTERM)
    if current is _on_sigterm:
        return
    _PREVIOUS_SIGTERM = current
    signal.signal(signal.SIGTERM, _on_sigterm)


def remove_temporary_folders() -> None:
    """Remove every folder of :func:`temporary_folder` not removed yet (a process that ends
    without unwinding: a signal's handler)."""
    with _LOCK:
        paths = list(_TEMPORARY)
        _TEMPORARY.clear()
    for path in paths:
        shutil.rmtree(path, ignore_errors=True)


def _on_sigterm(signum: int, frame: Any) -> None:
    remove_temporary_folders()
    previous = _PREVIOUS_SIGTERM
    if callable(previous):
        previous(signum, frame)
    elif previous != signal.SIG_IGN:  # the default (or unknown: None): end as the signal does
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
