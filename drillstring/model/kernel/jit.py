"""Optional numba acceleration of the stepping kernel.

The kernel functions are plain Python written in the subset numba compiles. ``jit_for(__name__)``
returns ``numba.njit`` when numba is importable (and ``DRILLSTRING_JIT`` is not ``0``), and the
identity otherwise, so the model is written once and runs with or without the accelerator.
Modules loaded under a name containing ``_pure`` are never compiled: that copy runs a Python
callable as control law inside the loop (see :mod:`drillstring.model.kernel.stepper`).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])


def _identity(func: F) -> F:
    return func


def numba_available() -> bool:
    """True when the compiled kernel is used (numba importable and not disabled)."""
    if os.environ.get("DRILLSTRING_JIT", "1") == "0":
        return False
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def jit_for(module_name: str) -> Callable[[F], F]:
    """Decorator compiling kernel functions of ``module_name`` when numba is available."""
    if "_pure" in module_name or not numba_available():
        return _identity
    import numba

    return numba.njit(cache=True, nogil=True)  # type: ignore[return-value]
