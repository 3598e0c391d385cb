"""Print the numbers of ``docs/reference_rig.md``, "The pipe rig", for both named rigs.

Usage::

    .venv/bin/python tools/rig_numbers.py            # everything (the limit cycles take minutes)
    .venv/bin/python tools/rig_numbers.py --quick    # without the limit cycles and the slope A

Each number comes from the project's own functions: the rig and its pipe
(:mod:`drillstring.model.params`, :mod:`drillstring.model.pipe`,
:class:`drillstring.controller.tuning.Pipe`), the scaled set and its fast-time quantities
(:class:`~drillstring.model.params.ScaledParams`), the axial equilibrium's characteristic
equation (21) (:mod:`drillstring.analysis.axial_stability`), the axial limit cycles and the
slope A of (22) (:mod:`drillstring.analysis.limit_cycles`, the budget of the search given with
``--max-periods``), and the averaged model (29)-(31) (:mod:`drillstring.controller.averaged`).
The LMI design (33) is ``drillstring design --params NAME --A A`` with the A printed here.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from drillstring.analysis.axial_stability import (
    axial_spectral_abscissa,
    crossing_frequencies,
    taubar_crit,
    unstable_root_count,
)
from drillstring.analysis.limit_cycles import design_inputs, fast_params, limit_cycle
from drillstring.controller.averaged import averaged_model
from drillstring.controller.tuning import rig_pipe
from drillstring.model.engine import OUTPUT_COLUMNS, Engine, EngineOptions
from drillstring.model.params import (
    REFERENCE_PIPE_EA_L,
    REFERENCE_PIPE_LENGTH,
    REFERENCE_PIPE_MASS,
    get_params,
    get_physical,
)
from drillstring.model.pipe import rig_string

RIGS = ("reference-rig", "pipe-rig")


def _rig(name: str) -> None:
    rig, s, pipe = get_physical(name), get_params(name), rig_string(name)
    print(f"== {name}")
    print(f"  M = {rig.M:.6g} kg, K = {rig.K:.6g} N/m, D = {rig.D:.6g} N s/m")
    print(f"  axial damping ratio D/(2 sqrt(K M)) = gamma/(2 eta) = {s.gamma / (2 * s.eta):.4g}")
    print(
        f"  t* = {rig.t_star:.6g} s, L* = {rig.L_star:.6g} m, W0 = {rig.W0:.6g} N, "
        f"T0 = {rig.T0:.6g} N m"
    )
    print(
        f"  scaled: psi = {s.psi:.6g}, gamma = {s.gamma:.6g}, eta = {s.eta:.6g}, "
        f"etabar^2 = {s.etabar2:.6g}, gammabar = {s.gammabar:.6g}"
    )
    print(
        f"  separation: sqrt(n psi) = {s.sqrt_npsi:.6g}, eta = {s.eta:.6g} "
        f"(axial frequency sqrt(K/M)/(2 pi) = {math.sqrt(rig.K / rig.M) / (2 * math.pi):.4g} Hz, "
        f"torsional sqrt(C/I1)/(2 pi) = {1 / (2 * math.pi * rig.t_star):.4g} Hz)"
    )
    ts = rig.t_star
    print(
        f"  string: kappa = {pipe.kappa:.6g}, axial mass ratio = {pipe.axial_mass_ratio:.6g}; "
        f"torsional travel time sqrt(kappa) = {pipe.travel_time:.6g} t* = "
        f"{pipe.travel_time * ts:.6g} s, impedance sqrt(kappa) = {pipe.impedance:.6g} C t* = "
        f"{pipe.impedance * rig.C * ts:.6g} N m s/rad (pipe J sqrt(G rho): "
        f"{rig_pipe(rig).impedance:.6g})"
    )
    if pipe.axial_mass_ratio > 0.0:
        mu = pipe.axial_mass_ratio
        print(
            f"  axial: travel time sqrt(mu)/eta = {math.sqrt(mu) / s.eta * ts:.6g} s, "
            f"impedance sqrt(mu) eta M/t* = {math.sqrt(mu) * s.eta * rig.M / ts:.6g} N s/m, "
            f"bit end keeps 1 - mu/3 = {1 - mu / 3:.6g} of M"
        )
    tc = taubar_crit(s)
    print(
        f"  (21): crossings (w, direction) = "
        f"{[(round(w, 6), d) for w, d in crossing_frequencies(s.gammabar, s.etabar2)]}"
    )
    print(
        f"  (21): taubar_crit = {tc:.6g}, taubar_n0 = {s.taubar_n0:.6g}, roots in the right "
        f"half plane at taubar_n0: {int(unstable_root_count(s.gammabar, s.etabar2, s.taubar_n0))}, "
        f"spectral abscissa {axial_spectral_abscissa(s.gammabar, s.etabar2, s.taubar_n0):.4g} "
        f"-> equilibrium {'UNSTABLE' if tc < s.taubar_n0 else 'stable'}"
    )
    # the weight's settling through the axial spring: tau_n0/etabar^2 in fast time
    settle = s.taubar_n0 / s.etabar2
    print(
        f"  weight transfer time taubar_n0/etabar^2 = {settle:.4g} fast = "
        f"{settle / s.sqrt_npsi:.4g} t* = {settle / s.sqrt_npsi * ts:.4g} s "
        f"({settle / s.sqrt_npsi / (2 * math.pi):.3g} torsional periods)"
    )


def _averaging(name: str, max_periods: int) -> None:
    s = get_params(name)
    lov = s.lam / s.vbar0
    print(f"== {name}: axial limit cycles of (18) (lambda/vbar0 = {lov:.4g})")
    for budget in (400, max_periods):
        lc = limit_cycle(
            s.gammabar, s.etabar2, s.taubar_n0, lam_over_vbar0=lov, max_periods=budget, n_samples=0
        )
        print(
            f"  at taubar_n0, max_periods = {budget}: {lc.kind}, period {lc.period:.5g} fast "
            f"= {lc.period / s.sqrt_npsi:.4g} slow "
            f"({2 * math.pi * s.sqrt_npsi / lc.period:.3g} per torsional period 2 pi), "
            f"(lambda/vbar0)<gbar> = {lc.average:.5g}, "
            f"stick fraction {lc.stick_fraction:.3g}, found after {lc.time_simulated:.5g} fast"
        )
    for budget in (400, max_periods):
        try:
            d = design_inputs(s, max_periods=budget)
        except ValueError as exc:
            print(f"  slope A, max_periods = {budget}: {exc}")
            continue
        kinds = [lc.kind for lc in d.curve]
        print(
            f"  slope A, max_periods = {budget}: A = {d.A!r}, taubar_zero = {d.taubar_zero:.5g}, "
            f"rms residual {d.fit.residual_rms:.3g}, "
            f"{kinds.count('periodic')}/{len(kinds)} periodic "
            f"(delays {d.fit.taubar[0]:.4g} .. {d.fit.taubar[-1]:.4g})"
        )
        try:
            m = averaged_model(s, d.A, d.taubar_crit)
        except ValueError as exc:
            print(f"  averaged model: {exc}")
            continue
        print(
            f"  averaged model: taubar_crit = {m.taubar_crit:.6g}, tau_n_crit = "
            f"{m.tau_n_crit:.6g}, tau_n0 = {m.tau_n0:.6g}, c = {m.c:.6g}, K0 = {m.K0:.6g}"
        )


def _settling(name: str, window: float = 400.0, end: float = 4000.0) -> None:
    """The mean of ubar over windows of (18) at taubar_n0 from the kick of the limit-cycle search:
    how fast the axial motion reaches its limit cycle."""
    s = get_params(name)
    p = fast_params(s.gammabar, s.etabar2, s.taubar_n0, s.lam / s.vbar0)
    eng = Engine(p, EngineOptions(h=0.02, freeze_torsion=True), initial={"u": 0.05})
    ts = np.arange(1, int(end / 0.1) + 1) * 0.1
    rows, _ = eng.sample(ts)
    u, g = rows[:, OUTPUT_COLUMNS.index("u")], rows[:, OUTPUT_COLUMNS.index("g")]
    per = int(window / 0.1)
    means = [f"{u[i : i + per].mean():.4g}" for i in range(0, ts.size, per)]
    gs = [f"{g[i : i + per].mean():.4g}" for i in range(0, ts.size, per)]
    print(f"== {name}: (18) at taubar_n0 from ubar(0) = 0.05, windows of {window:g} fast")
    print(f"  mean ubar: {', '.join(means)}")
    print(f"  mean gbar: {', '.join(gs)}")
    # the e-folding time of the mean: windows of 100 fast after the first (the growth from the
    # kick), while the distance from the last window's mean is above 1 % of the second window's
    fine = int(100.0 / 0.1)
    m = np.array([u[i : i + fine].mean() for i in range(0, ts.size, fine)])
    dist = np.abs(m - m[-1])
    k = 1
    while k + 1 < m.size and dist[k + 1] > 1e-2 * dist[1]:
        k += 1
    rate = -np.polyfit(np.arange(k) * 100.0, np.log(dist[1 : k + 1]), 1)[0]
    print(
        f"  e-folding time of the mean of ubar: {1 / rate:.4g} fast = "
        f"{1 / rate / s.sqrt_npsi:.4g} t* = {1 / rate / s.sqrt_npsi / (2 * math.pi):.3g} "
        f"torsional periods (log-linear fit over {k} windows of 100 fast, from 100 fast on)"
    )


def _same_damping_ratio(max_periods: int) -> None:
    """The alternative choice of D: the reference rig's damping ratio gamma/(2 eta) kept."""
    ref, s = get_params("reference-rig"), get_params("pipe-rig")
    zeta = ref.gamma / (2 * ref.eta)
    alt = s.replace(gamma=2 * zeta * s.eta)
    rig = get_physical("pipe-rig")
    print(f"== pipe-rig with the damping ratio {zeta:.4g} of reference-rig instead of its D")
    D = alt.gamma * rig.M / rig.t_star
    print(
        f"  D = {D:.6g} N s/m ({D / rig.D - 1:+.1%}), gamma = {alt.gamma:.6g}, "
        f"gammabar = {alt.gammabar:.6g}, taubar_crit = {taubar_crit(alt):.6g}, roots in the "
        f"right half plane at taubar_n0: "
        f"{int(unstable_root_count(alt.gammabar, alt.etabar2, alt.taubar_n0))}"
    )
    d = design_inputs(alt, max_periods=max_periods)
    m = averaged_model(alt, d.A, d.taubar_crit)
    print(f"  A = {d.A:.6g} (max_periods = {max_periods}), K0 = {m.K0:.6g}, c = {m.c:.6g}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the limit cycles and A")
    ap.add_argument(
        "--max-periods",
        type=int,
        default=4000,
        help="budget of the limit-cycle search besides its default 400 (default 4000)",
    )
    args = ap.parse_args()
    print(
        f"pipe: length G J/C = {REFERENCE_PIPE_LENGTH:.6g} m, mass {REFERENCE_PIPE_MASS:.6g} kg, "
        f"E A/L = {REFERENCE_PIPE_EA_L:.6g} N/m"
    )
    for name in RIGS:
        _rig(name)
    if not args.quick:
        for name in RIGS:
            _averaging(name, args.max_periods)
        for name in RIGS:
            _settling(name)
        _same_damping_ratio(args.max_periods)


if __name__ == "__main__":
    main()
