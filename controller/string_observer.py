"""A surface observer of the bit designed on the string: a Kalman filter on a short lumped chain
(``docs/controllers.md``, "An observer for the string").

The one-mode observer (:mod:`drillstring.controller.estimation`) models the pipe as a massless
spring: on the distributed string the torque at the top is not theta - phi, the wave takes
sqrt(kappa) to cross the pipe and the higher modes are in every surface signal. This observer
is designed on the chain of ``elements`` equal elements of
:func:`~drillstring.model.pipe.torsional_chain` (default 3: three flexible modes, the first two
within a few per cent of the string's), with the bit node carrying the averaged bit law in its
Taylor form (27), ``J_b w_b' = k (q_{b-1} - q_b) - c tau_n0 w_b + d``, and ``d`` an unknown
torque at the bit (a random walk; K0 at the operating point) that takes up what the
linearisation leaves out (the stick-slip's friction, the chain's error).

State ``z = [q_0 .. q_M, w_0 .. w_M, d]`` (the nodes' angle and speed perturbations, node 0 the
table, node M the bit), input ``u = R - R0`` (the motor torque, measured), measurements
``y = [theta, dtheta, T_top]`` (the table's angle and speed and the torque at the top of the
string, ``k (q_0 - q_1)``, what ``top_torque_minus_R0`` is). With the table angle measured the
bit angle is observable (the rigid-body mode is seen through theta), which the one-mode
observer, without it, integrates open loop. The laws get ``phi = q_M``, ``dphi = w_M`` and the
twist ``phi - theta = q_M - q_0``.

The filter is the steady-state Kalman filter of the exactly discretised chain (zero-order hold
of the motor torque over the sample period): the noise on the motor torque enters as process
noise on the table, an error in the top drive's inertia as more of it
(:func:`design_string_observer`). It runs here, in Python, on recorded surface signals
(:meth:`StringObserver.run`) or one sample at a time (:meth:`StringObserver.correct`,
:meth:`StringObserver.predict`); the compiled controller's observer slot holds the one-mode
filter's four states.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import solve_discrete_are

from drillstring.controller.averaged import AveragedModel
from drillstring.controller.estimation import discretise
from drillstring.model.params import REFERENCE_RIG
from drillstring.model.pipe import StringParams, torsional_chain
from drillstring.model.sensing import Observer
from drillstring.validation import check_int, check_real

__all__ = [
    "DEFAULT_ELEMENTS",
    "ERROR_WINDOW",
    "SURFACE_NOISE_SI",
    "StringObserver",
    "design_string_observer",
    "estimation_errors",
    "noisy_surface",
    "one_mode_estimates",
    "scaled_surface_noise",
]

#: Elements of the observer's chain: three flexible modes (the first two of the string within
#: about 1 % and 5 %), 9 states.
DEFAULT_ELEMENTS = 3

#: The noise (standard deviations, SI) on the surface signals of the tests and of the table in
#: ``docs/controllers.md``. Ours, reasoned: the table speed from the motor's encoder at 1 kHz,
#: 0.5 rpm; its angle 0.5 degree; the torque at the top from a torque sub, 0.2 kN m (1 % of a
#: 20 kN m sub, twenty times below the TDS-11SA's rating); the motor torque from the drive's
#: current, 0.5 kN m (1 % of the TDS-11SA's 50.8 kN m). Each is about half of the nominal torque
#: R0 (1.04 kN m) or a tenth of the nominal speed (51.8 rpm) and more: coarse, not optimistic.
SURFACE_NOISE_SI = {
    "theta_deg": 0.5,
    "dtheta_rpm": 0.5,
    "top_torque_knm": 0.2,
    "motor_torque_knm": 0.5,
}


@dataclass(frozen=True)
class StringObserver:
    """The discrete steady-state Kalman filter of the module docstring (numbers only).

    Attributes
    ----------
    Ad : array (n, n)
        The chain's system matrix over the sample period, ``n = 2 (elements + 1) + 1``.
    Bd : array (n,)
        Its input column (the motor torque R - R0, held).
    C : array (3, n)
        The measured combinations: table angle, table speed, torque at the top.
    M : array (n, 3)
        The filter gain.
    elements : int
        M, the chain's elements.
    K0 : float
        K0 of the averaged model (the bit torque d at the operating point; x3 = twist - K0).
    Ts : float
        The sample period of the discretisation (scaled).
    """

    Ad: np.ndarray
    Bd: np.ndarray
    C: np.ndarray
    M: np.ndarray
    elements: int
    K0: float
    Ts: float

    def __post_init__(self) -> None:
        m = check_int("StringObserver.elements", self.elements, lower=1)
        n = 2 * (m + 1) + 1
        for name, shape in (("Ad", (n, n)), ("Bd", (n,)), ("C", (3, n)), ("M", (n, 3))):
            a = np.array(getattr(self, name), dtype=float)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise ValueError(
                    f"StringObserver.{name} must be finite of shape {shape} (elements = {m}), "
                    f"got shape {a.shape}"
                )
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "K0", check_real("StringObserver.K0", self.K0))
        object.__setattr__(self, "Ts", check_real("StringObserver.Ts", self.Ts, lower=0.0))

    @property
    def size(self) -> int:
        """n, the number of states."""
        return self.Ad.shape[0]

    def initial(self, theta: float, dtheta: float, torque: float) -> NDArray[np.float64]:
        """The state the first measurements give: the string turning with the table, its twist
        uniform and carrying the measured torque, the bit torque balancing it."""
        m = self.elements
        k = self.C[2, 0]  # the element stiffness: T = k (q_0 - q_1)
        z = np.zeros(self.size)
        z[: m + 1] = theta - np.arange(m + 1) * torque / k
        z[m + 1 : 2 * m + 2] = dtheta
        z[-1] = -torque
        return z

    def run(
        self, theta: ArrayLike, dtheta: ArrayLike, torque: ArrayLike, r: ArrayLike
    ) -> dict[str, NDArray[np.float64]]:
        """The filtered estimates at each sample of recorded surface signals.

        Parameters
        ----------
        theta, dtheta : array_like
            The table's angle and speed perturbations at the samples (scaled).
        torque : array_like
            The torque at the top of the string less R0 (scaled).
        r : array_like
            The motor torque R - R0 held from each sample on (scaled).

        Returns
        -------
        dict
            ``phi``, ``dphi`` (the bit's angle and speed), ``twist`` (phi - theta) and ``d``
            (the bit torque), one value per sample.

        Raises
        ------
        ValueError
            Signals of different lengths, empty or not finite.
        """
        ys = _signals(("theta", theta), ("dtheta", dtheta), ("torque", torque), ("r", r))
        theta_, dtheta_, torque_, r_ = ys
        n = theta_.size
        m = self.elements
        Y = np.column_stack([theta_, dtheta_, torque_])
        out = np.empty((n, 4))
        z = self.initial(theta_[0], dtheta_[0], torque_[0])
        Ad, Bd, C, M = self.Ad, self.Bd, self.C, self.M
        for i in range(n):
            if i > 0:
                z = z + M @ (Y[i] - C @ z)
            out[i] = (z[m], z[2 * m + 1], z[m] - z[0], z[-1])
            z = Ad @ z + Bd * r_[i]
        return {"phi": out[:, 0], "dphi": out[:, 1], "twist": out[:, 2], "d": out[:, 3]}

    def correct(
        self, prior: NDArray[np.float64] | None, theta: float, dtheta: float, torque: float
    ) -> NDArray[np.float64]:
        """The filtered state at a sample from its prior (None: the first sample,
        :meth:`initial`) and the sample's measurements, as :meth:`run` does."""
        if prior is None:
            return self.initial(theta, dtheta, torque)
        return prior + self.M @ (np.array([theta, dtheta, torque]) - self.C @ prior)

    def predict(self, z: NDArray[np.float64], r: float) -> NDArray[np.float64]:
        """The prior of the next sample from the filtered state and the motor torque held."""
        return self.Ad @ z + self.Bd * r

    def bit(self, z: NDArray[np.float64]) -> tuple[float, float]:
        """(phi, dphi): the bit's angle and speed in the state ``z``."""
        m = self.elements
        return float(z[m]), float(z[2 * m + 1])


def _signals(*named: tuple[str, ArrayLike]) -> list[NDArray[np.float64]]:
    """The signals as 1-D float arrays of one length, finite, named when they are not."""
    arrays = []
    for name, values in named:
        a = np.asarray(values, dtype=float).reshape(-1)
        if a.size == 0:
            raise ValueError(f"{name} is empty")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite, got a non-finite value at sample "
                             f"{int(np.flatnonzero(~np.isfinite(a))[0])}")  # fmt: skip
        arrays.append(a)
    sizes = {name: a.size for (name, _), a in zip(named, arrays, strict=True)}
    if len(set(sizes.values())) != 1:
        raise ValueError(f"the signals must have one length, got {sizes}")
    return arrays


def design_string_observer(
    model: AveragedModel,
    string: StringParams,
    Ts: float,
    *,
    elements: int = DEFAULT_ELEMENTS,
    rho: float | None = None,
    noise: dict[str, float] | None = None,
    bit: float = 1.0,
    bias: float = 0.1,
    chain: float = 1.0,
    inertia_error: float = 0.2,
) -> StringObserver:
    """The observer of the module docstring.

    Parameters
    ----------
    model : AveragedModel
        The averaged model (its c, tau_n0, K0; its rho unless ``rho`` is given).
    string : StringParams
        The pipe: its kappa; on the paper's one-mode string (``lumping = "paper"``) the
        observer's model is that string itself (one element, ``elements`` not used), else the
        lumped chain of ``elements`` (the plant's own number of elements is not used).
    Ts : float
        Sample period (scaled), > 0.
    elements : int
        M, the elements of the observer's chain, >= 2 (at least two flexible modes).
    rho : float, optional
        The top drive's inertia ratio the observer assumes, > 0 (default the model's).
    noise : dict, optional
        Scaled standard deviations ``theta``, ``dtheta``, ``torque`` (the top's), ``motor``,
        each > 0; default those of :data:`SURFACE_NOISE_SI` on the reference rig.
    bit : float
        Deviation (per sqrt(tau)) of the bit's unmodelled acceleration, > 0 (1: as today's
        observer's ``process``).
    bias : float
        Deviation (per sqrt(tau)) of the random walk of the bit torque d, > 0.
    chain : float
        Deviation (per sqrt(tau)) of the unmodelled acceleration of the chain's inner nodes
        and table (the neglected modes), > 0.
    inertia_error : float
        The relative error of ``rho`` the filter allows for, >= 0: the table's acceleration
        error ``inertia_error * rho * |dtheta'|`` taken as process noise with the motor torque's
        noise, at a typical acceleration of one torque unit over rho.

    Returns
    -------
    StringObserver

    Raises
    ------
    ValueError
        A value out of its range, naming it.
    """
    if not isinstance(model, AveragedModel):
        raise TypeError(f"model must be an AveragedModel, got {type(model).__name__}")
    if not isinstance(string, StringParams):
        raise TypeError(f"string must be a StringParams, got {type(string).__name__}")
    Ts = check_real("Ts", Ts, lower=0.0)
    m = check_int("elements", elements, lower=2)
    rho = model.rho if rho is None else check_real("rho", rho, lower=0.0)
    if string.kappa == 0.0 and not string.is_paper:
        raise ValueError("string.kappa must be > 0: a chain needs the pipe's inertia, got 0")
    sig = _scaled_noise(noise)
    q_bit = check_real("bit", bit, lower=0.0)
    q_bias = check_real("bias", bias, lower=0.0)
    q_chain = check_real("chain", chain, lower=0.0)
    e_rho = check_real("inertia_error", inertia_error, lower=0.0, strict=False)
    if e_rho >= 1.0:
        raise ValueError(f"inertia_error must be < 1, got {inertia_error!r}")

    if string.is_paper:  # the paper's one-mode string: its own model, exactly
        ch = torsional_chain(string, rho)
    else:
        ch = torsional_chain(StringParams(elements=m, kappa=string.kappa, lumping="lumped"), rho)
    J, k = ch.inertia, ch.stiffness
    m = ch.elements
    nn = m + 1
    n = 2 * nn + 1
    K = np.zeros((nn, nn))
    for e in range(m):
        K[e, e] += k
        K[e + 1, e + 1] += k
        K[e, e + 1] -= k
        K[e + 1, e] -= k
    A = np.zeros((n, n))
    A[:nn, nn : 2 * nn] = np.eye(nn)
    A[nn : 2 * nn, :nn] = -K / J[:, None]
    A[2 * nn - 1, 2 * nn - 1] = -model.c * model.tau_n0 / J[-1]
    A[2 * nn - 1, -1] = 1.0 / J[-1]
    B = np.zeros(n)
    B[nn] = 1.0 / J[0]
    Ad, Bd = discretise(A, B, Ts)
    C = np.zeros((3, n))
    C[0, 0] = 1.0
    C[1, nn] = 1.0
    C[2, 0], C[2, 1] = k, -k

    # process noise: continuous white accelerations (variance per unit time times Ts), the motor
    # torque's noise held over the sample (Bd Bd^T), the inertia error as more of it
    G = np.zeros((n, 3))
    G[2 * nn - 1, 0] = q_bit / J[-1]
    G[-1, 1] = q_bias
    Q = G @ G.T * Ts
    Q[nn : 2 * nn, nn : 2 * nn] += np.diag(np.full(nn, (q_chain**2) * Ts))
    table = sig["motor"] ** 2 + (e_rho * 1.0) ** 2
    Q += np.outer(Bd, Bd) * table
    Q += np.eye(n) * 1e-12
    R = np.diag([sig["theta"] ** 2, sig["dtheta"] ** 2, sig["torque"] ** 2])
    P = solve_discrete_are(Ad.T, C.T, Q, R)
    M = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
    if not np.all(np.abs(np.linalg.eigvals((np.eye(n) - M @ C) @ Ad)) < 1.0):
        raise ValueError("the filter is not stable (check the noise levels)")  # pragma: no cover
    return StringObserver(Ad=Ad, Bd=Bd, C=C, M=M, elements=m, K0=model.K0, Ts=Ts)


def scaled_surface_noise(C: float, t_star: float) -> dict[str, float]:
    """:data:`SURFACE_NOISE_SI` in the scaled units of a rig (torque scale C [N m/rad], time
    scale t* [s]): ``theta``, ``dtheta``, ``torque``, ``motor``."""
    C = check_real("C", C, lower=0.0)
    t_star = check_real("t_star", t_star, lower=0.0)
    s = SURFACE_NOISE_SI
    return {
        "theta": math.radians(s["theta_deg"]),
        "dtheta": s["dtheta_rpm"] * math.pi / 30.0 * t_star,
        "torque": s["top_torque_knm"] * 1e3 / C,
        "motor": s["motor_torque_knm"] * 1e3 / C,
    }


def _scaled_noise(noise: dict[str, float] | None) -> dict[str, float]:
    if noise is None:
        return scaled_surface_noise(REFERENCE_RIG.C, REFERENCE_RIG.t_star)
    if not isinstance(noise, dict):
        raise TypeError(f"noise must be a dict, got {type(noise).__name__}")
    keys = ("theta", "dtheta", "torque", "motor")
    unknown = sorted(set(noise) - set(keys))
    missing = sorted(set(keys) - set(noise))
    if unknown or missing:
        raise ValueError(f"noise needs the keys {', '.join(keys)}: unknown {unknown}, "
                         f"missing {missing}")  # fmt: skip
    return {key: check_real(f"noise[{key!r}]", noise[key], lower=0.0) for key in keys}


def one_mode_estimates(
    observer: Observer, theta: ArrayLike, dtheta: ArrayLike, torque: ArrayLike, r: ArrayLike
) -> dict[str, NDArray[np.float64]]:
    """Today's one-mode observer on recorded surface signals, as the compiled controller runs it
    (``drillstring/model/sensing.py``, ``_observer_view``): the string torque its model
    knows is the measured torque at the top.

    Returns
    -------
    dict
        ``phi``, ``dphi``, ``twist`` (phi - theta = x3 + K0), one value per sample.
    """
    if not isinstance(observer, Observer):
        raise TypeError(f"observer must be an Observer, got {type(observer).__name__}")
    theta_, dtheta_, torque_, r_ = _signals(
        ("theta", theta), ("dtheta", dtheta), ("torque", torque), ("r", r)
    )
    K0 = observer.K0
    Ad, Bd, M = observer.Ad, observer.Bd, observer.M
    out = np.empty((dtheta_.size, 3))
    x = np.zeros(4)
    for i in range(dtheta_.size):
        x3 = -torque_[i] - K0
        if i == 0:
            # the compiled first sample: the state the measurements give (its only use of theta)
            x = np.array([theta_[i] - torque_[i], dtheta_[i], x3, dtheta_[i]])
        else:
            x = x + M @ (np.array([dtheta_[i], x3]) - x[[3, 2]])
        out[i] = (x[0], x[1], x[2] + K0)
        x = Ad @ x + Bd * (r_[i] + K0)
    return {"phi": out[:, 0], "dphi": out[:, 1], "twist": out[:, 2]}


# --------------------------------------------------------------------------------------------
# the observers on a run: noisy surface signals, estimation errors, the comparison table
# --------------------------------------------------------------------------------------------

#: The window of the error metrics (scaled time): after the first estimates' transient, in the
#: stick-slip of the Fig. 6 open loop (its period is about 7).
ERROR_WINDOW = (20.0, 40.0)


def noisy_surface(
    data: dict[str, np.ndarray], noise: dict[str, float] | None, seed: int = 1
) -> dict[str, NDArray[np.float64]]:
    """The surface signals of a run's rows (one per sample) with independent Gaussian noise.

    Parameters
    ----------
    data : dict
        The run's columns (``theta``, ``dtheta``, ``top_torque_minus_R0``, ``R_minus_R0``).
    noise : dict or None
        Scaled deviations ``theta``, ``dtheta``, ``torque``, ``motor`` (None: no noise).
    seed : int
        Seed of numpy's default generator, >= 0.

    Returns
    -------
    dict
        ``theta``, ``dtheta``, ``torque``, ``r``: the arguments of :meth:`StringObserver.run`.
    """
    seed = check_int("seed", seed, lower=0)
    sig = {"theta": 0.0, "dtheta": 0.0, "torque": 0.0, "motor": 0.0}
    if noise is not None:
        sig = _scaled_noise(noise)
    rng = np.random.default_rng(seed)
    out = {}
    for key, column, channel in (
        ("theta", "theta", "theta"),
        ("dtheta", "dtheta", "dtheta"),
        ("torque", "top_torque_minus_R0", "torque"),
        ("r", "R_minus_R0", "motor"),
    ):
        x = np.asarray(data[column], dtype=float)
        out[key] = x + sig[channel] * rng.standard_normal(x.size)
    return out


def estimation_errors(
    estimates: dict[str, np.ndarray],
    data: dict[str, np.ndarray],
    window: tuple[float, float] = ERROR_WINDOW,
) -> dict[str, float]:
    """RMS and largest estimation errors over ``window`` (scaled): ``dphi_rms``, ``dphi_max``,
    ``phi_rms``, ``twist_rms`` (the bit's speed, angle and twist phi - theta)."""
    lo, hi = (check_real(f"window[{i}]", w) for i, w in enumerate(window))
    if not hi > lo:
        raise ValueError(f"window must be (start, end) with end > start, got {window!r}")
    tau = np.asarray(data["tau"])
    w = (tau >= lo) & (tau <= hi)
    if not np.any(w):
        raise ValueError(f"window = {window!r} holds no sample of the run (tau up to {tau[-1]})")
    e_dphi = estimates["dphi"][w] - data["dphi"][w]
    e_phi = estimates["phi"][w] - data["phi"][w]
    e_twist = estimates["twist"][w] - (data["phi"][w] - data["theta"][w])

    def rms(x: np.ndarray) -> float:
        return float(np.sqrt(np.mean(x * x)))

    return {
        "dphi_rms": rms(e_dphi),
        "dphi_max": float(np.abs(e_dphi).max()),
        "phi_rms": rms(e_phi),
        "twist_rms": rms(e_twist),
    }
