"""Tests of the stepping engine against independent results (roots of the linearisation,
convergence order, invariance, recomputation of d and tau_n, bit-exact restore)."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest

from drillstring.analysis.axial_stability import critical_delay
from drillstring.analysis.spectrum import dde_roots
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import Engine, EngineOptions, stick_entries
from drillstring.model.kernel import state as S
from drillstring.model.kernel.jit import numba_available
from drillstring.model.params import REFERENCE
from drillstring.model.simulate import simulate

P = REFERENCE


def test_nominal_motion_is_invariant():
    """With no perturbation and R = R0 the nominal motion is an exact solution."""
    r = simulate(P, 1.0, dt_out=1e-2, progress=False)
    assert r.status.ok
    for name in ("u", "du", "phi", "dphi", "theta", "dtheta"):
        assert np.max(np.abs(getattr(r, name))) < 1e-12, name
    assert np.max(np.abs(r.d - P.d0)) < 1e-12
    assert np.max(np.abs(r.tau_n - P.tau_n0)) < 1e-12
    assert np.all(r.g == 0.0)


def test_axial_kick_decays_below_critical_delay():
    """Below the critical delay of (21) the axial equilibrium is stable: a kick decays."""
    taubar_crit = critical_delay(P.gammabar, P.etabar2)
    taubar = 0.5 * taubar_crit
    omega0 = 2 * math.pi / (P.n * taubar / P.sqrt_npsi)
    p = P.replace(omega0=omega0)
    assert p.taubar_n0 == pytest.approx(taubar)
    r = simulate(p, 20.0, initial={"u": 1e-4}, dt_out=1e-3, progress=False)
    assert r.status.ok
    early = np.max(np.abs(r.du[r.tau < 1.0]))
    late = np.max(np.abs(r.du[r.tau > 18.0]))
    assert early > 1e-4
    assert late < 1e-3 * early


def _rightmost_root(p) -> complex:
    """Rightmost root of s^2 + gamma s + eta^2 + n psi (1 - exp(-s tau_n0)), by Newton from
    the spectral estimate of drillstring.analysis.spectrum (independent of the engine)."""
    npsi = p.n * p.psi
    a0 = np.array([[0.0, 1.0], [-(p.eta**2 + npsi), -p.gamma]])
    a1 = np.array([[0.0, 0.0], [npsi, 0.0]])
    s = complex(dde_roots(a0, [(p.tau_n0, a1)], re_min=1.0, n_cheb_max=800)[0])
    for _ in range(50):
        e = np.exp(-s * p.tau_n0)
        f = s * s + p.gamma * s + p.eta**2 + npsi * (1 - e)
        fp = 2 * s + p.gamma + npsi * p.tau_n0 * e
        s -= f / fp
    assert abs(f) < 1e-9
    return s


def _matrix_pencil(y: np.ndarray, dt: float, order: int) -> np.ndarray:
    """Continuous-time exponents of a sum of `order` damped exponentials fitted to samples."""
    n = y.size
    L = n // 2
    Y = np.array([y[i : i + L + 1] for i in range(n - L)])
    _, _, vh = np.linalg.svd(Y, full_matrices=False)
    V = vh[:order].conj().T
    z = np.linalg.eigvals(np.linalg.pinv(V[:-1]) @ V[1:])
    return np.log(z) / dt


def test_linear_growth_matches_rightmost_root():
    """Torsion frozen, small axial kick: growth rate and frequency of u are those of the
    rightmost characteristic root of the linearised (11) (to 1%)."""
    s_exact = _rightmost_root(P)
    assert s_exact.real > 0
    dt = 2e-3
    opts = EngineOptions(h=2.5e-4, freeze_torsion=True)
    r = simulate(P, 5.0, initial={"u": 1e-9}, dt_out=dt, options=opts, progress=False)
    assert r.status.ok
    assert len(r.events) == 0, "no contact event: (11) is linear while V > 0"
    window = (r.tau >= 2.0) & (r.tau <= 5.0)
    exps = _matrix_pencil(r.u[window], dt, order=8)
    dominant = exps[np.argmax(exps.real)]
    print(f"rightmost root {s_exact:.6f}, measured {dominant:.6f}")
    assert abs(dominant.real - s_exact.real) < 0.01 * abs(s_exact.real)
    assert abs(abs(dominant.imag) - s_exact.imag) < 0.01 * abs(s_exact.imag)


def test_convergence_order_rk4():
    """Error against a fine reference run shrinks at RK4's order on the reference set."""
    T = 10.0

    def run(h):
        return simulate(P, T, initial={"dphi": -2.5}, options=EngineOptions(h=h), progress=False)

    ref = run(6.25e-5)
    errs = []
    hs = [2e-3, 1e-3, 5e-4]
    for h in hs:
        r = run(h)
        errs.append(max(np.max(np.abs(r.du - ref.du)), np.max(np.abs(r.dphi - ref.dphi))))
    orders = [math.log2(errs[i] / errs[i + 1]) for i in range(len(errs) - 1)]
    print("errors", errs, "measured orders", orders)
    # 3.92 and 3.95 measured; without the tracking of delayed discontinuities 2.95 and 2.18
    assert min(orders) >= 3.5
    assert errs[-1] < 1e-6


def test_no_precision_floor_below_quarter_millistep():
    """Halving h below 2.5e-4 still reduces the error over tau in [0, 60] (Fig. 5 open loop).

    Each step's end is computed from the interval's end and the step is the difference of the
    two times; with tau + h accumulated instead, the error stalled at about 1e-7 from here on.
    """

    def run(h):
        opts = EngineOptions(h=h)
        return simulate(P, 60.0, initial={"dphi": -2.5}, options=opts, progress=False)

    ref = run(1.5625e-5)
    errs = [float(np.max(np.abs(run(h).du - ref.du))) for h in (2.5e-4, 1.25e-4, 6.25e-5)]
    print("errors in du/dtau", errs)
    assert errs[1] < errs[0] / 4
    assert errs[2] < errs[1] / 2


@pytest.fixture(scope="module")
def ref_run():
    return simulate(P, 20.0, initial={"dphi": -2.5}, dt_out=1e-3, progress=False)


def test_stick_events_are_on_the_switching_surface(ref_run):
    r = ref_run
    stick = stick_entries(r.events)
    assert len(stick) > 20
    assert max(abs(e.V) for e in stick) < 1e-9
    assert all(0.0 <= e.gstar <= 1.0 for e in stick)
    in_stick = r.mode == 1
    assert in_stick.sum() > 100
    assert np.all(r.du[in_stick] == -P.v0)  # V = 0 exactly
    assert np.all((r.g[in_stick] >= -1e-9) & (r.g[in_stick] <= 1 + 1e-9))
    slip = r.mode == 0
    assert np.all(r.g[slip] == 0.0) and np.all(r.du[slip] >= -P.v0 - 1e-9)


def _hermite_eval(t, y, dy, tq):
    k = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, t.size - 2)
    h = t[k + 1] - t[k]
    s = (tq - t[k]) / h
    return (
        (2 * s**3 - 3 * s**2 + 1) * y[k]
        + (s**3 - 2 * s**2 + s) * h * dy[k]
        + (-2 * s**3 + 3 * s**2) * y[k + 1]
        + (s**3 - s**2) * h * dy[k + 1]
    )


def test_delay_and_depth_recomputed_from_returned_arrays(ref_run):
    """tau_n and d solve (14) and (5) for the returned trajectory (recomputed independently
    from the sampled u, phi by interpolation and bisection)."""
    r = ref_run
    t = r.tau
    U = r.u + P.v0 * t
    V = r.du + P.v0
    Phi = r.phi + P.omega0 * t
    W = r.dphi + P.omega0
    blade = 2 * math.pi / P.n
    idx = np.arange(2000, t.size, 97)
    errs_tau, errs_d = [], []
    for i in idx:
        target = Phi[i] - blade
        lo, hi = t[0], t[i]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if _hermite_eval(t, Phi, W, mid) <= target:
                lo = mid
            else:
                hi = mid
        s = 0.5 * (lo + hi)
        errs_tau.append(abs((t[i] - s) - r.tau_n[i]))
        errs_d.append(abs(U[i] - _hermite_eval(t, U, V, s) - r.d[i]))
    print("max tau_n error", max(errs_tau), "max d error", max(errs_d))
    assert max(errs_tau) < 1e-6
    assert max(errs_d) < 1e-6


def live_history(e: Engine) -> np.ndarray:
    """A copy of the engine's live history window (one column a node)."""
    s = e.kernel_arrays()
    return s.history[:, int(s.ints[S.I_HSTART]) : int(s.ints[S.I_HEND])].copy()


def test_restore_is_bit_identical():
    e = Engine(P, initial={"dphi": -2.5})
    assert e.advance(5.0).ok
    snap = e.get_state()
    blob = e.serialize_state()
    assert e.advance(10.0).ok
    first = (e.total_state(), e.outputs(), live_history(e), e.counters)
    e.set_state(snap)
    assert e.tau == 5.0
    assert e.advance(10.0).ok
    second = (e.total_state(), e.outputs(), live_history(e), e.counters)
    fresh = Engine(P)
    fresh.deserialize_state(blob)
    assert fresh.advance(10.0).ok
    third = (fresh.total_state(), fresh.outputs(), live_history(fresh), fresh.counters)
    for other in (second, third):
        assert np.array_equal(first[0], other[0])
        assert first[1] == other[1]
        assert np.array_equal(first[2], other[2])
        assert first[3]["steps"] == other[3]["steps"]


def test_history_memory_is_bounded():
    e = Engine(P, initial={"dphi": -2.5})
    sizes = []
    for k in range(1, 31):
        assert e.advance(2.0 * k).ok
        sizes.append(live_history(e).shape[1])
    tau_n_max = 2 * math.pi / P.n / (P.omega0 - 4.0)
    assert max(sizes) < 1.5 * tau_n_max / e.options.h + 50
    assert e.kernel_arrays().history.shape[1] <= 4 * 2048


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"h": 0.0}, "h"),
        ({"h": float("nan")}, "h"),
        ({"on_invalid": "ignore"}, "on_invalid"),
        ({"event_tol": 1e-3}, "event_tol"),
        ({"history_capacity": 3}, "history_capacity"),
    ],
)
def test_bad_options(kwargs, field):
    with pytest.raises(ValueError, match=field):
        EngineOptions(**kwargs)


def test_bad_inputs_give_clear_errors():
    e = Engine(P)
    with pytest.raises(ValueError, match="finite"):
        e.set_input(float("nan"))
    with pytest.raises(ValueError, match="finite"):
        e.set_input(float("inf"))
    with pytest.raises(ValueError, match="number"):
        e.set_input("abc")
    assert e.advance(0.1).ok
    with pytest.raises(ValueError, match="before the current time"):
        e.advance(0.05)
    with pytest.raises(ValueError, match="dphi"):
        Engine(P, initial={"dphi": -6.0})
    with pytest.raises(ValueError, match="unknown"):
        Engine(P, initial={"dphii": 0.0})
    with pytest.raises(ValueError, match="finite"):
        Engine(P, initial={"u": float("nan")})
    with pytest.raises(TypeError, match="control"):
        Engine(P, control="fast")


def test_nan_from_callable_control_stops_the_run():
    e = Engine(P, control=lambda tau, y: float("nan") if tau > 0.01 else 0.0)
    st = e.advance(0.1)
    assert not st.ok and st.code == "nonfinite" and "tau" in st.message


def test_callable_control_matches_compiled_affine_law():
    """The plain-Python kernel (callable law) and the compiled one (AffineFeedback) agree."""
    F = (-3448.5, -1574.7, 481.8, -89.0)
    K0, r_ff = 0.5, -0.5
    law = AffineFeedback(F=F, K0=K0, R_ff=r_ff)

    def f(tau, y):
        x = (y[2], y[3], y[2] - y[4] - K0, y[5])
        return r_ff + F[0] * x[0] + F[1] * x[1] + F[2] * x[2] + F[3] * x[3]

    a = simulate(P, 0.5, control=law, initial={"dphi": -2.5}, progress=False)
    b = simulate(P, 0.5, control=f, initial={"dphi": -2.5}, progress=False)
    for name in ("u", "du", "phi", "dphi", "theta", "dtheta"):
        assert np.max(np.abs(getattr(a, name) - getattr(b, name))) < 1e-10, name


def test_torsional_stick_outside_model_stops_with_status():
    r = simulate(P, 40.0, control=-0.9, initial={"dphi": -4.9}, progress=False)
    assert not r.status.ok
    assert r.status.code == "torsional_stick"
    assert "torsional stick" in r.status.message and "tau" in r.status.message
    assert r.flags["torsional_stick"]
    assert abs(r.dphi[-1] + P.omega0) < 1e-9  # stopped where W reached 0


def test_torsional_stick_model():
    opts = EngineOptions(torsional_stick=True)
    r = simulate(P, 40.0, control=-0.9, initial={"dphi": -4.9}, options=opts, progress=False)
    assert r.status.ok, r.status
    assert r.counters["torsional_stick_events"] >= 1
    W = r.dphi + P.omega0
    assert np.min(W) >= -1e-9
    stuck = r.mode == 3
    assert stuck.any()
    assert np.all(W[stuck] == 0.0) and np.all(r.du[stuck] == -P.v0)
    assert np.all(r.d >= 0.0)


def test_bit_bounce_stop_or_continue():
    kick = {"du": -100.0}
    r = simulate(P, 2.0, initial=kick, progress=False)
    assert r.status.code == "bit_bounce" and "d < 0" in r.status.message
    assert abs(r.d[-1]) < 1e-9
    opts = EngineOptions(on_invalid="continue")
    r2 = simulate(P, 2.0, initial=kick, options=opts, progress=False)
    assert r2.status.ok and r2.counters["bit_bounce_events"] >= 1
    assert r2.flags["bit_bounce"]


#: The runs compared between the compiled and the plain-Python kernel: stick-slip with axial
#: stick events, and torsional stick with the feedback switched on inside the run.
_PLAIN_RUNS = r"""
import sys
import numpy as np
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import EngineOptions
from drillstring.model.kernel import state as S
from drillstring.model.kernel.jit import numba_available
from drillstring.model.params import REFERENCE
from drillstring.model.simulate import simulate

def runs():
    law = AffineFeedback((-3353.5916, -2028.4214, 520.6036, -57.1065), 0.183892, -0.183892,
                         t_on=1.5, latch="angle")
    yield simulate(REFERENCE, 2.0, initial={"dphi": -2.5}, options=EngineOptions(h=1e-3),
                   progress=False)
    yield simulate(REFERENCE, 2.0, initial={"dphi": -4.9, "theta": -1.0}, control=law,
                   options=EngineOptions(h=1e-3, torsional_stick=True), progress=False)

if __name__ == "__main__":
    assert not numba_available()
    out = {}
    for i, r in enumerate(runs()):
        for c, v in r.data.items():
            out[f"{i}.{c}"] = v
        out[f"{i}.events"] = np.array([(e.tau, e.V, e.gstar, e.u, e.g_integral)
                                       for e in r.events])
        out[f"{i}.counters"] = np.array(list(r.counters.values()))
    np.savez(sys.argv[1], **out)
"""


def test_plain_python_kernel_is_bit_identical(tmp_path):
    """DRILLSTRING_JIT=0 runs the same source as plain Python: the same numbers, bit for bit,
    through axial stick, torsional stick, a switch-on and its events."""
    assert numba_available()  # the comparison needs the compiled kernel here
    script = tmp_path / "plain_runs.py"
    script.write_text(_PLAIN_RUNS)
    env = {**os.environ, "DRILLSTRING_JIT": "0"}
    subprocess.run([sys.executable, str(script), str(tmp_path / "plain.npz")], env=env, check=True)
    plain = np.load(tmp_path / "plain.npz")
    namespace: dict = {}
    exec(compile(_PLAIN_RUNS, str(script), "exec"), namespace)  # the same runs, compiled here
    for i, r in enumerate(namespace["runs"]()):
        assert r.status.ok and r.counters["stick_events"] >= 2
        if i == 1:
            assert any(e.kind == "switch_on" for e in r.events)
            assert r.counters["torsional_stick_events"] >= 1
        for c, v in r.data.items():
            assert np.array_equal(plain[f"{i}.{c}"], v), (i, c)
        ev = np.array([(e.tau, e.V, e.gstar, e.u, e.g_integral) for e in r.events])
        assert np.array_equal(plain[f"{i}.events"], ev)
        assert np.array_equal(plain[f"{i}.counters"], np.array(list(r.counters.values())))
