"""The history buffer of the delay equation (14): the prehistory for tau <= 0.

The buffer stores U, V, Phi, W at the integrator's nodes (``drillstring.model.kernel.hermite``
holds its numerics); this module fills it for tau <= 0.
Memory is bounded: nodes older than the current delay interval are dropped as the run goes on,
and a torsional-stick stretch is kept as two nodes.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from drillstring.model.kernel.state import H_PHI, H_ROWS, H_TAU, H_U, H_V, H_W
from drillstring.model.params import ScaledParams

__all__ = ["HistoryFunction", "build_prehistory", "nominal_history"]

HistoryFunction = Callable[[float], tuple[float, float, float, float]]
"""tau <= 0 -> (u, du/dtau, phi, dphi/dtau), perturbations from the nominal motion."""

MAX_PREHISTORY_NODES = 1_000_000


def nominal_history(tau: float) -> tuple[float, float, float, float]:
    """The nominal motion u = phi = 0 (``docs/model.md``, "Coordinates"): the default.

    Parameters
    ----------
    tau : float
        A past time, tau <= 0 (unused: the perturbations are 0 at every time).

    Returns
    -------
    tuple of 4 float
        (u, du/dtau, phi, dphi/dtau) = (0, 0, 0, 0).
    """
    return 0.0, 0.0, 0.0, 0.0


def _too_long(h: float) -> None:
    raise ValueError(
        "history does not span one blade angle 2*pi/n within "
        f"{MAX_PREHISTORY_NODES} steps of {h}: the bit hardly rotates before tau = 0"
    )


def _perturbations(history: HistoryFunction | None, tau: np.ndarray) -> np.ndarray:
    """(u, du, phi, dphi) of ``history`` at the times ``tau``, as a 4 x len(tau) array.

    The nominal history is zero without a call; any other is called once per time with a
    Python float (its contract is a scalar function), the only per-node Python left.
    """
    if history is None:
        return np.zeros((4, tau.size))
    values = [tuple(map(float, history(t))) for t in tau.tolist()]
    for t, v in zip(tau.tolist(), values, strict=True):
        if len(v) != 4:
            raise ValueError(f"history({t!r}) must return (u, du, phi, dphi), got {v!r}")
    return np.array(values, dtype=float).reshape(tau.size, 4).T


def _first(mask: np.ndarray) -> int:
    """Index of the first True of ``mask``, or its length."""
    return int(np.argmax(mask)) if mask.any() else mask.size


def _nodes(params: ScaledParams, history: HistoryFunction | None, h: float) -> np.ndarray:
    """Nodes tau_k = -k h, k = 0, 1, ..., with U, V, Phi, W of eqs. (11)-(13) in total
    coordinates (``docs/model.md``, "Coordinates"), until they span one blade angle 2*pi/n
    (eq. (6)) with two nodes beyond it, so the delay is always bracketed; in decreasing time.

    Built array-wise in blocks: the first block is the nominal motion's node count, the next
    ones double it. The nodes equal those of the node-by-node rule bit for bit (the same IEEE
    operations on the same numbers, ``tests/test_prehistory.py``); a bad node (non-finite,
    dPhi/dtau < 0, Phi decreasing in time) raises at the first one before the stop, as that
    rule would.
    """
    w0, v0 = params.omega0, params.v0
    blade = 2.0 * math.pi / params.n
    limit = MAX_PREHISTORY_NODES + 1
    count = math.ceil(blade / (w0 * h)) + 5
    if count > limit:
        _too_long(h)
    parts: list[np.ndarray] = []
    perts: list[np.ndarray] = []
    done = 0
    while True:
        k = np.arange(done, count)
        tau = -k * h  # as the scalar rule -k*h: 0.0 (not -0.0) first
        pert = _perturbations(history, tau)
        u, du, phi, dphi = pert
        perts.append(pert)
        part = np.zeros((k.size, H_ROWS))
        part[:, H_TAU] = tau
        part[:, H_U] = v0 * tau + u
        part[:, H_V] = v0 + du
        part[:, H_PHI] = w0 * tau + phi
        part[:, H_W] = w0 + dphi
        parts.append(part)
        nodes = np.concatenate(parts) if len(parts) > 1 else part
        Phi = nodes[:, H_PHI]
        behind = Phi[0] - Phi  # the angle rotated since each node (NaN never stops)
        stop = np.zeros(Phi.size, dtype=bool)
        stop[2:] = (behind[2:] > blade) & (behind[:-2] > blade)
        last = _first(stop)
        vals = nodes[: min(last + 1, Phi.size)]
        bad_value = ~np.all(np.isfinite(vals[:, [H_TAU, H_U, H_V, H_PHI, H_W]]), axis=1)
        backwards = vals[:, H_W] < 0.0
        decreasing = np.zeros(len(vals), dtype=bool)
        decreasing[1:] = vals[1:, H_PHI] > vals[:-1, H_PHI]
        bad = _first(bad_value | backwards | decreasing)
        if bad < len(vals):
            t = float(vals[bad, H_TAU])
            if bad_value[bad]:
                values = tuple(np.concatenate(perts, axis=1)[:, bad].tolist())
                raise ValueError(f"history({t!r}) returned a non-finite value: {values}")
            if backwards[bad]:
                raise ValueError(
                    f"history({t!r}) has dPhi/dtau = {float(vals[bad, H_W])!r} < 0: "
                    "the bit rotates backwards"
                )
            raise ValueError(f"history: Phi decreases in time at tau = {t!r}")
        if last < Phi.size:
            return vals
        if count >= limit:
            _too_long(h)
        done, count = count, min(2 * count, limit)


def build_prehistory(
    params: ScaledParams, history: HistoryFunction, h: float, capacity: int
) -> tuple[np.ndarray, int]:
    """The history buffer of the delay equation (14) filled for tau <= 0.

    Parameters
    ----------
    params : ScaledParams
        The scaled parameter set (v0, omega0 and the blade angle 2*pi/n of eq. (6)).
    history : callable
        tau <= 0 -> (u, du/dtau, phi, dphi/dtau), perturbations from the nominal motion;
        :func:`nominal_history` is built without calling it.
    h : float
        Node spacing (the engine's nominal step).
    capacity : int
        Minimum number of columns of the buffer.

    Returns
    -------
    H : ndarray
        ``H_ROWS x max(capacity, 2 n + 16)``: nodes tau_k = -k h in increasing time (tau = 0
        last) until they span one blade angle, the rest zero.
    n : int
        The number of nodes.

    Raises
    ------
    ValueError
        If the history is not finite, dPhi/dtau < 0 or Phi decreases in time (the bit would
        rotate backwards, outside the model), or the nodes never span a blade angle.
    """
    nodes = _nodes(params, None if history is nominal_history else history, h)[::-1]
    cap = max(capacity, 2 * len(nodes) + 16)
    H = np.zeros((H_ROWS, cap))
    H[:, : len(nodes)] = nodes.T
    return H, len(nodes)
