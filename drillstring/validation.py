"""Input checking shared by every layer: one place that says what a valid number is.

Every public function of the project that takes numbers from a user (parameters, options, gains,
file contents, FMU variables) checks them with these helpers, so a bad value always gets the same
kind of message: the name of the value, the rule it breaks and the value itself, e.g.
``EngineOptions.h must be > 0, got -0.001``. ``error`` selects the exception class (a
``ValueError`` subclass of the caller's, such as ``ParameterError``).
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar

__all__ = [
    "is_finite_real",
    "check_int",
    "check_real",
    "check_choice",
    "check_str",
    "check_table",
    "check_out_folder",
]

E = TypeVar("E", bound=ValueError)


def is_finite_real(value: Any) -> bool:
    """True for a finite real number (``bool`` and strings excluded).

    Parameters
    ----------
    value : object
        Anything.

    Returns
    -------
    bool
        Whether ``value`` is a :class:`numbers.Real` other than ``bool`` with a finite value.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return False
    return math.isfinite(float(value))


def check_real(
    name: str,
    value: Any,
    *,
    lower: float | None = None,
    upper: float | None = None,
    strict: bool = True,
    error: type[E] = ValueError,  # type: ignore[assignment]
) -> float:
    """Return ``value`` as a finite float within the bounds, or raise ``error`` naming it.

    Parameters
    ----------
    name : str
        What the value is, as the message should call it (``"EngineOptions.h"``).
    value : object
        The value to check; ``bool`` and non-numbers are rejected.
    lower, upper : float, optional
        Bounds; ``strict`` makes the lower bound exclusive (the upper bound is inclusive).
    error : type
        Exception class raised (a ``ValueError`` subclass).

    Returns
    -------
    float
        The checked value.

    Raises
    ------
    error
        ``value`` is not a real number, not finite or out of bounds.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise error(f"{name} must be a real number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise error(f"{name} must be finite, got {value!r}")
    below = lower is not None and ((strict and not x > lower) or (not strict and not x >= lower))
    above = upper is not None and not x <= upper
    if (below or above) and lower is not None and upper is not None:
        interval = f"{'(' if strict else '['}{lower:g}, {upper:g}]"
        raise error(f"{name} must be in {interval}, got {value!r}")
    if below:
        raise error(f"{name} must be {'>' if strict else '>='} {lower:g}, got {value!r}")
    if above:
        raise error(f"{name} must be <= {upper:g}, got {value!r}")
    return x


def check_int(
    name: str,
    value: Any,
    *,
    lower: int | None = None,
    integral_floats: bool = False,
    error: type[E] = ValueError,  # type: ignore[assignment]
) -> int:
    """Return ``value`` as an int (>= ``lower``), or raise ``error`` naming it.

    Parameters
    ----------
    name : str
        What the value is, as the message should call it.
    value : object
        The value to check; ``bool`` is always rejected.
    lower : int, optional
        Inclusive lower bound.
    integral_floats : bool
        Also accept a real with an integral value (``4.0``), as FMI hosts and JSON writers
        deliver integers as reals.
    error : type
        Exception class raised (a ``ValueError`` subclass).

    Returns
    -------
    int
        The checked value.

    Raises
    ------
    error
        ``value`` is not an integer (or an accepted integral real), or is below ``lower``.
    """
    bound = "" if lower is None else (" positive" if lower == 1 else f" >= {lower}")
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise error(_int_message(name, bound, value))
    if isinstance(value, numbers.Integral):
        out = int(value)
    else:
        x = float(value)
        if not (integral_floats and math.isfinite(x) and x == math.floor(x)):
            raise error(_int_message(name, bound, value))
        out = int(x)
    if lower is not None and out < lower:
        raise error(_int_message(name, bound, value))
    return out


def _int_message(name: str, bound: str, value: Any) -> str:
    if bound == " positive":
        return f"{name} must be a positive integer, got {value!r}"
    return f"{name} must be an integer{bound}, got {value!r}"


def check_choice(
    name: str,
    value: Any,
    choices: Sequence[str],
    *,
    error: type[E] = ValueError,  # type: ignore[assignment]
) -> str:
    """Return ``value`` if it is one of ``choices``, else raise ``error`` listing them.

    Parameters
    ----------
    name : str
        What the value is, as the message should call it.
    value : object
        The value to check; it must be a ``str``.
    choices : sequence of str
        The allowed values.
    error : type
        Exception class raised (a ``ValueError`` subclass).

    Returns
    -------
    str
        ``value``.

    Raises
    ------
    error
        ``value`` is not one of ``choices``.
    """
    if not isinstance(value, str) or value not in choices:
        raise error(f"{name} must be one of {', '.join(map(repr, choices))}, got {value!r}")
    return value


def check_str(
    name: str,
    value: Any,
    *,
    error: type[E] = ValueError,  # type: ignore[assignment]
) -> str:
    """Return ``value`` if it is a ``str``, else raise ``error`` naming it.

    Parameters
    ----------
    name : str
        What the value is, as the message should call it.
    value : object
        The value to check.
    error : type
        Exception class raised (a ``ValueError`` subclass).

    Returns
    -------
    str
        ``value``.

    Raises
    ------
    error
        ``value`` is not a string.
    """
    if not isinstance(value, str):
        raise error(f"{name} must be a string, got {value!r}")
    return value


def check_table(
    name: str,
    value: Any,
    known: Sequence[str],
    *,
    error: type[E] = ValueError,  # type: ignore[assignment]
) -> dict[str, Any]:
    """Return ``value`` as a dict if it is a mapping of known keys, else raise ``error``.

    Parameters
    ----------
    name : str
        What the table is, as the message should call it (``"options"``).
    value : object
        The value to check (a parsed TOML table or JSON object).
    known : sequence of str
        The keys allowed (not all need be present).
    error : type
        Exception class raised (a ``ValueError`` subclass).

    Returns
    -------
    dict
        A copy of ``value``.

    Raises
    ------
    error
        ``value`` is not a mapping, or has a key not in ``known`` (the message names it and
        lists the known keys).
    """
    if not isinstance(value, Mapping):
        raise error(f"{name} must be a table/object, got {value!r}")
    for key in value:
        if key not in known:
            raise error(f"unknown key {key!r} in {name} (known keys: {', '.join(known)})")
    return dict(value)


def check_out_folder(
    name: str,
    path: str | os.PathLike[str],
    *,
    error: type[E] = ValueError,  # type: ignore[assignment]
) -> Path:
    """Return ``path`` if it is a folder or can be made one, else raise ``error`` naming it.

    Checked before any work is done, so that a command does not compute for minutes and then
    fail to write: ``path`` must be an existing folder, or its nearest existing ancestor must
    be a folder (the missing ones are created when the results are written).

    Parameters
    ----------
    name : str
        What the path is, as the message should call it (the option, ``"--out"``).
    path : path-like
        The output folder.
    error : type
        Exception class raised (a ``ValueError`` subclass).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    error
        ``path``, or the ancestor it would be created in, exists and is not a folder.
    """
    out = Path(path)
    for existing in (out, *out.parents):
        if existing.exists():
            if not existing.is_dir():
                where = "" if existing == out else f": {str(existing)!r}"
                raise error(f"{name} {str(out)!r}{where} is a file, not a folder")
            break
    return out
