"""Tuning rules of the industrial laws (drillstring.controller.tuning, lineup).

The SoftSpeed rule states the damping of the string's torsional modes in closed form; the
closed loop of the linearised torsional model (13), (27) is built as a matrix and its
eigenvalues must give that damping. The matrix itself is checked against the characteristic
polynomial derived by hand.
"""

from __future__ import annotations

import dataclasses
import math

import fmu_testlib as tl
import numpy as np
import pytest

from drillstring.controller.averaged import averaged_model, linearised_ode_matrix
from drillstring.controller.gains import PAPER_F
from drillstring.controller.lineup import (
    INDUSTRIAL,
    Tuning,
    industrial_lineup,
    lmi_gain,
)
from drillstring.controller.tuning import (
    OMEGA_S,
    REFERENCE_PIPE,
    Pipe,
    impedance,
    linear_closed_loop,
    soft_speed,
    soft_speed_damping,
    stiff_pi,
    z_torque,
)
from drillstring.model.control import AffineFeedback
from drillstring.model.laws import SampledAffine, SpeedPI, ZTorque
from drillstring.model.params import REFERENCE, REFERENCE_RIG

A_REF, TAUBAR_CRIT_REF = 0.38541455958349763, 2.3927883571184694  # the reference design


def _model(rho: float, *, string_only: bool):
    m = averaged_model(REFERENCE.replace(rho=rho), A_REF, TAUBAR_CRIT_REF)
    return dataclasses.replace(m, c=0.0) if string_only else m


def _nonzero(ev: np.ndarray) -> np.ndarray:
    return ev[np.abs(ev) > 1e-9]


@pytest.mark.parametrize("rho", [2.5, 5.0, 10.0])
@pytest.mark.parametrize("kp_over_min", [1.0, 1.3, 1.6])
def test_soft_speed_gives_the_damping_it_states(rho, kp_over_min):
    """(13), (27) without velocity weakening (the lumped string), closed by the SoftSpeed PI:
    every torsional pole on |s| = omega_s, damping ratios as soft_speed_damping states."""
    params = REFERENCE.replace(rho=rho)
    kp = kp_over_min * 2.0 * math.sqrt(rho)
    law = soft_speed(params, kp=kp)
    ev = _nonzero(np.linalg.eigvals(linear_closed_loop(_model(rho, string_only=True), law)))
    assert ev.size == 4
    # a double pole (kp at its minimum) is only found to sqrt(machine epsilon)
    tol = 1e-6 if kp_over_min == 1.0 else 1e-10
    np.testing.assert_allclose(np.abs(ev), OMEGA_S, atol=tol)
    zeta = np.sort(-ev.real / np.abs(ev))
    lo, hi = soft_speed_damping(rho, kp)
    np.testing.assert_allclose(zeta, [lo, lo, hi, hi], atol=tol)
    assert lo * hi == pytest.approx(1.0 / (4.0 * rho), rel=1e-12)


def test_soft_speed_default_is_the_largest_common_damping():
    rho = REFERENCE.rho
    law = soft_speed(REFERENCE)
    assert (law.kp, law.ki) == (2.0 * math.sqrt(rho), rho)
    lo, hi = soft_speed_damping(rho, law.kp)
    assert lo == pytest.approx(1.0 / (2.0 * math.sqrt(rho)), rel=1e-7) == pytest.approx(hi)
    # a softer P gain pulls the poles off the circle and damps both modes less
    softer = SpeedPI(kp=0.8 * law.kp, ki=law.ki)
    ev = _nonzero(np.linalg.eigvals(linear_closed_loop(_model(rho, string_only=True), softer)))
    assert np.min(-ev.real / np.abs(ev)) < lo - 0.02
    with pytest.raises(ValueError, match="below 2\\*sqrt\\(rho\\)"):
        soft_speed_damping(rho, 0.8 * law.kp)
    with pytest.raises(ValueError, match="above 2\\*rho \\+ 1/2"):
        soft_speed_damping(rho, 2.0 * rho + 0.6)


def test_soft_speed_cancels_the_table_inertia_at_the_string_frequency():
    """The table with the PI, as an impedance torque/speed: rho*s + kp + ki/s = kp at s = i."""
    law = soft_speed(REFERENCE)
    s = 1j * OMEGA_S
    assert REFERENCE.rho * s + law.kp + law.ki / s == pytest.approx(law.kp, abs=1e-15)


def test_closed_loop_matrix_has_the_hand_derived_characteristic_polynomial():
    """(s^2 - nu*s + 1)(rho*s^2 + kp*s + ki + 1) - 1 = 0 with nu = -c*tau_n0 (phi and theta
    eliminated by hand), times s for the rigid-body angle."""
    m = _model(REFERENCE.rho, string_only=False)
    nu, rho = -m.c * m.tau_n0, m.rho
    kp, ki = 3.0, 4.0
    quartic = np.polymul([1.0, -nu, 1.0], [rho, kp, ki + 1.0]) - np.array([0, 0, 0, 0, 1.0])
    expected = np.polymul(quartic / rho, [1.0, 0.0])
    got = np.poly(linear_closed_loop(m, SpeedPI(kp=kp, ki=ki)))
    np.testing.assert_allclose(got, expected, atol=1e-12)
    # the paper's law: the ODE (13), (27) with R_fb = F x has the poles of A + B F
    F = np.asarray(PAPER_F)
    lmi = linear_closed_loop(m, SampledAffine(AffineFeedback(PAPER_F, m.K0, m.R_ff)))
    np.testing.assert_allclose(lmi, linearised_ode_matrix(m) + m.B @ F[None, :], atol=0)


def test_z_torque_tends_to_an_impedance_matched_top():
    """With the table following -torque/Z exactly (infinitely stiff loop, no filters), (13), (27)
    reduce to s^2 + (1 - nu)s + (1 - nu) = 0: |s| = sqrt(1 - nu), damping sqrt(1 - nu)/2. The
    law's closed loop approaches that pair as the loop stiffens and the filters open up, the
    error falling tenfold per decade of bandwidth."""
    m = _model(REFERENCE.rho, string_only=False)
    nu = -m.c * m.tau_n0
    target = complex(-(1.0 - nu) / 2.0, math.sqrt((1.0 - nu) - (1.0 - nu) ** 2 / 4.0))
    errors = []
    for bw in (1e2, 1e3, 1e4):
        law = z_torque(REFERENCE, bandwidth=bw, omega_hp=3.0 / bw, omega_lp=bw)
        ev = np.linalg.eigvals(linear_closed_loop(m, law))
        errors.append(float(np.min(np.abs(ev - target))))
    assert errors[-1] < 2e-4
    assert 8.0 < errors[0] / errors[1] < 12.0 and 8.0 < errors[1] / errors[2] < 12.0
    stiff = _nonzero(np.linalg.eigvals(linear_closed_loop(m, stiff_pi(REFERENCE))))
    assert np.max(stiff.real) > 0.0  # the stiff PI alone: the velocity weakening wins


def test_z_torque_high_pass_corner_is_the_fastest_for_the_string():
    """The default corner 0.3*omega_s minimises the spectral abscissa of the string-only closed
    loop over a grid of corners (to the grid's 0.05), at the reference rho = 5."""
    m = _model(REFERENCE.rho, string_only=True)
    corners = np.arange(0.05, 1.0, 0.05)

    def abscissa(w):
        ev = _nonzero(np.linalg.eigvals(linear_closed_loop(m, z_torque(REFERENCE, omega_hp=w))))
        return float(np.max(ev.real))

    best = corners[int(np.argmin([abscissa(w) for w in corners]))]
    assert z_torque(REFERENCE).omega_hp == 0.3
    assert abs(best - 0.3) <= 0.05 + 1e-12
    assert abscissa(0.3) < min(abscissa(0.1), abscissa(0.6)) - 0.1


def test_stiff_pi_and_z_torque_gains():
    pi = stiff_pi(REFERENCE, bandwidth=10.0, damping=1.0)
    assert (pi.kp, pi.ki) == (2 * 10.0 * 5.0, 100.0 * 5.0)
    zt = z_torque(REFERENCE, matching=0.5, omega_hp=0.2, omega_lp=8.0)
    assert isinstance(zt, ZTorque) and (zt.kp, zt.ki) == (pi.kp, pi.ki)
    assert (zt.z_gain, zt.omega_hp, zt.omega_lp) == (0.5, 0.2, 8.0)
    # a quarter of full matching against the pipe's impedance: z_gain = 0.25/Z
    assert z_torque(REFERENCE, matching=0.25, Z=2.0).z_gain == 0.125
    with pytest.raises(ValueError, match="stiff_pi bandwidth must be > 0"):
        stiff_pi(REFERENCE, bandwidth=0.0)


def test_pipe_impedance_of_the_reference_rig_by_hand():
    """5-in 19.5 lb/ft pipe: J = pi (0.127^4 - 0.1086^4)/32 = 1.188e-5 m^4, Z = J sqrt(G rho)
    = 1.188e-5 * sqrt(79.3e9 * 7850) = 296.5 N m s/rad; the lumped sqrt(C I1) = sqrt(235*200) =
    216.8: 1.37 times."""
    J = math.pi * (0.127**4 - 0.1086**4) / 32.0
    assert REFERENCE_PIPE.J == pytest.approx(J, rel=1e-14) and J == pytest.approx(1.188e-5, 1e-3)
    assert REFERENCE_PIPE.impedance == pytest.approx(J * math.sqrt(79.3e9 * 7850.0), rel=1e-14)
    assert REFERENCE_PIPE.impedance == pytest.approx(296.5, abs=0.05)
    assert impedance("lumped") == 1.0
    Zp = impedance("pipe", REFERENCE_RIG)
    assert Zp == pytest.approx(296.5 / math.sqrt(235.0 * 200.0), abs=1e-3)
    with pytest.raises(ValueError, match="impedance must be one of"):
        impedance("wave")
    with pytest.raises(ValueError, match="Pipe: id = 0.2 is not below od = 0.1"):
        Pipe(od=0.1, id=0.2)


def test_tuning_choices_select_the_rules():
    rho = REFERENCE.rho
    lumped = industrial_lineup(REFERENCE)
    assert lumped["soft-speed"].kp == 2.0 * math.sqrt(rho)  # the two-mass optimum, Z = 1
    field = industrial_lineup(REFERENCE, tuning=Tuning(impedance="pipe", soft_speed="impedance"))
    Zp = impedance("pipe", REFERENCE_RIG)
    assert field["soft-speed"].kp == pytest.approx(Zp)  # the field rule: kp = Z of the pipe
    assert field["soft-speed"].ki == lumped["soft-speed"].ki == rho  # inertia cancelled
    assert field["z-torque"].z_gain == pytest.approx(1.0 / Zp)
    quarter = industrial_lineup(REFERENCE, tuning=Tuning(z_matching=0.25))
    assert quarter["z-torque"].z_gain == 0.25
    # the two-mass rule is 3.3 times the pipe's impedance on the reference rig (issue's reading)
    assert lumped["soft-speed"].kp / Zp == pytest.approx(3.27, abs=0.01)
    with pytest.raises(ValueError, match="Tuning.soft_speed must be one of"):
        Tuning(soft_speed="stiff")


def test_the_pipe_impedance_is_that_of_the_simulated_rig():
    """Z = J sqrt(G rho_steel) over the simulated rig's sqrt(C I1): a rig with a stiffer string
    (C = 470 N m/rad, a 2 km string of the same pipe) scales the same 296.5 N m s/rad by
    sqrt(470*200) = 306.6, not by the reference rig's 216.8; a map point (another speed and
    feed) keeps the reference string and its pipe; a string of no known pipe is refused."""
    short = REFERENCE_RIG.replace(C=470.0)
    with pytest.raises(ValueError, match=r"no drill pipe is known .* \(C = 470 N m/rad"):
        impedance("pipe", short)
    with pytest.raises(ValueError, match="impedance 'pipe' needs the simulated rig"):
        impedance("pipe")
    Z = impedance("pipe", short, REFERENCE_PIPE)
    assert Z == pytest.approx(296.5 / math.sqrt(470.0 * 200.0), abs=1e-3)
    assert Z == pytest.approx(0.967, abs=1e-3) and impedance("pipe", REFERENCE_RIG) > 1.36
    point = REFERENCE_RIG.replace(Omega0=2.0 * REFERENCE_RIG.Omega0, V0=3.0 * REFERENCE_RIG.V0)
    assert impedance("pipe", point) == impedance("pipe", REFERENCE_RIG)
    # the lineups: the rig given or, for a known rig's set, found; else refused
    field = Tuning(impedance="pipe", soft_speed="impedance", pipe=REFERENCE_PIPE)
    laws = industrial_lineup(short.to_scaled(), tuning=field, rig=short)
    assert laws["soft-speed"].kp == pytest.approx(Z, rel=1e-12)
    assert laws["z-torque"].z_gain == pytest.approx(1.0 / Z, rel=1e-12)
    with pytest.raises(ValueError, match="the parameter set is of no known rig"):
        industrial_lineup(short.to_scaled(), tuning=Tuning(impedance="pipe"))
    with pytest.raises(ValueError, match="no drill pipe is known"):
        industrial_lineup(short.to_scaled(), tuning=Tuning(impedance="pipe"), rig=short)
    with pytest.raises(TypeError, match="Tuning.pipe must be a Pipe"):
        Tuning(impedance="pipe", pipe=(0.127, 0.1086))


def test_lineup_shares_feedforward_and_switch_on():
    m = averaged_model(REFERENCE, A_REF, TAUBAR_CRIT_REF)
    gains = tl.gains_file(PAPER_F, A_REF, TAUBAR_CRIT_REF, solver="none", solver_status="none")
    gain = lmi_gain(m, gains)
    assert gain.F == PAPER_F and gain.R_ff == m.R_ff and gain.abscissa < 0.0
    laws = industrial_lineup(REFERENCE, R_ff=gain.R_ff, t_on=25.0)
    assert tuple(laws) == INDUSTRIAL
    assert {law.R_ff for law in laws.values()} == {m.R_ff}
    assert {law.t_on for law in laws.values()} == {25.0}
    with pytest.raises(ValueError, match="feedforward must be one of"):
        lmi_gain(m, gains, feedforward="nominal")
