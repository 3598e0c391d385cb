"""The FMU archive, validated with ``fmpy.validate_fmu`` (it is written deterministically by
:func:`drillstring.fileio.write_zip`).
"""

from __future__ import annotations

from pathlib import Path

from fmpy.validation import validate_fmu

from drillstring.apps.export.specs import BuildError

__all__ = ["validate"]


def validate(fmu: Path) -> None:
    """Raise :class:`BuildError` listing every problem ``fmpy.validate_fmu`` reports."""
    problems = validate_fmu(str(fmu))
    if problems:
        listing = "\n  ".join(problems)
        raise BuildError(
            f"{fmu.name}: fmpy.validate_fmu reports {len(problems)} problem(s):\n  {listing}"
        )
