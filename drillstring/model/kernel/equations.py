"""Right-hand side of the scaled axial-torsional model, eqs. (11)-(13), in total coordinates.

With U = v0*tau + u, Phi = omega0*tau + phi, Theta = omega0*tau + theta (``docs/model.md``,
"Coordinates"), the paper's one-mode model:

    dU/dtau = V
    dV/dtau = -gamma*(V - v0) - eta^2*(U - v0*tau) + n*psi*(d0 - d + lambda*g)      (11)
    dPhi/dtau = W
    dW/dtau = -(Phi - Theta) + n*(d0 - d + beta*lambda*g)                            (12)
    dTheta/dtau = Wt
    rho*dWt/dtau = (Phi - Theta) + (R - R0)                                          (13)

On the distributed string (``docs/model.md``, "The distributed string") the bit and the table
are the end nodes of a chain: the spring of (12)-(13) joins each to its neighbouring inner node
(Theta and Phi themselves for one element), with the element's stiffness k_t, and the bit's and
the table's inertias are those of the chain's end nodes; axially the bit's spring joins it to
the last inner node (the hook, v0*tau, for a massless spring). With the paper's values (k_t = 1,
J_bit = 1, J_table = rho, k_a = eta^2, m_bit = 1) every expression below is (11)-(13) to the
bit. :func:`chain_rhs` is the inner nodes' part.

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
    P_GAMMA,
    P_JB,
    P_JI,
    P_JT,
    P_KA,
    P_KT,
    P_LAM,
    P_MB,
    P_MI,
    P_N,
    P_NA,
    P_NPSI,
    P_NT,
    P_OMEGA0,
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
    bit_neighbour: float,
    table_neighbour: float,
    hook_side: float,
) -> tuple[float, float, float, float, float, float]:
    """dY/dtau for depth of cut d, contact g and torque r = R - R0.

    ``bit_neighbour`` and ``table_neighbour`` are the angles of the nodes the bit and the table
    are joined to (Theta and Phi for one element), ``hook_side`` the axial position of the
    bit's neighbour (the hook, v0*tau, for a massless spring). In axial stick V is held at 0
    (dV/dtau = 0 by the choice g = g*); in torsional stick U, V, Phi, W are frozen and only
    the rotary table (and the string) move. ``freeze`` holds the torsion at the nominal speed
    (constant delay tau_n0), which turns (11) into the fast axial model (18).
    """
    lam = P[P_LAM]
    d0 = P[P_D0]
    if mode == MODE_STICK or mode == MODE_TSTICK:
        dU = 0.0
        dV = 0.0
    else:
        dU = V
        dV = (
            -P[P_GAMMA] * (V - P[P_V0]) - P[P_KA] * (U - hook_side) + P[P_NPSI] * (d0 - d + lam * g)
        ) / P[P_MB]
    if freeze:
        return dU, dV, P[P_OMEGA0], 0.0, P[P_OMEGA0], 0.0
    twist = Phi - bit_neighbour
    if mode == MODE_TSTICK:
        dPhi = 0.0
        dW = 0.0
    else:
        dPhi = W
        dW = (-P[P_KT] * twist + P[P_N] * (d0 - d + P[P_BETA] * lam * g)) / P[P_JB]
    return dU, dV, dPhi, dW, Wt, (P[P_KT] * (table_neighbour - Theta) + r) / P[P_JT]


@inline
def chain_rhs(
    P: np.ndarray,
    freeze: bool,
    tau: float,
    Z: np.ndarray,
    zin: int,
    zout: int,
    Phi: float,
    Theta: float,
    U: float,
) -> None:
    """The inner nodes' derivative: row ``zin`` of Z (their state) into row ``zout``.

    Each inner node is pulled by the two elements beside it, k*((left - x) - (x - right))/J
    (differences first: the total coordinates are large, the elements' stretches small); the
    torsional chain ends at the table (Theta) and the bit (Phi), the axial one at the hook
    (v0*tau, imposed) and the bit (U). With the torsion frozen the inner nodes turn at the
    nominal speed, as the bit and the table do.
    """
    nt = int(P[P_NT])
    na = int(P[P_NA])
    kt = P[P_KT]
    jin = P[P_JI]
    for i in range(nt):
        if freeze:
            Z[zout, i] = P[P_OMEGA0]
            Z[zout, nt + i] = 0.0
            continue
        x = Z[zin, i]
        left = Theta if i == 0 else Z[zin, i - 1]
        right = Phi if i == nt - 1 else Z[zin, i + 1]
        Z[zout, i] = Z[zin, nt + i]
        Z[zout, nt + i] = kt * ((left - x) - (x - right)) / jin
    base = 2 * nt
    ka = P[P_KA]
    mi = P[P_MI]
    for i in range(na):
        x = Z[zin, base + i]
        left = P[P_V0] * tau if i == 0 else Z[zin, base + i - 1]
        right = U if i == na - 1 else Z[zin, base + i + 1]
        Z[zout, base + i] = Z[zin, base + na + i]
        Z[zout, base + na + i] = ka * ((left - x) - (x - right)) / mi
