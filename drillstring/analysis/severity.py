"""Stick-slip severity of a run, defined once: the numbers the controller maps and tables show.

All are computed over a late window [tau_end - window, tau_end] of a full-model run with the
torsional-stick model on (``docs/model.md``, "Torsional stick"), from the bit speed
omega_bit = omega0 + dphi/dtau (scaled, eq. (14)'s omega0 is the nominal speed):

* UTR, the under-the-rotation ratio of Aarsnes and van de Wouw (J. Sound Vib. 444, 2019):
  ``(omega0 - min omega_bit)/omega0``; 1 when the bit stops, 0 for steady drilling;
* the severity ``(max omega_bit - min omega_bit)/(2*mean omega_bit)``, the industry's stick-slip
  index (NaN when the mean speed is 0);
* the fraction of the window spent in torsional stick, exact from the located mode events;
* the peak top-drive torque ``max R`` (scaled, units of C) from a given time on (the switch-on);
* stall, permanent stick: the bit in torsional stick over the whole window, its own outcome.

:func:`outcome` names what a run did, :func:`best_controller` picks the best of several runs
(lowest severity, then lowest peak torque).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from drillstring.model.engine import MODE_NAMES, Event, time_in_mode
from drillstring.validation import check_real

__all__ = [
    "OUTCOMES",
    "Severity",
    "best_controller",
    "outcome",
    "peak_torque",
    "severity_metrics",
    "speed_severity",
    "stick_fraction",
    "utr",
    "window_start",
]

#: Outcomes of a complete run, best to worst (a stopped run's outcome is its status code).
OUTCOMES = ("steady", "vibration", "stick-slip", "stall")
_TSTICK = "torsional_stick"


def utr(omega_bit: ArrayLike, omega0: float) -> float:
    """UTR ``(omega0 - min omega_bit)/omega0`` (Aarsnes and van de Wouw 2019).

    Parameters
    ----------
    omega_bit : array
        Bit speed (total, dPhi/dtau) over the window.
    omega0 : float
        Nominal speed, > 0.

    Returns
    -------
    float
    """
    w = _nonempty(omega_bit, "omega_bit")
    omega0 = check_real("omega0", omega0, lower=0.0)
    return float((omega0 - np.min(w)) / omega0)


def speed_severity(omega_bit: ArrayLike) -> float:
    """Severity ``(max - min)/(2*mean)`` of the bit speed; NaN when the mean is not > 0."""
    w = _nonempty(omega_bit, "omega_bit")
    mean = float(np.mean(w))
    if not mean > 0.0:
        return math.nan
    return float((np.max(w) - np.min(w)) / (2.0 * mean))


def stick_fraction(events: Iterable[Event], t0: float, t1: float, mode_at_t0: str) -> float:
    """Fraction of [t0, t1] in torsional stick, exact from the mode events.

    Parameters
    ----------
    events : iterable of Event
        The run's events in time order (:attr:`drillstring.model.simulate.SimulationResult.events`).
    t0, t1 : float
        The window, t1 > t0.
    mode_at_t0 : str
        The contact mode at t0 (a name of :data:`drillstring.model.engine.MODE_NAMES`).

    Returns
    -------
    float
        In [0, 1].
    """
    t0 = check_real("t0", t0)
    t1 = check_real("t1", t1)
    if not t1 > t0:
        raise ValueError(f"stick_fraction: the window must have t1 > t0, got t0={t0!r}, t1={t1!r}")
    return time_in_mode(events, _TSTICK, t0, t1, mode_at_t0) / (t1 - t0)


def peak_torque(tau: ArrayLike, R_minus_R0: ArrayLike, R0: float, t_from: float = 0.0) -> float:
    """Largest top-drive torque ``R = R0 + (R - R0)`` from ``t_from`` on (scaled, units of C)."""
    t = np.asarray(tau, dtype=float)
    r = np.asarray(R_minus_R0, dtype=float)
    if t.shape != r.shape:
        raise ValueError(f"tau and R_minus_R0 differ in shape: {t.shape} and {r.shape}")
    sel = r[t >= t_from]
    if sel.size == 0:
        raise ValueError(f"no samples at or after t_from = {t_from!r}")
    return float(R0 + np.max(sel))


def window_start(tau: ArrayLike, window: float) -> int:
    """Index of the first sample of the late window ``[tau[-1] - window, tau[-1]]``."""
    t = _nonempty(tau, "tau")
    window = check_real("window", window, lower=0.0)
    if window > t[-1] - t[0] + 1e-9 * max(1.0, abs(t[-1])):
        raise ValueError(f"window = {window!r} is longer than the run ({t[0]!r} .. {t[-1]!r})")
    return int(np.searchsorted(t, t[-1] - window - 1e-9 * max(1.0, abs(t[-1]))))


@dataclass(frozen=True)
class Severity:
    """The severity metrics of one run (see the module docstring); NaN for a stopped run.

    Attributes
    ----------
    utr, severity, stick_fraction, peak_torque : float
    stall : bool
    outcome : str
        One of :data:`OUTCOMES`, or the status code of a stopped run.
    tau_reached : float
    """

    utr: float
    severity: float
    stick_fraction: float
    peak_torque: float
    stall: bool
    outcome: str
    tau_reached: float

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def outcome(severity: float, stick: float, stall: bool, *, vibration_tol: float = 0.05) -> str:
    """The outcome of a complete run: "stall" (stuck over the whole window), "stick-slip" (any
    torsional stick in it), "vibration" (severity above ``vibration_tol``), else "steady"."""
    if stall:
        return "stall"
    if stick > 0.0:
        return "stick-slip"
    if not severity <= vibration_tol:
        return "vibration"
    return "steady"


def severity_metrics(
    result: Any, window: float, *, t_from: float = 0.0, vibration_tol: float = 0.05
) -> Severity:
    """The severity metrics of a full-model run (a SimulationResult or SampledResult).

    Parameters
    ----------
    result : SimulationResult
        With ``params``, ``status``, ``events`` and the columns tau, dphi, R_minus_R0, mode.
    window : float
        Length of the late window (scaled time).
    t_from : float
        Start of the peak-torque search (the switch-on time).
    vibration_tol : float
        Severity below which a run without stick counts as steady.

    Returns
    -------
    Severity
        For a run that stopped early (bit bouncing, reverse rotation, ...) every number is NaN
        and the outcome is the status code.
    """
    tau = np.asarray(result.tau, dtype=float)
    if not result.status.ok:
        nan = math.nan
        return Severity(nan, nan, nan, nan, False, result.status.code, float(tau[-1]))
    p = result.params
    j = window_start(tau, window)
    w = p.omega0 + np.asarray(result.dphi, dtype=float)[j:]
    t0, t1 = float(tau[j]), float(tau[-1])
    first = MODE_NAMES[int(result.mode[j])]
    stick = stick_fraction(result.events, t0, t1, first)
    stall = bool(stick >= 1.0 - 1e-12 and MODE_NAMES[int(result.mode[-1])] == _TSTICK)
    sev = math.nan if stall else speed_severity(w)
    return Severity(
        utr=utr(w, p.omega0),
        severity=sev,
        stick_fraction=stick,
        peak_torque=peak_torque(tau, result.R_minus_R0, p.R0, t_from),
        stall=stall,
        outcome=outcome(sev, stick, stall, vibration_tol=vibration_tol),
        tau_reached=t1,
    )


def best_controller(metrics: Mapping[str, Severity], *, tie: float = 0.02) -> str:
    """The best of several runs at one operating point, or "" if none qualifies.

    Ranking: a run that stopped or stalled never wins; among the others the lowest speed
    severity wins, and runs within ``tie`` of the lowest severity are ranked by the lowest peak
    torque (the same smoothness for less torque is better); the first name given wins a tie in
    both. The severity, not UTR, ranks: UTR only sees how far the bit falls below omega0, and is
    negative for a bit that runs above it through the whole window.

    Parameters
    ----------
    metrics : mapping of name to Severity
    tie : float
        Severity difference regarded as equal, >= 0.

    Returns
    -------
    str
    """
    tie = check_real("tie", tie, lower=0.0, strict=False)
    ok = {
        k: m for k, m in metrics.items() if m.outcome in OUTCOMES[:3] and math.isfinite(m.severity)
    }
    if not ok:
        return ""
    low = min(m.severity for m in ok.values())
    close = [k for k, m in ok.items() if m.severity <= low + tie]
    return min(close, key=lambda k: ok[k].peak_torque)


def _nonempty(x: ArrayLike, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float).reshape(-1)
    if a.size == 0:
        raise ValueError(f"{name} is empty")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} has non-finite values")
    return a
