"""The demo's chain of artifacts: the design's axial fit is Fig. 4's line, computed once."""

from __future__ import annotations

import csv

import drillstring.analysis.figures as figures
from drillstring.analysis.figures import read_average_points, write_average_figure
from drillstring.controller import design_controller, read_gains, write_design
from drillstring.model.params import REFERENCE


def test_fig4_reuses_the_design_fit_and_shows_its_slope(tmp_path, monkeypatch):
    design = design_controller(REFERENCE, evaluate_paper=False)
    paths = write_design(design, tmp_path / "design")
    gains = read_gains(paths["gains"])
    fit = read_average_points(paths["fit"])
    assert len(fit) == len(design.axial.curve) == 25

    computed = []
    real = figures.find_limit_cycle
    monkeypatch.setattr(
        figures, "find_limit_cycle", lambda *a, **k: computed.append(a) or real(*a, **k)
    )
    out = write_average_figure(
        tmp_path / "fig4", gammabars=(REFERENCE.gammabar,), known=fit, progress=False
    )
    assert computed == []  # every point of the line came from the design
    with open(out["fits"], newline="") as fh:
        (row,) = list(csv.DictReader(fh))
    assert float(row["A"]) == gains.A == design.axial.A  # the very slope of the design
