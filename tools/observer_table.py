"""The table of ``docs/controllers.md``, "An observer for the string": today's one-mode surface
observer and the string observer (``controller/string_observer.py``) on the same runs.

Each run is the Fig. 6 open loop (R - R0 = R_ff, dphi/dtau(0) = -4.9, torsional stick) sampled
every Ts = 1e-3 to tau = 40, on the one-mode string or the reference rig's string of 16
elements; the observers read the table's angle and speed, the torque at the top of the string
and the motor torque, with the noise of ``SURFACE_NOISE_SI`` (seed 1) or none, and assume the
top drive's inertia exact or 20 % off. The errors are over tau in [20, 40].

    .venv/bin/python tools/observer_table.py
"""

from __future__ import annotations

import math

from drillstring.controller.averaged import averaged_model
from drillstring.controller.estimation import design_observer
from drillstring.controller.string_observer import (
    design_string_observer,
    estimation_errors,
    noisy_surface,
    one_mode_estimates,
    scaled_surface_noise,
)
from drillstring.model.engine import EngineOptions
from drillstring.model.laws import FeedForward
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.pipe import rig_string
from drillstring.model.sampled import simulate_sampled

#: The design's averaged model (A, taubar_crit of ``drillstring design``).
MODEL = averaged_model(REFERENCE, 0.385415, 2.392788)
TS = 1e-3
#: What the observers assume when the signals carry no noise: today's design's 1e-2.
QUIET = {"theta": 1e-2, "dtheta": 1e-2, "torque": 1e-2, "motor": 1e-2}


def fig6_run(elements: int) -> dict:
    """The rows (every sample) of the Fig. 6 open loop to tau = 40 on the string."""
    res = simulate_sampled(
        REFERENCE,
        FeedForward(R_ff=MODEL.R_ff),
        40.0,
        TS,
        initial={"dphi": -4.9},
        options=EngineOptions(torsional_stick=True),
        string=rig_string("reference-rig", elements),
        dt_out=TS,
    )
    assert res.status.ok, res.status
    return res.data


def rows() -> list[tuple[str, str, dict[str, float]]]:
    """(run, observer, errors) of every row of the table."""
    noise = scaled_surface_noise(REFERENCE_RIG.C, REFERENCE_RIG.t_star)
    out = []
    runs = {1: fig6_run(1), 16: fig6_run(16)}
    for elements, noisy, factor in (
        (1, False, 1.0),
        (16, False, 1.0),
        (16, True, 1.0),
        (16, True, 0.8),
        (16, True, 1.2),
    ):
        data = runs[elements]
        sig = noisy_surface(data, noise if noisy else None, seed=1)
        model = MODEL.with_rho(factor)
        label = (
            f"N = {elements}, {'noise' if noisy else 'no noise'}, "
            f"inertia {'exact' if factor == 1.0 else f'{factor - 1:+.0%}'}"
        )
        one = design_observer(model, TS)
        e1 = one_mode_estimates(one, sig["theta"], sig["dtheta"], sig["torque"], sig["r"])
        string = rig_string("reference-rig", 3 if elements > 1 else 1)  # N = 1: its own model
        obs = design_string_observer(model, string, TS, noise=noise if noisy else QUIET)
        e2 = obs.run(sig["theta"], sig["dtheta"], sig["torque"], sig["r"])
        out.append((label, "one-mode (today's)", estimation_errors(e1, data)))
        if noisy:  # today's observer told the noise it sees
            tuned = design_observer(
                model, TS, speed_noise=noise["dtheta"], torque_noise=noise["torque"]
            )
            e3 = one_mode_estimates(tuned, sig["theta"], sig["dtheta"], sig["torque"], sig["r"])
            out.append((label, "one-mode, told the noise", estimation_errors(e3, data)))
        name = "string (3-element chain)" if elements > 1 else "string (one-mode model)"
        out.append((label, name, estimation_errors(e2, data)))
    return out


def main() -> None:
    rpm = 30.0 / math.pi / REFERENCE_RIG.t_star  # scaled speed -> rpm
    omega0 = REFERENCE.omega0
    print("| run | observer | bit speed RMS [rpm] | (of omega0) | bit speed max [rpm] "
          "| bit angle RMS [deg] | twist RMS [deg] |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for label, name, e in rows():
        print(
            f"| {label} | {name} | {e['dphi_rms'] * rpm:.2f} | {e['dphi_rms'] / omega0:.1%} "
            f"| {e['dphi_max'] * rpm:.1f} | {math.degrees(e['phi_rms']):.1f} "
            f"| {math.degrees(e['twist_rms']):.1f} |"
        )


if __name__ == "__main__":
    main()
