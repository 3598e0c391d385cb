"""What a digital controller knows of the string: the sensing settings (``docs/controllers.md``,
"Sensing").

:class:`Sensing` says how the downhole bit angle and speed reach the law (exact; by mud-pulse
or wired telemetry at a frame period with latency and noise; or estimated at the surface by an
:class:`Observer`) and how the string torque at the top is known (the twist, as from a torque
sub; or from the motor torque and the table acceleration). The compiled model is
:mod:`drillstring.model.digital.sense`; the observer's gains are designed by
:func:`drillstring.controller.estimation.design_observer` (the model layer only holds numbers).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from drillstring.model.digital import layout as L
from drillstring.model.tables import Parameter, Scales, table_from_si, table_to_si
from drillstring.validation import check_choice, check_int, check_real

__all__ = ["DOWNHOLE", "TORQUE", "Observer", "Sensing"]

#: How the law gets the bit angle and speed (index: the block's code).
DOWNHOLE = ("ideal", "telemetry", "observer")
#: How the law gets the string torque at the top (index: the block's code).
TORQUE = ("twist", "motor")


@dataclass(frozen=True)
class Observer:
    """A discrete Kalman filter on the linearised averaged torsional model (13), (27).

    State ``x = [phi, dphi, x3, dtheta]`` with ``x3 = phi - theta - K0`` (the state of (29)),
    measurements ``y = [dtheta, x3]`` (x3 from the string torque the controller knows), input
    ``u = R - R0 + K0``: the prior of the next sample is ``Ad x + Bd u``, the estimate at a
    sample ``x + M (y - C x)``.

    Parameters
    ----------
    Ad : array (4, 4)
        Discrete system matrix over the sample period ``Ts``.
    Bd : array (4,)
        Discrete input column.
    M : array (4, 2)
        Filter gain.
    K0 : float
        K0 of the model (29)-(30).
    Ts : float
        The sample period the matrices are discretised with (scaled); the controller must be
        sampled with it.
    """

    Ad: np.ndarray
    Bd: np.ndarray
    M: np.ndarray
    K0: float
    Ts: float

    def __post_init__(self) -> None:
        for name, shape in (("Ad", (4, 4)), ("Bd", (4,)), ("M", (4, 2))):
            a = np.array(getattr(self, name), dtype=float)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise ValueError(f"Observer.{name} must be finite of shape {shape}, got {a!r}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "K0", check_real("Observer.K0", self.K0))
        object.__setattr__(self, "Ts", check_real("Observer.Ts", self.Ts, lower=0.0))


@dataclass(frozen=True)
class Sensing:
    """How the controller's measurements are made.

    Parameters
    ----------
    downhole : str
        One of :data:`DOWNHOLE`: the bit angle and speed exact ("ideal"), by telemetry, or
        estimated from surface signals ("observer", needs ``observer``).
    period : float
        Telemetry frame period (scaled time), > 0.
    latency : float
        Telemetry latency (scaled time), >= 0, at most ``(N_FRAMES - 2)*period``.
    noise_phi, noise_dphi : float
        Standard deviations of the noise on the transmitted bit angle and speed, >= 0.
    seed : int
        Seed of the telemetry noise, in [0, 2**32).
    torque : str
        One of :data:`TORQUE`: the string torque at the top exact ("twist") or from the motor
        torque and the table acceleration ("motor").
    observer : Observer or None
        The observer of ``downhole = "observer"``.
    """

    downhole: str = "ideal"
    period: float = 1.0
    latency: float = 0.0
    noise_phi: float = 0.0
    noise_dphi: float = 0.0
    seed: int = 0
    torque: str = "twist"
    observer: Observer | None = field(default=None, compare=False)

    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter(
            "downhole",
            "1",
            "How the law gets the bit angle and speed: ideal, telemetry (frames with latency "
            "and noise), or observer (estimated from surface signals)",
            choices=DOWNHOLE,
        ),
        Parameter("period", "time", "Telemetry frame period", 0.0, strict=True),
        Parameter("latency", "time", "Telemetry latency (frame taken to frame used)", 0.0),
        Parameter("noise_phi", "angle", "Noise (standard deviation) of the transmitted angle", 0.0),
        Parameter(
            "noise_dphi", "speed", "Noise (standard deviation) of the transmitted speed", 0.0
        ),
        Parameter("seed", "1", "Seed of the telemetry noise", 0.0),
        Parameter(
            "torque",
            "1",
            "How the law gets the string torque at the top: twist (measured, e.g. a torque sub) "
            "or motor (motor torque minus table inertia times its acceleration)",
            choices=TORQUE,
        ),
    )

    def __post_init__(self) -> None:
        check_choice("Sensing.downhole", self.downhole, DOWNHOLE)
        check_choice("Sensing.torque", self.torque, TORQUE)
        for p in self.PARAMETERS:
            if not p.choices and p.name != "seed":
                object.__setattr__(self, p.name, p.check("Sensing", getattr(self, p.name)))
        seed = check_int("Sensing.seed", self.seed, lower=0, integral_floats=True)
        if seed >= 2**32:
            raise ValueError(f"Sensing.seed must be below 2**32, got {self.seed!r}")
        object.__setattr__(self, "seed", seed)
        if self.latency > (L.N_FRAMES - 2) * self.period:
            raise ValueError(
                f"Sensing.latency = {self.latency!r} is more than {L.N_FRAMES - 2} frame periods "
                f"({self.period!r}): the controller keeps {L.N_FRAMES} frames"
            )
        if self.downhole == "observer" and not isinstance(self.observer, Observer):
            raise ValueError("Sensing.downhole = 'observer' needs an Observer (observer=...)")

    def values(self) -> dict[str, Any]:
        """The settings by name (scaled; the observer excluded)."""
        return {p.name: getattr(self, p.name) for p in self.PARAMETERS}

    def to_si(self, scales: Scales) -> dict[str, Any]:
        """The settings in SI units (s, rad, rad/s), each scaled by its dimension.

        Parameters
        ----------
        scales : PhysicalParams or any object with ``C`` and ``t_star``
            The rig's scales.

        Returns
        -------
        dict
            Name -> SI value.
        """
        return table_to_si(self.PARAMETERS, self.values(), scales)

    @classmethod
    def from_si(cls, scales: Scales, values: dict[str, Any]) -> Sensing:
        """The settings of SI values, the inverse of :meth:`to_si` (no observer).

        Raises
        ------
        ValueError
            An unknown name or a value :class:`Sensing` rejects.
        """
        scaled = table_from_si("Sensing.from_si", cls.PARAMETERS, values, scales)
        if "seed" in values:
            scaled["seed"] = values["seed"]
        return cls(**scaled)

    def pack(self, b: np.ndarray) -> None:
        """Write the settings (and the observer's numbers) into the block ``b``."""
        s = L.B_SN
        b[s : s + L.N_SN] = 0.0
        b[s + L.SN_MODE] = DOWNHOLE.index(self.downhole)
        b[s + L.SN_PERIOD] = self.period
        b[s + L.SN_LATENCY] = self.latency
        b[s + L.SN_NPHI] = self.noise_phi
        b[s + L.SN_NDPHI] = self.noise_dphi
        b[s + L.SN_SEED] = self.seed
        b[s + L.SN_TORQUE] = TORQUE.index(self.torque)
        o = self.observer
        if o is not None:
            b[s + L.SN_TS] = o.Ts
            b[s + L.SN_K0] = o.K0
            b[s + L.SN_AD : s + L.SN_AD + 16] = o.Ad.ravel()
            b[s + L.SN_BD : s + L.SN_BD + 4] = o.Bd
            b[s + L.SN_M : s + L.SN_M + 8] = o.M.ravel()
