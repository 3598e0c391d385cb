"""``drillstring modes``: the distributed string's modes, chain and continuous, as JSON and PNG.

Examples::

    drillstring modes --elements 16 --table held --out out/modes            # reference rig
    drillstring modes --elements 1 --table free --out out/modes-paper       # the paper's model
    drillstring modes --elements 32 --axial --axial-mass-ratio 0.5 --out out/modes-axial

Writes ``modes.json`` (the N-element chain's first modes beside the continuous string's exact
ones, in scaled units and in rad/s and Hz through the rig's t*, and their convergence in N) and
``modes.png`` (the mode shapes). ``docs/analysis.md``, "Modes of the string", derives what is
computed; :mod:`drillstring.analysis.modes` computes it.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from drillstring.analysis.modes import (
    TABLES,
    ChainModes,
    Convergence,
    axial_convergence,
    axial_elements_needed,
    axial_exact_modes,
    axial_exact_shape,
    axial_modes,
    to_hz,
    to_rad_s,
    torsional_convergence,
    torsional_elements_needed,
    torsional_exact_modes,
    torsional_exact_shape,
    torsional_modes,
)
from drillstring.apps.usage import OneLineParser, UsageError
from drillstring.fileio import save_figure, write_json
from drillstring.model.params import (
    KNOWN_PARAMS,
    KNOWN_PHYSICAL,
    ParameterError,
    ScaledParams,
    params_from_spec,
    rig_from_spec,
)
from drillstring.model.pipe import LUMPINGS, REFERENCE_KAPPA, StringParams
from drillstring.plotting import new_figure

__all__ = ["MAX_COUNT", "modes_main"]

#: The most modes ``--count`` may ask for (the first modes; a chain resolves few of its own).
MAX_COUNT = 32
#: The tolerance of the "elements needed" entries of modes.json.
REL_TOL = 0.01


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of the ``modes`` subcommand.

    Returns
    -------
    argparse.ArgumentParser
        The parser (``prog="drillstring modes"``); its options are listed by ``--help``. Its
        errors raise instead of exiting, so that :func:`modes_main` reports them in one line.
    """
    ap = OneLineParser(
        prog="drillstring modes",
        description="Modes of the distributed string: the N-element chain beside the "
        "continuous string's exact modes, and their convergence in N.",
    )
    ap.add_argument("--elements", required=True, help="N, the number of elements (1 to 4096)")
    ap.add_argument("--table", choices=TABLES, default="held", help="the rotary table's end")
    ap.add_argument("--axial", action="store_true", help="the axial modes too (hook held)")
    ap.add_argument("--count", default="3", help=f"how many modes (1 to {MAX_COUNT}), default 3")
    ap.add_argument("--params", default="reference", help="parameter set name or file")
    ap.add_argument(
        "--kappa",
        type=float,
        default=REFERENCE_KAPPA,
        help=f"pipe polar inertia over I1 (default the reference rig's, {REFERENCE_KAPPA:.4g})",
    )
    ap.add_argument(
        "--axial-mass-ratio",
        type=float,
        default=0.0,
        help="pipe mass over M (default 0: the paper's massless axial spring)",
    )
    ap.add_argument(
        "--lumping",
        choices=LUMPINGS,
        default=None,
        help="'paper' (N = 1 only) or 'lumped' (default: paper at N = 1, lumped above)",
    )
    ap.add_argument(
        "--t-star",
        type=float,
        default=None,
        help="t* = sqrt(I1/C) in s, for a scaled set that is no known rig's",
    )
    ap.add_argument("--out", type=Path, default=Path("out/modes"))
    return ap


def _whole(option: str, text: str, upper: int | None = None) -> int:
    """``text`` as an integer (in [1, upper] when given), or a one-line error naming the value."""
    try:
        value = int(text)
    except ValueError:
        raise UsageError(f"{option} must be a positive integer, got {text!r}") from None
    if upper is not None and not 1 <= value <= upper:
        raise UsageError(f"{option} must be an integer in [1, {upper}], got {text!r}")
    return value


def _rig(spec: str, t_star: float | None) -> tuple[ScaledParams, float, str]:
    """The scaled set of ``--params``, the t* [s] of its rig and a name for the title."""
    scaled = params_from_spec(spec)
    name = spec if spec in KNOWN_PARAMS else Path(spec).name
    if t_star is not None:
        if not (math.isfinite(t_star) and t_star > 0):
            raise UsageError(f"--t-star must be a positive number of seconds, got {t_star!r}")
        return scaled, t_star, f"{name}, t* given"
    phys = rig_from_spec(spec)
    if phys is None:
        raise UsageError(
            f"--params {spec!r} is a scaled set of no known rig, so t* is unknown: "
            "give --t-star SECONDS or a physical parameter file"
        )
    rig = next((k for k, v in KNOWN_PHYSICAL.items() if v is phys), spec)
    if rig != spec:  # a scaled set of a known rig
        name = f"{name} = {rig}"
    return scaled, phys.t_star, name


def _padded(values: np.ndarray, count: int) -> list[float | None]:
    """``values`` as a JSON list of ``count`` entries, null where there is no such mode."""
    out: list[float | None] = [None] * count
    for i, v in enumerate(values[:count]):
        out[i] = None if not math.isfinite(float(v)) else float(v)
    return out


def _table(conv: Convergence) -> dict[str, Any]:
    def rows(a: np.ndarray) -> list[list[float | None]]:
        return [_padded(r, a.shape[1]) for r in a]

    return {
        "elements": [int(n) for n in conv.elements],
        "lumping": "lumped",
        "omega_scaled": rows(conv.omega),
        "relative_error": rows(conv.rel_error),
        "error_ratio_per_doubling": rows(conv.ratio),
    }


def _direction(chain: ChainModes, exact: np.ndarray, count: int, t_star: float) -> dict[str, Any]:
    """The JSON entries of one direction: the chain's modes beside the exact ones."""
    n = max(count, exact.size)
    err = chain.omega[: exact.size] / exact[: chain.omega.size] - 1.0
    return {
        "omega_scaled": _padded(chain.omega, count),
        "omega_rad_s": _padded(to_rad_s(chain.omega, t_star), count),
        "frequency_hz": _padded(to_hz(chain.omega, t_star), count),
        "omega_exact_scaled": _padded(exact, n),
        "omega_exact_rad_s": _padded(to_rad_s(exact, t_star), n),
        "frequency_exact_hz": _padded(to_hz(exact, t_star), n),
        "relative_error": _padded(err, count),
    }


UNITS = {
    "omega_scaled": "angular frequency in rad per unit of scaled time tau = t/t*",
    "omega_rad_s": "angular frequency in rad/s (omega_scaled/t*)",
    "frequency_hz": "frequency in Hz (omega_rad_s/(2*pi))",
    "*_exact_*": "the continuous string's modes (roots of its frequency equation), same units",
    "relative_error": "omega_scaled/omega_exact_scaled - 1 (dimensionless)",
    "t_star_s": "t* = sqrt(I1/C) in s",
    "kappa_I1": "pipe polar inertia in units of I1",
    "rho_I1": "rotary-table inertia in units of I1",
    "bit_inertia_I1": "bit-end inertia of the continuous string, 1 - kappa/3, units of I1",
    "axial_mass_ratio_M": "pipe mass in units of M (0: the paper's massless spring)",
    "bit_mass_M": "bit-end mass of the continuous string, 1 - mu/3, units of M",
    "eta": "scaled axial stiffness parameter of (15), dimensionless",
    "convergence": "the lumped chain against N (elements, dimensionless counts); "
    "error_ratio_per_doubling is |error(N)|/|error(2N)| (4 at second order)",
    "elements_within_1_percent": "smallest N (count) whose mode k is within 1 % of the exact "
    "(the engine's lumping: the paper's at N = 1, lumped above)",
    "null": "no such mode (a chain of N elements has N modes; a massless spring one)",
}


def _write_figure(
    path: Path,
    title: str,
    panels: list[tuple[str, str, ChainModes, np.ndarray, Any]],
    t_star: float,
) -> Path:
    """The mode shapes: chain at the nodes (markers) and continuous string (lines)."""
    fig = new_figure((10.0, 4.2 * len(panels)))
    axes = fig.subplots(len(panels), 1, squeeze=False)[:, 0]
    x = np.linspace(0.0, 1.0, 401)
    for ax, (ylabel, xlabel, chain, exact, shape_of) in zip(axes, panels, strict=True):
        for k, w in enumerate(chain.omega[:4]):
            color = f"C{k}"
            style = "o-" if chain.x.size <= 65 else "-"
            ax.plot(
                chain.x,
                chain.shapes[k],
                style,
                color=color,
                ms=4,
                lw=0.6,
                label=f"mode {k + 1}, chain: {float(to_hz(w, t_star)):.4g} Hz",
            )
            if k < exact.size:
                ax.plot(
                    x,
                    shape_of(exact[k], x),
                    "--",
                    color=color,
                    lw=1.0,
                    label=f"mode {k + 1}, continuous: {float(to_hz(exact[k], t_star)):.4g} Hz",
                )
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_xlim(0.0, 1.0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    axes[0].set_title(title, fontsize="small")
    fig.tight_layout()
    return save_figure(fig, path)


def modes_main(argv: Sequence[str] | None = None) -> int:
    """Run the ``modes`` subcommand; exit code 0 (ok) or 2 (bad input, one line naming it).

    Writes ``modes.json`` and ``modes.png`` into ``--out`` (atomically) and prints the first
    modes.
    """
    try:
        args = build_parser().parse_args(argv)
        n = _whole("--elements", args.elements)  # StringParams bounds it
        count = _whole("--count", args.count, MAX_COUNT)
        try:
            string = StringParams(
                elements=n,
                kappa=args.kappa,
                axial_mass_ratio=args.axial_mass_ratio,
                lumping=args.lumping,
            )
        except ValueError as exc:
            msg = str(exc).replace("StringParams.", "--").replace("StringParams: ", "")
            raise UsageError(msg.replace("_", "-")) from None
        params, t_star, rig = _rig(args.params, args.t_star)
        result, panels = _compute(string, params, args.table, args.axial, count, t_star)
        result.update(
            {
                "elements": string.elements,
                "table": args.table,
                "lumping": string.lumping,
                "params": args.params,
                "rig": rig,
                "t_star_s": t_star,
            }
        )
        kappa_text = f"kappa = {string.kappa:.4g}"
        title = (
            f"Modes of the {n}-element string ({string.lumping} lumping), table {args.table}; "
            f"lines: continuous string\n{rig}: t* = {t_star:.4g} s, {kappa_text}, "
            f"rho = {params.rho:g}"
        )
        if args.axial:
            spring = "" if string.axial_distributed else " (a massless spring)"
            title += (
                f"; axial: hook held, mu = {string.axial_mass_ratio:g}{spring}, "
                f"eta = {params.eta:g}"
            )
        out = args.out
        write_json(out / "modes.json", result)
        _write_figure(out / "modes.png", title, panels, t_star)
    except (UsageError, ParameterError, ValueError, OSError) as exc:
        print(f"drillstring modes: {exc}", file=sys.stderr)
        return 2
    hz = ", ".join(f"{f:.4g}" for f in result["frequency_hz"] if f is not None)
    print(f"torsional modes of the {n}-element string, table {args.table}: {hz} Hz")
    if args.axial:
        hz = ", ".join(f"{f:.4g}" for f in result["axial"]["frequency_hz"] if f is not None)
        print(f"axial modes: {hz} Hz")
    print(f"wrote {out / 'modes.json'}, {out / 'modes.png'}")
    return 0


def _compute(
    string: StringParams,
    params: ScaledParams,
    table: str,
    axial: bool,
    count: int,
    t_star: float,
) -> tuple[dict[str, Any], list[tuple[str, str, ChainModes, np.ndarray, Any]]]:
    """modes.json's content and the figure's panels."""
    kappa, rho, eta, mu = string.kappa, params.rho, params.eta, string.axial_mass_ratio
    chain = torsional_modes(string, rho, table, count)
    exact = torsional_exact_modes(kappa, rho, table, count)
    result: dict[str, Any] = {
        "units": UNITS,
        "kappa_I1": kappa,
        "rho_I1": rho,
        "bit_inertia_I1": 1.0 - kappa / 3.0,
        **_direction(chain, exact, count, t_star),
        "convergence": None,
        "elements_within_1_percent": None,
    }
    if kappa > 0.0:
        result["convergence"] = _table(torsional_convergence(kappa, rho, table, count))
        result["elements_within_1_percent"] = {
            f"mode_{k}": torsional_elements_needed(kappa, rho, table, k, REL_TOL)
            for k in range(1, count + 1)
        }
    panels = [
        (
            r"twist amplitude $\theta/\max|\theta|$ [-]",
            "position along the pipe x/L [-] (0: rotary table, 1: bit)",
            chain,
            exact,
            lambda w, x: torsional_exact_shape(kappa, rho, table, w, x),
        )
    ]
    if axial:
        achain = axial_modes(string, eta, count)
        aexact = axial_exact_modes(mu, eta, count)
        entry: dict[str, Any] = {
            "axial_mass_ratio_M": mu,
            "bit_mass_M": 1.0 - mu / 3.0,
            "eta": eta,
            "distributed": string.axial_distributed,
            **_direction(achain, aexact, count, t_star),
            "convergence": None,
            "elements_within_1_percent": None,
        }
        if mu > 0.0:
            entry["convergence"] = _table(axial_convergence(mu, eta, count))
            entry["elements_within_1_percent"] = {
                f"mode_{k}": axial_elements_needed(mu, eta, k, REL_TOL) for k in range(1, count + 1)
            }
        result["axial"] = entry
        panels.append(
            (
                r"axial displacement $u/\max|u|$ [-]",
                "position along the pipe x/L [-] (0: hook, held; 1: bit)",
                achain,
                aexact,
                lambda w, x: axial_exact_shape(mu, eta, w, x),
            )
        )
    return result, panels
