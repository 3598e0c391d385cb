"""The FMU archive: written deterministically (sorted entries, fixed timestamps, Unix
permissions) and validated with ``fmpy.validate_fmu``.
"""

from __future__ import annotations

import datetime as _dt
import zipfile
from collections.abc import Mapping
from pathlib import Path

from fmpy.validation import validate_fmu

from drillstring.apps.export.specs import BuildError

__all__ = ["validate", "write_zip"]

#: Fixed timestamp of the archive entries (the earliest a zip file can hold).
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)


def write_zip(
    entries: Mapping[str, bytes | Path], dest: Path, source_date_epoch: int | None
) -> None:
    """Write ``entries`` (name: bytes, or the file that holds them) to ``dest`` through a
    temporary name: a failed write leaves no half-written FMU."""
    date_time = _ZIP_EPOCH
    if source_date_epoch is not None:
        t = _dt.datetime.fromtimestamp(max(source_date_epoch, 315532800), tz=_dt.UTC)
        date_time = (t.year, t.month, t.day, t.hour, t.minute, t.second)
    tmp = dest.with_name(dest.name + ".tmp")
    try:
        with zipfile.ZipFile(tmp, "w") as z:
            for name in sorted(entries):
                info = zipfile.ZipInfo(name, date_time=date_time)
                info.compress_type = zipfile.ZIP_DEFLATED
                mode = 0o755 if name.endswith(".so") else 0o644
                info.external_attr = mode << 16
                info.create_system = 3  # unix, so external_attr is read as permissions
                data = entries[name]
                z.writestr(info, data.read_bytes() if isinstance(data, Path) else data)
        tmp.replace(dest)
    finally:
        tmp.unlink(missing_ok=True)


def validate(fmu: Path) -> None:
    """Raise :class:`BuildError` listing every problem ``fmpy.validate_fmu`` reports."""
    problems = validate_fmu(str(fmu))
    if problems:
        listing = "\n  ".join(problems)
        raise BuildError(
            f"{fmu.name}: fmpy.validate_fmu reports {len(problems)} problem(s):\n  {listing}"
        )
