"""The pipe rig (docs/reference_rig.md, "The pipe rig"): the reference rig with M and K made
consistent with its drill pipe, its data file, its string by name, and the named sets that were
there before it, unchanged.

Expected values are computed here from the pipe's geometry and the steel's constants (by another
route than the code: the annulus area as pi*(OD - ID)*(OD + ID)/4 and the polar moment as area
times (OD^2 + ID^2)/8), never taken from the code under test.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib
from pathlib import Path

import pytest

from drillstring.apps.simulate import simulate_main
from drillstring.controller.tuning import REFERENCE_PIPE, rig_pipe
from drillstring.model.params import (
    KNOWN_PARAMS,
    KNOWN_PHYSICAL,
    PIPE_RIG,
    REFERENCE,
    REFERENCE_RIG,
    ParameterError,
    PhysicalParams,
    get_params,
    get_physical,
    known_rig,
    load_params,
    params_from_spec,
    read_params,
    rig_from_spec,
    save_params,
)
from drillstring.model.pipe import (
    KNOWN_STRINGS,
    REFERENCE_KAPPA,
    StringParams,
    axial_chain,
    rig_string,
)

DATA = Path(__file__).resolve().parents[1] / "drillstring" / "model" / "data"

# --- the pipe by hand (docs/reference_rig.md): 5-in 19.5 lb/ft, steel ---------------------
OD, ID = 0.1270, 0.1086  # m
RHO_STEEL, G, E = 7850.0, 79.3e9, 206.8e9  # kg/m^3, Pa, Pa
AREA = math.pi * (OD - ID) * (OD + ID) / 4.0  # 3.4047e-3 m^2
J = AREA * (OD**2 + ID**2) / 8.0  # thick tube: J = A*(OD^2 + ID^2)/8 = 1.1884e-5 m^4
LENGTH = G * J / 235.0  # GJ/L = C = 235 N m/rad -> 4010.1 m
PIPE_MASS = RHO_STEEL * AREA * LENGTH  # 107 180 kg
PIPE_EA_L = E * AREA / LENGTH  # 1.7558e5 N/m
# the reference rig's M, the collars alone: psi = zeta*eps*a*t*^2/M = 250 with t*^2 = 200/235
BHA = 0.6 * 60e6 * 0.10795 * (200.0 / 235.0) / 250.0  # 13 229.6 kg
M_PIPE_RIG = BHA + PIPE_MASS / 3.0  # 48 956 kg

# the reference rig as shipped in reference_rig.toml before the pipe rig (repr floats)
REFERENCE_RIG_VALUES = dict(
    M=13229.617021276596,
    I1=200.0,
    I2=1000.0,
    C=235.0,
    K=1554480.0,
    D=90697.68479345886,
    n=4,
    a=0.10795,
    eps=60000000.0,
    zeta=0.6,
    sigma_bar=60000000.0,
    l=0.0006372497174060092,
    mu=0.625,
    xi=1.3333333333333333,
    V0=0.0007286521446700334,
    Omega0=5.4198708471697,
)
REFERENCE_VALUES = dict(
    n=4,
    psi=250.0,
    gamma=2.0 * math.sqrt(10.0),
    eta=10.0,
    lam=1.58,
    beta=0.5,
    rho=5.0,
    v0=1.0,
    omega0=5.0,
)


def test_pipe_by_hand_matches_the_documented_pipe() -> None:
    # the hand arithmetic itself, against the numbers of docs/reference_rig.md
    assert J == pytest.approx(1.188e-5, rel=1e-3)
    assert RHO_STEEL * J == pytest.approx(0.0932, rel=1e-3)  # kg m^2 per metre
    assert G * J == pytest.approx(9.42e5, rel=1e-3)
    assert LENGTH == pytest.approx(4010.14, rel=1e-6)
    assert PIPE_EA_L == pytest.approx(1.76e5, rel=3e-3)
    assert BHA == pytest.approx(13229.617021276596, rel=1e-14)


def test_pipe_rig_m_and_k_from_the_pipe_by_hand() -> None:
    r = PIPE_RIG
    assert r.M == pytest.approx(M_PIPE_RIG, rel=1e-13)
    assert r.K == pytest.approx(PIPE_EA_L, rel=1e-13)
    # the numbers quoted in docs/reference_rig.md, "The pipe rig"
    assert (r.M, r.K) == pytest.approx((48956.17, 175579.47), rel=1e-7)
    assert PIPE_MASS == pytest.approx(107179.67, rel=1e-7)
    # a third of the pipe is on the bit end: the BHA is 1 - mu/3 of M
    assert BHA / r.M == pytest.approx(1.0 - PIPE_MASS / r.M / 3.0, rel=1e-13)


def test_pipe_rig_keeps_everything_else_of_the_reference_rig() -> None:
    same = {k: v for k, v in REFERENCE_RIG_VALUES.items() if k not in ("M", "K")}
    assert {k: getattr(PIPE_RIG, k) for k in same} == same  # D included: the dashpot is kept
    assert PIPE_RIG.M != REFERENCE_RIG.M and PIPE_RIG.K != REFERENCE_RIG.K
    assert PIPE_RIG.t_star == REFERENCE_RIG.t_star and PIPE_RIG.L_star == REFERENCE_RIG.L_star


def test_pipe_rig_scaled_set_by_hand() -> None:
    s = get_params("pipe-rig")
    zea = 0.6 * 60e6 * 0.10795  # zeta*eps*a
    t = math.sqrt(200.0 / 235.0)
    psi = zea * 200.0 / (M_PIPE_RIG * 235.0)  # (15)
    eta2 = PIPE_EA_L * 200.0 / (M_PIPE_RIG * 235.0)  # (15)
    gamma = 90697.68479345886 * t / M_PIPE_RIG  # (15)
    assert s.psi == pytest.approx(psi, rel=1e-13)
    assert s.eta == pytest.approx(math.sqrt(eta2), rel=1e-13)
    assert s.gamma == pytest.approx(gamma, rel=1e-13)
    # etabar^2 = K/(n*zeta*eps*a) whatever M: the string's 0.011 of docs/reference_rig.md
    assert s.etabar2 == pytest.approx(PIPE_EA_L / (4 * zea), rel=1e-13)
    assert (s.psi, s.eta, s.gamma, s.etabar2) == pytest.approx(
        (67.558, 1.74709, 1.70911, 0.0112951), rel=1e-5
    )
    # the torsional and bit values are the reference set's
    for name in ("n", "lam", "beta", "rho", "v0", "omega0"):
        assert getattr(s, name) == pytest.approx(REFERENCE_VALUES[name], rel=1e-12), name


def test_pipe_rig_file_is_the_set() -> None:
    path = DATA / "pipe_rig.toml"
    table = tomllib.loads(path.read_text())
    assert table["kind"] == "physical"
    assert table["M"] == pytest.approx(M_PIPE_RIG, rel=1e-13)
    assert table["K"] == pytest.approx(PIPE_EA_L, rel=1e-13)
    assert read_params(path) == PIPE_RIG  # repr floats: bit for bit
    assert load_params(path) == get_params("pipe-rig")
    assert params_from_spec(str(path)) == params_from_spec("pipe-rig")


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_pipe_rig_file_round_trip(tmp_path: Path, suffix: str) -> None:
    path = save_params(PIPE_RIG, tmp_path / f"pipe{suffix}")
    back = read_params(path)
    assert isinstance(back, PhysicalParams) and back == PIPE_RIG
    assert back.to_scaled() == get_params("pipe-rig")


def test_pipe_rig_by_name() -> None:
    assert get_physical("pipe-rig") is PIPE_RIG
    assert KNOWN_PHYSICAL["pipe-rig"] is PIPE_RIG
    assert params_from_spec("pipe-rig") == PIPE_RIG.to_scaled()
    assert known_rig(get_params("pipe-rig")) is PIPE_RIG
    assert rig_pipe(PIPE_RIG) == REFERENCE_PIPE  # the same drill pipe, for the impedance rules


def test_rig_string_by_name() -> None:
    kappa = RHO_STEEL * J * LENGTH / 200.0  # I_pipe/I1
    assert kappa == pytest.approx(1.870, abs=5e-4)
    pipe = rig_string("pipe-rig")
    assert pipe.kappa == pytest.approx(kappa, rel=1e-13)
    assert pipe.kappa == REFERENCE_KAPPA
    assert pipe.axial_mass_ratio == pytest.approx(PIPE_MASS / M_PIPE_RIG, rel=1e-13)
    assert pipe.axial_mass_ratio == pytest.approx(2.1893, rel=1e-4)
    assert pipe.elements == 1 and pipe.is_paper
    ref = rig_string("reference-rig")
    assert ref.kappa == pytest.approx(kappa, rel=1e-13)
    assert ref.axial_mass_ratio == 0.0  # the paper's K is not the pipe's
    assert KNOWN_STRINGS["pipe-rig"] == pipe and KNOWN_STRINGS["reference-rig"] == ref
    assert set(KNOWN_STRINGS) == set(KNOWN_PHYSICAL)


def test_rig_string_with_elements() -> None:
    s = rig_string("pipe-rig", elements=4)
    assert (s.elements, s.lumping, s.axial_distributed) == (4, "lumped", True)
    chain = axial_chain(s, get_params("pipe-rig").eta)
    # the bit node: the BHA (1 - mu/3 of M) plus half an element of pipe
    mu = PIPE_MASS / M_PIPE_RIG
    assert chain.inertia[-1] == pytest.approx(BHA / M_PIPE_RIG + mu / 8.0, rel=1e-12)
    assert chain.inertia.sum() == pytest.approx(mu + BHA / M_PIPE_RIG, rel=1e-12)
    assert not rig_string("reference-rig", elements=4).axial_distributed
    assert rig_string("reference-rig", elements=1, lumping="lumped").lumping == "lumped"
    with pytest.raises(ValueError, match="'paper' lumping has one element"):
        rig_string("pipe-rig", elements=2, lumping="paper")


def test_rig_from_spec_by_name_and_by_file(tmp_path: Path) -> None:
    """The physical rig behind a ``--params`` value: a physical set as it is (also one of no
    known rig), a scaled set the known rig it is the scaled set of, else none."""
    assert rig_from_spec("pipe-rig") is PIPE_RIG
    assert rig_from_spec("reference-rig") is REFERENCE_RIG
    assert rig_from_spec("reference") is REFERENCE_RIG
    faster = PIPE_RIG.replace(Omega0=2.0 * PIPE_RIG.Omega0)
    assert rig_from_spec(save_params(faster, tmp_path / "faster.toml")) == faster
    assert rig_from_spec(save_params(get_params("pipe-rig"), tmp_path / "s.json")) is PIPE_RIG
    assert rig_from_spec(save_params(REFERENCE.replace(psi=300.0), tmp_path / "o.toml")) is None
    with pytest.raises(ParameterError, match="unknown parameter set 'nope'"):
        rig_from_spec("nope")


def test_simulate_finds_a_known_rigs_pipe_by_its_numbers(tmp_path: Path) -> None:
    """``drillstring simulate --elements N`` on a file of the pipe rig at twice its speed (no
    named set: only its masses, inertias and stiffnesses tell the rig) runs the pipe rig's pipe,
    its axial mass ratio and kappa by hand; on a rig of no known pipe the reference pipe."""
    faster = save_params(PIPE_RIG.replace(Omega0=2.0 * PIPE_RIG.Omega0), tmp_path / "fast.toml")
    other = save_params(REFERENCE.replace(psi=300.0), tmp_path / "other.toml")
    strings = {}
    for name, spec in (("pipe", faster), ("other", other)):
        out = tmp_path / name
        argv = ["--params", str(spec), "--elements", "4", "--tau-end", "0.2", "--out", str(out)]
        assert simulate_main(argv) == 0
        strings[name] = json.loads((out / "simulation.json").read_text())["string"]
    kappa = RHO_STEEL * J * LENGTH / 200.0
    pipe = strings["pipe"]
    assert (pipe["elements"], pipe["lumping"]) == (4, "lumped")
    assert pipe["axial_mass_ratio"] == pytest.approx(PIPE_MASS / M_PIPE_RIG, rel=1e-13)
    assert pipe["kappa"] == pytest.approx(kappa, rel=1e-13)
    assert strings["other"]["axial_mass_ratio"] == 0.0  # the reference pipe: a massless spring
    assert strings["other"]["kappa"] == pytest.approx(kappa, rel=1e-13)


@pytest.mark.parametrize("name", ["reference", "nope", None])
def test_rig_string_unknown_names(name: object) -> None:
    with pytest.raises(ValueError, match=r"no string is known .*pipe-rig.*reference-rig"):
        rig_string(name)  # type: ignore[arg-type]


# ---------------------------------------------------------------------------------------------
# what was there before stays as it was
# ---------------------------------------------------------------------------------------------


def test_reference_sets_unchanged() -> None:
    """Bit for bit (the names, files and the rig's scaled set: tests/test_params.py)."""
    assert dataclasses.asdict(REFERENCE) == REFERENCE_VALUES
    assert KNOWN_PARAMS["reference"] is REFERENCE
    assert dataclasses.asdict(REFERENCE_RIG) == REFERENCE_RIG_VALUES
    # the scaled reference set is still recognised as the reference rig, not the pipe rig
    assert known_rig(REFERENCE) is REFERENCE_RIG
    assert rig_pipe(REFERENCE_RIG) == REFERENCE_PIPE


def test_the_string_default_is_still_the_paper() -> None:
    s = StringParams()
    assert (s.elements, s.lumping, s.axial_mass_ratio) == (1, "paper", 0.0)
    assert s.kappa == REFERENCE_KAPPA
