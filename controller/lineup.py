"""The controllers compared at an operating point: three industrial top-drive laws and the LMI law.

:func:`controller_lineup` builds, for one parameter set, the stiff speed PI, SoftTorque, Z-Torque
(tuned from the lumped string, :mod:`drillstring.controller.tuning`) and the paper's state
feedback (29)-(31) with a gain :func:`lmi_gain` takes from a gains file or designs by Theorem 1
at the point. All four share the feed-forward R_ff and the switch-on time, so that they start
from the same state in the same way (``docs/controllers.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drillstring.controller.averaged import AveragedModel, closed_loop_roots
from drillstring.controller.gains import GainsFile
from drillstring.controller.synthesis import synthesize
from drillstring.controller.tuning import soft_torque, stiff_pi, z_torque
from drillstring.model.control import AffineFeedback
from drillstring.model.laws import Law, SampledAffine
from drillstring.model.params import ScaledParams
from drillstring.validation import check_choice

__all__ = ["CONTROLLERS", "FEEDFORWARD", "LmiGain", "controller_lineup", "lmi_gain"]

#: The controllers, in the order of every table and figure.
CONTROLLERS = ("stiff-pi", "soft-torque", "z-torque", "lmi")
#: Where the LMI law's K0 and R_ff come from with a gains file: the file, or the point's (31).
FEEDFORWARD = ("file", "point")


@dataclass(frozen=True)
class LmiGain:
    """A gain of (29)-(31) for one averaged model: F, K0, R_ff and the closed loop's spectral
    abscissa at tau_n0 (the synthesis' certified one when designed)."""

    F: tuple[float, float, float, float]
    K0: float
    R_ff: float
    abscissa: float


def lmi_gain(
    model: AveragedModel,
    gains: GainsFile | None = None,
    *,
    feedforward: str = "file",
    gain_max: float | None = None,
) -> LmiGain:
    """The gain of the paper's law at a point: from ``gains`` or designed there (Theorem 1).

    Parameters
    ----------
    model : AveragedModel
        The averaged model (29)-(31) of the point.
    gains : GainsFile, optional
        A fixed design; None designs at the point by :func:`~drillstring.controller.synthesis.
        synthesize` (LMI (33)).
    feedforward : str
        With ``gains``: K0 and R_ff from the file ("file") or from the point's model ("point").
    gain_max : float, optional
        Bound on ||F|| of the design (default: the synthesis' own).

    Returns
    -------
    LmiGain
    """
    check_choice("feedforward", feedforward, FEEDFORWARD)
    if gains is None:
        syn = synthesize(model) if gain_max is None else synthesize(model, gain_max=gain_max)
        F = np.asarray(syn.F, dtype=float).reshape(4)
        K0, R_ff = model.K0, model.R_ff
        abscissa = float(syn.certificate.abscissa_nominal)
    else:
        F = np.asarray(gains.F, dtype=float)
        K0, R_ff = (gains.K0, gains.R_ff) if feedforward == "file" else (model.K0, model.R_ff)
        abscissa = float(closed_loop_roots(model, F, None, 1)[0].real)
    gain = (float(F[0]), float(F[1]), float(F[2]), float(F[3]))
    return LmiGain(F=gain, K0=float(K0), R_ff=float(R_ff), abscissa=abscissa)


def controller_lineup(
    params: ScaledParams,
    gain: LmiGain,
    *,
    t_on: float = 0.0,
    latch: str = "angle",
) -> dict[str, Law]:
    """The four controllers of :data:`CONTROLLERS` at ``params``.

    Parameters
    ----------
    params : ScaledParams
        The operating point (rho for the industrial tunings).
    gain : LmiGain
        The paper's law; its R_ff is the feed-forward of every law.
    t_on : float
        Switch-on time of every law.
    latch : str
        Bumpless switch-on of the paper's law (``docs/model.md``, "Bumpless switch-on"); the
        PI laws preset their integrators instead (``drillstring.model.laws``).

    Returns
    -------
    dict
        Name -> law, in the order of :data:`CONTROLLERS`.
    """
    common = {"R_ff": gain.R_ff, "t_on": t_on}
    return {
        "stiff-pi": stiff_pi(params, **common),
        "soft-torque": soft_torque(params, **common),
        "z-torque": z_torque(params, **common),
        "lmi": SampledAffine(AffineFeedback(gain.F, gain.K0, gain.R_ff, t_on, latch)),
    }
