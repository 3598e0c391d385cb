"""The controller design of Sections IV-V as one call: axial analysis, LMI synthesis, gains.

:func:`design_controller` runs the whole chain for a parameter set: the slope A of (22) from the
axial limit cycles (the Fig. 4 line at the set's gammabar, etabar^2), taubar_crit of (21), the
averaged model (29)-(31), the line search of Theorem 1 with its independent certificate, and,
for comparison, the paper's published gain on the same model; with a top drive, also the
input-constrained design (:mod:`drillstring.controller.constrained`: the least peak torque
from the Fig. 6 switch-on within the drive's rating). :func:`write_design` writes the
artifacts the rest of the project consumes: the gains file (baked into the controller FMU; the
paper's design, which the reproduction of Figs. 5-6 uses), the constrained design's gains file
and the points of the fit (reused as that line of Fig. 4, so the figure shows the slope the
controller was designed with).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from drillstring.analysis.axial_stability import taubar_crit as critical_delay_of
from drillstring.analysis.figures import write_average_points
from drillstring.analysis.limit_cycles import AxialDesignInputs, design_inputs
from drillstring.controller.averaged import AveragedModel, averaged_model
from drillstring.controller.constrained import (
    BRAKING_TOL,
    DEFAULT_DECAY,
    ConstrainedInfeasible,
    ConstrainedResult,
    least_braking,
    switch_on_states,
    synthesize_constrained,
    torque_budget,
    torque_margins,
)
from drillstring.controller.gains import PAPER_F, GainsFile, write_gains
from drillstring.controller.string_design import design_string, fig6_on_string, string_record
from drillstring.controller.synthesis import (
    GAIN_MAX,
    GainEvaluation,
    SynthesisResult,
    evaluate_gain,
    synthesize,
    to_gains_file,
)
from drillstring.model.experiments import FIG6
from drillstring.model.params import ScaledParams
from drillstring.model.topdrive import TopDrive
from drillstring.validation import check_real

__all__ = [
    "STRING_FILE",
    "design_on_string",
    "CONSTRAINED_FILE",
    "FIT_FILE",
    "GAINS_FILE",
    "ConstrainedDesign",
    "Design",
    "design_constrained",
    "design_controller",
    "write_design",
]

#: File names of the design's artifacts in its output folder.
GAINS_FILE = "gains.json"
CONSTRAINED_FILE = "gains_constrained.json"
STRING_FILE = "gains_string.json"
FIT_FILE = "axial_fit.csv"


@dataclass(frozen=True, eq=False)
class ConstrainedDesign:
    """The input-constrained design: its result (with certificate), gains record and drive."""

    result: ConstrainedResult
    gains: GainsFile
    top_drive: TopDrive
    label: str


@dataclass(frozen=True, eq=False)
class Design:
    """Everything a controller design computed (see :func:`design_controller`)."""

    params: ScaledParams
    axial: AxialDesignInputs | None
    model: AveragedModel
    synthesis: SynthesisResult
    gains: GainsFile
    paper: GainEvaluation | None
    constrained: ConstrainedDesign | None = None


def design_constrained(
    params: ScaledParams,
    model: AveragedModel,
    top_drive: TopDrive,
    *,
    decay: float = DEFAULT_DECAY,
    label: str = "",
    alphas: Sequence[float] | None = None,
    braking_tol: float = BRAKING_TOL,
) -> ConstrainedDesign:
    """The input-constrained design for a top drive, from the switch-on states of Fig. 6 (with its
    latch).

    The drive's range [R_min, R_max] need not be symmetric about the operating torque R0 + R_ff:
    the budget is the smaller margin (:func:`~drillstring.controller.constrained.torque_budget`),
    and a drive that brakes less (R_min = -braking limit; 0: no braking) than the design needs is
    refused with the least braking limit that a certified design needs, found by bisection
    (:func:`~drillstring.controller.constrained.least_braking`) to ``braking_tol``.

    Parameters
    ----------
    params : ScaledParams
        The parameter set.
    model : AveragedModel
        Its averaged model (29)-(31).
    top_drive : TopDrive
        The drive whose torque range bounds the feedback (:func:`~drillstring.controller.
        constrained.torque_budget`).
    decay : float
        Required decay rate of the certificate (1/tau), >= 0 (default
        :data:`~drillstring.controller.constrained.DEFAULT_DECAY`: half-life three torsional
        periods).
    label : str
        How the drive was named (for the gains file).
    alphas : sequence of float, optional
        The alpha grid (default the synthesis' :data:`~drillstring.controller.synthesis.
        ALPHA_GRID`, refined around its best point; given: no refinement).
    braking_tol : float
        Tolerance of the bisection on the braking limit after a refusal (units of C).

    Returns
    -------
    ConstrainedDesign

    Raises
    ------
    drillstring.controller.constrained.ConstrainedInfeasible
        No gain keeps the torque within the drive's range from those states; its
        ``least_braking`` is the least braking limit (-R_min) that a certified design needs,
        within ``braking_tol`` above (None: no braking limit helps, the margin above the
        operating torque is too small).
    """
    states = switch_on_states(params, model, FIG6, latch=FIG6.latch)
    u_max = torque_budget(params, top_drive, model.R_ff)
    grid = {} if alphas is None else {"alphas": alphas, "refine": 0}
    try:
        result = synthesize_constrained(model, states, u_max, sigma=decay, **grid)
    except ConstrainedInfeasible as exc:
        raise _refusal(params, model, top_drive, states, decay, braking_tol, exc) from None
    gains = to_gains_file(
        result,
        params,
        constraint={
            "u_max": result.u_max,
            "peak_torque": result.peak_torque,
            "decay": result.sigma,
            "tau_max": result.tau_max,
            "torque_limit": [top_drive.R_min, top_drive.R_max],
            # the most negative torque the drive applies, as a positive number (0: no braking):
            # the margin below the operating torque, which the re-check takes from here
            "braking_limit": -top_drive.R_min + 0.0,
            "top_drive": label,
            "states": int(len(states)),
            "experiment": FIG6.name,
            # the ellipsoid E = {x^T S^-1 x <= 1} and the states in it: the certificate can be
            # checked again from the file (constrained.recheck_constrained)
            "S": [[float(v) for v in row] for row in result.S],
            "switch_on_states": [[float(v) for v in row] for row in result.states],
        },
    )
    return ConstrainedDesign(result=result, gains=gains, top_drive=top_drive, label=label)


def _refusal(
    params: ScaledParams,
    model: AveragedModel,
    top_drive: TopDrive,
    states,
    decay: float,
    tol: float,
    exc: ConstrainedInfeasible,
) -> ConstrainedInfeasible:
    """The refusal of a constrained design, with the least braking limit that would certify."""
    below, above = torque_margins(params, top_drive, model.R_ff)
    braking = -top_drive.R_min + 0.0
    least = None
    note = ""
    if exc.alpha is not None and exc.least_peak is not None and below < above:
        least, solves = least_braking(
            model, states, exc.alpha, operating_torque=params.R0 + model.R_ff,
            R_max=top_drive.R_max, braking_limit=max(braking, 0.0), sigma=decay, tol=tol,
        )  # fmt: skip
        note = f" ({solves} LMI solves at alpha = {exc.alpha:.4g}, to {tol:.3g})"
    if exc.alpha is None:
        what = "no alpha of the grid was solved"
    elif least is not None:
        what = (
            f"a certified design needs a braking limit of at least {least:.4g} (units of C, "
            f"{least / params.R0:.3g} R0; bisection{note})"
        )
    else:
        what = (
            "no braking limit gives a certified design: the margin above the operating torque, "
            f"R_max - R0 - R_ff = {above:.4g}, is itself below what the design needs"
        )
    return ConstrainedInfeasible(
        f"no certificate at the braking limit {braking:.4g} (R_min = {top_drive.R_min:.4g}, "
        f"units of C): {exc}; {what}",
        least_peak=exc.least_peak,
        alpha=exc.alpha,
        u_max=exc.u_max,
        braking_limit=braking,
        least_braking=least,
        tol=tol,
    )


def design_controller(
    params: ScaledParams,
    *,
    A: float | None = None,
    taubar_crit: float | None = None,
    gain_max: float = GAIN_MAX,
    evaluate_paper: bool = True,
    progress: bool = False,
    top_drive: TopDrive | None = None,
    top_drive_label: str = "",
    decay: float = DEFAULT_DECAY,
    braking_tol: float = BRAKING_TOL,
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
    top_drive : TopDrive, optional
        Also the input-constrained design for this drive (:func:`design_constrained`).
    top_drive_label : str
        The drive's name for its gains file.
    decay : float
        Required decay rate of the constrained design.
    braking_tol : float
        Tolerance of the bisection on the braking limit when the constrained design is refused.

    Returns
    -------
    Design
        The axial inputs, averaged model, synthesis result (with certificate), gains record,
        the paper's gain evaluated and the constrained design.

    Raises
    ------
    ValueError
        For bad ``A``, ``taubar_crit`` or ``gain_max``.
    drillstring.controller.synthesis.SynthesisInfeasible
        When no alpha gives an admissible certified gain (the constrained design's refusal is
        its subclass :class:`~drillstring.controller.constrained.ConstrainedInfeasible`).
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
    constrained = None
    if top_drive is not None:
        constrained = design_constrained(
            params, model, top_drive, decay=decay, label=top_drive_label, braking_tol=braking_tol
        )
    return Design(
        params=params,
        axial=axial,
        model=model,
        synthesis=result,
        gains=to_gains_file(result, params),
        paper=paper,
        constrained=constrained,
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
        ``{"gains": path}``, with a constrained design ``"constrained": path``
        (:data:`CONSTRAINED_FILE`) and, with an axial fit, ``"fit": path`` (a Fig. 4 points
        file).

    Raises
    ------
    ValueError
        When a certificate failed: no gains file is written for an uncertified gain.
    """
    if not design.synthesis.certificate.passed:
        raise ValueError("the certificate check failed; the gains file is not written")
    c = design.constrained
    if c is not None and not c.result.certificate.passed:
        raise ValueError(
            f"the constrained design's certificate failed ({c.result.certificate.margins()}); "
            "no gains file is written"
        )
    out = Path(out_dir)
    paths = {"gains": write_gains(design.gains, out / GAINS_FILE)}
    if c is not None:
        paths["constrained"] = write_gains(c.gains, out / CONSTRAINED_FILE)
    if design.axial is not None:
        paths["fit"] = write_average_points(out / FIT_FILE, design.axial.curve)
    return paths


def design_on_string(
    params: ScaledParams,
    model: AveragedModel,
    *,
    elements: int = 3,
    top_drive: TopDrive | None = None,
    label: str = "",
) -> tuple[object, GainsFile, dict | None]:
    """The string design (:mod:`drillstring.controller.string_design`) as a gains file; with a
    top drive also its nonlinear Fig. 6 switch-on on the 16-element string under that drive
    (recorded in the file's ``string_design["fig6"]``).

    Returns
    -------
    (StringDesign, GainsFile, dict or None)
        The design, its gains record and the nonlinear run's numbers (None without a drive).
    """
    design = design_string(model, elements=elements)
    record = string_record(design)
    fig6 = None
    if top_drive is not None:
        fig6 = fig6_on_string(params, design, top_drive)
        record["fig6"] = {  # NaN (not settled) as null: the file is strict JSON
            k: None if isinstance(v, float) and v != v else v for k, v in fig6.items() if k != "run"
        }
        record["top_drive"] = label
        record["torque_limit"] = [top_drive.R_min, top_drive.R_max]
        record["braking_limit"] = -top_drive.R_min + 0.0
    cert = design.certificate
    gains = GainsFile.of_model(
        model,
        params,
        design.F,
        # no Razumikhin alpha here: the file's alpha is the certified decay of the reduced chain
        alpha=design.sigma,
        certificate=cert.margins(),
        spectral_abscissa=max(cert.abscissae.values()),
        solver="CLARABEL",
        solver_status="optimal",
        string_design=record,
    )
    return design, gains, fig6
