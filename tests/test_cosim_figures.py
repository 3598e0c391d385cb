"""The paper's closed-loop Figs. 5 and 6 by co-simulation of the two FMUs (issue 6).

Checks are made on the written CSV (every communication point), not on the summary alone:
the co-simulated curves coincide with the monolithic ones, the torsional vibration dies out
(Fig. 5), and in Fig. 6 torsional stick-slip occurs before the switch-on and never after, with
d >= 0 and a small ripple at the end. Before the switch-on of Fig. 6 the loop is open (the
controller outputs R_ff), so there is no coupling error at all: co-simulation and monolithic run
must then agree to round-off.
"""

from __future__ import annotations

import fmu_testlib as tl
import numpy as np
import pytest

from drillstring.controller.gains import read_gains
from drillstring.orchestration.closed_loop import LoopSetup
from drillstring.orchestration.figures import FIG6_RIPPLE, run_pair, write_fig5, write_fig6

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="session")
def built(tmp_path_factory):
    return tl.built_fmus(tmp_path_factory)


@pytest.fixture(autouse=True)
def _sys_path():
    yield from tl.restore_sys_path()


def _read(path) -> np.ndarray:
    return np.genfromtxt(path, delimiter=",", names=True)


def test_fig5_cosim_matches_monolithic_and_torsion_dies_out(built, tmp_path):
    tau_end, H, dphi0 = 30.0, 1e-3, -2.5
    s = write_fig5(tmp_path, built.gains, built.out, H=H, tau_end=tau_end, csv_dt=None)
    print({k: v for k, v in s.items() if k not in ("png", "csv")})
    assert s["png"].read_bytes()[:8] == PNG
    d = _read(s["csv"])
    assert len(d) == round(tau_end / H) + 1
    assert np.allclose(d["tau"], np.arange(len(d)) * H, rtol=0, atol=1e-9)
    assert d["dphi_cosim"][0] == dphi0 and d["dphi_monolithic"][0] == dphi0
    err = np.max(np.abs(d["dphi_cosim"] - d["dphi_monolithic"]))
    assert err == pytest.approx(s["max_abs_diff_dphi"], rel=1e-12)
    # linear extrapolation (second order) at H = 1e-3: within 1e-3 of the initial deviation
    assert err < 1e-3 * abs(dphi0)
    late = d["tau"] >= tau_end - 10.0
    for col in ("dphi_cosim", "dphi_monolithic"):
        assert np.max(np.abs(d[col][late])) < 0.05 * abs(dphi0)
    assert np.ptp(d["du_cosim"][late]) > 1.0  # axial stick-slip goes on (Remark 1)
    assert np.all(d["d_cosim"] >= 0.0)
    assert s["cosim_completed"] and s["steps"] == round(tau_end / H)


def test_fig6_switch_on_suppresses_torsional_stick_slip(built, tmp_path):
    tau_end, H, t_on, dphi0 = 60.0, 1e-3, 25.0, -4.9
    s = write_fig6(tmp_path, built.gains, built.out, H=H, tau_end=tau_end, csv_dt=None)
    print({k: v for k, v in s.items() if k not in ("png", "csv")})
    assert s["png"].read_bytes()[:8] == PNG
    d = _read(s["csv"])
    assert len(d) == round(tau_end / H) + 1
    before = d["tau"] <= t_on
    count = d["torsional_stick_count_cosim"]
    # torsional stick-slip under way before t_on, none after
    assert count[before][-1] >= 2
    assert np.all(count[~before] == count[before][-1])
    # the bit stands still (dPhi/dtau = omega0 + dphi/dtau = 0) during the episodes, not after
    omega0 = read_gains(built.gains).params.omega0
    at_rest = d["dphi_cosim"] == -omega0
    assert np.sum(at_rest[before]) > 100 and not np.any(at_rest[~before])
    assert np.all(d["d_cosim"] >= 0.0)
    late = d["tau"] >= 50.0
    ripple = np.max(np.abs(d["dphi_cosim"][late]))
    assert ripple < FIG6_RIPPLE * abs(dphi0)
    # open loop before t_on: no coupling error, only round-off of the time grid
    for name in ("du", "dphi"):
        diff = np.abs(d[f"{name}_cosim"] - d[f"{name}_monolithic"])
        print(
            f"{name}: max |cosim - monolithic| before t_on {np.max(diff[before]):.2e}, "
            f"after {np.max(diff[~before]):.2e}"
        )
        assert np.max(diff[before]) < 1e-8
    # after t_on the curves coincide at plot resolution (1% of the initial deviation)
    assert np.max(np.abs(d["dphi_cosim"] - d["dphi_monolithic"])) < 1e-2 * abs(dphi0)
    # the summary states the same, and the monolithic run agrees on the episodes
    assert s["suppressed"] is True
    assert s["torsional_stick_before_t_on_cosim"] == int(count[before][-1])
    assert s["torsional_stick_after_t_on_cosim"] == 0
    assert s["torsional_stick_before_t_on_monolithic"] == s["torsional_stick_before_t_on_cosim"]
    assert s["torsional_stick_after_t_on_monolithic"] == 0
    assert s["bit_bounce_cosim"] == 0 and not s["torsional_stick_mode_after_t_on_cosim"]


def test_run_pair_rejects_bad_macro_steps(built):
    setup = LoopSetup()
    with pytest.raises(ValueError, match="multiple of the engine step"):
        run_pair(built.gains, built.out, setup, 1.0, 3e-4)
    with pytest.raises(ValueError, match="positive finite"):
        run_pair(built.gains, built.out, setup, 1.0, -1e-3)
    with pytest.raises(ValueError, match="multiple of the macro step"):
        run_pair(built.gains, built.out, setup, 1.0005, 1e-3)
    with pytest.raises(ValueError, match="t_on must lie inside"):
        write_fig6("unused", built.gains, built.out, tau_end=20.0, t_on=25.0)
