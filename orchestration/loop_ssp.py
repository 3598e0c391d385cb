"""The closed loop of Section V as an SSP 1.0 package, in either unit system.

``build_fmus.py`` writes ``DrillStringClosedLoop.ssp`` (the scaled FMUs) and
``DrillStringClosedLoopSI.ssp`` (the SI FMUs) with :func:`write_loop_package`, and
``DrillStringTopDrive.ssp``, ``DrillStringTopDriveSI.ssp``, the same loops closed by the
industrial top-drive controller (variants
:data:`~drillstring.orchestration.closed_loop.TOPDRIVE`, ``TOPDRIVE_SI``). Each holds both
FMUs, the connections of :class:`~drillstring.orchestration.closed_loop.LoopVariant`, every
connector with its unit, and one SSD per experiment (:data:`LMI_EXPERIMENTS`,
:data:`TOPDRIVE_EXPERIMENTS`; :func:`loop_experiments`):

* ``SystemStructure.ssd`` is ``fig5``, the loop of Fig. 5 (``docs/model.md``, "Experiments of
  Figs. 5 and 6"); ``fig6.ssd`` is Fig. 6 (LMI packages); ``fig6-stiff-pi.ssd``,
  ``fig6-soft-speed.ssd``, ``fig6-z-torque.ssd`` each run an industrial law
  (:func:`topdrive_tunings`) from Fig. 6's state, switched on at Fig. 6's t_on (top-drive
  packages; their ``fig5`` is SoftSpeed, the FMU's start values, from t = 0);
* each SSD binds exactly one parameter set per component, named after the SSD
  (``resources/<variant>.<component>.ssv``), and complete: every parameter of the FMU, its
  start value unless the experiment (:func:`~drillstring.orchestration.closed_loop.
  experiment_start_values`, the whole initial state) or the tuning sets it (in SI converted on
  the reference rig). SSP 1.0's every-binding-in-order, libcosim's first binding, Ecos's
  ``--parameterSet <variant>`` and the project's master then apply the same values;
* each SSD has its default experiment (:func:`loop_default_experiment`) with the fixed-step
  annotation;
* ``documentation/index.html`` (:func:`package_documentation`) says what each variant is,
  which tool honours what, and Ecos's pitfalls.
"""

from __future__ import annotations

import html
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from fmpy import read_model_description

from drillstring.controller.lineup import INDUSTRIAL, industrial_lineup
from drillstring.model.experiments import FIG5, FIG6, Experiment
from drillstring.model.laws import ZTorque
from drillstring.model.params import REFERENCE, REFERENCE_RIG
from drillstring.model.units import SCALED_UNITS, SI_UNITS, UNITS
from drillstring.orchestration.closed_loop import (
    SCALED,
    LoopVariant,
    experiment_start_values,
    fmu_paths,
)
from drillstring.orchestration.connections import declared_start_values, variable_unit
from drillstring.orchestration.ssp import (
    SSD_FILE,
    SspComponent,
    SspConnection,
    SspConnector,
    SspParameter,
    SspVariant,
    write_ssp,
)

__all__ = [
    "DEFAULT_STEP",
    "LMI_EXPERIMENTS",
    "LoopExperiment",
    "TOPDRIVE_DEFAULT",
    "TOPDRIVE_EXPERIMENTS",
    "TOPDRIVE_PARAMETERS",
    "loop_default_experiment",
    "loop_experiments",
    "package_documentation",
    "topdrive_tunings",
    "write_loop_package",
]

#: The fixed macro step of the packages' default experiments (scaled time; 1 ms in SI).
DEFAULT_STEP = 1e-3
#: The top-drive controller FMU's parameters a tuning sets.
TOPDRIVE_PARAMETERS = ("kp", "ki", "z_gain", "omega_hp", "omega_lp")
#: The tuning that is the top-drive controller FMU's start values.
TOPDRIVE_DEFAULT = "soft-speed"


@dataclass(frozen=True)
class LoopExperiment:
    """One SSD of a loop package: an experiment, and for the top-drive controller its tuning.

    Attributes
    ----------
    name : str
        The SSD's name and file stem, and the name of the parameter sets it binds.
    experiment : Experiment
        Initial state, RK4 step, torsional-stick model, switch-on time, latch, enabled flag and
        length of the run (scaled time).
    tuning : str or None
        Top-drive packages: the industrial tuning (:func:`topdrive_tunings`); None for the LMI
        controller (its gains are the FMU's).
    summary : str
        One line on what the run is (the SSD's description, the documentation).
    plant : tuple of (str, object)
        Plant parameters the SSD sets besides the experiment's (the distributed string's
        ``string_elements``); their names are the same in both unit systems.
    """

    name: str
    experiment: Experiment
    tuning: str | None = None
    summary: str = ""
    plant: tuple[tuple[str, object], ...] = ()


_LAWS = {"stiff-pi": "stiff speed PI", "soft-speed": "SoftSpeed", "z-torque": "Z-Torque"}
#: The SSDs of the packages of the loop closed by the LMI controller; the first is
#: ``SystemStructure.ssd``.
LMI_EXPERIMENTS: tuple[LoopExperiment, ...] = (
    LoopExperiment(
        "fig5", FIG5, None, "Fig. 5: the LMI controller on from t = 0, dphi/dtau(0) = -2.5"
    ),
    LoopExperiment(
        "fig6",
        FIG6,
        None,
        "Fig. 6: torsional stick-slip from dphi/dtau(0) = -4.9 (torsional-stick model on), the "
        "LMI controller switched on at tau = 25 with the bumpless latch 'angle'",
    ),
)
#: The SSDs of the top-drive packages; the first is ``SystemStructure.ssd``.
TOPDRIVE_EXPERIMENTS: tuple[LoopExperiment, ...] = (
    LoopExperiment(
        "fig5",
        FIG5,
        TOPDRIVE_DEFAULT,
        "Fig. 5's initial state, SoftSpeed (the FMU's start values) on from t = 0",
    ),
    *(
        LoopExperiment(
            f"fig6-{t}",
            FIG6,
            t,
            f"Fig. 6's torsional stick-slip, {_LAWS.get(t, t)} switched on at tau = 25",
        )
        for t in INDUSTRIAL
    ),
    LoopExperiment(
        "fig6-soft-speed-string",
        FIG6,
        "soft-speed",
        "Fig. 6's torsional stick-slip on a distributed string of 16 elements (the reference "
        "rig's pipe, docs/model.md, 'The distributed string'), SoftSpeed switched on at tau = 25",
        (("string_elements", 16),),
    ),
)


def loop_experiments(variant: LoopVariant) -> tuple[LoopExperiment, ...]:
    """The SSDs of the package of ``variant`` (its controller's list), default first.

    Parameters
    ----------
    variant : LoopVariant
        The loop (``variant.controller``: ``"lmi"`` or ``"topdrive"``).

    Returns
    -------
    tuple of LoopExperiment
        :data:`TOPDRIVE_EXPERIMENTS` or :data:`LMI_EXPERIMENTS`.
    """
    return TOPDRIVE_EXPERIMENTS if variant.controller == "topdrive" else LMI_EXPERIMENTS


def topdrive_tunings(variant: LoopVariant = SCALED) -> dict[str, dict[str, float]]:
    """The industrial tunings of the reference set as values of the top-drive FMU's parameters.

    :func:`~drillstring.controller.lineup.industrial_lineup` of the scaled reference set; a
    SpeedPI is the FMU's law with ``z_gain = 0`` (its filter corners, unread, are ZTorque's
    defaults). The values are converted by the unit system's scales on the reference rig
    (:meth:`~drillstring.model.laws.ZTorque.to_si`), as the SI FMU converts its start values.

    Parameters
    ----------
    variant : LoopVariant
        The unit system (``variant.units``).

    Returns
    -------
    dict
        Tuning name (:data:`~drillstring.controller.lineup.INDUSTRIAL`) -> parameter -> value.
    """
    out = {}
    for name, law in industrial_lineup(REFERENCE).items():
        z = law if isinstance(law, ZTorque) else ZTorque(kp=law.kp, ki=law.ki, z_gain=0.0)
        values = z.to_si(variant.units.scales())
        out[name] = {k: float(values[k]) for k in TOPDRIVE_PARAMETERS}
    return out


def loop_default_experiment(
    variant: LoopVariant, experiment: Experiment = FIG5
) -> tuple[float, float, float]:
    """The default experiment (start, stop, step) of an SSD of a loop package.

    See ``docs/model.md``, "Experiments of Figs. 5 and 6".

    Parameters
    ----------
    variant : LoopVariant
        :data:`~drillstring.orchestration.closed_loop.SCALED` or ``SI`` (or their top-drive
        forms).
    experiment : Experiment
        The run (its ``tau_end``); default Fig. 5.

    Returns
    -------
    tuple of 3 float
        ``(0, stop, step)`` with the fixed step :data:`DEFAULT_STEP`: stop is tau_end in the
        variant's time (on the reference rig) rounded up to a whole number of steps, so that
        every host takes the same equal steps (scaled: 60 for Figs. 5 and 6; SI: 55.352 s).
    """
    step = DEFAULT_STEP
    stop = variant.units.scales().time(experiment.tau_end)
    return 0.0, float(round(math.ceil(stop / step) * step, 12)), step


def _complete_set(md, given: Mapping[str, object]) -> tuple[SspParameter, ...]:
    """Every parameter of the FMU, in its declaration order: ``given`` where it sets one, else
    the FMU's start value (an unknown name in ``given`` is an error)."""
    starts = declared_start_values(md)
    variables = [v for v in md.modelVariables if v.causality == "parameter"]
    unknown = sorted(set(given) - {v.name for v in variables})
    if unknown:
        raise ValueError(f"{md.modelName}: no parameter(s) {unknown} to set")
    out = []
    for var in variables:
        unit = variable_unit(var)
        unit = unit if var.type == "Real" and unit not in (None, "1") else None
        out.append(SspParameter(var.name, var.type, given.get(var.name, starts[var.name]), unit))
    return tuple(out)


def write_loop_package(
    fmus_dir: str | os.PathLike[str],
    variant: LoopVariant,
    source_date_epoch: int | None = None,
) -> Path:
    """Write the SSP package of the closed loop of the FMUs in ``fmus_dir`` (module docstring)
    to ``fmus_dir/<variant.ssp>``.

    Parameters
    ----------
    fmus_dir : path
        Folder with the variant's two FMUs (``build_fmus.py``'s output).
    variant : LoopVariant
        :data:`~drillstring.orchestration.closed_loop.SCALED`, ``SI``, ``TOPDRIVE`` or
        ``TOPDRIVE_SI``.
    source_date_epoch : int, optional
        Timestamp of the archive entries (reproducible builds).

    Returns
    -------
    Path
        The package, validated against the SSP 1.0 schemas.
    """
    paths = dict(zip(("plant", "controller"), fmu_paths(fmus_dir, variant), strict=True))
    target = Path(fmus_dir) / variant.ssp
    mds = {name: read_model_description(str(fmu)) for name, fmu in paths.items()}
    connectors = {
        name: tuple(
            SspConnector(
                v.name, v.causality, v.type, variable_unit(v) if v.type == "Real" else None
            )
            for v in md.modelVariables
            if v.causality in ("input", "output")
        )
        for name, md in mds.items()
    }
    connections = []
    for spec in variant.connections:
        src, dst = (part.strip().split(".", 1) for part in spec.split("->"))
        connections.append(SspConnection(src[0], src[1], dst[0], dst[1]))
    tunings = topdrive_tunings(variant) if variant.controller == "topdrive" else {}
    ssds = []
    for e in loop_experiments(variant):
        given = experiment_start_values(e.experiment, variant, full_initial=True)
        if e.tuning is not None:
            given["controller"] = {**given["controller"], **tunings[e.tuning]}
        given["plant"] = {**given["plant"], **dict(e.plant)}
        comps = tuple(
            SspComponent(
                name,
                f"resources/{paths[name].name}",
                connectors[name],
                {e.name: _complete_set(mds[name], given[name])},
            )
            for name in paths
        )
        ssds.append((e, comps))
    (first, first_comps), rest = ssds[0], ssds[1:]
    return write_ssp(
        target,
        name=first.name,
        system=variant.system,
        components=first_comps,
        fmus=paths,
        connections=connections,
        units=UNITS,
        default_experiment=loop_default_experiment(variant, first.experiment),
        description=_description(variant, first),
        variants=[
            SspVariant(
                f"{e.name}.ssd",
                e.name,
                comps,
                tuple(connections),
                loop_default_experiment(variant, e.experiment),
                _description(variant, e),
            )
            for e, comps in rest
        ],
        documentation={"index.html": package_documentation(variant)},
        source_date_epoch=source_date_epoch,
    )


def _loop_description(variant: LoopVariant) -> str:
    """What the package's loop is (the SSDs' descriptions without the experiment)."""
    kind = variant.units.quantities
    topdrive = variant.controller == "topdrive"
    law = "industrial top-drive controller" if topdrive else "torsional controller (29)-(31)"
    return (
        f"Drill-string plant (11)-(14), (17) of Besselink, van de Wouw and Nijmeijer (IEEE "
        f"CCA 2011) and {law} in closed loop, in {kind}"
    )


def _description(variant: LoopVariant, e: LoopExperiment) -> str:
    return f"{_loop_description(variant)}. {e.summary}"


#: What the package documentation says of the units and the time base of its FMUs.
_TIME_NOTE = {
    SI_UNITS.name: (
        "<p>The FMUs are in SI units and seconds: every variable declares its unit (with its "
        "SI base-unit exponents in the FMUs' <code>UnitDefinitions</code> and the SSD's "
        "<code>Units</code>), and the time of <code>fmi2DoStep</code> and of the default "
        "experiments is in seconds.</p>"
    ),
    SCALED_UNITS.name: (
        "<p>The FMUs speak the paper's scaled, dimensionless quantities (unit "
        '<code>"1"</code>). Their time is the scaled time tau = t/t*, t* = sqrt(I1/C), '
        "which FMI 2.0 gives no unit a tool can read: an FMU that declares no independent "
        "variable has one named <code>time</code> in <code>s</code> (FMI 2.0, section "
        "2.2.7), so every tool shows tau as seconds. One unit of time is t* seconds of the "
        "rig ({t_star:.6g} s for the reference rig), and so are the default experiments' "
        "times, the step and the time-valued parameters (<code>h</code>, <code>t_on</code> "
        "and the others; the FMUs' model descriptions say so in the FMU's and in each such "
        "variable's description). To "
        "couple the loop with models in seconds use the SI package "
        "<code>{si_package}.ssp</code>.</p>"
    ),
}


def package_documentation(variant: LoopVariant) -> str:
    """``documentation/index.html`` of a loop package: its variants, what each tool honours,
    Ecos's pitfalls, units and the time base (module docstring).

    Parameters
    ----------
    variant : LoopVariant
        The loop of the package.

    Returns
    -------
    str
        The HTML page.
    """
    esc = html.escape
    units = variant.units
    experiments = loop_experiments(variant)
    rows = []
    for i, e in enumerate(experiments):
        start, stop, step = loop_default_experiment(variant, e.experiment)
        file = SSD_FILE if i == 0 else f"{e.name}.ssd"
        unit = units.time_unit
        t_on = units.scales().time(e.experiment.t_on)
        rows.append(
            f"<tr><td><code>{esc(file)}</code></td><td><code>{esc(e.name)}</code></td>"
            f"<td>{esc(e.summary)}</td><td>{t_on:.6g}{unit}</td><td>{start:g} to "
            f"{stop:g}{unit}, step {step:g}{unit}</td></tr>"
        )
    first = experiments[0]
    other = experiments[1].name
    _, stop, step = loop_default_experiment(variant, first.experiment)
    system = variant.system
    time = _TIME_NOTE[units.name].format(
        si_package=esc(system + SI_UNITS.suffix), t_star=REFERENCE_RIG.t_star
    )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{esc(system)}</title></head>
<body>
<h1>{esc(system)}</h1>
<p>{esc(_loop_description(variant))}. SSP 1.0 package written by the
drillstring project (<code>build_fmus.py</code>), validated against the SSP 1.0 schemas.</p>

<h2>One experiment per SSD</h2>
<p>Each SSD at the root of the package is one experiment (an SSP variant). Each binds exactly
one parameter set per component, named like the SSD
(<code>resources/&lt;name&gt;.&lt;component&gt;.ssv</code>), with every parameter of the FMU;
each has its own default experiment (start and stop time, and the Open Simulation Platform's
fixed-step annotation). <code>{SSD_FILE}</code> is the default, what a tool that knows no
variants runs.</p>
<table border="1" cellspacing="0" cellpadding="3">
<tr><th>SSD</th><th>name and parameter set</th><th>experiment (scaled time tau)</th>
<th>switch-on</th><th>default experiment</th></tr>
{chr(10).join(rows)}
</table>

<h2>What each tool does with it</h2>
<ul>
<li><b>The drillstring master</b>: <code>Master.from_ssp(PACKAGE, variant="{esc(other)}")</code>
or <code>drillstring cosim PACKAGE --variant {esc(other)} --out DIR</code> applies the SSD's
bindings as SSP 1.0 does (every binding of a component in order, later ones winning), runs its
default experiment, converts parameter values given in another unit of the same dimension into
the FMU variable's unit and refuses incompatible ones, and converts (or refuses) values on
connections between FMUs of different units. <code>parameter_set=</code> names sets
explicitly instead.</li>
<li><b>libcosim</b> (<code>CosimExecution.from_ssp_file</code>) applies the first binding of
each component (here the only one) and takes its step from the fixed-step annotation. Given the
archive it reads <code>{SSD_FILE}</code>; for another variant unpack the package and give the
path of its <code>.ssd</code>. It sets values as given, without units, and ignores
Enumeration variables.</li>
<li><b>Ecos</b> (<code>ecos simulate</code>, ecospy 0.7.2) applies only the parameter set named
by <code>--parameterSet</code> and reads only <code>{SSD_FILE}</code> of the archive or folder
given. Run the default as <code>ecos simulate --path {esc(system)}.ssp --stepSize {step:g}
--stopTime {stop:g} --parameterSet {esc(first.name)}</code>; for another variant unpack the
package into a folder, copy its <code>.ssd</code> over <code>{SSD_FILE}</code>, and run
<code>ecos simulate --path FOLDER --stepSize {step:g} --stopTime ... --parameterSet
NAME</code> (a path to an <code>.ssd</code> file crashes it: segmentation fault, exit code
139). See the pitfalls below.</li>
<li><b>fmpy</b> (<code>fmpy.ssp.simulation.simulate_ssp</code>) reads only <code>{SSD_FILE}</code>
and applies none of its bindings: pass the set as its <code>parameter_set</code> argument, with
names <code>component.variable</code>. Its connectors start at 0 without an initialization
exchange, so its runs begin with a transient.</li>
</ul>

<h2>Ecos: what it does not tell you</h2>
<ul>
<li>A misspelt <code>--parameterSet</code> (or none) is ignored without a word: the FMUs' start
values run (for these FMUs: Fig. 5's initial state and the controller on from t = 0).</li>
<li>The default experiment is ignored: without <code>--stopTime</code> the run stops at 1 s.
Give <code>--stopTime</code> and <code>--stepSize</code> from the table above.</li>
<li>A set that binds only one component leaves the other at its start values: a
controller-only set runs the plant from its own initial state (a stiff PI set alone, on from
t = 0, ran the plant from Fig. 5's state with the torsional-stick model off, which leaves the
model at 54.017 s in SI). Every set of this package binds both components for that reason.</li>
<li>When the plant leaves the validity of its model (bit bouncing, torsional stick without the
torsional-stick model: <code>fmi2Discard</code>), Ecos prints nothing of it at its default log
level, goes on stepping with the plant's outputs frozen (the controller computes on) and
exits with code 0: check that the plant's outputs still change at the end of the run.</li>
<li>A run of fewer than 10 steps ends in a floating-point exception (exit code 136).</li>
<li>Enumeration parameters (<code>latch</code>, <code>on_invalid</code>) are not set (Ecos warns
that no int variable of that name is registered): they keep the FMUs' start values, which are
the values the sets give.</li>
</ul>

<h2>Units and time</h2>
<p>Every connector carries the unit of its FMU variable; the SSD's <code>Units</code> and each
<code>.ssv</code>'s define them by their SI base-unit exponents.</p>
{time}
</body>
</html>
"""
