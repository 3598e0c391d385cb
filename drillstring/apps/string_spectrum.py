"""``drillstring string-spectrum``: every law's linearised closed loop on the N-element string.

Examples::

    drillstring string-spectrum --gains out/design/gains.json --elements 32 --out out/string
    drillstring string-spectrum --elements 1,2,4,8,16,32,64,128 --torque top --out out/string-top

For every law of the lineup (the open loop, stiff PI, SoftSpeed, Z-Torque with the industrial
tuning choices, the paper's LMI law of ``--gains`` and the input-constrained law of
``--constrained``) and every N of ``--elements``, the spectral abscissa of the loop linearised
about the gains' operating point on the chain of N elements
(:func:`drillstring.controller.string_spectrum.string_abscissa`; N = 1 is the paper's lumping,
the one-mode model, N >= 2 the lumped chain), and the frequency of the rightmost root and of every
unstable root. Writes ``string_spectrum.csv`` and ``string_spectrum.json`` into ``--out`` and
prints the table; ``docs/controllers.md``, "On the distributed string", reads it. Exit 0, or 2
with one line naming a bad value.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from drillstring.apps.usage import OneLineParser, UsageError
from drillstring.controller.averaged import AveragedModel, averaged_model
from drillstring.controller.design import CONSTRAINED_FILE
from drillstring.controller.gains import DEFAULT_GAINS_PATH, GainsFile, GainsFileError, read_gains
from drillstring.controller.lineup import INDUSTRIAL, Tuning, industrial_lineup
from drillstring.controller.reflection import MODE_TABLE, reflection_at_modes
from drillstring.controller.string_spectrum import (
    BIT_FORMS,
    TORQUE_SIGNALS,
    string_roots,
)
from drillstring.controller.tuning import SOFT_SPEED_RULES, STRING_IMPEDANCES
from drillstring.fileio import write_csv, write_json
from drillstring.model.control import AffineFeedback
from drillstring.model.laws import Law, SampledAffine
from drillstring.model.params import ParameterError, known_rig, params_from_spec
from drillstring.model.pipe import MAX_ELEMENTS, REFERENCE_KAPPA, StringParams

__all__ = [
    "COLUMNS",
    "DEFAULT_ELEMENTS",
    "reflection_table",
    "spectrum_table",
    "string_spectrum_main",
]

#: The default ``--elements``: 1 (the paper's one-mode model), 2, 4, ..., 32.
DEFAULT_ELEMENTS = (1, 2, 4, 8, 16, 32)
#: The CSV's columns, each with its unit.
COLUMNS = (
    "law",
    "elements",
    "lumping",
    "abscissa_scaled_per_tau",
    "abscissa_per_s",
    "frequency_scaled_rad_per_tau",
    "frequency_hz",
    "unstable_roots",
    "unstable_frequencies_hz",
)
#: How many rightmost roots are kept per loop (all with Re s > 0 when the loop is unstable).
N_ROOTS = 4000


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of the ``string-spectrum`` subcommand (errors raise, not exit)."""
    ap = OneLineParser(
        prog="drillstring string-spectrum",
        description="The spectral abscissa of every law's linearised closed loop on the "
        "N-element string, against N.",
    )
    ap.add_argument(
        "--gains",
        type=Path,
        default=DEFAULT_GAINS_PATH,
        help=f"gains file of the paper's LMI design (default {DEFAULT_GAINS_PATH}); its "
        "parameter set, A and taubar_crit are the operating point",
    )
    ap.add_argument(
        "--constrained",
        type=Path,
        default=None,
        help=f"gains file of the input-constrained design (default: {CONSTRAINED_FILE} beside "
        "--gains, when it is there)",
    )
    ap.add_argument(
        "--elements",
        default=",".join(str(n) for n in DEFAULT_ELEMENTS),
        help="the numbers of elements: a comma list (1,2,4,8) or a maximum M (1, 2, 4, ... up "
        "to M, and M); 1 is the paper's one-mode model (default 1,2,4,8,16,32)",
    )
    ap.add_argument(
        "--params",
        default=None,
        help="parameter set name or file; must be the gains' set (default: the gains' set)",
    )
    ap.add_argument(
        "--kappa",
        type=float,
        default=REFERENCE_KAPPA,
        help=f"pipe polar inertia over I1 (default the reference rig's, {REFERENCE_KAPPA:.4g})",
    )
    ap.add_argument(
        "--torque",
        choices=TORQUE_SIGNALS,
        default="motor",
        help="the string torque Z-Torque gets: motor (motor torque less rho times the table's "
        "acceleration, the rig lineup's), top (the top element's torque, a torque sub), twist "
        "(table angle minus bit angle); default motor",
    )
    ap.add_argument(
        "--bit",
        choices=BIT_FORMS,
        default="delay",
        help="the bit's averaged law: with its delay, (28)-(30), or its Taylor form (27); "
        "default delay",
    )
    ap.add_argument("--impedance", choices=STRING_IMPEDANCES, default="lumped",
                    help="string impedance of the industrial rules: lumped, pipe, or string "
                    "(sqrt(--kappa), the string's own; default lumped)")  # fmt: skip
    ap.add_argument("--soft-speed", choices=SOFT_SPEED_RULES, default="two-mass",
                    help="SoftSpeed's kp rule (default two-mass)")  # fmt: skip
    ap.add_argument("--z-matching", type=float, default=1.0,
                    help="Z-Torque's fraction of full impedance matching (default 1)")  # fmt: skip
    ap.add_argument("--out", type=Path, default=Path("out/string-spectrum"), help="output folder")
    return ap


def parse_elements(text: str) -> tuple[int, ...]:
    """``--elements``: a comma list, or one maximum M (1, 2, 4, ... below M, and M).

    Raises
    ------
    UsageError
        A value that is not an integer in [1, MAX_ELEMENTS], naming it.
    """
    values = []
    for part in str(text).split(","):
        try:
            value = int(part.strip())
        except ValueError:
            raise UsageError(
                f"--elements must be integers in [1, {MAX_ELEMENTS}], got {part.strip()!r}"
            ) from None
        if not 1 <= value <= MAX_ELEMENTS:
            raise UsageError(f"--elements must be integers in [1, {MAX_ELEMENTS}], got {value}")
        values.append(value)
    if len(values) == 1:
        top = values[0]
        values = [2**i for i in range(top.bit_length()) if 2**i < top] + [top]
    return tuple(sorted(set(values)))


def _lineup(gains: GainsFile, constrained: GainsFile | None, tuning: Tuning) -> dict[str, Any]:
    """Name -> law (None for the open loop), in the order of the table."""
    laws: dict[str, Law | None] = {"open-loop": None}
    laws.update(industrial_lineup(gains.params, tuning=tuning, R_ff=gains.R_ff))
    laws["lmi"] = SampledAffine(AffineFeedback(gains.F, gains.K0, gains.R_ff))
    if constrained is not None:
        laws["lmi-constrained"] = SampledAffine(
            AffineFeedback(constrained.F, constrained.K0, constrained.R_ff)
        )
    return laws


def spectrum_table(
    model: AveragedModel,
    laws: dict[str, Law | None],
    elements: Sequence[int],
    kappa: float,
    t_star: float | None,
    *,
    torque: str = "motor",
    bit: str = "delay",
) -> list[dict[str, Any]]:
    """One row per law and N: the abscissa, the rightmost root's frequency, the unstable roots.

    Parameters
    ----------
    model : AveragedModel
        The operating point's averaged model.
    laws : dict
        Name -> law (None: the open loop).
    elements : sequence of int
        The N (1: the paper's lumping).
    kappa : float
        The pipe's inertia over I1.
    t_star : float or None
        t* [s] of the rig, for the SI columns (None: they are NaN).
    torque, bit : str
        As :func:`~drillstring.controller.string_spectrum.string_closed_loop`.

    Returns
    -------
    list of dict
        Keyed by :data:`COLUMNS` (``unstable_frequencies_hz`` a list).
    """
    ts = math.nan if t_star is None else float(t_star)
    rows = []
    for name, law in laws.items():
        for n in elements:
            string = StringParams(elements=n, kappa=kappa)
            r = string_roots(model, law, string, torque=torque, bit=bit, n_roots=N_ROOTS)
            top = r[0]
            if top.real > 0.0:  # every unstable root, not only those near the rightmost
                kw = {"torque": torque, "bit": bit, "n_roots": N_ROOTS, "re_min": 0.0}
                r = string_roots(model, law, string, **kw)
            up = r[(r.real > 0.0) & (r.imag >= 0.0)]
            rows.append(
                {
                    "law": name,
                    "elements": n,
                    "lumping": string.lumping,
                    "abscissa_scaled_per_tau": float(top.real),
                    "abscissa_per_s": float(top.real) / ts,
                    "frequency_scaled_rad_per_tau": float(abs(top.imag)),
                    "frequency_hz": float(abs(top.imag)) / (2.0 * math.pi * ts),
                    "unstable_roots": int(up.size),
                    "unstable_frequencies_hz": sorted(
                        round(float(s.imag) / (2.0 * math.pi * ts), 4) for s in up
                    ),
                }
            )
    return rows


def reflection_table(
    laws: dict[str, Law | None], rho: float, kappa: float, t_star: float | None
) -> list[dict[str, Any]]:
    """The reflection coefficient of each top-drive law at the string's first two modes with
    the table held (:func:`~drillstring.controller.reflection.reflection_at_modes`), and of the
    table's inertia alone; one row per law and mode."""
    rows = []
    for name, law in [("table-inertia", None), *((n, laws[n]) for n in INDUSTRIAL if n in laws)]:
        for r in reflection_at_modes(law, rho, kappa, table=MODE_TABLE, count=2):
            rows.append({"law": name, "table": MODE_TABLE, **r.values(t_star)})
    return rows


def _print(rows: list[dict[str, Any]], elements: Sequence[int]) -> None:
    laws = list(dict.fromkeys(r["law"] for r in rows))
    print("spectral abscissa [1/s] (scaled per tau in brackets) against N")
    print(f"{'law':<16}" + "".join(f"{'N = ' + str(n):>20}" for n in elements))
    for law in laws:
        cells = [r for r in rows if r["law"] == law]
        print(
            f"{law:<16}"
            + "".join(
                f"{r['abscissa_per_s']:>+10.4f} ({r['abscissa_scaled_per_tau']:+.4f})"
                for r in cells
            )
        )


def _print_reflection(rows: list[dict[str, Any]]) -> None:
    print("reflection at the top drive, string modes with the table held: |r|, arg r [deg]")
    for law in dict.fromkeys(r["law"] for r in rows):
        cells = [r for r in rows if r["law"] == law]
        print(
            f"{law:<16}"
            + "".join(
                f"   mode {r['mode']} ({r['frequency_hz']:.3f} Hz): {r['r_magnitude']:.3f}, "
                f"{r['r_phase_deg']:+7.1f}"
                for r in cells
            )
        )


def string_spectrum_main(argv: Sequence[str] | None = None) -> int:
    """Run ``drillstring string-spectrum``; exit 0, or 2 with one line naming a bad value."""
    prog = "drillstring string-spectrum"
    try:
        args = build_parser().parse_args(argv)
        elements = parse_elements(args.elements)
        try:
            StringParams(elements=max(elements), kappa=args.kappa)
        except ValueError as exc:
            raise UsageError(str(exc).replace("StringParams.", "--")) from None
        gains = read_gains(args.gains)
        path = args.constrained
        if path is None:
            beside = Path(args.gains).with_name(CONSTRAINED_FILE)
            path = beside if beside.is_file() else None
        constrained = None if path is None else read_gains(path)
        params = gains.params
        if args.params is not None and params_from_spec(args.params) != params:
            raise UsageError(
                f"--params {args.params!r} is not the parameter set of the gains file "
                f"{str(args.gains)!r}"
            )
        if constrained is not None and constrained.params != params:
            raise UsageError(
                f"--constrained {str(path)!r} is for another parameter set than --gains"
            )
        tuning = Tuning(
            impedance=args.impedance,
            soft_speed=args.soft_speed,
            z_matching=args.z_matching,
            kappa=args.kappa if args.impedance == "string" else None,
        )
        model = averaged_model(params, gains.A, gains.taubar_crit)
        rig = known_rig(params)
        t_star = None if rig is None else rig.t_star
        laws = _lineup(gains, constrained, tuning)
        rows = spectrum_table(
            model, laws, elements, args.kappa, t_star, torque=args.torque, bit=args.bit
        )
        reflections = reflection_table(laws, params.rho, args.kappa, t_star)
        out = args.out
        csv_rows = [
            [*(r[c] for c in COLUMNS[:-1]), ";".join(f"{f:g}" for f in r[COLUMNS[-1]])]
            for r in rows
        ]
        write_csv(out / "string_spectrum.csv", COLUMNS, csv_rows)
        write_json(
            out / "string_spectrum.json",
            {
                "command": " ".join(
                    ["drillstring string-spectrum", *(sys.argv[1:] if argv is None else argv)]
                ),
                "gains": str(args.gains),
                "constrained": None if path is None else str(path),
                "elements": list(elements),
                "kappa": args.kappa,
                "torque": args.torque,
                "bit": args.bit,
                "tuning": tuning.values(),
                "t_star_s": t_star,
                "units": {
                    "abscissa_scaled_per_tau": "1 (per unit of tau = t/t*)",
                    "abscissa_per_s": "1/s",
                    "frequency_scaled_rad_per_tau": "rad per unit of tau",
                    "frequency_hz": "Hz",
                    "unstable_roots": "count: real roots and complex pairs with Re s > 0",
                    "unstable_frequencies_hz": "Hz, one per unstable real root or pair",
                },
                "note": "linearised about the gains' operating point: the bit's averaged law "
                "(27)/(28) with its delay tau_n0, the law in continuous time (no sampling, no "
                "drive limits or lag); the rigid-body root s = 0 left out; N = 1 is the "
                "paper's one-mode model",
                "rows": [
                    {
                        k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                        for k, v in r.items()
                    }
                    for r in rows
                ],  # fmt: skip
                "reflection": {
                    "note": "speed-wave reflection r = (Z_pipe - Z_top)/(Z_pipe + Z_top) at the "
                    "top drive, Z_pipe = sqrt(kappa), Z_top = rho s + the law's torque per "
                    "speed at s = i omega of the continuous string's modes with the table "
                    "held (docs/controllers.md, 'Reflection at the top drive'); the torque "
                    "wave is reflected with -r",
                    "units": {
                        "omega_scaled": "rad per unit of tau",
                        "frequency_hz": "Hz",
                        "Z_top_re": "C t* (scaled)",
                        "Z_top_im": "C t* (scaled)",
                        "r_phase_deg": "degrees",
                    },  # fmt: skip
                    "rows": [
                        {
                            k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                            for k, v in r.items()
                        }
                        for r in reflections
                    ],
                },
            },
        )
    except (UsageError, GainsFileError, ParameterError, ValueError, OSError) as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2
    _print(rows, elements)
    _print_reflection(reflections)
    print(f"wrote {out / 'string_spectrum.csv'}, {out / 'string_spectrum.json'}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(string_spectrum_main())
