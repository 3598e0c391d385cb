"""Run FMUs through their whole lifecycle in fmpy, so that numba compiles (and caches) every
function they use: the warm-up of a self-contained build (:mod:`drillstring.apps.export.
self_contained`).

Run as a script, ``python warmup_host.py FMU [FMU ...]``, in an environment that names the
package cache (``DRILLSTRING_FMU_CACHE``) and the CPU to compile for (``NUMBA_CPU_NAME``). It
imports fmpy and nothing of the project: the FMUs copy their own ``drillstring`` package into
that cache and numba compiles it there, where the builder collects the compiled files. Exit
status 0, or 1 with the failing call on stderr.

Each FMU goes through what hosts call: instantiation, parameters, initialization, steps on the
native fast path (``fmi2GetReal`` between steps), FMU states taken, serialized, restored and
freed, ``fmi2Reset`` and a second run, termination and release; then an instance on the Python
path only (``DRILLSTRING_FMU_NATIVE=0``), and a long run that fills the plant's history buffer (a
step the native path hands back to Python). The controllers run once as they start and once
with the top drive and sampled downhole sensing on, switched on at the first step.
"""

from __future__ import annotations

import os
import sys

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

#: Communication step and number of steps of each run (scaled time tau; seconds for SI FMUs),
#: and of the long run.
STEP = 1e-3
STEPS = 200
LONG_STEP = 1e-2
LONG_STEPS = 20_000
#: Parameter settings of the controllers' second run (top drive and telemetry on), where the FMU
#: has them.
ACTIVE = {"t_on": 0.0, "top_drive": True, "period": 0.05}


def _run(
    slave: FMU2Slave,
    refs: dict[str, tuple[int, str]],
    settings: dict,
    steps: int = STEPS,
    step: float = STEP,
) -> None:
    for name, value in settings.items():
        if name not in refs:
            continue
        vr, kind = refs[name]
        if kind == "Boolean":
            slave.setBoolean([vr], [bool(value)])
        else:
            slave.setReal([vr], [float(value)])
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    outputs = [vr for vr, kind in refs.values() if kind == "Real"]
    t = 0.0
    for k in range(steps):
        slave.doStep(currentCommunicationPoint=t, communicationStepSize=step)
        t += step
        if k % 50 == 0:
            slave.getReal(outputs)
    state = slave.getFMUstate()
    copy = slave.deSerializeFMUstate(slave.serializeFMUstate(state))
    slave.setFMUstate(copy)
    slave.doStep(currentCommunicationPoint=t, communicationStepSize=step)
    slave.freeFMUstate(copy)
    slave.freeFMUstate(state)


def _instance(path: str, md) -> FMU2Slave:
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=extract(path),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="warmup",
    )
    slave.instantiate(loggingOn=False)
    return slave


def warm_up(path: str) -> None:
    """Every lifecycle call of the FMU at ``path`` (see the module docstring)."""
    md = read_model_description(path)
    refs = {v.name: (v.valueReference, v.type) for v in md.modelVariables}
    slave = _instance(path, md)
    _run(slave, refs, {})
    slave.reset()
    _run(slave, refs, ACTIVE if "top_drive" in refs else {})
    slave.terminate()
    slave.freeInstance()
    os.environ["DRILLSTRING_FMU_NATIVE"] = "0"  # read when an instance is made
    try:
        slave = _instance(path, md)
    finally:
        del os.environ["DRILLSTRING_FMU_NATIVE"]
    _run(slave, refs, {})
    slave.terminate()
    slave.freeInstance()
    slave = _instance(path, md)
    _run(slave, refs, {}, LONG_STEPS, LONG_STEP)
    slave.terminate()
    slave.freeInstance()


def main(paths: list[str]) -> int:
    for path in paths:
        try:
            warm_up(path)
        except Exception as exc:  # reported to the builder, which fails the build
            print(f"warm-up of {path} failed: {type(exc).__name__}: {exc}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
