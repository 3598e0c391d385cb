"""Closed loop on the full nonlinear model (paper Fig. 5, Remark 1), monolithic solver."""

from __future__ import annotations

import numpy as np
import pytest

from drillstring.analysis.limit_cycles import design_inputs
from drillstring.controller.averaged import averaged_model
from drillstring.controller.gains import PAPER_F
from drillstring.controller.synthesis import synthesize
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import EngineOptions, stick_entries
from drillstring.model.params import REFERENCE
from drillstring.model.simulate import simulate

DPHI0 = -2.5


@pytest.fixture(scope="module")
def lmi_design():
    inputs = design_inputs(REFERENCE)
    return synthesize(averaged_model(REFERENCE, inputs.A, inputs.taubar_crit))


@pytest.mark.parametrize("which", ["lmi", "paper"])
def test_fig5_controller_stabilises_torsion_while_axial_stick_slip_persists(lmi_design, which):
    m = lmi_design.model
    F = tuple(lmi_design.F) if which == "lmi" else PAPER_F
    law = AffineFeedback(F=F, K0=m.K0, R_ff=m.R_ff)
    r = simulate(REFERENCE, 60.0, control=law, initial={"dphi": DPHI0}, progress=False)
    assert r.status.ok, r.status.message
    assert not r.flags["bit_bounce"] and not r.flags["torsional_stick"]
    assert np.all(r.d >= 0) and np.all(r.dphi > -REFERENCE.omega0)
    late = r.tau >= 50.0
    amplitude = np.max(np.abs(r.dphi[late]))
    print(f"{which}: max |dphi| on [50, 60] = {amplitude:.4f}")
    assert amplitude < 0.05 * abs(DPHI0)
    late_sticks = [e for e in stick_entries(r.events) if e.tau >= 50.0]
    assert len(late_sticks) >= 10  # axial stick-slip continues under torsional control


def test_open_loop_with_feedforward_only_does_not_converge(lmi_design):
    """Without feedback the averaged torsion is unstable (velocity weakening): no convergence."""
    m = lmi_design.model
    r = simulate(REFERENCE, 60.0, control=m.R_ff, initial={"dphi": DPHI0}, progress=False)
    late = r.tau >= 50.0
    assert (not r.status.ok) or np.max(np.abs(r.dphi[late])) > 0.5 * abs(DPHI0)


def test_fig6_switch_on_suppresses_torsional_stick_slip(lmi_design):
    """Fig. 6: torsional stick-slip under way (torsional-stick model on), controller switched on
    bumplessly at tau = 25: no torsional stick afterwards, dphi back to a small ripple."""
    m = lmi_design.model
    law = AffineFeedback(F=tuple(lmi_design.F), K0=m.K0, R_ff=m.R_ff, t_on=25.0, latch="angle")
    opts = EngineOptions(torsional_stick=True)
    r = simulate(REFERENCE, 60.0, control=law, initial={"dphi": -4.9}, options=opts, progress=False)
    assert r.status.ok, r.status.message
    stick_starts = [e.tau for e in r.events if e.to_mode == "torsional_stick"]
    assert len(stick_starts) >= 2 and max(stick_starts) < 25.0
    assert [e.tau for e in r.events if e.kind == "switch_on"] == [25.0]
    after = r.tau > 25.0
    assert np.all(r.mode[after] != 3)
    assert np.all(r.d >= 0.0)
    late = r.tau >= 50.0
    assert np.max(np.abs(r.dphi[late])) < 0.05 * 4.9
