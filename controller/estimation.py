"""An estimator of the downhole state from surface signals: a Kalman filter on the averaged
torsional model (``docs/controllers.md``, "Sensing").

The paper's law needs the bit angle and speed, which a rig measures downhole only (mud-pulse
telemetry: a few bits per second, seconds of latency). At the surface it has the table speed and
the motor torque; with the table's equation (13) the mean string torque over a sample follows
from the motor torque and the table acceleration (:mod:`drillstring.model.sensing`). On the
linearised averaged model (13), (27), state ``x = [phi, dphi, x3, dtheta]`` (29), input ``u = R -
R0 + K0``, the measurements ``y = [dtheta, x3]`` (``x3 = -(string torque) - K0``) make ``dphi``
observable; the bit angle ``phi`` is not (it enters no measured equation: the rigid-body mode),
so the filter integrates it from its speed estimate without correction.

:func:`design_observer` discretises the model exactly over the sample period (zero-order hold of
the applied torque) and takes the steady-state Kalman gain of the observable part from the
discrete algebraic Riccati equation; the result is an :class:`~drillstring.model.sensing.
Observer` (numbers only), run by the compiled controller.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm, solve_discrete_are

from drillstring.controller.averaged import AveragedModel, linearised_ode_matrix
from drillstring.model.sensing import Observer
from drillstring.validation import check_real

__all__ = ["OBSERVED", "design_observer", "discretise"]

#: The measured combinations of x: y = C x (table speed, twist state x3).
OBSERVED = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.0]])


def discretise(
    A: NDArray[np.float64], B: NDArray[np.float64], Ts: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(Ad, Bd) of ``x' = A x + B u`` with ``u`` held over ``Ts`` (exact, by the exponential of
    the augmented matrix)."""
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A
    M[:n, n] = np.asarray(B, dtype=float).reshape(-1)
    E = expm(M * Ts)
    return E[:n, :n], E[:n, n]


def design_observer(
    model: AveragedModel,
    Ts: float,
    *,
    process: float = 1.0,
    speed_noise: float = 1e-2,
    torque_noise: float = 1e-2,
) -> Observer:
    """The steady-state Kalman filter of the module docstring.

    Parameters
    ----------
    model : AveragedModel
        The averaged model (its c, tau_n0, rho and K0).
    Ts : float
        Sample period of the controller (scaled), > 0.
    process : float
        Standard deviation (per unit of sqrt(tau)) of the bit's unmodelled acceleration (the
        axial stick-slip the averaging leaves out), > 0.
    speed_noise, torque_noise : float
        Standard deviations of the measured table speed and string torque, > 0.

    Returns
    -------
    Observer
        ``Ad``, ``Bd``, the filter gain ``M`` (row 0 zero: the angle is not corrected), K0, Ts.
    """
    Ts = check_real("Ts", Ts, lower=0.0)
    q = check_real("process", process, lower=0.0)
    rv = check_real("speed_noise", speed_noise, lower=0.0)
    rt = check_real("torque_noise", torque_noise, lower=0.0)
    A = linearised_ode_matrix(model)
    B = model.B.reshape(-1)
    Ad, Bd = discretise(A, B, Ts)
    # the observable part x[1:] = [dphi, x3, dtheta]: phi enters no other equation
    Ao = Ad[1:, 1:]
    Co = OBSERVED[:, 1:]
    Q = np.diag([q * q * Ts, 1e-12, 1e-12])
    R = np.diag([rv * rv, rt * rt])
    P = solve_discrete_are(Ao.T, Co.T, Q, R)
    Mo = P @ Co.T @ np.linalg.inv(Co @ P @ Co.T + R)
    M = np.zeros((4, 2))
    M[1:, :] = Mo
    return Observer(Ad=Ad, Bd=Bd, M=M, K0=model.K0, Ts=Ts)
