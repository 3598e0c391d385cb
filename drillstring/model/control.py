"""The torsional controller of Section V: R - R0 = R_ff + R_fb, R_fb = F x, eqs. (29)-(31).

x = [phi - phi_ref, dphi/dtau, phi - theta - K0 - twist_ref, dtheta/dtau]; R_ff = -K0 (31).
Before the switch-on time only the feed-forward acts. ``phi_ref`` and ``twist_ref`` are 0 for the
paper's law; a bumpless switch-on latches them at t_on (NOTES.md section 7, our reconstruction).
Both the controller FMU and the monolithic solver call this one function.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drillstring.model.kernel.jit import jit_for

jit = jit_for(__name__)

LATCH_MODES = ("none", "angle", "angle+twist")


@jit
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
    """R - R0 at time tau for perturbation states phi, dphi, theta, dtheta (eqs. (29)-(31))."""
    if tau < t_on:
        return R_ff
    x0 = phi - phi_ref
    x2 = phi - theta - K0 - twist_ref
    return R_ff + F[0] * x0 + F[1] * dphi + F[2] * x2 + F[3] * dtheta


@dataclass(frozen=True)
class AffineFeedback:
    """State feedback with feed-forward, evaluated continuously by the monolithic solver.

    ``latch`` selects the bumpless switch-on: "none" (paper's law, references 0), "angle"
    (phi_ref = phi(t_on)) or "angle+twist" (also twist_ref = phi - theta - K0 at t_on).
    """

    F: tuple[float, float, float, float]
    K0: float
    R_ff: float
    t_on: float = 0.0
    latch: str = "none"

    def __post_init__(self) -> None:
        if len(self.F) != 4:
            raise ValueError(f"AffineFeedback.F must have 4 entries, got {len(self.F)}: {self.F!r}")
        vals = [*self.F, self.K0, self.R_ff]
        if not all(np.isfinite(v) for v in vals):
            raise ValueError(
                f"AffineFeedback gains must be finite, got F={self.F}, K0={self.K0}, "
                f"R_ff={self.R_ff}"
            )
        if not np.isfinite(self.t_on):
            raise ValueError(f"AffineFeedback.t_on must be finite, got {self.t_on!r}")
        if self.latch not in LATCH_MODES:
            raise ValueError(
                f"AffineFeedback.latch must be one of {LATCH_MODES}, got {self.latch!r}"
            )
        object.__setattr__(self, "F", tuple(float(f) for f in self.F))
