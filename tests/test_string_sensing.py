"""The digital controller's string torque on the distributed string.

A torque sub under the top drive reads the torque of the string's top element (the kernel's
``top_torque_minus_R0``), not the twist theta - phi of the whole string; the motor-torque
estimate divides by the table node's inertia rho + kappa/(2N). Checked by replaying the sampled
loop's rows through the controller's own compiled sample, given the kernel's top torque.
"""

from __future__ import annotations

import numpy as np

from drillstring.model.digital.controller import DigitalController, Running
from drillstring.model.digital.layout import BLOCK
from drillstring.model.laws import ZTorque
from drillstring.model.params import REFERENCE
from drillstring.model.pipe import rig_string, torsional_chain
from drillstring.model.sampled import simulate_sampled
from drillstring.model.sensing import Sensing, string_torque

TS = 1e-3


def _replay(controller, r, rho=None):
    """The controller's applied torques at the rows of ``r`` (one row per sample), given the
    plant's measurements and the kernel's top torque of each row; and its torque estimates."""
    block = controller.block(REFERENCE)
    if rho is not None:
        block[BLOCK.rho] = rho
    run = Running(controller, block)
    applied, sensed = [], []
    for k in range(len(r.tau) - 1):
        m = (r.phi[k], r.dphi[k], r.theta[k], r.dtheta[k])
        top = r.top_torque_minus_R0[k]
        sensed.append(string_torque(block, BLOCK.sensing, block[BLOCK.rho], top, r.dtheta[k]))
        applied.append(run.step(k * TS, *m, TS, top=top))
    return np.array(applied), np.array(sensed)


def test_the_string_torque_sensed_on_the_string_is_the_top_elements() -> None:
    string = rig_string("reference-rig", 8)
    law = ZTorque(kp=20.0, ki=5.0, z_gain=1.0, R_ff=0.0, t_on=0.0)
    ctl = DigitalController(law)
    r = simulate_sampled(REFERENCE, ctl, 2.0, TS, initial={"dphi": -2.0}, dt_out=TS,
                         string=string)  # fmt: skip
    # the string rings: its top torque is not the whole string's twist
    assert np.max(np.abs(r.top_torque_minus_R0 - (r.theta - r.phi))) > 0.05
    applied, sensed = _replay(ctl, r)
    assert np.array_equal(sensed, r.top_torque_minus_R0[:-1])
    # the loop's applied torques are the replay's, bit for bit, given the top torque
    assert np.array_equal(applied, r.R_minus_R0[: len(applied)])


def test_the_motor_estimate_uses_the_table_nodes_inertia() -> None:
    string = rig_string("reference-rig", 8)
    J0 = torsional_chain(string, REFERENCE.rho).inertia[0]
    assert J0 > REFERENCE.rho
    law = ZTorque(kp=20.0, ki=5.0, z_gain=1.0, R_ff=0.0, t_on=0.0)
    ctl = DigitalController(law, sensing=Sensing(torque="motor"))
    r = simulate_sampled(REFERENCE, ctl, 2.0, TS, initial={"dphi": -2.0}, dt_out=TS,
                         string=string)  # fmt: skip
    applied, est = _replay(ctl, r, rho=J0)
    assert np.array_equal(applied, r.R_minus_R0[: len(applied)])
    # the estimate is the top torque's mean over the last sample: within half a sample's change
    mid = 0.5 * (r.top_torque_minus_R0[:-2] + r.top_torque_minus_R0[1:-1])
    assert np.max(np.abs(est[1:] - mid)) < 1e-3 * np.max(np.abs(r.top_torque_minus_R0))
