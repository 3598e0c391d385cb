"""Print the numbers of ``docs/controllers.md``, "Braking": the input-constrained design's Fig. 6
switch-on run under the TDS-11SA with the drive's braking limited.

Usage::

    .venv/bin/python tools/braking_runs.py --design out/design 50.84 39.71 9 5 0

For each braking limit [kN m] (0: a drive that cannot brake), the comparison's
``lmi-constrained`` row (``drillstring controllers compare``: the same lineup, the Fig. 6
set-up, sampled every 1e-3, run to tau = 100, the metrics of its table) with the TDS-11SA's
rating and its torque range's lower end at -limit: the run's status, the most negative torque the
drive applied (the braking used), the lowest table speed, the settling time and the fraction of
samples the drive limited. The gain is the design's ``gains_constrained.json`` (``drillstring
design --torque-limit tds-11sa``); every braking limit at which a design is certified gives the
same gain (the design's least peak does not depend on the budget), so one file serves.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

import numpy as np

from drillstring.apps.controllers import COMPARISON_TAU_END, COMPARISON_WINDOW, _row
from drillstring.controller.averaged import averaged_model
from drillstring.controller.design import CONSTRAINED_FILE, GAINS_FILE
from drillstring.controller.gains import read_gains
from drillstring.controller.lineup import lmi_gain, rig_lineup
from drillstring.model.engine import EngineOptions
from drillstring.model.experiments import FIG6
from drillstring.model.params import REFERENCE_RIG
from drillstring.model.sampled import DEFAULT_TS, simulate_sampled
from drillstring.model.topdrive import RPM, TDS_11SA, top_drive


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--design", type=Path, default=Path("out/design"))
    ap.add_argument("braking", type=float, nargs="+", help="braking limits [kN m]")
    args = ap.parse_args()
    g = read_gains(args.design / CONSTRAINED_FILE)
    paper = read_gains(args.design / GAINS_FILE)
    params, rig = g.params, REFERENCE_RIG
    model = averaged_model(params, g.A, g.taubar_crit)
    rating = top_drive(TDS_11SA, rig)
    options = EngineOptions(h=FIG6.h, torsional_stick=FIG6.torsional_stick)
    for knm in args.braking:
        drive = dataclasses.replace(
            rating,
            R_min=-knm * 1e3 / rig.C + 0.0,
            braking="four-quadrant" if knm > 0 else "none",
        )
        controller = rig_lineup(
            params, model, paper=lmi_gain(model, paper), constrained=lmi_gain(model, g),
            top_drive=drive, scales=rig, Ts=DEFAULT_TS, t_on=FIG6.t_on, latch=FIG6.latch,
            names=["lmi-constrained"],
        )["lmi-constrained"]  # fmt: skip
        r = simulate_sampled(
            params, controller, COMPARISON_TAU_END, DEFAULT_TS, initial=FIG6.initial(),
            options=options,
        )  # fmt: skip
        on = r.tau >= FIG6.t_on
        row = _row("lmi-constrained", "tds-11sa", r, COMPARISON_WINDOW, FIG6.t_on, rig)
        table = (params.omega0 + r.dtheta[on]) / rig.t_star / RPM
        stop = ""
        if not r.status.ok:
            after = (r.tau[-1] - FIG6.t_on) * rig.t_star
            stop = f" at tau {r.tau[-1]:.2f} ({after:.1f} s after the switch-on)"
        settle = row["settling_time_s"]
        print(
            f"braking limit {knm:g} kN m: {r.status.code}{stop}; braking used "
            f"{max(-float(np.min(r.R_min[on])), 0.0) * rig.C / 1e3 + 0.0:.2f} kN m; lowest table "
            f"speed {float(np.min(table)):.2f} rpm; settles in "
            f"{'-' if math.isnan(settle) else f'{settle:.2f} s'}; limited samples "
            f"{row['saturated_fraction']:.3g}"
        )


if __name__ == "__main__":
    main()
