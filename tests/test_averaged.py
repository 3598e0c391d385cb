"""Averaged torsional model (25)-(31): matrices against the equations, open-loop instability."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drillstring.analysis.axial_stability import critical_delay
from drillstring.controller.averaged import (
    averaged_model,
    delay_roots,
    linearised_ode_matrix,
    ode_poles,
)
from drillstring.model.params import REFERENCE

# Slope A(gammabar, etabar) of (22) at the reference set, as
# drillstring.analysis.limit_cycles.design_inputs measures it (0.3855; tests/test_axial.py checks
# the fit). It is an input here, not a result: the conclusions below are also checked on A_RANGE
# around it, so they do not hinge on it.
A_REF = 0.3855
A_RANGE = (0.3, A_REF, 0.6)
# Critical delay of (21) at the reference set (gammabar = 0.2, etabar^2 = 0.1).
TAUBAR_CRIT_REF = critical_delay(REFERENCE.gammabar, REFERENCE.etabar2)


def direct_rhs(p, A, taubar_crit, phi, dphi, theta, dtheta, phi_delayed, R_fb):
    """(13) and (28) written out in the original variables, with R - R0 = R_ff + R_fb (31)."""
    tau_n0 = 2 * math.pi / (p.n * p.omega0)
    tau_n_crit = taubar_crit / math.sqrt(p.n * p.psi)
    const = p.n * p.v0 * p.beta * A * (tau_n0 - tau_n_crit)
    ddphi = -(phi - theta) + const - p.n * p.v0 / p.omega0 * (p.beta * A - 1) * (phi - phi_delayed)
    R_minus_R0 = -const + R_fb
    ddtheta = ((phi - theta) + R_minus_R0) / p.rho
    return np.array([dphi, ddphi, dphi - dtheta, ddtheta]), const


PARAM_SETS = [
    REFERENCE,
    REFERENCE.replace(rho=3.0, omega0=7.0),
    REFERENCE.replace(n=3, beta=0.3, v0=0.7, psi=400.0),
]


@pytest.mark.parametrize("p", PARAM_SETS)
def test_matrices_give_rhs_of_13_28(p):
    rng = np.random.default_rng(1234)
    tc = critical_delay(p.gammabar, p.etabar2)
    for _ in range(20):
        A = rng.uniform(0.05, 0.95)
        m = averaged_model(p, A, tc)
        phi, dphi, theta, dtheta, phi_d, R_fb = rng.normal(scale=2.0, size=6)
        expected, const = direct_rhs(p, A, tc, phi, dphi, theta, dtheta, phi_d, R_fb)
        x = np.array([phi, dphi, phi - theta - const, dtheta])
        # delayed state: only its first entry (phi(tau - tau_n)) may matter
        xd = np.array([phi_d, *rng.normal(scale=5.0, size=3)])
        got = m.A0 @ x + m.A1 @ xd + m.B[:, 0] * R_fb  # (29)
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)
        assert m.K0 == pytest.approx(const, rel=1e-14)
        assert m.R_ff == -m.K0


def test_ode_matrix_is_27():
    """(27): phi'' + (phi - theta) = K0 - n v0 (beta A - 1) 2 pi/(n omega0^2) phi'."""
    p = REFERENCE
    m = averaged_model(p, A_REF, TAUBAR_CRIT_REF)
    rng = np.random.default_rng(7)
    M = linearised_ode_matrix(m)
    for _ in range(10):
        phi, dphi, theta, dtheta = rng.normal(size=4)
        A = A_REF
        ddphi = (
            -(phi - theta)
            + m.K0
            - p.n * p.v0 * (p.beta * A - 1) * 2 * math.pi / (p.n * p.omega0**2) * dphi
        )
        ddtheta = ((phi - theta) - m.K0) / p.rho
        x = np.array([phi, dphi, phi - theta - m.K0, dtheta])
        np.testing.assert_allclose(M @ x, [dphi, ddphi, dphi - dtheta, ddtheta], atol=1e-12)


def rhp_zero_count(A0, A1, tau, delta):
    """Zeros of det(s I - A0 - A1 exp(-s tau)) with Re s > delta, by the argument principle.

    Every zero with Re s >= 0 has |s| <= ||A0|| + ||A1||, so the rectangle
    [delta, R] x [-R, R] with R = ||A0|| + ||A1|| + 1 encloses them all.
    """
    R = np.linalg.norm(A0, 2) + np.linalg.norm(A1, 2) + 1.0
    w = np.geomspace(1e-7, R, 40000)
    left = delta + 1j * np.concatenate([w[::-1], [0.0], -w])  # downwards
    x = np.linspace(delta, R, 40000)
    bottom = x - 1j * R
    right = R + 1j * np.linspace(-R, R, 80000)
    top = x[::-1] + 1j * R
    s = np.concatenate([left, bottom, right, top, left[:1]])
    d = np.linalg.det(s[:, None, None] * np.eye(4) - A0 - A1 * np.exp(-s * tau)[:, None, None])
    assert np.min(np.abs(d)) > 0.0
    winding = np.sum(np.diff(np.unwrap(np.angle(d)))) / (2 * math.pi)
    assert abs(winding - round(winding)) < 1e-3, winding
    return round(winding)


@pytest.mark.parametrize("A", A_RANGE)
def test_open_loop_unstable_delay_system_and_ode(A):
    m = averaged_model(REFERENCE, A, TAUBAR_CRIT_REF)
    assert m.c < 0  # velocity weakening, beta*A < 1
    roots = delay_roots(m)
    assert roots[0].real > 0.0
    # the returned roots are zeros of the characteristic function written here
    for s in roots:
        D = s * np.eye(4) - m.A0 - m.A1 * np.exp(-s * m.tau_n0)
        sv = np.linalg.svd(D, compute_uv=False)
        assert sv[-1] / sv[0] < 1e-9
    # independent count of unstable roots (argument principle), excluding the root at 0 (phi)
    delta = 1e-3
    n_unstable = int(np.sum(roots.real > delta))
    assert n_unstable >= 1
    assert rhp_zero_count(m.A0, m.A1, m.tau_n0, delta) == n_unstable
    # ODE (13),(27): its own matrix written from (27) with numpy eigenvalues
    c_tau = p_c_tau(A)
    M = np.array(
        [[0, 1, 0, 0], [0, -c_tau, -1, 0], [0, 1, 0, -1], [0, 0, 1 / REFERENCE.rho, 0]], float
    )
    ev = np.linalg.eigvals(M)
    assert np.sum(ev.real > delta) == n_unstable
    np.testing.assert_allclose(np.sort_complex(ode_poles(m)), np.sort_complex(ev), atol=1e-12)


def p_c_tau(A):
    """Coefficient of phi' in (27) moved to the left: n v0 (beta A - 1) 2 pi / (n omega0^2)."""
    p = REFERENCE
    return p.n * p.v0 * (p.beta * A - 1) * 2 * math.pi / (p.n * p.omega0**2)


@pytest.mark.parametrize(
    ("A", "tc", "match"),
    [
        (0.0, TAUBAR_CRIT_REF, "A"),
        (float("nan"), TAUBAR_CRIT_REF, "A"),
        (0.45, -1.0, "taubar_crit"),
        (0.45, 50.0, "taubar_crit"),
    ],
)
def test_bad_axial_pair_rejected(A, tc, match):
    with pytest.raises(ValueError, match=match):
        averaged_model(REFERENCE, A, tc)
