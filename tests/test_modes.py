"""Modes of the distributed string: the chain, the continuous string, the CLI.

Every expected value comes from outside the code under test: the paper's one-mode closed forms,
the frequency equations evaluated here in their tan form (and a pole-free form whose sign changes
count the roots), small-kappa expansions worked by hand (``docs/analysis.md``, "Modes of the
string"), the wave's travel time, a dense generalized eigensolver on the chain's own matrices,
and the measured order of convergence.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

from drillstring.analysis.modes import (
    axial_convergence,
    axial_exact_modes,
    axial_modes,
    paper_one_mode,
    to_hz,
    torsional_convergence,
    torsional_elements_needed,
    torsional_exact_modes,
    torsional_exact_shape,
    torsional_modes,
)
from drillstring.apps.cli import main
from drillstring.model.params import get_physical
from drillstring.model.pipe import REFERENCE_KAPPA, StringParams, axial_chain, torsional_chain

RHO, ETA = 5.0, 10.0  # the reference set's table inertia and axial stiffness parameter
KAPPA = REFERENCE_KAPPA
RIG = get_physical("reference-rig")
T_STAR = math.sqrt(RIG.I1 / RIG.C)  # t* = sqrt(I1/C), from the rig's own I1 and C


def held_residual(s: np.ndarray, kappa: float) -> np.ndarray:
    """tan(s) - kappa/(J_b*s), the held table's frequency equation as the docs state it."""
    return np.tan(s) - kappa / ((1.0 - kappa / 3.0) * s)


def free_residual(s: np.ndarray, kappa: float, rho: float) -> np.ndarray:
    """The free table's equation without poles: (r + b)*s*cos(s) + (1 - r*b*s^2)*sin(s)."""
    r, b = rho / kappa, (1.0 - kappa / 3.0) / kappa
    return (r + b) * s * np.cos(s) + (1.0 - r * b * s * s) * np.sin(s)


def sign_changes(f: np.ndarray) -> int:
    return int(np.count_nonzero(np.signbit(f[1:]) != np.signbit(f[:-1])))


# --------------------------------------------------------------------------------------------
# the paper's one-mode model
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("rho", [0.5, 5.0, 80.0])
def test_paper_lumping_is_the_one_mode_model(rho):
    """N = 1, 'paper': the bit (inertia 1) on the spring 1; free, two inertias on one spring."""
    held = torsional_modes(StringParams(elements=1), rho, "held").omega
    free = torsional_modes(StringParams(elements=1), rho, "free").omega
    assert held == pytest.approx([1.0], rel=1e-14)
    assert free == pytest.approx([math.sqrt(1.0 / rho + 1.0)], rel=1e-14)
    assert paper_one_mode(rho, "held") == 1.0
    assert paper_one_mode(rho, "free") == pytest.approx(math.sqrt((rho + 1.0) / rho), rel=1e-15)
    # the free mode: the table swings against the bit with no net angular momentum
    shape = torsional_modes(StringParams(elements=1), rho, "free").shapes[0]
    assert rho * shape[0] + 1.0 * shape[1] == pytest.approx(0.0, abs=1e-12)


def test_axial_massless_spring_is_the_papers():
    assert axial_modes(StringParams(elements=1), ETA).omega == pytest.approx([ETA], rel=1e-14)
    assert axial_modes(StringParams(elements=8), ETA).omega == pytest.approx([ETA], rel=1e-14)
    assert axial_exact_modes(0.0, ETA, 3) == pytest.approx([ETA])


# --------------------------------------------------------------------------------------------
# the chain's eigenproblem
# --------------------------------------------------------------------------------------------


def dense_modes(inertia: np.ndarray, k: float, held: bool) -> np.ndarray:
    """omega of K x = omega^2 J x by a dense generalized eigensolver, K assembled here."""
    n = inertia.size - 1
    K = np.zeros((n + 1, n + 1))
    for e in range(n):  # element e joins nodes e and e + 1
        K[e : e + 2, e : e + 2] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
    J = np.diag(inertia)
    if held:
        K, J = K[1:, 1:], J[1:, 1:]
    lam = scipy.linalg.eigh(K, J, eigvals_only=True)
    return np.sqrt(np.clip(lam, 0.0, None))


@pytest.mark.parametrize("table", ["held", "free"])
def test_chain_modes_agree_with_a_dense_eigensolver(table):
    string = StringParams(elements=12, kappa=KAPPA)
    chain = torsional_chain(string, RHO)
    dense = dense_modes(chain.inertia, chain.stiffness, table == "held")
    if table == "free":
        assert dense[0] < 1e-6  # the rigid-body rotation, which modes drops
        dense = dense[1:]
    got = torsional_modes(string, RHO, table)
    assert got.omega.size == 12
    assert got.omega == pytest.approx(dense, rel=1e-10)
    # shapes: J-orthogonal, and each satisfies K x = omega^2 J x
    J = np.diag(chain.inertia)
    gram = got.shapes @ J @ got.shapes.T
    off = gram - np.diag(np.diag(gram))
    assert np.max(np.abs(off)) < 1e-10 * np.max(np.diag(gram))
    if table == "held":
        assert np.all(got.shapes[:, 0] == 0.0)


def test_axial_chain_modes_agree_with_a_dense_eigensolver():
    string = StringParams(elements=10, axial_mass_ratio=0.6)
    chain = axial_chain(string, ETA)
    dense = dense_modes(chain.inertia, chain.stiffness, held=True)
    assert axial_modes(string, ETA).omega == pytest.approx(dense, rel=1e-10)


# --------------------------------------------------------------------------------------------
# the continuous string's exact modes
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kappa", [0.05, 1.0, KAPPA, 2.9])
def test_held_roots_solve_their_equation_and_none_is_missed(kappa):
    w = torsional_exact_modes(kappa, RHO, "held", 8)
    s = w * math.sqrt(kappa)
    assert np.all(np.abs(held_residual(s, kappa)) < 1e-9 * (1.0 + np.abs(np.tan(s))))
    grid = np.linspace(1e-6, s[-1] + 0.5 * (s[-1] - s[-2]), 200_001)
    f = (1.0 - kappa / 3.0) * grid * np.sin(grid) - kappa * np.cos(grid)  # tan form * J_b s cos
    assert sign_changes(f) == 8  # exactly the 8 roots returned, none skipped


@pytest.mark.parametrize("kappa", [0.05, 1.0, KAPPA, 2.9])
@pytest.mark.parametrize("rho", [0.3, RHO, 200.0])
def test_free_roots_solve_their_equation_and_none_is_missed(kappa, rho):
    w = torsional_exact_modes(kappa, rho, "free", 8)
    s = w * math.sqrt(kappa)
    scale = (rho / kappa) * ((1.0 - kappa / 3.0) / kappa) * s * s
    assert np.all(np.abs(free_residual(s, kappa, rho)) < 1e-9 * scale)
    # (0, s_8 + half a spacing]: the 8 elastic roots and no other (s = 0, the rigid body, is
    # left out by starting the grid above it)
    grid = np.linspace(1e-4, s[-1] + 0.5 * (s[-1] - s[-2]), 200_001)
    assert sign_changes(free_residual(grid, kappa, rho)) == 8


def test_axial_roots_solve_their_equation():
    mu = 0.7
    w = axial_exact_modes(mu, ETA, 6)
    s = w * math.sqrt(mu) / ETA
    assert np.tan(s) == pytest.approx(mu / ((1.0 - mu / 3.0) * s), rel=1e-9)
    assert np.all(np.diff(s) > 0) and np.all((s % math.pi) < math.pi / 2)


def test_high_modes_are_spaced_by_the_travel_time():
    """For large s the end inertias reflect like fixed ends: omega_{n+1} - omega_n tends to
    pi/sqrt(kappa), 2*pi over the round trip 2*sqrt(kappa) of the wave."""
    for table in ("held", "free"):
        w = torsional_exact_modes(KAPPA, RHO, table, 200)
        assert w[-1] - w[-2] == pytest.approx(math.pi / math.sqrt(KAPPA), rel=1e-4)


def test_small_kappa_the_one_third_rule_and_the_free_tables_first_order():
    """kappa -> 0: held, omega = 1 + O(kappa^2) (a third of the pipe at the bit is exact to first
    order); free, omega = sqrt(1 + 1/rho) + c*kappa with c worked by hand from the equation's
    expansion in s^2 = kappa*omega^2: w = 1 + 1/rho + kappa*(1/3 + (1 - (rho+1)^2/(3 rho))/rho)."""
    e1, e2 = (abs(torsional_exact_modes(k, RHO, "held", 1)[0] - 1.0) for k in (1e-2, 1e-3))
    assert e1 < 1e-2**2 and 50.0 < e1 / e2 < 200.0
    slope = (1.0 / 3.0 + (1.0 - (RHO + 1.0) ** 2 / (3.0 * RHO)) / RHO) / (
        2.0 * math.sqrt(1.0 + 1.0 / RHO)
    )
    for k in (1e-2, 1e-3):
        got = torsional_exact_modes(k, RHO, "free", 1)[0] - math.sqrt(1.0 + 1.0 / RHO)
        assert got == pytest.approx(slope * k, rel=20 * k)


def test_massive_table_free_tends_to_held():
    held = torsional_exact_modes(KAPPA, RHO, "held", 4)
    free = torsional_exact_modes(KAPPA, 1e9, "free", 4)
    assert free == pytest.approx(held, rel=1e-8)
    assert torsional_exact_modes(KAPPA, 5.0, "free", 1)[0] > held[0] * 1.05  # rho matters
    string = StringParams(elements=16, kappa=KAPPA)
    assert torsional_modes(string, 1e9, "free", 4).omega == pytest.approx(
        torsional_modes(string, RHO, "held", 4).omega, rel=1e-8
    )


@pytest.mark.parametrize("table", ["held", "free"])
def test_small_kappa_chain_tends_to_the_one_mode_model(table):
    """kappa -> 0 at fixed N: the lumped chain's first mode tends to the paper's, linearly in
    kappa, and its pipe modes leave to infinity like 1/sqrt(kappa)."""
    err, high = [], []
    for kappa in (1e-3, 1e-4):
        omega = torsional_modes(StringParams(elements=8, kappa=kappa), RHO, table, 2).omega
        err.append(abs(omega[0] / paper_one_mode(RHO, table) - 1.0))
        high.append(omega[1])
        assert err[-1] < kappa
    assert 5.0 < err[0] / err[1] < 20.0
    assert high[1] / high[0] == pytest.approx(math.sqrt(10.0), rel=1e-2)


# --------------------------------------------------------------------------------------------
# convergence in N
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("table", ["held", "free"])
def test_torsional_chain_converges_at_second_order(table):
    conv = torsional_convergence(KAPPA, RHO, table, count=2, elements=(8, 16, 32, 64, 128))
    err = np.abs(conv.omega / torsional_exact_modes(KAPPA, RHO, table, 2) - 1.0)
    ratios = err[:-1] / err[1:]
    assert np.all((ratios > 3.5) & (ratios < 4.5)), ratios
    assert np.all(err[-1] < 1e-4)
    # Richardson's extrapolation of two chains lands far closer than either: an independent
    # estimate of the continuous root (no transcendental equation involved)
    rich = (4.0 * conv.omega[-1] - conv.omega[-2]) / 3.0
    assert rich == pytest.approx(conv.exact, rel=1e-8)


def test_axial_chain_converges_at_second_order():
    conv = axial_convergence(0.8, ETA, count=2, elements=(8, 16, 32, 64, 128))
    err = np.abs(conv.omega / axial_exact_modes(0.8, ETA, 2) - 1.0)
    ratios = err[:-1] / err[1:]
    assert np.all((ratios > 3.5) & (ratios < 4.5)), ratios


def test_elements_needed_is_the_first_n_within_tolerance():
    exact = torsional_exact_modes(KAPPA, RHO, "held", 2)[1]
    n = torsional_elements_needed(KAPPA, RHO, "held", mode=2, rel_tol=0.01)
    at = [
        torsional_modes(StringParams(elements=m, kappa=KAPPA), RHO, "held", 2).omega
        for m in (n - 1, n)
    ]
    assert abs(at[1][1] / exact - 1.0) <= 0.01 < abs(at[0][1] / exact - 1.0)


def test_chain_shapes_converge_to_the_continuous_ones():
    string = StringParams(elements=64, kappa=KAPPA)
    for table in ("held", "free"):
        modes = torsional_modes(string, RHO, table, 3)
        exact = torsional_exact_modes(KAPPA, RHO, table, 3)
        for k in range(3):
            shape = torsional_exact_shape(KAPPA, RHO, table, exact[k], modes.x)
            assert np.max(np.abs(modes.shapes[k] - shape)) < 5e-3


# --------------------------------------------------------------------------------------------
# the reference rig
# --------------------------------------------------------------------------------------------


def test_reference_rig_travel_time_and_second_mode():
    """The issue's numbers: a one-way travel time of about 1.3 s and a second torsional mode
    (table held) of about 0.5 Hz."""
    assert math.sqrt(KAPPA) * T_STAR == pytest.approx(1.26, abs=0.01)
    f = to_hz(torsional_exact_modes(KAPPA, RHO, "held", 2), T_STAR)
    assert 0.45 < f[1] < 0.55
    # the one-mode model's frequency 1/(2 pi t*) (docs/reference_rig.md: 0.1725 Hz) is the
    # first mode's to within the pipe's share
    assert f[0] == pytest.approx(0.1725, rel=0.05)


# --------------------------------------------------------------------------------------------
# the command
# --------------------------------------------------------------------------------------------


def run(tmp_path: Path, *args: str) -> tuple[int, dict]:
    out = tmp_path / "out"
    rc = main(["modes", *args, "--out", str(out)])
    data = json.loads((out / "modes.json").read_text()) if rc == 0 else {}
    return rc, data


def test_cli_writes_modes_and_figure(tmp_path):
    rc, d = run(tmp_path, "--elements", "16", "--table", "held", "--axial",
                "--axial-mass-ratio", "0.5", "--count", "3")  # fmt: skip
    assert rc == 0
    assert d["elements"] == 16 and d["table"] == "held" and d["t_star_s"] == pytest.approx(T_STAR)
    w = np.array(d["omega_scaled"])
    assert np.array(d["omega_rad_s"]) == pytest.approx(w / T_STAR, rel=1e-12)
    assert np.array(d["frequency_hz"]) == pytest.approx(w / T_STAR / (2 * math.pi), rel=1e-12)
    s = np.array(d["omega_exact_scaled"]) * math.sqrt(KAPPA)
    assert held_residual(s, KAPPA) == pytest.approx(np.zeros(3), abs=1e-8)
    assert np.array(d["relative_error"]) == pytest.approx(w / (s / math.sqrt(KAPPA)) - 1.0)
    assert all(-0.01 < e < 0 for e in d["relative_error"])  # lumped masses: from below
    conv = d["convergence"]
    assert conv["elements"] == [2**i for i in range(9)]
    assert 3.5 < conv["error_ratio_per_doubling"][-1][1] < 4.5
    assert set(d["elements_within_1_percent"]) == {"mode_1", "mode_2", "mode_3"}
    ax = d["axial"]
    sa = np.array(ax["omega_exact_scaled"]) * math.sqrt(0.5) / ETA
    assert np.tan(sa) == pytest.approx(0.5 / ((1 - 0.5 / 3) * sa), rel=1e-8)
    assert np.array(ax["omega_rad_s"]) == pytest.approx(np.array(ax["omega_scaled"]) / T_STAR)
    assert set(d["units"]) >= {"omega_scaled", "omega_rad_s", "frequency_hz", "relative_error"}
    png = (tmp_path / "out" / "modes.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_cli_paper_model_at_one_element(tmp_path):
    rc, d = run(tmp_path, "--elements", "1", "--table", "free", "--count", "3")
    assert rc == 0
    assert d["lumping"] == "paper"
    assert d["omega_scaled"] == pytest.approx([math.sqrt(1.0 + 1.0 / RHO), None, None])
    assert len(d["omega_exact_scaled"]) == 3 and d["relative_error"][1:] == [None, None]


def test_cli_scaled_set_needs_t_star(tmp_path, capsys):
    spec = tmp_path / "scaled.toml"
    spec.write_text(
        'kind = "scaled"\nn = 4\npsi = 250.0\ngamma = 6.0\neta = 10.0\nlambda = 1.58\n'
        "beta = 0.5\nrho = 3.0\nv0 = 1.0\nomega0 = 5.0\n"
    )
    assert (
        main(["modes", "--elements", "4", "--params", str(spec), "--out", str(tmp_path / "a")]) == 2
    )
    assert "--t-star" in capsys.readouterr().err
    rc, d = run(tmp_path, "--elements", "4", "--params", str(spec), "--t-star", "2.0")
    assert rc == 0 and d["rho_I1"] == 3.0
    assert np.array(d["omega_rad_s"]) == pytest.approx(np.array(d["omega_scaled"]) / 2.0)


@pytest.mark.parametrize(
    "args, named",
    [
        (["--elements", "0"], "0"),
        (["--elements", "-3"], "-3"),
        (["--elements", "2.5"], "2.5"),
        (["--elements", "abc"], "abc"),
        (["--elements", "1000000"], "1000000"),
        (["--elements", "8", "--count", "0"], "0"),
        (["--elements", "8", "--table", "upside"], "upside"),
        (["--elements", "8", "--kappa", "3.5"], "3.5"),
    ],
)
def test_cli_refuses_bad_values_in_one_line(tmp_path, capsys, args, named):
    out = tmp_path / "out"
    assert main(["modes", *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and named in err and err.startswith("drillstring modes:")
    assert not out.exists()
