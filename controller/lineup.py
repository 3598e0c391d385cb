"""The controllers compared at an operating point: three industrial top-drive laws and the LMI law.

:func:`industrial_lineup` builds, for one parameter set, the stiff speed PI, SoftSpeed, Z-Torque
(tuned from the string by the rules of :mod:`drillstring.controller.tuning`, the choices a
:class:`Tuning` states); the paper's state feedback (29)-(31) takes the gain :func:`lmi_gain`
reads from a gains file or designs by Theorem 1 at the point. All four share the feed-forward
R_ff and the switch-on time, so that they start from the same state in the same way
(``docs/controllers.md``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillstring.controller.averaged import AveragedModel, delay_roots
from drillstring.controller.estimation import design_observer
from drillstring.controller.gains import GainsFile
from drillstring.controller.synthesis import synthesize
from drillstring.controller.tuning import (
    SOFT_SPEED_RULES,
    STRING_IMPEDANCES,
    Pipe,
    impedance,
    soft_speed,
    stiff_pi,
    z_torque,
)
from drillstring.model.control import AffineFeedback
from drillstring.model.digital.controller import DigitalController
from drillstring.model.laws import SampledAffine, SpeedPI, ZTorque
from drillstring.model.params import ScaledParams, known_rig
from drillstring.model.pipe import StringParams
from drillstring.model.sensing import Sensing
from drillstring.model.tables import Scales, scales_of
from drillstring.model.timing import Timing
from drillstring.model.topdrive import RPM, TopDrive
from drillstring.validation import check_choice, check_real

__all__ = [
    "CONSTRAINED_CONTROLLERS",
    "CONTROLLERS",
    "FEEDFORWARD",
    "INDUSTRIAL",
    "LmiGain",
    "MAP_CONTROLLERS",
    "MUD_PULSE_LATENCY_S",
    "MUD_PULSE_NOISE_DEG",
    "MUD_PULSE_NOISE_RPM",
    "MUD_PULSE_PERIOD_S",
    "MUD_PULSE_SEED",
    "RIG_CONTROLLERS",
    "SENSING",
    "TIMED_CONTROLLERS",
    "Tuning",
    "industrial_lineup",
    "lmi_gain",
    "rig_lineup",
    "sensing_note",
]

#: The laws, in the order of every table and figure.
CONTROLLERS = ("stiff-pi", "soft-speed", "z-torque", "lmi")
#: The surface-only (industrial) controllers of :data:`CONTROLLERS`.
INDUSTRIAL = CONTROLLERS[:3]
#: The digital controllers of a rig (:func:`rig_lineup`): the industrial laws with the string
#: torque from the motor, the paper's LMI design with exact downhole measurements, the
#: input-constrained design with exact measurements, by mud-pulse telemetry and from the
#: surface observer.
RIG_CONTROLLERS = (*INDUSTRIAL, "lmi", "lmi-constrained", "lmi-telemetry", "lmi-observer")
#: The controllers of :data:`RIG_CONTROLLERS` with the input-constrained design's gain.
CONSTRAINED_CONTROLLERS = RIG_CONTROLLERS[4:]
#: The controllers a map runs by default: the constrained LMI law with mud-pulse telemetry too
#: (it ends in reverse rotation early, 4 % of a point's time; the observer's row, a full run, is
#: left to the option).
MAP_CONTROLLERS = RIG_CONTROLLERS[:6]
#: Mud-pulse telemetry of the downhole bit angle and speed: a frame every 2 s, used 4 s after
#: it was taken (a few bits per second, seconds of latency; ``docs/controllers.md``).
MUD_PULSE_PERIOD_S = 2.0
MUD_PULSE_LATENCY_S = 4.0
#: The noise (standard deviations) of the transmitted bit angle [deg] and speed [rpm]: the
#: angle to the 2 degrees MWD tools resolve their tool face in, the speed to 1 rpm (a value of
#: 8 bits over 0-255 rpm, the sensor's error besides; ``docs/controllers.md``, "Sensing").
MUD_PULSE_NOISE_DEG = 2.0
MUD_PULSE_NOISE_RPM = 1.0
#: The seed of the telemetry noise: fixed, so that the comparison and the maps repeat exactly.
MUD_PULSE_SEED = 1
#: What each controller of :data:`RIG_CONTROLLERS` measures (:func:`rig_lineup`): the notes of
#: the maps and tables: the table speed, the string torque from the motor torque and the table's
#: acceleration, the bit angle and speed "exact downhole" (the paper's idealisation: no rig
#: measures them at every sample), by mud-pulse telemetry, or observed from surface signals.
SENSING = {
    "stiff-pi": "table speed",
    "soft-speed": "table speed",
    "z-torque": "speed, motor torque",
    "lmi": "exact downhole",
    "lmi-constrained": "exact downhole",
    "lmi-telemetry": f"mud pulse {MUD_PULSE_PERIOD_S:g} s, {MUD_PULSE_LATENCY_S:g} s late",
    "lmi-observer": "observer (surface)",
}
#: Where the LMI law's K0 and R_ff come from with a gains file: the file, or the point's (31).
FEEDFORWARD = ("file", "point")
#: The timing of a real drive (``docs/controllers.md``, "Timing of a real drive"): the rows of the
#: comparison whose controller computes at its own period [s] with one period of latency
#: (computation and fieldbus), by row name: (the controller of :data:`RIG_CONTROLLERS`, period
#: [s]). A row of this table is a controller of :func:`rig_lineup` with that
#: :class:`~drillstring.model.timing.Timing`.
TIMED_CONTROLLERS: dict[str, tuple[str, float]] = {
    f"{base}-{ms}ms": (base, ms / 1e3)
    for base in ("soft-speed", "z-torque", "lmi-constrained")
    for ms in (10, 20, 50)
}
SENSING.update(
    {
        name: f"{SENSING[base]}, {period * 1e3:g} ms + {period * 1e3:g} ms late"
        for name, (base, period) in TIMED_CONTROLLERS.items()
    }
)


def sensing_note(names: Sequence[str]) -> str:
    """What the controllers ``names`` measure (:data:`SENSING`), grouped: the note of a map or
    table that compares them ("sensing: stiff-pi, soft-speed: table speed; lmi: ...")."""
    groups: dict[str, list[str]] = {}
    for name in names:
        groups.setdefault(SENSING[name], []).append(name)
    return "sensing: " + "; ".join(f"{', '.join(n)}: {what}" for what, n in groups.items())


@dataclass(frozen=True)
class Tuning:
    """The choices of the industrial tuning rules (``docs/controllers.md``).

    Parameters
    ----------
    impedance : str
        The string impedance Z of the rules (:data:`~drillstring.controller.tuning.
        STRING_IMPEDANCES`): ``"lumped"`` (sqrt(C*I1), the model's), ``"pipe"`` (the simulated
        rig's drill pipe, J*sqrt(G*rho_steel)) or ``"string"`` (the simulated string's
        sqrt(kappa)), :func:`~drillstring.controller.tuning.impedance`.
    soft_speed : str
        SoftSpeed's proportional gain (:data:`~drillstring.controller.tuning.SOFT_SPEED_RULES`):
        ``"two-mass"`` (2*sqrt(rho)*Z) or ``"impedance"`` (Z).
    z_matching : float
        Z-Torque's fraction of full impedance matching (1; Simulator4nDOF: 0.25), >= 0.
    pipe : Pipe, optional
        The drill pipe of ``"pipe"`` (default: the known pipe of the simulated rig's string,
        :func:`~drillstring.controller.tuning.rig_pipe`).
    kappa : float, optional
        The simulated string's pipe inertia over I1 for ``"string"`` (Z = sqrt(kappa));
        :meth:`for_string` sets it from the string.
    """

    impedance: str = "lumped"
    soft_speed: str = "two-mass"
    z_matching: float = 1.0
    pipe: Pipe | None = None
    kappa: float | None = None

    @classmethod
    def for_string(cls, string: StringParams | None, z_matching: float = 1.0) -> Tuning:
        """The default tuning on ``string``: on the paper's one-mode string (or None) the
        lumped impedance with SoftSpeed's two-mass rule; on a distributed string the field
        rules on its own impedance sqrt(kappa): SoftSpeed's ``kp = Z``, Z-Torque matched to Z
        by the fraction ``z_matching`` (``docs/controllers.md``, "Field tunings on the
        string")."""
        if string is None or string.is_paper:
            return cls(z_matching=z_matching)
        return cls(impedance="string", soft_speed="impedance", z_matching=z_matching,
                   kappa=string.kappa)  # fmt: skip

    def __post_init__(self) -> None:
        check_choice("Tuning.impedance", self.impedance, STRING_IMPEDANCES)
        check_choice("Tuning.soft_speed", self.soft_speed, SOFT_SPEED_RULES)
        value = check_real("Tuning.z_matching", self.z_matching, lower=0.0, strict=False)
        object.__setattr__(self, "z_matching", value)
        if self.pipe is not None and not isinstance(self.pipe, Pipe):
            raise TypeError(f"Tuning.pipe must be a Pipe or None, got {self.pipe!r}")
        if self.kappa is not None:
            kappa = check_real("Tuning.kappa", self.kappa, lower=0.0)
            object.__setattr__(self, "kappa", kappa)
        elif self.impedance == "string":
            raise ValueError("Tuning.impedance = 'string' needs the string's kappa (kappa=)")

    def Z(self, rig: Scales | None = None) -> float:  # noqa: N802 - the rules' symbol
        """The impedance on the simulated ``rig``, scaled (units of its sqrt(C*I1)).

        Raises
        ------
        ValueError
            ``"pipe"`` without a rig, or for a rig whose pipe is neither given nor known.
        """
        return impedance(self.impedance, rig, self.pipe, kappa=self.kappa)

    def values(self) -> dict[str, Any]:
        """The choices by name (the pipe as its od, id, G and density, or None)."""
        pipe = None if self.pipe is None else dict(vars(self.pipe))
        out: dict[str, Any] = {
            "impedance": self.impedance,
            "soft_speed": self.soft_speed,
            "z_matching": self.z_matching,
            "pipe": pipe,
        }
        if self.kappa is not None:  # the string's kappa: only when given (the records before)
            out["kappa"] = self.kappa
        return out


@dataclass(frozen=True)
class LmiGain:
    """A gain of (29)-(31) for one averaged model: F, K0, R_ff and the closed loop's spectral
    abscissa at tau_n0 (the synthesis' certified one when designed)."""

    F: tuple[float, float, float, float]
    K0: float
    R_ff: float
    abscissa: float


def lmi_gain(
    model: AveragedModel,
    gains: GainsFile | None = None,
    *,
    feedforward: str = "file",
    gain_max: float | None = None,
    roots: bool = True,
) -> LmiGain:
    """The gain of the paper's law at a point: from ``gains`` or designed there (Theorem 1).

    Parameters
    ----------
    model : AveragedModel
        The averaged model (29)-(31) of the point.
    gains : GainsFile, optional
        A fixed design; None designs at the point by :func:`~drillstring.controller.synthesis.
        synthesize` (LMI (33)).
    feedforward : str
        With ``gains``: K0 and R_ff from the file ("file") or from the point's model ("point").
    gain_max : float, optional
        Bound on ||F|| of the design (default: the synthesis' own).
    roots : bool
        With ``gains``: compute the closed loop's spectral abscissa at tau_n0 (False: NaN, for
        callers that only need the gain).

    Returns
    -------
    LmiGain
    """
    check_choice("feedforward", feedforward, FEEDFORWARD)
    if gains is None:
        syn = synthesize(model) if gain_max is None else synthesize(model, gain_max=gain_max)
        F = np.asarray(syn.F, dtype=float).reshape(4)
        K0, R_ff = model.K0, model.R_ff
        abscissa = float(syn.certificate.abscissa_nominal)
    else:
        if gains.string_design is not None:
            raise ValueError(
                "the gains file is the string design (drillstring design --string-elements): its "
                "law also feeds back the string torque (torque_gain "
                f"{gains.string_design['torque_gain']:g}), which this affine law would drop"
            )
        F = np.asarray(gains.F, dtype=float)
        K0, R_ff = (gains.K0, gains.R_ff) if feedforward == "file" else (model.K0, model.R_ff)
        abscissa = float(delay_roots(model, F, None, 1)[0].real) if roots else math.nan
    gain = (float(F[0]), float(F[1]), float(F[2]), float(F[3]))
    return LmiGain(F=gain, K0=float(K0), R_ff=float(R_ff), abscissa=abscissa)


def industrial_lineup(
    params: ScaledParams,
    *,
    tuning: Tuning | None = None,
    R_ff: float = 0.0,
    t_on: float = 0.0,
    rig: Scales | None = None,
    string: StringParams | None = None,
) -> dict[str, SpeedPI | ZTorque]:
    """The industrial controllers of :data:`INDUSTRIAL` at ``params``, tuned by the rules of
    :mod:`drillstring.controller.tuning` with the ``tuning`` choices (default: the lumped
    string, SoftSpeed's two-mass rule, full matching); the default is also what the top-drive
    controller FMU is built with.

    Parameters
    ----------
    params : ScaledParams
        The operating point (rho).
    tuning : Tuning, optional
        The rules' choices.
    R_ff, t_on : float
        Feed-forward (31) and switch-on time of every law.
    rig : PhysicalParams or any object with C and t_star, optional
        The simulated rig, for the pipe's impedance (default: the known rig whose scaled set is
        ``params``, if any).
    string : StringParams, optional
        The simulated string: without ``tuning``, the default is :meth:`Tuning.for_string`
        (the field rules on its impedance when it is distributed).

    Returns
    -------
    dict
        Name -> law, in the order of :data:`INDUSTRIAL`.

    Raises
    ------
    ValueError
        ``tuning.impedance = "pipe"`` and no rig, or a rig whose pipe is not known.
    """
    tuning = Tuning.for_string(string) if tuning is None else tuning
    common = {"R_ff": R_ff, "t_on": t_on}
    if tuning.impedance == "pipe" and rig is None:
        rig = known_rig(params)
        if rig is None:
            raise ValueError(
                "Tuning.impedance = 'pipe': the parameter set is of no known rig; give the "
                "simulated rig (rig=) for its pipe's impedance"
            )
    Z = tuning.Z(rig)
    return {
        "stiff-pi": stiff_pi(params, **common),
        "soft-speed": soft_speed(params, rule=tuning.soft_speed, Z=Z, **common),
        "z-torque": z_torque(params, matching=tuning.z_matching, Z=Z, **common),
    }


def rig_lineup(
    params: ScaledParams,
    model: AveragedModel,
    *,
    paper: LmiGain,
    constrained: LmiGain | None,
    top_drive: TopDrive | None,
    scales: Scales,
    Ts: float,
    tuning: Tuning | None = None,
    t_on: float = 0.0,
    latch: str = "angle",
    names: Sequence[str] = RIG_CONTROLLERS,
    string: StringParams | None = None,
) -> dict[str, DigitalController]:
    """The digital controllers of :data:`RIG_CONTROLLERS` at ``params``, all with the same top
    drive (``docs/controllers.md``, "Fig. 6-like comparison").

    The industrial laws measure the string torque from the motor torque and the table
    acceleration (``Sensing(torque="motor")``: a rig has no torque sub at the top as a rule);
    ``lmi`` is the paper's design (Theorem 1) with exact bit angle and speed, the paper's
    assumption; ``lmi-constrained`` the input-constrained design
    (:mod:`drillstring.controller.constrained`) with exact measurements, ``lmi-telemetry`` with
    the bit angle and speed by mud-pulse telemetry (:data:`MUD_PULSE_PERIOD_S`,
    :data:`MUD_PULSE_LATENCY_S`, the noise of :data:`MUD_PULSE_NOISE_DEG` and
    :data:`MUD_PULSE_NOISE_RPM` seeded with :data:`MUD_PULSE_SEED`), ``lmi-observer`` with them
    estimated from the table speed and the motor torque
    (:func:`~drillstring.controller.estimation.design_observer`). The LMI laws
    hold their bit angle while the drive saturates (``on_saturation = "freeze-angle"``).

    Parameters
    ----------
    params : ScaledParams
        The operating point.
    model : AveragedModel
        Its averaged model (the observer's).
    paper, constrained : LmiGain
        The two LMI designs (``constrained`` None: its rows are left out).
    top_drive : TopDrive or None
        The limits of every controller.
    scales : PhysicalParams or any object with C and t_star
        The simulated rig's scales: the telemetry's seconds, the pipe's impedance.
    Ts : float
        Sample period of every controller (the observer is discretised with it).
    tuning : Tuning, optional
        The industrial rules' choices.
    t_on, latch : float, str
        Switch-on of every law; the LMI laws' latch.
    names : sequence of str
        The controllers wanted (a subset of :data:`RIG_CONTROLLERS` and of the rows of
        :data:`TIMED_CONTROLLERS`: their controller with its period and one period of latency,
        in seconds of ``scales``).
    string : StringParams, optional
        The simulated string, for the default tuning (:meth:`Tuning.for_string`).

    Returns
    -------
    dict
        Name -> DigitalController, in the order of ``names`` (the timed rows last).
    """
    unknown = sorted(set(names) - set(RIG_CONTROLLERS) - set(TIMED_CONTROLLERS))
    if unknown:
        raise ValueError(f"unknown controller(s) {unknown} (known: {', '.join(RIG_CONTROLLERS)})")
    _, t_star = scales_of(scales)
    timed = {n: TIMED_CONTROLLERS[n] for n in names if n in TIMED_CONTROLLERS}
    bases = [b for b, _ in timed.values() if b not in names]
    names = [n for n in names if n not in timed]
    surface = Sensing(torque="motor")
    laws = (
        industrial_lineup(
            params, tuning=tuning, R_ff=paper.R_ff, t_on=t_on, rig=scales, string=string
        )
        if any(name in INDUSTRIAL for name in names)
        else {}
    )
    out: dict[str, DigitalController] = {}

    def lmi(gain: LmiGain) -> SampledAffine:
        feedback = AffineFeedback(gain.F, gain.K0, gain.R_ff, t_on, latch)
        return SampledAffine(feedback, on_saturation="freeze-angle")

    for name in names:
        if name in INDUSTRIAL:
            out[name] = DigitalController(laws[name], top_drive, surface)
        elif name == "lmi":
            out[name] = DigitalController(lmi(paper), top_drive)
        elif constrained is not None:
            if name == "lmi-constrained":
                sensing = Sensing()
            elif name == "lmi-telemetry":
                sensing = Sensing(
                    downhole="telemetry",
                    period=MUD_PULSE_PERIOD_S / t_star,
                    latency=MUD_PULSE_LATENCY_S / t_star,
                    noise_phi=math.radians(MUD_PULSE_NOISE_DEG),
                    noise_dphi=MUD_PULSE_NOISE_RPM * RPM * t_star,
                    seed=MUD_PULSE_SEED,
                )
            else:
                observer = design_observer(model, Ts)
                sensing = Sensing(downhole="observer", observer=observer, torque="motor")
            out[name] = DigitalController(lmi(constrained), top_drive, sensing)
    if timed:
        # the controllers the timed rows are made of, also when they are not rows themselves
        extra = {} if not bases else rig_lineup(
            params, model, paper=paper, constrained=constrained, top_drive=top_drive,
            scales=scales, Ts=Ts, tuning=tuning, t_on=t_on, latch=latch,
            names=list(dict.fromkeys(bases)), string=string,
        )  # fmt: skip
        base = {**out, **extra}
        for name, (of, period) in timed.items():
            if of in base:
                P = period / t_star
                out[name] = dataclasses.replace(base[of], timing=Timing(period=P, latency=P))
    return out
