"""Averaged torsional model of Section IV-V of the paper.

The fast axial stick-slip is replaced by its average (22)-(24); the torsional dynamics (12)-(13)
then become (25) with the state-dependent delay (14). Two linear models follow from it:

* the delay form (28)-(30): ``x' = A0 x(tau) + A1 x(tau - tau_n) + B R_fb`` with
  ``x = [phi, dphi/dtau, phi - theta - K0, dtheta/dtau]`` and ``R - R0 = R_ff + R_fb``,
  ``R_ff = -K0`` (31); the matrices are derived in ``docs/model.md``, "Equation (30)";
* the ODE (13), (27), obtained with the Taylor approximation (26) of the delay, in the same state.

Everything here is a pure function of a :class:`~drillstring.model.params.ScaledParams` and
the two axial quantities ``A`` (slope of (22)) and ``taubar_crit`` (critical delay of (21), fast
time scale), which come from the axial analysis.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from drillstring.analysis.spectrum import dde_roots
from drillstring.model.params import ScaledParams
from drillstring.validation import check_real

__all__ = [
    "AveragedModel",
    "averaged_model",
    "default_delay_sweep",
    "balanced",
    "delay_roots",
    "linearised_ode_matrix",
    "ode_poles",
    "spectral_abscissa_sweep",
]

#: Number of rightmost characteristic roots returned by default.
N_ROOTS_DEFAULT = 8


@dataclass(frozen=True, eq=False)
class AveragedModel:
    """Matrices and constants of the averaged torsional model (29)-(31).

    Attributes
    ----------
    A0, A1 : ndarray
        4x4 matrices of (30) (``docs/model.md``, "Equation (30)").
    B : ndarray
        Input matrix of (30), shape (4, 1).
    c : float
        ``n*v0/omega0*(beta*A - 1)`` of (28)-(30); negative means velocity weakening.
    K0 : float
        ``n*v0*beta*A*(tau_n0 - tau_n_crit)``, the constant of (27)-(28).
    R_ff : float
        Feed-forward torque ``-K0`` of (31).
    tau_n0 : float
        Nominal delay ``2*pi/(n*omega0)``.
    tau_n_crit : float
        ``taubar_crit/sqrt(n*psi)``, critical delay in the slow time scale.
    A, taubar_crit : float
        The axial quantities the model was built from.
    rho : float
        Inertia ratio (16).
    """

    A0: NDArray[np.float64]
    A1: NDArray[np.float64]
    B: NDArray[np.float64]
    c: float
    K0: float
    R_ff: float
    tau_n0: float
    tau_n_crit: float
    A: float
    taubar_crit: float
    rho: float

    def with_rho(self, factor: float) -> AveragedModel:
        """The model with the table's inertia ratio rho times ``factor`` (B of (30) scales as
        1/rho): what a controller or observer that misjudges the drive's inertia assumes."""
        rho = self.rho * factor
        return replace(self, rho=rho, B=self.B * (self.rho / rho))


def averaged_model(params: ScaledParams, A: float, taubar_crit: float) -> AveragedModel:
    """Build the averaged torsional model (29)-(31) for ``params`` and the axial pair.

    Parameters
    ----------
    params : ScaledParams
        Scaled parameter set.
    A : float
        Slope ``A(gammabar, etabar)`` of the averaged contact force (22); must be > 0.
    taubar_crit : float
        Critical delay of (21) in the fast time ``taubar``; must satisfy
        ``0 < taubar_crit < taubar_n0``, the validity condition of (25) (Section IV).

    Returns
    -------
    AveragedModel
        The matrices (30) and the constants c, K0, R_ff of (28), (31).

    Raises
    ------
    ValueError
        For non-finite or out-of-range ``A`` or ``taubar_crit``.
    """
    A = check_real("A", A)
    taubar_crit = check_real("taubar_crit", taubar_crit)
    if A <= 0.0:
        raise ValueError(f"A (slope of (22)) must be > 0, got {A!r}")
    if taubar_crit <= 0.0:
        raise ValueError(f"taubar_crit must be > 0, got {taubar_crit!r}")
    if taubar_crit >= params.taubar_n0:
        raise ValueError(
            f"taubar_crit = {taubar_crit!r} must be below taubar_n0 = {params.taubar_n0!r}: "
            "the averaged model (25) only holds when the axial motion is a stick-slip limit cycle"
        )
    n, v0, omega0, beta, rho = params.n, params.v0, params.omega0, params.beta, params.rho
    tau_n0 = params.tau_n0
    tau_n_crit = taubar_crit / params.sqrt_npsi
    c = n * v0 / omega0 * (beta * A - 1.0)
    K0 = n * v0 * beta * A * (tau_n0 - tau_n_crit)
    A0 = np.array(
        [
            [0.0, 1.0, 0.0, 0.0],
            [-c, 0.0, -1.0, 0.0],
            [0.0, 1.0, 0.0, -1.0],
            [0.0, 0.0, 1.0 / rho, 0.0],
        ]
    )
    A1 = np.zeros((4, 4))
    A1[1, 0] = c
    B = np.array([[0.0], [0.0], [0.0], [1.0 / rho]])
    return AveragedModel(
        A0=A0,
        A1=A1,
        B=B,
        c=c,
        K0=K0,
        R_ff=-K0,
        tau_n0=tau_n0,
        tau_n_crit=tau_n_crit,
        A=A,
        taubar_crit=taubar_crit,
        rho=rho,
    )


def linearised_ode_matrix(model: AveragedModel) -> NDArray[np.float64]:
    """System matrix of the ODE (13), (27) with ``R - R0 = R_ff`` (no feedback), same state x.

    (27): ``phi'' + (phi - theta) = K0 - c*tau_n0*phi'``, since
    ``n*v0*(beta*A - 1)*2*pi/(n*omega0**2) = c*tau_n0``. The angle ``phi`` only enters
    through the twist, so the matrix has the rigid-body eigenvalue 0.

    Parameters
    ----------
    model : AveragedModel
        The averaged model (its c, tau_n0 and rho are used).

    Returns
    -------
    ndarray
        The 4x4 system matrix.
    """
    c, t0, rho = model.c, model.tau_n0, model.rho
    return np.array(
        [
            [0.0, 1.0, 0.0, 0.0],
            [0.0, -c * t0, -1.0, 0.0],
            [0.0, 1.0, 0.0, -1.0],
            [0.0, 0.0, 1.0 / rho, 0.0],
        ]
    )


def ode_poles(model: AveragedModel) -> NDArray[np.complex128]:
    """Poles of the linear ODE (13), (27), sorted by real part, descending.

    Parameters
    ----------
    model : AveragedModel
        The averaged model.

    Returns
    -------
    ndarray of complex
        The four eigenvalues of :func:`linearised_ode_matrix`.
    """
    ev = np.linalg.eigvals(linearised_ode_matrix(model))
    return ev[np.lexsort((-ev.imag, -ev.real))]


def _closed_loop_A0(model: AveragedModel, F: ArrayLike | None) -> NDArray[np.float64]:
    if F is None:
        return model.A0
    Fv = np.asarray(F, dtype=float).reshape(-1)
    if Fv.shape != (4,) or not np.all(np.isfinite(Fv)):
        raise ValueError(f"F must be 4 finite numbers, got {F!r}")
    return model.A0 + model.B @ Fv[None, :]


def balanced(
    A0: NDArray[np.float64], A1: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Diagonal similarity ``D^-1 (.) D`` (powers of two, exact) balancing ``|A0| + |A1|``.

    The characteristic roots are unchanged; large gains make ``||A0 + B F||`` (hence the
    collocation degree of the root finder, which grows with the norm) needlessly large.
    """
    _, (scale, _) = scipy.linalg.matrix_balance(
        np.abs(A0) + np.abs(A1), permute=False, separate=True
    )
    return A0 / scale[:, None] * scale[None, :], A1 / scale[:, None] * scale[None, :]


def delay_roots(
    model: AveragedModel,
    F: ArrayLike | None = None,
    tau: float | None = None,
    n_roots: int = N_ROOTS_DEFAULT,
) -> NDArray[np.complex128]:
    """Rightmost characteristic roots of ``x' = (A0 + B F) x + A1 x(t - tau)``.

    ``F = None`` is the open loop (R_fb = 0), ``tau = None`` the nominal delay ``tau_n0``.
    Roots come from :func:`drillstring.analysis.spectrum.dde_roots` (automatic region: every
    root within ``min(1, 2/tau)`` of the rightmost one), applied to a balanced similar system,
    sorted by real part, descending.

    Parameters
    ----------
    model : AveragedModel
        The averaged model.
    F : array_like, optional
        Gain of R_fb = F x, 4 entries; ``None`` is the open loop (R_fb = 0).
    tau : float, optional
        Constant delay > 0; ``None`` is the nominal delay ``tau_n0``.
    n_roots : int
        Return at most this many roots.

    Returns
    -------
    ndarray of complex
        The rightmost roots.

    Raises
    ------
    ValueError
        A non-finite or non-positive ``tau``, or an ``F`` that is not 4 finite numbers.
    """
    tau = model.tau_n0 if tau is None else check_real("tau", tau)
    if tau <= 0.0:
        raise ValueError(f"delay tau must be > 0, got {tau!r}")
    Ab, A1b = balanced(_closed_loop_A0(model, F), model.A1)
    roots = np.asarray(dde_roots(Ab, delayed=[(tau, A1b)]))
    return roots[:n_roots]


def spectral_abscissa_sweep(
    model: AveragedModel, F: ArrayLike | None, taus: Sequence[float] | NDArray[np.float64]
) -> NDArray[np.float64]:
    """Spectral abscissa (largest real part of the roots, :func:`delay_roots`) of the gain ``F``
    (``None``: the open loop) at each constant delay of ``taus`` (each > 0), one per delay.
    """
    return np.array([float(delay_roots(model, F, t, 1)[0].real) for t in taus])


def default_delay_sweep(model: AveragedModel, n: int = 25) -> NDArray[np.float64]:
    """``n`` equally spaced constant delays in ``(0, 5*tau_n0]`` of ``model`` (first point
    ``5*tau_n0/n``), increasing.
    """
    return np.linspace(5.0 * model.tau_n0 / n, 5.0 * model.tau_n0, n)
