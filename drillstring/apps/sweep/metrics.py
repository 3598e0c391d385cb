"""The metrics each sweep study records: the columns of ``results.csv`` and the maps drawn.

Defined apart from the point functions (:mod:`.studies`) so that the sweep description
(:mod:`.spec`) can validate metric names without importing the studies.
"""

from __future__ import annotations

__all__ = ["METRICS", "plottable"]

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
}


def plottable(study: str) -> tuple[str, ...]:
    """Metric names that get a heat map (all of them; strings as categorical maps)."""
    return tuple(name for name, _ in METRICS[study])
