"""LMI synthesis (33), certificate (32), the paper's gain, and the gains file."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from test_averaged import A_REF, TAUBAR_CRIT_REF, rhp_zero_count

from drillstring.apps.design import design_main
from drillstring.controller.averaged import averaged_model, delay_roots
from drillstring.controller.gains import (
    PAPER_F,
    GainsFileError,
    params_hash,
    read_gains,
    write_gains,
)
from drillstring.controller.synthesis import (
    ALPHA_GRID,
    GAIN_MAX,
    LMI_MARGIN,
    SynthesisInfeasible,
    evaluate_gain,
    synthesize,
    to_gains_file,
)
from drillstring.model.params import REFERENCE


def block32(Abar, A1, P, alpha):
    """(32) written out."""
    return np.block([[P @ Abar + Abar.T @ P + alpha * P, P @ A1], [A1.T @ P, -alpha * P]])


def block33(A0, A1, B, S, X, alpha):
    """(33) written out."""
    M11 = A0 @ S + S @ A0.T + B @ X + X.T @ B.T + alpha * S
    return np.block([[M11, A1 @ S], [S @ A1.T, -alpha * S]])


@pytest.fixture(scope="module")
def result():
    return synthesize(averaged_model(REFERENCE, A_REF, TAUBAR_CRIT_REF))


def test_synthesis_feasible_and_certified(result):
    m = result.model
    cert = result.certificate
    assert cert.passed
    # LMI (33) holds for the returned S, X (computed here, not by the package)
    M33 = block33(m.A0, m.A1, m.B, result.S, result.X, result.alpha)
    assert np.linalg.eigvalsh(0.5 * (M33 + M33.T))[-1] < 0.0
    assert np.linalg.eigvalsh(result.S)[0] >= 1.0 - 1e-6  # normalisation S >= I
    np.testing.assert_allclose(result.F @ result.S, result.X.ravel(), rtol=1e-9, atol=1e-9)
    # Lemma 1 (32) with P = S^-1 and A0 + B F
    P = np.linalg.inv(result.S)
    Abar = m.A0 + m.B @ result.F[None, :]
    M32 = block32(Abar, m.A1, P, result.alpha)
    assert np.linalg.eigvalsh(0.5 * (M32 + M32.T))[-1] < 0.0
    assert cert.lmi_max_eig < 0.0
    assert cert.lmi_decay_margin >= 0.5 * LMI_MARGIN
    # bounded gain
    assert np.linalg.norm(result.F) <= GAIN_MAX
    # spectral abscissa negative over the whole sweep (0, 5 tau_n0]
    assert cert.taus.min() > 0.0
    assert cert.taus.max() == pytest.approx(5 * m.tau_n0, rel=1e-12)
    assert len(cert.taus) >= 20
    assert np.all(cert.abscissa < 0.0)
    # no closed-loop root in Re s >= 0 at tau_n0 and 5 tau_n0 (argument principle, no root finder)
    for tau in (m.tau_n0, 5 * m.tau_n0):
        assert rhp_zero_count(Abar, m.A1, tau, 0.0) == 0
    # chosen alpha is the best accepted one of the search
    best = min(a.abscissa for a in result.attempts if a.accepted)
    assert cert.abscissa_nominal == pytest.approx(best, abs=1e-9)


@pytest.mark.parametrize("A", [0.3, 0.6])
def test_synthesis_feasible_around_placeholder(A):
    m = averaged_model(REFERENCE, A, TAUBAR_CRIT_REF)
    res = synthesize(m, alphas=ALPHA_GRID[::2], refine=0, taus=np.linspace(0.1, 5, 6) * m.tau_n0)
    assert res.certificate.passed
    assert np.all(res.certificate.abscissa < 0.0)
    Abar = m.A0 + m.B @ res.F[None, :]
    assert rhp_zero_count(Abar, m.A1, m.tau_n0, 0.0) == 0


def test_b_zero_is_infeasible():
    m = averaged_model(REFERENCE, A_REF, TAUBAR_CRIT_REF)
    m0 = dataclasses.replace(m, B=np.zeros((4, 1)))
    with pytest.raises(SynthesisInfeasible) as info:
        synthesize(m0)
    msg = str(info.value)
    assert "no admissible gain" in msg
    assert f"alpha = {ALPHA_GRID[0]:.4g}" in msg and f"alpha = {ALPHA_GRID[-1]:.4g}" in msg
    assert len(info.value.attempts) == len(ALPHA_GRID)
    assert not any(a.accepted for a in info.value.attempts)


@pytest.mark.parametrize("A", [0.3, A_REF, 0.6])
def test_paper_gain_stabilises_averaged_model(A):
    taus = None if A == A_REF else [5 * REFERENCE.tau_n0]  # full sweep once
    ev = evaluate_gain(PAPER_F, REFERENCE, A, TAUBAR_CRIT_REF, taus=taus)
    m = ev.model
    Abar = m.A0 + m.B @ np.asarray(PAPER_F)[None, :]
    assert ev.abscissa_nominal < 0.0
    assert rhp_zero_count(Abar, m.A1, m.tau_n0, 0.0) == 0
    assert ev.certificate is not None
    P = ev.certificate.P
    M32 = block32(Abar, m.A1, P, ev.certificate.alpha)
    assert np.linalg.eigvalsh(0.5 * (M32 + M32.T))[-1] < 0.0
    assert np.linalg.eigvalsh(P)[0] > 0.0
    assert np.all(ev.abscissa < 0.0)
    if A == A_REF:
        assert len(ev.abscissa) >= 20


def test_open_loop_not_certified():
    """A gain that leaves the loop unstable gets no certificate and a positive abscissa."""
    ev = evaluate_gain([0.0, 0.0, 0.0, 0.0], REFERENCE, A_REF, TAUBAR_CRIT_REF, taus=[0.3])
    assert ev.abscissa_nominal > 0.0
    assert ev.certificate is None


def test_gains_file_round_trip_and_hash(result, tmp_path):
    path = tmp_path / "gains.json"
    g = to_gains_file(result, REFERENCE)
    assert write_gains(g, path) == path
    assert [p.name for p in tmp_path.iterdir()] == ["gains.json"]  # no temp file left
    back = read_gains(path)
    assert back.F == tuple(float(v) for v in result.F)
    assert back.params == REFERENCE
    assert back.K0 == result.model.K0 and back.R_ff == -result.model.K0
    assert back.alpha == result.alpha and back.A == A_REF
    assert back.taubar_crit == TAUBAR_CRIT_REF
    assert back.certificate["lmi32_max_eig"] < 0.0
    assert back == g
    data = json.loads(path.read_text())
    assert data["params_sha256"] == params_hash(REFERENCE)
    assert params_hash(REFERENCE.replace(psi=251.0)) != params_hash(REFERENCE)

    # a parameter edited without updating the hash is rejected
    bad = dict(data, params=dict(data["params"], psi=251.0))
    path.write_text(json.dumps(bad))
    with pytest.raises(GainsFileError, match="hash mismatch"):
        read_gains(path)
    # an edited K0 no longer matches (27) for the stored parameters
    bad = dict(data, K0=data["K0"] * 1.01, R_ff=-data["K0"] * 1.01)
    path.write_text(json.dumps(bad))
    with pytest.raises(GainsFileError, match="K0"):
        read_gains(path)
    # malformed gain, missing key, not JSON
    path.write_text(json.dumps(dict(data, F=[1.0, 2.0, 3.0])))
    with pytest.raises(GainsFileError, match="4 entries"):
        read_gains(path)
    path.write_text(json.dumps({k: v for k, v in data.items() if k != "alpha"}))
    with pytest.raises(GainsFileError, match="missing key"):
        read_gains(path)
    path.write_text("{not json")
    with pytest.raises(GainsFileError, match="not valid JSON"):
        read_gains(path)


def test_delay_roots_reject_bad_gain():
    m = averaged_model(REFERENCE, A_REF, TAUBAR_CRIT_REF)
    with pytest.raises(ValueError, match="F must be 4 finite"):
        delay_roots(m, [1.0, 2.0, float("nan"), 0.0])


def test_design_command_writes_certified_gains(tmp_path, capsys):
    out = tmp_path / "design"
    argv = ["--params", "reference", "--A", str(A_REF), "--out", str(out)]
    assert design_main([*argv, "--no-paper"]) == 0
    text = capsys.readouterr().out
    assert "certificate PASSED" in text and "Open loop" in text and "alpha" in text
    assert not (out / "axial_fit.csv").exists()  # A was given: no fit computed
    g = read_gains(out / "gains.json")
    assert g.taubar_crit == TAUBAR_CRIT_REF  # default from drillstring.analysis.axial_stability
    assert g.certificate["abscissa_sweep_max"] < 0.0


def test_design_command_rejects_bad_input(tmp_path, capsys):
    out = tmp_path / "design"
    assert design_main(["--A", "-0.2", "--out", str(out)]) == 2
    assert "drillstring design: --A must be > 0, got -0.2" in capsys.readouterr().err
    assert design_main(["--A", "0.3", "--taubar-crit", "nan", "--out", str(out)]) == 2
    assert "drillstring design: --taubar-crit must be finite, got nan" in capsys.readouterr().err
    assert not out.exists()
    # the option as typed (the constrained design calls it sigma), before anything is designed
    argv = ["--A", str(A_REF), "--torque-limit", "tds-11sa", "--out", str(out)]
    assert design_main([*argv, "--decay", "-1"]) == 2
    assert "drillstring design: --decay must be >= 0, got -1.0" in capsys.readouterr().err
    assert not out.exists()
    (tmp_path / "a_file").write_text("")
    assert design_main(["--A", str(A_REF), "--out", str(tmp_path / "a_file")]) == 2
    assert f"--out {str(tmp_path / 'a_file')!r} is a file" in capsys.readouterr().err
