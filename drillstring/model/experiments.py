"""The paper's closed-loop experiments (Figs. 5 and 6) as named data, defined once.

Every part of the project that runs these experiments (the monolithic solver, the co-simulation
figures, the cross-check, the sweeps, the FMUs' defaults, the command line) takes its numbers
from here. The set-ups are reconstructions where the paper is silent (``docs/model.md``,
"Experiments of Figs. 5 and 6").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from drillstring.model.control import LATCH_MODES
from drillstring.validation import check_choice, check_real

__all__ = ["DEFAULT_H", "DEFAULT_DT_OUT", "Experiment", "FIG5", "FIG6", "EXPERIMENTS"]

#: Nominal RK4 step of the engine (scaled time): error in du/dtau about 1e-6 over Fig. 5
#: (``docs/model.md``, "Experiments of Figs. 5 and 6").
DEFAULT_H = 5e-4
#: Default output sampling of a monolithic run (scaled time).
DEFAULT_DT_OUT = 1e-2


@dataclass(frozen=True)
class Experiment:
    """One closed-loop experiment on the full model (11)-(14), (17).

    Attributes
    ----------
    name : str
        Short name (``"fig5"``).
    dphi0 : float
        Initial bit speed perturbation dphi/dtau(0); u = phi = theta = dtheta/dtau = 0 at tau = 0
        and the nominal motion before it.
    tau_end : float
        Length of the run (scaled time).
    t_on : float
        Switch-on time of the feedback R_fb = F x (only the feed-forward R_ff acts before it).
    latch : str
        Bumpless switch-on (``docs/model.md``, "Bumpless switch-on"): ``"none"`` (the paper's
        law), ``"angle"`` or ``"angle+twist"``.
    enabled : bool
        False: the feedback never acts (R - R0 = R_ff throughout).
    torsional_stick : bool
        Model torsional stick of the bit (``docs/model.md``, "Torsional stick").
    h : float
        Nominal RK4 step of the engine.
    """

    name: str
    dphi0: float
    tau_end: float
    t_on: float = 0.0
    latch: str = "none"
    enabled: bool = True
    torsional_stick: bool = False
    h: float = DEFAULT_H

    def __post_init__(self) -> None:
        check_real(f"Experiment.dphi0 of {self.name!r}", self.dphi0)
        check_real(f"Experiment.tau_end of {self.name!r}", self.tau_end, lower=0.0)
        check_real(f"Experiment.t_on of {self.name!r}", self.t_on)
        check_real(f"Experiment.h of {self.name!r}", self.h, lower=0.0)
        check_choice(f"Experiment.latch of {self.name!r}", self.latch, LATCH_MODES)

    def initial(self) -> Mapping[str, float]:
        """The initial perturbation as the engine's ``initial`` mapping.

        Returns
        -------
        mapping of str to float
            ``{"dphi": dphi0}``: the other perturbations u, du, phi, theta, dtheta are 0 at tau = 0
            (``docs/model.md``, "Experiments of Figs. 5 and 6").
        """
        return {"dphi": float(self.dphi0)}


#: Fig. 5: controller on from tau = 0, dphi/dtau(0) = -2.5 (Section V of the paper).
FIG5 = Experiment("fig5", dphi0=-2.5, tau_end=60.0)
#: Fig. 6: open loop (R_ff only) in torsional stick-slip from dphi/dtau(0) = -4.9, controller
#: switched on at tau = 25 with the bumpless latch "angle" (our reconstruction).
FIG6 = Experiment("fig6", dphi0=-4.9, tau_end=60.0, t_on=25.0, latch="angle", torsional_stick=True)
EXPERIMENTS: dict[str, Experiment] = {e.name: e for e in (FIG5, FIG6)}
