"""Braking as an input of the input-constrained LMI design.

* an asymmetric torque range: the budget is the smaller of the two margins about the operating
  torque, and on the certificate's (centred) ellipsoid the feedback torque does reach both -peak
  and +peak, so the smaller margin is what binds;
* hand-made drives: a generous braking limit certifies and its gains file records the limit,
  which the re-check from the file uses; no braking (R_min = 0) on the reference set is refused
  with the least braking limit, which a re-run of the design confirms at +- the bisection's
  tolerance; a drive whose margin above the operating torque is too small is refused with no
  braking limit at all;
* ``drillstring design --torque-limit tds-11sa --braking-limit KNM``: exit 1 and the least braking
  in kN m at 0 (certified at that number, refused just below), the limit in the file and in
  ``--check``; a bad value exits 2 naming --braking-limit.
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from drillstring.apps.design import design_main
from drillstring.controller.averaged import averaged_model
from drillstring.controller.constrained import (
    ConstrainedInfeasible,
    recheck_constrained,
    torque_budget,
    torque_margins,
)
from drillstring.controller.design import design_constrained
from drillstring.controller.gains import GainsFileError, read_gains, write_gains
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.topdrive import TopDrive

A, TAUBAR_CRIT = 0.38541455958349763, 2.3927883571184694  # the design's, from the axial fit
MODEL = averaged_model(REFERENCE, A, TAUBAR_CRIT)
ALPHAS = np.logspace(-0.5, 0.5, 5)  # around the best alpha of the full grid (0.63)
#: the operating torque R0 + R_ff about which the feedback acts (31)
BIAS = REFERENCE.R0 + MODEL.R_ff
#: the TDS-11SA's torque on the reference rig, 37,500 ft lbf, by hand in units of C
RATING = 37_500 * 0.3048 * 4.4482216152605 / REFERENCE_RIG.C
TOL = 0.05  # bisection tolerance, units of C


def _drive(braking: float, R_max: float = RATING) -> TopDrive:
    return TopDrive(
        R_min=-braking + 0.0, R_max=R_max, braking="four-quadrant" if braking > 0 else "none"
    )


def _design(braking: float, R_max: float = RATING):
    return design_constrained(
        REFERENCE, MODEL, _drive(braking, R_max), alphas=ALPHAS, label="hand", braking_tol=TOL
    )


def test_the_smaller_margin_binds_on_the_centred_ellipsoid():
    # the margins of a hand-made asymmetric range, by hand
    below, above = torque_margins(REFERENCE, _drive(10.0, 100.0), MODEL.R_ff)
    assert below == pytest.approx(BIAS + 10.0, rel=1e-12)
    assert above == pytest.approx(100.0 - BIAS, rel=1e-12)
    assert torque_budget(REFERENCE, _drive(10.0, 100.0), MODEL.R_ff) == pytest.approx(BIAS + 10)
    # no braking: the budget is the operating torque itself (a light load: about R0)
    assert torque_budget(REFERENCE, _drive(0.0), MODEL.R_ff) == pytest.approx(BIAS, rel=1e-12)
    assert 0.9 * REFERENCE.R0 < BIAS < REFERENCE.R0
    # on E = {x^T S^-1 x <= 1} a linear F x reaches +sqrt(F S F^T) and -sqrt(F S F^T): a random
    # S and F, the boundary sampled, both extremes found (the range is symmetric)
    rng = np.random.default_rng(3)
    M = rng.normal(size=(4, 4))
    S = M @ M.T + 0.1 * np.eye(4)
    F = rng.normal(size=4)
    u = rng.normal(size=(4, 200_000))
    x = np.linalg.cholesky(S) @ (u / np.linalg.norm(u, axis=0))
    assert np.max(np.einsum("ij,ij->j", x, np.linalg.solve(S, x))) == pytest.approx(1.0)
    Fx = F @ x
    peak = math.sqrt(F @ S @ F)
    assert np.max(Fx) <= peak * (1 + 1e-12) and np.max(Fx) > 0.99 * peak
    assert np.min(Fx) >= -peak * (1 + 1e-12) and np.min(Fx) < -0.99 * peak


@pytest.fixture(scope="module")
def generous(tmp_path_factory):
    d = _design(200.0)  # 47 kN m of braking on the reference rig (the TDS-11SA: 50.8)
    return d, write_gains(d.gains, tmp_path_factory.mktemp("braking") / "gains_constrained.json")


def test_a_generous_braking_limit_certifies_and_the_file_records_it(generous):
    d, path = generous
    assert d.result.certificate.passed
    assert d.result.u_max == pytest.approx(BIAS + 200.0, rel=1e-12)  # the braking side binds
    assert d.result.peak_torque <= BIAS + 200.0
    g = read_gains(path)
    assert g.constraint["braking_limit"] == 200.0
    assert g.constraint["torque_limit"] == [-200.0, RATING]
    again = recheck_constrained(g)
    assert again.passed and again.braking_limit == 200.0
    assert again.u_max == pytest.approx(BIAS + 200.0, rel=1e-12)
    assert design_main(["--check", str(path)]) == 0


def _edited(path, tmp_path, name, change):
    data = json.loads(path.read_text())
    change(data["constraint"])
    out = tmp_path / name
    out.write_text(json.dumps(data))
    return out


def test_the_recheck_from_the_file_takes_the_braking_limit(generous, tmp_path):
    d, path = generous
    peak = d.result.certificate.peak_torque  # sqrt(F S F^T), what the check computes

    def lower(c, b):
        c["braking_limit"] = b
        c["torque_limit"][0] = -b

    # the braking limit lowered below what the peak needs: the file reads, the check fails
    small = peak - BIAS - 1.0
    out = _edited(path, tmp_path, "less.json", lambda c: lower(c, small))
    cert = recheck_constrained(read_gains(out))
    assert not cert.passed and cert.u_max == pytest.approx(BIAS + small, rel=1e-12)
    assert design_main(["--check", str(out)]) == 1
    # just enough braking still passes
    enough = peak - BIAS + 1e-6
    assert recheck_constrained(
        read_gains(_edited(path, tmp_path, "enough.json", lambda c: lower(c, enough)))
    ).passed
    # a braking limit that is not -R_min of the torque limit, or negative: refused on reading
    with pytest.raises(GainsFileError, match="is not -R_min"):
        read_gains(_edited(path, tmp_path, "x.json", lambda c: c.update(braking_limit=50.0)))
    with pytest.raises(GainsFileError, match="must be >= 0"):
        read_gains(_edited(path, tmp_path, "n.json", lambda c: lower(c, -1.0)))
    # a file written before the braking limit was recorded: the torque limit gives it
    old = recheck_constrained(
        read_gains(_edited(path, tmp_path, "old.json", lambda c: c.pop("braking_limit")))
    )
    assert old.passed and old.braking_limit == 200.0


def test_no_braking_is_refused_with_the_least_braking_a_rerun_confirms(generous):
    with pytest.raises(ConstrainedInfeasible) as info:
        _design(0.0)
    exc = info.value
    assert exc.braking_limit == 0.0 and exc.tol == TOL
    least = exc.least_braking
    assert least is not None and f"at least {least:.4g}" in str(exc)
    assert "no certificate at the braking limit 0 " in str(exc)
    # the design's least peak (from any drive that certifies: it does not depend on the budget)
    # less the operating torque is the least braking, to within the tolerance
    peak = generous[0].result.peak_torque
    assert peak - BIAS - 1e-3 <= least <= peak - BIAS + TOL + 1e-3
    # the design re-run: certified at least + tol, refused at least - tol
    assert _design(least + TOL).result.certificate.passed
    with pytest.raises(ConstrainedInfeasible):
        _design(least - TOL)


def test_no_braking_helps_when_the_margin_above_is_too_small():
    with pytest.raises(ConstrainedInfeasible, match="no braking limit gives a certified") as e:
        _design(500.0, R_max=100.0)
    assert e.value.least_braking is None


def _kNm(text: str, pattern: str) -> float:
    m = re.search(pattern, text)
    assert m is not None, text
    return float(m.group(1))


@pytest.mark.slow  # an end-to-end run of several seconds: make test, not test-fast
def test_the_command_line_refuses_no_braking_and_names_the_least_braking(tmp_path, capsys):
    base = ["--A", repr(A), "--taubar-crit", repr(TAUBAR_CRIT), "--no-paper",
            "--torque-limit", "tds-11sa"]  # fmt: skip
    out = tmp_path / "zero"
    assert design_main([*base, "--out", str(out), "--braking-limit", "0"]) == 1
    err = capsys.readouterr().err
    assert "no certificate exists at the braking limit 0 kN m" in err
    least = _kNm(err, r"the least braking a certified design needs is ([0-9.]+) kN m")
    assert "tolerance 0.01 kN m" in err
    assert not (out / "gains_constrained.json").exists()
    # consistent with the least peak it names: peak - operating torque, in kN m (C = 235 N m)
    peak = _kNm(err, r"the least peak feedback torque from the switch-on is ([0-9.]+) kN m")
    bias_kNm = BIAS * REFERENCE_RIG.C / 1e3
    assert peak - bias_kNm - 0.01 <= least <= peak - bias_kNm + 0.03
    # the number is certified as printed, and 0.02 kN m less (tolerance and rounding) is not
    ok = tmp_path / "ok"
    assert design_main([*base, "--out", str(ok), "--braking-limit", f"{least:.2f}"]) == 0
    printed = capsys.readouterr().out
    assert "certificate PASSED" in printed
    g = read_gains(ok / "gains_constrained.json")
    assert g.constraint["braking_limit"] == pytest.approx(least * 1e3 / REFERENCE_RIG.C, 1e-12)
    assert g.constraint["torque_limit"][0] == -g.constraint["braking_limit"]
    assert g.constraint["torque_limit"][1] == pytest.approx(RATING, rel=1e-9)
    assert design_main(["--check", str(ok / "gains_constrained.json")]) == 0
    assert "braking limit" in capsys.readouterr().out
    below = f"{least - 0.02:.2f}"
    assert design_main([*base, "--out", str(tmp_path / "below"), "--braking-limit", below]) == 1
    assert f"at the braking limit {float(below):.4g} kN m" in capsys.readouterr().err


@pytest.mark.parametrize("bad", ["-1", "nan", "inf", "lots", ""])
def test_a_bad_braking_limit_exits_2_naming_it(bad, tmp_path, capsys):
    argv = ["--torque-limit", "tds-11sa", "--braking-limit", bad, "--out", str(tmp_path)]
    with pytest.raises(SystemExit) as info:
        design_main(argv)
    assert info.value.code == 2
    assert "--braking-limit" in capsys.readouterr().err


def test_a_braking_limit_needs_a_torque_limit(tmp_path, capsys):
    argv = ["--A", repr(A), "--no-paper", "--braking-limit", "5", "--out", str(tmp_path)]
    assert design_main(argv) == 2
    assert "--braking-limit needs --torque-limit" in capsys.readouterr().err
