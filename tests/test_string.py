"""The distributed string in the engine (``docs/model.md``, "The distributed string").

Each check is against something independent of the chain's code: the paper's one-mode engine
run (bit for bit), the continuous string's travel time sqrt(kappa), an energy balance of the
torsional string written from the equations of motion, and convergence as N doubles.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import drillstring as ds
from drillstring.analysis.string_figures import write_string_fig6
from drillstring.apps.simulate import simulate_main
from drillstring.controller.gains import PAPER_F
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import Engine, EngineOptions
from drillstring.model.params import get_params
from drillstring.model.pipe import REFERENCE_KAPPA, StringParams, rig_string, torsional_chain

TSTICK = EngineOptions(torsional_stick=True)


def _run(n: int | None, tau_end: float, **kw) -> ds.SimulationResult:
    string = None if n is None else StringParams(elements=n)
    return ds.simulate(ds.REFERENCE, tau_end, string=string, progress=False, **kw)


def test_one_paper_element_is_the_paper_model_bit_for_bit() -> None:
    # Fig. 6's open loop with torsional stick, through stick events: the explicit paper string
    # against the default engine (whose runs the stored hashes of test_limits_off pin)
    a = _run(None, 30.0, initial={"dphi": -4.9}, options=TSTICK)
    b = _run(1, 30.0, initial={"dphi": -4.9}, options=TSTICK)
    assert a.counters["torsional_stick_events"] > 0
    for c in ("u", "du", "phi", "dphi", "theta", "dtheta", "d", "g", "tau_n"):
        assert np.array_equal(a.data[c], b.data[c]), c
    # on one element the top-of-string torque is the twist of (12)-(13)
    assert np.allclose(a.top_torque_minus_R0, a.theta - a.phi, rtol=0.0, atol=1e-12)
    # and it is the first element's torque of the profiles
    assert np.allclose(a.top_torque_minus_R0, a.profiles["torque_minus_R0"][:, 0], atol=1e-12)


def test_a_lumped_single_element_is_not_the_paper_model() -> None:
    # the lumped lumping at N = 1 puts half the pipe at each end: another model, not the paper's
    a = _run(None, 5.0, initial={"dphi": -2.5})
    b = ds.simulate(
        ds.REFERENCE,
        5.0,
        initial={"dphi": -2.5},
        string=StringParams(elements=1, lumping="lumped"),
        progress=False,
    )
    assert np.max(np.abs(a.dphi - b.dphi)) > 0.1


def _arrival(n: int) -> float:
    # a torque step at the table from the steady state: the first instant at which the bit
    # element's torque has moved by 1e-3 of the step
    r = _run(n, 2.5, control=0.1, dt_out=1e-3)
    assert r.status.ok
    s_bit = r.profiles["torque_minus_R0"][:, -1]
    moved = np.abs(s_bit - s_bit[0]) > 1e-4
    assert moved.any()
    return float(r.tau[np.argmax(moved)])


def test_a_torque_step_reaches_the_bit_after_the_travel_time() -> None:
    travel = math.sqrt(REFERENCE_KAPPA)  # the continuous string's one-way travel time
    assert _arrival(1) < 0.15 * travel  # the massless spring of the paper has no delay
    errors = [travel - _arrival(n) for n in (16, 32, 64, 128)]
    # the lumped chain's front runs ahead of the continuous one (dispersion) and converges
    assert all(e > 0.0 for e in errors), errors
    assert all(b < 0.7 * a for a, b in zip(errors, errors[1:], strict=False)), errors
    assert errors[-1] < 0.03 * travel


def _torsional_energy(r: ds.SimulationResult) -> np.ndarray:
    p = r.params
    chain = torsional_chain(r.string, p.rho)
    speed = p.omega0 + r.profiles["dphi_node"]  # total speeds, table to bit
    torque = p.R0 + r.profiles["torque_minus_R0"]  # total element torques
    kinetic = 0.5 * (speed**2 @ chain.inertia)
    strain = 0.5 * np.sum(torque**2, axis=1) / chain.stiffness
    return kinetic + strain


def _torque_on_bit(r: ds.SimulationResult) -> np.ndarray:
    p = r.params
    d, g = r.d, r.g
    return p.n * (d + p.beta * p.lam * (1.0 - g))


@pytest.mark.parametrize("n", [1, 8])
def test_energy_balance_of_the_torsional_string_across_stick_events(n: int) -> None:
    # table power (R0 + r)*Wt in, bit power T*W out, the string's kinetic and strain energy
    # between: written from the equations of motion, not from the code. In torsional stick
    # W = 0, so the bit takes no power whatever T is.
    r = _run(n, 30.0, initial={"dphi": -4.9}, options=TSTICK, dt_out=2e-4)
    assert r.status.ok and r.counters["torsional_stick_events"] > 0
    p = r.params
    table_power = p.R0 * (p.omega0 + r.dtheta)  # R - R0 = 0: the open loop
    bit_power = _torque_on_bit(r) * (p.omega0 + r.dphi)
    net = table_power - bit_power
    work = np.concatenate([[0.0], np.cumsum(0.5 * (net[1:] + net[:-1]) * np.diff(r.tau))])
    energy = _torsional_energy(r)
    throughput = np.trapezoid(np.abs(table_power), r.tau)
    err = np.max(np.abs((energy - energy[0]) - work)) / throughput
    # measured 3.2e-6 (N = 1) and 2.2e-6 (N = 8) of the throughput, falling with the grid: the
    # trapezoid rule on the output grid, first order where the contact switches between samples
    assert err < 1e-5, err


def test_the_fig6_open_loop_converges_as_n_doubles() -> None:
    runs = {n: _run(n, 10.0, initial={"dphi": -4.9}, options=TSTICK) for n in (8, 16, 32, 64)}
    diffs = [np.max(np.abs(runs[n].dphi - runs[2 * n].dphi)) for n in (8, 16, 32)]
    assert diffs[0] > diffs[1] > diffs[2], diffs
    assert diffs[2] < 0.3 * diffs[0], diffs


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (0, "positive integer, got 0"),
        (-3, "positive integer, got -3"),
        (2.5, "got 2.5"),
        (10**6, "<= 4096, got 1000000"),
        ("8", "got '8'"),
    ],
)
def test_bad_element_counts_are_refused_naming_the_value(value: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        StringParams(elements=value)  # type: ignore[arg-type]


def test_more_elements_than_rk4_integrates_stably_is_refused() -> None:
    # h = 0.05: the chain's highest frequency 2N/sqrt(kappa) times h must stay below 2.5
    with pytest.raises(ValueError, match="string elements = 64 is more than RK4"):
        Engine(ds.REFERENCE, EngineOptions(h=0.05), string=StringParams(elements=64))


def test_the_state_round_trips_with_the_string() -> None:
    e = Engine(ds.REFERENCE, initial={"dphi": -2.5}, string=StringParams(elements=8))
    e.advance(3.0)
    saved = e.serialize_state()
    e.advance(4.0)
    ref = e.string_nodes()
    f = Engine(ds.REFERENCE, initial={"dphi": -2.5}, string=StringParams(elements=8))
    f.deserialize_state(saved)
    f.advance(4.0)
    assert np.array_equal(f.string_nodes(), ref)
    assert ref.size == 2 * 7  # seven inner nodes, angle and speed


def test_simulate_command_writes_the_string_along_its_length(tmp_path) -> None:
    out = tmp_path / "run"
    argv = ["--tau-end", "1", "--dphi0", "-2.5", "--elements", "4", "--dt-out", "0.5"]
    assert simulate_main([*argv, "--out", str(out)]) == 0
    nodes = np.genfromtxt(out / "string_nodes.csv", delimiter=",", names=True)
    elements = np.genfromtxt(out / "string_elements.csv", delimiter=",", names=True)
    assert nodes.size == 3 * 5 and elements.size == 3 * 4  # 3 samples, 5 nodes, 4 elements
    at0 = nodes[nodes["tau_scaled"] == 0.0]
    # the initial speed perturbation runs linearly from the table (0) to the bit (-2.5)
    assert np.allclose(at0["dphi_node_scaled"], [0.0, -0.625, -1.25, -1.875, -2.5], atol=1e-12)
    assert np.allclose(at0["x_scaled"], [0.0, 0.25, 0.5, 0.75, 1.0])
    assert set(elements.dtype.names) == {
        "tau_scaled",
        "element",
        "x_scaled",
        "torque_minus_R0_scaled",
    }


def test_simulate_command_refuses_a_bad_element_count(tmp_path, capsys) -> None:
    assert simulate_main(["--elements", "0", "--out", str(tmp_path / "x")]) == 2
    assert "elements must be a positive integer, got 0" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_the_pipe_rig_distributes_the_axial_string_too() -> None:
    p = get_params("pipe-rig")
    string = rig_string("pipe-rig", 8)
    assert string.axial_distributed
    r = ds.simulate(p, 2.0, initial={"du": 0.5}, string=string, progress=False, dt_out=0.01)
    assert r.status.ok
    u = r.profiles["u_node"]
    assert u.shape == (r.tau.size, 9) and np.all(u[:, 0] == 0.0)  # the hook's feed is imposed
    # the axial wave: the inner nodes have moved off the initial straight stretch by t = 2
    straight = np.outer(r.u, r.profiles["x_axial"])
    assert np.max(np.abs(u[-1] - straight[-1])) > 1e-3
    # the reference rig keeps the paper's massless axial spring
    assert not rig_string("reference-rig", 8).axial_distributed


def test_fig6_on_both_strings_is_written_in_si(tmp_path) -> None:
    p = ds.REFERENCE
    law = AffineFeedback(PAPER_F, 0.18, -0.18)
    info = write_string_fig6(tmp_path, law, elements=8)
    data = np.genfromtxt(info["csv"], delimiter=",", names=True)
    assert set(data.dtype.names) == {
        "time_s",
        "bit_speed_rpm_one_mode",
        "bit_speed_rpm_string",
        "top_torque_kNm_one_mode",
        "top_torque_kNm_string",
    }
    rig = ds.REFERENCE_RIG
    # at t = 0 both start from dphi/dtau = -4.9 of the nominal 51.76 rpm, with the nominal
    # torque R0 = 1037.9 N m at the top of the string (docs/reference_rig.md)
    start_rpm = (p.omega0 - 4.9) / rig.t_star * 60 / (2 * math.pi)
    assert data["bit_speed_rpm_one_mode"][0] == pytest.approx(start_rpm, rel=1e-12)
    assert data["bit_speed_rpm_string"][0] == pytest.approx(start_rpm, rel=1e-12)
    assert data["top_torque_kNm_string"][0] == pytest.approx(rig.R0 / 1e3, rel=1e-9)
    assert data["time_s"][-1] <= ds.FIG6.tau_end * rig.t_star * (1 + 1e-12)
    assert info["png"].stat().st_size > 10_000
    # the one-mode run is the plain engine run of Fig. 6 with that law
    ref = ds.simulate(
        p,
        ds.FIG6.tau_end,
        control=AffineFeedback(PAPER_F, 0.18, -0.18, t_on=ds.FIG6.t_on, latch="angle"),
        initial=ds.FIG6.initial(),
        options=TSTICK,
        progress=False,
    )
    speed = (p.omega0 + ref.dphi) / rig.t_star * 60 / (2 * math.pi)
    assert np.allclose(data["bit_speed_rpm_one_mode"], speed[: data.size], rtol=1e-12, atol=0)


def test_a_state_with_a_non_finite_inner_node_is_refused() -> None:
    e = Engine(ds.REFERENCE, initial={"dphi": -2.5}, string=StringParams(elements=4))
    e.advance(1.0)
    state = e.get_state()
    state.arrays["chain"][0, 1] = np.nan  # an inner node's angle
    with pytest.raises(ValueError, match="array 'chain' holds non-finite numbers"):
        e.set_state(state)
    bad_shape = e.get_state()
    bad_shape.arrays["chain"] = bad_shape.arrays["chain"][:, :2]
    with pytest.raises(ValueError, match="array 'chain' has shape"):
        e.set_state(bad_shape)
