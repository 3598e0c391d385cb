"""The paper's closed-loop Figs. 5 and 6 by co-simulation of the two FMUs.

Checks are made on the written CSV (every communication point), not on the summary alone:
the co-simulated curves coincide with the monolithic ones, the torsional vibration dies out
(Fig. 5), and in Fig. 6 torsional stick-slip occurs before the switch-on and never after, with
d >= 0 and a small ripple at the end. Before the switch-on of Fig. 6 the loop is open (the
controller outputs R_ff), so there is no coupling error at all: co-simulation and monolithic run
must then agree to round-off.

One path for the data: the gains and the parameter set are the FMUs' own (baked in by
``build_fmus.py --gains``), the run starts from the SSP package of the loop, an experiment passes
only its own start values, and the monolithic twin reads the start values the master's units
begin with (each model description read once per run). FMUs built from other gains give another
closed loop, and its twin follows.
"""

from __future__ import annotations

import collections
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from drillstring.controller.gains import read_gains
from drillstring.model.control import AffineFeedback
from drillstring.model.experiments import FIG5, FIG6
from drillstring.model.params import REFERENCE
from drillstring.model.topdrive import TDS_11SA
from drillstring.orchestration import connections
from drillstring.orchestration.closed_loop import (
    closed_loop_master,
    experiment_start_values,
    read_loop_model,
)
from drillstring.orchestration.figures import FIG6_RIPPLE, run_pair, write_fig5, write_fig6

pytestmark = pytest.mark.fmu

PNG = b"\x89PNG\r\n\x1a\n"


def _read(path) -> np.ndarray:
    return np.genfromtxt(path, delimiter=",", names=True)


def test_fig5_cosim_matches_monolithic_and_torsion_dies_out(built, tmp_path):
    tau_end, H, dphi0 = 30.0, 1e-3, FIG5.dphi0
    fig5 = dataclasses.replace(FIG5, tau_end=tau_end)
    s = write_fig5(tmp_path, built.out, H=H, experiment=fig5, csv_dt=None)
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


def test_fig6_switch_on_suppresses_torsional_stick_slip(built, tmp_path, monkeypatch):
    tau_end, H, t_on, dphi0 = FIG6.tau_end, 1e-3, FIG6.t_on, FIG6.dphi0
    parsed: collections.Counter[str] = collections.Counter()
    read = connections.read_model_description

    def counted(path, *args, **kwargs):
        parsed[Path(path).name] += 1
        return read(path, *args, **kwargs)

    monkeypatch.setattr(connections, "read_model_description", counted)
    s = write_fig6(tmp_path, built.out, H=H, csv_dt=None)
    monkeypatch.undo()
    # the run, its twin and its checks read each model description once
    assert parsed == {"DrillStringPlant.fmu": 1, "TorsionalController.fmu": 1}
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
    omega0 = read_loop_model(built.out, FIG6).params.omega0
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
    # what the paper's set-up asks of the actuator (from the monolithic twin), stated on the
    # figure: the co-simulation's own torque agrees, and no real top drive delivers it
    R0 = read_loop_model(built.out, FIG6).params.R0
    a = s["actuator"]
    peak = (R0 + np.max(d["R_minus_R0_cosim"])) / R0
    assert a["peak_torque_over_R0"] == pytest.approx(peak, rel=1e-2) and peak > 500.0
    assert a["within_tds_11sa"] is False and a["peak_torque_Nm"] > 10 * TDS_11SA.torque
    assert "beyond a NOV TDS-11SA (50.8 kN m, 597 kW, 0-228 rpm)" in s["assumes"]


def test_run_pair_rejects_bad_macro_steps(built):
    one = dataclasses.replace(FIG5, tau_end=1.0)
    with pytest.raises(ValueError, match="multiple of the engine step"):
        run_pair(built.out, one, 3e-4)
    with pytest.raises(ValueError, match="positive finite"):
        run_pair(built.out, one, -1e-3)
    with pytest.raises(ValueError, match="multiple of the macro step"):
        run_pair(built.out, dataclasses.replace(FIG5, tau_end=1.0005), 1e-3)
    with pytest.raises(ValueError, match="t_on must lie inside"):
        write_fig6("unused", built.out, experiment=dataclasses.replace(FIG6, tau_end=20.0))
    with pytest.raises(ValueError, match="feedback enabled"):
        write_fig6("unused", built.out, experiment=dataclasses.replace(FIG6, enabled=False))
    with pytest.raises(ValueError, match="not of the form 'plant.variable'"):
        run_pair(built.out, one, 1e-3, overrides={"F[1]": 1.0})


# ------------------------------------------------------------------------------------------------
# one path for the data
# ------------------------------------------------------------------------------------------------


def test_experiment_passes_only_its_own_start_values(built):
    """The units get dphi0, h, torsional_stick_model and t_on, latch, enabled: no gains, no
    parameter set (those are the FMUs' own)."""
    assert experiment_start_values(FIG6) == {
        "plant": {"dphi0": -4.9, "h": 5e-4, "torsional_stick_model": True},
        "controller": {"t_on": 25.0, "latch": 2, "enabled": True},  # Enumeration item "angle"
    }
    with closed_loop_master(built.out, FIG5, overrides={"controller.K0": 0.1}) as m:
        plant, controller = m.system.units
    assert set(plant.start_values) == {"dphi0", "h", "torsional_stick_model"}
    assert set(controller.start_values) == {"t_on", "latch", "enabled", "K0"}


def test_twin_reads_the_gains_and_parameters_baked_into_the_fmus(built):
    """Against the gains file the FMUs were built from (independent of the FMUs' XML)."""
    g = built.gains_values
    model = read_loop_model(built.out, FIG5)
    assert model.params == REFERENCE
    assert model.control == AffineFeedback(tuple(g["F"]), g["K0"], g["R_ff"], 0.0, "none")
    assert model.initial.dphi == FIG5.dphi0 and model.options.h == FIG5.h
    assert not model.options.torsional_stick
    off = read_loop_model(built.out, dataclasses.replace(FIG5, enabled=False))
    assert off.control == g["R_ff"]
    over = read_loop_model(built.out, FIG5, {"plant.rho": 4.0, "controller.F[2]": -1.0})
    assert over.params == dataclasses.replace(REFERENCE, rho=4.0)
    assert over.control.F == (g["F"][0], -1.0, *g["F"][2:])


@pytest.fixture(scope="module")
def rebuilt(built, other_gains):
    """A controller FMU built from other gains than the session's (conftest's ``other_gains``,
    beside the session's plant), and those gains."""
    gains = read_gains(other_gains.gains)
    assert gains.F != read_gains(built.gains).F
    return other_gains.out, gains


def test_build_gains_change_the_results_and_the_twin_follows(built, rebuilt):
    out, gains = rebuilt
    assert read_loop_model(out, FIG5).control.F == gains.F
    short = dataclasses.replace(FIG5, tau_end=2.0)
    cos_a, _, s_a, _ = run_pair(built.out, short, 1e-3)
    cos_b, _, s_b, twin = run_pair(out, short, 1e-3)
    assert twin.control.F == gains.F
    change = float(np.max(np.abs(cos_b["plant.dphi"] - cos_a["plant.dphi"])))
    print(
        f"max |dphi change| from the gains: {change:.3e}; co-sim vs twin: "
        f"{s_a['max_abs_diff_dphi']:.3e} (session build), {s_b['max_abs_diff_dphi']:.3e} (other)"
    )
    assert change > 1e-2  # the build's --gains has an effect on the co-simulation ...
    # ... and the twin describes the same system: the coupling error stays as small as before,
    # far below the change
    assert s_b["max_abs_diff_dphi"] < 1e-3 * abs(FIG5.dphi0)
    assert s_b["max_abs_diff_dphi"] < 1e-2 * change
