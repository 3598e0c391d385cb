"""Fixed colours of the controllers and of the outcomes, shared by the maps and the figures."""

from __future__ import annotations

__all__ = ["CONTROLLER_COLORS", "OUTCOME_COLORS"]

#: One colour per controller of ``drillstring.controller.lineup.RIG_CONTROLLERS``.
CONTROLLER_COLORS = {
    "stiff-pi": "#7f7f7f",
    "soft-speed": "#1f77b4",
    "z-torque": "#2ca02c",
    "lmi": "#d62728",
    "lmi-constrained": "#9467bd",
    "lmi-telemetry": "#8c564b",
    "lmi-observer": "#e377c2",
}
#: Outcomes of ``drillstring.analysis.severity``, from good (green) to bad (red).
OUTCOME_COLORS = {
    "steady": "#2ca02c",
    "settling": "#98df8a",
    "vibration": "#bcbd22",
    "stick-slip": "#ff7f0e",
    "stall": "#d62728",
    "no_design": "#7f7f7f",
    "reverse_rotation": "#8c564b",
    "bit_bounce": "#17becf",
}
