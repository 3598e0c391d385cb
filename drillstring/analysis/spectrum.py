"""Characteristic roots of linear retarded delay-differential equations with discrete delays.

The system is

    x'(t) = A0 x(t) + sum_k A_k x(t - tau_k),    x in R^m (or C^m),  tau_k > 0,

with characteristic matrix Delta(s) = s I - A0 - sum_k A_k exp(-s tau_k); the characteristic roots
are the zeros of det Delta(s). This module is shared by the axial analysis (eq. (21) of Besselink,
van de Wouw and Nijmeijer, IEEE CCA 2011) and the torsional analysis and controller check
(eqs. (29)-(33)).

Method
------
1. Spectral (Chebyshev collocation) discretisation of the infinitesimal generator of the solution
   semigroup on C([-tau_max, 0], C^m) (Breda, Maset and Vermiglio, SIAM J. Sci. Comput. 27 (2005)
   482-495): the state is represented by its values at the N + 1 Chebyshev extremal points
   theta_j = tau_max (cos(j pi / N) - 1) / 2 (theta_0 = 0, theta_N = -tau_max); rows 1..N are the
   Chebyshev differentiation matrix, row 0 is the DDE itself with x(-tau_k) obtained by barycentric
   interpolation. Its m(N + 1) eigenvalues approximate the rightmost characteristic roots.
2. Every approximate eigenvalue in the region of interest is refined by Newton's method on
   f(s) = det Delta(s), using f'(s)/f(s) = trace(Delta(s)^-1 Delta'(s)),
   Delta'(s) = I + sum_k tau_k A_k exp(-s tau_k). A candidate is kept only if the relative smallest
   singular value of Delta at the refined point, divided by the size of its terms
   (:meth:`DDESystem.scale`), is below ``res_tol``.
3. Converged candidates are deduplicated; for real coefficient matrices conjugate pairs are
   completed and near-real roots snapped to the real axis.

Region and collocation degree
-----------------------------
Every root s with Re s >= re_min satisfies the a-priori bound

    |s| <= R(re_min) := rho(|A0| + sum_k |A_k| exp(-re_min tau_k))

(|.| entrywise, rho the spectral radius): s is an eigenvalue of M(s) = A0 + sum_k A_k e^{-s tau_k},
and rho(M) <= rho(|M|) <= rho(B) for any entrywise bound |M| <= B (Perron-Frobenius). Unlike a norm
bound this is invariant under diagonal scaling, so for a companion-form second-order equation such
as (21) it gives |s| ~ exp(-re_min tau / 2), not exp(-re_min tau).

An eigenfunction e^{s theta} on [-tau_max, 0] is resolved by Chebyshev interpolation to about
machine precision once N >~ |s| tau_max (interpolation error ~ (e |s| tau_max / (4 N))^N), and the
approximate eigenvalue then lies well inside the Newton basin of the exact root. The default degree
is N = ceil(R tau_max) + 24, at least 24; all roots with Re s >= re_min are then found. Measured on
the scalar equation against its Lambert-W closed form (seven cases, R tau_max from 18 to 200), the
smallest degree that finds every root of the region to 1e-12 is N ~ 0.5 R tau_max, so the rule
carries a safety factor of about 2. The tests check completeness against Lambert W and the
spectral convergence of the unrefined rightmost eigenvalue in N. If an explicit ``re_min`` needs
more than ``n_cheb_max`` a ``ValueError`` is raised (raise ``re_min``, or pass ``n_cheb``, which
then carries no completeness guarantee).

With ``re_min=None`` (default) the region is chosen automatically: a first pass estimates the
spectral abscissa alpha, then re_min = alpha - margin, margin = min(1, 2 / tau_max), so every root
within that distance of the rightmost one is returned (if that needs more than ``n_cheb_max`` a
``RuntimeWarning`` is issued and ``n_cheb_max`` used: the rightmost roots stay exact, the far end of
the strip may be incomplete).
"""

from __future__ import annotations

import contextlib
import math
import warnings
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "DDESystem",
    "chebyshev_generator",
    "dde_roots",
    "delayed_columns",
    "spectral_abscissa",
]

try:  # optional: keep OpenBLAS single-threaded for these small dense problems
    from threadpoolctl import threadpool_limits
except ImportError:  # pragma: no cover
    threadpool_limits = None

N_CHEB_MIN = 24
N_CHEB_MAX_DEFAULT = 400
_RES_TOL = 1e-10
_DEDUP_RTOL = 1e-6


class DDESystem:
    """A validated linear retarded DDE: x' = A0 x + sum_k A_k x(t - tau_k).

    Parameters
    ----------
    A0 : array_like
        Real or complex (m, m) matrix, finite; a scalar is read as 1 x 1.
    delayed : sequence of (float, array_like)
        Pairs ``(tau_k, A_k)`` with finite ``tau_k > 0`` and ``A_k`` of the same shape as ``A0``.
        Equal delays are merged (their matrices added); the delays are stored sorted.

    Raises
    ------
    ValueError
        A malformed pair, a bad delay or a matrix that is not square, numeric and finite (named).
    """

    __slots__ = ("A0", "As", "_n0", "_nk", "m", "taus")

    def __init__(self, A0: ArrayLike, delayed: Sequence[tuple[float, ArrayLike]] = ()) -> None:
        a0 = _as_matrix(A0, "A0")
        m = a0.shape[0]
        merged: dict[float, NDArray] = {}
        for i, item in enumerate(delayed):
            try:
                tau, ak = item
            except (TypeError, ValueError):
                raise ValueError(f"delayed[{i}] must be a pair (tau, A), got {item!r}") from None
            if isinstance(tau, bool) or not isinstance(tau, int | float | np.integer | np.floating):
                raise ValueError(f"delayed[{i}]: delay tau must be a real number, got {tau!r}")
            tau = float(tau)
            if not math.isfinite(tau) or tau <= 0.0:
                raise ValueError(f"delayed[{i}]: delay tau must be finite and > 0, got {tau!r}")
            ak = _as_matrix(ak, f"delayed[{i}] matrix")
            if ak.shape != a0.shape:
                raise ValueError(
                    f"delayed[{i}] matrix has shape {ak.shape}, expected {a0.shape} like A0"
                )
            merged[tau] = merged.get(tau, 0.0) + ak
        self.A0: NDArray = a0
        self.m: int = m
        self.taus: tuple[float, ...] = tuple(sorted(merged))
        self.As: tuple[NDArray, ...] = tuple(merged[t] for t in self.taus)
        self._n0 = float(np.linalg.norm(a0, 2))
        self._nk = tuple(float(np.linalg.norm(a, 2)) for a in self.As)

    @property
    def tau_max(self) -> float:
        """Largest delay (0.0 for an ODE)."""
        return self.taus[-1] if self.taus else 0.0

    @property
    def is_real(self) -> bool:
        """True when all coefficient matrices are real (roots then come in conjugate pairs)."""
        return not any(np.iscomplexobj(a) for a in (self.A0, *self.As))

    def radius_bound(self, re_min: float) -> float:
        """R(re_min) = rho(|A0| + sum |A_k| exp(-re_min tau_k)), |.| entrywise, rho spectral radius:
        every root with Re s >= re_min has |s| <= R (module docstring).
        """
        b = np.abs(self.A0)
        for tau, a in zip(self.taus, self.As, strict=True):
            b = b + np.abs(a) * math.exp(min(-re_min * tau, 700.0))
        return float(np.max(np.abs(np.linalg.eigvals(b))))

    def delta(self, s: complex) -> NDArray:
        """Characteristic matrix Delta(s) = s I - A0 - sum A_k exp(-s tau_k), complex (m, m)."""
        d = s * np.eye(self.m, dtype=complex) - self.A0
        for tau, a in zip(self.taus, self.As, strict=True):
            d = d - a * np.exp(-s * tau)
        return d

    def ddelta(self, s: complex) -> NDArray:
        """Derivative Delta'(s) = I + sum tau_k A_k exp(-s tau_k), complex (m, m)."""
        d = np.eye(self.m, dtype=complex)
        for tau, a in zip(self.taus, self.As, strict=True):
            d = d + tau * a * np.exp(-s * tau)
        return d

    def scale(self, s: complex) -> float:
        """Size of the terms of Delta(s): |s| + ||A0|| + sum ||A_k|| |exp(-s tau_k)| (||.|| the
        spectral norm): sigma_min(Delta(s)) / scale(s) is ~1e-16 at an exact root in floating point
        and O(1) far from roots.
        """
        r = abs(s) + self._n0
        for tau, nk in zip(self.taus, self._nk, strict=True):
            r += nk * math.exp(min(-s.real * tau, 700.0))
        return r


def _as_matrix(a: ArrayLike, name: str) -> NDArray:
    arr = np.asarray(a)
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.number) and not np.issubdtype(arr.dtype, np.bool_)
    ):
        raise ValueError(f"{name} must be a numeric array, got dtype {arr.dtype}")
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or arr.shape[0] == 0:
        raise ValueError(
            f"{name} must be a square (m, m) matrix with m >= 1, got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains non-finite entries: {arr!r}")
    if np.iscomplexobj(arr):
        return arr.astype(complex)
    return arr.astype(float)


def _system(A0: ArrayLike | DDESystem, delayed: Sequence[tuple[float, ArrayLike]]) -> DDESystem:
    if isinstance(A0, DDESystem):
        if delayed:
            raise ValueError("pass either a DDESystem or (A0, delayed), not both")
        return A0
    return DDESystem(A0, delayed)


def _cheb(n: int) -> tuple[NDArray, NDArray]:
    """Chebyshev extremal points x_j = cos(j pi / n) and differentiation matrix (Trefethen, SMM)."""
    x = np.cos(np.pi * np.arange(n + 1) / n)
    c = np.ones(n + 1)
    c[0] = c[-1] = 2.0
    c *= (-1.0) ** np.arange(n + 1)
    dx = x[:, None] - x[None, :]
    d = np.outer(c, 1.0 / c) / (dx + np.eye(n + 1))
    d -= np.diag(d.sum(axis=1))
    return x, d


def _bary_row(x: NDArray, xi: float) -> NDArray:
    """Lagrange basis values l_j(xi) on Chebyshev extremal points x (barycentric formula)."""
    n = len(x) - 1
    w = (-1.0) ** np.arange(n + 1)
    w[0] *= 0.5
    w[-1] *= 0.5
    diff = xi - x
    hit = np.flatnonzero(np.abs(diff) < 1e-14)
    row = np.zeros(n + 1)
    if hit.size:
        row[hit[0]] = 1.0
        return row
    t = w / diff
    return t / t.sum()


def delayed_columns(sys_: DDESystem) -> NDArray[np.intp]:
    """Indices of the state components whose past enters the equation (a nonzero column of a
    delayed matrix A_k), ascending.

    Parameters
    ----------
    sys_ : DDESystem
        The system.

    Returns
    -------
    ndarray of int
        The indices j with A_k[:, j] != 0 for some k (empty for an ODE).
    """
    used = np.zeros(sys_.m, dtype=bool)
    for a in sys_.As:
        used |= np.any(a != 0, axis=0)
    return np.flatnonzero(used)


def chebyshev_generator(sys_: DDESystem, n_cheb: int, reduced: bool = False) -> NDArray:
    """Matrix A_N (size m(N+1)) discretising the infinitesimal generator on [-tau_max, 0].

    State ordering: blocks phi(theta_0), ..., phi(theta_N), theta_j = tau_max (cos(j pi/N) - 1)/2.
    Block row 0: phi'(0) = A0 phi(0) + sum_k A_k phi(-tau_k) (interpolated); block rows 1..N:
    phi'(theta_i) = sum_j D_ij phi(theta_j) with D the Chebyshev matrix scaled by 2 / tau_max.

    ``reduced=True`` keeps the past only of the components :func:`delayed_columns` names (p of
    them): the state is phi(theta_0) (all m) followed by blocks of those p components at
    theta_1, ..., theta_N, size m + pN. The past of any other component is read by no row but
    its own, so the full matrix is block triangular with this one and N-by-N blocks of D (one
    per such component, the spurious eigenvalues of the discretised shift, which the refinement
    rejects) on the diagonal: the eigenvalues of the reduced matrix are those of the full one
    less those blocks'. A system whose delay acts on a few components (the drill string's bit,
    ``drillstring.controller.string_spectrum``) is then as cheap as its ODE.

    Parameters
    ----------
    sys_ : DDESystem
        The system.
    n_cheb : int
        Chebyshev degree N.
    reduced : bool
        Keep the past of the delayed columns only (default False: every component's).

    Returns
    -------
    ndarray
        The (m(N+1), m(N+1)) matrix (m + pN with ``reduced``), complex if the system is; a copy
        of A0 for an ODE.
    """
    if sys_.tau_max <= 0.0:
        return sys_.A0.copy()
    if reduced:
        return _reduced_generator(sys_, int(n_cheb))
    n = int(n_cheb)
    m = sys_.m
    x, d = _cheb(n)
    d = d * (2.0 / sys_.tau_max)
    dtype = complex if not sys_.is_real else float
    big = np.zeros((m * (n + 1), m * (n + 1)), dtype=dtype)
    big[m:, :] = np.kron(d[1:, :], np.eye(m))
    big[:m, :m] += sys_.A0
    for tau, a in zip(sys_.taus, sys_.As, strict=True):
        xi = 2.0 * (-tau) / sys_.tau_max + 1.0
        big[:m, :] += np.kron(_bary_row(x, xi)[None, :], a)
    return big


def _reduced_generator(sys_: DDESystem, n: int) -> NDArray:
    """:func:`chebyshev_generator` with ``reduced=True``: x(0), then the delayed columns' past."""
    m = sys_.m
    cols = delayed_columns(sys_)
    p = cols.size
    x, d = _cheb(n)
    d = d * (2.0 / sys_.tau_max)
    dtype = complex if not sys_.is_real else float
    big = np.zeros((m + p * n, m + p * n), dtype=dtype)
    eye = np.eye(p)
    big[:m, :m] = sys_.A0
    for tau, a in zip(sys_.taus, sys_.As, strict=True):
        row = _bary_row(x, 2.0 * (-tau) / sys_.tau_max + 1.0)
        big[:m, cols] += row[0] * a[:, cols]
        big[:m, m:] += np.kron(row[None, 1:], a[:, cols])
    big[m:, cols] = np.kron(d[1:, :1], eye)
    big[m:, m:] = np.kron(d[1:, 1:], eye)
    return big


def _newton(sys_: DDESystem, s0: complex, max_iter: int, step_tol: float) -> complex:
    s = complex(s0)
    for _ in range(max_iter):
        dlt = sys_.delta(s)
        try:
            if sys_.m == 1:
                if dlt[0, 0] == 0:
                    return s  # exact root
                ratio = sys_.ddelta(s)[0, 0] / dlt[0, 0]
            else:
                ratio = np.trace(np.linalg.solve(dlt, sys_.ddelta(s)))
        except np.linalg.LinAlgError:
            return s  # Delta exactly singular: s is a root
        if not np.isfinite(ratio) or ratio == 0:
            return s
        step = 1.0 / ratio
        s = s - step
        if not np.isfinite(s):
            return s
        if abs(step) <= step_tol * max(1.0, abs(s)):
            break
    return s


def default_n_cheb(sys_: DDESystem, re_min: float) -> int:
    """Collocation degree N = ceil(R(re_min) tau_max) + 24 (module docstring), at least 24.

    Parameters
    ----------
    sys_ : DDESystem
        The system.
    re_min : float
        Lower bound of the real part of the roots to resolve.

    Returns
    -------
    int
        The degree that resolves every root with Re s >= re_min.
    """
    r = sys_.radius_bound(re_min)
    return max(N_CHEB_MIN, math.ceil(r * sys_.tau_max) + N_CHEB_MIN)


def _refine(
    sys_: DDESystem,
    cands: NDArray,
    re_min: float,
    r_max: float,
    max_iter: int,
    step_tol: float,
    res_tol: float,
) -> NDArray:
    roots: list[complex] = []
    for lam in cands:
        if not (lam.real >= re_min - 0.5 - 0.1 * abs(lam) and abs(lam) <= 1.5 * r_max + 1.0):
            continue
        if sys_.is_real and lam.imag < -1e-12 * max(1.0, abs(lam)):
            continue  # conjugate of a pair; the partner is refined and mirrored below
        s = _newton(sys_, lam, max_iter, step_tol)
        if not np.isfinite(s) or s.real < re_min:
            continue
        smin = float(np.linalg.svd(sys_.delta(s), compute_uv=False)[-1])
        if smin > res_tol * sys_.scale(s):
            continue
        roots.append(s)
    if sys_.is_real:
        out = []
        for s in roots:
            if abs(s.imag) <= 1e-10 * max(1.0, abs(s)):
                out.append(complex(s.real, 0.0))
            else:
                s = complex(s.real, abs(s.imag))
                out.extend((s, s.conjugate()))
        roots = out
    return _dedup(np.asarray(roots, dtype=complex))


def _dedup(roots: NDArray) -> NDArray:
    if roots.size == 0:
        return roots
    roots = roots[np.lexsort((-roots.imag, -roots.real))]
    kept: list[complex] = []
    for s in roots:
        if all(abs(s - t) > _DEDUP_RTOL * max(1.0, abs(s)) for t in kept):
            kept.append(s)
    out = np.asarray(kept, dtype=complex)
    return out[np.lexsort((-out.imag, -out.real))]


@contextlib.contextmanager
def _single_thread_blas() -> Iterator[None]:
    """Limit BLAS to one thread: the eigenproblems here have size < ~1000, where OpenBLAS threads
    only add overhead; on a loaded 2-core machine they made ``eigvals`` ~30x slower (measured)."""
    if threadpool_limits is None:
        yield
        return
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def dde_roots(
    A0: ArrayLike | DDESystem,
    delayed: Sequence[tuple[float, ArrayLike]] = (),
    *,
    re_min: float | None = None,
    n_cheb: int | None = None,
    n_cheb_max: int = N_CHEB_MAX_DEFAULT,
    max_roots: int | None = None,
    max_iter: int = 60,
    step_tol: float = 1e-14,
    res_tol: float = _RES_TOL,
    reduced: bool = False,
) -> NDArray[np.complex128]:
    """Characteristic roots of x' = A0 x + sum_k A_k x(t - tau_k) with Re s >= re_min.

    Parameters
    ----------
    A0, delayed
        The system (see :class:`DDESystem`); ``A0`` may also be a :class:`DDESystem` (then
        ``delayed`` must be empty).
    re_min : float, optional
        Lower bound of the real part of the returned roots. ``None`` chooses
        ``alpha - min(1, 2/tau_max)`` with alpha a first estimate of the spectral abscissa.
    n_cheb : int, optional
        Chebyshev degree N; default from the a-priori bound (module docstring). An explicit value is
        used as given (no completeness guarantee if it is below the rule).
    n_cheb_max : int
        Largest degree the automatic rule may choose. Beyond it, with an explicit ``re_min`` a
        ``ValueError`` is raised; with ``re_min=None`` a ``RuntimeWarning`` is issued and
        ``n_cheb_max`` used.
    max_roots : int, optional
        Return at most this many roots (the rightmost ones).
    max_iter, step_tol, res_tol : int, float, float
        Newton iterations, relative step tolerance, and the acceptance threshold for the
        relative residual sigma_min(Delta(s)) / scale(s) (:meth:`DDESystem.scale`).
    reduced : bool
        Discretise the past of the delayed columns only (:func:`chebyshev_generator`): the
        same roots, at a fraction of the cost when the delays act on few components.

    Returns
    -------
    ndarray of complex
        Distinct roots (multiplicity not reported) sorted by real part descending, then imaginary
        part descending. For an ODE (no delays) these are the eigenvalues of A0 with Re >= re_min.

    Raises
    ------
    ValueError
        An invalid system or option, or an explicit ``re_min`` that needs more than
        ``n_cheb_max``.
    RuntimeError
        With ``re_min=None``, no root converged in the first pass.
    """
    sys_ = _system(A0, delayed)
    with _single_thread_blas():
        return _dde_roots(
            sys_, re_min, n_cheb, n_cheb_max, max_roots, max_iter, step_tol, res_tol, reduced
        )


def _dde_roots(
    sys_: DDESystem,
    re_min: float | None,
    n_cheb: int | None,
    n_cheb_max: int,
    max_roots: int | None,
    max_iter: int,
    step_tol: float,
    res_tol: float,
    reduced: bool = False,
) -> NDArray[np.complex128]:
    if re_min is not None:
        re_min = float(re_min)
        if not math.isfinite(re_min):
            raise ValueError(f"re_min must be finite, got {re_min!r}")
    if n_cheb is not None:
        if isinstance(n_cheb, bool) or int(n_cheb) != n_cheb or n_cheb < 2:
            raise ValueError(f"n_cheb must be an integer >= 2, got {n_cheb!r}")
        n_cheb = int(n_cheb)
    if max_roots is not None and (int(max_roots) != max_roots or max_roots < 1):
        raise ValueError(f"max_roots must be a positive integer, got {max_roots!r}")

    if sys_.tau_max == 0.0:
        ev = np.linalg.eigvals(sys_.A0).astype(complex)
        if sys_.is_real:
            ev = np.where(np.abs(ev.imag) <= 1e-14 * np.maximum(1.0, np.abs(ev)), ev.real, ev)
        if re_min is not None:
            ev = ev[ev.real >= re_min]
        ev = ev[np.lexsort((-ev.imag, -ev.real))]
        return ev[:max_roots] if max_roots else ev

    auto_region = re_min is None
    n0 = lam0 = None
    if re_min is None:
        margin = min(1.0, 2.0 / sys_.tau_max)
        # First pass: the rightmost roots are the best-resolved eigenvalues; a moderate degree
        # (resolving |s| <= R(0)) estimates alpha, the second pass guarantees the region.
        n0 = n_cheb if n_cheb is not None else min(default_n_cheb(sys_, 0.0), n_cheb_max)
        lam0 = np.linalg.eigvals(chebyshev_generator(sys_, n0, reduced))
        trusted = lam0[np.abs(lam0) <= max(1.0, 0.5 * n0 / sys_.tau_max)]
        pre = _refine(sys_, trusted, -np.inf, np.inf, max_iter, step_tol, res_tol)
        if pre.size == 0:  # nothing resolved in the trusted disc: try every eigenvalue
            pre = _refine(sys_, lam0, -np.inf, np.inf, max_iter, step_tol, res_tol)
        if pre.size == 0:
            raise RuntimeError(
                f"no characteristic root converged in the first pass (Chebyshev degree {n0})"
            )
        re_min = float(pre.real.max()) - margin

    r_max = sys_.radius_bound(re_min)
    if n_cheb is None:
        n_cheb = default_n_cheb(sys_, re_min)
        if n_cheb > n_cheb_max and auto_region:
            warnings.warn(
                f"automatic region Re s >= {re_min:.4g} would need Chebyshev degree {n_cheb}; "
                f"using n_cheb_max={n_cheb_max}: roots far from the rightmost may be missed",
                RuntimeWarning,
                stacklevel=3,
            )
            n_cheb = n_cheb_max
        elif n_cheb > n_cheb_max:
            raise ValueError(
                f"re_min={re_min!r} needs Chebyshev degree {n_cheb} > n_cheb_max={n_cheb_max} "
                f"(root modulus bound R={r_max:.4g}, tau_max={sys_.tau_max:.4g}); raise re_min "
                "or n_cheb_max"
            )
    if auto_region and n_cheb == n0:
        lam = lam0
    else:
        lam = np.linalg.eigvals(chebyshev_generator(sys_, n_cheb, reduced))
    roots = _refine(sys_, lam, re_min, r_max, max_iter, step_tol, res_tol)
    if roots.size == 0 and np.any(lam.real >= re_min):
        warnings.warn(
            "no Newton refinement converged although the discretisation has eigenvalues with "
            f"Re >= re_min={re_min}",
            RuntimeWarning,
            stacklevel=3,
        )
    return roots[:max_roots] if max_roots else roots


def spectral_abscissa(
    A0: ArrayLike | DDESystem, delayed: Sequence[tuple[float, ArrayLike]] = (), **kwargs: Any
) -> float:
    """max Re s over the characteristic roots (the rightmost root of :func:`dde_roots`).

    Parameters
    ----------
    A0, delayed
        The system, as for :func:`dde_roots`.
    **kwargs
        Passed to :func:`dde_roots`.

    Returns
    -------
    float
        The spectral abscissa: < 0 iff the system is exponentially stable.

    Raises
    ------
    RuntimeError
        No root was found in the requested region.
    """
    roots = dde_roots(A0, delayed, **kwargs)
    if roots.size == 0:
        raise RuntimeError("no characteristic root found in the requested region")
    return float(roots.real.max())
