"""A digital controller: a control law between a sensing stage and the top drive.

:class:`DigitalController` is what every host runs (the controller FMUs, the sampled monolithic
loop :func:`drillstring.model.sampled.simulate_sampled`, a Python caller): a
:class:`~drillstring.model.laws.Law`, optionally a :class:`~drillstring.model.topdrive.TopDrive`
(its limits; None: the command is applied as it is) and a
:class:`~drillstring.model.sensing.Sensing` (default: exact measurements). :meth:`~
DigitalController.block` writes all of it into the block the compiled code runs
(:data:`~drillstring.model.digital.layout.BLOCK`), each part into its section;
:class:`Running` is a controller in operation for a Python caller, one sample at a time, on the
same compiled functions.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drillstring.model.digital.block import commit, sample
from drillstring.model.digital.layout import BLOCK, slot_names, state_offsets
from drillstring.model.laws import AFFINE_STATE, LAW_SLOTS, Law
from drillstring.model.params import ScaledParams
from drillstring.model.sensing import SENSING_SLOTS, Sensing
from drillstring.model.timing import Timing
from drillstring.model.topdrive import TOP_DRIVE_SLOTS, TopDrive
from drillstring.validation import check_real

__all__ = ["DigitalController", "OperatingPoint", "Running", "check_block"]


@dataclass(frozen=True)
class OperatingPoint:
    """The nominal motion a controller works about (scaled).

    Parameters
    ----------
    omega0 : float
        Nominal table speed (the speed set point), > 0.
    R0 : float
        Nominal table torque (absolute, units of C; eq. (8)), finite.
    rho : float
        Inertia ratio I2/I1 of the table (16), > 0 (for the torque estimated from the motor).
    """

    omega0: float
    R0: float
    rho: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "omega0", check_real("OperatingPoint.omega0", self.omega0,
                                                      lower=0.0))  # fmt: skip
        object.__setattr__(self, "R0", check_real("OperatingPoint.R0", self.R0))
        object.__setattr__(self, "rho", check_real("OperatingPoint.rho", self.rho, lower=0.0))

    @classmethod
    def of(cls, params: ScaledParams) -> OperatingPoint:
        """The operating point of a scaled parameter set: omega0, R0 of (8), rho."""
        if not isinstance(params, ScaledParams):
            raise TypeError(f"params must be a ScaledParams, got {type(params).__name__}")
        return cls(params.omega0, params.R0, params.rho)


@dataclass(frozen=True)
class DigitalController:
    """A sampled law with its sensing and its top drive.

    Parameters
    ----------
    law : Law
        The control law (its ``t_on`` is the switch-on time).
    top_drive : TopDrive or None
        The drive's limits (None: none).
    sensing : Sensing
        How the measurements are made.
    enabled : bool
        False: the feed-forward R_ff alone, always.
    timing : Timing
        The controller's own sample period and latency (default: the law at every sample of
        the host, no latency).
    """

    law: Law
    top_drive: TopDrive | None = None
    sensing: Sensing = field(default_factory=Sensing)
    enabled: bool = True
    timing: Timing = field(default_factory=Timing)

    def __post_init__(self) -> None:
        if not isinstance(self.law, Law):
            raise TypeError(f"law must be a Law, got {type(self.law).__name__}")
        if self.top_drive is not None and not isinstance(self.top_drive, TopDrive):
            raise TypeError(f"top_drive must be a TopDrive or None, got {self.top_drive!r}")
        if not isinstance(self.sensing, Sensing):
            raise TypeError(f"sensing must be a Sensing, got {type(self.sensing).__name__}")
        if not isinstance(self.enabled, bool):
            raise TypeError(f"enabled must be a bool, got {self.enabled!r}")
        if not isinstance(self.timing, Timing):
            raise TypeError(f"timing must be a Timing, got {type(self.timing).__name__}")

    def block(self, point: OperatingPoint | ScaledParams) -> np.ndarray:
        """The block of this controller at the operating point, at rest (nothing sampled yet).

        Parameters
        ----------
        point : OperatingPoint or ScaledParams
            The nominal motion (a parameter set gives its own).

        Returns
        -------
        ndarray
            float64 of ``BLOCK.size`` (:data:`~drillstring.model.digital.layout.BLOCK`),
            scaled connectors.
        """
        if isinstance(point, ScaledParams):
            point = OperatingPoint.of(point)
        if not isinstance(point, OperatingPoint):
            raise TypeError(f"point must be an OperatingPoint or ScaledParams, got {point!r}")
        b = np.zeros(BLOCK.size)
        b[BLOCK.resume] = -1.0
        b[BLOCK.t_star] = 1.0
        b[BLOCK.C] = 1.0
        b[BLOCK.enabled] = 1.0 if self.enabled else 0.0
        b[BLOCK.t_on] = self.law.t_on
        b[BLOCK.omega0] = point.omega0
        b[BLOCK.R0] = point.R0
        b[BLOCK.rho] = point.rho
        self.law.pack(b, BLOCK.law)
        if self.top_drive is not None:
            self.top_drive.pack(b, BLOCK.top_drive)
        self.sensing.pack(b, BLOCK.sensing)
        self.timing.pack(b, BLOCK.timing)
        return b

    def start(self, point: OperatingPoint | ScaledParams) -> Running:
        """The controller in operation from rest (see :class:`Running`)."""
        return Running(self, self.block(point))


class Running:
    """A digital controller in operation: its block, sampled one instant at a time.

    The measurements are the plant's scaled perturbations (phi, dphi, theta, dtheta) at the
    sample instant; :meth:`output` is pure, :meth:`step` commits the sample and moves the
    controller's state one period on (what an FMU's output getter and ``fmi2DoStep`` do).
    """

    def __init__(self, controller: DigitalController, block: np.ndarray) -> None:
        self.controller = controller
        self.block = block

    def output(
        self,
        tau: float,
        phi: float,
        dphi: float,
        theta: float,
        dtheta: float,
        top: float | None = None,
    ) -> float:
        """R - R0 the controller applies from the sample instant ``tau`` (pure); ``top`` is the
        string torque at the top less R0 (default: the one-mode string's twist theta - phi)."""
        top = float(theta) - float(phi) if top is None else float(top)
        return float(sample(self.block, float(tau), float(phi), float(dphi), float(theta),
                            float(dtheta), top)[0])  # fmt: skip

    def step(
        self,
        tau: float,
        phi: float,
        dphi: float,
        theta: float,
        dtheta: float,
        Ts: float,
        top: float | None = None,
    ) -> float:
        """Commit the sample ``tau`` and advance the state by ``Ts``; returns R - R0 applied.
        ``top`` as in :meth:`output`."""
        Ts = check_real("Ts", Ts, lower=0.0)
        top = float(theta) - float(phi) if top is None else float(top)
        return float(commit(self.block, float(tau), float(phi), float(dphi), float(theta),
                            float(dtheta), top, Ts))  # fmt: skip

    @property
    def law_state(self) -> tuple[float, ...]:
        """The law's state (its section's ``x``), meaningful once :attr:`active`."""
        x = BLOCK.law + LAW_SLOTS.x
        return tuple(self.block[x : x + LAW_SLOTS.size - LAW_SLOTS.x].tolist())

    @property
    def active(self) -> bool:
        """True once the law has been switched on."""
        return bool(self.block[BLOCK.active] != 0.0)

    @property
    def saturated(self) -> bool:
        """True when the top drive limited the command of the last committed sample."""
        return bool(self.block[BLOCK.saturated] != 0.0)

    @property
    def commanded(self) -> float:
        """The law's command R - R0 of the last committed sample."""
        return float(self.block[BLOCK.r_cmd])


#: Entries of the block that change while the controller runs besides its state: an FMU's io
#: entries and connectors.
_RUNTIME = ("stale", "resume", "time", "nsteps", "inputs", "output")
_SIZES = dict(BLOCK.SLOTS)
_SENSING = BLOCK.sensing
#: Entries that are 0 or 1, and counts (non-negative integers), by offset in the block.
_FLAGS = (
    BLOCK.stale,
    BLOCK.active,
    BLOCK.law + LAW_SLOTS.x + AFFINE_STATE.hold,
    BLOCK.top_drive + TOP_DRIVE_SLOTS.init,
    _SENSING + SENSING_SLOTS.prev,
    _SENSING + SENSING_SLOTS.observing,
    BLOCK.saturated,
)
_COUNTS = (BLOCK.nsteps, _SENSING + SENSING_SLOTS.taken, BLOCK.n_sat, BLOCK.n_samples)
_CHANGING = np.union1d(
    state_offsets(),
    np.concatenate([np.arange(getattr(BLOCK, n), getattr(BLOCK, n) + _SIZES[n]) for n in _RUNTIME]),
)
_FIXED = np.setdiff1d(np.arange(BLOCK.size), _CHANGING)
_NAME_AT = slot_names()


def check_block(saved: object, reference: np.ndarray) -> None:
    """Check a saved block (an FMU state's) against the block of the same controller at rest,
    ``reference``, before it replaces a running one: the compiled code indexes the block by its
    entries (telemetry frames by their count), so a block that was not saved by the controller
    (forged bytes behind a recomputed checksum) must never reach it.

    Checked: a float64 array of ``BLOCK.size`` entries; its parameter entries (law, top drive,
    sensing, operating point, unit system, switch-on) bit for bit those of ``reference``; its
    state and connector entries finite, its flags 0 or 1, its counts non-negative integers, and
    ``resume`` -1 or a non-negative integer.

    Raises
    ------
    ValueError
        Naming the entry (by its name in :data:`~drillstring.model.digital.layout.BLOCK`, a
        part's as ``part.entry``).
    """
    if not isinstance(saved, np.ndarray) or saved.dtype != np.float64:
        kind = getattr(saved, "dtype", type(saved).__name__)
        raise ValueError(f"the controller block is {kind}, not float64")
    if saved.shape != (BLOCK.size,):
        raise ValueError(f"the controller block holds {saved.size} entries, not {BLOCK.size}")
    differ = _FIXED[saved[_FIXED].view(np.int64) != reference[_FIXED].view(np.int64)]
    if differ.size:
        k = int(differ[0])
        raise ValueError(
            f"the controller block's parameter entry {_NAME_AT[k]} (block[{k}]) is "
            f"{float(saved[k])!r}, but this instance's parameters give {float(reference[k])!r}"
        )
    bad = _CHANGING[~np.isfinite(saved[_CHANGING])]
    if bad.size:
        k = int(bad[0])
        raise ValueError(f"the controller block's entry {_NAME_AT[k]} (block[{k}]) is "
                         f"{float(saved[k])!r}, not finite")  # fmt: skip
    for k in _FLAGS:
        if saved[k] not in (0.0, 1.0):
            raise ValueError(f"the controller block's entry {_NAME_AT[k]} (block[{k}]) is "
                             f"{float(saved[k])!r}, neither 0 nor 1")  # fmt: skip
    for k in (*_COUNTS, BLOCK.resume):
        x = float(saved[k])
        if not (x.is_integer() and (x >= 0.0 or (k == BLOCK.resume and x == -1.0))):
            raise ValueError(f"the controller block's entry {_NAME_AT[k]} (block[{k}]) is {x!r}, "
                             "not a count")  # fmt: skip
