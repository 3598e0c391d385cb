"""The command line's refusals of bad input that no other module's tests cover: ``drillstring
simulate`` (an ``--out`` that is a file, a step ``--h`` beyond the model's time scales). Each
exits with status 2 and a message naming the option and the value, before any work is done and
without writing anything."""

from __future__ import annotations

import math

import pytest

from drillstring.apps.simulate import simulate_main
from drillstring.model.params import REFERENCE


def test_reference_step_bound_is_a_tenth_of_the_axial_period():
    """For the reference set (n psi = 1000) the axial period 2 pi/sqrt(1000) = 0.1987 is the
    shortest time scale (tau_n0 = pi/10, the torsional period 2 pi); its runs use h = 5e-4."""
    assert REFERENCE.h_max == pytest.approx(2.0 * math.pi / math.sqrt(1000.0) / 10.0, rel=1e-15)
    assert REFERENCE.h_max < REFERENCE.tau_n0 / 10.0


def test_simulate_refuses_a_step_beyond_the_model_time_scales(tmp_path, capsys):
    out = tmp_path / "h"
    assert simulate_main(["--h", "10", "--tau-end", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--h must be in (0, {REFERENCE.h_max:g}], got 10.0" in err, err
    assert not out.exists()
    # the bound itself is a step of the model
    argv = ["--h", repr(REFERENCE.h_max), "--tau-end", "0.2", "--out", str(out)]
    assert simulate_main(argv) == 0, capsys.readouterr().err


def test_simulate_refuses_an_out_that_is_a_file(tmp_path, capsys):
    afile = tmp_path / "simulation.csv"
    afile.write_text("mine\n")
    assert simulate_main(["--tau-end", "0.2", "--out", str(afile)]) == 2
    assert f"--out {str(afile)!r} is a file, not a folder" in capsys.readouterr().err
    assert afile.read_text() == "mine\n"
