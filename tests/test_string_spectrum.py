"""The laws' linearised closed loops on the distributed string (drillstring.controller.
string_spectrum, ``drillstring string-spectrum``).

* N = 1 with the paper's lumping is the one-mode analysis: the roots equal those of the existing
  functions, computed on the one-mode state by their own code (``delay_roots`` of (29)-(30)
  for the LMI laws, ``linear_closed_loop`` / ``linear_abscissa`` of (13), (27) for every law, and
  the delay form of the industrial laws assembled here from ``linear_closed_loop`` and the
  averaged model's A0, A1);
* hand-made cases: without the bit law and with the table free, the roots are +-i times the
  chain's modes (``drillstring.analysis.modes``); a damper at the table with the pipe's
  impedance sqrt(kappa) puts every root in the left half plane;
* the abscissae converge as N doubles;
* the command writes its table, and refuses a bad value in one line.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math

import fmu_testlib as tl
import numpy as np
import pytest

from drillstring.analysis.modes import torsional_modes
from drillstring.analysis.spectrum import (
    DDESystem,
    chebyshev_generator,
    dde_roots,
    delayed_columns,
)
from drillstring.apps.cli import main
from drillstring.apps.sweep.studies import linear_abscissa
from drillstring.controller.averaged import averaged_model, delay_roots
from drillstring.controller.gains import write_gains
from drillstring.controller.lineup import industrial_lineup
from drillstring.controller.string_spectrum import (
    string_abscissa,
    string_closed_loop,
    string_roots,
)
from drillstring.controller.tuning import linear_closed_loop
from drillstring.model.control import AffineFeedback
from drillstring.model.digital.controller import DigitalController
from drillstring.model.laws import SampledAffine, SpeedPI
from drillstring.model.params import REFERENCE
from drillstring.model.pipe import REFERENCE_KAPPA, StringParams, rig_string

A, TAUBAR_CRIT = 0.385415, 2.392788  # the design's A, taubar_crit (tests/test_constrained.py)
MODEL = averaged_model(REFERENCE, A, TAUBAR_CRIT)
#: the project's design of the paper's LMI (33) at the reference set (gains.json)
PAPER_F = (-3353.65, -2028.44, 520.61, -57.11)
#: the input-constrained design for the TDS-11SA (docs/controllers.md: abscissa -0.540)
CONSTRAINED_F = (-100.62, -74.14, 57.69, -20.32)
PAPER = StringParams()  # one element, the paper's lumping


def _affine(F):
    return SampledAffine(AffineFeedback(F, MODEL.K0, MODEL.R_ff))


LAWS = {
    **industrial_lineup(REFERENCE, R_ff=MODEL.R_ff),
    "lmi": _affine(PAPER_F),
    "lmi-constrained": _affine(CONSTRAINED_F),
}


def _same_roots(a: np.ndarray, b: np.ndarray, rtol: float = 1e-8) -> None:
    assert a.size == b.size
    for s in a:
        assert np.min(np.abs(b - s)) <= rtol * max(1.0, abs(s)), (s, b)


def _without_origin(roots: np.ndarray) -> np.ndarray:
    i = int(np.argmin(np.abs(roots)))
    assert abs(roots[i]) < 1e-9
    return np.delete(roots, i)


# ------------------------------------------------------------------------------------------
# N = 1: the one-mode analysis
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("F", [PAPER_F, CONSTRAINED_F], ids=["lmi", "lmi-constrained"])
def test_one_element_lmi_laws_are_the_certified_delay_form(F) -> None:
    mine = string_roots(MODEL, _affine(F), PAPER, n_roots=6)
    theirs = delay_roots(MODEL, np.asarray(F), None, 6)
    _same_roots(mine, theirs)
    if F == CONSTRAINED_F:
        assert mine[0].real == pytest.approx(-0.540, abs=5e-4)  # the certificate's
    assert string_abscissa(MODEL, _affine(F), PAPER) == pytest.approx(theirs[0].real, abs=1e-10)


@pytest.mark.parametrize("name", list(LAWS))
def test_one_element_taylor_form_is_the_maps_linear_closed_loop(name) -> None:
    law = LAWS[name]
    mine = string_roots(MODEL, law, PAPER, bit="taylor", n_roots=20)
    ev = np.linalg.eigvals(linear_closed_loop(MODEL, law))
    if not isinstance(law, SampledAffine):  # phi is a rigid-body coordinate there
        ev = _without_origin(ev)
    _same_roots(mine, ev)
    existing = linear_abscissa(MODEL, DigitalController(law))
    assert string_abscissa(MODEL, law, PAPER, bit="taylor") == pytest.approx(existing, abs=1e-10)


@pytest.mark.parametrize("name", ["stiff-pi", "soft-speed", "z-torque"])
def test_one_element_delay_form_of_the_industrial_laws(name) -> None:
    # the reference: the one-mode ODE closed by the law, its bit row put back in delay form
    law = LAWS[name]
    M = linear_closed_loop(MODEL, law)
    M[1, :4] = MODEL.A0[1]
    M1 = np.zeros_like(M)
    M1[:4, :4] = MODEL.A1
    theirs = _without_origin(dde_roots(M, [(MODEL.tau_n0, M1)]))[:6]
    mine = string_roots(MODEL, law, PAPER, n_roots=6)
    _same_roots(mine, theirs)
    # what the one-mode analysis says of them
    a = mine[0].real
    assert (a > 0.05) if name == "stiff-pi" else (a < 0.0)


def test_reduced_generator_keeps_the_roots_of_the_full_one() -> None:
    A0, A1 = string_closed_loop(MODEL, LAWS["z-torque"], rig_string("reference-rig", 3))
    sys_ = DDESystem(A0, [(MODEL.tau_n0, A1)])
    assert list(delayed_columns(sys_)) == [3]  # the bit's angle, phi_3
    full = dde_roots(sys_, re_min=-2.0)
    reduced = dde_roots(sys_, re_min=-2.0, reduced=True)
    _same_roots(full, reduced, 1e-9)
    assert chebyshev_generator(sys_, 30, reduced=True).shape == (A0.shape[0] + 30,) * 2


# ------------------------------------------------------------------------------------------
# hand-made cases on the chain
# ------------------------------------------------------------------------------------------

NO_BIT = dataclasses.replace(MODEL, c=0.0)


@pytest.mark.parametrize("bit", ["delay", "taylor"])
@pytest.mark.parametrize("n", [2, 8, 24])
def test_without_the_bit_law_the_free_chain_rings_at_its_modes(n, bit) -> None:
    string = rig_string("reference-rig", n)
    roots = string_roots(NO_BIT, None, string, bit=bit, n_roots=4 * n)
    assert roots.size == 2 * n  # N elastic pairs, the rigid-body root left out
    assert np.max(np.abs(roots.real)) < 1e-8
    omega = np.sort(roots.imag[roots.imag > 0])
    modes = torsional_modes(string, REFERENCE.rho, "free").omega
    np.testing.assert_allclose(omega, modes, rtol=1e-9)


def test_a_damper_of_the_pipes_impedance_at_a_massless_top_absorbs_the_wave() -> None:
    # The continuous string with a damper sqrt(kappa) (its impedance) at a massless top and no
    # bit law: Laplace, theta = a exp(-s sqrt(kappa) x) + b exp(s sqrt(kappa) x); the top's
    # theta_x(0) = sqrt(kappa) s theta(0) gives a = 0 (no wave leaves the top), the bit end's
    # J_b s^2 theta(1) = -theta_x(1) gives J_b s = -sqrt(kappa): one root, -sqrt(kappa)/J_b,
    # besides the rigid rotation. On the chain every root decays, and the real root and the
    # low-frequency ones move left towards it as N grows (slowly: the chain reflects a wave of
    # frequency w by O((w/w_N)^2), so its other roots leave to -infinity like log N).
    top = dataclasses.replace(NO_BIT, rho=0.0)
    damper = SpeedPI(kp=math.sqrt(REFERENCE_KAPPA), ki=0.0)
    exact = -math.sqrt(REFERENCE_KAPPA) / (1.0 - REFERENCE_KAPPA / 3.0)
    real_roots, slowest = [], []
    for n in (4, 16, 64):
        # ki = 0 leaves the integrator decoupled: its root s = 0 goes with the rigid one
        roots = string_roots(top, damper, rig_string("reference-rig", n), bit="taylor",
                             n_roots=10 * n)  # fmt: skip
        assert roots.size == 2 * n + 1 and np.all(roots.real < 0.0)
        real_roots.append(roots[np.abs(roots.imag) < 1e-9].real)
        slowest.append(roots[np.abs(roots.imag) < 3.5].real.max())  # the lowest modes
    assert all(r.size == 1 for r in real_roots)
    assert exact < real_roots[2][0] < real_roots[1][0] < real_roots[0][0]
    assert slowest[2] < slowest[1] < slowest[0] < -0.5


@pytest.mark.parametrize("n", [4, 16])
def test_the_same_damper_under_the_tables_inertia_still_damps_every_mode(n) -> None:
    # the table's inertia rho reflects the high frequencies: they decay, but barely
    damper = SpeedPI(kp=math.sqrt(REFERENCE_KAPPA), ki=0.0)
    roots = string_roots(NO_BIT, damper, rig_string("reference-rig", n), n_roots=10 * n)
    assert roots.size == 2 * n + 1 and np.all(roots.real < 0.0)


# ------------------------------------------------------------------------------------------
# convergence in N and what the string does to each law
# ------------------------------------------------------------------------------------------

NS = (1, 2, 4, 8, 16, 32, 64)


@pytest.fixture(scope="module")
def abscissae() -> dict[str, np.ndarray]:
    return {
        name: np.array([string_abscissa(MODEL, law, rig_string("reference-rig", n)) for n in NS])
        for name, law in LAWS.items()
    }


@pytest.mark.parametrize("name", ["stiff-pi", "soft-speed", "lmi", "lmi-constrained"])
def test_abscissae_converge_in_n(abscissae, name) -> None:
    # second order once the rightmost root is resolved (the paper's LMI changes its rightmost
    # root from the 2.2 to the 6.4 rad/tau branch at N = 16): the steps at least halve
    steps = np.abs(np.diff(abscissae[name]))
    assert steps[-1] <= 0.5 * steps[-2] + 1e-9
    assert steps[-1] < 0.02


@pytest.mark.slow  # an end-to-end run of several seconds: make test, not test-fast
def test_z_torque_converges_slower_from_its_high_modes(abscissae) -> None:
    # its rightmost roots are high modes (about 25 rad/tau): resolved from N = 64 on
    a128 = string_abscissa(MODEL, LAWS["z-torque"], rig_string("reference-rig", 128))
    a32, a64 = abscissae["z-torque"][-2:]
    assert abs(a128 - a64) < 0.5 * abs(a64 - a32)
    assert a128 > 0.1  # unstable on the converged string


def test_what_the_string_does_to_each_law(abscissae) -> None:
    # the claims, checked on N = 64 (converged above)
    string = rig_string("reference-rig", 64)
    held = torsional_modes(string, REFERENCE.rho, "held", 4).omega

    def unstable(name):  # every root in the right half plane, the rigid one left out
        r = string_roots(MODEL, LAWS[name], string, n_roots=1000, re_min=0.0)
        assert np.all(r.real >= 0.0)
        return np.sort(r.imag[(r.real > 0) & (r.imag > 0)])

    # stiff PI: unstable in modes 1, 2 and 3 (the table nearly held)
    np.testing.assert_allclose(unstable("stiff-pi"), held[:3], rtol=0.03)
    # SoftSpeed: stable on one mode, weakly unstable in mode 2 (and 3, 4) on the string
    assert abscissae["soft-speed"][0] < 0.0 < abscissae["soft-speed"][-1] < 0.05
    assert unstable("soft-speed")[0] == pytest.approx(held[1], rel=0.03)
    # the paper's LMI: its automatic region (1 below the abscissa, 2.1) holds 6 of them
    assert unstable("lmi").size == 32
    assert string_roots(MODEL, LAWS["lmi"], string, n_roots=1000).real.min() > 1.0
    # the constrained LMI: -0.540 on one mode, strongly unstable on the string
    assert abscissae["lmi-constrained"][0] == pytest.approx(-0.540, abs=5e-4)
    assert abscissae["lmi-constrained"][-1] > 0.8
    # not from the pipe's inertia on table and bit alone: lumped half at each end of one element
    one = StringParams(elements=1, lumping="lumped")
    assert string_abscissa(MODEL, LAWS["lmi-constrained"], one) < -0.4


# ------------------------------------------------------------------------------------------
# the command
# ------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def gains_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("design")
    write_gains(tl.gains_file(PAPER_F, A, TAUBAR_CRIT), folder / "gains.json")
    record = {"u_max": 212.1, "peak_torque": 173.2, "decay": 0.0368, "tau_max": 0.63}
    write_gains(
        tl.gains_file(CONSTRAINED_F, A, TAUBAR_CRIT, constraint=record),
        folder / "gains_constrained.json",
    )
    return folder


def test_command_writes_the_table(gains_dir, tmp_path, capsys) -> None:
    out = tmp_path / "spec"
    args = ["--gains", str(gains_dir / "gains.json"), "--elements", "4", "--out", str(out)]
    assert main(["string-spectrum", *args]) == 0
    with open(out / "string_spectrum.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    laws = ["open-loop", "stiff-pi", "soft-speed", "z-torque", "lmi", "lmi-constrained"]
    assert [r["law"] for r in rows] == [law for law in laws for _ in (1, 2, 4)]
    first = next(r for r in rows if r["law"] == "lmi-constrained")
    assert first["lumping"] == "paper"
    assert float(first["abscissa_scaled_per_tau"]) == pytest.approx(-0.540, abs=5e-4)
    t_star = json.loads((out / "string_spectrum.json").read_text())["t_star_s"]
    assert float(first["abscissa_per_s"]) == pytest.approx(-0.540 / t_star, abs=1e-3)
    assert "N = 4" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--elements", "0"], "got 0"),
        (["--elements", "2,x"], "'x'"),
        (["--elements", "5000"], "5000"),
        (["--kappa", "4"], "kappa"),
        (["--torque", "sub"], "sub"),
        (["--params", "no-such-set"], "no-such-set"),
    ],
)
def test_command_refuses_a_bad_value_in_one_line(gains_dir, tmp_path, capsys, args, named):
    base = ["--gains", str(gains_dir / "gains.json"), "--out", str(tmp_path / "x")]
    assert main(["string-spectrum", *base, *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and named in err
