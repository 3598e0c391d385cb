"""The metrics each sweep study records: the columns of ``results.csv`` and the maps drawn.

Defined apart from the point functions (:mod:`.studies`) so that the sweep description
(:mod:`.spec`) can validate metric names without importing the studies.
"""

from __future__ import annotations

from drillstring.controller.lineup import CONTROLLERS

__all__ = [
    "CONTROLLER_METRICS",
    "METRICS",
    "controller_column",
    "plottable",
]

#: Severity metrics recorded for every controller of the controllers study
#: (:mod:`drillstring.analysis.severity`), (name, type).
CONTROLLER_METRICS: tuple[tuple[str, str], ...] = (
    ("utr", "float"),
    ("severity", "float"),
    ("stick_fraction", "float"),
    ("peak_torque", "float"),
    ("stall", "flag"),
    ("outcome", "str"),
)


def controller_column(metric: str, controller: str) -> str:
    """Column of ``metric`` for ``controller`` in the controllers study (``utr.stiff-pi``)."""
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
        ("lmi_gain_norm", "float"),
        ("lmi_abscissa", "float"),
        ("lmi_design_error", "str"),
        *((controller_column(m, c), kind) for c in CONTROLLERS for m, kind in CONTROLLER_METRICS),
        ("best", "str"),
    ),
}


def plottable(study: str) -> tuple[str, ...]:
    """Metric names that get a map: every metric (strings as categorical maps); for the
    controllers study the severity metrics (one figure with a panel per controller, one shared
    colour scale) and ``best``."""
    if study == "controllers":
        return (*(m for m, _ in CONTROLLER_METRICS), "best")
    return tuple(name for name, _ in METRICS[study])
