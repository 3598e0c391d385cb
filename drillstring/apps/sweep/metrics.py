"""The metrics each sweep study records: the columns of ``results.csv`` and the maps drawn.

Defined apart from the point functions (:mod:`.studies`) so that the sweep description
(:mod:`.spec`) can validate metric names without importing the studies.
"""

from __future__ import annotations

import math

from drillstring.controller.lineup import RIG_CONTROLLERS
from drillstring.model.units import si_scale

__all__ = [
    "CONTROLLER_METRICS",
    "METRICS",
    "SI_DISPLAY",
    "controller_column",
    "plottable",
    "si_factor",
]

#: Metrics recorded for every controller of the controllers study, (name, type): the fields of
#: :class:`~drillstring.analysis.severity.Severity` (scaled: torques in units of C, power in
#: C per unit of tau, speeds per unit of tau, times in tau) and the spectral abscissa of the
#: law's closed loop linearised about the point (:func:`~drillstring.apps.sweep.studies.
#: linear_abscissa`; NaN for a law with delayed or estimated measurements).
CONTROLLER_METRICS: tuple[tuple[str, str], ...] = (
    ("outcome", "str"),
    ("utr", "float"),
    ("severity", "float"),
    ("stick_fraction", "float"),
    ("stall", "flag"),
    ("peak_torque", "float"),
    ("peak_torque_late", "float"),
    ("rms_torque_late", "float"),
    ("peak_power", "float"),
    ("saturated_fraction", "float"),
    ("min_table_speed", "float"),
    ("settling_time", "float"),
    ("linear_abscissa", "float"),
)


#: How the maps of a physical base show the controllers' dimensional metrics: (dimension of
#: :data:`drillstring.model.units.DIMENSIONS`, factor from SI, unit).
SI_DISPLAY: dict[str, tuple[str, float, str]] = {
    "peak_torque": ("torque", 1e-3, "kN m"),
    "peak_torque_late": ("torque", 1e-3, "kN m"),
    "rms_torque_late": ("torque", 1e-3, "kN m"),
    "peak_power": ("power", 1e-3, "kW"),
    "min_table_speed": ("speed", 30.0 / math.pi, "rpm"),
    "settling_time": ("time", 1.0, "s"),
    "linear_abscissa": ("frequency", 1.0, "1/s"),
}


def si_factor(metric: str, C: float, t_star: float) -> tuple[float, str]:
    """The factor from a controller metric's scaled value to its display unit on a rig.

    Parameters
    ----------
    metric : str
        A name of :data:`CONTROLLER_METRICS`.
    C, t_star : float
        The rig's torque and time scales (eqs. (15)-(16)).

    Returns
    -------
    (float, str)
        The factor and the unit (1 and "" for a dimensionless metric).
    """
    if metric not in SI_DISPLAY:
        return 1.0, ""
    dimension, factor, unit = SI_DISPLAY[metric]
    return si_scale(dimension, C, t_star) * factor, unit


def controller_column(metric: str, controller: str) -> str:
    """Column name of ``metric`` for ``controller`` in the controllers study.

    Parameters
    ----------
    metric : str
        A name of :data:`CONTROLLER_METRICS` (``"utr"``).
    controller : str
        A name of :data:`~drillstring.controller.lineup.RIG_CONTROLLERS` (``"stiff-pi"``).

    Returns
    -------
    str
        ``"<metric>.<controller>"`` (``"utr.stiff-pi"``), a metric with a physical dimension
        (:data:`SI_DISPLAY`) as ``"<metric>_scaled.<controller>"`` (``"peak_torque_scaled.lmi"``:
        the column holds the paper's scaled value); not checked against the names.
    """
    if metric in SI_DISPLAY:
        return f"{metric}_scaled.{controller}"
    return f"{metric}.{controller}"


#: Metric columns per study: (name, type) with type "float", "flag" (0/1), "int" or "str".
METRICS: dict[str, tuple[tuple[str, str], ...]] = {
    "open-loop": (
        ("A", "float"),
        ("taubar_crit", "float"),
        ("R_ff", "float"),
        ("root_real", "float"),
        ("root_imag", "float"),
        ("torsional_stick", "flag"),
        ("time_to_stick", "float"),
        ("axial_stick_fraction", "float"),
        ("bit_bounce", "flag"),
        ("status", "str"),
        ("tau_reached", "float"),
    ),
    "closed-loop": (
        ("A", "float"),
        ("taubar_crit", "float"),
        ("gain_norm", "float"),
        ("abscissa_closed", "float"),
        ("converged", "flag"),
        ("dphi_amplitude", "float"),
        ("ripple", "float"),
        ("max_dR", "float"),
        ("axial_stick_fraction", "float"),
        ("torsional_stick", "flag"),
        ("bit_bounce", "flag"),
        ("status", "str"),
        ("tau_reached", "float"),
    ),
    "axial": (
        ("average", "float"),
        ("period", "float"),
        ("stick_fraction", "float"),
        ("stick_phases", "int"),
        ("kind", "str"),
        ("time_simulated", "float"),
    ),
    "controllers": (
        ("A", "float"),
        ("taubar_crit", "float"),
        ("open_loop_abscissa_scaled", "float"),
        ("lmi_gain_norm", "float"),
        ("lmi_abscissa_scaled", "float"),
        ("lmi_design_error", "str"),
        ("lmi_constrained_gain_norm", "float"),
        ("lmi_constrained_abscissa_scaled", "float"),
        *(
            (controller_column(m, c), kind)
            for c in RIG_CONTROLLERS
            for m, kind in CONTROLLER_METRICS
        ),
        ("best", "str"),
    ),
}


def plottable(study: str) -> tuple[str, ...]:
    """Metric names that get a map in a study.

    Parameters
    ----------
    study : str
        A key of :data:`METRICS`.

    Returns
    -------
    tuple of str
        Every metric of the study (strings as categorical maps); for the controllers study the
        names of :data:`CONTROLLER_METRICS` (one figure each, a panel per controller on one
        colour scale) and ``"best"``.

    Raises
    ------
    KeyError
        ``study`` is not a study of :data:`METRICS`.
    """
    if study == "controllers":
        return (*(m for m, _ in CONTROLLER_METRICS), "best")
    return tuple(name for name, _ in METRICS[study])
