"""FMI 2.0 co-simulation unit of the torsional controller (pythonfmu script of
``TorsionalController``).

Output ``R_minus_R0 = R_ff + F x`` with ``x = [phi - phi_ref, dphi, phi - theta - K0 - twist_ref,
dtheta]``, the state feedback with feed-forward of Section V, eqs. (29)-(31), evaluated by
:func:`drillstring.model.control.feedback_torque` (the same function the monolithic solver uses; no
control code lives here, and the lifecycle is :class:`drillstring_fmu_support.FmuModel`). Before
``t_on`` only ``R_ff`` acts (the paper's Fig. 6). Bumpless switch-on (``docs/model.md``,
"Bumpless switch-on", our reconstruction): at the first communication point at or after ``t_on``
the controller takes the measured angle as its reference, ``phi_ref = phi`` (``latch`` = angle),
and with ``latch`` = angle+twist also ``twist_ref = phi - theta - K0``; ``latch`` = none is the
paper's law. Until that point has been stepped from, outputs at or after ``t_on`` use the current
inputs as references (so ``x1 = 0`` at switch-on whatever order the master uses).

The output depends directly on the inputs (declared in ``ModelStructure`` by ``build_fmus.py``);
the FMU has no dynamics, its state is the time, the inputs, the parameters and the latch. The
start values of ``F``, ``K0``, ``R_ff`` are the gains file of the synthesis, baked in by
``build_fmus.py --gains`` into ``resources/drillstring_fmu.json``.

The unit system is the class's: ``torsional_controller_si.py`` derives
``TorsionalControllerSI`` from :class:`TorsionalController`, replacing the variables, the law's
parameters (:meth:`TorsionalController.new_law`, :meth:`~TorsionalController.initial_values`) and
the measured coordinates the law acts on (:meth:`~TorsionalController.measured`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import drillstring_fmu_support as fmu
import numpy as np

from drillstring.model import native
from drillstring.model.control import (
    LATCH_MODES,
    AffineFeedback,
    feedback_torque,
    switch_on_references,
)

INPUTS = (
    ("phi", "Measured bit angle perturbation phi (plant output)"),
    ("dphi", "Measured bit angular velocity perturbation dphi/dtau (plant output)"),
    ("theta", "Measured rotary-table angle perturbation theta (plant output)"),
    ("dtheta", "Measured rotary-table angular velocity perturbation dtheta/dtau (plant output)"),
)
GAIN_NAMES = ("F[1]", "F[2]", "F[3]", "F[4]")
_X = ("phi - phi_ref", "dphi", "phi - theta - K0 - twist_ref", "dtheta")
LATCH_ITEMS = (
    ("none", "the paper's law: phi_ref = twist_ref = 0"),
    ("angle", "phi_ref = phi at the switch-on, so that x1 = 0 there"),
    ("angle+twist", "also twist_ref = phi - theta - K0, so that x3 = 0 there too"),
)
assert tuple(name for name, _ in LATCH_ITEMS) == LATCH_MODES


def _variables() -> tuple[fmu.Variable, ...]:
    out = [fmu.input_real(name, 0.0, desc) for name, desc in INPUTS]
    out.append(
        fmu.output(
            "R_minus_R0",
            "Real",
            "Rotary-table torque deviation R - R0 = R_ff + F x (eqs. (29)-(31))",
            depends_on=[name for name, _ in INPUTS],
        )
    )
    baked = "; start value: the synthesis result baked in by build_fmus.py --gains"
    out += [
        fmu.parameter(name, "Real", 0.0, f"State-feedback gain on x{i + 1} = {x}{baked}")
        for i, (name, x) in enumerate(zip(GAIN_NAMES, _X, strict=True))
    ]
    out += [
        fmu.parameter("K0", "Real", 0.0, f"Nominal twist offset K0 of x3 (eq. (30)){baked}"),
        fmu.parameter("R_ff", "Real", 0.0, f"Feed-forward torque R_ff = -K0 (eq. (31)){baked}"),
        fmu.parameter("t_on", "Real", 0.0, "Switch-on time of the feedback: before it only R_ff"),
        fmu.parameter("enabled", "Boolean", True, "Feedback enabled; false: R - R0 = R_ff always"),
        fmu.enumeration(
            "latch",
            "Latch",
            LATCH_ITEMS,
            "angle",
            'Bumpless switch-on (docs/model.md, "Bumpless switch-on"): 1 = none (the paper\'s '
            "law), 2 = angle (phi_ref = phi at t_on), 3 = angle+twist (also twist_ref)",
        ),
    ]
    return tuple(out)


class TorsionalController(fmu.FmuModel):
    """State feedback with feed-forward R - R0 = R_ff + F x of Section V, eqs. (29)-(31)."""

    MODEL = "TorsionalController"
    VARIABLES = _variables()
    VALIDITY = (
        "A static law without limits of validity: finite inputs give a finite output. Before "
        "t_on, or with enabled = false, the output is R_ff; the references are latched at the "
        "first communication point at or after t_on (latch).",
    )
    description = (
        "Torsional stick-slip controller R - R0 = R_ff + F x of Besselink, van de Wouw and "
        "Nijmeijer (IEEE CCA 2011), Section V, eqs. (29)-(31), with bumpless switch-on at t_on"
    )

    law: AffineFeedback | None = None
    latched = False
    refs = (0.0, 0.0)

    #: The output's name.
    OUTPUT = "R_minus_R0"

    def initial_values(self) -> Mapping[str, Any]:
        """F, K0, R_ff of this FMU's own build configuration (not of the class: FMUs of two
        builds share the Python module when a host loads both)."""
        g = self.config["gains"]
        return {**dict(zip(GAIN_NAMES, g["F"], strict=True)), "K0": g["K0"], "R_ff": g["R_ff"]}

    def new_law(self, v: Mapping[str, Any]) -> Any:
        """The law's parameters, validated like the Python API (AffineFeedback)."""
        return AffineFeedback(
            F=tuple(v[name] for name in GAIN_NAMES),  # type: ignore[arg-type]
            K0=v["K0"],
            R_ff=v["R_ff"],
            t_on=v["t_on"],
            latch=LATCH_MODES[v["latch"] - 1],
        )

    def measured(self) -> tuple[float, float, float, float]:
        """The coordinates (phi, dphi, theta, dtheta) of (29)-(31) of the current inputs."""
        x = self.values
        return x["phi"], x["dphi"], x["theta"], x["dtheta"]

    # ----------------------------------------------------------------- law
    def configure(self, values: Mapping[str, Any]) -> None:
        self.law = self.new_law(values)
        self.latched, self.refs = False, (0.0, 0.0)

    def _candidate_references(self) -> tuple[float, float]:
        law = self.law
        assert law is not None
        phi, _, theta, _ = self.measured()
        phi_ref, twist_ref = switch_on_references(law.latch_code, phi, theta, law.K0)
        return float(phi_ref), float(twist_ref)

    def output_values(self) -> Mapping[str, Any]:
        law = self.law
        assert law is not None
        phi_ref, twist_ref = self.refs if self.latched else self._candidate_references()
        t_on = law.t_on if self.values["enabled"] else math.inf
        phi, dphi, theta, dtheta = self.measured()
        r = feedback_torque(
            self.time, phi, dphi, theta, dtheta, law.F, law.K0, law.R_ff, t_on, phi_ref,
            twist_ref,
        )  # fmt: skip
        return {self.OUTPUT: float(r)}

    def advance(self, t: float, h: float) -> fmu.StepResult:
        law = self.law
        assert law is not None
        if not self.latched and self.values["enabled"] and t >= law.t_on:
            self.refs, self.latched = self._candidate_references(), True
        return fmu.StepResult(t + h)

    # ----------------------------------------------------------------- native fast path
    _fast_block: fmu.FastPath | None = None
    #: 1.0: the law acts on the errors from the set point Omega0 (SI), 0.0: on the inputs.
    FAST_SI = 0.0

    def fast_path(self) -> fmu.FastPath | None:
        # a subclass is served natively only if it says so (FAST_SI): it may compute otherwise
        if "FAST_SI" not in type(self).__dict__:
            return None
        if not native.AVAILABLE or self.law is None:
            return None
        if self._fast_block is None:
            step, outputs = native.controller_functions()
            inputs = [v.name for v in self.VARIABLES if v.causality == "input"]
            at = {name: native.CTRL_IN + i for i, name in enumerate(inputs)}
            io = np.zeros(native.CTRL_IO_SIZE)
            self._fast_block = fmu.FastPath(io, step, outputs, at, {self.OUTPUT: native.CTRL_OUT})
        return self._fast_block

    def fast_push(self, io: np.ndarray) -> None:
        law = self.law
        assert law is not None
        enabled = bool(self.values["enabled"])
        io[native.CTRL_SI] = self.FAST_SI
        io[native.CTRL_LATCHED] = float(self.latched)
        io[native.CTRL_REF : native.CTRL_REF + 2] = self.refs
        io[native.CTRL_ENABLED] = float(enabled)
        io[native.CTRL_TON] = law.t_on
        io[native.CTRL_TON_EFF] = law.t_on if enabled else math.inf
        io[native.CTRL_F : native.CTRL_F + 4] = law.F
        io[native.CTRL_K0] = law.K0
        io[native.CTRL_RFF] = law.R_ff
        io[native.CTRL_LATCH] = law.latch_code
        io[native.CTRL_OMEGA0] = getattr(law, "Omega0", 0.0)

    def fast_pull(self, io: np.ndarray) -> None:
        self.latched = bool(io[native.CTRL_LATCHED] != 0.0)
        self.refs = (float(io[native.CTRL_REF]), float(io[native.CTRL_REF + 1]))

    # ----------------------------------------------------------------- FMU state
    def save(self) -> tuple[dict[str, Any], Any, Callable[[], bytes]]:
        fields = {"latched": self.latched, "refs": list(self.refs), "law": self.law is not None}
        return fields, None, lambda: b""

    def restore(self, fields: Mapping[str, Any], snapshot: Any, payload: bytes | None) -> None:
        self.law = self.new_law(self.values) if fields["law"] else None
        self.latched, self.refs = bool(fields["latched"]), tuple(fields["refs"])
