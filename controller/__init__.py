"""Sections IV-V: the averaged torsional model, LMI state-feedback synthesis, gains files.

Installed as ``drillstring.controller`` (folder ``controller/``). The usual entry point is
:func:`design_controller`; :func:`read_gains` reads what :func:`write_design` wrote.
"""

from drillstring.controller.averaged import AveragedModel, averaged_model
from drillstring.controller.design import Design, design_controller, write_design
from drillstring.controller.gains import PAPER_F, GainsFile, GainsFileError, read_gains, write_gains
from drillstring.controller.synthesis import SynthesisInfeasible, synthesize

__all__ = [
    "PAPER_F",
    "AveragedModel",
    "Design",
    "GainsFile",
    "GainsFileError",
    "SynthesisInfeasible",
    "averaged_model",
    "design_controller",
    "read_gains",
    "synthesize",
    "write_design",
    "write_gains",
]
