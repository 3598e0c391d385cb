"""Section III: axial limit cycle and averaged contact force (Fig. 3, Fig. 4, eq. (22))."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drillstring.analysis.axial_stability import critical_delay
from drillstring.analysis.limit_cycles import design_inputs, fast_params, fit_slope, limit_cycle
from drillstring.model.params import REFERENCE

G, E2 = 0.2, 0.1


def test_fast_params_reproduce_the_fast_scaling():
    p = fast_params(G, E2, 7.5, lam_over_vbar0=40.0)
    assert p.gammabar == pytest.approx(G)
    assert p.etabar2 == pytest.approx(E2)
    assert p.taubar_n0 == pytest.approx(7.5)
    assert p.lam / p.vbar0 == pytest.approx(40.0)
    with pytest.raises(ValueError, match="taubar_n"):
        fast_params(G, E2, -1.0)
    with pytest.raises(ValueError, match="etabar2"):
        fast_params(G, 0.0, 5.0)


def test_equilibrium_below_critical_delay():
    lc = limit_cycle(G, E2, 0.6 * critical_delay(G, E2))
    assert lc.kind == "equilibrium"
    assert lc.average == 0.0


@pytest.fixture(scope="module")
def cycle():
    return limit_cycle(G, E2, 10.0)


def test_periodic_orbit_above_critical_delay(cycle):
    assert cycle.kind == "periodic"
    assert cycle.period_drift < 1e-6
    assert cycle.stick_phases == 1
    assert 0.0 < cycle.stick_fraction < 1.0
    assert cycle.period > 10.0  # a period spans the delay plus the slip phase


def test_filippov_conditions_on_the_cycle(cycle):
    s = cycle.samples
    stick = (s["gbar"] > 0) | (s["dubar"] == -1.0)
    assert stick.sum() > 100
    # in stick the bit does not move axially: ubar' = -1 exactly, the contact stays in [0, 1]
    assert np.all(s["dubar"][stick] == -1.0)
    assert np.all((s["gbar"] >= 0.0) & (s["gbar"] <= 1.0))
    # in slip the bit moves down with full contact
    slip = ~stick
    assert np.all(s["dubar"][slip] > -1.0) and np.all(s["gbar"][slip] == 0.0)


def test_average_has_two_consistent_estimates(cycle):
    """(lambda/vbar0)<gbar> from the g integral equals etabar^2 <ubar> (period average of (11))."""
    assert cycle.average > 0
    assert cycle.average_check == pytest.approx(cycle.average, rel=1e-6)


def test_average_independent_of_initial_condition_and_step(cycle):
    other_kick = limit_cycle(G, E2, 10.0, kick=0.5, n_samples=0)
    half_step = limit_cycle(G, E2, 10.0, h=0.01, n_samples=0)
    assert other_kick.average == pytest.approx(cycle.average, rel=1e-6)
    assert half_step.average == pytest.approx(cycle.average, rel=1e-6)
    assert half_step.period == pytest.approx(cycle.period, rel=1e-6)


def test_slope_below_one_decreasing_in_damping_and_zero_near_critical_delay():
    slopes = []
    for g in (0.2, 0.4, 0.6):
        tc = critical_delay(g, E2)
        tb = np.linspace(1.5 * tc, tc + 20.0, 5)
        avg = [limit_cycle(g, E2, t, n_samples=0).average for t in tb]
        fit = fit_slope(g, E2, tb, avg)
        print(f"gammabar={g}: A={fit.A:.5f}, zero={fit.taubar_zero:.4f}, crit={tc:.4f}")
        assert 0 < fit.A < 1
        assert abs(fit.taubar_zero - tc) < 0.1 * tc
        # linear in the delay (the paper's observation behind (22)): small residual
        assert fit.residual_rms < 0.01 * max(avg)
        slopes.append(fit.A)
    assert slopes[0] > slopes[1] > slopes[2]


def test_fit_needs_two_periodic_points():
    with pytest.raises(ValueError, match="two periodic points"):
        fit_slope(G, E2, [1.0, 2.0], [0.0, math.nan])


def test_design_inputs_at_reference_set():
    d = design_inputs(REFERENCE, taubars=[5.0, 10.0, 15.0])
    assert d.taubar_crit == pytest.approx(critical_delay(REFERENCE.gammabar, REFERENCE.etabar2))
    assert 0.3 < d.A < 0.45
    assert REFERENCE.taubar_n0 > d.taubar_crit  # the reference set is in axial stick-slip
