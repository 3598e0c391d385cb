"""An input-constrained synthesis beside Theorem 1: a gain whose torque stays within the top
drive's rating from the switch-on, certified on the averaged model (``docs/controllers.md``,
"The input-constrained design").

The paper's synthesis (33) bounds nothing but the gain; the fastest decay it allows needs torques
no top drive has (about 1200 R0 at the Fig. 6 switch-on). Here, for fixed alpha, in ``S = S^T``,
``X`` (1x4) and ``mu``::

    minimise mu  subject to
      M_c(S, X) + margin*diag(S, S) <= 0   for c in {1, exp(sigma*tau_max)}          (a)
      [[1, x_i^T], [x_i, S]] >= 0            for every switch-on state x_i             (b)
      [[mu, X], [X^T, S]] >= 0                                                        (c)
      mu <= u_max**2                         (with a torque limit)                    (d)

with ``M_c`` the block matrix of (33) for ``A0 + sigma*I`` and ``c*A1``. (a) is Lemma 1 for the
closed loop of ``x = exp(-sigma tau) z``: ``z' = (A0 + B F + sigma I) z + exp(sigma tau_n) A1
z(tau - tau_n)``; (33) is affine in the factor ``exp(sigma tau_n)``, so the two ends of its range
for delays in (0, tau_max] cover every delay between, and the Razumikhin function ``x^T S^-1 x``
then decays at the rate ``sigma`` (at least) on the averaged model (29). (b) puts every
switch-on state (the state at the switch-on and its history over the delay before it, as the
Razumikhin argument needs) in the ellipsoid ``E = {x : x^T S^-1 x <= 1}``, which (a) makes
invariant. (c) says ``max over E of |F x| = sqrt(F S F^T) <= sqrt(mu)``, ``F = X S^-1``: from any
switch-on state the feedback torque never exceeds ``sqrt(mu)`` (on the averaged model). The
objective is the smallest such peak feedback torque: the least gain that the required decay
``sigma`` allows from these states. With a torque limit ``u_max`` (the smaller of the top
drive's two margins about the operating torque, :func:`torque_budget`: the range need not be
symmetric, and on the centred ellipsoid the smaller margin binds exactly) the design is refused
when even the smallest peak exceeds it; :func:`least_braking` then finds, by bisection on the
braking limit (-R_min) with the solve above, the least braking at which a design is certified
(``docs/controllers.md``, "Braking"). alpha runs over the grid of the paper's design, refined
around the best point.

The required decay defaults to :data:`DEFAULT_DECAY`, the rate at which a deviation halves in
three torsional periods of the string (``docs/controllers.md``, "The input-constrained design").

:func:`check_constrained` verifies a result independently of the solver (numpy eigenvalues and
the root finder): (a) at both ends, (b) for every state, (c) and (d), and the closed-loop
spectral abscissa at tau_n0 and over the delay sweep of the paper's certificate.
:func:`recheck_constrained` does it again from a gains file alone (its ellipsoid S and switch-on
states are written there).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

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
from drillstring.controller.gains import GainsFile, GainsFileError
from drillstring.controller.synthesis import (
    ALPHA_GRID,
    LMI_MARGIN,
    REFINE_POINTS,
    SOLVED,
    SOLVERS,
    SynthesisInfeasible,
    lmi32,
    solve_program,
)
from drillstring.controller.tuning import OMEGA_S
from drillstring.model.control import LATCH_MODES
from drillstring.model.engine import EngineOptions
from drillstring.model.experiments import Experiment
from drillstring.model.params import ScaledParams
from drillstring.model.simulate import simulate
from drillstring.model.topdrive import TopDrive
from drillstring.validation import check_choice, check_real

__all__ = [
    "BRAKING_TOL",
    "DEFAULT_DECAY",
    "HALF_LIFE_PERIODS",
    "ConstrainedCertificate",
    "ConstrainedInfeasible",
    "ConstrainedResult",
    "check_constrained",
    "least_braking",
    "recheck_constrained",
    "solve_constrained_lmi",
    "switch_on_states",
    "synthesize_constrained",
    "torque_budget",
    "torque_margins",
]

#: Half-life of a deviation of the averaged closed loop that the default decay requires, in
#: torsional periods of the string with the table held (2*pi/omega_s).
HALF_LIFE_PERIODS = 3
#: Default required decay rate sigma of the constrained design (1/tau): a deviation at least
#: halves in three torsional periods, sigma = ln 2/(3*2*pi/omega_s) = 0.0368 (a half-life of
#: 17.4 s on the reference rig). Zero certifies stability only (the Razumikhin function does not
#: grow: an arbitrarily slow decay passes). Measured on the reference rig with the TDS-11SA from
#: the Fig. 6 switch-on: the torque budget 212.1 allows up to about 0.08 (least peaks 185 at
#: 0.05, 227 at 0.1), but from two periods (0.055) on the full-model run drives the table
#: against the drive's no-reverse speed limit, which the certificate does not bound; at three
#: periods no sample is limited (``docs/controllers.md``, "The input-constrained design").
DEFAULT_DECAY = math.log(2.0) / (HALF_LIFE_PERIODS * 2.0 * math.pi / OMEGA_S)
#: Default tolerance of the bisection on the braking limit (:func:`least_braking`), units of C
#: (0.05 C = 11.8 N m on the reference rig; ``drillstring design`` bisects to 0.01 kN m).
BRAKING_TOL = 0.05
#: Relative slack of the state and torque constraints inside the LMI program.
_SLACK = 1e-6


@dataclass(frozen=True, eq=False)
class ConstrainedCertificate:
    """The independent check of a constrained design (see :func:`check_constrained`).

    ``lmi_max_eig`` is the largest eigenvalue of the shifted (32) with ``P = S^-1`` over both
    ends of the delay factor (must be < 0); ``state_max`` the largest ``x_i^T S^-1 x_i`` (must be
    <= 1); ``peak_torque`` is ``sqrt(F S F^T)``, the largest feedback torque on the ellipsoid
    (<= ``u_max``, the smaller of the drive's two margins about the operating torque);
    ``abscissa_nominal`` and ``abscissa`` the closed-loop spectral abscissae at tau_n0 and over
    ``taus`` (must be <= -sigma); ``braking_limit`` the drive's braking limit the lower margin
    came from (-R_min, units of C; None: not known to the check).
    """

    lmi_max_eig: float
    state_max: float
    peak_torque: float
    u_max: float
    sigma: float
    abscissa_nominal: float
    taus: NDArray[np.float64]
    abscissa: NDArray[np.float64]
    braking_limit: float | None = None

    @property
    def passed(self) -> bool:
        """Every condition holds."""
        return (
            self.lmi_max_eig < 0.0
            and self.state_max <= 1.0
            and self.peak_torque <= self.u_max
            and self.abscissa_nominal <= -self.sigma
            and bool(np.all(self.abscissa <= -self.sigma))
        )

    def margins(self) -> dict[str, float]:
        """The certificate's numbers for the gains file and reports."""
        return {
            "lmi32_max_eig": self.lmi_max_eig,
            "switch_on_states_max": self.state_max,
            "peak_torque": self.peak_torque,
            "abscissa_nominal": self.abscissa_nominal,
            "abscissa_sweep_max": float(np.max(self.abscissa, initial=self.abscissa_nominal)),
        }


@dataclass(frozen=True, eq=False)
class ConstrainedResult:
    """The chosen constrained design: gain, ellipsoid, alpha search and certificate."""

    model: AveragedModel
    alpha: float
    F: NDArray[np.float64]
    S: NDArray[np.float64]
    peak_torque: float
    u_max: float
    sigma: float
    tau_max: float
    states: NDArray[np.float64]
    solver: str
    status: str
    attempts: tuple[tuple[float, str, float | None], ...]
    certificate: ConstrainedCertificate


class ConstrainedInfeasible(SynthesisInfeasible):
    """No constrained design within the drive's torque range: the least peak feedback torque
    found (``least_peak``, at ``alpha``) is above the budget ``u_max``.

    ``braking_limit`` is the drive's braking limit (-R_min, units of C) and ``least_braking``
    the least braking limit at which a design is certified (found by :func:`least_braking`;
    None: not searched, or no braking limit helps because the margin above the operating torque
    is itself too small), to within ``tol``.
    """

    def __init__(
        self,
        message: str,
        *,
        least_peak: float | None,
        alpha: float | None,
        u_max: float,
        braking_limit: float | None = None,
        least_braking: float | None = None,
        tol: float | None = None,
    ) -> None:
        super().__init__(message, ())
        self.least_peak = least_peak
        self.alpha = alpha
        self.u_max = u_max
        self.braking_limit = braking_limit
        self.least_braking = least_braking
        self.tol = tol


def torque_margins(params: ScaledParams, top_drive: TopDrive, R_ff: float) -> tuple[float, float]:
    """The drive's two margins about the operating torque R0 + R_ff: ``(R0 + R_ff - R_min,
    R_max - R0 - R_ff)``, below (braking side) and above (absolute torques, units of C).

    The range [R_min, R_max] need not be symmetric about R0: a drive without braking has
    R_min = 0, so its margin below is the operating torque itself."""
    bias = params.R0 + check_real("R_ff", R_ff)
    return bias - top_drive.R_min, top_drive.R_max - bias


def torque_budget(params: ScaledParams, top_drive: TopDrive, R_ff: float) -> float:
    """The feedback torque the top drive leaves around the feed-forward: the smaller of its two
    margins (:func:`torque_margins`), ``min(R_max - (R0 + R_ff), (R0 + R_ff) - R_min)``
    (absolute torques, units of C; eq. (8), (31)).

    The ellipsoid E of the certificate is symmetric about x = 0, so the feedback torque F x
    takes the values [-sqrt(F S F^T), +sqrt(F S F^T)] on it: for the torque to stay within an
    asymmetric range from every state of E, the smaller margin binds, exactly
    (``docs/controllers.md``, "Braking").

    Raises
    ------
    ValueError
        The feed-forward torque itself is outside the drive's range.
    """
    bias = params.R0 + check_real("R_ff", R_ff)
    budget = min(torque_margins(params, top_drive, R_ff))
    if not budget > 0.0:
        raise ValueError(
            f"the feed-forward torque R0 + R_ff = {bias!r} is not inside the top drive's range "
            f"[{top_drive.R_min!r}, {top_drive.R_max!r}]"
        )
    return budget


def switch_on_states(
    params: ScaledParams,
    model: AveragedModel,
    experiment: Experiment,
    *,
    latch: str = "angle",
    span: float | None = None,
    every: int = 5,
) -> NDArray[np.float64]:
    """The states x of (29) at an experiment's switch-on and over the delay before it.

    The open loop (``R - R0 = R_ff``, the torsional-stick model as the experiment says) is run
    to ``t_on``; x = [phi - phi_ref, dphi, phi - theta - K0 - twist_ref, dtheta] with the
    references the latch takes at ``t_on`` (``docs/model.md``, "Bumpless switch-on"), sampled
    every ``every``-th output point (0.01) over [t_on - span, t_on] (default span 2 tau_n0).

    Returns
    -------
    ndarray (k, 4)
        The states, the last one at the switch-on.
    """
    check_choice("latch", latch, LATCH_MODES)
    t_on = check_real("experiment t_on", experiment.t_on, lower=0.0)
    span = 2.0 * model.tau_n0 if span is None else check_real("span", span, lower=0.0)
    options = EngineOptions(h=experiment.h, torsional_stick=experiment.torsional_stick)
    run = simulate(params, t_on, control=model.R_ff, initial=experiment.initial(), options=options)
    if not run.status.ok:
        raise ValueError(f"the open loop before the switch-on stopped: {run.status.message}")
    phi_ref = run.phi[-1] if latch != "none" else 0.0
    twist_ref = run.phi[-1] - run.theta[-1] - model.K0 if latch == "angle+twist" else 0.0
    keep = run.tau >= t_on - span
    x = np.column_stack(
        [
            run.phi[keep] - phi_ref,
            run.dphi[keep],
            run.phi[keep] - run.theta[keep] - model.K0 - twist_ref,
            run.dtheta[keep],
        ]
    )
    return np.ascontiguousarray(x[::-1][::every][::-1])


def _shifted(model: AveragedModel, sigma: float, tau_max: float):
    n = model.A0.shape[0]
    A0s = model.A0 + sigma * np.eye(n)
    return A0s, (model.A1, math.exp(sigma * tau_max) * model.A1)


def solve_constrained_lmi(
    model: AveragedModel,
    states: ArrayLike,
    alpha: float,
    *,
    sigma: float = DEFAULT_DECAY,
    tau_max: float | None = None,
    u_max: float | None = None,
    margin: float = LMI_MARGIN,
    solvers: Sequence[str] = SOLVERS,
) -> tuple[str, str, NDArray[np.float64] | None, NDArray[np.float64] | None, float | None]:
    """Solve the program of the module docstring at fixed ``alpha``.

    Returns
    -------
    (solver, status, S, F, peak)
        ``S``, ``F`` and the peak feedback torque ``sqrt(mu)`` when solved, else None.
    """
    X0 = np.atleast_2d(np.asarray(states, dtype=float))
    n = model.A0.shape[0]
    tau_max = 2.0 * model.tau_n0 if tau_max is None else tau_max
    A0s, A1s = _shifted(model, sigma, tau_max)
    S = cp.Variable((n, n), symmetric=True)
    X = cp.Variable((1, n))
    mu = cp.Variable((1, 1))
    D = cp.bmat([[S, np.zeros((n, n))], [np.zeros((n, n)), S]])
    cons = [S >> 1e-9 * np.eye(n)]
    for A1 in A1s:
        M11 = A0s @ S + S @ A0s.T + model.B @ X + X.T @ model.B.T + alpha * S
        M = cp.bmat([[M11, A1 @ S], [S @ A1.T, -alpha * S]])
        cons.append(0.5 * (M + M.T) + margin * D << 0)
    # (b) and (d) with a relative slack, so that the solver's tolerance cannot put a state or
    # the peak just outside what the independent check accepts
    inside = np.full((1, 1), 1.0 - _SLACK)
    for x in X0:
        cons.append(cp.bmat([[inside, x[None, :]], [x[:, None], S]]) >> 0)
    cons.append(cp.bmat([[mu, X], [X.T, S]]) >> 0)
    if u_max is not None:
        cons.append(mu <= (u_max * (1.0 - _SLACK)) ** 2)
    problem = cp.Problem(cp.Minimize(mu[0, 0]), cons)
    tried, status, _ = solve_program(problem, solvers)
    if status not in SOLVED or S.value is None:
        return tried, status, None, None, None
    Sv = 0.5 * (S.value + S.value.T)
    F = np.linalg.solve(Sv, np.asarray(X.value, dtype=float).T).reshape(-1)
    return tried, status, Sv, F, float(math.sqrt(max(float(mu.value[0, 0]), 0.0)))


def check_constrained(
    model: AveragedModel,
    F: ArrayLike,
    S: ArrayLike,
    alpha: float,
    states: ArrayLike,
    u_max: float,
    *,
    sigma: float = DEFAULT_DECAY,
    tau_max: float | None = None,
    braking_limit: float | None = None,
) -> ConstrainedCertificate:
    """Check a constrained design without the solver (module docstring); ``braking_limit`` is
    only recorded in the result (``u_max`` already holds the margin it gives).

    Returns
    -------
    ConstrainedCertificate
        ``passed`` is the verdict.
    """
    Fv = np.asarray(F, dtype=float).reshape(-1)
    Sm = np.asarray(S, dtype=float)
    Sm = 0.5 * (Sm + Sm.T)
    P = np.linalg.inv(Sm)
    P = 0.5 * (P + P.T)
    tau_max = 2.0 * model.tau_n0 if tau_max is None else tau_max
    A0s, A1s = _shifted(model, sigma, tau_max)
    Abar = A0s + model.B @ Fv[None, :]
    lmi_max = max(float(np.linalg.eigvalsh(lmi32(Abar, A1, P, alpha))[-1]) for A1 in A1s)
    X0 = np.atleast_2d(np.asarray(states, dtype=float))
    state_max = float(max(x @ P @ x for x in X0))
    peak = float(math.sqrt(max(float(Fv @ Sm @ Fv), 0.0)))
    taus_arr = default_delay_sweep(model)
    nominal = float(delay_roots(model, Fv, None, 1)[0].real)
    sweep = np.asarray(spectral_abscissa_sweep(model, Fv, taus_arr), dtype=float)
    return ConstrainedCertificate(
        lmi_max,
        state_max,
        peak,
        float(u_max),
        float(sigma),
        nominal,
        taus_arr,
        sweep,
        None if braking_limit is None else float(braking_limit),
    )


def synthesize_constrained(
    model: AveragedModel,
    states: ArrayLike,
    u_max: float,
    *,
    sigma: float = DEFAULT_DECAY,
    tau_max: float | None = None,
    alphas: Sequence[float] | NDArray[np.float64] = ALPHA_GRID,
    refine: int = REFINE_POINTS,
    margin: float = LMI_MARGIN,
    solvers: Sequence[str] = SOLVERS,
) -> ConstrainedResult:
    """The gain of least peak feedback torque from ``states`` at the decay ``sigma``, within
    ``u_max`` (module docstring), over the alpha grid with a refinement around the best point.

    Parameters
    ----------
    model : AveragedModel
        The averaged model (29)-(31).
    states : array (k, 4)
        The switch-on states (:func:`switch_on_states`).
    u_max : float
        The feedback torque the top drive allows (:func:`torque_budget`), > 0.
    sigma : float
        Required decay rate (>= 0) of the Razumikhin function on the averaged model.
    tau_max : float, optional
        Largest delay the certificate covers (default 2 tau_n0).
    alphas, refine, margin, solvers
        As for :func:`drillstring.controller.synthesis.synthesize`.

    Returns
    -------
    ConstrainedResult
        With its certificate (check ``certificate.passed``).

    Raises
    ------
    ConstrainedInfeasible
        No alpha gives a gain whose peak torque is within ``u_max``; the message gives the
        smallest peak found (and the exception its alpha).
    """
    u_max = check_real("u_max", u_max, lower=0.0)
    sigma = check_real("sigma", sigma, lower=0.0, strict=False)
    tau_max = 2.0 * model.tau_n0 if tau_max is None else check_real("tau_max", tau_max, lower=0.0)
    X0 = np.atleast_2d(np.asarray(states, dtype=float))
    if X0.shape[1] != 4 or not np.all(np.isfinite(X0)):
        raise ValueError(f"states must be finite rows of 4, got shape {X0.shape}")
    grid = np.sort(np.asarray(alphas, dtype=float).reshape(-1))
    attempts: list[tuple[float, str, float | None]] = []
    best: tuple[float, float, str, str, NDArray[np.float64], NDArray[np.float64]] | None = None

    def run(a: float) -> None:
        nonlocal best
        solver, status, S, F, peak = solve_constrained_lmi(
            model, X0, a, sigma=sigma, tau_max=tau_max, margin=margin, solvers=solvers
        )
        attempts.append((a, status, peak))
        if S is not None and F is not None and peak is not None:
            if best is None or peak < best[0]:
                best = (peak, a, solver, status, S, F)

    for a in grid:
        run(float(a))
    if best is not None and refine > 0 and grid.size > 1:
        i = int(np.searchsorted(grid, best[1]))
        lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        for a in np.logspace(math.log10(lo), math.log10(hi), refine + 2)[1:-1]:
            run(float(a))
    if best is None or best[0] > u_max:
        found = "none solved" if best is None else f"the smallest peak is {best[0]:.4g}"
        raise ConstrainedInfeasible(
            f"no gain keeps the feedback torque within u_max = {u_max:.4g} (units of C) from the "
            f"{len(X0)} switch-on states at decay {sigma:g}: {found}",
            least_peak=None if best is None else best[0],
            alpha=None if best is None else best[1],
            u_max=u_max,
        )
    peak, alpha, solver, status, S, F = best
    cert = check_constrained(model, F, S, alpha, X0, u_max, sigma=sigma, tau_max=tau_max)
    return ConstrainedResult(
        model=model,
        alpha=alpha,
        F=F,
        S=S,
        peak_torque=peak,
        u_max=u_max,
        sigma=sigma,
        tau_max=tau_max,
        states=X0,
        solver=solver,
        status=status,
        attempts=tuple(attempts),
        certificate=cert,
    )


def least_braking(
    model: AveragedModel,
    states: ArrayLike,
    alpha: float,
    *,
    operating_torque: float,
    R_max: float,
    braking_limit: float = 0.0,
    sigma: float = DEFAULT_DECAY,
    tol: float = BRAKING_TOL,
) -> tuple[float | None, int]:
    """The least braking limit b (R_min = -b, units of C) at which the program of the module
    docstring is feasible at ``alpha`` with the budget ``u_max(b) = min(operating_torque + b,
    R_max - operating_torque)``: a bisection on b with :func:`solve_constrained_lmi` (its
    constraint (d) on) deciding each step.

    ``braking_limit`` is a limit already refused (the lower end of the bracket); the upper end
    is the limit at which the two margins are equal, ``R_max - 2 operating_torque``: more
    braking does not raise the budget. The bisection stops when the bracket is narrower than
    ``tol``; the answer is its upper end, a limit at which the solve succeeded (so within
    ``tol`` above the least one; ``alpha`` should be the alpha of the least peak the design
    found, where the smallest budget is feasible).

    Returns
    -------
    (least, solves)
        ``least`` None when even the upper end of the bracket is not feasible (the margin above
        the operating torque is itself too small); ``solves`` the number of LMI solves.
    """
    tol = check_real("tol", tol, lower=0.0)
    lo = check_real("braking_limit", braking_limit, lower=0.0, strict=False)
    bias = check_real("operating_torque", operating_torque, lower=0.0)
    X0 = np.atleast_2d(np.asarray(states, dtype=float))
    solves = 0

    def feasible(b: float) -> bool:
        nonlocal solves
        solves += 1
        u = min(bias + b, R_max - bias)
        if not u > 0.0:
            return False
        return solve_constrained_lmi(model, X0, alpha, sigma=sigma, u_max=u)[2] is not None

    if math.isfinite(R_max):
        hi = R_max - 2.0 * bias
        if not (hi > lo and feasible(hi)):
            return None, solves
    else:  # no upper limit: double until feasible (1e6 C is far beyond any drive)
        hi = max(2.0 * lo, 1.0)
        while not feasible(hi):
            if hi > 1e6:
                return None, solves
            lo, hi = hi, 2.0 * hi
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if feasible(mid):
            hi = mid
        else:
            lo = mid
    return hi, solves


def recheck_constrained(gains: GainsFile) -> ConstrainedCertificate:
    """The certificate of an input-constrained design checked again from its gains file alone.

    The averaged model (29)-(31) is rebuilt from the file's parameter set, A and taubar_crit;
    :func:`check_constrained` then runs on the file's F, alpha, ellipsoid S, switch-on states,
    decay and tau_max (the ``constraint`` record, written by
    :func:`drillstring.controller.design.design_constrained`) and the budget: the smallest of
    the recorded u_max and the two margins of the recorded drive about the operating torque R0 +
    R_ff, below from the braking limit (``braking_limit``, -R_min; from ``torque_limit`` in a
    file written before it was recorded) and above from R_max, so a file whose braking limit is
    lowered below what the design needs fails.

    Parameters
    ----------
    gains : GainsFile
        A gains file of an input-constrained design (``drillstring design --torque-limit``).

    Returns
    -------
    ConstrainedCertificate
        ``passed`` is the verdict (False for an S or a gain the design did not give).

    Raises
    ------
    GainsFileError
        No constraint record, or one without the ellipsoid S and the switch-on states (a file
        written before they were recorded: design again).
    """
    record = gains.constraint
    if record is None:
        raise GainsFileError("gains file: no input-constrained design (constraint is null)")
    missing = [k for k in ("S", "switch_on_states") if k not in record]
    if missing:
        raise GainsFileError(
            f"gains file: the constraint record lacks {', '.join(missing)}: the certificate "
            "cannot be checked from the file (design again: drillstring design --torque-limit)"
        )
    model = averaged_model(gains.params, gains.A, gains.taubar_crit)
    bias = gains.params.R0 + gains.R_ff
    u_max = float(record["u_max"])
    limit = record.get("torque_limit")
    braking = record.get("braking_limit")
    if braking is None and limit is not None:
        braking = -float(limit[0])
    if braking is not None:
        u_max = min(u_max, bias + float(braking))
    if limit is not None:
        u_max = min(u_max, float(limit[1]) - bias)
    return check_constrained(
        model,
        gains.F,
        np.asarray(record["S"], dtype=float),
        gains.alpha,
        np.asarray(record["switch_on_states"], dtype=float),
        u_max,
        sigma=float(record["decay"]),
        tau_max=float(record["tau_max"]),
        braking_limit=braking,
    )
