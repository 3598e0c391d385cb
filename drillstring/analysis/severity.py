"""Stick-slip severity of a run, defined once: the numbers the controller maps and tables show.

All are computed over a late window [tau_end - window, tau_end] of a full-model run with the
torsional-stick model on (``docs/model.md``, "Torsional stick"), from the bit speed
omega_bit = omega0 + dphi/dtau (scaled, eq. (14)'s omega0 is the nominal speed):

* UTR, the under-the-rotation ratio of Aarsnes and van de Wouw (J. Sound Vib. 444, 2019):
  ``(omega0 - min omega_bit)/omega0``; 1 when the bit stops, 0 for steady drilling;
* the severity ``(max - min)/(2*mean)`` of the bit speed averaged over the axial cycle
  (:func:`axial_average`: the axial stick-slip, which every controller leaves, ripples the bit
  speed at the axial frequency; the torsional severity is what remains), the industry's
  stick-slip index (NaN when the mean speed is 0);
* the fraction of the window spent in torsional stick, exact from the located mode events;
* the top drive's effort: the peak torque ``max R`` (scaled, units of C) from a given time on
  (the switch-on), the peak and RMS torque over the window, the peak power ``|R Omega|`` and the
  minimum table speed from the switch-on, the fraction of samples the drive limited;
* the settling time: from the switch-on until the averaged bit speed stays within
  ``settle_band`` of omega0;
* stall, permanent stick: the bit in torsional stick over the whole window, its own outcome.

:func:`outcome` names what a run did: a run whose averaged bit speed still varies by more than
``vibration_tol`` is "settling" when its amplitude over the window is at most half of the
amplitude over the window before (a decay that a longer run would finish), else "vibration".
:func:`best_controller` picks the best of several runs (lowest severity, then lowest peak
torque).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from drillstring.model.engine import MODE_NAMES, Event, time_in_mode
from drillstring.model.topdrive import TopDrive
from drillstring.validation import check_real

__all__ = [
    "MIN_WINDOW_PERIODS",
    "OUTCOMES",
    "SLOWEST_PERIOD",
    "ActuatorDemand",
    "Severity",
    "actuator_demand",
    "axial_average",
    "axial_period",
    "best_controller",
    "check_window",
    "outcome",
    "severity_metrics",
    "speed_severity",
    "stick_fraction",
    "utr",
    "window_start",
]

#: Outcomes of a complete run, best to worst (a stopped run's outcome is its status code).
OUTCOMES = ("steady", "settling", "vibration", "stick-slip", "stall")
#: A decay counts as "settling" when the last window's amplitude is at most this fraction of
#: the window's before.
SETTLING_RATIO = 0.5
#: Periods of the slowest oscillation the late window must hold for its outcome (and the trend
#: test's comparison with the window before) to classify the run (``docs/controllers.md``,
#: "Maps").
MIN_WINDOW_PERIODS = 5
#: The slowest oscillation the outcome must classify (scaled time): the torsional stick-slip
#: under a stiff speed loop, slower than the string's period with the table held, 2*pi/omega_s
#: = 2*pi (omega_s = sqrt(C/I1) = 1 scaled, eqs. (12)-(13)). Measured over the default map
#: (30-150 rpm x 17.3-23.1 kN nominal WOB on the reference rig, the stiff PI under the
#: TDS-11SA, tau in [100, 200]): 6.34 to 6.96, longest at low speed and high WOB; rounded up.
SLOWEST_PERIOD = 7.0
_TSTICK = "torsional_stick"


def check_window(
    window: float, *, periods: float = MIN_WINDOW_PERIODS, where: str = "window"
) -> float:
    """``window`` if it holds ``periods`` periods of :data:`SLOWEST_PERIOD`, else an error.

    Parameters
    ----------
    window : float
        Length of the late window of :func:`severity_metrics` (scaled time), > 0.
    periods : float
        Periods it must hold, >= 0 (0: no requirement, for a run that is not to be classified,
        e.g. a quick test).
    where : str
        How the error names the window (e.g. ``"options.window"``).

    Returns
    -------
    float
        The window.

    Raises
    ------
    ValueError
        ``window`` is not > 0, ``periods`` not >= 0, or the window is shorter than ``periods *
        SLOWEST_PERIOD``; the message names the value and the periods it holds.
    """
    window = check_real(where, window, lower=0.0)
    periods = check_real("periods", periods, lower=0.0, strict=False)
    if window < periods * SLOWEST_PERIOD:
        raise ValueError(
            f"{where} = {window!r} holds {window / SLOWEST_PERIOD:.2f} periods of the slowest "
            f"oscillation the outcome classifies (the stick-slip, up to {SLOWEST_PERIOD:g} in "
            f"scaled time): at least {periods:g} are needed, a window of "
            f"{periods * SLOWEST_PERIOD:g} or more"
        )
    return window


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
    """Severity ``(max - min)/(2*mean)`` of the bit speed, the industry's stick-slip index.

    See ``docs/controllers.md``, "Severity metrics".

    Parameters
    ----------
    omega_bit : array_like
        Bit speed (total, omega0 + dphi/dtau, scaled) over the window; flattened.

    Returns
    -------
    float
        The severity; NaN when the mean speed is not > 0.

    Raises
    ------
    ValueError
        ``omega_bit`` is empty or has non-finite values.
    """
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


def axial_period(events: Iterable[Event], t0: float, t1: float, default: float) -> float:
    """The period of the axial stick-slip in [t0, t1]: the median time between entries into
    axial stick (``default`` with fewer than three entries: no axial limit cycle).

    Parameters
    ----------
    events : iterable of Event
        The run's events in time order.
    t0, t1 : float
        The window.
    default : float
        The period without enough entries (e.g. 2*pi/eta, the axial mode's), > 0.

    Returns
    -------
    float
    """
    entries = [
        e.tau for e in events if e.kind == "mode" and e.to_mode == "stick" and t0 <= e.tau <= t1
    ]
    if len(entries) < 3:
        return check_real("default", default, lower=0.0)
    return float(np.median(np.diff(entries)))


def axial_average(tau: ArrayLike, x: ArrayLike, period: float) -> tuple[np.ndarray, np.ndarray]:
    """(tau, mean of x over the preceding ``period``): the moving average over one axial cycle.

    Parameters
    ----------
    tau : array_like
        Equally spaced sample times.
    x : array_like
        Samples, same shape.
    period : float
        Averaging length (scaled time), > 0; at least one sample.

    Returns
    -------
    (ndarray, ndarray)
        The times from ``tau[0] + period`` on and the trailing means there.

    Raises
    ------
    ValueError
        Fewer samples than the averaging length, or shapes that differ.
    """
    t = _nonempty(tau, "tau")
    v = _nonempty(x, "x")
    if t.shape != v.shape:
        raise ValueError(f"tau and x differ in shape: {t.shape} and {v.shape}")
    period = check_real("period", period, lower=0.0)
    dt = (t[-1] - t[0]) / max(t.size - 1, 1)
    k = max(1, int(round(period / dt))) if dt > 0.0 else 1
    if k > v.size:
        raise ValueError(f"period = {period!r} is longer than the samples ({t[-1] - t[0]!r})")
    c = np.concatenate([[0.0], np.cumsum(v)])
    return t[k - 1 :], (c[k:] - c[:-k]) / k


@dataclass(frozen=True)
class ActuatorDemand:
    """What a run asks of the top drive from a time on (scaled: torque in units of C, time
    tau; :func:`actuator_demand`), and whether a rated drive delivers it.

    Attributes
    ----------
    peak_torque, min_torque : float
        Largest and smallest table torque R = R0 + (R - R0).
    peak_power : float
        Largest |R dTheta/dtau| (units of C per unit of tau).
    min_table_speed, max_table_speed : float
        Range of the table speed dTheta/dtau = omega0 + dtheta/dtau.
    """

    peak_torque: float
    min_torque: float
    peak_power: float
    min_table_speed: float
    max_table_speed: float

    def to_si(self, C: float, t_star: float) -> dict[str, float]:
        """The same in SI: torques in N m (times C), power in W (times C/t*), speeds in rad/s
        (divided by t*) on a rig of stiffness ``C`` [N m/rad] and time scale ``t_star`` [s]."""
        return {
            "peak_torque": self.peak_torque * C,
            "min_torque": self.min_torque * C,
            "peak_power": self.peak_power * C / t_star,
            "min_table_speed": self.min_table_speed / t_star,
            "max_table_speed": self.max_table_speed / t_star,
        }

    def within(self, drive: TopDrive) -> bool:
        """Whether ``drive`` (scaled like the demand) delivers it: torque in [R_min, R_max],
        power at most P_max, table speed in [omega_min, omega_max]."""
        return (
            drive.R_min <= self.min_torque
            and self.peak_torque <= drive.R_max
            and self.peak_power <= drive.P_max
            and drive.omega_min <= self.min_table_speed
            and self.max_table_speed <= drive.omega_max
        )


def actuator_demand(
    tau: ArrayLike, R_minus_R0: ArrayLike, dtheta: ArrayLike, R0: float, omega0: float,
    t_from: float = 0.0,
) -> ActuatorDemand:  # fmt: skip
    """The top-drive torque, power and table speed a run asks for from ``t_from`` on.

    Parameters
    ----------
    tau, R_minus_R0, dtheta : array_like
        Sample times, torque deviation R - R0 and table speed deviation dtheta/dtau (scaled,
        eqs. (13)-(14)), of one shape.
    R0, omega0 : float
        Nominal table torque (units of C) and speed, eqs. (14), (16).
    t_from : float
        First time included (the switch-on time).

    Returns
    -------
    ActuatorDemand
        Peak and least torque, peak power |R Omega|, range of the table speed.

    Raises
    ------
    ValueError
        Arrays of different shapes, or no sample at or after ``t_from``.
    """
    t = np.asarray(tau, dtype=float)
    r = np.asarray(R_minus_R0, dtype=float)
    w = np.asarray(dtheta, dtype=float)
    if not t.shape == r.shape == w.shape:
        raise ValueError(
            f"tau, R_minus_R0 and dtheta differ in shape: {t.shape}, {r.shape}, {w.shape}"
        )
    on = t >= t_from
    if not np.any(on):
        raise ValueError(f"no samples at or after t_from = {t_from!r}")
    R, Omega = R0 + r[on], omega0 + w[on]
    return ActuatorDemand(
        peak_torque=float(np.max(R)),
        min_torque=float(np.min(R)),
        peak_power=float(np.max(np.abs(R * Omega))),
        min_table_speed=float(np.min(Omega)),
        max_table_speed=float(np.max(Omega)),
    )


def window_start(tau: ArrayLike, window: float) -> int:
    """Index of the first sample of the late window ``[tau[-1] - window, tau[-1]]``.

    Parameters
    ----------
    tau : array_like
        Increasing sample times (scaled); flattened.
    window : float
        Window length (scaled time), > 0 and not longer than the run.

    Returns
    -------
    int
        The first index ``j`` with ``tau[j] >= tau[-1] - window`` (to a relative 1e-9).

    Raises
    ------
    ValueError
        ``tau`` is empty or non-finite, ``window`` is not > 0 or is longer than the run.
    """
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
        As the module docstring (peak torque from the switch-on, units of C).
    stall : bool
    outcome : str
        One of :data:`OUTCOMES`, or the status code of a stopped run.
    tau_reached : float
    peak_torque_late, rms_torque_late : float
        Peak and RMS of the absolute table torque R over the window (units of C).
    peak_power : float
        Peak of ``|R Omega|`` from the switch-on (scaled: units of C per unit of tau).
    saturated_fraction : float
        Fraction of the samples from the switch-on whose torque the top drive limited (NaN for
        a run without the record, e.g. a continuous law).
    min_table_speed : float
        Lowest table speed omega0 + dtheta/dtau from the switch-on (scaled).
    settling_time : float
        Time from the switch-on until the averaged bit speed stays within the band (NaN: not
        within it at the end).
    """

    utr: float
    severity: float
    stick_fraction: float
    peak_torque: float
    stall: bool
    outcome: str
    tau_reached: float
    peak_torque_late: float = math.nan
    rms_torque_late: float = math.nan
    peak_power: float = math.nan
    saturated_fraction: float = math.nan
    min_table_speed: float = math.nan
    settling_time: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """The fields as a plain dict.

        Returns
        -------
        dict
            Field name to value (floats, bool, str), as :func:`dataclasses.asdict` gives.
        """
        return asdict(self)


def outcome(
    severity: float,
    stick: float,
    stall: bool,
    *,
    vibration_tol: float = 0.05,
    decay: float = math.nan,
) -> str:
    """The outcome of a complete run, one of :data:`OUTCOMES`.

    "stall" (stuck over the whole window), else "stick-slip" (any torsional stick in it), else
    for a severity above ``vibration_tol`` (or NaN) "settling" when ``decay`` (the amplitude over
    the window over the amplitude over the window before) is at most :data:`SETTLING_RATIO`, else
    "vibration"; else "steady" (``docs/controllers.md``, "Severity metrics").

    Parameters
    ----------
    severity : float
        Speed severity of the window (:func:`speed_severity`).
    stick : float
        Fraction of the window in torsional stick (:func:`stick_fraction`).
    stall : bool
        Whether the bit was in torsional stick over the whole window.
    vibration_tol : float
        Severity above which a run without stick counts as a vibration or a decay.
    decay : float
        The trend of the amplitude between the two windows (NaN: unknown, no "settling").

    Returns
    -------
    str
        The outcome.
    """
    if stall:
        return "stall"
    if stick > 0.0:
        return "stick-slip"
    if not severity <= vibration_tol:
        return "settling" if decay <= SETTLING_RATIO else "vibration"
    return "steady"


def severity_metrics(
    result: Any,
    window: float,
    *,
    t_from: float = 0.0,
    vibration_tol: float = 0.05,
    settle_band: float = 0.05,
) -> Severity:
    """The severity metrics of a full-model run (a SimulationResult or SampledResult).

    Parameters
    ----------
    result : SimulationResult
        With ``params``, ``status``, ``events`` and the columns tau, dphi, dtheta, R_minus_R0,
        mode (a sampled run's ``R_max``, ``R_min``, ``P_max``, ``n_saturated`` are used when
        present: sample-exact).
    window : float
        Length of the late window (scaled time); the trend compares it with the window before.
    t_from : float
        Start of the peak, power, saturation and settling records (the switch-on time).
    vibration_tol : float
        Severity below which a run without stick counts as steady.
    settle_band : float
        Relative band about omega0 of the settling time.

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
    data = result.data
    j = window_start(tau, window)
    t0, t1 = float(tau[j]), float(tau[-1])
    period = axial_period(result.events, t0, t1, 2.0 * math.pi / p.eta)
    w_all = p.omega0 + np.asarray(result.dphi, dtype=float)
    ta, wa = axial_average(tau, w_all, period)
    late = ta >= t0 - 1e-9 * max(1.0, abs(t0))
    w = w_all[j:]
    first = MODE_NAMES[int(result.mode[j])]
    stick = stick_fraction(result.events, t0, t1, first)
    stall = bool(stick >= 1.0 - 1e-12 and MODE_NAMES[int(result.mode[-1])] == _TSTICK)
    sev = math.nan if stall else speed_severity(wa[late])
    before = (ta >= t0 - window) & (ta < t0)
    decay = math.nan
    if np.count_nonzero(before) > 1 and np.count_nonzero(late) > 1:
        a_before, a_late = float(np.ptp(wa[before])), float(np.ptp(wa[late]))
        decay = a_late / a_before if a_before > 0.0 else math.nan
    R = p.R0 + np.asarray(result.R_minus_R0, dtype=float)
    on = tau >= t_from
    demand = actuator_demand(tau, result.R_minus_R0, result.dtheta, p.R0, p.omega0, t_from)
    if "R_max" in data:
        peak_late = float(np.max(data["R_max"][j:]))
        power = float(np.max(data["P_max"][on]))
        samples = (tau[on][-1] - tau[on][0]) / result.Ts if np.count_nonzero(on) > 1 else 0.0
        saturated = float(np.sum(data["n_saturated"][on][1:]) / samples) if samples else 0.0
    else:
        peak_late = float(np.max(R[j:]))
        power = demand.peak_power
        saturated = math.nan
    outside = np.abs(wa - p.omega0) > settle_band * p.omega0
    after = ta >= t_from
    if outside[-1]:
        settling = math.nan
    elif np.any(outside & after):
        settling = float(ta[np.nonzero(outside & after)[0][-1] + 1] - t_from)
    else:
        settling = 0.0
    return Severity(
        utr=utr(w, p.omega0),
        severity=sev,
        stick_fraction=stick,
        peak_torque=demand.peak_torque,
        stall=stall,
        outcome=outcome(sev, stick, stall, vibration_tol=vibration_tol, decay=decay),
        tau_reached=t1,
        peak_torque_late=peak_late,
        rms_torque_late=float(np.sqrt(np.mean(R[j:] ** 2))),
        peak_power=power,
        saturated_fraction=saturated,
        min_table_speed=demand.min_table_speed,
        settling_time=settling,
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
        k: m for k, m in metrics.items() if m.outcome in OUTCOMES[:4] and math.isfinite(m.severity)
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
