"""Tests of drillstring.analysis.spectrum: roots of linear retarded DDEs against independent
references.

References: the Lambert-W closed form of the scalar equation x' = a x + b x(t - tau),
s = W_k(b tau exp(-a tau)) / tau + a (every branch k is a root, and these are all roots);
numpy eigenvalues for ODEs; determinants computed here from the definition of Delta(s).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import lambertw

from drillstring.analysis.spectrum import (
    DDESystem,
    chebyshev_generator,
    dde_roots,
    spectral_abscissa,
)


def lambert_roots(a: float, b: float, tau: float, re_min: float, kmax: int = 400) -> np.ndarray:
    """All roots of s - a - b exp(-s tau) with Re s >= re_min, from the Lambert-W branches."""
    ks = np.arange(-kmax, kmax + 1)
    s = np.array([lambertw(b * tau * np.exp(-a * tau), k) / tau + a for k in ks])
    s = s[s.real >= re_min]
    # the last branches kept must be well inside kmax (the chain's real part decreases with |k|)
    assert s.size < kmax
    return s


def match_error(found: np.ndarray, exact: np.ndarray) -> tuple[float, float]:
    """(max distance exact -> found, max distance found -> exact), both relative to max(1, |s|)."""
    e1 = max(np.min(np.abs(found - s)) / max(1.0, abs(s)) for s in exact)
    e2 = max(np.min(np.abs(exact - s)) / max(1.0, abs(s)) for s in found)
    return e1, e2


SCALAR_CASES = [  # a, b, tau, re_min
    (-1.0, -2.0, 1.0, -3.0),
    (0.5, -1.5, 2.0, -1.5),
    (-0.2, 0.8, 5.0, -0.6),
    (1.0, -3.0, 0.3, -10.0),
    (0.0, -1.0, 30.0, -0.05),
]


@pytest.mark.parametrize(("a", "b", "tau", "re_min"), SCALAR_CASES)
def test_scalar_dde_matches_lambert_w(a: float, b: float, tau: float, re_min: float) -> None:
    exact = lambert_roots(a, b, tau, re_min)
    found = dde_roots(a, [(tau, b)], re_min=re_min)
    # the region is chosen away from roots on its edge; all branches found, no spurious roots
    assert found.size == exact.size
    assert found.size >= 6  # several branches, not just the principal one
    e_miss, e_extra = match_error(found, exact)
    assert e_miss < 1e-12
    assert e_extra < 1e-12


def test_automatic_region_returns_the_rightmost_branches() -> None:
    a, b, tau = 0.5, -1.5, 2.0
    w0 = lambertw(b * tau * np.exp(-a * tau), 0) / tau + a
    # the principal branch is the rightmost root for real a, b (Shinozaki and Mori, 2006)
    assert abs(spectral_abscissa(a, [(tau, b)]) - w0.real) < 1e-12
    # default strip: Re s >= alpha - min(1, 2/tau), every branch in it and nothing else
    found = dde_roots(a, [(tau, b)])
    exact = lambert_roots(a, b, tau, w0.real - min(1.0, 2.0 / tau))
    assert found.size == exact.size >= 2
    assert max(match_error(found, exact)) < 1e-12


def test_two_delays_matrix_system_is_union_of_scalar_spectra() -> None:
    """Similarity-transformed diagonal system with two delays: roots = union of two Lambert sets."""
    rng = np.random.default_rng(7)
    t = rng.normal(size=(2, 2)) + 2.0 * np.eye(2)
    ti = np.linalg.inv(t)
    (a1, b1, tau1), (a2, b2, tau2) = (-0.5, -1.2, 1.0), (0.3, -0.9, 2.5)
    a0 = t @ np.diag([a1, a2]) @ ti
    m1 = t @ np.diag([b1, 0.0]) @ ti
    m2 = t @ np.diag([0.0, b2]) @ ti
    re_min = -1.0
    found = dde_roots(a0, [(tau1, m1), (tau2, m2)], re_min=re_min)
    exact = np.concatenate(
        [lambert_roots(a1, b1, tau1, re_min), lambert_roots(a2, b2, tau2, re_min)]
    )
    assert found.size == exact.size
    assert max(match_error(found, exact)) < 1e-10


def test_ode_equals_numpy_eigenvalues() -> None:
    rng = np.random.default_rng(3)
    a = rng.normal(size=(5, 5))
    exact = np.linalg.eigvals(a)
    found = dde_roots(a)
    assert found.size == 5
    assert max(match_error(found, exact)) < 1e-12
    # a delayed term with a zero matrix leaves only the ODE roots (the discretisation adds spurious
    # eigenvalues that must not survive the Newton/residual filter)
    found_z = dde_roots(a, [(1.3, np.zeros((5, 5)))], re_min=-3.0)
    exact_z = exact[exact.real >= -3.0]
    assert found_z.size == exact_z.size
    assert max(match_error(found_z, exact_z)) < 1e-10


@pytest.mark.parametrize("branch", [0, 5])
def test_eigenvalue_converges_spectrally_in_n_cheb(branch: int) -> None:
    """Unrefined collocation eigenvalues: geometric convergence once N ~ |s| tau / 2, machine
    precision at the default rule N = |s| tau + 24 (branch 0 is the rightmost root)."""
    a, b, tau = 0.0, -1.0, 30.0
    s0 = lambertw(b * tau * np.exp(-a * tau), branch) / tau + a
    st = abs(s0) * tau  # 2.3 for branch 0, 33 for branch 5
    sys_ = DDESystem(a, [(tau, b)])
    ns = [4, 8, 16, 24, 32, 40, int(np.ceil(st)) + 24]
    errs = [np.min(np.abs(np.linalg.eigvals(chebyshev_generator(sys_, n)) - s0)) for n in ns]
    assert errs[-1] < 1e-13
    for n1, e1, e2 in zip(ns, errs, errs[1:], strict=False):
        assert e2 <= e1 or e2 < 1e-13  # monotone until round-off
        if n1 >= st / 2:
            assert e2 < 1e-2 * e1 or e2 < 1e-13  # resolved: >= 2 digits per step until round-off
    if branch:
        assert errs[ns.index(16)] > 1e-2  # N < |s| tau / 2 does not resolve the root


def test_residual_is_tiny_at_every_returned_root() -> None:
    """Three states, two delays, complex coupling: det Delta(s), computed here, vanishes."""
    rng = np.random.default_rng(11)
    a0 = rng.normal(size=(3, 3)) - np.eye(3)
    mats = [(0.7, 0.8 * rng.normal(size=(3, 3))), (1.9, 0.5 * rng.normal(size=(3, 3)))]
    roots = dde_roots(a0, mats, re_min=-2.0)
    assert roots.size >= 6
    norm = np.linalg.norm(a0, 2) + sum(np.linalg.norm(m, 2) for _, m in mats)
    for s in roots:
        delta = s * np.eye(3) - a0 - sum(m * np.exp(-s * tau) for tau, m in mats)
        scale = abs(s) + norm * max(1.0, np.exp(-s.real * 1.9))
        assert abs(np.linalg.det(delta)) / scale**3 < 1e-12
        # relative residual: smallest singular value over the size of Delta's terms
        terms = abs(s) + np.linalg.norm(a0, 2)
        terms += sum(np.linalg.norm(m, 2) * np.exp(-s.real * tau) for tau, m in mats)
        assert np.linalg.svd(delta, compute_uv=False)[-1] / terms < 1e-13
    # conjugate pairs and ordering by real part
    assert np.all(np.diff(roots.real) <= 1e-12)
    for s in roots[np.abs(roots.imag) > 0]:
        assert np.min(np.abs(roots - s.conjugate())) < 1e-12


def test_explicit_region_too_large_for_cap_raises() -> None:
    with pytest.raises(ValueError, match="n_cheb_max"):
        dde_roots(0.0, [(30.0, -1.0)], re_min=-0.5)


@pytest.mark.parametrize(
    ("a0", "delayed", "match"),
    [
        (np.ones((2, 3)), [], "square"),
        (np.ones((2, 2)), [(-1.0, np.eye(2))], "tau"),
        (np.ones((2, 2)), [(np.nan, np.eye(2))], "tau"),
        (np.ones((2, 2)), [(1.0, np.eye(3))], "shape"),
        (np.array([[np.inf]]), [], "non-finite"),
        (np.ones((2, 2)), [(1.0,)], "pair"),
        (np.array([["a"]]), [], "numeric"),
    ],
)
def test_bad_input_is_rejected(a0, delayed, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        dde_roots(a0, delayed)


def test_bad_options_are_rejected() -> None:
    with pytest.raises(ValueError, match="n_cheb"):
        dde_roots(-1.0, [(1.0, 0.5)], n_cheb=1)
    with pytest.raises(ValueError, match="re_min"):
        dde_roots(-1.0, [(1.0, 0.5)], re_min=float("nan"))


def test_reduced_generator_finds_the_same_roots() -> None:
    # a delay on one component of a 5-state system: the past of that component alone suffices
    rng = np.random.default_rng(3)
    a0 = rng.normal(size=(5, 5)) - 2.0 * np.eye(5)
    a1 = np.zeros((5, 5))
    a1[:, 2] = rng.normal(size=5)
    full = dde_roots(a0, [(0.7, a1)], re_min=-4.0)
    reduced = dde_roots(a0, [(0.7, a1)], re_min=-4.0, reduced=True)
    assert full.size == reduced.size >= 3
    np.testing.assert_allclose(reduced, full, rtol=1e-10, atol=1e-12)
    sys_ = DDESystem(a0, [(0.7, a1)])
    assert chebyshev_generator(sys_, 20, reduced=True).shape == (5 + 20, 5 + 20)
