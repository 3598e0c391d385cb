"""The options of each sweep study, typed: one frozen dataclass per study.

Each field is an option of the spec file's ``[options]`` table (``docs/sweeps.md``), its default
the study's; every value is checked on construction by the shared checks of
:mod:`drillstring.validation`, the error naming the option and the value
(``options.h must be > 0, got 0.0``). :class:`ControllerOptions` is also what
:func:`~drillstring.apps.sweep.studies.evaluate_controllers` takes for the Fig. 6-like
comparison: the industrial rules' choices travel as one :class:`~drillstring.controller.lineup.
Tuning` (the spec's ``impedance``, ``soft_speed``, ``z_matching``), built once when the spec is
read. Every class pickles (the sweep sends its options to the Dask workers).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from drillstring.analysis.severity import MIN_WINDOW_PERIODS, SLOWEST_PERIOD, check_window
from drillstring.controller.gains import GainsFile
from drillstring.controller.lineup import (
    FEEDFORWARD,
    MAP_CONTROLLERS,
    RIG_CONTROLLERS,
    Tuning,
)
from drillstring.controller.tuning import IMPEDANCES, SOFT_SPEED_RULES
from drillstring.model.control import LATCH_MODES
from drillstring.model.engine import ON_INVALID_CHOICES
from drillstring.model.sampled import sample_count
from drillstring.model.topdrive import BRAKING
from drillstring.validation import check_choice, check_int, check_real, check_str

__all__ = [
    "MAP_WINDOW",
    "TUNING_KEYS",
    "AxialOptions",
    "ClosedLoopOptions",
    "ControllerOptions",
    "OpenLoopOptions",
    "StudyOptions",
    "option_keys",
    "options_from_table",
    "options_table",
]

#: The late window of the controllers study's metrics (scaled time): :data:`~drillstring.
#: analysis.severity.MIN_WINDOW_PERIODS` periods of the slowest oscillation it classifies
#: (:data:`~drillstring.analysis.severity.SLOWEST_PERIOD`, the stick-slip): 35.
MAP_WINDOW = MIN_WINDOW_PERIODS * SLOWEST_PERIOD
#: The spec's options that make up :attr:`ControllerOptions.tuning`, in this order.
TUNING_KEYS = ("impedance", "soft_speed", "z_matching")


def _positive(name: str, value: Any) -> float:
    return check_real(name, value, lower=0.0)


def _at_least_zero(name: str, value: Any) -> float:
    return check_real(name, value, lower=0.0, strict=False)


def _choice(choices: tuple[str, ...]) -> Callable[[str, Any], str]:
    return lambda name, value: check_choice(name, value, choices)


def _controllers(name: str, value: Any) -> tuple[str, ...]:
    """A non-empty list of distinct names of RIG_CONTROLLERS, in its order."""
    known = RIG_CONTROLLERS
    if not isinstance(value, list | tuple) or not value:
        raise ValueError(f"{name} must be a non-empty list of names, got {value!r}")
    for k, item in enumerate(value):
        check_choice(f"{name}[{k}]", item, known)
    if len(set(value)) != len(value):
        raise ValueError(f"{name} lists a controller twice: {list(value)!r}")
    return tuple(c for c in known if c in value)


#: The check of each option, by name: the value returned is the one kept.
_RULES: dict[str, Callable[[str, Any], Any]] = {
    **dict.fromkeys(("h", "dt_out", "window", "tol", "kick", "lam_over_vbar0", "Ts"), _positive),
    **dict.fromkeys(("tie", "vibration_tol", "min_periods"), _at_least_zero),
    **dict.fromkeys(("dphi0", "t_on"), check_real),
    "dphi0_rel": lambda name, value: check_real(name, value, lower=-1.0),
    "gain_max": lambda name, value: None if value is None else _positive(name, value),
    **dict.fromkeys(("max_periods", "elements"), lambda n, v: check_int(n, v, lower=1)),
    "braking": _choice(BRAKING),
    "feedforward": _choice(FEEDFORWARD),
    "latch": _choice(LATCH_MODES),
    "on_invalid": _choice(ON_INVALID_CHOICES),
    "gains": check_str,
    "gains_constrained": lambda name, value: None if value is None else check_str(name, value),
    "top_drive": lambda name, value: check_str(name, value).strip().lower(),
    "controllers": _controllers,
}
#: Fields that are not options of the file: the gains files the spec reads.
_LOADED = {"loaded": True}


def _check(options: Any) -> None:
    """Check every option of ``options`` by :data:`_RULES`, keeping the checked value, and
    that the engine's step is within the output sampling."""
    for f in fields(options):
        if f.name in _RULES:
            value = _RULES[f.name](f"options.{f.name}", getattr(options, f.name))
            object.__setattr__(options, f.name, value)
    if hasattr(options, "dt_out") and options.h > options.dt_out:
        raise ValueError(
            f"options.h = {options.h!r} must not exceed options.dt_out = {options.dt_out!r}"
        )


@dataclass(frozen=True)
class OpenLoopOptions:
    """The open-loop study: engine step ``h``, initial dphi/dtau ``dphi0`` (the paper's -2.5),
    output sampling ``dt_out``."""

    h: float = 5e-4
    dphi0: float = -2.5
    dt_out: float = 1e-2

    def __post_init__(self) -> None:
        _check(self)


@dataclass(frozen=True)
class ClosedLoopOptions:
    """The closed-loop study: as the open loop, and ``gains`` ("design": LMI (33) at each point,
    or a gains file), ``gain_max`` (the design's bound on ||F||), ``feedforward`` (R_ff of the
    file, "file", or -K0 of (27) at the point, "point"), and the convergence criterion: the
    largest |dphi/dtau| over the late ``window`` below ``tol*|dphi0|``. ``gains_file``: the file
    read (set by the spec)."""

    h: float = 5e-4
    dphi0: float = -2.5
    dt_out: float = 1e-2
    gains: str = "design"
    gain_max: float | None = None
    feedforward: str = "file"
    window: float = 10.0
    tol: float = 0.05
    gains_file: GainsFile | None = field(default=None, compare=False, metadata=_LOADED)

    def __post_init__(self) -> None:
        _check(self)
        if self.dphi0 == 0.0:
            raise ValueError(
                "options.dphi0 must be nonzero for the closed-loop study (convergence is "
                "measured relative to the initial deviation), got 0.0"
            )


@dataclass(frozen=True)
class AxialOptions:
    """The axial study (:func:`~drillstring.analysis.limit_cycles.limit_cycle`): step ``h``,
    ``kick``, the period budget ``max_periods``, ``lam_over_vbar0``."""

    h: float = 1e-2
    kick: float = 0.05
    max_periods: int = 400
    lam_over_vbar0: float = 50.0

    def __post_init__(self) -> None:
        _check(self)


@dataclass(frozen=True)
class ControllerOptions:
    """How the controller lineup is evaluated at a point (the controllers study, the Fig. 6-like
    comparison).

    ``controllers``: which of :data:`~drillstring.controller.lineup.RIG_CONTROLLERS` run (in
    that order; :func:`~drillstring.apps.sweep.studies.evaluate_controllers` also takes the rows
    of :data:`~drillstring.controller.lineup.TIMED_CONTROLLERS` by name);
    ``top_drive``: the drive of every controller (a spec of
    :func:`~drillstring.model.topdrive.top_drive_from_spec`, or "none") and its ``braking``
    ("four-quadrant", or "none": the torque range [0, R_max]); ``elements``: the drill pipe's
    elements at each point of a sweep (1: the paper's one-mode model); ``h``: engine step;
    ``Ts``: sample period of the laws; ``dt_out``: output sampling (a multiple of ``Ts``);
    ``dphi0_rel``: a sweep point's dphi/dtau(0) as a fraction of omega0 (Fig. 5: -0.5);
    ``t_on``, ``latch``: switch-on of every law; ``window``: the late window of the metrics (the
    trend test compares it with the window before, both after ``t_on``), holding
    ``min_periods`` periods of the slowest oscillation (0: a quick run, not to be classified);
    ``gains``, ``gain_max``, ``feedforward``: a sweep's paper-style LMI gain as in the
    closed-loop study (``feedforward`` "point": K0 and R_ff of the point, shared by every law);
    ``gains_constrained``: the input-constrained design's gains file; ``tie``: severity
    difference treated as equal when ranking; ``vibration_tol``: severity below which a run is
    steady; ``on_invalid``: what the engine does when the bit bounces; ``tuning``: the
    industrial rules' choices (the spec's ``impedance`` "lumped" or "pipe" of the point's rig,
    ``soft_speed`` "two-mass" or "impedance", ``z_matching``). ``gains_file`` and
    ``constrained_file``: the files read (set by the spec).
    """

    controllers: tuple[str, ...] = MAP_CONTROLLERS
    top_drive: str = "tds-11sa"
    elements: int = 1
    braking: str = "four-quadrant"
    h: float = 5e-4
    Ts: float = 1e-3
    dt_out: float = 1e-2
    dphi0_rel: float = -0.5
    t_on: float = 0.0
    latch: str = "angle"
    window: float = MAP_WINDOW
    min_periods: float = MIN_WINDOW_PERIODS
    gains: str = "design"
    gains_constrained: str | None = None
    gain_max: float | None = None
    feedforward: str = "point"
    tie: float = 0.02
    vibration_tol: float = 0.05
    on_invalid: str = "stop"
    tuning: Tuning = field(default_factory=Tuning)
    gains_file: GainsFile | None = field(default=None, compare=False, metadata=_LOADED)
    constrained_file: GainsFile | None = field(default=None, compare=False, metadata=_LOADED)

    def __post_init__(self) -> None:
        _check(self)
        if not isinstance(self.tuning, Tuning):
            raise TypeError(f"options.tuning must be a Tuning, got {self.tuning!r}")
        if self.h > self.Ts:
            raise ValueError(f"options.h = {self.h!r} must not exceed options.Ts = {self.Ts!r}")
        sample_count(self.dt_out, self.Ts, "options.dt_out")
        try:
            check_window(self.window, periods=self.min_periods, where="options.window")
        except ValueError as exc:
            raise ValueError(f"{exc} (options.min_periods = {self.min_periods!r})") from None

    def check_run(self, tau_end: float) -> float:
        """``tau_end`` if a run to it can be evaluated with these options.

        Parameters
        ----------
        tau_end : float
            End of the run (scaled).

        Returns
        -------
        float
            ``tau_end``.

        Raises
        ------
        ValueError
            ``tau_end`` is not > 0 or not a multiple of ``Ts``, or the window and the one
            before it (the trend test) do not both follow the switch-on ``t_on`` (``t_on``
            outside [0, tau_end - 2 window]); the message names the value.
        """
        tau_end = check_real("tau_end", tau_end, lower=0.0)
        if self.window > tau_end:
            raise ValueError(f"options.window = {self.window!r} exceeds tau_end = {tau_end!r}")
        sample_count(tau_end, self.Ts, "tau_end")
        if not 0.0 <= self.t_on <= tau_end - 2.0 * self.window:
            raise ValueError(
                f"options.t_on = {self.t_on!r} must lie in [0, tau_end - 2 window] = "
                f"[0, {tau_end - 2.0 * self.window!r}]: the metrics' window and the one "
                "before it (the trend test) follow the switch-on"
            )
        return tau_end


#: Any study's options.
StudyOptions = OpenLoopOptions | ClosedLoopOptions | AxialOptions | ControllerOptions


def option_keys(cls: type) -> tuple[str, ...]:
    """The keys of the spec's ``[options]`` table of a study's options class.

    Parameters
    ----------
    cls : type
        One of the classes of :data:`StudyOptions`.

    Returns
    -------
    tuple of str
        Its fields, the tuning as :data:`TUNING_KEYS`, without the files the spec reads.
    """
    out: list[str] = []
    for f in fields(cls):
        if f.name == "tuning":
            out += TUNING_KEYS
        elif not f.metadata.get("loaded"):
            out.append(f.name)
    return tuple(out)


def options_from_table(cls: type, table: Mapping[str, Any]) -> StudyOptions:
    """The options of a spec's ``[options]`` table (its keys checked by the caller).

    Parameters
    ----------
    cls : type
        One of the classes of :data:`StudyOptions`.
    table : mapping
        Option name -> value; the study's default for a name not given.

    Returns
    -------
    StudyOptions

    Raises
    ------
    ValueError
        A bad value, named (``options.impedance must be one of 'lumped', 'pipe', got 'wave'``).
    """
    data = dict(table)
    if cls is ControllerOptions:
        choices = {k: data.pop(k) for k in TUNING_KEYS if k in data}
        if "impedance" in choices:
            check_choice("options.impedance", choices["impedance"], IMPEDANCES)
        if "soft_speed" in choices:
            check_choice("options.soft_speed", choices["soft_speed"], SOFT_SPEED_RULES)
        if "z_matching" in choices:
            choices["z_matching"] = _at_least_zero("options.z_matching", choices["z_matching"])
        data["tuning"] = Tuning(**choices)
    return cls(**data)


def options_table(options: StudyOptions) -> dict[str, Any]:
    """The options as the spec's ``[options]`` table (the inverse of
    :func:`options_from_table`), JSON-able, the tuning as :data:`TUNING_KEYS`; what ``spec.json``
    holds and ``--resume`` compares.

    Parameters
    ----------
    options : StudyOptions
        A study's options.

    Returns
    -------
    dict
        Every option by name; with a gains file read also ``gains_F``, ``gains_K0`` and
        ``gains_params_sha256`` (with a constrained one ``gains_constrained_F``, ...), so that
        a changed file does not pass as the same spec.
    """
    out: dict[str, Any] = {}
    for f in fields(options):
        value = getattr(options, f.name)
        if f.name == "tuning":
            out.update({k: value.values()[k] for k in TUNING_KEYS})
        elif not f.metadata.get("loaded"):
            out[f.name] = list(value) if isinstance(value, tuple) else value
    for prefix, gains in (
        ("gains", getattr(options, "gains_file", None)),
        ("gains_constrained", getattr(options, "constrained_file", None)),
    ):
        if gains is not None:
            out[f"{prefix}_F"] = list(gains.F)
            out[f"{prefix}_K0"] = gains.K0
            out[f"{prefix}_params_sha256"] = gains.params_sha256
    return out
