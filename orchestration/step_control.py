"""Macro-step size control from the coupling error, at no extra FMU cost.

After a step ``t_n -> t_n + H`` the local coupling error is estimated from the exchanged
signals alone: the defect ``d = y(t_n + H) - P(t_n + H)`` of the extrapolation polynomial
``P`` (constant for ``"zoh"``, the line through the last two values for ``"linear"``) gives the
input-error impulse a receiving unit integrated over the step,
``int |u_held - u| dt ~ c_p H |d|`` (``c_0 = 1/2``, ``c_1 = 5/12``), which is ``O(H^(p+2))``
and drives its state error. The error norm is ``err = max_i c_p H |d_i| / (atol + rtol |y_i|)``
with ``|y_i|`` the larger of the magnitudes at both ends of the step (:func:`coupling_error`).

Above 1 the step is rejected and retried with ``H*max(shrink_min, safety*err**(-1/(p+2)))``
(:func:`retry_step`); otherwise it is accepted and the next step is
``H*clip(safety*err**(-1/(p+2)), shrink_min, grow_max)``, without growth right after a
rejection (:func:`next_step`), always within ``[h_min, h_max]``. A constant error per step is
what minimizes the number of steps for a given global error (to leading order). A step at
``h_min`` is accepted even above tolerance (:func:`accepts`; the driver counts it as forced).
Gauss-Seidel uses the same estimate, conservative for inputs that receive fresh values.

These are pure functions of the exchanged values; :mod:`.adaptive` drives the units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drillstring.validation import check_real

__all__ = ["StepControl", "step_to_take", "coupling_error", "accepts", "retry_step", "next_step"]


@dataclass(frozen=True)
class StepControl:
    """Tolerances on the coupling-error estimate and limits of the macro step.

    Attributes
    ----------
    rtol, atol : float
        Relative and absolute tolerance of the input-error impulse of every exchanged signal,
        ``c_p H |defect_i| <= atol + rtol*|y_i|``, ``|y_i|`` the larger magnitude at the two
        ends of the step (not both 0).
    h_min, h_max : float
        Limits of the macro step, ``0 < h_min <= h_max``.
    h_init : float, optional
        First step (default ``h_max``).
    safety, grow_max, shrink_min : float
        Shape of the step-size update: safety factor in (0, 1], largest growth > 1, largest
        shrink in (0, 1).
    """

    rtol: float = 1e-3
    atol: float = 1e-6
    h_min: float = 1e-6
    h_max: float = 0.1
    h_init: float | None = None
    safety: float = 0.9
    grow_max: float = 2.0
    shrink_min: float = 0.2

    def __post_init__(self) -> None:
        check_real("StepControl.rtol", self.rtol, lower=0.0, strict=False)
        check_real("StepControl.atol", self.atol, lower=0.0, strict=False)
        if self.rtol == 0 and self.atol == 0:
            raise ValueError("StepControl: rtol and atol cannot both be 0")
        check_real("StepControl.h_max", self.h_max, lower=0.0)
        check_real("StepControl.h_min", self.h_min, lower=0.0, upper=self.h_max)
        if self.h_init is not None:
            check_real(
                "StepControl.h_init", self.h_init, lower=self.h_min, upper=self.h_max, strict=False
            )
        check_real("StepControl.safety", self.safety, lower=0.0, upper=1.0)
        check_real("StepControl.grow_max", self.grow_max, lower=1.0)
        if check_real("StepControl.shrink_min", self.shrink_min, lower=0.0) >= 1.0:
            raise ValueError(f"StepControl.shrink_min must be < 1, got {self.shrink_min!r}")


def step_to_take(h: float, t: float, t_end: float, h_min: float) -> float:
    """The step to attempt from ``t``: ``h``, or what lands on ``t_end`` without a sliver.

    A remainder below ``h_min`` is avoided by halving the rest; the step is never lengthened,
    so that rejections always shrink it.

    Parameters
    ----------
    h : float
        The proposed step.
    t, t_end : float
        Current communication point and stop time.
    h_min : float
        Smallest step.

    Returns
    -------
    float
        The step.
    """
    remaining = t_end - t
    if h >= remaining:
        return remaining
    if remaining - h < h_min:
        return 0.5 * remaining
    return h


def coupling_error(
    y: np.ndarray,
    y_n: np.ndarray,
    y_prev: np.ndarray | None,
    h: float,
    h_prev: float,
    control: StepControl,
) -> tuple[float, int]:
    """Error norm of a step from the extrapolation defect (module docstring).

    Parameters
    ----------
    y : numpy.ndarray
        Exchanged values at the end of the step.
    y_n : numpy.ndarray
        Exchanged values at its start.
    y_prev : numpy.ndarray or None
        Values one step earlier for linear extrapolation (None: zero-order hold).
    h, h_prev : float
        This step and the previous one.
    control : StepControl
        Tolerances.

    Returns
    -------
    err : float
        The error norm (``inf`` if not finite); the step is good when ``err <= 1``.
    p : int
        Degree of the extrapolation (local error ``O(h^(p+2))``).
    """
    if y_prev is not None:
        p, c_p = 1, 5.0 / 12.0
        pred = y_n + (y_n - y_prev) * (h / h_prev)
    else:
        p, c_p = 0, 0.5
        pred = y_n
    scale = control.atol + control.rtol * np.maximum(np.abs(y), np.abs(y_n))
    err = c_p * h * float(np.max(np.abs(y - pred) / scale)) if len(y) else 0.0
    if not math.isfinite(err):
        err = math.inf
    return err, p


def accepts(err: float, h: float, control: StepControl) -> bool:
    """Whether a step is accepted.

    Parameters
    ----------
    err : float
        Its error norm.
    h : float
        The step.
    control : StepControl
        Tolerances and limits.

    Returns
    -------
    bool
        True within tolerance, or at ``h_min`` (a forced step).
    """
    return err <= 1.0 or h <= control.h_min * (1 + 1e-12)


def retry_step(h: float, err: float, p: int, control: StepControl) -> float:
    """The step to retry with after a rejection.

    Parameters
    ----------
    h, err, p
        The rejected step, its error norm (``> 1``) and the extrapolation degree.
    control : StepControl
        Limits and shape of the update.

    Returns
    -------
    float
        A shorter step, at least ``h_min``.
    """
    factor = max(control.shrink_min, control.safety * err ** (-1.0 / (p + 2)))
    return max(control.h_min, min(h * factor, h))


def next_step(h: float, err: float, p: int, rejected: bool, control: StepControl) -> float:
    """The step after accepting step ``h`` with error ``err``.

    Parameters
    ----------
    h, err, p
        The accepted step, its error norm and the extrapolation degree.
    rejected : bool
        A rejection happened at this communication point (then the step does not grow).
    control : StepControl
        Limits and shape of the update.

    Returns
    -------
    float
        The next step, within ``[h_min, h_max]``.
    """
    factor = control.grow_max if err == 0 else control.safety * err ** (-1.0 / (p + 2))
    factor = min(control.grow_max, max(control.shrink_min, factor))
    if rejected:
        factor = min(factor, 1.0)
    return min(control.h_max, max(control.h_min, h * factor))
