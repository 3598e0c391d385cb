"""The stepping engine of the scaled drill-string model (11)-(14) with contact (17).

:class:`Engine` owns the state (current state, mode, history buffer, counters, control law) and
drives the kernel (:mod:`drillstring.model.kernel.stepper`) with ``advance(to_tau)``, which is what
both the monolithic solver and the plant FMU call. ``get_state``/``set_state`` capture
everything for rollback; ``serialize_state`` gives bytes (FMI serialized FMU state).
"""

from __future__ import annotations

import importlib.util
import io
import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from types import ModuleType
from typing import Any, NamedTuple

import numpy as np

from drillstring.model.control import LATCH_MODES, AffineFeedback
from drillstring.model.kernel import jit as _jit
from drillstring.model.kernel import layout as L
from drillstring.model.kernel import stepper as _stepper_compiled
from drillstring.model.kernel.filippov import g_star, mode_at_zero_velocity
from drillstring.model.params import ScaledParams
from drillstring.model.prehistory import (
    HistoryFunction,
    HistoryView,
    build_prehistory,
    nominal_history,
)

MODE_NAMES = {
    L.MODE_SLIP: "slip",
    L.MODE_STICK: "stick",
    L.MODE_UP: "up",
    L.MODE_TSTICK: "torsional_stick",
}
EVENT_KINDS = {
    L.EV_MODE: "mode",
    L.EV_BOUNCE: "bit_bounce",
    L.EV_BOUNCE_END: "bit_bounce_end",
    L.EV_SWITCH_ON: "switch_on",
    L.EV_TSTICK_STOP: "torsional_stick",
}
STATUS_CODES = {
    L.ST_OK: "ok",
    L.ST_TSTICK_OUT: "torsional_stick",
    L.ST_BOUNCE: "bit_bounce",
    L.ST_REVERSE: "reverse_rotation",
    L.ST_NONFINITE: "nonfinite",
    L.ST_DELAY: "delay_error",
    L.ST_ZENO: "zeno",
}
STATUS_TEXT = {
    L.ST_TSTICK_OUT: "torsional stick: outside the model (dPhi/dtau reached 0 with the "
    "torsional-stick model off)",
    L.ST_BOUNCE: "bit bouncing: depth of cut d < 0, outside the model",
    L.ST_REVERSE: "reverse rotation: twist torque below 0 during torsional stick",
    L.ST_NONFINITE: "non-finite state or torque",
    L.ST_DELAY: "the delay tau_n could not be found in the history (shorter than a step?)",
    L.ST_ZENO: "events accumulate without progress in time (Zeno behaviour)",
}
OUTPUT_NAMES = (
    "u",
    "du",
    "phi",
    "dphi",
    "theta",
    "dtheta",
    "d",
    "g",
    "tau_n",
    "mode",
    "stick_events",
    "bit_bounce",
    "torsional_stick",
)

_PURE_STEPPER: ModuleType | None = None


def load_stepper(pure: bool) -> ModuleType:
    """The kernel stepper: compiled (if numba is available) or a plain-Python copy.

    The plain copy is the same source file loaded under another module name, so that a Python
    callable can serve as control law inside the integration loop; the model is written once.
    """
    global _PURE_STEPPER
    if not pure or not _jit.numba_available():
        return _stepper_compiled
    if _PURE_STEPPER is None:
        path = Path(_stepper_compiled.__file__)
        spec = importlib.util.spec_from_file_location(
            "drillstring.model.kernel._stepper_pure", path
        )
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _PURE_STEPPER = module
    return _PURE_STEPPER


@dataclass(frozen=True)
class EngineOptions:
    """Integration options.

    h: nominal RK4 step (each ``advance`` interval is split into equal steps no longer than h).
    torsional_stick: model torsional stick (NOTES.md section 6); off: W = 0 stops the run.
    on_invalid: "stop" or "continue" when the bit bounces (d < 0); "continue" counts episodes.
    freeze_torsion: hold the bit at nominal speed (constant delay): the fast axial model (18).
    event_tol: time tolerance of event location.
    """

    h: float = 5e-4
    torsional_stick: bool = False
    on_invalid: str = "stop"
    freeze_torsion: bool = False
    event_tol: float = 1e-12
    history_capacity: int = 2048
    event_capacity: int = 256
    keep_events: bool = True

    def __post_init__(self) -> None:
        if not (isinstance(self.h, int | float) and math.isfinite(self.h) and self.h > 0):
            raise ValueError(f"EngineOptions.h must be a positive finite step, got {self.h!r}")
        if self.on_invalid not in ("stop", "continue"):
            raise ValueError(
                f"EngineOptions.on_invalid must be 'stop' or 'continue', got {self.on_invalid!r}"
            )
        if not (math.isfinite(self.event_tol) and 0 < self.event_tol <= 1e-10):
            raise ValueError(
                f"EngineOptions.event_tol must be in (0, 1e-10], got {self.event_tol!r}"
            )
        for name in ("history_capacity", "event_capacity"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 16:
                raise ValueError(f"EngineOptions.{name} must be an integer >= 16, got {v!r}")


@dataclass(frozen=True)
class InitialState:
    """Initial perturbation from the nominal motion at tau = 0 (paper's u, phi, theta)."""

    u: float = 0.0
    du: float = 0.0
    phi: float = 0.0
    dphi: float = 0.0
    theta: float = 0.0
    dtheta: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not (isinstance(v, int | float | np.floating) and math.isfinite(v)):
                raise ValueError(f"InitialState.{f.name} must be a finite number, got {v!r}")

    @classmethod
    def coerce(cls, value: InitialState | Mapping[str, float] | None) -> InitialState:
        if value is None:
            return cls()
        if isinstance(value, InitialState):
            return value
        unknown = set(value) - {f.name for f in fields(cls)}
        if unknown:
            raise ValueError(f"unknown initial-state key(s) {sorted(unknown)}")
        return cls(**{k: float(v) for k, v in value.items()})


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

_STATE_ARRAYS = ("P", "O", "C", "X", "Y", "I", "H", "D")


class Engine:
    """Stateful integrator of the delay-Filippov model; see the module docstring."""

    def __init__(
        self,
        params: ScaledParams,
        options: EngineOptions | None = None,
        initial: InitialState | Mapping[str, float] | None = None,
        history: HistoryFunction | None = None,
        control: Control = None,
    ) -> None:
        if not isinstance(params, ScaledParams):
            raise TypeError(f"params must be a ScaledParams, got {type(params).__name__}")
        self.params = params
        self.options = options or EngineOptions()
        init = InitialState.coerce(initial)
        opt = self.options
        p = params
        self._P = np.zeros(L.P_SIZE)
        self._P[L.P_N] = p.n
        self._P[L.P_PSI] = p.psi
        self._P[L.P_GAMMA] = p.gamma
        self._P[L.P_ETA] = p.eta
        self._P[L.P_LAM] = p.lam
        self._P[L.P_BETA] = p.beta
        self._P[L.P_RHO] = p.rho
        self._P[L.P_V0] = p.v0
        self._P[L.P_OMEGA0] = p.omega0
        self._P[L.P_TAUN0] = p.tau_n0
        self._P[L.P_D0] = p.d0
        self._P[L.P_NPSI] = p.n * p.psi
        self._P[L.P_BLADE] = 2.0 * math.pi / p.n
        self._P[L.P_R0] = p.R0
        self._O = np.zeros(L.O_SIZE)
        self._O[L.O_H] = opt.h
        self._O[L.O_TSTICK] = float(opt.torsional_stick)
        self._O[L.O_CONTINUE] = float(opt.on_invalid == "continue")
        self._O[L.O_FREEZE] = float(opt.freeze_torsion)
        self._O[L.O_EVTOL] = opt.event_tol
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
        self._H, n_nodes = build_prehistory(
            p, history or nominal_history, opt.h, opt.history_capacity
        )
        self._X = np.zeros(L.X_SIZE)
        self._Y = np.array(
            [
                init.u,
                p.v0 + init.du,
                init.phi,
                p.omega0 + init.dphi,
                init.theta,
                p.omega0 + init.dtheta,
            ]
        )
        self._I = np.zeros(L.I_SIZE, dtype=np.int64)
        # the initial state joins the prehistory at tau = 0: a discontinuity node (a second node
        # at tau = 0 when the state jumps there, e.g. dphi(0) != 0 after a nominal past)
        last = n_nodes - 1
        if not np.array_equal(self._H[1:5, last], self._Y[:4]):
            n_nodes += 1
            last += 1
            self._H[0, last] = 0.0
            self._H[1:5, last] = self._Y[:4]
        self._H[L.H_FLAG, last] = 1.0
        self._I[L.I_HEND] = n_nodes
        self._D = np.zeros(L.D_SIZE)
        self._E = np.zeros((opt.event_capacity, L.E_COLS))
        self._K = np.zeros((5, 6))
        self._W = np.zeros((9, max(6, L.D_SIZE)))
        self._C = np.zeros(L.C_SIZE)
        self._events: list[Event] = []
        self._n_events = 0
        self._ext: Callable[[float, np.ndarray], float] | None = None
        self._stepper = _stepper_compiled
        self._failed: Status | None = None
        self.set_control(control, _initial=True)
        # initial axial mode from the sign of V, or from g* when V = 0 (Filippov)
        st = self._refresh_with_mode(L.MODE_SLIP)
        if self._Y[1] > 0.0:
            mode = L.MODE_SLIP
        elif self._Y[1] < 0.0:
            mode = L.MODE_UP
        else:
            mode = mode_at_zero_velocity(g_star(self._P, 0.0, self._Y[0], self._D[L.D_D]))
        st = self._refresh_with_mode(mode)
        if st != L.ST_OK:
            raise ValueError(f"invalid initial condition: {STATUS_TEXT.get(st, st)}")
        if self._D[L.D_D] < 0.0:
            raise ValueError(
                f"invalid initial condition: depth of cut d = {self._D[L.D_D]!r} < 0 (bit bouncing)"
            )

    # ----------------------------------------------------------------- control
    def set_control(self, control: Control, *, _initial: bool = False) -> None:
        """Set the torque law: None (R - R0 = 0), a held float, AffineFeedback, or a callable.

        A callable ``f(tau, y) -> R - R0`` gets the perturbation state y = [u, du, phi, dphi,
        theta, dtheta] at every RK stage (continuous feedback, plain-Python kernel: slower).
        """
        C = np.zeros(L.C_SIZE)
        ext = None
        if control is None:
            C[L.C_KIND] = L.CTRL_HELD
        elif isinstance(control, AffineFeedback):
            C[L.C_KIND] = L.CTRL_AFFINE
            C[L.C_TON] = control.t_on
            C[L.C_F0 : L.C_F0 + 4] = control.F
            C[L.C_K0] = control.K0
            C[L.C_RFF] = control.R_ff
            C[L.C_LATCH] = LATCH_MODES.index(control.latch)
        elif callable(control):
            C[L.C_KIND] = L.CTRL_EXTERNAL
            ext = self._wrap_callable(control)
        elif isinstance(control, int | float | np.floating) and not isinstance(control, bool):
            C[L.C_KIND] = L.CTRL_HELD
            C[L.C_R] = self._check_torque(control)
        else:
            raise TypeError(
                "control must be None, a float, AffineFeedback or a callable, "
                f"got {type(control).__name__}"
            )
        self._C = C
        self._ext = ext
        self._stepper = load_stepper(pure=ext is not None)
        if not _initial:
            self._refresh()

    def _wrap_callable(self, f: Callable[[float, np.ndarray], float]) -> Callable:
        w0, v0 = self.params.omega0, self.params.v0
        y = np.zeros(6)

        def ext(tau: float, Y: np.ndarray) -> float:
            y[0] = Y[0] - v0 * tau
            y[1] = Y[1] - v0
            y[2] = Y[2] - w0 * tau
            y[3] = Y[3] - w0
            y[4] = Y[4] - w0 * tau
            y[5] = Y[5] - w0
            return float(f(tau, y.copy()))

        return ext

    @staticmethod
    def _check_torque(r: Any) -> float:
        try:
            value = float(r)
        except (TypeError, ValueError):
            raise ValueError(f"torque R - R0 must be a number, got {r!r}") from None
        if not math.isfinite(value):
            raise ValueError(f"torque R - R0 must be finite, got {r!r}")
        return value

    def set_input(self, r: float) -> None:
        """Hold the rotary-table torque deviation R - R0 = r over the following advances."""
        value = self._check_torque(r)
        if int(self._C[L.C_KIND]) != L.CTRL_HELD:
            self.set_control(value)
            return
        if value != self._C[L.C_R]:
            self._C[L.C_R] = value
            self._refresh()

    # ----------------------------------------------------------------- stepping
    def _call(self, name: str, *args: Any) -> int:
        fn = getattr(self._stepper, name)
        return int(fn(*args, self._ext))

    def _refresh_with_mode(self, mode: int) -> int:
        self._I[L.I_MODE] = mode
        return self._refresh()

    def _refresh(self) -> int:
        return self._call(
            "refresh",
            self._P,
            self._O,
            self._C,
            self._X,
            self._Y,
            self._I,
            self._H,
            self._D,
            self._K,
        )

    def advance(self, to_tau: float) -> Status:
        """Integrate to ``to_tau``; events inside are located. Returns the outcome."""
        try:
            to_tau = float(to_tau)
        except (TypeError, ValueError):
            raise ValueError(f"advance: target time must be a number, got {to_tau!r}") from None
        if not math.isfinite(to_tau):
            raise ValueError(f"advance: target time must be finite, got {to_tau!r}")
        if to_tau < self.tau:
            raise ValueError(
                f"advance: target time {to_tau!r} is before the current time {self.tau!r}"
            )
        if self._failed is not None:
            return self._failed
        while True:
            st = self._call(
                "advance",
                self._P,
                self._O,
                self._C,
                self._X,
                self._Y,
                self._I,
                self._H,
                self._D,
                self._E,
                self._K,
                self._W,
                to_tau,
            )
            self._drain_events()
            if st == L.ST_EVLOG_FULL:
                continue
            if st == L.ST_HIST_FULL:
                self._grow_history()
                continue
            break
        if st == L.ST_OK:
            return Status("ok", "", self.tau)
        code = STATUS_CODES.get(st, f"status_{st}")
        msg = f"{STATUS_TEXT.get(st, code)} at tau = {self.tau:.12g}"
        self._failed = Status(code, msg, self.tau)
        return self._failed

    def _grow_history(self) -> None:
        H = np.zeros((self._H.shape[0], 2 * self._H.shape[1]))
        end = int(self._I[L.I_HEND])
        H[:, :end] = self._H[:, :end]
        self._H = H

    def _drain_events(self) -> None:
        n = int(self._I[L.I_ENUM])
        if n == 0:
            return
        self._n_events += n
        if self.options.keep_events:
            for row in self._E[:n]:
                self._events.append(
                    Event(
                        float(row[L.E_TAU]),
                        EVENT_KINDS[int(row[L.E_KIND])],
                        MODE_NAMES[int(row[L.E_FROM])],
                        MODE_NAMES[int(row[L.E_TO])],
                        float(row[L.E_V]),
                        float(row[L.E_GSTAR]),
                        float(row[L.E_U]),
                        float(row[L.E_GINT]),
                    )
                )
        self._I[L.I_ENUM] = 0

    # ----------------------------------------------------------------- outputs
    @property
    def tau(self) -> float:
        return float(self._X[L.X_TAU])

    @property
    def g_integral(self) -> float:
        """Integral of the contact multiplier g over tau from 0 (RK4 quadrature)."""
        return float(self._X[L.X_GINT])

    @property
    def mode(self) -> str:
        return MODE_NAMES[int(self._I[L.I_MODE])]

    @property
    def events(self) -> list[Event]:
        return list(self._events)

    @property
    def failed(self) -> Status | None:
        return self._failed

    @property
    def counters(self) -> dict[str, int]:
        I = self._I  # noqa: E741
        return {
            "steps": int(I[L.I_NSTEPS]),
            "events": int(I[L.I_NEVENTS]),
            "stick_events": int(I[L.I_NSTICK]),
            "bit_bounce_events": int(I[L.I_NBOUNCE]),
            "torsional_stick_events": int(I[L.I_NTSTICK]),
            "event_trials": int(I[L.I_NREJECT]),
        }

    def history(self) -> HistoryView:
        """A copy of the live history nodes."""
        return HistoryView(self._H, int(self._I[L.I_HSTART]), int(self._I[L.I_HEND]))

    def perturbation(self) -> np.ndarray:
        """[u, du, phi, dphi, theta, dtheta] at the current time."""
        tau, Y, p = self.tau, self._Y, self.params
        return np.array(
            [
                Y[0] - p.v0 * tau,
                Y[1] - p.v0,
                Y[2] - p.omega0 * tau,
                Y[3] - p.omega0,
                Y[4] - p.omega0 * tau,
                Y[5] - p.omega0,
            ]
        )

    def total_state(self) -> np.ndarray:
        """[U, V, Phi, W, Theta, Wt] (total scaled coordinates) at the current time."""
        return self._Y.copy()

    def diagnostics(self) -> dict[str, float]:
        """d, tau_n, g, g*, twist torque S, torque on bit T, applied R - R0 at the current time."""
        D = self._D
        return {
            "d": float(D[L.D_D]),
            "tau_n": float(D[L.D_TAUN]),
            "g": float(D[L.D_G]),
            "gstar": float(D[L.D_GSTAR]),
            "twist_torque": float(D[L.D_S]),
            "torque_on_bit": float(D[L.D_TOB]),
            "R_minus_R0": float(D[L.D_R]),
        }

    def outputs(self) -> dict[str, float]:
        """The FMU outputs: perturbation states, d, g, tau_n, mode and validity counters."""
        y = self.perturbation()
        I = self._I  # noqa: E741
        return {
            "u": float(y[0]),
            "du": float(y[1]),
            "phi": float(y[2]),
            "dphi": float(y[3]),
            "theta": float(y[4]),
            "dtheta": float(y[5]),
            "d": float(self._D[L.D_D]),
            "g": float(self._D[L.D_G]),
            "tau_n": float(self._D[L.D_TAUN]),
            "mode": float(I[L.I_MODE]),
            "stick_events": float(I[L.I_NSTICK]),
            "bit_bounce": float(I[L.I_NBOUNCE]),
            "torsional_stick": float(I[L.I_NTSTICK]),
        }

    # ----------------------------------------------------------------- state
    def get_state(self) -> EngineState:
        """Capture everything (history, mode, counters, control, latch) for a bit-exact restore."""
        arrays = {name: getattr(self, "_" + name).copy() for name in _STATE_ARRAYS}
        failed = self._failed
        arrays["failed"] = np.array(
            [-1.0 if failed is None else list(STATUS_CODES.values()).index(failed.code)]
        )
        return EngineState(arrays=arrays, n_events=len(self._events))

    def set_state(self, state: EngineState) -> None:
        """Restore a state from :meth:`get_state` of an engine with the same parameters."""
        a = state.arrays
        if not np.array_equal(a["P"], self._P):
            raise ValueError("set_state: the state was captured with different parameters")
        for name in _STATE_ARRAYS:
            setattr(self, "_" + name, a[name].copy())
        if int(self._C[L.C_KIND]) == L.CTRL_EXTERNAL and self._ext is None:
            raise ValueError("set_state: the state uses a callable control law this engine lacks")
        if int(self._C[L.C_KIND]) != L.CTRL_EXTERNAL:
            self._ext = None
            self._stepper = load_stepper(pure=False)
        del self._events[state.n_events :]
        code = int(a["failed"][0])
        if code < 0:
            self._failed = None
        else:
            c = list(STATUS_CODES.values())[code]
            self._failed = Status(c, f"{c} (restored) at tau = {self.tau:.12g}", self.tau)

    def serialize_state(self) -> bytes:
        """The state as bytes (numpy .npz, no pickle)."""
        s = self.get_state()
        buf = io.BytesIO()
        np.savez(buf, n_events=np.array([s.n_events]), **s.arrays)
        return buf.getvalue()

    def deserialize_state(self, data: bytes) -> None:
        """Restore from :meth:`serialize_state` bytes."""
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except Exception as exc:
            raise ValueError(f"deserialize_state: not an engine state ({exc})") from exc
        missing = [k for k in (*_STATE_ARRAYS, "failed", "n_events") if k not in arrays]
        if missing:
            raise ValueError(f"deserialize_state: missing arrays {missing}")
        n_events = int(arrays.pop("n_events")[0])
        self.set_state(EngineState(arrays=arrays, n_events=n_events))

    def options_dict(self) -> dict[str, Any]:
        return asdict(self.options)
