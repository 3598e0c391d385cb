"""The controller design of Sections IV-V as one call: axial analysis, LMI synthesis, gains.

:func:`design_controller` runs the whole chain for a parameter set: the slope A of (22) from the
axial limit cycles (the Fig. 4 line at the set's gammabar, etabar^2), taubar_crit of (21), the
averaged model (29)-(31), the line search of Theorem 1 with its independent certificate, and,
for comparison, the paper's published gain on the same model. :func:`write_design` writes the
artifacts the rest of the project consumes: the gains file (baked into the controller FMU) and
the points of the fit (reused as that line of Fig. 4, so the figure shows the slope the
controller was designed with).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from drillstring.analysis.axial_stability import taubar_crit as critical_delay_of
from drillstring.analysis.figures import write_average_points
from drillstring.analysis.limit_cycles import AxialDesignInputs, design_inputs
from drillstring.controller.averaged import AveragedModel, averaged_model
from drillstring.controller.gains import PAPER_F, GainsFile, write_gains
from drillstring.controller.synthesis import (
    GAIN_MAX,
    GainEvaluation,
    SynthesisResult,
    evaluate_gain,
    synthesize,
    to_gains_file,
)
from drillstring.model.params import ScaledParams
from drillstring.validation import check_real

__all__ = ["GAINS_FILE", "FIT_FILE", "Design", "design_controller", "write_design"]

#: File names of the design's artifacts in its output folder.
GAINS_FILE = "gains.json"
FIT_FILE = "axial_fit.csv"


@dataclass(frozen=True, eq=False)
class Design:
    """Everything a controller design computed (see :func:`design_controller`)."""

    params: ScaledParams
    axial: AxialDesignInputs | None
    model: AveragedModel
    synthesis: SynthesisResult
    gains: GainsFile
    paper: GainEvaluation | None


def design_controller(
    params: ScaledParams,
    *,
    A: float | None = None,
    taubar_crit: float | None = None,
    gain_max: float = GAIN_MAX,
    evaluate_paper: bool = True,
    progress: bool = False,
) -> Design:
    """Design the torsional controller (29)-(31) for ``params`` by Theorem 1 (LMI (33)).

    Parameters
    ----------
    params : ScaledParams
        The scaled parameter set.
    A : float, optional
        Slope of the averaged contact force (22); default: computed from the axial limit
        cycles (:func:`drillstring.analysis.limit_cycles.design_inputs`).
    taubar_crit : float, optional
        Critical delay of (21) in fast time; default: the crossing formula.
    gain_max : float
        Bound on ||F||_2 of an admissible gain.
    evaluate_paper : bool
        Also evaluate the paper's gain on the same averaged model.
    progress : bool
        Progress bar of the limit cycles.

    Returns
    -------
    Design
        The axial inputs, averaged model, synthesis result (with certificate), gains record and
        the paper's gain evaluated.

    Raises
    ------
    ValueError
        For bad ``A``, ``taubar_crit`` or ``gain_max``.
    drillstring.controller.synthesis.SynthesisInfeasible
        When no alpha gives an admissible certified gain.
    """
    axial = None
    if A is None:
        axial = design_inputs(params, progress=progress)
        A = axial.A
    A = check_real("A (slope of (22))", A, lower=0.0)
    if taubar_crit is None:
        taubar_crit = critical_delay_of(params)
    taubar_crit = check_real("taubar_crit", taubar_crit, lower=0.0)
    model = averaged_model(params, A, taubar_crit)
    result = synthesize(model, gain_max=gain_max)
    paper = evaluate_gain(PAPER_F, params, A, taubar_crit) if evaluate_paper else None
    return Design(
        params=params,
        axial=axial,
        model=model,
        synthesis=result,
        gains=to_gains_file(result, params),
        paper=paper,
    )


def write_design(design: Design, out_dir: str | os.PathLike[str]) -> dict[str, Path]:
    """Write the gains file and (when the design computed it) the axial fit into ``out_dir``.

    Parameters
    ----------
    design : Design
        A result of :func:`design_controller`.
    out_dir : path-like
        Output folder; the files are :data:`GAINS_FILE` and :data:`FIT_FILE`, written atomically.

    Returns
    -------
    dict
        ``{"gains": path}`` and, with an axial fit, ``"fit": path`` (a Fig. 4 points file).

    Raises
    ------
    ValueError
        When the certificate failed: no gains file is written for an uncertified gain.
    """
    if not design.synthesis.certificate.passed:
        raise ValueError("the certificate check failed; the gains file is not written")
    out = Path(out_dir)
    paths = {"gains": write_gains(design.gains, out / GAINS_FILE)}
    if design.axial is not None:
        paths["fit"] = write_average_points(out / FIT_FILE, design.axial.curve)
    return paths
