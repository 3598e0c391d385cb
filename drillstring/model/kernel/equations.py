"""Right-hand side of the scaled axial-torsional model, eqs. (11)-(13), in total coordinates.

With U = v0*tau + u, Phi = omega0*tau + phi, Theta = omega0*tau + theta (``docs/model.md``,
"Coordinates"):

    dU/dtau = V
    dV/dtau = -gamma*(V - v0) - eta^2*(U - v0*tau) + n*psi*(d0 - d + lambda*g)      (11)
    dPhi/dtau = W
    dW/dtau = -(Phi - Theta) + n*(d0 - d + beta*lambda*g)                            (12)
    dTheta/dtau = Wt
    rho*dWt/dtau = (Phi - Theta) + (R - R0)                                          (13)

This is the only place the model equations are written.
"""

from __future__ import annotations

import numpy as np

from drillstring.model.kernel.jit import jit_for
from drillstring.model.kernel.state import (
    MODE_STICK,
    MODE_TSTICK,
    P_BETA,
    P_D0,
    P_ETA,
    P_GAMMA,
    P_LAM,
    P_N,
    P_NPSI,
    P_OMEGA0,
    P_RHO,
    P_V0,
)

jit = jit_for(__name__)
inline = jit_for(__name__, inline=True)


@inline
def rhs(
    P: np.ndarray,
    freeze: bool,
    mode: int,
    tau: float,
    U: float,
    V: float,
    Phi: float,
    W: float,
    Theta: float,
    Wt: float,
    d: float,
    g: float,
    r: float,
) -> tuple[float, float, float, float, float, float]:
    """dY/dtau for depth of cut d, contact g and torque r = R - R0.

    In axial stick V is held at 0 (dV/dtau = 0 by the choice g = g*); in torsional stick U, V,
    Phi, W are frozen and only the rotary table moves. ``freeze`` holds the torsion at the
    nominal speed (constant delay tau_n0), which turns (11) into the fast axial model (18).
    """
    eta = P[P_ETA]
    lam = P[P_LAM]
    d0 = P[P_D0]
    if mode == MODE_STICK or mode == MODE_TSTICK:
        dU = 0.0
        dV = 0.0
    else:
        dU = V
        dV = (
            -P[P_GAMMA] * (V - P[P_V0])
            - eta * eta * (U - P[P_V0] * tau)
            + P[P_NPSI] * (d0 - d + lam * g)
        )
    if freeze:
        return dU, dV, P[P_OMEGA0], 0.0, P[P_OMEGA0], 0.0
    twist = Phi - Theta
    if mode == MODE_TSTICK:
        dPhi = 0.0
        dW = 0.0
    else:
        dPhi = W
        dW = -twist + P[P_N] * (d0 - d + P[P_BETA] * lam * g)
    return dU, dV, dPhi, dW, Wt, (twist + r) / P[P_RHO]
