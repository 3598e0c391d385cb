"""Fig. 6 on the one-mode model and on the distributed string, side by side, in SI units.

The same rig, the same initial state, the same law and the same switch-on; only the string
differs: the paper's one-mode model (a massless spring, ``docs/model.md``, (11)-(13)) against
the pipe as N lumped elements (``docs/model.md``, "The distributed string"). What the figure
assumes is in its title: the law acts continuously on exact downhole measurements with no drive
limits, as the paper's Fig. 6 does (``docs/controllers.md`` shows the laws under a real drive).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from drillstring.fileio import save_figure, write_csv
from drillstring.model.control import AffineFeedback
from drillstring.model.engine import EngineOptions
from drillstring.model.experiments import FIG6
from drillstring.model.params import REFERENCE_RIG
from drillstring.model.pipe import StringParams
from drillstring.model.simulate import simulate
from drillstring.plotting import new_figure

__all__ = ["write_string_fig6"]

#: The elements of "the converged string": its second torsional mode within 0.4 % of the
#: continuous string's on the reference rig (``docs/analysis.md``, "Modes of the string").
CONVERGED_ELEMENTS = 16


def write_string_fig6(
    out_dir: str | Path,
    law: AffineFeedback,
    elements: int = CONVERGED_ELEMENTS,
) -> dict[str, Any]:
    """Write ``fig6_string.png`` and ``fig6_string.csv`` (SI) and return what they show: Fig. 6's
    run on the reference rig on the one-mode model and on the reference rig's pipe (kappa =
    1.870) in ``elements`` elements.

    Parameters
    ----------
    out_dir : path
        Folder to write into.
    law : AffineFeedback
        The law (the design's gains); its switch-on time and latch are Fig. 6's.
    elements : int
        N of the distributed string (default :data:`CONVERGED_ELEMENTS`).

    Returns
    -------
    dict
        ``png``, ``csv`` and per model the run's status, its torsional stick entries before
        and after the switch-on, the lowest bit speed after it [rpm], the peak top-of-string
        torque after it [kN m] and the late bit speed's spread (max - min over the last
        quarter) [rpm].
    """
    out = Path(out_dir)
    rig, string = REFERENCE_RIG, StringParams(elements=elements)
    control = AffineFeedback(law.F, law.K0, law.R_ff, t_on=FIG6.t_on, latch=FIG6.latch)
    options = EngineOptions(h=FIG6.h, torsional_stick=FIG6.torsional_stick)
    runs = {
        name: simulate(
            rig.to_scaled(),
            FIG6.tau_end,
            control=control,
            initial=FIG6.initial(),
            options=options,
            string=s,
            progress=False,
        )
        for name, s in (("one_mode", None), ("string", string))
    }
    ts, C = rig.t_star, rig.C
    rpm = 60.0 / (2.0 * math.pi) / ts  # scaled speed -> rpm
    t_on = FIG6.t_on
    info: dict[str, Any] = {"elements": string.elements, "kappa": string.kappa}
    cols: dict[str, np.ndarray] = {}
    fig = new_figure(figsize=(8.0, 6.0))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    for name, label in (
        ("one_mode", "one-mode model (the paper's)"),
        ("string", f"distributed string, N = {string.elements}"),
    ):
        r = runs[name]
        t = r.tau * ts
        speed = (rig.Omega0 * ts + r.dphi) * rpm
        top = C * (r.params.R0 + r.top_torque_minus_R0) / 1e3
        ax1.plot(t, speed, lw=0.8, label=f"{label}: {r.status.code}")
        ax2.plot(t, top, lw=0.8, label=label)
        after = r.tau >= t_on
        late = r.tau >= r.tau[-1] - 0.25 * FIG6.tau_end
        stick = [e.tau for e in r.events if e.kind == "mode" and e.to_mode == "torsional_stick"]
        info[name] = {
            "status": r.status.code,
            "torsional_stick_before_t_on": sum(1 for x in stick if x < t_on),
            "torsional_stick_after_t_on": sum(1 for x in stick if x >= t_on),
            "min_bit_speed_after_t_on_rpm": float(speed[after].min()),
            "max_top_torque_after_t_on_kNm": float(top[after].max()),
            "late_bit_speed_spread_rpm": float(np.ptp(speed[late])),
        }
        cols[f"bit_speed_rpm_{name}"] = speed
        cols[f"top_torque_kNm_{name}"] = top
        cols.setdefault("time_s", t)
    for ax in (ax1, ax2):
        ax.axvline(t_on * ts, color="0.5", ls="--", lw=0.8)
    ax1.set_ylabel("bit speed [rpm]")
    ax2.set_ylabel("torque at the top of the string [kN m]")
    ax2.set_xlabel("time [s]")
    ax1.legend(fontsize=7, loc="upper right")
    fig.suptitle(
        f"Fig. 6 switch-on at {t_on * ts:.1f} s on the reference rig (kappa = {string.kappa:.3f}):"
        "\nthe LMI law acting continuously on exact downhole measurements, no drive limits",
        fontsize=9,
    )
    png = save_figure(fig, out / "fig6_string.png")
    n = min(len(c) for c in cols.values())
    header = ["time_s", *(k for k in cols if k != "time_s")]
    csv = write_csv(
        out / "fig6_string.csv", header, zip(*(cols[k][:n].tolist() for k in header), strict=True)
    )
    info.update(png=png, csv=csv)
    return info
