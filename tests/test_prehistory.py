"""Tests of the prehistory (tau <= 0) of the delay equation (14): the array-wise builder against
the node-by-node rule it replaces, the delay bracket it guarantees, and its input errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drillstring.model import prehistory
from drillstring.model.engine import Engine, EngineOptions
from drillstring.model.kernel.state import (
    H_FLAG,
    H_PHI,
    H_ROWS,
    H_TAU,
    H_U,
    H_V,
    H_W,
    I_HEND,
    I_HSTART,
)
from drillstring.model.params import REFERENCE
from drillstring.model.prehistory import build_prehistory, nominal_history
from drillstring.model.simulate import simulate

P = REFERENCE


def node_by_node(params, history, h):
    """The rule, one node at a time: tau_k = -k h until Phi(0) - Phi(tau_k) and
    Phi(0) - Phi(tau_{k-2}) both exceed the blade angle 2*pi/n (increasing time)."""
    blade = 2.0 * math.pi / params.n
    rows = []
    k = 0
    while True:
        tau = -k * h
        u, du, phi, dphi = (float(x) for x in history(tau))
        rows.append(
            (tau, params.v0 * tau + u, params.v0 + du, params.omega0 * tau + phi,
             params.omega0 + dphi, 0.0)
        )  # fmt: skip
        behind = rows[0][3] - rows[-1][3]
        if k >= 2 and behind > blade and rows[0][3] - rows[-3][3] > blade:
            return np.array(rows[::-1])
        k += 1


def wavy(tau: float) -> tuple[float, float, float, float]:
    """A smooth perturbed past: axial and torsional oscillation, still rotating forwards."""
    return (
        1e-3 * math.sin(3.0 * tau),
        3e-3 * math.cos(3.0 * tau),
        0.2 * math.sin(tau),
        0.2 * math.cos(tau),
    )


def slow(tau: float) -> tuple[float, float, float, float]:
    """A past rotating at a tenth of the nominal speed: ten times the nominal node count."""
    w = -0.9 * P.omega0
    return 0.0, 0.0, w * tau, w


@pytest.mark.parametrize("history", [nominal_history, wavy, slow, lambda t: (0.0, 0, 0, 0.0)])
@pytest.mark.parametrize("h", [1e-3, 1.25e-5, 0.7])
def test_builder_equals_node_by_node_rule(history, h):
    H, n = build_prehistory(P, history, h, 16)
    expected = node_by_node(P, history, h)
    assert n == len(expected)
    assert H.shape[0] == H_ROWS and H.shape[1] >= 2 * n
    assert np.array_equal(H[:, :n], expected.T)
    assert not np.any(H[:, n:])
    assert math.copysign(1.0, H[H_TAU, n - 1]) == 1.0  # tau = +0.0 last


def test_nodes_bracket_the_delay_of_the_first_step():
    """The three oldest nodes, and no others, lie more than a blade angle behind tau = 0
    (eq. (6)): the delayed instant of a state at tau >= 0 is bracketed with a node to spare."""
    for history in (nominal_history, wavy, slow):
        H, n = build_prehistory(P, history, 1e-3, 16)
        behind = H[H_PHI, n - 1] - H[H_PHI, :n]
        blade = 2 * math.pi / P.n
        assert np.all(behind[:3] > blade) and np.all(behind[3:] <= blade)
        assert np.all(np.diff(H[H_TAU, :n]) > 0.0)
        assert np.all(H[H_FLAG, :n] == 0.0)


def test_custom_history_runs_and_matches_its_definition():
    r = simulate(P, 1.0, history=wavy, initial={"u": 0.0, "dphi": 0.2}, progress=False)
    assert r.status.ok
    e = Engine(P, EngineOptions(h=1e-3), history=wavy, initial={"dphi": 0.2})
    s = e.kernel_arrays()
    nodes = s.history[:, int(s.ints[I_HSTART]) : int(s.ints[I_HEND])]
    tau = nodes[H_TAU, :-1]
    u = np.array([wavy(t)[0] for t in tau])
    assert np.array_equal(nodes[H_U, :-1], P.v0 * tau + u)
    assert np.array_equal(nodes[H_W, :-1], P.omega0 + np.array([wavy(t)[3] for t in tau]))
    assert np.array_equal(nodes[H_V, :-1], P.v0 + np.array([wavy(t)[1] for t in tau]))


@pytest.mark.parametrize(
    ("history", "match"),
    [
        (lambda t: (math.nan if t < -0.2 else 0.0, 0.0, 0.0, 0.0), r"history\(-0\.21\) returned"),
        (lambda t: (0.0, 0.0, 0.0, -2 * P.omega0 if t < -0.2 else 0.0), "rotates backwards"),
        (lambda t: (0.0, 0.0, -2 * P.omega0 * t if t < -0.2 else 0.0, 0.0), "Phi decreases"),
        (lambda t: (0.0, 0.0, 0.0), r"must return \(u, du, phi, dphi\)"),
    ],
)
def test_bad_history_gives_clear_error(history, match):
    with pytest.raises(ValueError, match=match):
        build_prehistory(P, history, 1e-2, 16)


def test_history_that_never_spans_a_blade_angle(monkeypatch):
    monkeypatch.setattr(prehistory, "MAX_PREHISTORY_NODES", 5000)
    stalled = lambda t: (0.0, 0.0, -P.omega0 * t, -P.omega0)  # noqa: E731  (Phi constant)
    with pytest.raises(
        ValueError, match=r"does not span one blade angle 2\*pi/n within 5000 steps"
    ):
        build_prehistory(P, stalled, 1e-2, 16)
    with pytest.raises(ValueError, match="does not span one blade angle"):
        build_prehistory(P, nominal_history, P.tau_n0 / 6000, 16)


def test_error_only_before_the_stop():
    """A bad value older than the nodes needed is never looked at (the rule stops first)."""
    H, n = build_prehistory(P, lambda t: (math.nan if t < -50.0 else 0.0, 0, 0, 0), 1e-2, 16)
    ref, m = build_prehistory(P, nominal_history, 1e-2, 16)
    assert n == m and np.array_equal(H, ref)
    assert H[H_U, 0] == P.v0 * H[H_TAU, 0] and H[H_V, 0] == P.v0 and H[H_W, 0] == P.omega0
