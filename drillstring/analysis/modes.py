"""Free vibration of the drill string: the chain's modes, the continuous string's exact modes
and the convergence of the one to the other.

The model is ``docs/model.md``, "The distributed string"; ``docs/analysis.md``, "Modes of the
string", derives the frequency equations. All frequencies here are scaled angular frequencies
(rad per unit of tau = t/t*); :func:`to_rad_s` and :func:`to_hz` convert them with a rig's
t* = sqrt(I1/C).

Torsion, in the paper's scaling (inertias in units of I1, torques in units of C), on
x in [0, 1] (x = 0 the rotary table, x = 1 the bit)::

    kappa*theta_tt = theta_xx                      along the pipe
    rho*theta_tt(0) = theta_x(0)                   table free   (theta(0) = 0 when held)
    J_b*theta_tt(1) = -theta_x(1)                  bit end, J_b = 1 - kappa/3

With theta = X(x) cos(omega*tau) and the scaled wave number s = omega*sqrt(kappa) (the phase
the wave gathers over the pipe) the modes are the roots of

* held table: ``tan(s) = kappa/(J_b*s)``, equivalently ``s = n*pi + atan(kappa/(J_b*s))``,
  X = sin(s*x);
* free table: ``tan(s) = (r + b)*s/(r*b*s^2 - 1)`` with r = rho/kappa and b = J_b/kappa,
  equivalently ``s = n*pi + atan(kappa/(rho*s)) + atan(kappa/(J_b*s))``,
  X = cos(s*x) - (rho*s/kappa)*sin(s*x), besides the rigid-body rotation omega = 0;

for n = 0, 1, 2, ... Each right-hand side of the phase form decreases with s, so each branch has
exactly one root, bracketed in (n*pi, n*pi + pi/2) (held) or (n*pi, (n + 1)*pi) (free) and found
by :func:`scipy.optimize.brentq`: no root is skipped and none depends on a guess.

Axially the hook is held (its motion is imposed), mu*u_tt = eta^2*u_xx, and the bit mass is
m_b = 1 - mu/3 (units of M): ``tan(s) = mu/(m_b*s)`` with s = omega*sqrt(mu)/eta, the held
equation with kappa -> mu, J_b -> m_b.

The chain of N lumped elements (:func:`drillstring.model.pipe.torsional_chain`,
:func:`~drillstring.model.pipe.axial_chain`) has the modes of K x = omega^2 J x, J the diagonal
of the node inertias and K the tridiagonal stiffness matrix; its frequencies converge to the
exact ones at second order in 1/N (the error falls by about 4 per doubling of N).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigh_tridiagonal
from scipy.optimize import brentq

from drillstring.model.pipe import MAX_ELEMENTS, Chain, StringParams, axial_chain, torsional_chain
from drillstring.validation import check_choice, check_int, check_real

__all__ = [
    "CONVERGENCE_ELEMENTS",
    "TABLES",
    "ChainModes",
    "Convergence",
    "axial_convergence",
    "axial_elements_needed",
    "axial_exact_modes",
    "axial_exact_shape",
    "axial_modes",
    "chain_modes",
    "paper_one_mode",
    "to_hz",
    "to_rad_s",
    "torsional_convergence",
    "torsional_elements_needed",
    "torsional_exact_modes",
    "torsional_exact_shape",
    "torsional_modes",
]

#: The table's boundary condition: ``"held"`` (theta = 0 at x = 0) or ``"free"`` (the table's
#: inertia rho moves with the string, no torque applied).
TABLES = ("held", "free")
#: The numbers of elements of the convergence table: 1, 2, 4, ..., 256.
CONVERGENCE_ELEMENTS = tuple(2**i for i in range(9))


@dataclass(frozen=True)
class ChainModes:
    """The first modes of a chain, lowest first.

    Attributes
    ----------
    omega : numpy.ndarray
        Scaled angular frequencies (rad per unit of tau), ascending, rigid-body mode excluded.
    shapes : numpy.ndarray
        ``shapes[k]`` is mode k over the nodes 0..N (a held node 0 included, as 0), scaled so
        that its largest magnitude is 1 and the bit's (node N) value is >= 0.
    x : numpy.ndarray
        The nodes' positions along the pipe, i/N (0 the table or hook, 1 the bit).
    """

    omega: np.ndarray
    shapes: np.ndarray
    x: np.ndarray


def _normalise(shapes: np.ndarray) -> np.ndarray:
    """Each row scaled to max |.| = 1, its last entry >= 0 (the largest entry > 0 if that is 0)."""
    out = np.array(shapes, dtype=float, copy=True)
    for row in out:
        row /= np.max(np.abs(row))
        ref = row[-1] if abs(row[-1]) > 1e-12 else row[np.argmax(np.abs(row))]
        if ref < 0:
            row *= -1.0
    return out


def chain_modes(chain: Chain, *, held: bool, count: int | None = None) -> ChainModes:
    """Modes of K x = omega^2 J x on a chain (generalized symmetric eigenproblem).

    The problem is solved in its symmetric form J^(-1/2) K J^(-1/2) y = omega^2 y, a
    tridiagonal matrix (:func:`scipy.linalg.eigh_tridiagonal`, only the lowest eigenvalues
    asked for, so the cost is linear in N), and x = J^(-1/2) y. A free top node (``held=False``)
    gives the chain a rigid-body mode omega = 0: it is dropped, and ``omega`` starts with the
    first elastic mode.

    Parameters
    ----------
    chain : Chain
        Node inertias ``inertia[0..N]`` and the element stiffness.
    held : bool
        Node 0 fixed (the table held, or the hook) instead of a degree of freedom.
    count : int, optional
        How many modes (default: all). A chain has N elastic modes; fewer are returned when
        ``count`` exceeds that.

    Returns
    -------
    ChainModes
        Frequencies and mode shapes.
    """
    J = np.asarray(chain.inertia, dtype=float)
    n = J.size - 1
    k = float(chain.stiffness)
    lo = 1 if held else 0  # the first degree of freedom
    dof = J[lo:]
    diag = np.full(dof.size, 2.0 * k)
    diag[-1] = k  # the bit: one element on one side
    if not held:
        diag[0] = k  # the free table: one element below it
    d = diag / dof
    e = -k / np.sqrt(dof[:-1] * dof[1:])
    available = n  # elastic modes: N (held: N dofs; free: N + 1 dofs minus the rigid one)
    want = available if count is None else min(check_int("count", count, lower=1), available)
    skip = 0 if held else 1
    lam, vec = eigh_tridiagonal(d, e, select="i", select_range=(skip, skip + want - 1))
    x = vec / np.sqrt(dof)[:, None]
    shapes = np.zeros((want, n + 1))
    shapes[:, lo:] = x.T
    omega = np.sqrt(np.clip(lam, 0.0, None))
    return ChainModes(omega, _normalise(shapes), np.arange(n + 1) / n)


def torsional_modes(
    string: StringParams, rho: float, table: str = "held", count: int | None = None
) -> ChainModes:
    """Torsional modes of :func:`~drillstring.model.pipe.torsional_chain`.

    Parameters
    ----------
    string : StringParams
        The pipe: N, kappa and the lumping.
    rho : float
        The table's inertia I2/I1.
    table : str
        ``"held"`` (node 0 fixed) or ``"free"`` (node 0 a degree of freedom; the rigid-body
        rotation, omega = 0, is dropped).
    count : int, optional
        How many modes (default: all N).

    Returns
    -------
    ChainModes
        Scaled frequencies and mode shapes. The paper's lumping (N = 1) gives omega = 1 (held)
        or omega^2 = 1 + 1/rho (free): :func:`paper_one_mode`.
    """
    check_choice("table", table, TABLES)
    rho = check_real("rho", rho, lower=0.0)
    return chain_modes(torsional_chain(string, rho), held=table == "held", count=count)


def axial_modes(string: StringParams, eta: float, count: int | None = None) -> ChainModes:
    """Axial modes of :func:`~drillstring.model.pipe.axial_chain`, the hook held.

    Parameters
    ----------
    string : StringParams
        The pipe: N and the axial mass ratio mu (0, or one element: a massless spring, one mode
        omega = eta).
    eta : float
        The scaled axial stiffness parameter of (15).
    count : int, optional
        How many modes (default: all).

    Returns
    -------
    ChainModes
        Scaled frequencies and mode shapes.
    """
    eta = check_real("eta", eta, lower=0.0)
    return chain_modes(axial_chain(string, eta), held=True, count=count)


def paper_one_mode(rho: float, table: str = "held") -> float:
    """The paper's one-mode model's frequency, in closed form: eqs. (11)-(13) without the bit.

    Two inertias (the table rho, the bit end 1) on the spring 1: held, omega = 1 (the bit on
    the spring); free, omega^2 = 1 + 1/rho (the two inertias against each other).

    Parameters
    ----------
    rho : float
        The table's inertia I2/I1.
    table : str
        ``"held"`` or ``"free"``.

    Returns
    -------
    float
        The scaled angular frequency.
    """
    check_choice("table", table, TABLES)
    rho = check_real("rho", rho, lower=0.0)
    return 1.0 if table == "held" else math.sqrt(1.0 + 1.0 / rho)


# ---------------------------------------------------------------------------------------------
# the continuous string
# ---------------------------------------------------------------------------------------------


def _phase_roots(phase: Callable[[float], float], count: int, width: float) -> np.ndarray:
    """The roots s_n of s = n*pi + phase(s), n = 0..count-1; phase decreases, within (0, width).

    g(s) = s - n*pi - phase(s) increases strictly, is < 0 at n*pi and >= 0 at n*pi + width,
    so each branch has one root in that bracket.
    """
    roots = np.empty(count)
    for n in range(count):
        a, b = n * math.pi, n * math.pi + width

        def g(s: float, n: int = n) -> float:
            return s - n * math.pi - phase(s)

        if n == 0:
            a = 1e-300  # the phase at s -> 0+ is its supremum; g(0+) < 0
        roots[n] = brentq(g, a, b, xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)
    return roots


def torsional_exact_modes(
    kappa: float, rho: float, table: str = "held", count: int = 3
) -> np.ndarray:
    """The first elastic modes of the continuous torsional string (scaled angular frequencies).

    Roots of the frequency equation (module docstring; ``docs/analysis.md``, "Modes of the
    string"): held, tan(s) = kappa/(J_b*s); free, tan(s) = (r + b)*s/(r*b*s^2 - 1), r =
    rho/kappa, b = J_b/kappa; s = omega*sqrt(kappa), J_b = 1 - kappa/3. The rigid-body mode of
    the free string is not counted. ``kappa = 0`` is the massless spring of the paper: one mode
    only, :func:`paper_one_mode`.

    Parameters
    ----------
    kappa : float
        Pipe polar inertia over I1, in [0, 3).
    rho : float
        The table's inertia I2/I1 (used by the free table only).
    table : str
        ``"held"`` or ``"free"``.
    count : int
        How many modes.

    Returns
    -------
    numpy.ndarray
        ``count`` frequencies (one for kappa = 0), ascending.
    """
    check_choice("table", table, TABLES)
    kappa = _check_ratio("kappa", kappa)
    rho = check_real("rho", rho, lower=0.0)
    count = check_int("count", count, lower=1)
    if kappa == 0.0:
        return np.array([paper_one_mode(rho, table)])
    jb = 1.0 - kappa / 3.0
    if table == "held":
        s = _phase_roots(lambda s: math.atan(kappa / (jb * s)), count, math.pi / 2)
    else:
        s = _phase_roots(
            lambda s: math.atan(kappa / (rho * s)) + math.atan(kappa / (jb * s)), count, math.pi
        )
    return s / math.sqrt(kappa)


def axial_exact_modes(mu: float, eta: float, count: int = 3) -> np.ndarray:
    """The first modes of the continuous axial string, the hook held.

    Roots of tan(s) = mu/(m_b*s), s = omega*sqrt(mu)/eta, m_b = 1 - mu/3. ``mu = 0`` is the
    massless spring of the paper: one mode, omega = eta.

    Parameters
    ----------
    mu : float
        Pipe mass over M (the axial mass ratio), in [0, 3).
    eta : float
        The scaled axial stiffness parameter of (15).
    count : int
        How many modes.

    Returns
    -------
    numpy.ndarray
        ``count`` scaled frequencies (one for mu = 0), ascending.
    """
    mu = _check_ratio("mu", mu)
    eta = check_real("eta", eta, lower=0.0)
    count = check_int("count", count, lower=1)
    if mu == 0.0:
        return np.array([eta])
    mb = 1.0 - mu / 3.0
    s = _phase_roots(lambda s: math.atan(mu / (mb * s)), count, math.pi / 2)
    return s * eta / math.sqrt(mu)


def torsional_exact_shape(
    kappa: float, rho: float, table: str, omega: float, x: np.ndarray
) -> np.ndarray:
    """The continuous string's torsional mode shape at the frequency ``omega``, over ``x``.

    Held, sin(s*x); free, cos(s*x) - (rho*s/kappa)*sin(s*x) (s = omega*sqrt(kappa)); for
    kappa = 0 (a massless spring) the straight line between the two inertias' amplitudes.
    Scaled like :class:`ChainModes` (max |.| = 1 over ``x``, the value at the bit >= 0).

    Parameters
    ----------
    kappa, rho : float
        The string's pipe inertia and the table's inertia (units of I1).
    table : str
        ``"held"`` or ``"free"``.
    omega : float
        A root of the frequency equation (:func:`torsional_exact_modes`).
    x : numpy.ndarray
        Positions along the pipe in [0, 1], the last one the bit (x = 1).

    Returns
    -------
    numpy.ndarray
        The shape over ``x``.
    """
    check_choice("table", table, TABLES)
    x = np.asarray(x, dtype=float)
    if kappa == 0.0:
        # held: the table at rest; free: rho*theta_0 = -theta_1 (no net momentum)
        top = 0.0 if table == "held" else -1.0 / rho
        shape = top + (1.0 - top) * x
    else:
        s = omega * math.sqrt(kappa)
        shape = np.sin(s * x)
        if table == "free":
            shape = np.cos(s * x) - (rho * s / kappa) * shape
    return _normalise(shape[None, :])[0]


def axial_exact_shape(mu: float, eta: float, omega: float, x: np.ndarray) -> np.ndarray:
    """The continuous string's axial mode shape sin(s*x), s = omega*sqrt(mu)/eta, over ``x``.

    Parameters
    ----------
    mu, eta : float
        The axial mass ratio and stiffness parameter (mu = 0: the straight line x).
    omega : float
        A root of the frequency equation (:func:`axial_exact_modes`).
    x : numpy.ndarray
        Positions along the pipe in [0, 1], the last one the bit.

    Returns
    -------
    numpy.ndarray
        The shape, scaled like :class:`ChainModes`.
    """
    x = np.asarray(x, dtype=float)
    shape = x.copy() if mu == 0.0 else np.sin(omega * math.sqrt(mu) / eta * x)
    return _normalise(shape[None, :])[0]


def _check_ratio(name: str, value: float) -> float:
    x = check_real(name, value, lower=0.0, strict=False)
    if not x < 3.0:
        raise ValueError(f"{name} must be < 3 (the bit end keeps 1 - {name}/3), got {value!r}")
    return x


# ---------------------------------------------------------------------------------------------
# convergence in N
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Convergence:
    """The chain's first modes against N beside the continuous string's.

    Attributes
    ----------
    elements : numpy.ndarray
        The numbers of elements N, one row each.
    omega : numpy.ndarray
        ``omega[i, k]``: mode k + 1 of the chain of ``elements[i]`` elements (scaled); NaN where
        the chain has fewer than k + 1 modes.
    exact : numpy.ndarray
        The continuous string's first modes (scaled).
    rel_error : numpy.ndarray
        ``omega/exact - 1``, the same shape as ``omega``.
    ratio : numpy.ndarray
        ``|rel_error[i]|/|rel_error[i + 1]|``, the error's fall from one row to the next (about
        4 per doubling of N at second order); NaN where undefined. One row fewer than ``omega``.
    """

    elements: np.ndarray
    omega: np.ndarray
    exact: np.ndarray
    rel_error: np.ndarray
    ratio: np.ndarray


def _convergence(
    modes_of: Callable[[int], np.ndarray], exact: np.ndarray, elements: Sequence[int]
) -> Convergence:
    ns = np.array([check_int("elements", n, lower=1) for n in elements], dtype=int)
    count = exact.size
    omega = np.full((ns.size, count), np.nan)
    for i, n in enumerate(ns):
        w = modes_of(int(n))[:count]
        omega[i, : w.size] = w
    err = omega / exact - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.abs(err[:-1]) / np.abs(err[1:])
    ratio[~np.isfinite(ratio)] = np.nan
    return Convergence(ns, omega, exact, err, ratio)


def torsional_convergence(
    kappa: float,
    rho: float,
    table: str = "held",
    count: int = 3,
    elements: Sequence[int] = CONVERGENCE_ELEMENTS,
    lumping: str | None = "lumped",
) -> Convergence:
    """The torsional chain's first ``count`` modes against N, beside the exact ones.

    Parameters
    ----------
    kappa, rho : float
        Pipe and table inertias (units of I1); kappa > 0.
    table : str
        ``"held"`` or ``"free"``.
    count : int
        How many modes.
    elements : sequence of int
        The values of N (default :data:`CONVERGENCE_ELEMENTS`).
    lumping : str or None
        ``"lumped"`` (default: the discretisation's own convergence, N = 1 included) or
        ``None`` (the engine's default: the paper's lumping at N = 1).

    Returns
    -------
    Convergence
        The table.
    """
    exact = torsional_exact_modes(kappa, rho, table, count)

    def modes_of(n: int) -> np.ndarray:
        string = StringParams(elements=n, kappa=kappa, lumping=lumping)
        return torsional_modes(string, rho, table, count).omega

    return _convergence(modes_of, exact, elements)


def axial_convergence(
    mu: float, eta: float, count: int = 3, elements: Sequence[int] = CONVERGENCE_ELEMENTS
) -> Convergence:
    """The axial chain's first ``count`` modes against N, beside the exact ones.

    At N = 1 the axial chain is the paper's massless spring (omega = eta) whatever mu.

    Parameters
    ----------
    mu : float
        The axial mass ratio, > 0.
    eta : float
        The scaled axial stiffness parameter.
    count : int
        How many modes.
    elements : sequence of int
        The values of N (default :data:`CONVERGENCE_ELEMENTS`).

    Returns
    -------
    Convergence
        The table.
    """
    exact = axial_exact_modes(mu, eta, count)

    def modes_of(n: int) -> np.ndarray:
        string = StringParams(elements=n, axial_mass_ratio=mu, lumping="lumped")
        return axial_modes(string, eta, count).omega

    return _convergence(modes_of, exact, elements)


def _elements_needed(
    modes_of: Callable[[int], np.ndarray], exact: float, mode: int, rel_tol: float
) -> int:
    rel_tol = check_real("rel_tol", rel_tol, lower=0.0)
    for n in range(1, MAX_ELEMENTS + 1):
        w = modes_of(n)
        if w.size >= mode and abs(w[mode - 1] / exact - 1.0) <= rel_tol:
            return n
    raise ValueError(
        f"mode {mode} is not within rel_tol = {rel_tol!r} of the continuous string's at "
        f"N <= {MAX_ELEMENTS}"
    )


def torsional_elements_needed(
    kappa: float,
    rho: float,
    table: str = "held",
    mode: int = 2,
    rel_tol: float = 0.01,
    lumping: str | None = None,
) -> int:
    """The smallest N whose torsional chain has mode ``mode`` within ``rel_tol`` of the exact.

    N runs 1, 2, 3, ... and the first N within the tolerance is returned (on the strings tried
    the lumped chain's error falls steadily with N, so later N stay within it).

    Parameters
    ----------
    kappa, rho : float
        Pipe and table inertias (units of I1); kappa > 0.
    table : str
        ``"held"`` or ``"free"``.
    mode : int
        Which mode, from 1.
    rel_tol : float
        The relative tolerance on the frequency.
    lumping : str or None
        ``None`` (default: what the engine runs, the paper's lumping at N = 1) or ``"lumped"``.

    Returns
    -------
    int
        N.

    Raises
    ------
    ValueError
        Not reached by N = :data:`~drillstring.model.pipe.MAX_ELEMENTS`.
    """
    mode = check_int("mode", mode, lower=1)
    exact = torsional_exact_modes(kappa, rho, table, mode)[-1]

    def modes_of(n: int) -> np.ndarray:
        string = StringParams(elements=n, kappa=kappa, lumping=lumping if n == 1 else "lumped")
        return torsional_modes(string, rho, table, mode).omega

    return _elements_needed(modes_of, exact, mode, rel_tol)


def axial_elements_needed(mu: float, eta: float, mode: int = 2, rel_tol: float = 0.01) -> int:
    """The smallest N whose axial chain (mass ratio ``mu`` > 0, stiffness parameter ``eta``) has
    mode ``mode`` within ``rel_tol`` of the exact; the rest as :func:`torsional_elements_needed`.
    """
    mode = check_int("mode", mode, lower=1)
    exact = axial_exact_modes(mu, eta, mode)[-1]

    def modes_of(n: int) -> np.ndarray:
        string = StringParams(elements=n, axial_mass_ratio=mu, lumping="lumped")
        return axial_modes(string, eta, mode).omega

    return _elements_needed(modes_of, exact, mode, rel_tol)


# ---------------------------------------------------------------------------------------------
# units
# ---------------------------------------------------------------------------------------------


def to_rad_s(omega: np.ndarray | float, t_star: float) -> np.ndarray:
    """Scaled angular frequency (per unit of tau = t/t*) to rad/s: omega/t*.

    Parameters
    ----------
    omega : array_like
        Scaled angular frequencies.
    t_star : float
        The rig's t* = sqrt(I1/C) in seconds (``PhysicalParams.t_star``).

    Returns
    -------
    numpy.ndarray
        rad/s.
    """
    t_star = check_real("t_star", t_star, lower=0.0)
    return np.asarray(omega, dtype=float) / t_star


def to_hz(omega: np.ndarray | float, t_star: float) -> np.ndarray:
    """Scaled angular frequency to Hz: omega/(2*pi*t*) (arguments as :func:`to_rad_s`)."""
    return to_rad_s(omega, t_star) / (2.0 * math.pi)
