"""The history buffer of the delay equation (14): past of U, V, Phi, W at integrator nodes.

The arrays are shared with the kernel (:mod:`drillstring.model.kernel.hermite` holds the numerics);
this module builds the prehistory for tau <= 0 and offers a read-only view for inspection.
Memory is bounded: nodes older than the current delay interval are dropped as the run goes on,
and a torsional-stick stretch is kept as two nodes.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from drillstring.model.kernel.hermite import interpolate
from drillstring.model.kernel.layout import H_FLAG, H_PHI, H_ROWS, H_TAU, H_U, H_V, H_W
from drillstring.model.params import ScaledParams

HistoryFunction = Callable[[float], tuple[float, float, float, float]]
"""tau <= 0 -> (u, du/dtau, phi, dphi/dtau), perturbations from the nominal motion."""

MAX_PREHISTORY_NODES = 1_000_000


def nominal_history(tau: float) -> tuple[float, float, float, float]:
    """The nominal motion u = phi = 0 (NOTES.md section 1): the default prehistory."""
    return 0.0, 0.0, 0.0, 0.0


def build_prehistory(
    params: ScaledParams, history: HistoryFunction, h: float, capacity: int
) -> tuple[np.ndarray, int]:
    """Sample the prehistory on nodes spaced h back from tau = 0 until it spans one blade angle.

    Returns the history array (``H_ROWS x capacity``, grown if needed) and the number of nodes,
    in increasing time. Raises ValueError if the history is not finite or Phi decreases (the bit
    would rotate backwards, outside the model).
    """
    w0, v0 = params.omega0, params.v0
    blade = 2.0 * np.pi / params.n
    nodes: list[tuple[float, ...]] = []
    phi_end = None
    k = 0
    while True:
        tau = -k * h
        u, du, phi, dphi = (float(x) for x in history(tau))
        vals = (tau, v0 * tau + u, v0 + du, w0 * tau + phi, w0 + dphi, 0.0)
        if not all(np.isfinite(vals)):
            raise ValueError(f"history({tau!r}) returned a non-finite value: {(u, du, phi, dphi)}")
        if vals[4] < 0.0:
            raise ValueError(
                f"history({tau!r}) has dPhi/dtau = {vals[4]!r} < 0: the bit rotates backwards"
            )
        if nodes and vals[3] > nodes[-1][3]:
            raise ValueError(f"history: Phi decreases in time at tau = {tau!r}")
        nodes.append(vals)
        if phi_end is None:
            phi_end = vals[3]
        # two nodes beyond the blade angle so the delay is always bracketed
        if phi_end - vals[3] > blade and k >= 2 and phi_end - nodes[-3][3] > blade:
            break
        k += 1
        if k > MAX_PREHISTORY_NODES:
            raise ValueError(
                "history does not span one blade angle 2*pi/n within "
                f"{MAX_PREHISTORY_NODES} steps of {h}: the bit hardly rotates before tau = 0"
            )
    nodes.reverse()
    cap = max(capacity, 2 * len(nodes) + 16)
    H = np.zeros((H_ROWS, cap))
    H[:, : len(nodes)] = np.array(nodes).T
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
        """Node arrays tau, U, V, Phi, W (total coordinates)."""
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
