"""A design that holds on the distributed string: a matched top, certified on a reduced chain.

``docs/controllers.md``, "A design that holds on the string", argues the design; in short:

* the laws of (29)-(31) feed back four signals (bit angle and speed, twist, table speed) through
  the table; on the string the table's inertia (rho = 5 I1) reflects the pipe's waves
  (impedance sqrt(kappa) = 1.37) and the bit terms excite the modes above the first. A direct
  search over the four gains finds no stable law on the converged string (the best spectral
  abscissa +0.006 1/tau at N = 16), and the LMI (33) restricted to these four signals (block
  diagonal S in the coordinates [measured; inner nodes]) is infeasible on the 2- and
  3-element chains, as is its Lyapunov (Taylor-form) and Crusius-Trofino counterpart;
* so the law also feeds back the string torque at the top, what Z-Torque measures (the motor
  torque less rho times the table's acceleration), with a gain g: the table's apparent inertia
  becomes J_0/(1 - g), and with a table-speed damper d the top absorbs the wave:
  ``R - R0 = R_ff + F x + g (torque + K0)``, ``F = [-k, 0, k, -d]`` (a spring k holding the
  table to its angle at the switch-on, ``-k (theta - phi_ref + K0)``, which fixes the rigid-body
  rotation; no bit terms: on the string they drive the higher modes);
* in closed form from the pipe: ``g = 1 - INERTIA_REDUCTION`` (the top ten times lighter),
  ``d = DAMPING * sqrt(kappa) * (1 - g)`` (twice the pipe's impedance seen through the lighter
  top), ``k = SPRING``.

The certificate is an LMI on a reduced model, the ``elements``-element lumped chain (default 3:
table, two inner nodes, bit, so the pipe's inertial coupling of table and bit and its second
mode) with the averaged bit law in its Taylor form (27): ``P >= I`` with
``Abar^T P + P Abar + 2 sigma P <= -margin P`` (the largest sigma by bisection, P solved at
:data:`DECAY_FRACTION` of it; the margin of (33), so that the check without it holds
strictly): the reduced loop decays at the rate sigma. The delay form (28) cannot be certified
this way: Lemma 1's Razumikhin condition (32), independent of the delay,
is infeasible for every law we tried on the chain (the chain's bit end has no damping of its
own). The delay and the neglected modes are checked instead, by the spectrum: the spectral
abscissa of the law on the N-element string in the delay form
(:func:`~drillstring.controller.string_spectrum.string_abscissa`) for each N of
:data:`CHECK_ELEMENTS` must be < 0. :func:`check_string_design` verifies both without the
solver; :func:`recheck_string_design` does it again from a gains file alone.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import cvxpy as cp
import numpy as np
from numpy.typing import NDArray

from drillstring.analysis.severity import severity_metrics
from drillstring.controller.averaged import AveragedModel, averaged_model
from drillstring.controller.gains import GainsFile, GainsFileError
from drillstring.controller.string_spectrum import string_abscissa, string_closed_loop
from drillstring.controller.synthesis import LMI_MARGIN, SOLVED, solve_program
from drillstring.model.control import AffineFeedback
from drillstring.model.digital.controller import DigitalController
from drillstring.model.engine import EngineOptions
from drillstring.model.experiments import FIG6
from drillstring.model.laws import SampledAffine
from drillstring.model.pipe import REFERENCE_KAPPA, StringParams
from drillstring.model.sampled import DEFAULT_TS, simulate_sampled
from drillstring.model.sensing import Sensing
from drillstring.validation import check_int, check_real

__all__ = [
    "CHECK_ELEMENTS",
    "DAMPING",
    "DECAY_FRACTION",
    "INERTIA_REDUCTION",
    "REDUCED_ELEMENTS",
    "SPRING",
    "StringCertificate",
    "StringDesign",
    "check_string_design",
    "design_string",
    "recheck_string_design",
    "string_law",
    "string_record",
]

#: Elements of the reduced chain the certificate is solved on (table, 2 inner nodes, bit).
REDUCED_ELEMENTS = 3
#: The converged strings on which the delay-form spectrum is checked.
CHECK_ELEMENTS = (16, 32, 64)
#: J_0 over the top's apparent inertia with the torque feedback: g = 1 - INERTIA_REDUCTION.
INERTIA_REDUCTION = 10.0
#: The table-speed damper in units of the pipe's impedance seen through the lighter top.
DAMPING = 2.0
#: The table's angle spring k (units of C per radian): what fixes the rigid-body rotation.
SPRING = 5.0
#: The Lyapunov matrix is solved at this fraction of the largest certified decay (room for the
#: independent check).
DECAY_FRACTION = 0.9
#: The string torque the law measures on the chain (the rig's: the motor torque less rho times
#: the table's acceleration; :data:`~drillstring.controller.string_spectrum.TORQUE_SIGNALS`).
TORQUE = "motor"


@dataclass(frozen=True, eq=False)
class StringCertificate:
    """The independent check of a string design (:func:`check_string_design`).

    ``lyapunov_max_eig`` is the largest eigenvalue of ``P^-1/2 (Abar^T P + P Abar + 2 sigma P)
    P^-1/2`` on the reduced chain (must be < 0), ``P_min_eig`` the smallest of P (> 0);
    ``abscissae`` the delay-form spectral abscissa on each checked string (each < 0);
    ``matches_record`` False when a gains file records other abscissae than these.
    """

    elements: int
    sigma: float
    lyapunov_max_eig: float
    P_min_eig: float
    abscissae: Mapping[int, float]
    matches_record: bool = True

    @property
    def passed(self) -> bool:
        """Every condition holds (and, re-checked from a file, its abscissae are the file's)."""
        return (
            self.matches_record
            and self.lyapunov_max_eig < 0.0
            and self.P_min_eig > 0.0
            and self.sigma > 0.0
            and all(a < 0.0 for a in self.abscissae.values())
        )

    def margins(self) -> dict[str, float]:
        """The certificate's numbers for the gains file and reports."""
        out = {
            "lyapunov_max_eig": self.lyapunov_max_eig,
            "P_min_eig": self.P_min_eig,
            "decay": self.sigma,
        }
        for n, a in self.abscissae.items():
            out[f"abscissa_N{n}"] = a
        return out


@dataclass(frozen=True, eq=False)
class StringDesign:
    """The string design: gain, torque gain, reduced-chain certificate and its numbers."""

    model: AveragedModel
    F: NDArray[np.float64]
    torque_gain: float
    elements: int
    P: NDArray[np.float64]
    sigma: float
    certificate: StringCertificate
    choices: dict[str, float] = field(default_factory=dict)


def string_law(
    model: AveragedModel,
    F: Sequence[float],
    torque_gain: float,
    *,
    t_on: float = 0.0,
    latch: str = "none",
    on_saturation: str = "none",
) -> SampledAffine:
    """The law ``R - R0 = R_ff + F x + g (torque + K0)`` at the model's K0 and R_ff."""
    feedback = AffineFeedback(tuple(float(v) for v in F), model.K0, model.R_ff, t_on, latch)
    return SampledAffine(feedback, on_saturation=on_saturation, torque_gain=float(torque_gain))


def _reduced(model: AveragedModel, law: SampledAffine, elements: int) -> NDArray[np.float64]:
    """The closed loop on the reduced chain, Taylor form (27) (an ODE)."""
    A0, _ = string_closed_loop(model, law, StringParams(elements=elements), torque=TORQUE,
                               bit="taylor")  # fmt: skip
    return A0


def _lyapunov(Abar: NDArray[np.float64], sigma: float) -> NDArray[np.float64] | None:
    """P >= I with the decay sigma and the relative margin LMI_MARGIN (as (33)'s), or None."""
    n = Abar.shape[0]
    P = cp.Variable((n, n), symmetric=True)
    L = Abar.T @ P + P @ Abar + (2.0 * sigma + LMI_MARGIN) * P
    problem = cp.Problem(cp.Minimize(cp.trace(P)), [P >> np.eye(n), 0.5 * (L + L.T) << 0])
    _, status, _ = solve_program(problem)
    if status not in SOLVED or P.value is None:
        return None
    return 0.5 * (P.value + P.value.T)


def _check_lyapunov(Abar, P, sigma) -> tuple[float, float]:
    P = 0.5 * (np.asarray(P, dtype=float) + np.asarray(P, dtype=float).T)
    smallest = float(np.linalg.eigvalsh(P)[0])
    try:
        Li = np.linalg.inv(np.linalg.cholesky(P))
    except np.linalg.LinAlgError:
        return math.inf, smallest
    Q = Li @ (Abar.T @ P + P @ Abar + 2.0 * sigma * P) @ Li.T
    return float(np.linalg.eigvalsh(0.5 * (Q + Q.T))[-1]), smallest


def check_string_design(
    model: AveragedModel,
    F: Sequence[float],
    torque_gain: float,
    P: Any,
    sigma: float,
    *,
    elements: int = REDUCED_ELEMENTS,
    kappa: float = REFERENCE_KAPPA,
    check_elements: Sequence[int] = CHECK_ELEMENTS,
) -> StringCertificate:
    """Check a string design without the solver: the Lyapunov inequality on the reduced chain
    (numpy eigenvalues) and the delay-form spectral abscissa on each checked string."""
    law = string_law(model, F, torque_gain)
    Abar = _reduced(model, law, elements)
    Pm = np.asarray(P, dtype=float)
    if Pm.shape != Abar.shape:
        raise ValueError(f"P must be {Abar.shape[0]} x {Abar.shape[0]}, got {Pm.shape}")
    top, smallest = _check_lyapunov(Abar, Pm, float(sigma))
    abscissae = {
        int(n): string_abscissa(
            model, law, StringParams(elements=int(n), kappa=kappa), torque=TORQUE
        )  # fmt: skip
        for n in check_elements
    }
    return StringCertificate(int(elements), float(sigma), top, smallest, abscissae)


def design_string(
    model: AveragedModel,
    *,
    elements: int = REDUCED_ELEMENTS,
    kappa: float = REFERENCE_KAPPA,
    inertia_reduction: float = INERTIA_REDUCTION,
    damping: float = DAMPING,
    spring: float = SPRING,
    check_elements: Sequence[int] = CHECK_ELEMENTS,
) -> StringDesign:
    """The matched-top law (module docstring) and its certificate on the reduced chain.

    Parameters
    ----------
    model : AveragedModel
        The averaged model (29)-(31) of the operating point.
    elements : int
        Elements of the reduced chain of the certificate (>= 2).
    kappa : float
        The pipe's inertia over I1 (the string's impedance sqrt(kappa)).
    inertia_reduction, damping, spring : float
        The top's apparent inertia reduction, the damper in units of the matched impedance and
        the table's angle spring (module docstring).
    check_elements : sequence of int
        The strings whose delay-form spectrum is checked.

    Returns
    -------
    StringDesign
        Check ``certificate.passed``.

    Raises
    ------
    ValueError
        A bad value; no decay certified on the reduced chain.
    """
    elements = check_int("elements", elements, lower=2)
    red = check_real("inertia_reduction", inertia_reduction, lower=1.0, strict=False)
    damping = check_real("damping", damping, lower=0.0)
    spring = check_real("spring", spring, lower=0.0)
    g = 1.0 - red
    d = damping * math.sqrt(kappa) * (1.0 - g)
    F = np.array([-spring, 0.0, spring, -d])
    law = string_law(model, F, g)
    Abar = _reduced(model, law, elements)
    hi = max(0.0, -float(np.linalg.eigvals(Abar).real.max()))
    lo, P = 0.0, None
    for _ in range(20):  # bisection on the decay: relative 1e-6 of the spectral bound
        mid = 0.5 * (lo + hi)
        if _lyapunov(Abar, mid) is not None:
            lo = mid
        else:
            hi = mid
    sigma = DECAY_FRACTION * lo
    P = _lyapunov(Abar, sigma) if sigma > 0.0 else None
    if P is None:
        raise ValueError(
            f"no decay certified on the {elements}-element chain for g = {g:g}, F = {F.tolist()}"
        )
    cert = check_string_design(model, F, g, P, sigma, elements=elements, kappa=kappa,
                               check_elements=check_elements)  # fmt: skip
    return StringDesign(
        model=model,
        F=F,
        torque_gain=g,
        elements=elements,
        P=P,
        sigma=sigma,
        certificate=cert,
        choices={
            "inertia_reduction": red,
            "damping": damping,
            "spring": spring,
            "kappa": float(kappa),
            "decay_bound": lo,
        },
    )


def string_record(design: StringDesign) -> dict[str, Any]:
    """The ``string_design`` record of the gains file (what the re-check needs)."""
    return {
        "torque_gain": design.torque_gain,
        "torque": TORQUE,
        "reduced_elements": design.elements,
        "kappa": design.choices["kappa"],
        "decay": design.sigma,
        "P": [[float(v) for v in row] for row in design.P],
        "check_elements": [int(n) for n in design.certificate.abscissae],
        "choices": dict(design.choices),
    }


def recheck_string_design(gains: GainsFile) -> StringCertificate:
    """The certificate of a string design checked again from its gains file alone.

    The averaged model is rebuilt from the file's parameter set, A and taubar_crit; then
    :func:`check_string_design` on the file's F, torque gain, P, decay and elements. The
    recorded abscissae must agree with the recomputed ones (to 1e-6), or the file was changed.

    Raises
    ------
    GainsFileError
        No ``string_design`` record, or one that cannot be checked.
    """
    record = gains.string_design
    if record is None:
        raise GainsFileError("gains file: no string design (string_design is null)")
    model = averaged_model(gains.params, gains.A, gains.taubar_crit)
    try:
        cert = check_string_design(
            model,
            gains.F,
            float(record["torque_gain"]),
            np.asarray(record["P"], dtype=float),
            float(record["decay"]),
            elements=int(record["reduced_elements"]),
            kappa=float(record["kappa"]),
            check_elements=[int(n) for n in record["check_elements"]],
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise GainsFileError(
            f"gains file: the string_design record cannot be checked: {exc}"
        ) from None
    for n, a in cert.abscissae.items():
        stored = gains.certificate.get(f"abscissa_N{n}")
        if stored is None or not math.isclose(stored, a, rel_tol=1e-6, abs_tol=1e-9):
            return dataclasses.replace(cert, matches_record=False)
    return cert


#: The string of the nonlinear check: the converged string of the Fig. 6 switch-on.
FIG6_ELEMENTS = 16
#: Length of the nonlinear check (the switch-on at 25, then 35 of closed loop).
FIG6_TAU_END = 60.0
#: Late window of its severity (scaled time).
FIG6_WINDOW = 10.0


def fig6_on_string(
    params: Any,
    design: StringDesign,
    top_drive: Any,
    *,
    tau_end: float = FIG6_TAU_END,
) -> dict[str, Any]:
    """The nonlinear Fig. 6 switch-on of the string law on the reference pipe in
    :data:`FIG6_ELEMENTS` elements under ``top_drive`` (sampled, freeze-angle on saturation, the
    motor's string torque), its severity over the last :data:`FIG6_WINDOW`.

    Returns
    -------
    dict
        ``outcome`` and ``severity`` of the late window (:func:`~drillstring.analysis.
        severity.severity_metrics`), ``settling_time`` (from the switch-on), ``min_table_speed``
        and ``min_torque`` (absolute, units of C: below 0 the drive brakes), ``peak_torque``,
        ``saturated_fraction``, ``elements``, ``tau_end``, the run's ``status``; and the run
        itself under ``"run"`` (not for the file).
    """
    law = string_law(design.model, design.F, design.torque_gain, t_on=FIG6.t_on,
                     latch=FIG6.latch, on_saturation="freeze-angle")  # fmt: skip
    controller = DigitalController(law, top_drive, Sensing(torque=TORQUE))
    options = EngineOptions(h=FIG6.h, torsional_stick=FIG6.torsional_stick)
    string = StringParams(elements=FIG6_ELEMENTS, kappa=REFERENCE_KAPPA)
    run = simulate_sampled(
        params, controller, tau_end, DEFAULT_TS, initial=FIG6.initial(), options=options,
        string=string,
    )  # fmt: skip
    sev = severity_metrics(run, FIG6_WINDOW, t_from=FIG6.t_on)
    on = np.asarray(run.tau) >= FIG6.t_on
    return {
        "elements": FIG6_ELEMENTS,
        "tau_end": float(tau_end),
        "status": run.status.code,
        "outcome": sev.outcome,
        "severity": sev.severity,
        "settling_time": sev.settling_time,
        "min_table_speed": sev.min_table_speed,
        "min_torque": float(np.min(run.data["R_min"][on])),
        "peak_torque": sev.peak_torque,
        "saturated_fraction": sev.saturated_fraction,
        "run": run,
    }


__all__ += ["FIG6_ELEMENTS", "fig6_on_string"]
