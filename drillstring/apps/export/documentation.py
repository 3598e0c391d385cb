"""``documentation/index.html`` of an FMU (FMI 2.0, section 2.1): its time base and units, its
variables, the validity of the model, the statuses and what a host needs.
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from typing import Any

from drillstring.apps.export.model_description import format_bound, format_start, scaled_time
from drillstring.apps.export.python_runtime import OVERRIDES, RUNTIME_NAME
from drillstring.model.params import REFERENCE_RIG
from drillstring.model.units import SCALED_TIME

__all__ = ["documentation"]


def _time_base(variables: Sequence[Any]) -> str:
    """The paragraph of ``documentation/index.html`` on what a host reads as the FMU's time."""
    implicit = (
        "The FMU declares no independent variable, so by FMI 2.0 (section 2.2.7) its time is a "
        "variable <code>time</code> with unit <code>s</code>, and every host reads it as seconds."
    )
    if not scaled_time(variables):
        return f"<p>{implicit} It is: this FMU's time is in seconds.</p>"
    times = [f"<code>{v.name}</code>" for v in variables if SCALED_TIME in v.description]
    return (
        f"<p>{implicit} Its numbers are the paper's scaled time tau = t/t*: one unit of this "
        f"FMU's time is t* = sqrt(I1/C) seconds of the rig ({REFERENCE_RIG.t_star:.6g} s for the "
        "reference rig), and in that unit are the start time, the communication points and step "
        "sizes of <code>fmi2SetupExperiment</code> and <code>fmi2DoStep</code>, the default "
        f'experiment and the time-valued variables ({", ".join(times)}; unit <code>"1"</code>, '
        "and their descriptions in the model description say so, as does the FMU's). The "
        "FMUs named <code>...SI</code> are the same model in seconds and SI units, for coupling "
        "with models in seconds.</p>"
    )


def documentation(
    cls: Any, variables: Sequence[Any], starts: dict[str, Any], record: dict[str, Any]
) -> str:
    """``documentation/index.html`` of one FMU (FMI 2.0, section 2.1: the documentation's entry);
    ``record`` is the Python that builds it (:func:`~drillstring.apps.export.python_runtime.
    python_record`), which the FMU needs."""
    esc = html.escape
    py = record["version"]
    modules = " and ".join(f"{n} {v}" for n, v in record["modules"].items() if v is not None)
    rows = []
    for v in variables:
        start = "" if v.causality == "output" else format_start(starts[v.name], v.type)
        if v.type == "Enumeration":
            start += " (" + v.item(int(starts[v.name])) + ")"
            kind = f"Enumeration {v.type_name}: " + ", ".join(
                f"{i + 1} = {n}" for i, (n, _) in enumerate(v.items)
            )
        else:
            kind = v.type
        lo = "" if v.min is None else format_bound(v.min, v.type)
        hi = "" if v.max is None else format_bound(v.max, v.type)
        rng = f"[{lo or '-inf'}, {hi or 'inf'}]" if (lo or hi) else ""
        unit = v.unit if v.type == "Real" else ""
        if v.display_unit is not None:
            unit += f" (shown in {v.display_unit})"
        rows.append(
            f"<tr><td><code>{esc(v.name)}</code></td><td>{v.causality}</td><td>{esc(kind)}</td>"
            f"<td>{esc(unit)}</td><td>{esc(start)}</td><td>{esc(rng)}</td>"
            f"<td>{esc(v.description)}</td></tr>"
        )
    validity = "".join(f"<p>{esc(p)}</p>" for p in cls.VALIDITY)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{esc(cls.MODEL)}</title></head>
<body>
<h1>{esc(cls.MODEL)}</h1>
<p>{esc(cls.description)}. FMI 2.0 co-simulation FMU built by the drillstring project
(<code>build_fmus.py</code>): a front layer in plain C
(<code>binaries/linux64/{cls.MODEL}.so</code>) in front of pythonfmu's library
(<code>binaries/linux64/{cls.MODEL}_pythonfmu.so</code>), which runs the Python model in
<code>resources/</code>.</p>

<h2>Time base and units</h2>
<p>{esc(cls.TIME_AND_UNITS)} The start time must be 0 (<code>fmi2SetupExperiment</code>): the
model's history before it is the nominal motion. Any step size &gt; 0 is accepted and need not
be constant; the communication point of <code>fmi2DoStep</code> must be the FMU's current time.
Inputs are held constant over each step.</p>
{_time_base(variables)}

<h2>Variables</h2>
<table border="1" cellspacing="0" cellpadding="3">
<tr><th>name</th><th>causality</th><th>type</th><th>unit</th><th>start</th><th>range</th>
<th>description</th></tr>
{chr(10).join(rows)}
</table>
<p>Outputs are computed from the parameters (<code>initial="calculated"</code>): they can be read
from <code>fmi2EnterInitializationMode</code> on.</p>

<h2>Validity of the model</h2>
{validity}

<h2>Statuses</h2>
<p><code>fmi2Error</code> comes from the very call that received a bad value (a parameter out of
range or an inconsistent combination at <code>fmi2ExitInitializationMode</code>, a non-finite
number, an unknown value reference, a variable of another type, a parameter set after
initialization, a step size &lt;= 0, a communication point that is not the FMU's time, an FMU
state of another FMU or corrupted bytes, an illegal call sequence); the value is not applied and
the instance goes on as before the call. <code>fmi2Warning</code> comes with a logged warning.
<code>fmi2Discard</code> only when the model leaves its validity inside a step: then
<code>fmi2GetRealStatus(fmi2LastSuccessfulTime)</code> is the time reached and the outputs hold
the state there; restore an earlier state (<code>fmi2SetFMUstate</code>) or terminate. Errors,
discards and warnings are always logged; information only with logging on (categories
<code>logInfo</code>, <code>logAll</code>).</p>

<h2>What the host needs</h2>
<p>Linux x86-64 and, on the machine that built the FMU, nothing else: the FMU loads the recorded
libpython itself and starts it with the recorded home and site-packages
(<code>resources/{RUNTIME_NAME}</code>). No <code>LD_PRELOAD</code>, <code>PYTHONPATH</code> or
<code>PYTHONHOME</code>. The FMU runs only in the kind of Python that built it: CPython {py}
(ABI <code>{esc(str(record["abi"]))}</code>) importing {esc(modules)}, the versions that compute
its numbers (<code>resources/requirements.txt</code> pins them). On another machine set</p>
<ul>
<li><code>{OVERRIDES["libpython"]}</code>: the <code>libpython{py}.so</code> of a CPython {py}
(built with <code>--enable-shared</code>);</li>
<li><code>{OVERRIDES["home"]}</code>: its installation prefix (with
<code>lib/python{py}</code>);</li>
<li><code>{OVERRIDES["site"]}</code>: ':'-separated site-packages with {esc(modules)}
(<code>pip install -r resources/requirements.txt</code>).</li>
</ul>
<p>A host that is itself Python (fmpy, libcosimpy) lends its interpreter instead (a process holds
one Python), and the variables above do not apply: that interpreter must be a CPython {py} of the
same ABI (another build of it will do, such as a distribution's python3 {py}) whose environment
imports {esc(modules)} (<code>pip install -r resources/requirements.txt</code> there).
Otherwise, a Python of another minor version, another numpy or numba or none, the FMU refuses at
<code>fmi2Instantiate</code> (NULL, with a logged error naming the host's version or modules and
the FMU's) before any of its Python code runs; such a host can run the FMU in a process of its
own that does not run Python (a C host, libcosim, Ecos), where the FMU starts the recorded
Python. With <code>DRILLSTRING_JIT=0</code> numba is not used and need not be there.</p>
<p>The drillstring package is copied once into <code>$DRILLSTRING_FMU_CACHE</code>, else
<code>$XDG_CACHE_HOME/drillstring</code>, else <code>~/.cache/drillstring</code>, where numba keeps
the compiled kernel: the first run on a machine compiles it (logged at info level, 10-20 s), every
later run of the same build, in any unpack folder, loads it. <code>DRILLSTRING_JIT=0</code> runs
the plain-Python kernel instead (bit-identical results, slower).</p>
</body></html>
"""
