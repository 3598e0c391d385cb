"""Digital control laws of the rotary-table torque R - R0: one abstraction, :class:`Law`.

A top-drive controller is a sampled law: at each sample instant it reads the measurements, puts
out a torque that is held until the next instant (zero-order hold) and updates its own state.
Every law here is a frozen dataclass of its parameters that declares them once, in its table
``PARAMETERS`` of :class:`Parameter` (name, dimension, meaning, range). From that table come

* the law's SI form: :meth:`Law.to_si` and :meth:`Law.from_si`, one conversion for every law,
  each parameter scaled by its dimension (:data:`drillstring.model.units.DIMENSIONS`, eqs.
  (15)-(16)); the feed-forward R_ff is a deviation from the nominal torque R0 in both unit
  systems (R_ff [N m] = C R_ff [scaled]);
* the variables of the controller FMUs (``fmu_src/drillstring_controller.py``), one script over
  a law class;
* the law's slots in the block the compiled code runs (:data:`PI_PARAMS`, :data:`AFFINE_PARAMS`
  in the section :data:`LAW_SLOTS`, written by :meth:`Law.pack`).

The evaluation is written once, below the declarations, in the subset numba compiles
(``jit_for``; plain Python without numba): the switch-on state, the output and the update of
each law kind (:func:`law_start`, :func:`law_output`, :func:`law_update`). A host runs a law
inside a :class:`~drillstring.model.digital.controller.DigitalController` (the law between a sensing
stage and a top drive): the controller FMUs, the sampled monolithic loop
(:func:`drillstring.model.sampled.simulate_sampled`) and a Python caller alike.

The laws (tuning rules: ``drillstring.controller.tuning`` and ``docs/controllers.md``):

* :class:`SpeedPI`: PI on the rotary-table speed, set point omega0 (stiff PI, SoftSpeed);
* :class:`ZTorque`: the same PI whose speed set point is lowered by the measured string torque,
  high-pass and low-pass filtered, divided by the string impedance (impedance matching);
* :class:`SampledAffine`: the paper's state feedback (29)-(31), the
  :class:`~drillstring.model.control.AffineFeedback` of the continuous monolithic solver
  evaluated at sample instants by the same :func:`~drillstring.model.control.feedback_torque`.

Everything is in the scaled form of the paper (time tau = t/t*, torques in units of C, angles in
rad, speeds d/dtau; all in perturbation form, eqs. (9)-(10), (13)). The string torque at the top
is the twist torque C*(Theta - Phi); its deviation from the nominal R0 is theta - phi in scaled
form.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

import numpy as np

from drillstring.model.control import (
    LATCH_MODES,
    AffineFeedback,
    feedback_torque,
    switch_on_references,
)
from drillstring.model.kernel.jit import jit_for
from drillstring.model.tables import (
    Parameter,
    Scales,
    Tabled,
    block_layout,
    check_names,
    parameter_slots,
)
from drillstring.validation import check_choice, check_real

__all__ = [
    "AFFINE_PARAMS",
    "AFFINE_STATE",
    "ANTI_WINDUP",
    "FEED_FORWARD_PARAMS",
    "LAW_AFFINE",
    "LAW_NONE",
    "LAW_PI",
    "LAW_SLOTS",
    "PI_PARAMS",
    "PI_STATE",
    "SATURATION",
    "FeedForward",
    "Law",
    "SampledAffine",
    "SpeedPI",
    "ZTorque",
    "feed_forward",
    "law_from_si",
    "law_output",
    "law_start",
    "law_state",
    "law_update",
    "preset",
]

#: The compiled law kinds (a law's ``KIND``, the block's code): the feed-forward alone, the PI
#: family on the table speed (stiff PI, SoftSpeed, Z-Torque), the paper's state feedback.
LAW_NONE = 0
LAW_PI = 1
LAW_AFFINE = 2

#: Anti-windup of the PI laws (their index is the block's code).
ANTI_WINDUP = ("none", "back-calculation", "conditional")
AW_BACK = ANTI_WINDUP.index("back-calculation")
AW_COND = ANTI_WINDUP.index("conditional")
#: What the affine law does while the top drive saturates (index: the block's code).
SATURATION = ("none", "freeze-angle")
SAT_FREEZE = SATURATION.index("freeze-angle")


_FEED_FORWARD = Parameter(
    "R_ff", "torque", "Feed-forward torque R_ff (eq. (31)): alone before t_on, the law's bias after"
)
_SWITCH_ON = Parameter("t_on", "time", "Switch-on time of the law: before it only R_ff acts")
_PI_GAINS = (
    Parameter("kp", "impedance", "Proportional gain of the speed PI (torque per speed)", 0.0),
    Parameter("ki", "stiffness", "Integral gain of the speed PI (torque per angle)", 0.0),
)
_WINDUP = (
    Parameter(
        "anti_windup",
        "1",
        "Anti-windup while the top drive limits the torque: none, back-calculation (the "
        "integral tracks the limited torque with time constant tracking_time) or conditional "
        "(the integral is held unless its error drives the torque back into range)",
        choices=ANTI_WINDUP,
    ),
    Parameter(
        "tracking_time",
        "time",
        "Tracking time constant of back-calculation; 0: the integral time kp/ki",
        0.0,
    ),
)

LawT = TypeVar("LawT", bound="Law")


class Law(Tabled):
    """What every law is: a frozen dataclass of the parameters of its ``PARAMETERS`` table.

    Subclasses define the table, their kind (the compiled law, ``KIND``) and :meth:`pack`; the
    feed-forward ``R_ff`` and the switch-on time ``t_on`` are parameters of every law.
    """

    KIND: ClassVar[int] = LAW_NONE
    R_ff: float
    t_on: float

    def replace(self: LawT, **changes: Any) -> LawT:
        """A validated copy with some parameters changed (names of the table)."""
        return type(self).from_values({**self.values(), **changes})

    def pack(self, b: np.ndarray, at: int) -> None:
        """Write the law into the controller's block ``b``, whose law section
        (:data:`LAW_SLOTS`) is at ``at``: its kind and its parameters (the switch-on time
        ``t_on`` is the controller's own entry)."""
        p = at + LAW_SLOTS.p
        b[at + LAW_SLOTS.kind] = self.KIND
        b[p : p + _N_P] = 0.0
        b[p + FEED_FORWARD_PARAMS.R_ff] = self.R_ff


def _tracking(kp: float, ki: float, tracking_time: float) -> float:
    """The back-calculation tracking time: given, else the integral time kp/ki, else 1."""
    if tracking_time > 0.0:
        return tracking_time
    return kp / ki if kp > 0.0 and ki > 0.0 else 1.0


# --------------------------------------------------------------------------------------------
# the PI family on the rotary-table speed
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SpeedPI(Law):
    """PI control of the rotary-table speed, set point omega0 (dtheta/dtau = 0).

    ``R - R0 = R_ff + kp*e + ki*I`` with the speed error ``e = -dtheta`` and ``I`` the sum of
    ``e*Ts`` over the samples since switch-on (forward Euler, as a drive's controller integrates).
    Bumpless transfer: at switch-on ``I`` is preset to ``-kp*e/ki``, so that the torque is
    continuous, ``R - R0 = R_ff`` at that instant, and the integrator then relaxes the speed
    error (with ``ki = 0`` there is no integrator to preset and the torque steps by ``kp*e``).
    While the top drive limits the torque the integral winds up unless ``anti_windup`` says
    otherwise. Stiff PI and SoftSpeed are this law with different gains
    (``drillstring.controller.tuning``); it is :class:`ZTorque` without torque feedback.

    Parameters
    ----------
    kp : float
        Proportional gain, >= 0 (units of C*t*: torque per speed; C*t* = sqrt(C*I1) is the
        impedance of the lumped string, 1 in scaled units).
    ki : float
        Integral gain, >= 0 (units of C: torque per angle).
    R_ff : float
        Feed-forward torque (31): alone before ``t_on``, the bias of the law after it.
    t_on : float
        Switch-on time (scaled).
    anti_windup : str
        One of :data:`ANTI_WINDUP`.
    tracking_time : float
        Tracking time of back-calculation (0: kp/ki).
    """

    kp: float
    ki: float
    R_ff: float = 0.0
    t_on: float = 0.0
    anti_windup: str = "back-calculation"
    tracking_time: float = 0.0

    KIND: ClassVar[int] = LAW_PI
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (*_PI_GAINS, _FEED_FORWARD, _SWITCH_ON,
                                                      *_WINDUP)  # fmt: skip

    def __post_init__(self) -> None:
        self._check_table()

    def pack(self, b: np.ndarray, at: int) -> None:
        """The compiled PI without torque feedback (``z_gain = 0``, filters at rest)."""
        _pack_pi(b, at, self, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ZTorque(Law):
    """Speed PI whose set point is lowered by the filtered string torque over the impedance.

    ``e = -dtheta - z_gain*y`` with ``y = LP(HP(torque))`` and ``R - R0 = R_ff + kp*e + ki*I``,
    ``I`` the sum of ``e*Ts``. The high-pass (corner ``omega_hp``) removes the mean drilling
    torque, so the mean table speed stays at the set point; the low-pass (corner ``omega_lp``)
    is the measurement filter. A stiff speed loop then makes the table speed follow
    ``-z_gain*torque/Z`` at the torsional frequencies: the top looks like a damper of impedance
    ``Z/z_gain`` to the string (Z = sqrt(C*I1) = 1 in scaled units), which absorbs the torsional
    waves when it matches the string's impedance, ``z_gain = 1``. Both filters are first order
    and discretised exactly for inputs held over a sample period. At switch-on the high-pass is
    at rest on the current torque (output 0), the low-pass at 0 and the integral preset for a
    continuous torque as in :class:`SpeedPI`. With ``z_gain = 0`` it is :class:`SpeedPI`, bit
    for bit (the same compiled law).

    Parameters
    ----------
    kp, ki : float
        Gains of the speed PI (as :class:`SpeedPI`), >= 0.
    z_gain : float
        Torque feedback gain in units of 1/Z (1: impedance matching), >= 0.
    omega_hp : float
        High-pass corner (rad per unit of scaled time), > 0 (default: the tuning of
        ``drillstring.controller.tuning.z_torque``).
    omega_lp : float
        Low-pass corner, > 0.
    R_ff, t_on, anti_windup, tracking_time
        As :class:`SpeedPI`.
    """

    kp: float
    ki: float
    z_gain: float = 1.0
    omega_hp: float = 0.3
    omega_lp: float = 10.0
    R_ff: float = 0.0
    t_on: float = 0.0
    anti_windup: str = "back-calculation"
    tracking_time: float = 0.0

    KIND: ClassVar[int] = LAW_PI
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        *_PI_GAINS,
        Parameter(
            "z_gain",
            "admittance",
            "Torque feedback of Z-Torque: speed set-point correction per string torque (1/Z: "
            "the lumped string's impedance matched); 0: the plain speed PI",
            0.0,
        ),
        Parameter("omega_hp", "frequency", "High-pass corner of the torque feedback", 0.0,
                     strict=True),
        Parameter("omega_lp", "frequency", "Low-pass corner of the torque feedback", 0.0,
                     strict=True),
        _FEED_FORWARD,
        _SWITCH_ON,
        *_WINDUP,
    )  # fmt: skip

    def __post_init__(self) -> None:
        self._check_table()

    def pack(self, b: np.ndarray, at: int) -> None:
        """The compiled PI with its torque feedback."""
        _pack_pi(b, at, self, self.z_gain, self.omega_hp, self.omega_lp)


def _pack_pi(
    b: np.ndarray, at: int, law: SpeedPI | ZTorque, z_gain: float, w_hp: float, w_lp: float
) -> None:
    Law.pack(law, b, at)
    p = at + LAW_SLOTS.p
    b[p + PI_PARAMS.kp] = law.kp
    b[p + PI_PARAMS.ki] = law.ki
    b[p + PI_PARAMS.z_gain] = z_gain
    b[p + PI_PARAMS.omega_hp] = w_hp
    b[p + PI_PARAMS.omega_lp] = w_lp
    b[p + PI_PARAMS.anti_windup] = ANTI_WINDUP.index(law.anti_windup)
    b[p + PI_PARAMS.tracking_time] = _tracking(law.kp, law.ki, law.tracking_time)


# --------------------------------------------------------------------------------------------
# the paper's law, sampled
# --------------------------------------------------------------------------------------------

_GAIN = tuple(f"F[{i}]" for i in range(1, 5))
_X = ("phi - phi_ref", "dphi", "phi - theta - K0 - twist_ref", "dtheta")


@dataclass(frozen=True)
class SampledAffine(Law):
    """The state feedback with feed-forward (29)-(31) of an AffineFeedback, at sample instants.

    The state is the pair of references (phi_ref, twist_ref) latched at switch-on by
    :func:`~drillstring.model.control.switch_on_references`; the output is
    :func:`~drillstring.model.control.feedback_torque` of the measured phi, dphi, theta, dtheta,
    the same function the continuous monolithic solver evaluates. While the top drive limits the
    torque, ``on_saturation = "freeze-angle"`` holds the bit-angle state x1 = phi - phi_ref (the
    angle reference moves with the bit), so that the law does not try to make up afterwards the
    revolutions the bit lost while the torque was limited (conditional integration of x1, the
    integral of the bit-speed error); ``"none"`` is the paper's law.

    Parameters
    ----------
    feedback : AffineFeedback
        Gain, K0, R_ff, t_on and latch of the law.
    on_saturation : str
        One of :data:`SATURATION`.
    torque_gain : float
        g: the law adds ``g*(torque + K0)``, the measured string torque at the top (what the
        sensing gives: ``Sensing(torque="motor")``, the motor torque less rho times the table's
        acceleration) less its steady value -K0. 0 (the default) is the paper's law; the string
        design (:mod:`drillstring.controller.string_design`) feeds it back to make the top
        absorb the pipe's waves.
    """

    feedback: AffineFeedback
    on_saturation: str = "none"
    torque_gain: float = 0.0

    KIND: ClassVar[int] = LAW_AFFINE
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        *(
            Parameter(name, dim, f"State-feedback gain on x{i + 1} = {x} (Theorem 1)")
            for i, (name, dim, x) in enumerate(
                zip(_GAIN, ("stiffness", "impedance", "stiffness", "impedance"), _X, strict=True)
            )
        ),
        Parameter("K0", "angle", "Nominal twist offset K0 of x3 (eqs. (29)-(30))"),
        _FEED_FORWARD,
        _SWITCH_ON,
        Parameter(
            "latch",
            "1",
            'Bumpless switch-on (docs/model.md, "Bumpless switch-on"): none (the paper\'s law), '
            "angle (phi_ref = phi at t_on), angle+twist (also twist_ref)",
            choices=LATCH_MODES,
        ),
        Parameter(
            "on_saturation",
            "1",
            "While the top drive limits the torque: none (the paper's law) or freeze-angle (x1 "
            "held, lost revolutions are not made up)",
            choices=SATURATION,
        ),
        Parameter(
            "torque_gain",
            "1",
            "Gain g on the measured string torque at the top less its steady value, "
            "g*(torque + K0) (0: the paper's law)",
        ),
    )

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "torque_gain", check_real("SampledAffine.torque_gain", self.torque_gain)
        )
        if not isinstance(self.feedback, AffineFeedback):
            raise TypeError(
                f"SampledAffine.feedback must be an AffineFeedback, got "
                f"{type(self.feedback).__name__}"
            )
        check_choice("SampledAffine.on_saturation", self.on_saturation, SATURATION)

    @property
    def R_ff(self) -> float:  # type: ignore[override]
        """Feed-forward torque (31) of the feedback (scaled, units of C)."""
        return self.feedback.R_ff

    @property
    def t_on(self) -> float:  # type: ignore[override]
        """Switch-on time of the feedback (scaled)."""
        return self.feedback.t_on

    def values(self) -> dict[str, Any]:
        """``F[1]`` ... ``F[4]``, ``K0``, ``R_ff``, ``t_on``, ``latch``, ``on_saturation``."""
        f = self.feedback
        return {
            **dict(zip(_GAIN, f.F, strict=True)),
            "K0": f.K0,
            "R_ff": f.R_ff,
            "t_on": f.t_on,
            "latch": f.latch,
            "on_saturation": self.on_saturation,
            "torque_gain": self.torque_gain,
        }

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> SampledAffine:
        """The law of ``F[1]`` ... ``F[4]`` and ``K0`` (required), ``R_ff`` and ``t_on``
        (default 0), ``latch`` (default "none"), ``on_saturation`` (default "none") and
        ``torque_gain`` (default 0)."""
        check_names(cls.__name__, cls.PARAMETERS, values)
        missing = [k for k in (*_GAIN, "K0") if k not in values]
        if missing:
            raise ValueError(f"SampledAffine: missing parameter(s) {missing}")
        feedback = AffineFeedback(
            F=tuple(values[k] for k in _GAIN),  # type: ignore[arg-type]
            K0=values["K0"],
            R_ff=values.get("R_ff", 0.0),
            t_on=values.get("t_on", 0.0),
            latch=values.get("latch", LATCH_MODES[0]),
        )
        return cls(
            feedback,
            on_saturation=values.get("on_saturation", SATURATION[0]),
            torque_gain=values.get("torque_gain", 0.0),
        )

    def pack(self, b: np.ndarray, at: int) -> None:
        """The compiled affine law: F, K0, R_ff, latch and saturation codes."""
        Law.pack(self, b, at)
        f = self.feedback
        p = at + LAW_SLOTS.p
        b[p + AFFINE_PARAMS.F : p + AFFINE_PARAMS.F + len(_GAIN)] = f.F
        b[p + AFFINE_PARAMS.K0] = f.K0
        b[p + AFFINE_PARAMS.latch] = f.latch_code
        b[p + AFFINE_PARAMS.on_saturation] = SATURATION.index(self.on_saturation)
        b[p + AFFINE_PARAMS.torque_gain] = self.torque_gain


@dataclass(frozen=True)
class FeedForward(Law):
    """The feed-forward alone: R - R0 = R_ff (the open loop of Figs. 5-6, eq. (31))."""

    R_ff: float = 0.0
    t_on: float = 0.0

    KIND: ClassVar[int] = LAW_NONE
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (_FEED_FORWARD, _SWITCH_ON)

    def __post_init__(self) -> None:
        self._check_table()


# --------------------------------------------------------------------------------------------
# the laws' slots in the controller's block, generated from their tables
# --------------------------------------------------------------------------------------------


def _kind_params(name: str, law: type[Law]) -> Any:
    """The ``p`` entries of a law kind: R_ff first (every kind has it), then the rest of the
    kind's table in its order; ``t_on`` is the controller's own entry (its switch-on)."""
    return block_layout(
        name, (("R_ff", 1), *parameter_slots(law.PARAMETERS, skip=("R_ff", "t_on")))
    )


#: The parameters of each kind, offsets in the law's ``p`` entries. :class:`SpeedPI` is the PI
#: kind of :class:`ZTorque`'s table with ``z_gain = 0`` (the same compiled law).
FEED_FORWARD_PARAMS = _kind_params("FeedForwardParams", FeedForward)
PI_PARAMS = _kind_params("PIParams", ZTorque)
AFFINE_PARAMS = _kind_params("AffineParams", SampledAffine)
#: The state of each kind, indices in the law's state tuple (its ``x`` entries): the PI's
#: integral of the speed error, the high-pass's internal low-pass and the filtered torque; the
#: affine law's latched references, its bit-angle state held while saturated and the hold flag.
PI_STATE = block_layout("PIState", (("integral", 1), ("z", 1), ("y", 1)))
AFFINE_STATE = block_layout(
    "AffineState", (("phi_ref", 1), ("twist_ref", 1), ("x1", 1), ("hold", 1))
)
_N_P = max(k.size for k in (FEED_FORWARD_PARAMS, PI_PARAMS, AFFINE_PARAMS))
_N_X = 4  # the compiled law's state is a tuple of this many floats
assert max(PI_STATE.size, AFFINE_STATE.size) <= _N_X
#: The law's section of the controller's block: the kind (``LAW_*``), the parameters of the
#: kind, the state.
LAW_SLOTS = block_layout("LawSlots", (("kind", 1), ("p", _N_P), ("x", _N_X)), state=("x",))


# --------------------------------------------------------------------------------------------
# the laws, compiled: on the block ``b`` whose law section (LAW_SLOTS) is at ``at``
# --------------------------------------------------------------------------------------------

inline = jit_for(__name__, inline=True)


@inline
def preset(kp: float, ki: float, e: float) -> float:
    """The integral that makes ``kp*e + ki*I = 0``: bumpless transfer of a PI law (0 without
    an integrator, ``ki = 0``)."""
    return -kp * e / ki if ki > 0.0 else 0.0


@inline
def feed_forward(b, at):
    """The law's feed-forward R_ff (31), what acts before its switch-on."""
    return b[at + LAW_SLOTS.p + FEED_FORWARD_PARAMS.R_ff]


@inline
def law_state(b, at):
    """The law's state as it is stored in its section (``x``)."""
    x = at + LAW_SLOTS.x
    return (b[x], b[x + 1], b[x + 2], b[x + 3])


@inline
def law_keep(b, at, x):
    """Store the law's state ``x`` in its section."""
    for i in range(_N_X):
        b[at + LAW_SLOTS.x + i] = x[i]


@inline
def law_start(b, at, theta, dtheta, torque, phi, dphi):
    """The law's state at switch-on from the measurements there (bumpless for each law).

    PI: the integral preset for a continuous torque (``ki*I = -kp*e`` with ``e = -dtheta``),
    the high-pass at rest on the current torque, the low-pass at 0. Affine: the references of
    the latch mode (``docs/model.md``, "Bumpless switch-on").
    """
    kind = int(b[at + LAW_SLOTS.kind])
    p = at + LAW_SLOTS.p
    if kind == LAW_PI:
        return (preset(b[p + PI_PARAMS.kp], b[p + PI_PARAMS.ki], -dtheta), torque, 0.0, 0.0)
    if kind == LAW_AFFINE:
        phi_ref, twist_ref = switch_on_references(
            int(b[p + AFFINE_PARAMS.latch]), phi, theta, b[p + AFFINE_PARAMS.K0]
        )
        return (phi_ref, twist_ref, 0.0, 0.0)
    return (0.0, 0.0, 0.0, 0.0)


@inline
def _gain(b, at):
    f = at + LAW_SLOTS.p + AFFINE_PARAMS.F
    return (b[f], b[f + 1], b[f + 2], b[f + 3])


@inline
def law_output(b, at, x, theta, dtheta, torque, phi, dphi):
    """R - R0 the law commands for the state ``x`` and the measurements (pure).

    PI: ``R_ff + kp*e + ki*I``, ``e = -dtheta - z_gain*y``; affine: (29)-(31) by
    :func:`~drillstring.model.control.feedback_torque`, plus ``g*(torque + K0)``; none: R_ff.
    """
    kind = int(b[at + LAW_SLOTS.kind])
    p = at + LAW_SLOTS.p
    R_ff = b[p + FEED_FORWARD_PARAMS.R_ff]
    if kind == LAW_PI:
        e = -dtheta - b[p + PI_PARAMS.z_gain] * x[PI_STATE.y]
        return R_ff + b[p + PI_PARAMS.kp] * e + b[p + PI_PARAMS.ki] * x[PI_STATE.integral]
    if kind == LAW_AFFINE:
        phi_ref = x[AFFINE_STATE.phi_ref]
        if x[AFFINE_STATE.hold] != 0.0:
            phi_ref = phi - x[AFFINE_STATE.x1]
        K0 = b[p + AFFINE_PARAMS.K0]
        r = feedback_torque(
            0.0, phi, dphi, theta, dtheta, _gain(b, at), K0, R_ff, 0.0, phi_ref,
            x[AFFINE_STATE.twist_ref],
        )  # fmt: skip
        g = b[p + AFFINE_PARAMS.torque_gain]
        if g != 0.0:  # the string torque's deviation from steady drilling (-K0), fed back
            r = r + g * (torque + K0)
        return r
    return R_ff


@inline
def law_update(b, at, x, theta, dtheta, torque, phi, dphi, Ts, r_cmd, r_lim):
    """The state one sample period ``Ts`` later, the measurements held over it.

    ``r_cmd`` is what the law commanded at the start of the period and ``r_lim`` what the top
    drive made of it (its limits; equal when nothing limited it): the anti-windup and the
    saturation behaviour of the affine law act only when they differ. PI: the integral by
    forward Euler (back-calculation: plus ``(r_lim - r_cmd)/(ki*tracking_time)``; conditional:
    only when the error drives the command back into range), both filters discretised exactly
    for the torque held over the sample.
    """
    kind = int(b[at + LAW_SLOTS.kind])
    p = at + LAW_SLOTS.p
    if kind == LAW_PI:
        ki = b[p + PI_PARAMS.ki]
        integral, z, y = x[PI_STATE.integral], x[PI_STATE.z], x[PI_STATE.y]
        e = -dtheta - b[p + PI_PARAMS.z_gain] * y
        aw = int(b[p + PI_PARAMS.anti_windup])
        if r_lim == r_cmd or ki <= 0.0:
            integral = integral + Ts * e
        elif aw == AW_BACK:
            integral = integral + Ts * (e + (r_lim - r_cmd) / (ki * b[p + PI_PARAMS.tracking_time]))
        elif aw == AW_COND:
            # integrate only when the error drives the command back into the range
            if (r_cmd > r_lim and e < 0.0) or (r_cmd < r_lim and e > 0.0):
                integral = integral + Ts * e
        else:
            integral = integral + Ts * e
        hp = torque - z
        a_hp = -math.expm1(-b[p + PI_PARAMS.omega_hp] * Ts)
        a_lp = -math.expm1(-b[p + PI_PARAMS.omega_lp] * Ts)
        return (integral, z + a_hp * (torque - z), y + a_lp * (hp - y), 0.0)
    if kind == LAW_AFFINE:
        if int(b[p + AFFINE_PARAMS.on_saturation]) != SAT_FREEZE:
            return x
        phi_ref, twist_ref = x[AFFINE_STATE.phi_ref], x[AFFINE_STATE.twist_ref]
        x1, hold = x[AFFINE_STATE.x1], x[AFFINE_STATE.hold]
        if r_lim != r_cmd:
            if hold == 0.0:
                return (phi_ref, twist_ref, phi - phi_ref, 1.0)
            return x
        if hold != 0.0:  # the saturation ended: the reference moves so that x1 goes on from x1
            return (phi - x1, twist_ref, 0.0, 0.0)
        return x
    return x


_LAW_CLASSES: dict[str, type[Law]] = {
    "SpeedPI": SpeedPI,
    "ZTorque": ZTorque,
    "SampledAffine": SampledAffine,
    "FeedForward": FeedForward,
}


def law_from_si(kind: str, scales: Scales, values: Mapping[str, Any]) -> Law:
    """A law from its SI parameters (``docs/controllers.md``, "SI form").

    Parameters
    ----------
    kind : str
        The class name: ``"SpeedPI"``, ``"ZTorque"``, ``"SampledAffine"`` or ``"FeedForward"``.
    scales : PhysicalParams or any object with ``C`` and ``t_star``
        The rig's scales (eqs. (15)-(16)).
    values : mapping
        The SI parameters, as the class's ``to_si`` returns them.

    Returns
    -------
    Law
        The law in scaled units.

    Raises
    ------
    ValueError
        ``kind`` is unknown, or the class's ``from_si`` rejects ``values``.
    TypeError
        ``scales`` lacks C or t_star.
    """
    if kind not in _LAW_CLASSES:
        raise ValueError(f"unknown law kind {kind!r} (known: {', '.join(_LAW_CLASSES)})")
    return _LAW_CLASSES[kind].from_si(scales, values)
