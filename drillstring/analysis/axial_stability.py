"""Linear stability of the fast axial dynamics, Section III of Besselink, van de Wouw and Nijmeijer
(IEEE CCA 2011): characteristic equation (21), tau-decomposition, critical delay and Fig. 2.

Linearising (18) about the equilibrium ubar = 0 (full contact, gbar = 0) gives

    ubar'' + gammabar ubar' + (etabar^2 + 1) ubar - ubar(taubar - taubar_n) = 0,
    P(s) = s^2 + gammabar s + etabar^2 + 1 - exp(-s taubar_n) = 0,                     (21)

written here as the first-order DDE x' = A0 x + A1 x(taubar - taubar_n), x = (ubar, ubar'),
A0 = [[0, 1], [-(etabar^2 + 1), -gammabar]], A1 = [[0, 0], [1, 0]], whose roots are computed by
:mod:`drillstring.analysis.spectrum` (spectral discretisation + Newton).

tau-decomposition (the paper's ref. [14])
-----------------------------------------
Write p(s) = s^2 + gammabar s + etabar^2 + 1. P(0) = etabar^2 for every delay, so for etabar^2 > 0
roots can only enter or leave the right half plane through s = +-i w, w > 0, where
exp(-i w taubar) = p(i w). Hence |p(i w)| = 1; with z = w^2 this is

    F(z) = z^2 - (2(etabar^2 + 1) - gammabar^2) z + etabar^2 (etabar^2 + 2) = 0,
    z_+- = [2(etabar^2 + 1) - gammabar^2 +- sqrt(D)] / 2,
    D = gammabar^4 - 4 gammabar^2 (etabar^2 + 1) + 4.

Two crossing frequencies w_+ > w_- > 0 exist iff D > 0 and 2(etabar^2 + 1) > gammabar^2;
otherwise no root ever reaches the imaginary axis and the equilibrium is stable for every delay
(gammabar > 0).
On the axis p(i w) = exp(i theta) with cos(theta_+-) = (gammabar^2 -+ sqrt(D)) / 2,
sin(theta) = gammabar w, theta in [0, pi]; the crossing delays are

    taubar_k = (2 pi k - theta) / w,    k = 1, 2, ...

The direction of crossing is sign Re(ds/dtaubar) = sign Re(-p'(i w) / (i w p(i w)))
= sign(gammabar^2 - 2 cos(theta)) = sign F'(z): +1 (destabilising) on the w_+ family, -1
(stabilising) on the w_- family. Because a retarded equation gains no roots from infinity, the
number of roots in the open right half plane is

    N(taubar) = 2 * (#{destabilising crossings < taubar} - #{stabilising crossings < taubar}),

starting from N = 0 near taubar = 0. The critical delay is the first destabilising crossing,
taubar_crit = (2 pi - theta_+) / w_+ (N can only grow at the first crossing since N >= 0).

Special cases (documented choices):

* gammabar = 0: at taubar = 0 the roots +-i etabar lie on the axis (marginal stability). They belong
  to the stabilising family (theta_- = 0, k = 0) and move into the left half plane for small
  taubar > 0, so the equilibrium is asymptotically stable on (0, taubar_crit), with
  taubar_crit = pi / sqrt(etabar^2 + 2). taubar = 0 itself is reported as not asymptotically stable.
* D = 0: the two families merge, the roots touch the imaginary axis without crossing; no interval of
  instability arises and :func:`critical_delay` returns ``inf``.
* etabar^2 = 0: s = 0 is a root for every delay (a continuum of equilibria), so the decomposition
  functions require etabar^2 > 0. The root finder accepts etabar^2 >= 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drillstring.analysis.spectrum import DDESystem, dde_roots
from drillstring.validation import check_real

if TYPE_CHECKING:
    from drillstring.model.params import ScaledParams

__all__ = [
    "FIG2_GAMMABARS",
    "Crossing",
    "StabilityDiagram",
    "axial_roots",
    "axial_spectral_abscissa",
    "axial_system",
    "critical_delay",
    "crossing_delays",
    "crossing_frequencies",
    "stability_diagram",
    "stability_intervals",
    "taubar_crit",
    "unstable_root_count",
]

FIG2_GAMMABARS: tuple[float, ...] = (0.0, 0.2, 0.4, 0.6)
TWO_PI = 2.0 * math.pi


# --------------------------------------------------------------------------------------------------
# validation


def _check_ge(
    gammabar: object, etabar2: object, *, etabar2_strict: bool = True
) -> tuple[float, float]:
    g = check_real("gammabar", gammabar, lower=0.0, strict=False)
    e2 = check_real("etabar2", etabar2, lower=0.0, strict=etabar2_strict)
    return g, e2


# --------------------------------------------------------------------------------------------------
# characteristic equation and roots


def axial_system(gammabar: float, etabar2: float, taubar_n: float) -> DDESystem:
    """Eq. (21) as x' = A0 x + A1 x(taubar - taubar_n), x = (ubar, ubar'); taubar_n = 0: the ODE.

    Parameters
    ----------
    gammabar : float
        Damping gammabar >= 0.
    etabar2 : float
        Stiffness etabar^2 >= 0.
    taubar_n : float
        Delay taubar_n >= 0 in fast time.

    Returns
    -------
    DDESystem
        The linearisation of (18) about ubar = 0 (module docstring).

    Raises
    ------
    ValueError
        A value that is not finite or is negative (named).
    """
    g, e2 = _check_ge(gammabar, etabar2, etabar2_strict=False)
    tau = check_real("taubar_n", taubar_n, lower=0.0, strict=False)
    a0 = np.array([[0.0, 1.0], [-(e2 + 1.0), -g]])
    a1 = np.array([[0.0, 0.0], [1.0, 0.0]])
    if tau == 0.0:
        return DDESystem(a0 + a1)
    return DDESystem(a0, [(tau, a1)])


def axial_roots(gammabar: float, etabar2: float, taubar_n: float, **kwargs: Any) -> NDArray:
    """Rightmost roots of (21), sorted by real part descending.

    Parameters
    ----------
    gammabar, etabar2, taubar_n : float
        As for :func:`axial_system`.
    **kwargs
        Passed to :func:`~drillstring.analysis.spectrum.dde_roots`.

    Returns
    -------
    ndarray of complex
        The roots; by default those within min(1, 2/taubar_n) of the rightmost one (both
        roots for taubar_n = 0).
    """
    return dde_roots(axial_system(gammabar, etabar2, taubar_n), **kwargs)


def axial_spectral_abscissa(
    gammabar: float, etabar2: float, taubar_n: float, **kwargs: Any
) -> float:
    """max Re s over the roots of (21): < 0 iff the axial equilibrium is asymptotically stable
    (arguments as :func:`axial_roots`).
    """
    return float(axial_roots(gammabar, etabar2, taubar_n, **kwargs).real.max())


# --------------------------------------------------------------------------------------------------
# tau-decomposition


@dataclass(frozen=True)
class Crossing:
    """A pair of roots +-i omega on the imaginary axis of (21) at delay ``taubar``.

    ``direction`` is +1 when the pair moves into the right half plane as taubar increases
    (destabilising), -1 when it leaves it; ``k`` is the phase branch,
    taubar = (2 pi k - theta) / omega.
    """

    taubar: float
    omega: float
    direction: int
    k: int
    theta: float


def _families(g: float, e2: float) -> list[tuple[float, float, int]]:
    """(omega, theta, direction) of the crossing families; [] when no root reaches the axis."""
    disc = g**4 - 4.0 * g * g * (e2 + 1.0) + 4.0
    ssum = 2.0 * (e2 + 1.0) - g * g
    if disc < 0.0 or ssum <= 0.0:
        return []
    sq = math.sqrt(disc)
    z_plus = 0.5 * (ssum + sq)
    z_minus = e2 * (e2 + 2.0) / z_plus
    out = []
    for z, cos_theta, direction in (
        (z_plus, 0.5 * (g * g - sq), 1 if disc > 0.0 else 0),
        (z_minus, 0.5 * (g * g + sq), -1 if disc > 0.0 else 0),
    ):
        w = math.sqrt(z)
        out.append((w, math.atan2(g * w, cos_theta), direction))
    return out


def crossing_frequencies(gammabar: float, etabar2: float) -> tuple[tuple[float, int], ...]:
    """Frequencies w > 0 with |p(i w)| = 1 and their crossing directions: ((w_+, +1), (w_-, -1)).

    Empty when no root of (21) can reach the imaginary axis; direction 0 for the tangential case
    D = 0 (then w_+ = w_-, reported once).

    Parameters
    ----------
    gammabar : float
        Damping gammabar >= 0.
    etabar2 : float
        Stiffness etabar^2 > 0.

    Returns
    -------
    tuple of (float, int)
        ``(w, direction)`` pairs, w_+ first.

    Raises
    ------
    ValueError
        gammabar < 0 or etabar^2 <= 0, or a non-finite value.
    """
    g, e2 = _check_ge(gammabar, etabar2)
    fam = _families(g, e2)
    if fam and fam[0][2] == 0:
        return ((fam[0][0], 0),)
    return tuple((w, d) for w, _, d in fam)


def crossing_delays(gammabar: float, etabar2: float, taubar_max: float) -> tuple[Crossing, ...]:
    """All crossings of (21) with 0 < taubar <= taubar_max, sorted by delay.

    Tangential contacts (D = 0, direction 0) are included with direction 0. For gammabar = 0 the
    marginal pair at taubar = 0 (k = 0) is not listed (module docstring).

    Parameters
    ----------
    gammabar, etabar2 : float
        As for :func:`crossing_frequencies`.
    taubar_max : float
        Largest delay listed, > 0.

    Returns
    -------
    tuple of Crossing
        Sorted by delay; at equal delays destabilising crossings first.

    Raises
    ------
    ValueError
        A value out of range or not finite (named).
    """
    g, e2 = _check_ge(gammabar, etabar2)
    tmax = check_real("taubar_max", taubar_max, lower=0.0, strict=True)
    out: list[Crossing] = []
    for w, theta, direction in _families(g, e2):
        k = 1
        while True:
            tau = (TWO_PI * k - theta) / w
            if tau > tmax:
                break
            if tau > 0.0:
                out.append(Crossing(tau, w, direction, k, theta))
            k += 1
        if direction == 0:
            break  # both families coincide
    out.sort(key=lambda c: (c.taubar, -c.direction))
    return tuple(out)


def critical_delay(gammabar: float, etabar2: float) -> float:
    """taubar_crit(gammabar, etabar^2): delay at which the axial equilibrium first loses stability.

    = (2 pi - theta_+) / w_+ (first destabilising crossing), ``inf`` when no root crosses the
    imaginary axis for any delay (D <= 0, or gammabar^2 >= 2(etabar^2 + 1)). For gammabar = 0
    this is pi / sqrt(etabar^2 + 2).

    Parameters
    ----------
    gammabar, etabar2 : float
        As for :func:`crossing_frequencies`.

    Returns
    -------
    float
        taubar_crit, or ``inf``.

    Raises
    ------
    ValueError
        gammabar < 0 or etabar^2 <= 0, or a non-finite value.
    """
    g, e2 = _check_ge(gammabar, etabar2)
    fam = _families(g, e2)
    if not fam or fam[0][2] == 0:
        return math.inf
    w, theta, _ = fam[0]
    return (TWO_PI - theta) / w


def taubar_crit(p: ScaledParams) -> float:
    """Critical delay taubar_crit of (22) for a parameter set.

    Parameters
    ----------
    p : ScaledParams
        The parameter set (its fast-time gammabar and etabar^2 are used).

    Returns
    -------
    float
        ``critical_delay(p.gammabar, p.etabar2)``.
    """
    return critical_delay(p.gammabar, p.etabar2)


def _branch_count(taubar: NDArray, w: NDArray, theta: NDArray) -> NDArray:
    """#{k >= 1 : (2 pi k - theta) / w < taubar} (strict)."""
    x = (taubar * w + theta) / TWO_PI
    return np.maximum(np.ceil(x) - 1.0, 0.0)


def _count_unstable(g: float, e2: NDArray, taubar: NDArray) -> NDArray:
    e2, taubar = np.broadcast_arrays(np.asarray(e2, float), np.asarray(taubar, float))
    disc = g**4 - 4.0 * g * g * (e2 + 1.0) + 4.0
    ssum = 2.0 * (e2 + 1.0) - g * g
    ok = (disc > 0.0) & (ssum > 0.0)
    sq = np.sqrt(np.where(ok, disc, 1.0))
    z_plus = 0.5 * (np.where(ok, ssum, 3.0) + sq)
    z_minus = e2 * (e2 + 2.0) / z_plus
    w_p, w_m = np.sqrt(z_plus), np.sqrt(z_minus)
    th_p = np.arctan2(g * w_p, 0.5 * (g * g - sq))
    th_m = np.arctan2(g * w_m, 0.5 * (g * g + sq))
    n = 2.0 * (_branch_count(taubar, w_p, th_p) - _branch_count(taubar, w_m, th_m))
    return np.where(ok, n, 0.0).astype(int)


def unstable_root_count(gammabar: float, etabar2: ArrayLike, taubar_n: ArrayLike) -> NDArray | int:
    """Number of roots of (21) in the open right half plane, from the crossing directions.

    Vectorised over ``etabar2`` and ``taubar_n`` (broadcast). A delay exactly at a crossing counts
    the pair on the axis as not unstable (only crossings strictly below ``taubar_n`` count).

    Parameters
    ----------
    gammabar : float
        Damping gammabar >= 0.
    etabar2 : array_like
        Stiffness etabar^2 > 0.
    taubar_n : array_like
        Delay taubar_n >= 0.

    Returns
    -------
    int or ndarray of int
        The count N(taubar_n) (module docstring), an int for scalar inputs.

    Raises
    ------
    ValueError
        A value out of range or not finite.
    """
    g = check_real("gammabar", gammabar, lower=0.0, strict=False)
    e2 = np.asarray(etabar2, dtype=float)
    tau = np.asarray(taubar_n, dtype=float)
    if not np.all(np.isfinite(e2)) or np.any(e2 <= 0.0):
        raise ValueError(f"etabar2 must be finite and > 0, got {etabar2!r}")
    if not np.all(np.isfinite(tau)) or np.any(tau < 0.0):
        raise ValueError(f"taubar_n must be finite and >= 0, got {taubar_n!r}")
    n = _count_unstable(g, e2, tau)
    return int(n) if n.ndim == 0 else n


def stability_intervals(
    gammabar: float, etabar2: float, taubar_max: float
) -> tuple[tuple[float, float], ...]:
    """Open delay intervals in (0, taubar_max) on which the equilibrium is asymptotically stable.

    Obtained by counting unstable roots across the crossings (:func:`crossing_delays`); the last
    interval ends at ``taubar_max`` when the equilibrium is still stable there. More than one
    interval is the "multiple stability regions" of Fig. 2 (e.g. gammabar = 0, etabar^2 > 1.6).

    Parameters
    ----------
    gammabar, etabar2 : float
        As for :func:`crossing_frequencies`.
    taubar_max : float
        End of the delay range, > 0.

    Returns
    -------
    tuple of (float, float)
        The intervals ``(start, end)`` in increasing order.

    Raises
    ------
    ValueError
        A value out of range or not finite (named).
    """
    crossings = crossing_delays(gammabar, etabar2, taubar_max)
    out: list[tuple[float, float]] = []
    n, start = 0, 0.0
    for c in crossings:
        new = n + 2 * c.direction
        if n == 0 and c.taubar > start:
            out.append((start, c.taubar))  # stable up to here; a tangency (direction 0) also cuts
        if new == 0:
            start = c.taubar
        n = new
    if n == 0 and start < float(taubar_max):
        out.append((start, float(taubar_max)))
    return tuple(out)


# --------------------------------------------------------------------------------------------------
# Fig. 2


@dataclass(frozen=True)
class StabilityDiagram:
    """Stability boundaries of (21) in the (taubar_n, etabar^2) plane, Fig. 2.

    ``boundaries[g]`` is a list of polylines (arrays of shape (n, 2), columns taubar_n, etabar^2)
    for damping ``g``: the parts of the crossing curves that separate a stable region (no root in
    the right half plane) from an unstable one. ``stable`` is the stability mask of
    ``shade_gammabar`` on the grid ``taubar_grid`` x ``etabar2_grid``, of shape
    (len(etabar2_grid), len(taubar_grid)).
    """

    gammabars: tuple[float, ...]
    taubar_range: tuple[float, float]
    etabar2_range: tuple[float, float]
    boundaries: dict[float, list[NDArray]] = field(repr=False)
    shade_gammabar: float
    taubar_grid: NDArray = field(repr=False)
    etabar2_grid: NDArray = field(repr=False)
    stable: NDArray = field(repr=False)


def _crossing_curves(
    g: float, taubar_range: tuple[float, float], e2_range: tuple[float, float], n_param: int
) -> list[tuple[NDArray, NDArray]]:
    """Crossing curves (taubar, etabar^2) of (21), one per phase branch k, densely parametrised.

    gammabar > 0: theta in (0, pi) parametrises both families at once (they join at the fold of
    etabar^2(theta)): w = sin(theta)/gammabar, etabar^2 = w^2 - 1 + cos(theta),
    taubar = (2 pi k - theta)/w. gammabar = 0: the families are separate, parametrised by etabar^2:
    w_- = etabar, taubar = 2 pi k / w_-;  w_+ = sqrt(etabar^2 + 2), taubar = (2k - 1) pi / w_+.
    """
    curves = []

    def branches(w: Any, theta: Any, e2: NDArray) -> None:
        k = 1
        while (tau := (TWO_PI * k - theta) / w).min() <= taubar_range[1]:
            curves.append((tau, e2))
            k += 1

    if g == 0.0:
        e2 = np.linspace(max(e2_range[0], 1e-9), e2_range[1], n_param)
        for w, theta in ((np.sqrt(e2 + 2.0), math.pi), (np.sqrt(e2), 0.0)):
            branches(w, theta, e2)
        return curves
    theta = np.linspace(0.0, math.pi, n_param + 2)[1:-1]
    w = np.sin(theta) / g
    branches(w, theta, w * w - 1.0 + np.cos(theta))
    return curves


def _thin(points: NDArray, scale: NDArray, min_step: float) -> NDArray:
    """Keep points at least ``min_step`` apart in box-normalised arc length (ends always kept)."""
    if len(points) <= 2:
        return points
    d = np.hypot(*((np.diff(points, axis=0) / scale).T))
    s = np.concatenate([[0.0], np.cumsum(d)])
    bins = np.floor(s / min_step)
    keep = np.concatenate([[True], bins[1:] != bins[:-1]])
    keep[-1] = True
    return points[keep]


def stability_diagram(
    gammabars: Sequence[float] = FIG2_GAMMABARS,
    taubar_range: tuple[float, float] = (0.0, 20.0),
    etabar2_range: tuple[float, float] = (0.0, 4.0),
    *,
    n_param: int = 40000,
    grid: tuple[int, int] = (801, 401),
) -> StabilityDiagram:
    """Boundaries of the stable region of (21) for each gammabar (Fig. 2), by tau-decomposition.

    A point of a crossing curve is kept as boundary when the unstable-root count
    (:func:`unstable_root_count`) is 0 on one side of it (in taubar) and positive on the other.

    Parameters
    ----------
    gammabars : sequence of float
        Damping values, each >= 0 (default: those of Fig. 2).
    taubar_range : (float, float)
        Delay range of the plot, increasing, >= 0.
    etabar2_range : (float, float)
        Stiffness range of the plot, increasing, >= 0.
    n_param : int
        Points per crossing curve before thinning.
    grid : (int, int)
        ``(n_taubar, n_etabar2)`` size of the shading mask, drawn for the smallest of
        ``gammabars``.

    Returns
    -------
    StabilityDiagram
        Boundaries per gammabar and the mask.

    Raises
    ------
    ValueError
        Empty ``gammabars``, a negative or non-finite value, or a range that does not increase.
    """
    gs = tuple(check_real("gammabar", g, lower=0.0, strict=False) for g in gammabars)
    if not gs:
        raise ValueError("gammabars must not be empty")
    t0, t1 = (check_real("taubar_range", v, lower=0.0, strict=False) for v in taubar_range)
    e0, e1 = (check_real("etabar2_range", v, lower=0.0, strict=False) for v in etabar2_range)
    if not (t1 > t0 and e1 > e0):
        raise ValueError(
            f"ranges must be increasing, got taubar_range={taubar_range!r}, "
            f"etabar2_range={etabar2_range!r}"
        )
    scale = np.array([t1 - t0, e1 - e0])
    boundaries: dict[float, list[NDArray]] = {}
    for g in gs:
        segs: list[NDArray] = []
        for tau, e2 in _crossing_curves(g, (t0, t1), (e0, e1), n_param):
            inside = (tau >= t0) & (tau <= t1) & (e2 > max(e0, 0.0)) & (e2 <= e1)
            e2s = np.where(inside, e2, 1.0)
            dt = 1e-9 * np.maximum(1.0, tau)
            n_lo = _count_unstable(g, e2s, np.maximum(tau - dt, 0.0))
            n_hi = _count_unstable(g, e2s, tau + dt)
            keep = inside & (np.minimum(n_lo, n_hi) == 0) & (n_lo != n_hi)
            idx = np.flatnonzero(keep)
            if idx.size == 0:
                continue
            breaks = np.flatnonzero(np.diff(idx) > 1) + 1
            for run in np.split(idx, breaks):
                if run.size >= 2:
                    pts = np.column_stack([tau[run], e2[run]])
                    segs.append(_thin(pts, scale, 1.0 / 1000.0))
        boundaries[g] = segs
    sg = min(gs)
    tg = np.linspace(t0, t1, grid[0])
    eg = np.linspace(max(e0, 1e-6), e1, grid[1])
    counts = _count_unstable(sg, eg[:, None], tg[None, :])
    stable = counts == 0
    if sg == 0.0:
        stable[:, tg == 0.0] = False  # marginal at taubar = 0
    return StabilityDiagram(gs, (t0, t1), (e0, e1), boundaries, sg, tg, eg, stable)
