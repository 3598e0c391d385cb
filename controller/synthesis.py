"""State-feedback synthesis of Theorem 1 (LMI (33)) and its independent certificate check (32).

Synthesis LMI (33), for fixed ``alpha > 0``, in ``S = S^T`` (4x4) and ``X`` (1x4)::

    M(S, X) = [[A0 S + S A0^T + B X + X^T B^T + alpha S,  A1 S],
               [S A1^T,                                  -alpha S]]
    M(S, X) + margin * diag(S, S) <= 0,        S >= I

The strict inequality of the paper is made well-posed by the margin, taken relative to
``diag(S, S)`` so that it means the same for every scaling of ``S`` and is equivalent (congruence
with ``diag(P, P)``, ``P = S^-1``) to ``(32) <= -margin*diag(P, P)``: the Razumikhin function
``x^T P x`` then has a guaranteed rate ``margin`` (units 1/tau). Because ``S >= I`` this implies
``M <= -margin*I``. (33) is homogeneous in ``(S, X)``, so the normalisation ``S >= I`` only fixes
the scale (it stops the solution from shrinking to 0). Among the solutions we take the one with the
smallest ``||X||_2`` (the least-effort certificate for that ``alpha``); ``F = X S^-1``. Solvers:
CLARABEL; SCS only if CLARABEL raises a solver error (an ``infeasible`` verdict is final).

Alpha line search (documented choice): ``alpha`` runs over :data:`ALPHA_GRID` (21 log-spaced
values, 4 per decade, 1e-3 .. 1e2). Every solution is checked independently (generalised
eigenvalues of (32) with ``P = S^-1``, which must show at least half the requested margin) and
kept only if the gain is bounded, ``||F||_2 <= gain_max``. The decay criterion is the spectral
abscissa of the averaged closed loop (29) with ``R_fb = F x`` at the nominal delay ``tau_n0``; the
best grid point is then refined on :data:`REFINE_POINTS` log-spaced values between its two grid
neighbours. In this family the decay improves with the gain (at the reference set, min ||X||
solutions: ||F|| = 120 at alpha = 0.56 with abscissa -0.68, ||F|| = 3.95e3 at alpha = 5.6 with
abscissa -2.57), so ``gain_max`` is the designer's knob; the default is of the order of the
paper's gain (``||F_paper||_2 = 3.82e3``).

Certificate check (independent of the solver): with ``P = S^-1`` the largest eigenvalue of the block
matrix (32) with ``A0 + B F`` must be negative (Lemma 1), and the closed-loop spectral abscissa must
be negative at ``tau_n0`` and for every constant delay of a sweep over ``(0, 5*tau_n0]``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cvxpy as cp
import numpy as np
from numpy.typing import ArrayLike, NDArray

from drillstring.controller.averaged import (
    AveragedModel,
    averaged_model,
    default_delay_sweep,
    delay_roots,
    spectral_abscissa_sweep,
)
from drillstring.controller.gains import GainsFile
from drillstring.model.params import ScaledParams

__all__ = [
    "ALPHA_GRID",
    "GAIN_MAX",
    "LMI_MARGIN",
    "REFINE_POINTS",
    "SOLVED",
    "SOLVERS",
    "AlphaAttempt",
    "Certificate",
    "GainEvaluation",
    "LmiSolution",
    "SynthesisInfeasible",
    "SynthesisResult",
    "check_certificate",
    "evaluate_gain",
    "lmi32",
    "razumikhin_certificate",
    "solve_program",
    "solve_synthesis_lmi",
    "synthesize",
    "to_gains_file",
]

#: Coarse alpha grid of the line search: 21 log-spaced values, 1e-3 .. 1e2.
ALPHA_GRID: NDArray[np.float64] = np.logspace(-3.0, 2.0, 21)
#: Number of log-spaced alphas in the refinement between the best grid point's neighbours.
REFINE_POINTS = 9
#: Relative margin of the LMIs: block <= -LMI_MARGIN * diag(S, S) (resp. diag(P, P)), S >= I.
LMI_MARGIN = 1e-3
#: Default bound on ||F||_2 for an admissible design (paper: ||F||_2 = 3.82e3).
GAIN_MAX = 4.0e3
#: Solvers tried in order for each LMI (the next only if one raises a solver error).
SOLVERS: tuple[str, ...] = ("CLARABEL", "SCS")
#: Options per solver (SCS: cap the iterations; its answer is checked independently anyway).
_SOLVER_OPTIONS: dict[str, dict[str, object]] = {"SCS": {"max_iters": 5000}}
#: The statuses whose answer is used (then checked independently, never trusted).
SOLVED = ("optimal", "optimal_inaccurate")


class SynthesisInfeasible(RuntimeError):
    """No admissible gain for any alpha tried; ``attempts`` holds what was tried."""

    def __init__(self, message: str, attempts: Sequence[AlphaAttempt]) -> None:
        super().__init__(message)
        self.attempts = tuple(attempts)


@dataclass(frozen=True, eq=False)
class LmiSolution:
    """Outcome of one LMI solve at fixed alpha; ``S``, ``X``, ``F`` are None unless solved."""

    alpha: float
    solver: str
    status: str
    tried: tuple[tuple[str, str], ...]
    S: NDArray[np.float64] | None = None
    X: NDArray[np.float64] | None = None
    F: NDArray[np.float64] | None = None


@dataclass(frozen=True)
class AlphaAttempt:
    """One point of the alpha line search (for reports and error messages)."""

    alpha: float
    solver: str
    status: str
    gain_norm: float | None
    abscissa: float | None
    accepted: bool
    note: str


@dataclass(frozen=True, eq=False)
class Certificate:
    """Independent check of a gain: Lemma 1 with ``P`` and the closed-loop spectrum.

    ``lmi_max_eig`` is the largest eigenvalue of the block matrix M of (32) with ``A0 + B F``
    (must be < 0); ``lmi_decay_margin = -mu`` with ``mu`` the largest generalised eigenvalue of
    ``(M, diag(P, P))``, i.e. the largest ``mu`` with ``M <= mu*diag(P, P)``: invariant under
    scaling of ``P`` and equal for (32) and (33) (congruence with ``diag(S, S)``), in units of
    1/tau; the LMIs are solved with ``mu <= -margin``. ``P_min_eig`` must be > 0.
    ``abscissa`` is the closed-loop spectral abscissa for each delay in ``taus``.
    """

    alpha: float
    P: NDArray[np.float64]
    lmi_max_eig: float
    lmi_decay_margin: float
    P_min_eig: float
    abscissa_nominal: float
    taus: NDArray[np.float64]
    abscissa: NDArray[np.float64]

    @property
    def lmi_ok(self) -> bool:
        """(32) holds: block and generalised eigenvalues w.r.t. diag(P, P) negative, P > 0."""
        return self.lmi_max_eig < 0.0 and self.lmi_decay_margin > 0.0 and self.P_min_eig > 0.0

    @property
    def spectrum_ok(self) -> bool:
        """All closed-loop roots in the open left half plane at tau_n0 and over the sweep."""
        return self.abscissa_nominal < 0.0 and bool(np.all(self.abscissa < 0.0))

    @property
    def passed(self) -> bool:
        """Both :attr:`lmi_ok` and :attr:`spectrum_ok`."""
        return self.lmi_ok and self.spectrum_ok

    def margins(self) -> dict[str, float]:
        """The certificate's numbers for the gains file and reports.

        Returns
        -------
        dict of str to float
            ``lmi32_max_eig`` and ``lmi32_decay_margin`` (Lemma 1, (32)), ``P_min_eig``,
            ``abscissa_nominal`` (at tau_n0) and ``abscissa_sweep_max`` (the largest spectral
            abscissa over the delay sweep and tau_n0).
        """
        return {
            "lmi32_max_eig": self.lmi_max_eig,
            "lmi32_decay_margin": self.lmi_decay_margin,
            "P_min_eig": self.P_min_eig,
            "abscissa_nominal": self.abscissa_nominal,
            "abscissa_sweep_max": float(np.max(self.abscissa, initial=self.abscissa_nominal)),
        }


@dataclass(frozen=True, eq=False)
class SynthesisResult:
    """Chosen design: gain, LMI solution, alpha search and certificate."""

    model: AveragedModel
    alpha: float
    F: NDArray[np.float64]
    S: NDArray[np.float64]
    X: NDArray[np.float64]
    solver: str
    status: str
    attempts: tuple[AlphaAttempt, ...]
    certificate: Certificate
    gain_max: float
    margin: float


@dataclass(frozen=True, eq=False)
class GainEvaluation:
    """A given gain on the averaged model: roots, delay sweep and Razumikhin certificate."""

    F: NDArray[np.float64]
    model: AveragedModel
    roots_nominal: NDArray[np.complex128]
    abscissa_nominal: float
    taus: NDArray[np.float64]
    abscissa: NDArray[np.float64]
    certificate: Certificate | None
    attempts: tuple[tuple[float, str, str], ...]


# ------------------------------------------------------------------------------------------------
# LMIs
# ------------------------------------------------------------------------------------------------


def lmi32(
    Abar: NDArray[np.float64], A1: NDArray[np.float64], P: NDArray[np.float64], alpha: float
) -> NDArray[np.float64]:
    """The (symmetrised) block matrix of (32) for ``x' = Abar x + A1 x(t - tau)``.

    Parameters
    ----------
    Abar : ndarray
        Closed-loop matrix ``A0 + B F`` (n x n).
    A1 : ndarray
        Delayed matrix (n x n).
    P : ndarray
        Candidate Razumikhin matrix (n x n, symmetric).
    alpha : float
        The scalar of Lemma 1.

    Returns
    -------
    ndarray
        The symmetric 2n x 2n matrix of (32); Lemma 1 asks it to be negative definite.
    """
    top = np.hstack([P @ Abar + Abar.T @ P + alpha * P, P @ A1])
    bottom = np.hstack([A1.T @ P, -alpha * P])
    M = np.vstack([top, bottom])
    return 0.5 * (M + M.T)


def _check_alpha(alpha: float) -> float:
    a = float(alpha)
    if not (math.isfinite(a) and a > 0.0):
        raise ValueError(f"alpha must be a finite number > 0, got {alpha!r}")
    return a


def solve_program(
    problem: cp.Problem, solvers: Sequence[str] = SOLVERS
) -> tuple[str, str, tuple[tuple[str, str], ...]]:
    """Solve with the first solver; the next one is only tried if a solver raises an error.

    A status such as ``infeasible`` is final (SCS, slower and less accurate here, would not
    overturn CLARABEL's verdict). Returns ``(solver, status, tried)``.
    """
    tried: list[tuple[str, str]] = []
    for name in solvers:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # "solution may be inaccurate": checked by us
                problem.solve(solver=name, **_SOLVER_OPTIONS.get(name, {}))
        except cp.error.SolverError as exc:
            tried.append((name, f"solver_error: {str(exc).splitlines()[0]}"))
            continue
        tried.append((name, str(problem.status)))
        break
    return tried[-1][0], tried[-1][1], tuple(tried)


def solve_synthesis_lmi(
    A0: NDArray[np.float64],
    A1: NDArray[np.float64],
    B: NDArray[np.float64],
    alpha: float,
    *,
    margin: float = LMI_MARGIN,
    solvers: Sequence[str] = SOLVERS,
) -> LmiSolution:
    """Solve (33) at fixed ``alpha``: ``S >= I``, block <= -margin*diag(S, S), min ``||X||_2``.

    Parameters
    ----------
    A0, A1, B : ndarray
        The matrices of (29)-(30): n x n, n x n, n x m.
    alpha : float
        The scalar of Theorem 1, finite and > 0.
    margin : float
        Relative margin of the strict inequality (module docstring).
    solvers : sequence of str
        cvxpy solvers; the next is tried only if one raises a solver error.

    Returns
    -------
    LmiSolution
        Solver, status and, when solved, ``S``, ``X`` and ``F = X S^-1``.

    Raises
    ------
    ValueError
        ``alpha`` not finite or not > 0.
    """
    alpha = _check_alpha(alpha)
    n, m = A0.shape[0], B.shape[1]
    S = cp.Variable((n, n), symmetric=True)
    X = cp.Variable((m, n))
    M11 = A0 @ S + S @ A0.T + B @ X + X.T @ B.T + alpha * S
    M = cp.bmat([[M11, A1 @ S], [S @ A1.T, -alpha * S]])
    D = cp.bmat([[S, np.zeros((n, n))], [np.zeros((n, n)), S]])
    cons = [S >> np.eye(n), 0.5 * (M + M.T) + margin * D << 0]
    problem = cp.Problem(cp.Minimize(cp.norm(X, 2)), cons)
    solver, status, tried = solve_program(problem, solvers)
    if status not in SOLVED or S.value is None or X.value is None:
        return LmiSolution(alpha, solver, status, tried)
    Sv = 0.5 * (S.value + S.value.T)
    Xv = np.asarray(X.value, dtype=float)
    F = np.linalg.solve(Sv, Xv.T).T  # X S^-1 with S symmetric
    return LmiSolution(alpha, solver, status, tried, Sv, Xv, F.reshape(-1))


def razumikhin_certificate(
    Abar: NDArray[np.float64],
    A1: NDArray[np.float64],
    alpha: float,
    *,
    margin: float = LMI_MARGIN,
    solvers: Sequence[str] = SOLVERS,
) -> tuple[NDArray[np.float64] | None, str, str]:
    """Feasibility of (32) in ``P`` for a fixed closed-loop ``Abar`` and ``alpha``.

    ``P >= I``, block <= -margin*diag(P, P), minimise trace(P).

    Parameters
    ----------
    Abar : ndarray
        Closed-loop matrix ``A0 + B F`` (n x n).
    A1 : ndarray
        Delayed matrix (n x n).
    alpha : float
        The scalar of Lemma 1, finite and > 0.
    margin : float
        Relative margin of the strict inequality.
    solvers : sequence of str
        cvxpy solvers, as for :func:`solve_synthesis_lmi`.

    Returns
    -------
    P : ndarray or None
        The solution, or None when the LMI was not solved.
    solver, status : str
        The solver that answered and its status.

    Raises
    ------
    ValueError
        ``alpha`` not finite or not > 0.
    """
    alpha = _check_alpha(alpha)
    n = Abar.shape[0]
    P = cp.Variable((n, n), symmetric=True)
    M = cp.bmat([[P @ Abar + Abar.T @ P + alpha * P, P @ A1], [A1.T @ P, -alpha * P]])
    D = cp.bmat([[P, np.zeros((n, n))], [np.zeros((n, n)), P]])
    cons = [P >> np.eye(n), 0.5 * (M + M.T) + margin * D << 0]
    problem = cp.Problem(cp.Minimize(cp.trace(P)), cons)
    solver, status, _ = solve_program(problem, solvers)
    if status not in SOLVED or P.value is None:
        return None, solver, status
    return 0.5 * (P.value + P.value.T), solver, status


# ------------------------------------------------------------------------------------------------
# certificate check
# ------------------------------------------------------------------------------------------------


def _as_gain(F: ArrayLike) -> NDArray[np.float64]:
    Fv = np.asarray(F, dtype=float).reshape(-1)
    if Fv.shape != (4,) or not np.all(np.isfinite(Fv)):
        raise ValueError(f"F must be 4 finite numbers, got {F!r}")
    return Fv


def check_certificate(
    model: AveragedModel,
    F: ArrayLike,
    P: ArrayLike,
    alpha: float,
    taus: Sequence[float] | NDArray[np.float64] | None = None,
    *,
    _sweep: tuple[float, NDArray[np.float64]] | None = None,
) -> Certificate:
    """Check Lemma 1 (32) for ``A0 + B F`` with ``P`` and the closed-loop roots over ``taus``.

    Uses only numpy eigenvalues and the root finder, not the LMI solver.

    Parameters
    ----------
    model : AveragedModel
        The averaged model.
    F : array_like
        The gain, 4 finite numbers.
    P : array_like
        Razumikhin matrix (symmetrised before use).
    alpha : float
        The scalar of Lemma 1, finite and > 0.
    taus : sequence of float, optional
        Constant delays of the spectral sweep; default
        :func:`~drillstring.controller.averaged.default_delay_sweep` (25 delays in
        (0, 5*tau_n0]).
    _sweep : (float, ndarray), optional
        Internal: an already computed ``(abscissa at tau_n0, sweep over taus)``.

    Returns
    -------
    Certificate
        The margins; :attr:`Certificate.passed` is the verdict.

    Raises
    ------
    ValueError
        A bad ``F`` or ``alpha``.
    """
    Fv = _as_gain(F)
    Pm = np.asarray(P, dtype=float)
    Pm = 0.5 * (Pm + Pm.T)
    alpha = _check_alpha(alpha)
    Abar = model.A0 + model.B @ Fv[None, :]
    M = lmi32(Abar, model.A1, Pm, alpha)
    lmi_max = float(np.linalg.eigvalsh(M)[-1])
    taus_arr = default_delay_sweep(model) if taus is None else np.asarray(taus, dtype=float)
    if _sweep is None:
        nominal = float(delay_roots(model, Fv, None, 1)[0].real)
        sweep = spectral_abscissa_sweep(model, Fv, taus_arr)
    else:
        nominal, sweep = _sweep
    return Certificate(
        alpha=alpha,
        P=Pm,
        lmi_max_eig=lmi_max,
        lmi_decay_margin=_decay_margin(M, Pm),
        P_min_eig=float(np.linalg.eigvalsh(Pm)[0]),
        abscissa_nominal=nominal,
        taus=taus_arr,
        abscissa=np.asarray(sweep, dtype=float),
    )


def _decay_margin(M: NDArray[np.float64], P: NDArray[np.float64]) -> float:
    """``-mu``, ``mu`` the largest generalised eigenvalue of ``(M, diag(P, P))``; -inf if P !> 0."""
    try:
        L = np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return -math.inf
    Z = np.zeros_like(L)
    Li = np.linalg.inv(np.block([[L, Z], [Z, L]]))
    return -float(np.linalg.eigvalsh(Li @ M @ Li.T)[-1])


def _margin_of(model: AveragedModel, F: NDArray[np.float64], P: NDArray[np.float64], alpha: float):
    return _decay_margin(lmi32(model.A0 + model.B @ F[None, :], model.A1, P, alpha), P)


# ------------------------------------------------------------------------------------------------
# synthesis with alpha line search
# ------------------------------------------------------------------------------------------------


def _attempt(
    model: AveragedModel, alpha: float, gain_max: float, margin: float, solvers: Sequence[str]
) -> tuple[AlphaAttempt, LmiSolution]:
    sol = solve_synthesis_lmi(model.A0, model.A1, model.B, alpha, margin=margin, solvers=solvers)
    if sol.F is None:
        note = "; ".join(f"{s}: {st}" for s, st in sol.tried)
        return AlphaAttempt(alpha, sol.solver, sol.status, None, None, False, note), sol
    gain = float(np.linalg.norm(sol.F))
    dm = _margin_of(model, sol.F, np.linalg.inv(sol.S), alpha)
    if not dm >= 0.5 * margin:
        note = f"(32) check: decay margin {dm:.2e} < margin/2"
        return AlphaAttempt(alpha, sol.solver, sol.status, gain, None, False, note), sol
    if gain > gain_max:
        note = f"||F|| = {gain:.3g} > gain_max = {gain_max:.3g}"
        return AlphaAttempt(alpha, sol.solver, sol.status, gain, None, False, note), sol
    abscissa = float(delay_roots(model, sol.F, None, 1)[0].real)
    if not abscissa < 0.0:
        note, ok = "closed loop not stable at tau_n0", False
    else:
        note, ok = "", True
    return AlphaAttempt(alpha, sol.solver, sol.status, gain, abscissa, ok, note), sol


def synthesize(
    model: AveragedModel,
    *,
    alphas: Sequence[float] | NDArray[np.float64] = ALPHA_GRID,
    refine: int = REFINE_POINTS,
    gain_max: float = GAIN_MAX,
    margin: float = LMI_MARGIN,
    solvers: Sequence[str] = SOLVERS,
    taus: Sequence[float] | NDArray[np.float64] | None = None,
) -> SynthesisResult:
    """Theorem 1: line search over alpha for the gain with the best closed-loop decay.

    See the module docstring for the grid, the refinement and the decay criterion.

    Parameters
    ----------
    model : AveragedModel
        The averaged model (29)-(31).
    alphas : sequence of float
        The coarse grid, each finite and > 0.
    refine : int
        Extra alphas between the best grid point's neighbours (0: no refinement).
    gain_max : float
        Bound on ||F||_2 of an admissible gain.
    margin : float
        Relative margin of the LMIs.
    solvers : sequence of str
        cvxpy solvers, as for :func:`solve_synthesis_lmi`.
    taus : sequence of float, optional
        Delays of the certificate's spectral sweep (see :func:`check_certificate`).

    Returns
    -------
    SynthesisResult
        The chosen gain with its LMI solution, every attempt and the certificate (whose
        ``passed`` must still be checked: the sweep over delays is not part of the search).

    Raises
    ------
    SynthesisInfeasible
        No alpha gives a verified gain with ``||F|| <= gain_max``.
    ValueError
        Bad ``alphas``, ``gain_max`` or ``margin``.
    """
    grid = np.sort(np.asarray(alphas, dtype=float).reshape(-1))
    if grid.size == 0 or not np.all(np.isfinite(grid)) or np.any(grid <= 0.0):
        raise ValueError(f"alphas must be finite numbers > 0, got {alphas!r}")
    if not (math.isfinite(gain_max) and gain_max > 0.0):
        raise ValueError(f"gain_max must be a finite number > 0, got {gain_max!r}")
    if not (math.isfinite(margin) and margin > 0.0):
        raise ValueError(f"margin must be a finite number > 0, got {margin!r}")

    attempts: list[AlphaAttempt] = []
    solutions: dict[float, LmiSolution] = {}
    for a in grid:
        att, sol = _attempt(model, float(a), gain_max, margin, solvers)
        attempts.append(att)
        solutions[att.alpha] = sol
    accepted = [att for att in attempts if att.accepted]
    if not accepted:
        raise SynthesisInfeasible(_infeasible_message(attempts, gain_max, margin), attempts)

    best = min(accepted, key=lambda att: att.abscissa)
    if refine > 0 and grid.size > 1:
        i = int(np.searchsorted(grid, best.alpha))
        lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        for a in np.logspace(math.log10(lo), math.log10(hi), refine + 2)[1:-1]:
            if any(math.isclose(a, g, rel_tol=1e-12) for g in grid):
                continue
            att, sol = _attempt(model, float(a), gain_max, margin, solvers)
            attempts.append(att)
            solutions[att.alpha] = sol
            if att.accepted and att.abscissa < best.abscissa:
                best = att

    sol = solutions[best.alpha]
    assert sol.S is not None and sol.X is not None and sol.F is not None
    cert = check_certificate(model, sol.F, np.linalg.inv(sol.S), best.alpha, taus)
    return SynthesisResult(
        model=model,
        alpha=best.alpha,
        F=sol.F,
        S=sol.S,
        X=sol.X,
        solver=sol.solver,
        status=sol.status,
        attempts=tuple(attempts),
        certificate=cert,
        gain_max=gain_max,
        margin=margin,
    )


def _infeasible_message(attempts: Sequence[AlphaAttempt], gain_max: float, margin: float) -> str:
    lines = [
        f"LMI (33) gave no admissible gain for any of the {len(attempts)} alphas tried "
        f"(margin {margin:g}, ||F|| <= {gain_max:g}):"
    ]
    for att in attempts:
        extra = f" ({att.note})" if att.note else ""
        lines.append(f"  alpha = {att.alpha:.4g}: {att.solver} {att.status}{extra}")
    solved = [att.gain_norm for att in attempts if att.gain_norm is not None]
    if solved:
        lines.append(f"smallest ||F|| among solved alphas: {min(solved):.4g}; raise gain_max?")
    return "\n".join(lines)


def to_gains_file(result: SynthesisResult, params: ScaledParams, **record: Any) -> GainsFile:
    """The gains-file record of a design.

    Parameters
    ----------
    result : SynthesisResult
        The design (or a :class:`~drillstring.controller.constrained.ConstrainedResult`: the
        same model, gain, alpha, certificate and solver).
    params : ScaledParams
        The set the model was built from (the record checks K0 against it).
    **record
        The record's further fields (a constrained design's ``constraint``).

    Returns
    -------
    GainsFile
        Gain, constants, certificate margins and solver of the design.

    Raises
    ------
    GainsFileError
        ``params`` does not give the model's K0.
    """
    return GainsFile.of_model(
        result.model,
        params,
        result.F,
        alpha=result.alpha,
        certificate=result.certificate.margins(),
        spectral_abscissa=result.certificate.abscissa_nominal,
        solver=result.solver,
        solver_status=result.status,
        **record,
    )


# ------------------------------------------------------------------------------------------------
# evaluation of a given gain
# ------------------------------------------------------------------------------------------------


def evaluate_gain(
    F: ArrayLike,
    params: ScaledParams,
    A: float,
    taubar_crit: float,
    *,
    taus: Sequence[float] | NDArray[np.float64] | None = None,
) -> GainEvaluation:
    """Evaluate a gain ``F`` (e.g. the paper's, :data:`~drillstring.controller.gains.PAPER_F`)
    on the averaged model at ``params``.

    Closed-loop roots at ``tau_n0`` (the 8 rightmost), the spectral abscissa over the delay
    sweep, and whether a Razumikhin certificate (32) exists for this ``F`` with some ``P`` and an
    ``alpha`` of :data:`ALPHA_GRID` (LMI in ``P`` with :data:`LMI_MARGIN`; the first alpha whose
    solution passes the numpy check is kept).

    Parameters
    ----------
    F : array_like
        The gain, 4 finite numbers.
    params : ScaledParams
        The parameter set.
    A, taubar_crit : float
        The axial quantities of (22).
    taus : sequence of float, optional
        Delays of the spectral sweep (default as :func:`check_certificate`).

    Returns
    -------
    GainEvaluation
        Roots, sweep and the certificate (None when no alpha gave one).

    Raises
    ------
    ValueError
        A bad ``F``, ``A`` or ``taubar_crit``.
    """
    Fv = _as_gain(F)
    model = averaged_model(params, A, taubar_crit)
    taus_arr = default_delay_sweep(model) if taus is None else np.asarray(taus, dtype=float)
    roots = delay_roots(model, Fv)
    sweep = spectral_abscissa_sweep(model, Fv, taus_arr)
    Abar = model.A0 + model.B @ Fv[None, :]
    tried: list[tuple[float, str, str]] = []
    cert: Certificate | None = None
    for a in np.asarray(ALPHA_GRID, dtype=float).reshape(-1):
        P, solver, status = razumikhin_certificate(Abar, model.A1, float(a))
        tried.append((float(a), solver, status))
        if P is not None and _margin_of(model, Fv, P, float(a)) >= 0.5 * LMI_MARGIN:
            nominal = float(roots[0].real)
            cert = check_certificate(model, Fv, P, float(a), taus_arr, _sweep=(nominal, sweep))
            break
    return GainEvaluation(
        F=Fv,
        model=model,
        roots_nominal=roots,
        abscissa_nominal=float(roots[0].real),
        taus=taus_arr,
        abscissa=sweep,
        certificate=cert,
        attempts=tuple(tried),
    )
