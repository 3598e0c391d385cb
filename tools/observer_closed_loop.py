"""The closed-loop rows of ``docs/controllers.md``, "An observer for the string": the
input-constrained LMI law (the design for the TDS-11SA) switched on in the Fig. 6 stick-slip on
the reference rig's string of 16 elements, under the TDS-11SA, with the bit's angle and speed
exact, from today's one-mode observer, or from the string observer; the observers read the
table's angle and speed, the torque at the top of the string and the motor torque with the noise
of ``SURFACE_NOISE_SI`` (seed 1) and assume the top drive's inertia 20 % high.

A Python loop on the engine (the compiled controller's observer slot holds the one-mode filter's
four states): at each sample the estimate, the law and the drive of the digital controller
(``Running``), the torque held to the next sample.

    .venv/bin/python tools/observer_closed_loop.py [--elements 16] [--tau-end 60]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from drillstring.controller.averaged import averaged_model
from drillstring.controller.estimation import design_observer
from drillstring.controller.string_observer import design_string_observer, scaled_surface_noise
from drillstring.model.control import AffineFeedback
from drillstring.model.digital.controller import DigitalController
from drillstring.model.engine import Engine, EngineOptions
from drillstring.model.experiments import FIG6
from drillstring.model.laws import SampledAffine
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.pipe import rig_string
from drillstring.model.topdrive import TDS_11SA, top_drive

MODEL = averaged_model(REFERENCE, 0.385415, 2.392788)
#: the input-constrained design for the TDS-11SA (tests/test_string_spectrum.py)
CONSTRAINED_F = (-100.62, -74.14, 57.69, -20.32)
TS = 1e-3


def run(
    elements: int, estimator: str, tau_end: float, factor: float = 1.2, scale: float = 1.0
) -> dict:
    """One closed-loop run: its status and the bit's speed late in it (``scale``: of the noise;
    ``factor``: the observers' top-drive inertia over the plant's)."""
    noise = scaled_surface_noise(REFERENCE_RIG.C, REFERENCE_RIG.t_star)
    noise = {key: scale * v for key, v in noise.items()}
    model = MODEL.with_rho(factor)
    law = SampledAffine(
        AffineFeedback(CONSTRAINED_F, MODEL.K0, MODEL.R_ff, FIG6.t_on, "angle"),
        on_saturation="freeze-angle",
    )
    controller = DigitalController(law, top_drive(TDS_11SA, REFERENCE_RIG)).start(REFERENCE)
    engine = Engine(
        REFERENCE,
        options=EngineOptions(torsional_stick=True),
        initial=FIG6.initial(),
        string=rig_string("reference-rig", elements),
    )
    rng = np.random.default_rng(1)
    pipe = rig_string("reference-rig", 1 if elements == 1 else 3)  # N = 1: its own model
    string_obs = design_string_observer(model, pipe, TS, noise=noise)
    one = design_observer(model, TS, speed_noise=noise["dtheta"], torque_noise=noise["torque"])
    z = None
    x = None
    n = round(tau_end / TS)
    speeds, errors, peak = [], [], 0.0
    status = None
    for k in range(n):
        tau = k * TS
        o = engine.outputs()
        theta = o["theta"] + noise["theta"] * rng.standard_normal()
        dtheta = o["dtheta"] + noise["dtheta"] * rng.standard_normal()
        torque = o["top_torque_minus_R0"] + noise["torque"] * rng.standard_normal()
        if estimator == "exact":
            phi, dphi, theta, dtheta = o["phi"], o["dphi"], o["theta"], o["dtheta"]
        elif estimator == "string":
            z = string_obs.correct(z, theta, dtheta, torque)
            phi, dphi = string_obs.bit(z)
        else:  # today's one-mode filter, as sense.py runs it
            x3 = -torque - one.K0
            if x is None:
                x = np.array([theta - torque, dtheta, x3, dtheta])
            else:
                x = x + one.M @ (np.array([dtheta, x3]) - x[[3, 2]])
            phi, dphi = float(x[0]), float(x[1])
        r = controller.step(tau, phi, dphi, theta, dtheta, TS)
        peak = max(peak, abs(r - MODEL.R_ff))
        motor = r + noise["motor"] * rng.standard_normal()  # the measured motor torque
        if estimator == "string":
            z = string_obs.predict(z, motor)
        elif estimator == "one-mode":
            x = one.Ad @ x + one.Bd * (motor + one.K0)
        engine.set_input(r)
        status = engine.advance(tau + TS)
        if tau >= tau_end - 20.0:
            speeds.append(o["dphi"])
            errors.append(dphi - o["dphi"])
        if not status.ok:
            break
    s = np.array(speeds) if speeds else np.array([np.nan])
    e = np.array(errors) if errors else np.array([np.nan])
    return {
        "status": status.code,
        "tau": engine.tau,
        "ptp": float(np.ptp(s)),
        "min": float(np.min(s)),
        "err": float(np.sqrt(np.mean(e * e))),
        "peak": peak,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--elements", type=int, default=16)
    parser.add_argument("--tau-end", type=float, default=60.0)
    parser.add_argument("--noise", type=float, default=1.0, help="scale of the noise")
    parser.add_argument("--inertia", type=float, default=1.2, help="observers' rho/true rho")
    args = parser.parse_args()
    rpm = 30.0 / math.pi / REFERENCE_RIG.t_star
    kNm = REFERENCE_RIG.C / 1e3  # noqa: N806
    print(f"noise x{args.noise:g}, the observers' top-drive inertia x{args.inertia:g}")
    print("| N | bit angle and speed | outcome | ends at tau | late bit speed swing [rpm] "
          "| late bit speed error RMS [rpm] | peak feedback torque [kN m] |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for est in ("exact", "one-mode", "string"):
        r = run(args.elements, est, args.tau_end, args.inertia, args.noise)
        late = "-" if math.isnan(r["ptp"]) else f"{r['ptp'] * rpm:.1f} | {r['err'] * rpm:.2f}"
        if late == "-":
            late = "- | -"
        print(f"| {args.elements} | {est} | {r['status']} | {r['tau']:.2f} | {late} "
              f"| {r['peak'] * kNm:.1f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
