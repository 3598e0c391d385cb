"""The history buffer of the delay equation (14): the prehistory for tau <= 0, and a view of it.

The buffer stores U, V, Phi, W at the integrator's nodes (``drillstring.model.kernel.hermite``
holds its numerics); this module fills it for tau <= 0 and offers a read-only view for inspection.
Memory is bounded: nodes older than the current delay interval are dropped as the run goes on,
and a torsional-stick stretch is kept as two nodes.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from drillstring.model.kernel.hermite import interpolate
from drillstring.model.kernel.state import H_FLAG, H_PHI, H_ROWS, H_TAU, H_U, H_V, H_W
from drillstring.model.params import ScaledParams

__all__ = ["HistoryFunction", "HistoryView", "build_prehistory", "nominal_history"]

HistoryFunction = Callable[[float], tuple[float, float, float, float]]
"""tau <= 0 -> (u, du/dtau, phi, dphi/dtau), perturbations from the nominal motion."""

MAX_PREHISTORY_NODES = 1_000_000


def nominal_history(tau: float) -> tuple[float, float, float, float]:
    """The nominal motion u = phi = 0 (``docs/model.md``, "Coordinates"): the default."""
    return 0.0, 0.0, 0.0, 0.0


def _nominal_nodes(params: ScaledParams, h: float) -> np.ndarray:
    """Nodes of the nominal prehistory, in decreasing time (vectorised :func:`_sampled_nodes`)."""
    w0, v0 = params.omega0, params.v0
    blade = 2.0 * math.pi / params.n
    n = math.ceil(blade / (w0 * h)) + 4
    if n > MAX_PREHISTORY_NODES:
        _too_long(h)
    tau = -np.arange(n + 1, dtype=float) * h
    tau[0] = 0.0  # not -0.0
    phi = w0 * tau + 0.0
    behind = phi[0] - phi  # angle rotated since each node
    k = np.arange(n + 1)
    stop = (behind > blade) & (k >= 2) & (np.roll(behind, 2) > blade)
    last = int(np.argmax(stop))
    nodes = np.zeros((last + 1, H_ROWS))
    nodes[:, H_TAU] = tau[: last + 1]
    nodes[:, H_U] = v0 * tau[: last + 1] + 0.0
    nodes[:, H_V] = v0 + 0.0
    nodes[:, H_PHI] = phi[: last + 1]
    nodes[:, H_W] = w0 + 0.0
    return nodes


def _too_long(h: float) -> None:
    raise ValueError(
        "history does not span one blade angle 2*pi/n within "
        f"{MAX_PREHISTORY_NODES} steps of {h}: the bit hardly rotates before tau = 0"
    )


def _sampled_nodes(params: ScaledParams, history: HistoryFunction, h: float) -> np.ndarray:
    """Sample ``history`` on nodes spaced h back from tau = 0 until it spans one blade angle
    (two nodes beyond it, so the delay is always bracketed); in decreasing time."""
    w0, v0 = params.omega0, params.v0
    blade = 2.0 * np.pi / params.n
    nodes: list[tuple[float, ...]] = []
    k = 0
    while True:
        tau = -k * h
        u, du, phi, dphi = (float(x) for x in history(tau))
        vals = (tau, v0 * tau + u, v0 + du, w0 * tau + phi, w0 + dphi, 0.0)
        if not all(np.isfinite(vals)):
            raise ValueError(f"history({tau!r}) returned a non-finite value: {(u, du, phi, dphi)}")
        if vals[H_W] < 0.0:
            raise ValueError(
                f"history({tau!r}) has dPhi/dtau = {vals[H_W]!r} < 0: the bit rotates backwards"
            )
        if nodes and vals[H_PHI] > nodes[-1][H_PHI]:
            raise ValueError(f"history: Phi decreases in time at tau = {tau!r}")
        nodes.append(vals)
        phi_end = nodes[0][H_PHI]
        if phi_end - vals[H_PHI] > blade and k >= 2 and phi_end - nodes[-3][H_PHI] > blade:
            break
        k += 1
        if k > MAX_PREHISTORY_NODES:
            _too_long(h)
    return np.array(nodes)


def build_prehistory(
    params: ScaledParams, history: HistoryFunction, h: float, capacity: int
) -> tuple[np.ndarray, int]:
    """The history buffer filled for tau <= 0, and the number of nodes.

    Nodes are spaced h back from tau = 0 until they span one blade angle 2*pi/n (eq. (6)).
    Returns the buffer (``H_ROWS x capacity``, larger if needed) with the nodes in increasing
    time. Raises ValueError if the history is not finite or Phi decreases (the bit would rotate
    backwards, outside the model).
    """
    if history is nominal_history:
        nodes = _nominal_nodes(params, h)
    else:
        nodes = _sampled_nodes(params, history, h)
    nodes = nodes[::-1]
    cap = max(capacity, 2 * len(nodes) + 16)
    H = np.zeros((H_ROWS, cap))
    H[:, : len(nodes)] = nodes.T
    return H, len(nodes)


class HistoryView:
    """Read-only view of the live part of a history buffer (for inspection and tests)."""

    def __init__(self, H: np.ndarray, start: int, end: int) -> None:
        self._H = H[:, start:end].copy()

    @property
    def tau(self) -> np.ndarray:
        return self._H[H_TAU]

    def __len__(self) -> int:
        return self._H.shape[1]

    def nodes(self) -> dict[str, np.ndarray]:
        """Node arrays tau, U, V, Phi, W (total coordinates) and the discontinuity flags."""
        return {
            "tau": self._H[H_TAU],
            "U": self._H[H_U],
            "V": self._H[H_V],
            "Phi": self._H[H_PHI],
            "W": self._H[H_W],
            "discontinuity": self._H[H_FLAG] > 0.0,
        }

    def evaluate(self, tau: float) -> tuple[float, float, float, float]:
        """(U, V, Phi, W) at a past time by the kernel's Hermite interpolation."""
        out = np.zeros(4)
        if not interpolate(self._H, 0, self._H.shape[1], float(tau), out):
            raise ValueError(
                f"tau = {tau!r} is outside the stored history [{self.tau[0]}, {self.tau[-1]}]"
            )
        return float(out[0]), float(out[1]), float(out[2]), float(out[3])
