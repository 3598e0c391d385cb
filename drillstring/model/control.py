"""The torsional controller of Section V: R - R0 = R_ff + R_fb, R_fb = F x, eqs. (29)-(31).

x = [phi - phi_ref, dphi/dtau, phi - theta - K0 - twist_ref, dtheta/dtau]; R_ff = -K0 (31).
Before the switch-on time only the feed-forward acts. ``phi_ref`` and ``twist_ref`` are 0 for the
paper's law; a bumpless switch-on latches them at t_on (``docs/model.md``, "Bumpless switch-on",
our reconstruction). The kernel of the monolithic solver and the controller FMU both call
:func:`feedback_torque` and :func:`switch_on_references`: the law is written once.
"""

from __future__ import annotations

from dataclasses import dataclass

from drillstring.model.kernel.jit import jit_for
from drillstring.validation import check_choice, check_real

jit = jit_for(__name__)
inline = jit_for(__name__, inline=True)

__all__ = [
    "LATCH_MODES",
    "LATCH_NONE",
    "LATCH_ANGLE",
    "LATCH_ANGLE_TWIST",
    "AffineFeedback",
    "feedback_torque",
    "switch_on_references",
]

#: Bumpless switch-on modes; their index is the code the kernel and the FMUs use.
LATCH_MODES = ("none", "angle", "angle+twist")
LATCH_NONE = 0
LATCH_ANGLE = 1
LATCH_ANGLE_TWIST = 2


@jit
def switch_on_references(latch: int, phi: float, theta: float, K0: float) -> tuple[float, float]:
    """References (phi_ref, twist_ref) latched at switch-on from the measured phi and theta.

    "none" keeps both 0 (the paper's law), "angle" takes phi_ref = phi, so that x1 = 0 at
    switch-on (the velocities and the twist act at first), "angle+twist" also takes
    twist_ref = phi - theta - K0, so that x3 = 0 too (only the velocities act at first);
    ``docs/model.md``, "Bumpless switch-on".

    Parameters
    ----------
    latch : int
        Index into :data:`LATCH_MODES` (:data:`LATCH_NONE`, :data:`LATCH_ANGLE`,
        :data:`LATCH_ANGLE_TWIST`).
    phi, theta : float
        Perturbation angles of the bit and the rotary table at switch-on.
    K0 : float
        Nominal twist offset of x3, eq. (29) (``docs/model.md``, "Equation (30)").

    Returns
    -------
    phi_ref, twist_ref : float
        The references that :func:`feedback_torque` subtracts from x1 and x3.
    """
    phi_ref = phi if latch != LATCH_NONE else 0.0
    twist_ref = (phi - theta) - K0 if latch == LATCH_ANGLE_TWIST else 0.0
    return phi_ref, twist_ref


@inline
def feedback_torque(
    tau: float,
    phi: float,
    dphi: float,
    theta: float,
    dtheta: float,
    F: tuple[float, float, float, float],
    K0: float,
    R_ff: float,
    t_on: float,
    phi_ref: float,
    twist_ref: float,
) -> float:
    """Table torque R - R0 = R_ff + F x at time tau, eq. (31) with R_fb = F x of Theorem 1.

    Parameters
    ----------
    tau : float
        Scaled time.
    phi, dphi, theta, dtheta : float
        Perturbation angles and speeds of the bit and the rotary table, eqs. (9)-(10).
    F : tuple of 4 float
        Gain of R_fb = F x, x = [phi - phi_ref, dphi, phi - theta - K0 - twist_ref, dtheta]
        (the state of (29), shifted by the references).
    K0 : float
        Nominal twist offset of x3, n*v0*beta*A*(tau_n0 - tau_n_crit).
    R_ff : float
        Feed-forward torque of (31).
    t_on : float
        Switch-on time: for tau < t_on only R_ff acts.
    phi_ref, twist_ref : float
        References latched at switch-on (:func:`switch_on_references`).

    Returns
    -------
    float
        R - R0, the scaled table torque deviation of (13).
    """
    if tau < t_on:
        return R_ff
    x0 = phi - phi_ref
    x2 = phi - theta - K0 - twist_ref
    return R_ff + F[0] * x0 + F[1] * dphi + F[2] * x2 + F[3] * dtheta


@dataclass(frozen=True)
class AffineFeedback:
    """State feedback with feed-forward (29)-(31), evaluated continuously by the monolithic solver.

    Parameters
    ----------
    F : tuple of 4 float
        Gain of R_fb = F x, x = [phi - phi_ref, dphi, phi - theta - K0 - twist_ref, dtheta].
    K0 : float
        Nominal twist offset of x3, eq. (29) (``docs/model.md``, "Equation (30)").
    R_ff : float
        Feed-forward torque (31), -K0 for the paper's design.
    t_on : float
        Switch-on time of the feedback (only R_ff acts before it).
    latch : str
        Bumpless switch-on, one of :data:`LATCH_MODES` (see :func:`switch_on_references`).
    """

    F: tuple[float, float, float, float]
    K0: float
    R_ff: float
    t_on: float = 0.0
    latch: str = "none"

    def __post_init__(self) -> None:
        if len(self.F) != 4:
            raise ValueError(f"AffineFeedback.F must have 4 entries, got {len(self.F)}: {self.F!r}")
        F = tuple(check_real(f"AffineFeedback.F[{i}]", f) for i, f in enumerate(self.F))
        object.__setattr__(self, "F", F)
        object.__setattr__(self, "K0", check_real("AffineFeedback.K0", self.K0))
        object.__setattr__(self, "R_ff", check_real("AffineFeedback.R_ff", self.R_ff))
        object.__setattr__(self, "t_on", check_real("AffineFeedback.t_on", self.t_on))
        check_choice("AffineFeedback.latch", self.latch, LATCH_MODES)

    @property
    def latch_code(self) -> int:
        """Index of ``latch`` in :data:`LATCH_MODES` (the kernel's and FMUs' code)."""
        return LATCH_MODES.index(self.latch)
