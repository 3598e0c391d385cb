"""Write the references of ``tests/test_limits_off.py`` from an older checkout of the project.

Usage (``tests/data/README.md``)::

    git worktree add --detach /tmp/old 0eb9d33
    NUMBA_CACHE_DIR=/tmp/nb_old .venv/bin/python tools/make_limits_off_refs.py \
        /tmp/old tests/data/limits_off_0eb9d33.json

The checkout given is imported instead of the installed package (the editable finder is
removed from ``sys.meta_path`` before any project import), with that checkout's own API: at
0eb9d33 ``simulate_sampled`` takes a law, there is no top drive and no digital controller. Each
run is the Fig. 6 set-up on the reference set (dphi/dtau(0) = -4.9, torsional stick on, the law
on at tau = 25, sampled every 1e-3, output every 0.01, tau in [0, 40]), and the paper's law
also evaluated continuously (the monolithic path of Figs. 5-6). The inputs are written into the
file with the results (the test reads them there). Per run: status, rows, the events (their
count and the SHA-256 of their times and modes), the SHA-256 of each column's float64 bytes
and the values at a few rows.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

if __name__ != "__main__" or len(sys.argv) != 3:
    raise SystemExit("usage: python tools/make_limits_off_refs.py CHECKOUT OUT.json")
ROOT = Path(sys.argv[1]).resolve()
sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in repr(f)]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import drillstring  # noqa: E402
from drillstring.model import laws as L  # noqa: E402
from drillstring.model.control import AffineFeedback  # noqa: E402
from drillstring.model.engine import EngineOptions  # noqa: E402
from drillstring.model.params import REFERENCE  # noqa: E402
from drillstring.model.sampled import simulate_sampled  # noqa: E402
from drillstring.model.simulate import simulate  # noqa: E402

if not Path(drillstring.__file__).resolve().is_relative_to(ROOT):
    raise SystemExit(f"imported {drillstring.__file__}, not the checkout {ROOT}")

#: The runs' inputs: the design's K0 at the reference set and the paper's published gain
#: (numbers, not computed, so that both versions get the same ones); stiff PI and SoftSpeed of
#: the reference set (rho = 5), Z-Torque with full matching, the paper's law, angle latched.
INPUTS = {
    "K0": 0.18383708216912742,
    "F": [-3448.5, -1574.7, 481.8, -89.0],
    "t_on": 25.0,
    "tau_end": 40.0,
    "Ts": 1e-3,
    "dt_out": 0.01,
    "dphi0": -4.9,
    "laws": {
        "stiff-pi": ["SpeedPI", {"kp": 100.0, "ki": 500.0}],
        "soft-speed": ["SpeedPI", {"kp": 4.47213595499958, "ki": 5.0}],
        "z-torque": [
            "ZTorque",
            {"kp": 100.0, "ki": 500.0, "z_gain": 1.0, "omega_hp": 0.3, "omega_lp": 10.0},
        ],
    },
    "columns": ["tau", "phi", "dphi", "theta", "dtheta", "u", "du", "R_minus_R0", "mode"],
    "sample_rows": [0, 1000, 2500, 2600, 4000],
}


def record(result) -> dict:
    """What is stored of one run."""
    out = {"status": result.status.code, "rows": len(result.tau), "events": len(result.events)}
    columns = {
        c: np.ascontiguousarray(np.asarray(getattr(result, c), dtype=np.float64))
        for c in INPUTS["columns"]
    }
    out["sha256"] = {c: hashlib.sha256(a.tobytes()).hexdigest() for c, a in columns.items()}
    out["samples"] = {c: [float(a[i]) for i in INPUTS["sample_rows"]] for c, a in columns.items()}
    # the located events: their times and modes (from, to by index of the names)
    names = sorted({e.from_mode for e in result.events} | {e.to_mode for e in result.events})
    ev = np.array(
        [[e.tau, names.index(e.from_mode), names.index(e.to_mode)] for e in result.events],
        dtype=np.float64,
    )
    out["events_sha256"] = hashlib.sha256(np.ascontiguousarray(ev).tobytes()).hexdigest()
    return out


K0, t_on = INPUTS["K0"], INPUTS["t_on"]
feedback = AffineFeedback(tuple(INPUTS["F"]), K0, -K0, t_on, "angle")
laws = {
    name: getattr(L, kind)(**values, R_ff=-K0, t_on=t_on)
    for name, (kind, values) in INPUTS["laws"].items()
}
laws["lmi"] = L.SampledAffine(feedback)
start = {
    "initial": {"dphi": INPUTS["dphi0"]},
    "options": EngineOptions(torsional_stick=True),
    "dt_out": INPUTS["dt_out"],
}
runs = {
    name: record(simulate_sampled(REFERENCE, law, INPUTS["tau_end"], INPUTS["Ts"], **start))
    for name, law in laws.items()
}
runs["lmi-continuous"] = record(
    simulate(REFERENCE, INPUTS["tau_end"], control=feedback, progress=False, **start)
)
commit = subprocess.run(
    ["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True, check=True
).stdout.strip()
doc = {
    "_comment": (
        "References of tests/test_limits_off.py, written by tools/make_limits_off_refs.py from "
        f"commit {commit} (tests/data/README.md)"
    ),
    "commit": commit,
    "python": sys.version.split()[0],
    "numpy": np.__version__,
    "inputs": INPUTS,
    "runs": runs,
}
Path(sys.argv[2]).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
