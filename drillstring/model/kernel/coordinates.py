"""Total and perturbation coordinates (``docs/model.md``, "Coordinates"): the one place where
U = v0*tau + u, Phi = omega0*tau + phi, Theta = omega0*tau + theta are converted.

The kernel integrates the total coordinates ``[U, V, Phi, W, Theta, Wt]``; the paper, the
controller and every output speak the perturbations ``[u, du, phi, dphi, theta, dtheta]``.
"""

from __future__ import annotations

import numpy as np

from drillstring.model.kernel.jit import jit_for
from drillstring.model.kernel.state import P_OMEGA0, P_V0

jit = jit_for(__name__)
inline = jit_for(__name__, inline=True)


@inline
def to_perturbation(
    P: np.ndarray, tau: float, U: float, V: float, Phi: float, W: float, Theta: float, Wt: float
) -> tuple[float, float, float, float, float, float]:
    """(u, du, phi, dphi, theta, dtheta) of the total state at time tau."""
    v0 = P[P_V0]
    w0 = P[P_OMEGA0]
    return U - v0 * tau, V - v0, Phi - w0 * tau, W - w0, Theta - w0 * tau, Wt - w0


@jit
def to_total(
    P: np.ndarray,
    tau: float,
    u: float,
    du: float,
    phi: float,
    dphi: float,
    theta: float,
    dtheta: float,
) -> tuple[float, float, float, float, float, float]:
    """(U, V, Phi, W, Theta, Wt) of the perturbation state at time tau."""
    v0 = P[P_V0]
    w0 = P[P_OMEGA0]
    return v0 * tau + u, v0 + du, w0 * tau + phi, w0 + dphi, w0 * tau + theta, w0 + dtheta
