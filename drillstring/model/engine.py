"""The stepping engine of the scaled drill-string model (11)-(14) with contact (17).

:class:`Engine` owns the kernel's state (:class:`~drillstring.model.kernel.state.KernelState`:
current state, mode, history buffer, counters, control law) and drives the kernel
(:mod:`drillstring.model.kernel.stepper`) with ``advance(to_tau)``, which is what both the
monolithic solver and the plant FMU call. ``get_state``/``set_state`` capture everything for
rollback; ``serialize_state`` gives bytes (FMI serialized FMU state).
"""

from __future__ import annotations

import importlib.util
import io
import math
import numbers
import zipfile
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from types import ModuleType
from typing import Any, NamedTuple

import numpy as np

from drillstring.model.control import LATCH_MODES, AffineFeedback
from drillstring.model.experiments import DEFAULT_H
from drillstring.model.kernel import jit as _jit
from drillstring.model.kernel import state as S
from drillstring.model.kernel import stepper as _stepper_compiled
from drillstring.model.kernel.coordinates import to_perturbation, to_total
from drillstring.model.kernel.filippov import g_star, mode_at_zero_velocity
from drillstring.model.params import ScaledParams
from drillstring.model.pipe import StringParams, axial_chain, max_elements, torsional_chain
from drillstring.model.prehistory import (
    HistoryFunction,
    build_prehistory,
    nominal_history,
)
from drillstring.validation import check_choice, check_int, check_real

__all__ = [
    "Control",
    "Engine",
    "EngineOptions",
    "EngineState",
    "Event",
    "InitialState",
    "MODE_NAMES",
    "ON_INVALID_CHOICES",
    "OUTPUT_COLUMNS",
    "OUTPUT_KEYS",
    "Status",
    "stick_entries",
    "time_in_mode",
]

MODE_NAMES = {
    S.MODE_SLIP: "slip",
    S.MODE_STICK: "stick",
    S.MODE_UP: "up",
    S.MODE_TSTICK: "torsional_stick",
}
EVENT_KINDS = {
    S.EV_MODE: "mode",
    S.EV_BOUNCE: "bit_bounce",
    S.EV_BOUNCE_END: "bit_bounce_end",
    S.EV_SWITCH_ON: "switch_on",
    S.EV_TSTICK_STOP: "torsional_stick",
}
STATUS_CODES = {
    S.ST_OK: "ok",
    S.ST_TSTICK_OUT: "torsional_stick",
    S.ST_BOUNCE: "bit_bounce",
    S.ST_REVERSE: "reverse_rotation",
    S.ST_NONFINITE: "nonfinite",
    S.ST_DELAY: "delay_error",
    S.ST_ZENO: "zeno",
}
STATUS_TEXT = {
    S.ST_TSTICK_OUT: "torsional stick: outside the model (dPhi/dtau reached 0 with the "
    "torsional-stick model off)",
    S.ST_BOUNCE: "bit bouncing: depth of cut d < 0, outside the model",
    S.ST_REVERSE: "reverse rotation: twist torque below 0 during torsional stick",
    S.ST_NONFINITE: "non-finite state or torque",
    S.ST_DELAY: "the delay tau_n could not be found in the history (shorter than a step?)",
    S.ST_ZENO: "events accumulate without progress in time (Zeno behaviour)",
}
_STATUS_LIST = tuple(STATUS_CODES.values())
#: What the engine does when the bit bounces (``EngineOptions.on_invalid``), in this order (the
#: FMUs' Enumeration ``on_invalid`` has the item values 1, 2 in this order).
ON_INVALID_CHOICES = ("stop", "continue")
#: Columns of :meth:`Engine.sample` rows (time, perturbations, d, g, tau_n, applied R - R0, mode).
OUTPUT_COLUMNS = S.OUTPUT_COLUMNS
#: Keys of :meth:`Engine.outputs`: the columns without time, and the validity counters.
OUTPUT_KEYS = (*OUTPUT_COLUMNS[1:], "stick_events", "bit_bounce", "torsional_stick")

_PURE_STEPPER: ModuleType | None = None


def load_stepper(pure: bool) -> ModuleType:
    """The kernel stepper: compiled (if numba is available) or a plain-Python copy.

    The plain copy is the same source file loaded under another module name, so that a Python
    callable can serve as control law inside the integration loop; the model is written once.

    Parameters
    ----------
    pure : bool
        True for the plain-Python copy (what a Python callable control law needs), False for
        the compiled module.

    Returns
    -------
    ModuleType
        :mod:`drillstring.model.kernel.stepper` itself when ``pure`` is False or numba is not
        available (the module then runs as plain Python anyway); otherwise the plain-Python
        copy, loaded at the first such call and reused.
    """
    global _PURE_STEPPER
    if not pure or not _jit.numba_available():
        return _stepper_compiled
    if _PURE_STEPPER is None:
        path = Path(_stepper_compiled.__file__)
        name = "drillstring.model.kernel._stepper_pure"
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _PURE_STEPPER = module
    return _PURE_STEPPER


@dataclass(frozen=True)
class EngineOptions:
    """Integration options of the engine.

    Parameters
    ----------
    h : float
        Nominal RK4 step; each ``advance`` interval is split into equal steps no longer than h.
    torsional_stick : bool
        Model torsional stick (``docs/model.md``, "Torsional stick"); off: W = 0 stops the run.
    on_invalid : str
        ``"stop"`` or ``"continue"`` when the bit bounces (d < 0); "continue" counts episodes.
    freeze_torsion : bool
        Hold the bit at nominal speed (constant delay): the fast axial model (18).
    event_tol : float
        Time tolerance of event location, in (0, 1e-10].
    history_capacity, event_capacity : int
        Initial sizes of the history buffer (grown as needed) and of the event log (drained).
    keep_events : bool
        Keep the located events in :attr:`Engine.events` (the FMU does not).
    """

    h: float = DEFAULT_H
    torsional_stick: bool = False
    on_invalid: str = "stop"
    freeze_torsion: bool = False
    event_tol: float = 1e-13
    history_capacity: int = 2048
    event_capacity: int = 256
    keep_events: bool = True

    def __post_init__(self) -> None:
        check_real("EngineOptions.h", self.h, lower=0.0)
        check_choice("EngineOptions.on_invalid", self.on_invalid, ON_INVALID_CHOICES)
        check_real("EngineOptions.event_tol", self.event_tol, lower=0.0, upper=1e-10)
        for name in ("history_capacity", "event_capacity"):
            check_int(f"EngineOptions.{name}", getattr(self, name), lower=16)


@dataclass(frozen=True)
class InitialState:
    """Initial perturbation from the nominal motion at tau = 0 (the paper's u, phi, theta)."""

    u: float = 0.0
    du: float = 0.0
    phi: float = 0.0
    dphi: float = 0.0
    theta: float = 0.0
    dtheta: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(
                self, f.name, check_real(f"InitialState.{f.name}", getattr(self, f.name))
            )

    @classmethod
    def coerce(cls, value: InitialState | Mapping[str, float] | None) -> InitialState:
        """An InitialState from None (all 0), an InitialState or a mapping of its fields.

        Parameters
        ----------
        value : InitialState, mapping or None
            An InitialState (returned as it is), a mapping of some of the fields ``u, du, phi,
            dphi, theta, dtheta`` (the others 0), or None for the nominal motion (all 0).

        Returns
        -------
        InitialState
            The validated initial perturbation.

        Raises
        ------
        ValueError
            A key of the mapping is not a field, or a value is not a finite real number.
        """
        if value is None:
            return cls()
        if isinstance(value, InitialState):
            return value
        unknown = set(value) - {f.name for f in fields(cls)}
        if unknown:
            raise ValueError(f"unknown initial-state key(s) {sorted(unknown)}")
        return cls(**value)


@dataclass(frozen=True)
class Status:
    """Outcome of ``advance``: ``code`` is "ok" or the reason the run stopped."""

    code: str
    message: str
    tau: float

    @property
    def ok(self) -> bool:
        return self.code == "ok"


class Event(NamedTuple):
    """A located event: time, kind, axial modes before/after, V, g*, u and the running
    integral of g (over tau, from 0) at the event."""

    tau: float
    kind: str
    from_mode: str
    to_mode: str
    V: float
    gstar: float
    u: float
    g_integral: float


@dataclass
class EngineState:
    """Everything the engine needs to resume bit-exactly (the FMU state)."""

    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    n_events: int = 0


Control = float | AffineFeedback | Callable[[float, np.ndarray], float] | None


class Engine:
    """Stateful integrator of the delay-Filippov model; see the module docstring.

    Parameters
    ----------
    params : ScaledParams
        The scaled parameter set of (11)-(16).
    options : EngineOptions, optional
        Integration options.
    initial : InitialState or mapping, optional
        Perturbation at tau = 0 (default: the nominal motion).
    history : callable, optional
        Prehistory tau <= 0 -> (u, du, phi, dphi) (default: the nominal motion).
    control : optional
        Torque law R - R0, see :meth:`set_control`.
    string : StringParams, optional
        The drill pipe (``docs/model.md``, "The distributed string"); default: the paper's
        one-mode model, a massless spring (one element, the ``"paper"`` lumping).
    """

    def __init__(
        self,
        params: ScaledParams,
        options: EngineOptions | None = None,
        initial: InitialState | Mapping[str, float] | None = None,
        history: HistoryFunction | None = None,
        control: Control = None,
        string: StringParams | None = None,
    ) -> None:
        if not isinstance(params, ScaledParams):
            raise TypeError(f"params must be a ScaledParams, got {type(params).__name__}")
        if string is None:
            string = StringParams()
        if not isinstance(string, StringParams):
            raise TypeError(f"string must be a StringParams, got {type(string).__name__}")
        self.params = params
        self.string = string
        self.options = opt = options or EngineOptions()
        n_max = max_elements(string, params.rho, params.eta, opt.h)
        if string.elements > n_max:
            raise ValueError(
                f"string elements = {string.elements} is more than RK4 with h = {opt.h:g} "
                f"integrates stably here ({n_max}); use fewer elements or a smaller h"
            )
        init = InitialState.coerce(initial)
        p = params
        if opt.freeze_torsion and (init.dphi != 0.0 or init.phi != 0.0):
            raise ValueError(
                "freeze_torsion holds the bit at nominal speed: initial phi and dphi must be 0, "
                f"got phi={init.phi!r}, dphi={init.dphi!r}"
            )
        if p.omega0 + init.dphi <= 0.0:
            raise ValueError(
                f"initial dphi = {init.dphi!r} gives dPhi/dtau = {p.omega0 + init.dphi!r} <= 0: "
                "the model needs a rotating bit (torsional stick at tau = 0)"
            )
        H, n_nodes = build_prehistory(p, history or nominal_history, opt.h, opt.history_capacity)
        P = _parameter_array(p, string)
        nt, na = int(P[S.P_NT]), int(P[S.P_NA])
        s = S.allocate(H, opt.event_capacity, S.chain_columns(nt, na))
        s.params[:] = P
        self._params_tuple = tuple(s.params.tolist())  # for Python-side conversions
        s.options[S.O_H] = opt.h
        s.options[S.O_TSTICK] = float(opt.torsional_stick)
        s.options[S.O_CONTINUE] = float(opt.on_invalid == "continue")
        s.options[S.O_FREEZE] = float(opt.freeze_torsion)
        s.options[S.O_EVTOL] = opt.event_tol
        s.y[:] = to_total(
            s.params, 0.0, init.u, init.du, init.phi, init.dphi, init.theta, init.dtheta
        )
        s.chain[S.Z_NOW] = _initial_chain(p, nt, na, init)
        # the initial state joins the prehistory at tau = 0: a discontinuity node (a second node
        # at tau = 0 when the state jumps there, e.g. dphi(0) != 0 after a nominal past)
        last = n_nodes - 1
        rows = [S.H_U, S.H_V, S.H_PHI, S.H_W]
        if not np.array_equal(H[rows, last], s.y[[S.Y_U, S.Y_V, S.Y_PHI, S.Y_W]]):
            n_nodes += 1
            last += 1
            H[S.H_TAU, last] = 0.0
            H[rows, last] = s.y[[S.Y_U, S.Y_V, S.Y_PHI, S.Y_W]]
        H[S.H_FLAG, last] = 1.0
        s.ints[S.I_HEND] = n_nodes
        self._s = s
        self._events: list[Event] = []
        self._ext: Callable[..., float] | None = None
        self._stepper = _stepper_compiled
        self._failed: Status | None = None
        self.set_control(control, _initial=True)
        # initial axial mode from the sign of V, or from g* when V = 0 (Filippov)
        self._refresh_with_mode(S.MODE_SLIP)
        V = s.y[S.Y_V]
        if V > 0.0:
            mode = S.MODE_SLIP
        elif V < 0.0:
            mode = S.MODE_UP
        else:
            hook_side = 0.0 if na == 0 else s.chain[S.Z_NOW, 2 * nt + na - 1]
            mode = mode_at_zero_velocity(g_star(s.params, s.y[S.Y_U], s.diag[S.D_D], hook_side))
        st = self._refresh_with_mode(mode)
        if st != S.ST_OK:
            raise ValueError(f"invalid initial condition: {STATUS_TEXT.get(st, st)}")
        if s.diag[S.D_D] < 0.0:
            raise ValueError(
                f"invalid initial condition: depth of cut d = {s.diag[S.D_D]!r} < 0 (bit bouncing)"
            )

    # ----------------------------------------------------------------- control
    def set_control(self, control: Control, *, _initial: bool = False) -> None:
        """Set the torque law R - R0.

        Parameters
        ----------
        control : None, float, AffineFeedback or callable
            None: R - R0 = 0; a float: held constant; :class:`AffineFeedback`: the law
            (29)-(31) evaluated continuously in the compiled kernel; a callable
            ``f(tau, y) -> R - R0`` gets the perturbation state y = [u, du, phi, dphi, theta,
            dtheta] at every RK stage (plain-Python kernel: slower).
        """
        C = np.zeros(S.C_SIZE)
        ext = None
        if control is None:
            C[S.C_KIND] = S.CTRL_HELD
        elif isinstance(control, AffineFeedback):
            C[S.C_KIND] = S.CTRL_AFFINE
            C[S.C_TON] = control.t_on
            C[S.C_F0 : S.C_F0 + 4] = control.F
            C[S.C_K0] = control.K0
            C[S.C_RFF] = control.R_ff
            C[S.C_LATCH] = control.latch_code
        elif callable(control):
            C[S.C_KIND] = S.CTRL_EXTERNAL
            ext = self._wrap_callable(control)
        elif isinstance(control, numbers.Real) and not isinstance(control, bool):
            C[S.C_KIND] = S.CTRL_HELD
            C[S.C_R] = _number("torque R - R0", control)
        else:
            raise TypeError(
                "control must be None, a float, AffineFeedback or a callable, "
                f"got {type(control).__name__}"
            )
        self._s.control[:] = C
        self._ext = ext
        self._stepper = load_stepper(pure=ext is not None)
        if not _initial:
            self._refresh()

    def _wrap_callable(self, f: Callable[[float, np.ndarray], float]) -> Callable[..., float]:
        P = self._s.params

        def ext(
            tau: float, U: float, V: float, Phi: float, W: float, Theta: float, Wt: float
        ) -> float:
            y = np.array(to_perturbation(P, tau, U, V, Phi, W, Theta, Wt))
            return float(f(tau, y))

        return ext

    def set_input(self, r: float) -> None:
        """Hold the rotary-table torque deviation R - R0 = r over the following advances.

        R - R0 is the input of (13). A law set by :meth:`set_control` (an :class:`AffineFeedback`
        or a callable) is replaced by the held value. The kernel holds it
        (:func:`~drillstring.model.kernel.stepper.hold`, the first half of the held-input step
        the plant FMU runs): the derivative and diagnostics at the current state are recomputed
        only when it changed.

        Parameters
        ----------
        r : float
            Scaled torque deviation R - R0 (torques in units of C, eq. (16)).

        Raises
        ------
        ValueError
            ``r`` cannot be converted to a finite float.
        """
        value = _number("torque R - R0", r)
        if int(self._s.control[S.C_KIND]) != S.CTRL_HELD:
            self.set_control(value)
            return
        self._stepper.hold_from(*self._s, value)

    # ----------------------------------------------------------------- stepping
    def _refresh_with_mode(self, mode: int) -> int:
        self._s.ints[S.I_MODE] = mode
        return self._refresh()

    def _refresh(self) -> int:
        return int(self._stepper.refresh_from(*self._s, self._ext))

    def advance(self, to_tau: float) -> Status:
        """Integrate to ``to_tau``; events inside are located.

        Parameters
        ----------
        to_tau : float
            Target time, not before the current time.

        Returns
        -------
        Status
            "ok", or why the run stopped (it then stays stopped: every later call returns the
            same status).
        """
        to_tau = self._check_target(to_tau)
        if self._failed is not None:
            return self._failed
        keep = self.options.keep_events
        while True:
            st = int(self._stepper.advance_drained_from(*self._s, to_tau, keep, self._ext))
            status = self.finish(st)
            if status is not None:
                return status

    def sample(
        self, times: np.ndarray, rows: np.ndarray | None = None, nodes: np.ndarray | None = None
    ) -> tuple[np.ndarray, Status]:
        """Advance through the increasing ``times``, recording the outputs at each.

        The kernel fills the rows itself (no Python per sample).

        Parameters
        ----------
        times : array of float
            Increasing times, none before the current time.
        rows : array, optional
            Output buffer of shape (len(times), len(OUTPUT_COLUMNS)).
        nodes : array, optional
            Buffer of shape (len(times), columns of the chain) for the string's inner nodes at
            each time (total coordinates, :meth:`string_nodes`'s layout); None: not kept.

        Returns
        -------
        rows : array
            One row per time reached, columns :data:`OUTPUT_COLUMNS`; when the run stops early,
            only the rows up to the stop (the last one holding the state at the stop time).
        status : Status
            As :meth:`advance`.
        """
        times = np.ascontiguousarray(times, dtype=float)
        if times.ndim != 1 or times.size == 0:
            raise ValueError(
                f"sample: times must be a non-empty 1-D array, got shape {times.shape}"
            )
        if not np.all(np.isfinite(times)) or np.any(np.diff(times) < 0.0):
            raise ValueError("sample: times must be finite and increasing")
        self._check_target(times[0])
        if rows is None:
            rows = np.empty((times.size, S.OUT_SIZE))
        if nodes is None:
            nodes = np.empty((times.size, 0))
        elif nodes.shape != (times.size, self._s.chain.shape[1]):
            raise ValueError(
                f"sample: nodes must have shape {(times.size, self._s.chain.shape[1])}, "
                f"got {nodes.shape}"
            )
        if self._failed is not None:
            return rows[:0], self._failed
        i = 0
        while True:
            st, i = self._stepper.advance_sampled_from(
                *self._s, times, rows, nodes, i, times.size, self._ext
            )
            status = self.finish(int(st))
            if status is not None:
                return rows[:i], status

    def _check_target(self, to_tau: Any) -> float:
        to_tau = _number("advance: target time", to_tau)
        if to_tau < self.tau:
            raise ValueError(
                f"advance: target time {to_tau!r} is before the current time {self.tau!r}"
            )
        return to_tau

    def finish(self, st: int) -> Status | None:
        """What Python does after a kernel call on :meth:`kernel_arrays` returned ``st``.

        The event log is drained (into :attr:`events` if ``options.keep_events``); a full
        history buffer is grown.

        Parameters
        ----------
        st : int
            The kernel status (an ``ST_*`` code of :mod:`~drillstring.model.kernel.state`).

        Returns
        -------
        Status or None
            None when the kernel call must be made again (the event log was full, or the
            history buffer); otherwise the outcome, as :meth:`advance` returns it (a stop is
            kept: :attr:`failed`).
        """
        self._drain_events()
        if st == S.ST_EVLOG_FULL:
            return None
        if st == S.ST_HIST_FULL:
            self._grow_history()
            return None
        if st == S.ST_OK:
            return Status("ok", "", self.tau)
        code = STATUS_CODES.get(st, f"status_{st}")
        msg = f"{STATUS_TEXT.get(st, code)} at tau = {self.tau:.12g}"
        self._failed = Status(code, msg, self.tau)
        return self._failed

    def _grow_history(self) -> None:
        old = self._s.history
        H = np.zeros((old.shape[0], 2 * old.shape[1]))
        end = int(self._s.ints[S.I_HEND])
        H[:, :end] = old[:, :end]
        self._s = self._s._replace(history=H)

    def _drain_events(self) -> None:
        s = self._s
        n = int(s.ints[S.I_ENUM])
        if n == 0:
            return
        if self.options.keep_events:
            for row in s.events[:n]:
                self._events.append(
                    Event(
                        float(row[S.E_TAU]),
                        EVENT_KINDS[int(row[S.E_KIND])],
                        MODE_NAMES[int(row[S.E_FROM])],
                        MODE_NAMES[int(row[S.E_TO])],
                        float(row[S.E_V]),
                        float(row[S.E_GSTAR]),
                        float(row[S.E_U]),
                        float(row[S.E_GINT]),
                    )
                )
        s.ints[S.I_ENUM] = 0

    # ----------------------------------------------------------------- outputs
    @property
    def tau(self) -> float:
        """Current time (scaled)."""
        return float(self._s.clock[S.X_TAU])

    @property
    def g_integral(self) -> float:
        """Integral of the contact multiplier g over tau from 0 (RK4 quadrature)."""
        return float(self._s.clock[S.X_GINT])

    @property
    def mode(self) -> str:
        """Contact mode: "slip", "stick", "up" or "torsional_stick"."""
        return MODE_NAMES[int(self._s.ints[S.I_MODE])]

    @property
    def events(self) -> list[Event]:
        """The located events so far (if ``options.keep_events``)."""
        return list(self._events)

    @property
    def failed(self) -> Status | None:
        """The status that stopped the run, or None."""
        return self._failed

    @property
    def counters(self) -> dict[str, int]:
        """Steps, events, entries into axial stick, bit bouncing and torsional stick, and the RK4
        trials spent on event locations (mode events and delayed discontinuities)."""
        I = self._s.ints  # noqa: E741
        return {
            "steps": int(I[S.I_NSTEPS]),
            "events": int(I[S.I_NEVENTS]),
            "stick_events": int(I[S.I_NSTICK]),
            "bit_bounce_events": int(I[S.I_NBOUNCE]),
            "torsional_stick_events": int(I[S.I_NTSTICK]),
            "event_trials": int(I[S.I_NTRIALS]),
            "event_locations": int(I[S.I_NLOCATE]),
        }

    def total_state(self) -> np.ndarray:
        """[U, V, Phi, W, Theta, Wt] (total scaled coordinates) at the current time.

        Returns
        -------
        ndarray
            Shape (6,), a copy of the kernel's state (``docs/model.md``, "Coordinates").
        """
        return self._s.y.copy()

    def string_nodes(self) -> np.ndarray:
        """The string's inner nodes now (a copy of chain row ``Z_NOW``).

        Returns
        -------
        ndarray
            Total scaled coordinates: the inner torsional nodes' angles (table side first),
            their speeds, the inner axial nodes' positions (hook side first), their velocities;
            empty for the paper's one-mode model (:func:`string_profiles` reads it).
        """
        return self._s.chain[S.Z_NOW].copy()

    def diagnostics(self) -> dict[str, float]:
        """d, tau_n, g, g*, twist torque S, torque on bit T, applied R - R0 at the current time.

        Returns
        -------
        dict of str to float
            Scaled values: ``d`` depth of cut (5), ``tau_n`` delay (14), ``g`` contact multiplier
            (17), ``gstar`` its balancing value g*
            (``docs/model.md``, "Wearflat contact as a Filippov system"), ``twist_torque`` S and
            ``torque_on_bit`` T (``docs/model.md``, "Coordinates"; in torsional stick T is the
            torque that holds the bit, ``docs/model.md``, "Torsional stick"), ``R_minus_R0`` the
            torque deviation applied in (13).
        """
        D = self._s.diag
        return {
            "d": float(D[S.D_D]),
            "tau_n": float(D[S.D_TAUN]),
            "g": float(D[S.D_G]),
            "gstar": float(D[S.D_GSTAR]),
            "twist_torque": float(D[S.D_S]),
            "torque_on_bit": float(D[S.D_TOB]),
            "R_minus_R0": float(D[S.D_R]),
        }

    def outputs(self) -> dict[str, float]:
        """The outputs at the current time (:data:`OUTPUT_COLUMNS` without ``tau``) and the
        validity counters ``stick_events``, ``bit_bounce``, ``torsional_stick``.

        Returns
        -------
        dict of str to float
            Keys :data:`OUTPUT_KEYS` in order: the scaled perturbations u, du, phi, dphi, theta,
            dtheta, the depth of cut d, the contact multiplier g (17), the delay tau_n (14), the
            applied R - R0, the mode code (a key of :data:`MODE_NAMES`), and the numbers of entries
            into axial stick, of bit-bounce episodes and of torsional sticks; all as floats.
        """
        s = self._s
        row = np.empty(S.OUT_SIZE)
        self._stepper.write_sample(s, row)
        I = s.ints  # noqa: E741
        values = (*row[1:].tolist(), I[S.I_NSTICK], I[S.I_NBOUNCE], I[S.I_NTSTICK])
        return dict(zip(OUTPUT_KEYS, map(float, values), strict=True))

    # ----------------------------------------------------------------- state
    def get_state(self) -> EngineState:
        """Capture everything (history, mode, counters, control, latch) for a bit-exact restore.

        Returns
        -------
        EngineState
            Copies of the kernel's persistent arrays, the status that stopped the run (if any) and
            the number of kept events; restore it with :meth:`set_state`.
        """
        arrays = {name: getattr(self._s, name).copy() for name in S.PERSISTENT}
        failed = self._failed
        arrays["failed"] = np.array([-1.0 if failed is None else _STATUS_LIST.index(failed.code)])
        return EngineState(arrays=arrays, n_events=len(self._events))

    def set_state(self, state: EngineState) -> None:
        """Restore a state from :meth:`get_state` of an engine with the same parameters.

        Events kept after the capture are dropped. A state with a callable control law runs with
        this engine's callable (the state holds no Python objects).

        Parameters
        ----------
        state : EngineState
            As returned by :meth:`get_state`.

        Raises
        ------
        ValueError
            :meth:`check_state` refuses it (nothing is changed then).
        """
        self.check_state(state)
        a = state.arrays
        self._s = self._s._replace(**{name: a[name].copy() for name in S.PERSISTENT})
        kind = int(self._s.control[S.C_KIND])
        if kind != S.CTRL_EXTERNAL:
            self._ext = None
            self._stepper = load_stepper(pure=False)
        del self._events[state.n_events :]
        code = int(a["failed"][0])
        if code < 0:
            self._failed = None
        else:
            c = _STATUS_LIST[code]
            self._failed = Status(c, f"{c} (restored) at tau = {self.tau:.12g}", self.tau)

    def check_state(self, state: EngineState) -> None:
        """Check every array of ``state`` against this engine's layout, before anything is
        overwritten: the compiled kernel indexes its arrays without bounds checks, so a state
        that was not captured by :meth:`get_state` (forged bytes behind a recomputed checksum)
        must never reach it.

        Checked: each array present, an ``ndarray`` of its dtype (``ints`` int64, the rest
        float64) and shape (the history: ``H_ROWS`` rows, any number of columns); the parameters
        and options those of this engine; the index ranges (contact mode, control kind and latch,
        the live history window ``0 <= I_HSTART < I_HEND <= columns``, the look-up hint, the
        event count within the event log, the status codes); counters >= 0; the flags 0 or 1;
        the time, the control law's numbers and the live history finite, its time and bit angle
        non-decreasing; the state, the string's inner nodes, stages and diagnostics finite unless
        the state is one of a run that stopped.

        Raises
        ------
        ValueError
            Naming the array (and entry) that does not fit.
        """
        a = state.arrays
        if not isinstance(a, Mapping):
            raise ValueError(f"set_state: the state's arrays are a {type(a).__name__}")
        s = self._s
        for name in (*S.PERSISTENT, "failed"):
            x = a.get(name)
            if not isinstance(x, np.ndarray):
                raise ValueError(f"set_state: array {name!r} is missing or not an array")
            dtype = np.dtype(np.int64 if name == "ints" else np.float64)
            if x.dtype != dtype and not (name == "failed" and x.dtype == np.int64):
                raise ValueError(f"set_state: array {name!r} has dtype {x.dtype}, not {dtype}")
            if name == "history":
                if x.ndim != 2 or x.shape[0] != S.H_ROWS or x.shape[1] < 1:
                    raise ValueError(
                        f"set_state: array 'history' has shape {x.shape}, not ({S.H_ROWS}, n)"
                    )
                continue
            shape = (1,) if name == "failed" else getattr(s, name).shape
            if x.shape != shape:
                raise ValueError(f"set_state: array {name!r} has shape {x.shape}, not {shape}")
        if not np.array_equal(a["params"], s.params):
            raise ValueError("set_state: the state was captured with different parameters")
        if not np.array_equal(a["options"], s.options):
            raise ValueError("set_state: array 'options': the state was captured with different "
                             "engine options")  # fmt: skip
        code = float(a["failed"][0])
        if not (code == -1.0 or (code.is_integer() and 0 <= code < len(_STATUS_LIST))):
            raise ValueError(f"set_state: array 'failed' holds {code!r}, not a status code")
        n_events = state.n_events
        if not isinstance(n_events, numbers.Integral) or n_events < 0:
            raise ValueError(f"set_state: n_events = {n_events!r} is not a count")

        C = a["control"]
        kind, latch, active = (float(C[k]) for k in (S.C_KIND, S.C_LATCH, S.C_ACTIVE))
        if kind not in (S.CTRL_HELD, S.CTRL_AFFINE, S.CTRL_EXTERNAL):
            raise ValueError(f"set_state: control[C_KIND] = {kind!r} is not a control kind")
        if kind == S.CTRL_EXTERNAL and self._ext is None:
            raise ValueError("set_state: the state uses a callable control law this engine lacks")
        if latch not in range(len(LATCH_MODES)):
            raise ValueError(f"set_state: control[C_LATCH] = {latch!r} is not a latch mode")
        if active not in (0.0, 1.0):
            raise ValueError(f"set_state: control[C_ACTIVE] = {active!r} is neither 0 nor 1")
        rest = np.delete(C, [S.C_KIND, S.C_LATCH, S.C_ACTIVE, S.C_TON])
        if not np.isfinite(rest).all() or math.isnan(C[S.C_TON]):
            raise ValueError("set_state: array 'control' holds non-finite numbers")
        if not np.isfinite(a["clock"]).all():
            raise ValueError("set_state: array 'clock' holds non-finite numbers")
        if code == -1.0:  # a run that stopped may hold what stopped it
            if not np.isfinite(a["chain"][S.Z_NOW : S.Z_KNOW + 1]).all():
                raise ValueError("set_state: array 'chain' holds non-finite numbers")
            for name in ("y", "diag", "stages"):
                if not np.isfinite(a[name]).all():
                    raise ValueError(f"set_state: array {name!r} holds non-finite numbers")

        I = a["ints"]  # noqa: E741
        H = a["history"]
        cols = H.shape[1]
        start, end = int(I[S.I_HSTART]), int(I[S.I_HEND])
        if not 0 <= start < end <= cols:
            raise ValueError(
                f"set_state: the live history window ints[I_HSTART:I_HEND] = [{start}, {end}) "
                f"does not lie in the {cols} column(s) of array 'history'"
            )
        ranges = {
            "I_MODE": (S.I_MODE, 0, len(MODE_NAMES) - 1),
            "I_KHINT": (S.I_KHINT, -1, end),
            "I_BOUNCING": (S.I_BOUNCING, 0, 1),
            "I_ENUM": (S.I_ENUM, 0, s.events.shape[0] - 1),
            "I_STATUS": (S.I_STATUS, 0, S.ST_ZENO),
        }
        for what in ("I_NSTEPS", "I_NEVENTS", "I_NSTICK", "I_NBOUNCE", "I_NTSTICK", "I_NTRIALS",
                     "I_NLOCATE"):  # fmt: skip
            ranges[what] = (getattr(S, what), 0, np.iinfo(np.int64).max)
        for what, (k, lo, hi) in ranges.items():
            if not lo <= int(I[k]) <= hi:
                raise ValueError(f"set_state: ints[{what}] = {int(I[k])} is not in [{lo}, {hi}]")
        live = H[:, start:end]
        if not np.isfinite(live).all():
            raise ValueError("set_state: the live columns of array 'history' hold non-finite "
                             "numbers")  # fmt: skip
        if (np.diff(live[S.H_TAU]) < 0.0).any() or (np.diff(live[S.H_PHI]) < 0.0).any():
            raise ValueError("set_state: the live columns of array 'history' are not ordered in "
                             "time and bit angle")  # fmt: skip

    def serialize_state(self) -> bytes:
        """The state as bytes (numpy .npz, no pickle).

        Returns
        -------
        bytes
            The arrays of :meth:`get_state` and the event count as an ``.npz`` archive, for
            :meth:`deserialize_state` (the FMU's serialized state).
        """
        s = self.get_state()
        buf = io.BytesIO()
        np.savez(buf, n_events=np.array([s.n_events]), **s.arrays)
        return buf.getvalue()

    def deserialize_state(self, data: bytes) -> None:
        """Restore from :meth:`serialize_state` bytes.

        Parameters
        ----------
        data : bytes
            An archive written by :meth:`serialize_state`.

        Raises
        ------
        ValueError
            ``data`` is not an ``.npz`` archive without pickled objects, lacks one of the arrays,
            or is refused by :meth:`set_state`.
        """
        try:
            with zipfile.ZipFile(io.BytesIO(data)) as archive:  # no member larger than the bytes
                unpacked = sum(member.file_size for member in archive.infolist())
            if unpacked > len(data):
                raise ValueError(f"its members unpack to {unpacked} bytes from {len(data)}")
            with np.load(io.BytesIO(data), allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except Exception as exc:
            raise ValueError(f"deserialize_state: not an engine state ({exc})") from exc
        missing = [k for k in (*S.PERSISTENT, "failed", "n_events") if k not in arrays]
        if missing:
            raise ValueError(f"deserialize_state: missing arrays {missing}")
        count = arrays.pop("n_events")
        if count.shape != (1,) or count.dtype.kind not in "iu":
            raise ValueError(f"deserialize_state: array 'n_events' is {count.dtype} {count.shape}")
        self.set_state(EngineState(arrays=arrays, n_events=int(count[0])))

    # ----------------------------------------------------------------- other callers of the kernel
    # (the plant FMU's step, drillstring.model.native; with finish() after each of its calls)
    def kernel_arrays(self) -> S.KernelState:
        """The kernel's arrays themselves (not copies), for a caller that runs the kernel on
        them (and then :meth:`finish`). Valid until the next call of a method of this engine:
        the history buffer grows and :meth:`set_state` replaces the arrays.

        Returns
        -------
        KernelState
            The live arrays, in :class:`~drillstring.model.kernel.state.KernelState` order.
        """
        return self._s


def stick_entries(events: Iterable[Event]) -> list[Event]:
    """The entries into axial stick among ``events`` (slip or moving up -> stick).

    Parameters
    ----------
    events : iterable of Event
        Located events, e.g. :attr:`Engine.events`.

    Returns
    -------
    list of Event
        The "mode" events whose new mode is "stick", in the order given.
    """
    return [e for e in events if e.kind == "mode" and e.to_mode == "stick"]


def time_in_mode(
    events: Iterable[Event], mode: str, t0: float, t1: float, mode_at_t0: str
) -> float:
    """Time spent in contact ``mode`` over [t0, t1], exact from the mode events.

    Parameters
    ----------
    events : iterable of Event
        Events in time order (other kinds than "mode" are ignored).
    mode : str
        A name of :data:`MODE_NAMES`.
    t0, t1 : float
        The window.
    mode_at_t0 : str
        The mode just before t0 (an event at t0 itself is applied).

    Returns
    -------
    float
        The total time in ``mode`` inside the window.
    """
    current, t_prev, total = mode_at_t0, t0, 0.0
    for e in events:
        if e.kind != "mode" or e.tau < t0:
            continue
        if e.tau > t1:
            break
        if current == mode:
            total += e.tau - t_prev
        current, t_prev = e.to_mode, e.tau
    if current == mode:
        total += t1 - t_prev
    return total


def string_profiles(
    params: ScaledParams, string: StringParams, data: Mapping[str, np.ndarray], nodes: np.ndarray
) -> dict[str, np.ndarray]:
    """The string along its length at each sample: nodes' angles and speeds, elements' torques.

    Parameters
    ----------
    params : ScaledParams
        The scaled set.
    string : StringParams
        The string the run integrated.
    data : mapping
        The run's columns ``tau, u, du, phi, dphi, theta, dtheta`` (perturbations, one row per
        sample).
    nodes : ndarray
        The inner nodes at each sample, shape (samples, chain columns), as :meth:`Engine.sample`
        records them (total coordinates).

    Returns
    -------
    dict of str to ndarray
        Scaled values, one row per sample: ``x_node`` (N + 1 positions along the pipe, 0 at the
        table, 1 at the bit), ``phi_node`` and ``dphi_node`` (angle and speed perturbations of
        the nodes, table first, bit last), ``x_element`` (the N elements' midpoints) and
        ``torque_minus_R0`` (each element's torque less the nominal R0, in units of C; the first
        is what a sub at the top of the string measures); ``x_axial``, ``u_node``, ``du_node``
        for the axial nodes (hook first, its perturbation 0).
    """
    tors = torsional_chain(string, params.rho)
    ax = axial_chain(string, params.eta)
    nt, na = tors.elements - 1, ax.elements - 1
    tau = np.asarray(data["tau"])[:, None]
    inner_phi = nodes[:, :nt] - params.omega0 * tau
    inner_w = nodes[:, nt : 2 * nt] - params.omega0
    phi = np.hstack([data["theta"][:, None], inner_phi, data["phi"][:, None]])
    dphi = np.hstack([data["dtheta"][:, None], inner_w, data["dphi"][:, None]])
    base = 2 * nt
    inner_u = nodes[:, base : base + na] - params.v0 * tau
    inner_du = nodes[:, base + na : base + 2 * na] - params.v0
    zero = np.zeros_like(tau)
    u = np.hstack([zero, inner_u, data["u"][:, None]])
    du = np.hstack([zero, inner_du, data["du"][:, None]])
    return {
        "x_node": np.linspace(0.0, 1.0, nt + 2),
        "phi_node": phi,
        "dphi_node": dphi,
        "x_element": (np.arange(nt + 1) + 0.5) / (nt + 1),
        "torque_minus_R0": tors.stiffness * (phi[:, :-1] - phi[:, 1:]),
        "x_axial": np.linspace(0.0, 1.0, na + 2),
        "u_node": u,
        "du_node": du,
    }


def _number(name: str, value: Any) -> float:
    """``value`` as a finite float (anything ``float`` converts), or ValueError naming it."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    return check_real(name, x)


def _initial_chain(p: ScaledParams, nt: int, na: int, init: InitialState) -> np.ndarray:
    """The string's inner nodes at tau = 0 (row ``Z_NOW``), in total coordinates.

    Perturbations interpolated linearly along the string, in angle and speed, from the table
    (theta, dtheta) to the bit (phi, dphi), and axially from the hook (0) to the bit (u, du):
    the quasi-static shape of a twist and a stretch, the same for every N (``docs/model.md``,
    "The distributed string").
    """
    z = np.zeros(S.chain_columns(nt, na))
    for i in range(1, nt + 1):
        x = i / (nt + 1)  # from the table (0) to the bit (1)
        z[i - 1] = (1.0 - x) * init.theta + x * init.phi
        z[nt + i - 1] = p.omega0 + (1.0 - x) * init.dtheta + x * init.dphi
    base = 2 * nt
    for i in range(1, na + 1):
        x = i / (na + 1)
        z[base + i - 1] = x * init.u
        z[base + na + i - 1] = p.v0 + x * init.du
    return z


def _parameter_array(p: ScaledParams, string: StringParams | None = None) -> np.ndarray:
    """The kernel's parameter array (``P_*``) of a scaled parameter set and a string."""
    tors = torsional_chain(string or StringParams(), p.rho)
    ax = axial_chain(string or StringParams(), p.eta)
    P = np.zeros(S.P_SIZE)
    P[S.P_N] = p.n
    P[S.P_PSI] = p.psi
    P[S.P_GAMMA] = p.gamma
    P[S.P_ETA] = p.eta
    P[S.P_LAM] = p.lam
    P[S.P_BETA] = p.beta
    P[S.P_RHO] = p.rho
    P[S.P_V0] = p.v0
    P[S.P_OMEGA0] = p.omega0
    P[S.P_TAUN0] = p.tau_n0
    P[S.P_D0] = p.d0
    P[S.P_NPSI] = p.n * p.psi
    P[S.P_BLADE] = 2.0 * math.pi / p.n
    P[S.P_R0] = p.R0
    P[S.P_KT] = tors.stiffness
    P[S.P_JT] = tors.inertia[0]
    P[S.P_JB] = tors.inertia[-1]
    P[S.P_JI] = tors.inertia[1] if tors.elements > 1 else 0.0
    P[S.P_KA] = ax.stiffness
    P[S.P_MB] = ax.inertia[-1]
    P[S.P_MI] = ax.inertia[1] if ax.elements > 1 else 0.0
    P[S.P_NT] = tors.elements - 1
    P[S.P_NA] = ax.elements - 1
    return P
