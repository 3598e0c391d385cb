"""``drillstring design``: open-loop analysis, LMI synthesis (33), certificate, gains file.

The command line of :func:`drillstring.controller.design_controller`. Example::

    drillstring design --params reference --out out/design   # A from the axial analysis

prints the open-loop characteristic roots of (29) and the poles of the ODE (13), (27), the alpha
line search, the gain F (and the paper's gain for comparison), the certificate (32) with its
margins and the closed-loop spectral abscissa over the delay sweep, then writes
``out/design/gains.json`` and, when A is computed rather than given with ``--A``, the points of
the axial fit ``out/design/axial_fit.csv`` (the Fig. 4 line the slope A comes from).

With ``--string-elements K`` also the design that holds on the distributed string
(``gains_string.json``; with a drive, its Fig. 6 switch-on on the 16-element string is run).
With ``--torque-limit DRIVE`` also the input-constrained design (``gains_constrained.json``);
``--braking-limit KNM`` sets the drive's most negative torque (0: no braking). Exit 0: done;
1: no certified constrained design at the drive's limits (the message names the braking limit and
the least braking a certified design needs); 2: a bad argument or input.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from drillstring.controller.averaged import AveragedModel, delay_roots, ode_poles
from drillstring.controller.constrained import (
    BRAKING_TOL,
    DEFAULT_DECAY,
    ConstrainedInfeasible,
    recheck_constrained,
)
from drillstring.controller.design import (
    CONSTRAINED_FILE,
    STRING_FILE,
    Design,
    design_controller,
    design_on_string,
    write_design,
)
from drillstring.controller.gains import (
    DEFAULT_GAINS_PATH,
    PAPER_F,
    GainsFileError,
    read_gains,
    write_gains,
)
from drillstring.controller.string_design import recheck_string_design
from drillstring.controller.synthesis import GAIN_MAX, SynthesisInfeasible, SynthesisResult
from drillstring.model.params import (
    KNOWN_PHYSICAL,
    ParameterError,
    PhysicalParams,
    ScaledParams,
    params_from_spec,
)
from drillstring.model.topdrive import TopDrive, top_drive_from_spec
from drillstring.validation import check_int, check_out_folder, check_real

__all__ = ["BRAKING_TOL_KNM", "build_parser", "design_main", "print_design"]

DEFAULT_OUT = DEFAULT_GAINS_PATH.parent
#: Tolerance of the bisection on the braking limit after a refusal on a physical rig [kN m].
BRAKING_TOL_KNM = 0.01


def _braking_limit(text: str) -> float:
    """``--braking-limit``: a finite number >= 0 (kN m)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of kN m >= 0, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(
            f"expected a finite number of kN m >= 0 (0: a drive that cannot brake), got {text!r}"
        )
    return value


def build_parser(prog: str = "drillstring design") -> argparse.ArgumentParser:
    """Argument parser of the ``design`` subcommand.

    Parameters
    ----------
    prog : str
        Program name shown in the usage text.

    Returns
    -------
    argparse.ArgumentParser
        The parser.
    """
    ap = argparse.ArgumentParser(
        prog=prog,
        description="Torsional analysis and LMI state-feedback synthesis (paper Sections IV-V).",
    )
    ap.add_argument(
        "--params", default="reference", help="parameter set name or file (default: reference)"
    )
    ap.add_argument(
        "--A",
        type=float,
        default=None,
        dest="A",
        help="slope A(gammabar, etabar) of the averaged contact force (22) (default: computed "
        "from the axial limit cycles at the set's gammabar, etabar^2)",
    )
    ap.add_argument(
        "--taubar-crit",
        type=float,
        default=None,
        help="critical delay of (21) in fast time (default: the crossing formula)",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=DEFAULT_OUT,
        help=f"folder of gains.json and axial_fit.csv (default: {DEFAULT_OUT})",
    )
    ap.add_argument(
        "--gain-max",
        type=float,
        default=GAIN_MAX,
        help=f"bound on ||F||_2 of an admissible design (default: {GAIN_MAX:g})",
    )
    ap.add_argument(
        "--no-paper", action="store_true", help="skip the evaluation of the paper's gain"
    )
    ap.add_argument(
        "--torque-limit",
        default=None,
        metavar="DRIVE",
        help="also the input-constrained design for this top drive, written to "
        f"{CONSTRAINED_FILE}: a rating (tds-11sa: the reference rig's drive), a multiple of the "
        "nominal torque (50R0) or a torque in N m on the rig (52kNm)",
    )
    ap.add_argument(
        "--braking-limit",
        type=_braking_limit,
        default=None,
        metavar="KNM",
        help="with --torque-limit: the most negative torque the drive applies, in kN m on the "
        "rig (0: a drive that cannot brake; default the drive's own, -rating for tds-11sa); "
        "the range need not be symmetric about the operating torque. Exit 1 when no design is "
        "certified at that limit, naming the least braking a certified design needs",
    )
    ap.add_argument(
        "--decay",
        type=float,
        default=DEFAULT_DECAY,
        help="required decay rate of the constrained design (1/tau; default "
        f"{DEFAULT_DECAY:.4g}: a deviation halves in three torsional periods)",
    )
    ap.add_argument(
        "--string-elements",
        type=int,
        default=None,
        metavar="K",
        help=f"also the design that holds on the distributed string, certified on the K-element "
        f"chain (K >= 2; 3: table, two inner nodes, bit), written to {STRING_FILE}; with "
        "--torque-limit its Fig. 6 switch-on on the 16-element string under that drive is run "
        "and recorded (docs/controllers.md, 'A design that holds on the string')",
    )
    ap.add_argument(
        "--check",
        type=Path,
        default=None,
        metavar="FILE",
        help=f"only check the certificate of a constrained design again from its gains file "
        f"({CONSTRAINED_FILE}: the ellipsoid S and the switch-on states are in it), or of a "
        f"string design ({STRING_FILE}: its Lyapunov matrix on the reduced chain, the spectra "
        "on the strings); exit 0 if it passes, 1 if not",
    )
    return ap


def _fmt_c(z: complex) -> str:
    return f"{z.real:+.5f} {'+' if z.imag >= 0 else '-'} {abs(z.imag):.5f}j"


def _print_open_loop(model: AveragedModel) -> None:
    dde = delay_roots(model)
    ode = ode_poles(model)
    print("Open loop (R_fb = 0): rightmost roots")
    print(f"  {'delay system (29) at tau_n0':>32}   {'ODE (13),(27)':>26}")
    for i in range(max(len(dde), len(ode))):
        a = _fmt_c(dde[i]) if i < len(dde) else ""
        b = _fmt_c(ode[i]) if i < len(ode) else ""
        print(f"  {a:>32}   {b:>26}")
    n_dde = int(np.sum(dde.real > 1e-9))
    n_ode = int(np.sum(ode.real > 1e-9))
    print(
        f"  unstable: {n_dde} (delay system), {n_ode} (ODE); velocity weakening c = "
        f"{model.c:.5f} < 0; the root at 0 is the rigid-body angle phi"
    )


def _print_search(result: SynthesisResult) -> None:
    print("Alpha line search (LMI (33), min ||X||; decay = spectral abscissa at tau_n0)")
    print(f"  {'alpha':>10} {'solver':>9} {'status':>22} {'||F||':>11} {'abscissa':>10}  note")
    for att in sorted(result.attempts, key=lambda a: a.alpha):
        g = f"{att.gain_norm:.4g}" if att.gain_norm is not None else "-"
        s = f"{att.abscissa:.5f}" if att.abscissa is not None else "-"
        mark = " *" if att.alpha == result.alpha else ""
        print(
            f"  {att.alpha:10.4g} {att.solver:>9} {att.status[:22]:>22} {g:>11} {s:>10}  "
            f"{att.note}{mark}"
        )


def _print_certificate(result: SynthesisResult) -> None:
    cert = result.certificate
    print(f"Certificate (independent of the solver), alpha = {cert.alpha:.6g}, P = S^-1:")
    print(f"  largest eigenvalue of (32) with A0 + B F: {cert.lmi_max_eig:.4e} (must be < 0)")
    print(f"  decay margin -max eig(M, diag(P, P)):     {cert.lmi_decay_margin:.4e} (must be > 0)")
    print(f"  smallest eigenvalue of P:                 {cert.P_min_eig:.4e}")
    print(f"  closed-loop spectral abscissa at tau_n0:  {cert.abscissa_nominal:.5f}")
    print("  spectral abscissa over constant delays in (0, 5*tau_n0]:")
    for t, a in zip(cert.taus, cert.abscissa, strict=True):
        print(f"    tau = {t:8.5f}   {a:+.5f}")
    print(f"  certificate {'PASSED' if cert.passed else 'FAILED'}")


def print_design(design: Design) -> None:
    """Print the analysis, the alpha search, the gain, the certificate and the paper's gain.

    Parameters
    ----------
    design : Design
        A result of :func:`~drillstring.controller.design.design_controller`; the axial fit
        and the paper's gain are printed when it holds them.
    """
    params, model = design.params, design.model
    if design.axial is not None:
        a = design.axial
        print(
            f"Slope A of (22) from {len(a.curve)} axial limit cycles: A = {a.A:.6f} "
            f"(fit zero at taubar = {a.taubar_zero:.4f}, taubar_crit = {a.taubar_crit:.4f})"
        )
    print(f"Parameters: {params.to_dict()}")
    print(
        f"  tau_n0 = {model.tau_n0:.6f}, taubar_n0 = {params.taubar_n0:.5f}, A = {model.A:.6g}, "
        f"taubar_crit = {model.taubar_crit:.6f} (tau_n_crit = {model.tau_n_crit:.6f})"
    )
    print(f"  c = {model.c:.6f}, K0 = {model.K0:.6f}, R_ff = {model.R_ff:.6f}")
    _print_open_loop(model)
    result = design.synthesis
    _print_search(result)
    print(f"Chosen alpha = {result.alpha:.6g} ({result.solver}: {result.status})")
    print(
        f"  F = [{', '.join(f'{v:.4f}' for v in result.F)}]   ||F|| = "
        f"{np.linalg.norm(result.F):.4g}"
    )
    print(
        f"  paper F = [{', '.join(f'{v:.1f}' for v in PAPER_F)}]   ||F|| = "
        f"{np.linalg.norm(PAPER_F):.4g}"
    )
    _print_certificate(result)
    ev = design.paper
    if ev is not None:
        cert_txt = (
            f"yes (alpha = {ev.certificate.alpha:.4g}, decay margin "
            f"{ev.certificate.lmi_decay_margin:.3e})"
            if ev.certificate is not None
            else "none found on the alpha grid"
        )
        print("Paper's gain on this averaged model:")
        print(f"  rightmost roots at tau_n0: {', '.join(_fmt_c(z) for z in ev.roots_nominal[:4])}")
        print(
            f"  spectral abscissa: {ev.abscissa_nominal:.5f} at tau_n0, max over sweep "
            f"{float(np.max(ev.abscissa)):.5f}; Razumikhin certificate: {cert_txt}"
        )
    c = design.constrained
    if c is not None:
        r, cert = c.result, c.result.certificate
        td = c.top_drive
        R0 = params.R0
        print(f"Input-constrained design ({c.label or 'top drive'}: R in [{td.R_min:.4g}, "
              f"{td.R_max:.4g}] = [{td.R_min / R0:.3g}, {td.R_max / R0:.3g}] R0)")  # fmt: skip
        print(
            f"  {len(r.states)} switch-on states of {c.gains.constraint['experiment']}; feedback "
            f"budget u_max = {r.u_max:.4g}; decay {r.sigma:g}"
        )
        print(f"  alpha = {r.alpha:.4g}: F = [{', '.join(f'{v:.4f}' for v in r.F)}]   ||F|| = "
              f"{np.linalg.norm(r.F):.4g}")  # fmt: skip
        print(
            f"  certified peak feedback torque {r.peak_torque:.4g} = {r.peak_torque / R0:.3g} R0 "
            f"(<= u_max); largest x^T S^-1 x of the states {cert.state_max:.6f} (<= 1)"
        )
        print(
            f"  (32) shifted, largest eigenvalue {cert.lmi_max_eig:.3e} (< 0); spectral abscissa "
            f"{cert.abscissa_nominal:.5f} at tau_n0, max over the sweep "
            f"{float(np.max(cert.abscissa)):.5f}"
        )
        bias = params.R0 + model.R_ff
        print(
            f"  braking limit {-td.R_min:.4g} (R_min): margins about the operating torque "
            f"{bias:.4g}: {bias - td.R_min:.4g} below, {td.R_max - bias:.4g} above; the smaller "
            "binds (u_max)"
        )
        print(f"  certificate {'PASSED' if cert.passed else 'FAILED'}")


def _with_braking(drive: TopDrive, knm: float, rig: PhysicalParams | None, spec: str) -> TopDrive:
    """The drive with its torque range's lower end at -``knm`` kN m on ``rig``."""
    if rig is None:
        raise ValueError(
            f"--braking-limit {knm:g} (kN m) needs a physical rig: the parameter set is not one "
            "of the known rigs"
        )
    R_min = -knm * 1e3 / rig.C + 0.0  # no -0.0: a drive without braking has R_min = 0
    if not R_min < drive.R_max:
        raise ValueError(f"--braking-limit {knm:g}: the drive {spec!r} has no torque above it")
    return dataclasses.replace(drive, R_min=R_min, braking="four-quadrant" if knm > 0 else "none")


def _refused(exc: ConstrainedInfeasible, knm: float, rig: PhysicalParams | None, spec: str) -> str:
    """The refusal of the constrained design as the command line says it (kN m on a rig)."""
    if rig is None:
        return f"drillstring design: {exc}"
    kNm = rig.C / 1e3
    head = f"drillstring design: no certificate exists at the braking limit {knm:.4g} kN m "
    if exc.least_braking is None:
        return f"{head}(--torque-limit {spec}), nor at any other: {exc}"
    least = math.ceil(exc.least_braking * kNm * 100.0) / 100.0
    return (
        f"{head}(--torque-limit {spec}): the least braking a certified design needs is "
        f"{least:.2f} kN m (bisection on the braking limit with the LMI solve, tolerance "
        f"{BRAKING_TOL_KNM:g} kN m; rounded up: certified there); the least peak feedback torque "
        f"from the switch-on is {(exc.least_peak or math.nan) * kNm:.2f} kN m about the operating "
        f"torque\n  ({exc})"
    )


def _same(a: ScaledParams, b: ScaledParams) -> bool:
    """The scaled sets agree to 1e-9 (a rig's conversion rounds)."""
    return all(
        abs(x - y) <= 1e-9 * max(abs(x), abs(y), 1.0)
        for x, y in zip(a.to_dict().values(), b.to_dict().values(), strict=True)
    )


def design_main(argv: Sequence[str] | None = None) -> int:
    """Run the ``design`` subcommand; returns the process exit code (0 ok, 1 no certified
    constrained design at the drive's limits, 2 error).

    Designs the controller for ``--params``, prints the design (:func:`print_design`) and
    writes it into ``--out`` (:func:`~drillstring.controller.design.write_design`).
    """
    args = build_parser().parse_args(argv)
    if args.check is not None:
        return _check_main(args.check)
    try:
        check_out_folder("--out", args.out)
        # the options as typed, not the design's names for them (sigma, A of (22))
        check_real("--decay", args.decay, lower=0.0, strict=False)
        if args.A is not None:
            check_real("--A", args.A, lower=0.0)
        if args.taubar_crit is not None:
            check_real("--taubar-crit", args.taubar_crit, lower=0.0)
        if args.string_elements is not None:  # named as typed, before the long design runs
            check_int("--string-elements", args.string_elements, lower=2)
        params: ScaledParams = params_from_spec(args.params)
        drive = None
        rig = next((r for r in KNOWN_PHYSICAL.values() if _same(r.to_scaled(), params)), None)
        if args.torque_limit is not None:
            drive = top_drive_from_spec(args.torque_limit, params.R0, rig)
            if args.braking_limit is not None:
                drive = _with_braking(drive, args.braking_limit, rig, args.torque_limit)
        elif args.braking_limit is not None:
            raise ValueError("--braking-limit needs --torque-limit (the drive it limits)")
        tol = BRAKING_TOL if rig is None else BRAKING_TOL_KNM * 1e3 / rig.C
        if args.A is None:
            print("Computing the slope A of (22) from axial limit cycles ...", flush=True)
        design = design_controller(
            params,
            A=args.A,
            taubar_crit=args.taubar_crit,
            gain_max=args.gain_max,
            evaluate_paper=not args.no_paper,
            progress=args.A is None,
            top_drive=drive,
            top_drive_label=args.torque_limit or "",
            decay=args.decay,
            braking_tol=tol,
        )
    except ConstrainedInfeasible as exc:
        braking = math.nan if exc.braking_limit is None else exc.braking_limit
        knm = args.braking_limit if args.braking_limit is not None else braking
        if args.braking_limit is None and rig is not None:
            knm = braking * rig.C / 1e3
        print(_refused(exc, knm, rig, args.torque_limit), file=sys.stderr)
        return 1
    except (ParameterError, ValueError, OSError, SynthesisInfeasible) as exc:
        print(f"drillstring design: {exc}", file=sys.stderr)
        return 2
    print_design(design)
    on_string = None
    if args.string_elements is not None:
        try:
            on_string = design_on_string(
                params, design.model, elements=args.string_elements, top_drive=drive,
                label=args.torque_limit or "",
            )  # fmt: skip
        except ValueError as exc:
            print(f"drillstring design: {exc}", file=sys.stderr)
            return 2
        _print_string(on_string, params, rig)
    try:
        paths = write_design(design, args.out)
        if on_string is not None:
            if not on_string[0].certificate.passed:
                raise ValueError("the string design's certificate failed; no gains file written")
            paths["string"] = write_gains(on_string[1], args.out / STRING_FILE)
    except ValueError as exc:
        print(f"drillstring design: {exc}", file=sys.stderr)
        return 2
    for path in paths.values():
        print(f"Wrote {path}")
    return 0


def _print_string(on_string, params: ScaledParams, rig: PhysicalParams | None) -> None:
    """The string design: law, certificate on the reduced chain, spectra, Fig. 6 on N = 16."""
    design, _, fig6 = on_string
    cert = design.certificate
    print(
        f"String design (matched top, certified on the {design.elements}-element chain): "
        f"F = [{', '.join(f'{v:.4f}' for v in design.F)}], torque gain g = "
        f"{design.torque_gain:.4g} on the motor's string torque"
    )
    print(
        f"  Lyapunov decay {design.sigma:.5f} on the reduced chain (Taylor form (27)); largest "
        f"eigenvalue of the check {cert.lyapunov_max_eig:.3e} (< 0)"
    )
    for n, a in cert.abscissae.items():
        print(f"  spectral abscissa on N = {n} (delay form): {a:+.3e} (< 0)")
    if fig6 is not None:
        kNm = "" if rig is None else f" = {fig6['min_torque'] * rig.C / 1e3:.2f} kN m"
        print(
            f"  Fig. 6 switch-on on N = {fig6['elements']}: {fig6['outcome']} (severity "
            f"{fig6['severity']:.4f}), settling time {fig6['settling_time']:.3g} after the "
            f"switch-on, lowest table speed {fig6['min_table_speed'] / params.omega0:.3f} "
            f"omega0, lowest torque {fig6['min_torque']:.4g}{kNm} (below 0: braking)"
        )
    print(f"  certificate {'PASSED' if cert.passed else 'FAILED'}")


def _check_string(gains) -> int:
    """``--check`` of a string design's file."""
    cert = recheck_string_design(gains)
    for name, value in cert.margins().items():
        print(f"  {name}: {value:.6g}")
    if not cert.matches_record:
        print("  the recomputed abscissae are not the file's: the file was changed")
    print(f"  string design: certificate {'PASSED' if cert.passed else 'FAILED'}")
    return 0 if cert.passed else 1


def _check_main(path: Path) -> int:
    """``--check FILE``: the constrained or string certificate from the file alone; 0 passed, 1
    failed, 2 the file cannot be checked."""
    try:
        gains = read_gains(path)
        if gains.string_design is not None:
            return _check_string(gains)
        cert = recheck_constrained(gains)
    except GainsFileError as exc:
        print(f"drillstring design --check: {exc}", file=sys.stderr)
        return 2
    for name, value in cert.margins().items():
        print(f"  {name}: {value:.6g}")
    if cert.braking_limit is not None:
        print(f"  braking limit {cert.braking_limit:.6g} (units of C, -R_min)")
    print(
        f"  u_max {cert.u_max:.6g}, decay {cert.sigma:.6g}: certificate "
        f"{'PASSED' if cert.passed else 'FAILED'} (checked from {path})"
    )
    return 0 if cert.passed else 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(design_main())
