"""The digital controller's block: one float64 array, laid out from its parts' tables.

A digital controller (:class:`~drillstring.model.digital.controller.DigitalController`) is a
sampled control law between a sensing stage and the top drive::

    plant measurements -> sensing -> law -> top drive -> table torque, held over the sample

Its parameters and its state live in one float64 array, the *block*, laid out by :data:`BLOCK`
(:func:`~drillstring.model.tables.block_layout`: entries in order, offsets computed). Each part
has its section, laid out where the part is declared, from its ``PARAMETERS`` table and its
state: the law (:data:`~drillstring.model.laws.LAW_SLOTS`), the top drive
(:data:`~drillstring.model.topdrive.TOP_DRIVE_SLOTS`), the sensing
(:data:`~drillstring.model.sensing.SENSING_SLOTS`) and the controller's own timing
(:data:`~drillstring.model.timing.TIMING_SLOTS`); each part's code takes the block and the offset
of its section in it (``BLOCK.law``, ``BLOCK.sensing``, ...). The compiled functions of
:mod:`drillstring.model.digital.block` read and write the block, and so do the controller FMUs
(on their Python path and natively in the front layer: the block is the FMU's io block) and the
compiled sampled loop (:mod:`drillstring.model.digital.loop`). So every host runs the same code
on the same numbers.

The block starts with the four entries every FMU io block has (the front layer reads them:
:mod:`drillstring.model.native`). Everything is in the paper's scaled units (time tau, torques in
units of C, perturbation coordinates of (9)-(10)); an SI controller FMU converts its connectors
with the rig scales it holds (``si``, ``t_star``, ``C``, ``omega0_si``, ``R0_si``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from drillstring.model.laws import LAW_SLOTS
from drillstring.model.sensing import SENSING_SLOTS
from drillstring.model.tables import block_layout
from drillstring.model.timing import TIMING_SLOTS
from drillstring.model.topdrive import TOP_DRIVE_SLOTS

__all__ = ["BLOCK", "SECTIONS", "slot_names", "state_offsets"]

#: The parts' sections of the block, by their entry in :data:`BLOCK`.
SECTIONS: dict[str, Any] = {
    "law": LAW_SLOTS,
    "top_drive": TOP_DRIVE_SLOTS,
    "sensing": SENSING_SLOTS,
    "timing": TIMING_SLOTS,
}

#: The block, entry by entry (the order is the FMU state's format: new entries go at the end).
BLOCK = block_layout(
    "ControllerBlock",
    (
        # the four entries of every FMU io block (drillstring.model.native)
        ("stale", 1),
        ("resume", 1),
        ("time", 1),
        ("nsteps", 1),
        # an FMU's connectors and unit system
        ("si", 1),  # 1: the connectors are in SI units (converted with the rig scales below)
        ("inputs", 4),  # phi, dphi, theta, dtheta (SI: bit and table angle and speed)
        ("output", 1),  # R - R0 (SI: the absolute table torque R)
        ("t_star", 1),  # rig scales of the SI connectors: t* [s], C [N m/rad], Omega0 [rad/s],
        ("C", 1),  # R0 [N m]
        ("omega0_si", 1),
        ("R0_si", 1),
        # switch-on (docs/model.md, "Bumpless switch-on")
        ("enabled", 1),
        ("t_on", 1),  # the law's switch-on time
        ("active", 1),  # 1 once the law has started (its state is valid)
        # operating point: nominal table speed omega0 and torque R0 (absolute), the table node's
        # inertia rho
        ("omega0", 1),
        ("R0", 1),
        ("rho", 1),
        # the law, the top drive, the sensing
        ("law", LAW_SLOTS.size),
        ("top_drive", TOP_DRIVE_SLOTS.size),
        ("sensing", SENSING_SLOTS.size),
        # what the last committed sample did (diagnostics)
        ("r_cmd", 1),  # the law's command
        ("r_app", 1),  # the applied torque (R - R0)
        ("saturated", 1),  # 1 if the top drive limited the command
        ("n_sat", 1),  # samples with the command limited
        ("n_samples", 1),  # samples committed
        # the controller's own period and latency
        ("timing", TIMING_SLOTS.size),
    ),
    state=("active", "r_cmd", "r_app", "saturated", "n_sat", "n_samples"),
)


def _entries(layout: Any) -> list[tuple[str, int, int]]:
    return [(name, getattr(layout, name), size) for name, size in layout.SLOTS]


def slot_names() -> list[str]:
    """The name of each entry of the block, by offset: ``"active"``, ``"law.x"``, ...
    (an entry of several slots names each of them)."""
    names: list[str] = []
    for name, _, size in _entries(BLOCK):
        if name in SECTIONS:
            names += [f"{name}.{n}" for n, _, k in _entries(SECTIONS[name]) for _ in range(k)]
        else:
            names += [name] * size
    return names


def state_offsets() -> np.ndarray:
    """The offsets of the block's state: its own state entries and each part's."""
    out: list[np.ndarray] = []
    for name, at, size in _entries(BLOCK):
        if name in BLOCK.STATE:
            out.append(np.arange(at, at + size))
        elif name in SECTIONS:
            part = SECTIONS[name]
            for n, a, k in _entries(part):
                if n in part.STATE:
                    out.append(np.arange(at + a, at + a + k))
    return np.concatenate(out)
