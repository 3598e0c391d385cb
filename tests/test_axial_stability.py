"""Tests of drillstring.analysis.axial_stability: eq. (21), tau-decomposition, critical delay,
Fig. 2.

The tau-decomposition (closed-form crossing frequencies, delays, directions) and the spectral root
finder are independent methods; the tests check each against the other.
"""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from drillstring.analysis.axial_stability import (
    FIG2_GAMMABARS,
    axial_roots,
    axial_spectral_abscissa,
    critical_delay,
    crossing_delays,
    crossing_frequencies,
    stability_diagram,
    stability_intervals,
    taubar_crit,
    unstable_root_count,
)
from drillstring.analysis.figures import write_stability_diagram
from drillstring.analysis.spectrum import dde_roots
from drillstring.model.params import REFERENCE


def characteristic_function(s: complex, g: float, e2: float, tau: float) -> complex:
    """P(s) = s^2 + gammabar s + etabar^2 + 1 - exp(-s taubar_n), eq. (21)."""
    return s * s + g * s + e2 + 1.0 - np.exp(-s * tau)


def first_destabilising_delay(g: float, e2: float, step: float = 0.25, tol: float = 1e-11) -> float:
    """First delay with a root in the right half plane, from the root finder alone: scan the
    spectral abscissa on a grid, then bisect on its sign."""
    lo = 0.05
    assert axial_spectral_abscissa(g, e2, lo) < 0.0
    hi = lo + step
    while axial_spectral_abscissa(g, e2, hi) <= 0.0:
        lo, hi = hi, hi + step
        assert hi < 50.0
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if axial_spectral_abscissa(g, e2, mid) > 0.0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("g", FIG2_GAMMABARS)
@pytest.mark.parametrize("e2", [0.1, 1.0])
def test_critical_delay_equals_root_finder_bisection(g: float, e2: float) -> None:
    tc = critical_delay(g, e2)
    assert abs(tc - first_destabilising_delay(g, e2)) < 1e-8


@pytest.mark.parametrize("g", FIG2_GAMMABARS)
def test_pair_on_imaginary_axis_at_critical_delay(g: float) -> None:
    e2 = 0.1
    tc = critical_delay(g, e2)
    roots = axial_roots(g, e2, tc)
    (w_plus, d_plus), _ = crossing_frequencies(g, e2)
    assert d_plus == 1
    assert abs(roots[0].real) < 1e-8 and abs(roots[1].real) < 1e-8
    assert abs(roots[0].imag - w_plus) < 1e-8 and abs(roots[1].imag + w_plus) < 1e-8
    assert roots[2].real < -1e-3  # the rest strictly in the left half plane
    # direct check of (21) at s = i w_+
    assert abs(characteristic_function(1j * w_plus, g, e2, tc)) < 1e-12


def test_gammabar_zero_closed_form() -> None:
    """gammabar = 0: P(i w) real => w^2 = etabar^2 + 2 with exp(-i w tau) = -1, tau = pi/w."""
    for e2 in (0.1, 0.7, 2.0):
        assert abs(critical_delay(0.0, e2) - math.pi / math.sqrt(e2 + 2.0)) < 1e-14
        # taubar = 0: s^2 + etabar^2 = 0, marginal pair +-i etabar (module docstring)
        r0 = axial_roots(0.0, e2, 0.0)
        assert np.allclose(np.sort(r0.imag), [-math.sqrt(e2), math.sqrt(e2)], atol=1e-14)
        assert np.allclose(r0.real, 0.0, atol=1e-14)
        # and asymptotically stable just after
        assert axial_spectral_abscissa(0.0, e2, 0.01) < 0.0


@pytest.mark.parametrize(("g", "e2"), [(0.0, 2.0), (0.2, 1.0), (0.4, 2.5), (0.6, 1.5)])
def test_crossing_directions_agree_with_root_finder(g: float, e2: float) -> None:
    """Before/after each crossing (taubar +- 1e-4): the number of roots in the right half plane from
    the root finder changes by 2 * direction, and equals the count from crossing directions."""
    crossings = crossing_delays(g, e2, 14.0)
    assert len(crossings) >= 4
    assert {c.direction for c in crossings} == {-1, 1}
    for c in crossings:
        n_before = int(np.sum(axial_roots(g, e2, c.taubar - 1e-4).real > 0.0))
        n_after = int(np.sum(axial_roots(g, e2, c.taubar + 1e-4).real > 0.0))
        assert n_after - n_before == 2 * c.direction
        assert n_before == unstable_root_count(g, e2, c.taubar - 1e-4)
        assert n_after == unstable_root_count(g, e2, c.taubar + 1e-4)
        # spectral abscissa changes sign exactly where the count leaves/enters 0
        if min(n_before, n_after) == 0:
            a_lo = axial_spectral_abscissa(g, e2, c.taubar - 1e-4)
            a_hi = axial_spectral_abscissa(g, e2, c.taubar + 1e-4)
            assert np.sign(a_hi) - np.sign(a_lo) == 2 * c.direction
        # the crossing pair satisfies (21) on the axis
        assert abs(characteristic_function(1j * c.omega, g, e2, c.taubar)) < 1e-12


def test_unstable_count_matches_root_finder_on_random_points() -> None:
    rng = np.random.default_rng(5)
    for _ in range(40):
        g = float(rng.choice(FIG2_GAMMABARS))
        e2 = float(rng.uniform(0.05, 4.0))
        tau = float(rng.uniform(0.1, 20.0))
        n_roots = int(np.sum(axial_roots(g, e2, tau).real > 0.0))
        assert n_roots == unstable_root_count(g, e2, tau), (g, e2, tau)


def test_multiple_stability_intervals() -> None:
    """gammabar = 0: a second stable window opens where 2 pi / etabar < 3 pi / sqrt(etabar^2 + 2),
    i.e. etabar^2 > 1.6 (hand calculation from the crossing delays)."""
    assert len(stability_intervals(0.0, 1.55, 10.0)) == 1
    two = stability_intervals(0.0, 1.65, 10.0)
    assert len(two) == 2
    (a0, b0), (a1, b1) = two
    assert a0 == 0.0 and abs(b0 - math.pi / math.sqrt(3.65)) < 1e-14
    assert abs(a1 - 2 * math.pi / math.sqrt(1.65)) < 1e-14
    assert abs(b1 - 3 * math.pi / math.sqrt(3.65)) < 1e-14
    # root finder: stable inside both windows, unstable in the gap between them
    assert axial_spectral_abscissa(0.0, 1.65, 0.5 * (a0 + b0)) < 0.0
    assert axial_spectral_abscissa(0.0, 1.65, 0.5 * (b0 + a1)) > 0.0
    assert axial_spectral_abscissa(0.0, 1.65, 0.5 * (a1 + b1)) < 0.0
    # damping widens the stable set (paper, Fig. 2): more windows at gammabar = 0.6, etabar^2 = 1.5
    assert len(stability_intervals(0.6, 1.5, 20.0)) >= 4


def test_damping_delays_the_loss_of_stability() -> None:
    """Paper, under Fig. 2: increasing gammabar enlarges the region of guaranteed stability."""
    for e2 in (0.05, 0.1, 0.5, 1.0, 1.5):
        tcs = [critical_delay(g, e2) for g in (0.0, 0.1, 0.2, 0.4, 0.6)]
        assert all(t2 > t1 for t1, t2 in zip(tcs, tcs[1:], strict=False))


def test_no_crossing_means_stable_for_all_delays() -> None:
    """D = g^4 - 4 g^2 (e2 + 1) + 4 < 0: e.g. gammabar = 0.6, etabar^2 = 2 (threshold 1.868)."""
    g, e2 = 0.6, 2.0
    assert g**4 - 4 * g**2 * (e2 + 1) + 4 < 0
    assert crossing_frequencies(g, e2) == ()
    assert critical_delay(g, e2) == math.inf
    assert stability_intervals(g, e2, 15.0) == ((0.0, 15.0),)
    for tau in (1.0, 5.0, 15.0):
        assert axial_spectral_abscissa(g, e2, tau) < 0.0


def test_reference_set_is_unstable() -> None:
    g, e2, tau0 = REFERENCE.gammabar, REFERENCE.etabar2, REFERENCE.taubar_n0
    assert abs(g - 0.2) < 1e-12 and abs(e2 - 0.1) < 1e-12 and abs(tau0 - 9.93) < 0.01
    tc = taubar_crit(REFERENCE)
    assert tc == critical_delay(0.2, 0.1)
    assert 2.0 < tc < tau0
    roots = axial_roots(g, e2, tau0)
    assert roots[0].real > 0.01  # paper: unstable for realistic parameters
    assert int(np.sum(roots.real > 0)) == unstable_root_count(g, e2, tau0) > 0


def test_axial_roots_agree_with_companion_form_and_satisfy_21() -> None:
    g, e2, tau = 0.4, 0.8, 7.5
    r1 = axial_roots(g, e2, tau, re_min=-0.3)
    # (21) as y'' = -g y' - (e2 + 1) y + y(t - tau), in companion form x = (y, y')
    companion = [[0.0, 1.0], [-(e2 + 1.0), -g]]
    r2 = dde_roots(companion, [(tau, [[0.0, 0.0], [1.0, 0.0]])], re_min=-0.3)
    assert r1.size == r2.size >= 4
    assert np.max(np.abs(r1 - r2)) < 1e-12
    for s in r1:
        scale = abs(s) ** 2 + g * abs(s) + e2 + 1 + abs(np.exp(-s * tau))
        assert abs(characteristic_function(s, g, e2, tau)) / scale < 1e-14


def test_diagram_boundaries_lie_on_crossing_curves_and_separate_stability(tmp_path) -> None:
    d = stability_diagram(n_param=4000, grid=(201, 101))
    paths = write_stability_diagram(tmp_path, diagram=d)
    assert paths["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob(".*tmp"))  # no temporary files left
    with paths["csv"].open() as fh:
        rows = list(csv.DictReader(fh))
    assert {float(r["gammabar"]) for r in rows} == set(FIG2_GAMMABARS)
    rng = np.random.default_rng(2)
    for r in rng.choice(rows, size=12, replace=False):
        g, tau, e2 = float(r["gammabar"]), float(r["taubar_n"]), float(r["etabar2"])
        # on a crossing curve: P(i w) = 0 for one of the crossing frequencies of this etabar^2
        res = min(
            abs(characteristic_function(1j * w, g, e2, tau)) for w, _ in crossing_frequencies(g, e2)
        )
        assert res < 1e-12
        # a boundary: the root finder sees a stable side and an unstable side
        h = 1e-3
        a_lo = axial_spectral_abscissa(g, e2, max(tau - h, 1e-3))
        a_hi = axial_spectral_abscissa(g, e2, tau + h)
        assert a_lo * a_hi < 0.0
    # the grey region of gammabar = 0 is the stable set: spot checks with the root finder
    assert d.shade_gammabar == 0.0
    picks = [(int(rng.integers(1, 101)), int(rng.integers(1, 201))) for _ in range(8)]
    picks += [(90, 11), (90, 23)]  # etabar^2 ~ 3.6, taubar ~ 1.1 and 2.3: first window and past it
    for iy, ix in picks:
        tau, e2 = d.taubar_grid[ix], d.etabar2_grid[iy]
        assert d.stable[iy, ix] == (axial_spectral_abscissa(0.0, e2, tau) < 0.0), (tau, e2)
    assert d.stable[90, 11] and not d.stable[90, 23]


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((-0.1, 0.1), "gammabar"),
        ((0.2, 0.0), "etabar2"),
        ((0.2, float("nan")), "etabar2"),
        ((True, 0.1), "gammabar"),
    ],
)
def test_bad_parameters_are_rejected(args, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        critical_delay(*args)


def test_bad_delay_is_rejected() -> None:
    with pytest.raises(ValueError, match="taubar_n"):
        axial_roots(0.2, 0.1, -1.0)
    with pytest.raises(ValueError, match="taubar_max"):
        crossing_delays(0.2, 0.1, 0.0)
    with pytest.raises(ValueError, match="taubar_n"):
        unstable_root_count(0.2, 0.1, [1.0, -2.0])
