"""The closed loops of the top-drive laws on the distributed string, linearised: their spectra.

The one-mode analysis of the laws has two forms today, both on the state
``x = [phi, dphi/dtau, phi - theta - K0, dtheta/dtau]`` of (29):

* the delay form (28)-(30), ``x' = A0 x(tau) + A1 x(tau - tau_n0) + B R_fb``, with which the LMI
  designs are certified (:func:`~drillstring.controller.averaged.delay_roots`,
  ``R_fb = F x``);
* the ODE (13), (27), the delay replaced by its Taylor approximation (26), closed by any law in
  continuous time (:func:`~drillstring.controller.tuning.linear_closed_loop`: the speed PI's
  integrator, Z-Torque's integrator and two filters, the affine law's ``F x``; no drive lag, no
  sampling), which the controllers map overlays (``drillstring.apps.sweep.studies.
  linear_abscissa``).

Here the pipe is the chain of :func:`~drillstring.model.pipe.torsional_chain` (``docs/model.md``,
"The distributed string"): N + 1 nodes, node 0 the rotary table (inertia J_0), node N the bit end
(J_N), element stiffness k. Linearised about steady drilling (the constants K0 and R_ff = -K0 of
(31) cancel as in (29)), with the state

    x = [phi_0, ..., phi_N, w_0, ..., w_N, law states],   w_i = dphi_i/dtau,

the string obeys

    J_0 w_0' = k (phi_1 - phi_0) + R_fb                                 the table, (13')
    J_i w_i' = k (phi_{i-1} - 2 phi_i + phi_{i+1})                      0 < i < N
    J_N w_N' = k (phi_{N-1} - phi_N) - c (phi_N(tau) - phi_N(tau - tau_n0))   the bit, (28)

with c = n v0/omega0 (beta A - 1) of (28)-(30) (the averaged bit law (27) with its delay, acting
on the bit's angle only), or, in the Taylor form, ``- c tau_n0 w_N`` in place of the delayed
difference (27). The law's torque R_fb acts on the table node; the laws measure what they
measure today: the table speed w_0; the string torque at the top (Z-Torque; see ``torque``
below); the bit angle and speed phi_N, w_N and the twist phi_N - phi_0 between bit and table
(the LMI state feedback ``R_fb = F [phi_N, w_N, phi_N - phi_0, w_0]``, plus ``g`` times the
measured string torque when the law has a ``torque_gain`` g, measured as ``torque`` says).
With the paper's lumping (N = 1: J = (rho, 1), k = 1) these are (29)-(30) and (13), (27) to
the letter, a permutation of the one-mode state; ``tests/test_string_spectrum.py`` checks the
roots against the one-mode functions.

When the law feeds back no absolute angle (the open loop, the speed PI, Z-Torque) the whole
string may turn by a constant angle: ``s = 0`` is a root (the rigid-body rotation, exactly as x1
in (30), ``docs/model.md``, "Equation (30)"). It is left out of the roots and of the abscissa,
as the one-mode map does (``linear_abscissa``): every root within 1e-7 ||A|| of the origin is
(a double root when nothing fixes the speed either, as on the undamped string with no bit law;
also a law state decoupled at s = 0, such as a PI integrator with ki = 0).

The delay acts on one component, so the roots come from the project's root finder
:func:`~drillstring.analysis.spectrum.dde_roots` with the past of that component alone
discretised (``reduced=True``): the matrix is 2(N + 1) + (law states) + Chebyshev degree, and
N = 32 costs a fraction of a second.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from drillstring.analysis.spectrum import dde_roots
from drillstring.controller.averaged import N_ROOTS_DEFAULT, AveragedModel, balanced
from drillstring.model.laws import Law, SampledAffine, SpeedPI, ZTorque
from drillstring.model.pipe import StringParams, torsional_chain
from drillstring.validation import check_choice, check_int, check_real

__all__ = [
    "BIT_FORMS",
    "TORQUE_SIGNALS",
    "law_states",
    "string_abscissa",
    "string_closed_loop",
    "string_roots",
]

#: How the bit's averaged law enters: ``"delay"`` (28)-(30), ``"taylor"`` (27) (an ODE).
BIT_FORMS = ("delay", "taylor")
#: What a law that measures the string torque at the top (Z-Torque) gets on the chain:
#: ``"motor"``: the motor torque less rho times the table's acceleration, what the rig lineup's
#: industrial controllers use (``Sensing(torque="motor")``; on the chain the table node's inertia
#: is rho + kappa/(2N), so this is the top element's torque plus kappa/(2N) times the table's
#: acceleration); ``"top"``: the top element's torque k (phi_0 - phi_1), a torque sub under the
#: drive; ``"twist"``: the twist phi_0 - phi_N between table and bit (in units of C, the string's
#: series stiffness being 1), what ``Sensing(torque="twist")`` computes from the table and bit
#: signals. All three are theta - phi at N = 1 with the paper's lumping.
TORQUE_SIGNALS = ("motor", "top", "twist")
#: |s| below which a root counts as the rigid-body root s = 0 (relative to max(1, ||A0||_1 +
#: ||A1||_1)); a double root splits by ~sqrt(eps ||A||) ~ 1e-8 sqrt(||A||).
_RIGID_TOL = 1e-7


def law_states(law: Law | None) -> tuple[str, ...]:
    """Names of the law's own states in the closed loop (after the string's angles and speeds).

    Parameters
    ----------
    law : Law or None
        :class:`~drillstring.model.laws.SpeedPI` (its integrator ``I``),
        :class:`~drillstring.model.laws.ZTorque` (``I``, the high-pass state ``z`` and the
        low-pass output ``y``), :class:`~drillstring.model.laws.SampledAffine` or None (none).

    Returns
    -------
    tuple of str
    """
    if isinstance(law, ZTorque):
        return ("I", "z", "y")
    if isinstance(law, SpeedPI):
        return ("I",)
    return ()


def _check(
    model: AveragedModel, law: Law | None, string: StringParams, torque: str, bit: str
) -> None:
    """The inputs of every function here, checked once (TypeError / ValueError naming them)."""
    if not isinstance(model, AveragedModel):
        raise TypeError(f"model must be an AveragedModel, got {type(model).__name__}")
    if not isinstance(string, StringParams):
        raise TypeError(f"string must be a StringParams, got {type(string).__name__}")
    if law is not None and not isinstance(law, SpeedPI | ZTorque | SampledAffine):
        raise TypeError(
            f"no linear closed loop for a law of type {type(law).__name__} "
            "(SpeedPI, ZTorque, SampledAffine or None)"
        )
    check_choice("torque", torque, TORQUE_SIGNALS)
    check_choice("bit", bit, BIT_FORMS)
    for name in ("c", "tau_n0", "rho"):
        check_real(f"model.{name}", getattr(model, name), lower=None)


def string_closed_loop(
    model: AveragedModel,
    law: Law | None,
    string: StringParams,
    *,
    torque: str = "motor",
    bit: str = "delay",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The linearised closed loop of ``law`` on the chain: ``x' = A0 x + A1 x(tau - tau_n0)``.

    Parameters
    ----------
    model : AveragedModel
        The averaged model (29)-(31) of the operating point
        (:func:`~drillstring.controller.averaged.averaged_model` of the parameter set, the slope
        A of (22) and taubar_crit): its c, tau_n0 and rho are used.
    law : Law or None
        :class:`~drillstring.model.laws.SpeedPI`, :class:`~drillstring.model.laws.ZTorque`,
        :class:`~drillstring.model.laws.SampledAffine` (``F`` of (29)-(31)), or None for the
        open loop (R - R0 = R_ff). Its R_ff and t_on play no part.
    string : StringParams
        The pipe; with the paper's lumping (N = 1) the loop is (29)-(30) (or (13), (27)).
    torque : str
        The string torque a torque-measuring law gets (:data:`TORQUE_SIGNALS`).
    bit : str
        ``"delay"``: the bit law (28) with its delay tau_n0; ``"taylor"``: (27), A1 = 0.

    Returns
    -------
    (ndarray, ndarray)
        A0 and A1, square, of size 2(N + 1) + len(:func:`law_states`); the state is the
        module's x (angles, then speeds, table first, then the law's states). A1 has one
        nonzero entry, c in the bit speed's row and the bit angle's column (zero in the
        Taylor form).

    Raises
    ------
    TypeError
        A model, string or law of another type.
    ValueError
        An unknown ``torque`` or ``bit``.
    """
    _check(model, law, string, torque, bit)
    chain = torsional_chain(string, model.rho)
    J = np.asarray(chain.inertia, dtype=float)
    k = float(chain.stiffness)
    n = J.size - 1
    names = law_states(law)
    m = 2 * (n + 1) + len(names)
    ang = np.arange(n + 1)  # phi_i
    spd = n + 1 + ang  # w_i
    ext = {name: 2 * (n + 1) + i for i, name in enumerate(names)}
    A0 = np.zeros((m, m))
    A1 = np.zeros((m, m))
    A0[ang, spd] = 1.0
    # the springs: each element pulls its two nodes together
    for i in range(n):
        for a, b in ((i, i + 1), (i + 1, i)):
            A0[spd[a], ang[a]] -= k / J[a]
            A0[spd[a], ang[b]] += k / J[a]
    # the bit: (28) with its delay, or (27)
    c = float(model.c)
    if bit == "delay":
        A0[spd[n], ang[n]] -= c / J[n]
        A1[spd[n], ang[n]] += c / J[n]
    else:
        A0[spd[n], spd[n]] -= c * model.tau_n0 / J[n]

    def unit(j: int) -> NDArray[np.float64]:
        e = np.zeros(m)
        e[j] = 1.0
        return e

    # the law's torque R_fb = u @ x, and its own states
    u = np.zeros(m)
    if isinstance(law, SampledAffine):
        F = np.asarray(law.feedback.F, dtype=float).reshape(4)
        u = (
            F[0] * unit(ang[n])
            + F[1] * unit(spd[n])
            + F[2] * (unit(ang[n]) - unit(ang[0]))
            + F[3] * unit(spd[0])
        )
        g = float(law.torque_gain)
        if g != 0.0:  # g times the measured string torque at the top (as Z-Torque's, below)
            top = k * (unit(ang[0]) - unit(ang[1]))
            if torque == "top":
                u = u + g * top
            elif torque == "twist":
                u = u + g * (unit(ang[0]) - unit(ang[n]))
            else:  # meas = u - rho (u - top)/J_0 with u = u_F + g meas: solved for meas
                share = 1.0 - model.rho / J[0]
                u = u + g * (share * u + (model.rho / J[0]) * top) / (1.0 - g * share)
    elif isinstance(law, ZTorque):
        I, Z, Y = ext["I"], ext["z"], ext["y"]  # noqa: E741
        e = -unit(spd[0]) - law.z_gain * unit(Y)
        u = law.kp * e + law.ki * unit(I)
        top = k * (unit(ang[0]) - unit(ang[1]))
        if torque == "top":
            meas = top
        elif torque == "twist":
            meas = unit(ang[0]) - unit(ang[n])
        else:  # motor torque less rho times the table's acceleration (J_0 w_0' = u - top)
            meas = u - model.rho * (u - top) / J[0]
        A0[I] = e
        A0[Z] = law.omega_hp * (meas - unit(Z))
        A0[Y] = law.omega_lp * (meas - unit(Z) - unit(Y))
    elif isinstance(law, SpeedPI):
        I = ext["I"]  # noqa: E741
        u = -law.kp * unit(spd[0]) + law.ki * unit(I)
        A0[I] = -unit(spd[0])
    A0[spd[0]] += u / J[0]
    return A0, A1


def _has_rigid_mode(A0: NDArray[np.float64], A1: NDArray[np.float64], n: int) -> bool:
    """Whether turning the whole string by a constant angle is an equilibrium of the loop."""
    v = np.zeros(A0.shape[0])
    v[: n + 1] = 1.0
    return not np.any((A0 + A1) @ v)


def _drop_rigid(roots: NDArray[np.complex128], scale: float) -> NDArray[np.complex128]:
    """The roots less those at the origin (|s| <= _RIGID_TOL max(1, scale)): the rigid-body
    rotation, a double root when nothing fixes the speed either (no bit law, no speed
    feedback), which the eigenvalue routines split by ~sqrt(eps)."""
    near = np.abs(roots) <= _RIGID_TOL * max(1.0, scale)
    if not np.any(near):
        nearest = roots[int(np.argmin(np.abs(roots)))] if roots.size else None
        raise RuntimeError(
            f"the loop has the rigid-body rotation but no root s = 0 was found (nearest: {nearest})"
        )
    return roots[~near]


def string_roots(
    model: AveragedModel,
    law: Law | None,
    string: StringParams,
    *,
    torque: str = "motor",
    bit: str = "delay",
    tau: float | None = None,
    n_roots: int = N_ROOTS_DEFAULT,
    re_min: float | None = None,
) -> NDArray[np.complex128]:
    """Rightmost characteristic roots of ``law``'s linearised closed loop on the string.

    The loop is :func:`string_closed_loop`; in the delay form its roots are those of
    ``det(s I - A0 - A1 exp(-s tau)) = 0`` from :func:`~drillstring.analysis.spectrum.
    dde_roots` (automatic region: every root within ``min(1, 2/tau)`` of the rightmost one;
    the past of the bit angle alone discretised), applied to a diagonally balanced similar
    system as :func:`~drillstring.controller.averaged.delay_roots` does; in the Taylor form
    the eigenvalues of A0. The rigid-body root s = 0 is left out when the law does not fix
    the absolute angle (module docstring).

    Parameters
    ----------
    model, law, string, torque, bit
        As :func:`string_closed_loop`.
    tau : float, optional
        Constant delay > 0 (default: the nominal tau_n0 of (14)); unused in the Taylor form.
    n_roots : int
        Return at most this many roots.
    re_min : float, optional
        Every root with Re s >= re_min (then :func:`~drillstring.analysis.spectrum.dde_roots`
        raises ValueError if that needs a Chebyshev degree above its maximum); default: the
        automatic region, which holds every root within min(1, 2/tau) of the rightmost one.

    Returns
    -------
    ndarray of complex
        The rightmost roots, by real part descending (then imaginary part descending), in
        scaled units (per unit of tau = t/t*).

    Raises
    ------
    TypeError, ValueError
        Bad inputs, named (as :func:`string_closed_loop`; a delay that is not > 0, an
        ``n_roots`` that is not a positive integer).
    """
    A0, A1 = string_closed_loop(model, law, string, torque=torque, bit=bit)
    n_roots = check_int("n_roots", n_roots, lower=1)
    n = string.elements
    rigid = _has_rigid_mode(A0, A1, n)
    scale = float(np.linalg.norm(A0, 1) + np.linalg.norm(A1, 1))
    tol = _RIGID_TOL * max(1.0, scale)
    # the region asked for, widened past the origin's cluster when it reaches the origin
    lo = None if re_min is None else check_real("re_min", re_min)
    near_origin = rigid and (lo is None or lo <= tol)
    query = None if lo is None else (min(lo, -2.0 * tol) if near_origin else lo)
    if bit == "taylor":
        roots = np.linalg.eigvals(A0).astype(complex)
        roots = roots[np.lexsort((-roots.imag, -roots.real))]
        if query is not None:
            roots = roots[roots.real >= query]
    else:
        tau = model.tau_n0 if tau is None else check_real("tau", tau, lower=0.0)
        A0b, A1b = balanced(A0, A1)
        roots = np.asarray(dde_roots(A0b, [(tau, A1b)], re_min=query, reduced=True), dtype=complex)
    if near_origin:
        roots = _drop_rigid(roots, scale)
    if lo is not None:
        roots = roots[roots.real >= lo]
    return roots[:n_roots]


def string_abscissa(
    model: AveragedModel,
    law: Law | None,
    string: StringParams,
    *,
    torque: str = "motor",
    bit: str = "delay",
) -> float:
    """Spectral abscissa (largest real part of the roots) of ``law`` on the string, at the
    nominal delay tau_n0 of (14).

    Parameters
    ----------
    model, law, string, torque, bit
        As :func:`string_roots`.

    Returns
    -------
    float
        max Re s over the roots of :func:`string_roots`, the rigid-body root left out, scaled
        (per unit of tau; divide by t* for 1/s); < 0: the linearised closed loop is stable.
    """
    roots = string_roots(model, law, string, torque=torque, bit=bit, n_roots=1)
    return float(roots[0].real) if roots.size else -math.inf
