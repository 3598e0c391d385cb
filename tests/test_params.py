"""Tests for drillstring.model.params: derived quantities, eqs. (15)-(16), files and validation.

Expected values are computed by hand from the reference set (docs/model.md, "Reference parameter
set"), the reference rig (docs/reference_rig.md) and the paper's formulas, never taken from the
code under test.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from drillstring.model.params import (
    KNOWN_PARAMS,
    KNOWN_PHYSICAL,
    REFERENCE,
    REFERENCE_RIG,
    REFERENCE_RIG_CHOICES,
    ParameterError,
    PhysicalParams,
    ScaledParams,
    get_params,
    get_physical,
    load_params,
    params_from_spec,
    read_params,
    save_params,
)

DATA = Path(__file__).resolve().parents[1] / "drillstring" / "model" / "data"

SCALED_OK = dict(
    n=4, psi=250.0, gamma=0.0, eta=10.0, lam=0.0, beta=1.0, rho=5.0, v0=1.0, omega0=5.0
)

# A made-up physical set chosen so that every scaled value is a round number by hand:
# t* = sqrt(4/1) = 2, L* = 2*1/(2*1^2) = 1, gamma = 2/8*2 = 0.5, eta = sqrt(50*4/(8*1)) = 5,
# psi = 0.5*2*1*4/(8*1) = 0.5, lambda = 1*0.3*10/(2*0.5*1) = 3, beta = 0.5*0.8*0.5 = 0.2,
# rho = 12/4 = 3, v0 = 0.25*2/1 = 0.5, omega0 = 1.5*2 = 3.
PHYS_ROUND = dict(
    M=8.0,
    I1=4.0,
    I2=12.0,
    C=1.0,
    K=50.0,
    D=2.0,
    n=3,
    a=1.0,
    eps=2.0,
    zeta=0.5,
    sigma_bar=10.0,
    l=0.3,
    mu=0.8,
    xi=0.5,
    V0=0.25,
    Omega0=1.5,
)
SCALED_ROUND = dict(
    n=3, psi=0.5, gamma=0.5, eta=5.0, lam=3.0, beta=0.2, rho=3.0, v0=0.5, omega0=3.0
)

# A field-scale made-up set (SI units) for a second, formula-based check.
PHYS_FIELD = dict(
    M=3.5e4,
    I1=120.0,
    I2=500.0,
    C=470.0,
    K=7.0e5,
    D=1.2e4,
    n=4,
    a=0.108,
    eps=60e6,
    zeta=0.6,
    sigma_bar=60e6,
    l=1.2e-3,
    mu=0.6,
    xi=1.2,
    V0=0.01,
    Omega0=10.0,
)


# ---------------------------------------------------------------------------------------------
# derived quantities
# ---------------------------------------------------------------------------------------------


def test_reference_derived_quantities() -> None:
    r = REFERENCE
    assert r.tau_n0 == pytest.approx(math.pi / 10, rel=1e-15)
    assert r.d0 == pytest.approx(math.pi / 10, rel=1e-15)  # v0 = 1
    assert r.sqrt_npsi == pytest.approx(math.sqrt(1000.0), rel=1e-15)
    assert r.gammabar == pytest.approx(0.2, rel=1e-14)
    assert r.etabar == pytest.approx(1.0 / math.sqrt(10.0), rel=1e-14)
    assert r.etabar2 == pytest.approx(0.1, rel=1e-14)
    assert r.vbar0 == pytest.approx(1.0 / math.sqrt(1000.0), rel=1e-14)
    # tau_n0 * sqrt(n psi) = (pi/10) * sqrt(1000) = pi * sqrt(10); docs/model.md rounds it to 9.93
    assert r.taubar_n0 == pytest.approx(math.pi * math.sqrt(10.0), rel=1e-14)
    assert abs(r.taubar_n0 - 9.93) < 5e-3
    # R0 = n d0 + n beta lambda = 4 pi/10 + 4 * 0.5 * 1.58
    assert r.R0 == pytest.approx(0.4 * math.pi + 3.16, rel=1e-14)


def test_derived_quantities_other_set() -> None:
    p = ScaledParams(**SCALED_ROUND)  # n = 3, psi = 0.5 -> sqrt(n psi) = sqrt(1.5)
    assert p.tau_n0 == pytest.approx(2 * math.pi / 9, rel=1e-15)
    assert p.d0 == pytest.approx(math.pi / 9, rel=1e-15)
    assert p.gammabar == pytest.approx(0.5 / math.sqrt(1.5), rel=1e-14)
    assert p.etabar2 == pytest.approx(25.0 / 1.5, rel=1e-14)
    assert p.etabar**2 == pytest.approx(p.etabar2, rel=1e-14)
    assert p.R0 == pytest.approx(3 * math.pi / 9 + 3 * 0.2 * 3.0, rel=1e-14)


# ---------------------------------------------------------------------------------------------
# physical -> scaled, eqs. (15)-(16)
# ---------------------------------------------------------------------------------------------


def test_physical_to_scaled_round_numbers() -> None:
    phys = PhysicalParams(**PHYS_ROUND)
    assert phys.t_star == pytest.approx(2.0, rel=1e-15)
    assert phys.L_star == pytest.approx(1.0, rel=1e-15)
    s = phys.to_scaled()
    for name, expected in SCALED_ROUND.items():
        assert getattr(s, name) == pytest.approx(expected, rel=1e-14), name
    assert isinstance(s.n, int) and s.n == 3


def test_physical_to_scaled_field_scale() -> None:
    q = PHYS_FIELD
    t = math.sqrt(q["I1"] / q["C"])
    L = 2 * q["C"] / (q["eps"] * q["a"] ** 2)
    expected = {
        "gamma": q["D"] / q["M"] * t,
        "eta": math.sqrt(q["K"] * q["I1"] / (q["M"] * q["C"])),
        "psi": q["zeta"] * q["eps"] * q["a"] * q["I1"] / (q["M"] * q["C"]),
        "lam": q["a"] ** 2 * q["l"] * q["sigma_bar"] / (2 * q["zeta"] * q["C"]),
        "beta": q["zeta"] * q["mu"] * q["xi"],
        "rho": q["I2"] / q["I1"],
        "v0": q["V0"] * t / L,
        "omega0": q["Omega0"] * t,
    }
    s = PhysicalParams(**q).to_scaled()
    for name, value in expected.items():
        assert getattr(s, name) == pytest.approx(value, rel=1e-13), name


@pytest.mark.parametrize("q", [PHYS_ROUND, PHYS_FIELD], ids=["round", "field"])
def test_nominal_torque_two_routes(q: dict) -> None:
    """Eq. (8) solved for R0 in SI units, divided by C, equals the scaled n*d0 + n*beta*lambda."""
    phys = PhysicalParams(**q)
    s = phys.to_scaled()
    assert phys.R0 / phys.C == pytest.approx(s.R0, rel=1e-13)
    # depth of cut scales by L*: d0 [m] / L* = v0 * tau_n0
    assert phys.d0 / phys.L_star == pytest.approx(s.d0, rel=1e-13)
    # delay scales by t*: t_n0 = 2 pi/(n Omega0) seconds
    assert 2 * math.pi / (phys.n * phys.Omega0) / phys.t_star == pytest.approx(s.tau_n0, rel=1e-13)


def test_sharp_cutter_and_no_damping_allowed() -> None:
    s = PhysicalParams(**{**PHYS_ROUND, "l": 0.0, "D": 0.0}).to_scaled()
    assert s.lam == 0.0 and s.gamma == 0.0
    s = PhysicalParams(**{**PHYS_ROUND, "sigma_bar": 0.0}).to_scaled()
    assert s.lam == 0.0


def test_physical_beta_above_one_is_reported() -> None:
    phys = PhysicalParams(**{**PHYS_ROUND, "mu": 2.0, "xi": 2.0})  # beta = 0.5*2*2 = 2
    with pytest.raises(ParameterError, match="beta") as exc:
        phys.to_scaled()
    assert "2.0" in str(exc.value)


# ---------------------------------------------------------------------------------------------
# named sets, replace, dicts
# ---------------------------------------------------------------------------------------------


def test_get_params_unknown_lists_known() -> None:
    with pytest.raises(ParameterError) as exc:
        get_params("nope")
    assert "nope" in str(exc.value) and "reference" in str(exc.value)


def test_reference_file_equals_reference() -> None:
    assert load_params(DATA / "reference.toml") == REFERENCE


def test_params_from_spec(tmp_path: Path) -> None:
    assert params_from_spec("reference") == REFERENCE
    f = save_params(ScaledParams(**SCALED_ROUND), tmp_path / "x.json")
    assert params_from_spec(str(f)) == ScaledParams(**SCALED_ROUND)
    with pytest.raises(ParameterError, match="missing"):
        params_from_spec("missing")


def test_replace_validates_and_aliases() -> None:
    p = REFERENCE.replace(omega0=10.0)
    assert p.omega0 == 10.0 and p.tau_n0 == pytest.approx(math.pi / 20, rel=1e-15)
    assert REFERENCE.omega0 == 5.0  # the original is untouched
    assert REFERENCE.replace(**{"lambda": 2.5}).lam == 2.5
    with pytest.raises(ParameterError, match="beta"):
        REFERENCE.replace(beta=1.5)
    with pytest.raises(ParameterError, match="bogus"):
        REFERENCE.replace(bogus=1.0)
    with pytest.raises(ParameterError, match="Omega0"):
        PhysicalParams(**PHYS_ROUND).replace(Omega0=0.0)


def test_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        REFERENCE.psi = 1.0  # type: ignore[misc]


def test_dict_round_trip_and_keys() -> None:
    d = REFERENCE.to_dict()
    assert list(d) == ["n", "psi", "gamma", "eta", "lambda", "beta", "rho", "v0", "omega0"]
    assert ScaledParams.from_dict(d) == REFERENCE
    d_lam = {("lam" if k == "lambda" else k): v for k, v in d.items()}
    assert ScaledParams.from_dict(d_lam) == REFERENCE
    with pytest.raises(ParameterError, match="twice"):
        ScaledParams.from_dict({**d, "lam": 1.0})
    assert PhysicalParams.from_dict(PhysicalParams(**PHYS_FIELD).to_dict()) == PhysicalParams(
        **PHYS_FIELD
    )


# ---------------------------------------------------------------------------------------------
# files
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_scaled_file_round_trip(tmp_path: Path, suffix: str) -> None:
    for p in (REFERENCE, ScaledParams(**SCALED_ROUND), REFERENCE.replace(psi=1.0 / 3.0, v0=1e-7)):
        path = save_params(p, tmp_path / f"p{suffix}")
        assert load_params(path) == p  # bit-exact: floats are written with repr
    assert [f.name for f in tmp_path.iterdir()] == [f"p{suffix}"]  # no temp file left behind


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_physical_file_round_trip(tmp_path: Path, suffix: str) -> None:
    phys = PhysicalParams(**PHYS_FIELD)
    path = save_params(phys, tmp_path / f"phys{suffix}")
    assert read_params(path) == phys
    assert load_params(path) == phys.to_scaled()


def test_toml_text_layout(tmp_path: Path) -> None:
    path = save_params(REFERENCE, tmp_path / "ref.toml")
    text = path.read_text()
    assert 'kind = "scaled"' in text and "lambda = 1.58" in text and "n = 4\n" in text
    data = tomllib.loads(text)
    assert data["kind"] == "scaled" and isinstance(data["n"], int)
    json_data = json.loads(save_params(REFERENCE, tmp_path / "ref.json").read_text())
    assert json_data["kind"] == "scaled" and json_data["lambda"] == 1.58


def _write(path: Path, data: dict) -> Path:
    if path.suffix == ".json":
        path.write_text(json.dumps(data))
    else:
        lines = [f"{k} = {json.dumps(v)}" for k, v in data.items()]
        path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_unknown_key_is_error(tmp_path: Path, suffix: str) -> None:
    data = {"kind": "scaled", **REFERENCE.to_dict(), "omega_0": 5.0}
    with pytest.raises(ParameterError, match="omega_0"):
        load_params(_write(tmp_path / f"p{suffix}", data))


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_missing_key_is_error(tmp_path: Path, suffix: str) -> None:
    data = {"kind": "scaled", **REFERENCE.to_dict()}
    del data["rho"]
    with pytest.raises(ParameterError, match="missing.*rho"):
        load_params(_write(tmp_path / f"p{suffix}", data))


def test_physical_unknown_and_missing_key(tmp_path: Path) -> None:
    data = {"kind": "physical", **PHYS_ROUND, "Omega": 1.0}
    with pytest.raises(ParameterError, match="'Omega'"):
        load_params(_write(tmp_path / "a.toml", data))
    data = {"kind": "physical", **PHYS_ROUND}
    del data["sigma_bar"]
    with pytest.raises(ParameterError, match="sigma_bar"):
        load_params(_write(tmp_path / "b.toml", data))


def test_file_kind_errors(tmp_path: Path) -> None:
    with pytest.raises(ParameterError, match="kind"):
        load_params(_write(tmp_path / "a.toml", REFERENCE.to_dict()))
    with pytest.raises(ParameterError, match="'scaledd'"):
        load_params(_write(tmp_path / "b.toml", {"kind": "scaledd", **REFERENCE.to_dict()}))
    # physical fields under the scaled kind: the first foreign key is named
    with pytest.raises(ParameterError, match="unknown key 'M'"):
        load_params(_write(tmp_path / "c.toml", {"kind": "scaled", **PHYS_ROUND}))


def test_file_format_errors(tmp_path: Path) -> None:
    with pytest.raises(ParameterError, match="suffix"):
        load_params(tmp_path / "p.yaml")
    with pytest.raises(ParameterError, match="suffix"):
        save_params(REFERENCE, tmp_path / "p.txt")
    bad = tmp_path / "bad.toml"
    bad.write_text("kind = scaled\n")
    with pytest.raises(ParameterError, match="not valid toml"):
        load_params(bad)
    with pytest.raises(ParameterError, match="cannot read"):
        load_params(tmp_path / "absent.json")
    with pytest.raises(ParameterError, match="psi"):
        load_params(_write(tmp_path / "s.json", {"kind": "scaled", **SCALED_OK, "psi": "250"}))


# ---------------------------------------------------------------------------------------------
# the reference rig (docs/reference_rig.md)
# ---------------------------------------------------------------------------------------------

SCALED_FIELDS = [f.name for f in dataclasses.fields(ScaledParams)]


def _assert_maps_onto(phys: PhysicalParams, target: ScaledParams, rel: float = 1e-12) -> None:
    s = phys.to_scaled()
    assert s.n == target.n and isinstance(s.n, int)
    for name in SCALED_FIELDS[1:]:
        assert getattr(s, name) == pytest.approx(getattr(target, name), rel=rel, abs=0.0), name


def test_reference_rig_maps_onto_reference() -> None:
    _assert_maps_onto(REFERENCE_RIG, REFERENCE)


def test_reference_rig_keeps_its_choices_and_scales() -> None:
    r = REFERENCE_RIG
    assert {k: getattr(r, k) for k in REFERENCE_RIG_CHOICES} == {
        "C": 235.0,
        "I1": 200.0,
        "a": 0.10795,  # 8 1/2-in bit
        "eps": 60e6,
        "zeta": 0.6,
        "xi": 4.0 / 3.0,
        "sigma_bar": 60e6,
    }
    assert r.n == 4
    # t* = sqrt(200/235); L* = 2*235/(60e6*0.10795^2) (Section II: t* ~ 1 s, L* ~ 1 mm)
    assert r.t_star == pytest.approx(0.9225312080288851, rel=1e-14)
    assert r.L_star == pytest.approx(6.722043432552839e-4, rel=1e-14)
    assert 0.5 < r.t_star < 2.0 and 0.3e-3 < r.L_star < 3e-3


def test_reference_rig_solved_values_by_hand() -> None:
    """The eight solved values, each from (15)-(16) by hand with t*^2 = 200/235."""
    r = REFERENCE_RIG
    t2 = 200.0 / 235.0
    zea = 0.6 * 60e6 * 0.10795  # zeta*eps*a = 3.8862e6 N/m
    assert r.M == pytest.approx(zea * t2 / 250.0, rel=1e-14)  # psi = zeta eps a t*^2 / M
    assert r.K == pytest.approx(0.1 * 4 * zea, rel=1e-14)  # eta^2/psi = K/(zeta eps a) = 0.4
    assert r.D == pytest.approx(2 * math.sqrt(10) * r.M / math.sqrt(t2), rel=1e-14)
    assert r.I2 == 1000.0
    assert r.mu == pytest.approx(0.625, rel=1e-15)  # 0.5/(0.6*4/3)
    assert r.l == pytest.approx(2 * 0.6 * 235 * 1.58 / (0.10795**2 * 60e6), rel=1e-14)
    assert r.Omega0 == pytest.approx(5.0 / math.sqrt(t2), rel=1e-14)
    assert r.V0 == pytest.approx(r.L_star / math.sqrt(t2), rel=1e-14)
    # and the numbers quoted in docs/reference_rig.md
    assert (r.M, r.K, r.D) == pytest.approx((13229.617, 1.55448e6, 90697.685), rel=1e-7)
    assert (r.l, r.V0, r.Omega0) == pytest.approx((6.3725e-4, 7.28652e-4, 5.419871), rel=1e-5)


def test_reference_rig_nominal_loads_from_the_paper() -> None:
    """W0, T0 = R0 from (4), (7), (8) in SI units, and again in closed form from the scaled set."""
    r = REFERENCE_RIG
    d0 = 2 * math.pi / r.n * r.V0 / r.Omega0  # (8): d0 = (2 pi/n) V0/Omega0 = V0 t_n0
    Wc = r.n * r.a * r.zeta * r.eps * d0  # (4)
    Wf = r.n * r.a * r.l * r.sigma_bar  # (7), dU/dt > 0
    Tc = 0.5 * r.n * r.a**2 * r.eps * d0  # (4)
    Tf = 0.5 * r.a * r.xi * r.mu * Wf  # (7)
    assert r.d0 == pytest.approx(d0, rel=1e-14)
    assert r.W0 == pytest.approx(Wc + Wf, rel=1e-14)
    assert r.T0 == pytest.approx(Tc + Tf, rel=1e-14)
    # (8) solved for R0
    R0 = 0.5 * r.n * r.a**2 * r.eps * d0 + 0.5 * r.n * r.a**2 * r.xi * r.mu * r.l * r.sigma_bar
    assert r.R0 == pytest.approx(R0, rel=1e-14)
    # closed forms through (16): T^c = C n d0/L*, T^f = C n beta lambda,
    # W^c = (2 n zeta C/a) d0/L*, W^f = (2 n zeta C/a) lambda; d0/L* = v0 tau_n0 = pi/10
    C, a, n = 235.0, 0.10795, 4
    assert Tc == pytest.approx(C * n * math.pi / 10, rel=1e-13)
    assert Tf == pytest.approx(C * n * 0.5 * 1.58, rel=1e-13)
    assert Wc == pytest.approx(2 * n * 0.6 * C / a * math.pi / 10, rel=1e-13)
    assert Wf == pytest.approx(2 * n * 0.6 * C / a * 1.58, rel=1e-13)
    assert r.R0 == pytest.approx(C * REFERENCE.R0, rel=1e-13)
    # the numbers quoted in docs/reference_rig.md: WOB 19.79 kN, TOB 1.038 kN m
    assert (r.W0, r.T0) == pytest.approx((19792.604, 1037.9097), rel=1e-7)


def test_reference_rig_operating_point() -> None:
    r = REFERENCE_RIG
    t_star = math.sqrt(200.0 / 235.0)
    # Omega0 = omega0/t* rad/s -> rpm; V0 = v0 L*/t* m/s -> m/h; n d0 = 2 pi V0/Omega0 per turn
    assert r.surface_speed_rpm == pytest.approx(5.0 / t_star * 60 / (2 * math.pi), rel=1e-14)
    assert r.rop_m_per_h == pytest.approx(r.L_star / t_star * 3600, rel=1e-14)
    assert r.depth_of_cut_per_rev_mm == pytest.approx(2 * math.pi * r.L_star / 5.0 * 1e3, rel=1e-13)
    assert (r.surface_speed_rpm, r.rop_m_per_h, r.depth_of_cut_per_rev_mm) == pytest.approx(
        (51.75595, 2.623148, 0.8447169), rel=1e-6
    )


@pytest.mark.parametrize("q", [PHYS_ROUND, PHYS_FIELD], ids=["round", "field"])
def test_operating_point_other_sets(q: dict) -> None:
    p = PhysicalParams(**q)
    assert p.surface_speed_rpm == pytest.approx(q["Omega0"] * 30 / math.pi, rel=1e-14)
    assert p.rop_m_per_h == pytest.approx(q["V0"] * 3600, rel=1e-14)
    per_rev = 2 * math.pi * q["V0"] / q["Omega0"]
    assert p.depth_of_cut_per_rev_mm == pytest.approx(per_rev * 1e3, rel=1e-14)
    d0 = per_rev / q["n"]
    W0 = q["n"] * q["a"] * (q["zeta"] * q["eps"] * d0 + q["l"] * q["sigma_bar"])
    assert p.W0 == pytest.approx(W0, rel=1e-14)
    assert p.T0 == p.R0


def test_from_scaled_inverts_to_scaled() -> None:
    choices = dict(C=1.0, I1=4.0, a=1.0, eps=2.0, zeta=0.5, xi=0.5, sigma_bar=10.0)
    phys = PhysicalParams.from_scaled(ScaledParams(**SCALED_ROUND), **choices)
    # PHYS_ROUND was built by hand to give SCALED_ROUND with exactly these seven values
    for name, value in PHYS_ROUND.items():
        assert getattr(phys, name) == pytest.approx(value, rel=1e-14), name
    _assert_maps_onto(phys, ScaledParams(**SCALED_ROUND))
    sharp = REFERENCE.replace(lam=0.0, gamma=0.0)
    p = PhysicalParams.from_scaled(sharp, **REFERENCE_RIG_CHOICES)
    assert p.l == 0.0 and p.D == 0.0
    _assert_maps_onto(p, sharp)


@pytest.mark.parametrize(
    ("name", "value"), [("C", 0.0), ("I1", -1.0), ("a", float("nan")), ("xi", "1"), ("eps", True)]
)
def test_from_scaled_rejects_bad_choices(name: str, value: object) -> None:
    with pytest.raises(ParameterError) as exc:
        PhysicalParams.from_scaled(REFERENCE, **{**REFERENCE_RIG_CHOICES, name: value})
    assert f"from_scaled: {name} " in str(exc.value) and repr(value) in str(exc.value)
    with pytest.raises(ParameterError, match="expected ScaledParams"):
        PhysicalParams.from_scaled(REFERENCE_RIG, **REFERENCE_RIG_CHOICES)  # type: ignore[arg-type]


def test_from_scaled_result_out_of_range_is_reported() -> None:
    # valid choices whose product overflows: the solved M = zeta*eps*a*t*^2/psi is not finite
    huge = {**REFERENCE_RIG_CHOICES, "zeta": 1e200, "eps": 1e200}
    with pytest.raises(ParameterError, match=r"PhysicalParams\.M must be finite, got inf"):
        PhysicalParams.from_scaled(REFERENCE, **huge)


def test_reference_rig_by_name() -> None:
    # the pipe rig (tests/test_pipe_rig.py) is the one set added since
    assert set(KNOWN_PARAMS) == {"reference", "reference-rig", "pipe-rig"}
    assert set(KNOWN_PHYSICAL) == {"reference-rig", "pipe-rig"}
    assert KNOWN_PHYSICAL["reference-rig"] is REFERENCE_RIG
    assert get_physical("reference-rig") is REFERENCE_RIG
    for s in (get_params("reference-rig"), params_from_spec("reference-rig")):
        assert isinstance(s, ScaledParams)
        for name in SCALED_FIELDS:
            assert getattr(s, name) == pytest.approx(getattr(REFERENCE, name), rel=1e-12), name
    assert get_params("reference") is REFERENCE  # scaled names unchanged
    with pytest.raises(ParameterError, match="'reference' is a scaled set.*reference-rig"):
        get_physical("reference")
    with pytest.raises(ParameterError, match="'nope' is unknown.*reference-rig"):
        get_physical("nope")
    with pytest.raises(ParameterError, match="unknown"):
        get_physical(["reference-rig"])  # type: ignore[arg-type]


def test_reference_rig_file() -> None:
    path = DATA / "reference_rig.toml"
    assert tomllib.loads(path.read_text())["kind"] == "physical"
    assert read_params(path) == REFERENCE_RIG  # the shipped file is the set, bit for bit
    s = load_params(path)
    for name in SCALED_FIELDS:
        assert getattr(s, name) == pytest.approx(getattr(REFERENCE, name), rel=1e-12), name
    assert params_from_spec(str(path)) == s


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_reference_rig_file_round_trip(tmp_path: Path, suffix: str) -> None:
    path = save_params(REFERENCE_RIG, tmp_path / f"rig{suffix}")
    back = read_params(path)
    assert isinstance(back, PhysicalParams) and back == REFERENCE_RIG
    _assert_maps_onto(back, REFERENCE)


# ---------------------------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------------------------

nan, inf = float("nan"), float("inf")

SCALED_BAD = [
    ("n", 0),
    ("n", -2),
    ("n", 4.5),
    ("n", True),
    ("n", "4"),
    ("n", nan),
    ("psi", 0.0),
    ("psi", -250.0),
    ("psi", nan),
    ("psi", inf),
    ("psi", "250"),
    ("psi", None),
    ("gamma", -0.1),
    ("gamma", nan),
    ("eta", 0.0),
    ("eta", -inf),
    ("lam", -1.0),
    ("lam", nan),
    ("beta", 0.0),
    ("beta", -0.5),
    ("beta", 1.0000001),
    ("beta", inf),
    ("rho", 0.0),
    ("rho", False),
    ("v0", 0.0),
    ("v0", -1.0),
    ("omega0", 0.0),
    ("omega0", -5.0),
    ("omega0", inf),
]


PHYS_STRICT = ["M", "I1", "I2", "C", "K", "a", "eps", "zeta", "mu", "xi", "V0", "Omega0"]
PHYS_NONNEG = ["D", "sigma_bar", "l"]
PHYS_BAD = (
    [(f, 0.0) for f in PHYS_STRICT]
    + [(f, -1.0) for f in PHYS_STRICT + PHYS_NONNEG]
    + [(f, nan) for f in PHYS_STRICT + PHYS_NONNEG]
    + [(f, inf) for f in ["M", "C", "D", "Omega0"]]
    + [("n", 0), ("n", 2.5), ("n", True), ("M", "1"), ("l", True)]
)


@pytest.mark.parametrize(
    ("cls", "valid", "rows"),
    [(ScaledParams, SCALED_OK, SCALED_BAD), (PhysicalParams, PHYS_ROUND, PHYS_BAD)],
    ids=["scaled", "physical"],
)
def test_validation(cls: type, valid: dict, rows: list[tuple[str, object]]) -> None:
    """Each bad value of a valid set is refused by a ParameterError (a ValueError) naming the
    field as ``Class.field`` and the value; every row that is not is listed."""
    assert issubclass(ParameterError, ValueError)
    failures = []
    for field, value in rows:
        try:
            cls(**{**valid, field: value})
        except ParameterError as exc:
            if f"{cls.__name__}.{field} " not in str(exc) or repr(value) not in str(exc):
                failures.append(f"{field} = {value!r}: {exc}")
        else:
            failures.append(f"{field} = {value!r} accepted")
    assert failures == []


def test_accepted_edge_values_and_coercion() -> None:
    p = ScaledParams(**SCALED_OK)  # gamma = 0, lam = 0, beta = 1 are allowed
    assert (p.gamma, p.lam, p.beta) == (0.0, 0.0, 1.0)
    q = ScaledParams(**{**SCALED_OK, "n": 4.0, "psi": 250})
    assert type(q.n) is int and q.n == 4 and type(q.psi) is float
    r = ScaledParams(**{**SCALED_OK, "n": np.int64(4), "psi": np.float32(250.0)})
    assert type(r.n) is int and type(r.psi) is float and r == q
    assert PhysicalParams(**{**PHYS_ROUND, "n": 3.0}).n == 3
