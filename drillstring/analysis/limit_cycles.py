"""Fast axial dynamics, Section III: axial stick-slip limit cycle (Fig. 3), averaged contact
force (lambda/vbar0)<gbar>_a and its linear fit (22) giving the slope A (Fig. 4).

The fast model (18) is the engine's model with the torsion frozen at nominal speed (constant
delay) in units where n*psi = 1 and v0 = 1: then tau = taubar, u = ubar (eq. (19) with constant
delay), gamma = gammabar, eta = etabar, and lambda = lambda/vbar0. The Filippov contact logic is
the engine's; nothing of the model is written again here.

Averages are exact integrals over one detected period: the engine integrates g with the RK4
quadrature and records the running integral at every event. A second estimate follows from
averaging (11) over a period (V, u periodic, <d - d0> = 0): etabar^2 <ubar> = (lambda/vbar0)<gbar>.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from tqdm import tqdm

from drillstring.analysis.axial_stability import critical_delay
from drillstring.model.engine import (
    OUTPUT_COLUMNS,
    Engine,
    EngineOptions,
    Event,
    stick_entries,
    time_in_mode,
)
from drillstring.model.params import ScaledParams
from drillstring.validation import check_real

#: Columns of the engine's sample rows used here.
_U, _DU, _G = (OUTPUT_COLUMNS.index(c) for c in ("u", "du", "g"))
DEFAULT_LAM_OVER_VBAR0 = 50.0  # reference set: 1.58*sqrt(1000) = 49.96; bit never moves up
FIG4_GAMMABARS = (0.2, 0.4, 0.6)
FIG4_ETABAR2 = 0.1


def fast_params(
    gammabar: float, etabar2: float, taubar_n: float, lam_over_vbar0: float = DEFAULT_LAM_OVER_VBAR0
) -> ScaledParams:
    """Parameters that make the engine integrate (18): n*psi = 1, v0 = 1, omega0 = 2*pi/taubar_n.

    Parameters
    ----------
    gammabar : float
        Damping gammabar >= 0 (becomes ``gamma``).
    etabar2 : float
        Stiffness etabar^2 > 0 (``eta = sqrt(etabar2)``).
    taubar_n : float
        Constant delay taubar_n > 0 (n = 1 blade turning at omega0 = 2*pi/taubar_n).
    lam_over_vbar0 : float
        lambda/vbar0 of (18) (becomes ``lam``).

    Returns
    -------
    ScaledParams
        The set, with beta = rho = 1 (the torsion is frozen, so they do not act).

    Raises
    ------
    ValueError
        A value out of range (named); :class:`~drillstring.model.params.ParameterError` for a
        negative ``lam_over_vbar0``.
    """
    gammabar = check_real("gammabar", gammabar, lower=0.0, strict=False)
    etabar2 = check_real("etabar2", etabar2, lower=0.0)
    taubar_n = check_real("taubar_n", taubar_n, lower=0.0)
    return ScaledParams(
        n=1,
        psi=1.0,
        gamma=float(gammabar),
        eta=math.sqrt(etabar2),
        lam=float(lam_over_vbar0),
        beta=1.0,
        rho=1.0,
        v0=1.0,
        omega0=2.0 * math.pi / taubar_n,
    )


@dataclass(frozen=True)
class LimitCycle:
    """Outcome of the limit-cycle search at one (gammabar, etabar^2, taubar_n).

    kind: "periodic", "equilibrium" (perturbation decayed), "not_converged", or "invalid" (the
    bit moved up or the run left the model). ``average`` is (lambda/vbar0)<gbar>_a (0 at the
    equilibrium), ``average_check`` the estimate etabar^2 <ubar> from one sampled period.
    """

    gammabar: float
    etabar2: float
    taubar_n: float
    kind: str
    period: float = math.nan
    average: float = math.nan
    average_check: float = math.nan
    stick_fraction: float = math.nan
    stick_phases: int = 0
    period_drift: float = math.nan
    time_simulated: float = 0.0
    samples: dict[str, np.ndarray] = field(default_factory=dict, repr=False, compare=False)


def _periodicity(entries: list[Event], max_phases: int, tol: float) -> tuple[int, float, float]:
    """Smallest k (stick phases per period) whose last two periods agree; (k, T, drift)."""
    for k in range(1, max_phases + 1):
        if len(entries) < 2 * k + 2:
            break
        a, b, c = entries[-1 - 2 * k], entries[-1 - k], entries[-1]
        t1 = b.tau - a.tau
        t2 = c.tau - b.tau
        drift = abs(t2 - t1)
        du = abs(c.u - b.u)
        if drift < tol * max(1.0, t2) and du < tol * max(1.0, abs(c.u)):
            return k, t2, drift
    return 0, math.nan, math.nan


def limit_cycle(
    gammabar: float,
    etabar2: float,
    taubar_n: float,
    *,
    lam_over_vbar0: float = DEFAULT_LAM_OVER_VBAR0,
    h: float = 0.02,
    kick: float = 0.05,
    tol: float = 1e-9,
    max_periods: int = 400,
    max_phases: int = 8,
    n_samples: int = 2000,
) -> LimitCycle:
    """Simulate (18) from a small kick until the motion is periodic (or decays).

    Periodicity: the stick-entry times and positions repeat with k stick phases per period, the
    last two periods agreeing to ``tol`` (relative). The average over that period is the exact
    RK4 integral of g. One further period is then sampled (``n_samples + 1`` points) for plots
    and the second estimate etabar^2 <ubar>.

    Parameters
    ----------
    gammabar, etabar2, taubar_n : float
        The point of (18), as for :func:`fast_params`.
    lam_over_vbar0 : float
        lambda/vbar0 of (18); it does not change the average while the bit never moves up.
    h : float
        RK4 step in fast time.
    kick : float
        Initial perturbation u(0) = ubar(0) from the equilibrium.
    tol : float
        Relative agreement of the last two periods (duration and u at the stick entries).
    max_periods : int
        Budget of the run, in units of taubar_n + 2*pi of fast time.
    max_phases : int
        Largest number k of stick phases per period looked for.
    n_samples : int
        Sampling intervals of the extra period; 0 skips it (no samples, no second estimate).

    Returns
    -------
    LimitCycle
        ``kind`` "periodic" with period, average and check; "equilibrium" when the
        perturbation decays without contact events; "invalid" when the bit moves up or the run
        stops; "not_converged" when the budget runs out.
    """
    p = fast_params(gammabar, etabar2, taubar_n, lam_over_vbar0)
    eng = Engine(p, EngineOptions(h=h, freeze_torsion=True), initial={"u": kick})
    chunk = 10.0 * (taubar_n + 2.0 * math.pi)
    t_max = max_periods * (taubar_n + 2.0 * math.pi)
    base = dict(gammabar=gammabar, etabar2=etabar2, taubar_n=taubar_n)
    while eng.tau < t_max:
        t0 = eng.tau
        n_events_before = len(eng.events)
        rows, st = eng.sample(np.linspace(t0, t0 + chunk, 201)[1:])
        if not st.ok:
            return LimitCycle(**base, kind="invalid", time_simulated=eng.tau)
        amp = float(np.max(np.abs(rows[:, _DU])))
        events = eng.events
        if any(e.to_mode == "up" for e in events):
            return LimitCycle(**base, kind="invalid", time_simulated=eng.tau)
        if len(events) == n_events_before:
            # no contact event in this chunk: linear regime; decayed means the equilibrium
            if amp < 1e-10:
                return LimitCycle(
                    **base,
                    kind="equilibrium",
                    average=0.0,
                    average_check=0.0,
                    stick_fraction=0.0,
                    time_simulated=eng.tau,
                )
            continue
        entries = stick_entries(events)
        k, period, drift = _periodicity(entries, max_phases, tol)
        if k:
            break
    else:
        return LimitCycle(**base, kind="not_converged", time_simulated=eng.tau)

    # the last k stick phases form one period: integral of g from the recorded running integral
    first, last = entries[-1 - k], entries[-1]
    g_int = last.g_integral - first.g_integral
    average = lam_over_vbar0 * g_int / period
    stick_time = time_in_mode(eng.events, "stick", first.tau, last.tau, first.from_mode)
    # sample one further period (same orbit) for the figure and the second estimate
    samples: dict[str, np.ndarray] = {}
    check = math.nan
    if n_samples > 0:
        t0 = eng.tau
        ts = t0 + period * np.arange(n_samples + 1) / n_samples
        rows, _ = eng.sample(ts)
        ub, dub, gb = rows[:, _U].copy(), rows[:, _DU].copy(), rows[:, _G].copy()
        check = etabar2 * float(np.trapezoid(ub, ts) / period)
        samples = {"taubar": ts - t0, "ubar": ub, "dubar": dub, "gbar": gb}
    return LimitCycle(
        **base,
        kind="periodic",
        period=period,
        average=average,
        average_check=check,
        stick_fraction=stick_time / period,
        stick_phases=k,
        period_drift=drift,
        time_simulated=eng.tau,
        samples=samples,
    )


@dataclass(frozen=True)
class SlopeFit:
    """Linear fit (22): (lambda/vbar0)<gbar>_a = A (taubar_n - taubar_zero) over periodic points."""

    gammabar: float
    etabar2: float
    A: float
    taubar_zero: float
    taubar_crit: float
    taubar: np.ndarray
    average: np.ndarray
    residual_rms: float


def fit_slope(
    gammabar: float, etabar2: float, taubar: Sequence[float], average: Sequence[float]
) -> SlopeFit:
    """Least-squares line (22) through the periodic points (finite, positive averages).

    Parameters
    ----------
    gammabar, etabar2 : float
        The line's damping and stiffness (for taubar_crit and the record).
    taubar : sequence of float
        Delays of the points.
    average : sequence of float
        (lambda/vbar0)<gbar>_a at these delays; NaN or non-positive entries are left out.

    Returns
    -------
    SlopeFit
        Slope A, fitted zero taubar_zero, taubar_crit from (21) and the RMS residual.

    Raises
    ------
    ValueError
        Fewer than two usable points, or etabar2 <= 0.
    """
    t = np.asarray(taubar, dtype=float)
    a = np.asarray(average, dtype=float)
    ok = np.isfinite(a) & (a > 0)
    if ok.sum() < 2:
        raise ValueError(
            f"fit_slope needs at least two periodic points, got {int(ok.sum())} "
            f"(gammabar={gammabar}, etabar2={etabar2})"
        )
    A, b = np.polyfit(t[ok], a[ok], 1)
    resid = a[ok] - (A * t[ok] + b)
    return SlopeFit(
        gammabar=gammabar,
        etabar2=etabar2,
        A=float(A),
        taubar_zero=float(-b / A),
        taubar_crit=critical_delay(gammabar, etabar2),
        taubar=t,
        average=a,
        residual_rms=float(np.sqrt(np.mean(resid**2))),
    )


#: Limit cycles per line of Fig. 4, which is also the fit that gives the design its slope A.
FIT_POINTS = 25


def default_fit_delays(gammabar: float, etabar2: float, n: int = FIT_POINTS) -> np.ndarray:
    """Delays of a line of Fig. 4 (and of the slope A): from 1.5 taubar_crit to taubar_crit + 30.

    Parameters
    ----------
    gammabar, etabar2 : float
        The line's damping and stiffness.
    n : int
        Number of delays.

    Returns
    -------
    ndarray
        ``n`` equally spaced delays (``docs/model.md``, "Averaging").
    """
    tc = critical_delay(gammabar, etabar2)
    return np.linspace(1.5 * tc, tc + 30.0, n)


@dataclass(frozen=True)
class AxialDesignInputs:
    """A and taubar_crit of (22) for a parameter set: the input of the controller design.

    ``curve`` holds the limit cycles of the fit, the line of Fig. 4 at the set's (gammabar,
    etabar^2), so that the figure shows the very fit the controller was designed with.
    """

    A: float
    taubar_crit: float
    taubar_zero: float
    gammabar: float
    etabar2: float
    fit: SlopeFit = field(repr=False, compare=False)
    curve: tuple[LimitCycle, ...] = field(default=(), repr=False, compare=False)


def design_inputs(
    params: ScaledParams,
    taubars: Sequence[float] | None = None,
    *,
    progress: bool = False,
    **kw: Any,
) -> AxialDesignInputs:
    """The slope A of (22) and taubar_crit at the parameter set's (gammabar, etabar^2).

    Parameters
    ----------
    params : ScaledParams
        The set; only its gammabar and etabar^2 matter.
    taubars : sequence of float, optional
        Delays of the fit (default: :func:`default_fit_delays`, the Fig. 4 line).
    progress : bool
        Show a progress bar.
    **kw
        Passed to :func:`limit_cycle` (except ``n_samples``, which is 0).

    Returns
    -------
    AxialDesignInputs
        A from the least-squares line through the periodic points, taubar_crit from the
        crossing formula of (21), and the limit cycles of the line.
    """
    g, e2 = params.gammabar, params.etabar2
    tb = default_fit_delays(g, e2) if taubars is None else np.asarray(taubars, dtype=float)
    bar = tqdm(list(tb), desc=f"gammabar={g:g}", disable=not progress, leave=False)
    curve = [limit_cycle(g, e2, float(t), n_samples=0, **kw) for t in bar]
    fit = fit_slope(g, e2, tb, [lc.average for lc in curve])
    return AxialDesignInputs(
        A=fit.A,
        taubar_crit=fit.taubar_crit,
        taubar_zero=fit.taubar_zero,
        gammabar=g,
        etabar2=e2,
        fit=fit,
        curve=tuple(curve),
    )
