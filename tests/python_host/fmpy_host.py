"""A Python host of the FMUs: fmpy's FMU2Slave in whatever interpreter runs this script.

Standalone (fmpy and the standard library only: the interpreter running it is a host of another
version or build, without the project; tests/test_fmu_python_hosts.py). Usage::

    python fmpy_host.py OUT.json STEPS H FMU [FMU ...]

Each FMU, in this one process and in order, is instantiated with logging on; if that succeeds it
is initialized at its start values, stepped STEPS times by H from 0 and its Real outputs read
after each step, then terminated and freed. OUT.json gets, per FMU: whether it was instantiated,
its log messages (status, category, text as a C host formats them) and the outputs as
``float.hex`` strings (bit-exact), plus this interpreter's version and executable.
"""

import ctypes
import json
import platform
import sys

from fmpy import extract, read_model_description
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

_libc = ctypes.CDLL(None)
_libc.calloc.restype = ctypes.c_void_p
_libc.calloc.argtypes = [ctypes.c_size_t, ctypes.c_size_t]
_libc.free.argtypes = [ctypes.c_void_p]


def run(path, steps, h):
    md = read_model_description(path)
    logs = []

    def logger(env, instance, status, category, message):
        text = message.decode("utf-8", "replace").replace("%%", "%")
        logs.append([int(status), category.decode() if category else "", text])

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(lambda n, s: _libc.calloc(n, s))
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(lambda p: _libc.free(p))
    folder = extract(path)
    model = md.coSimulation.modelIdentifier
    slave = FMU2Slave(
        guid=md.guid, unzipDirectory=folder, modelIdentifier=model, instanceName=model
    )
    slave.callbacks = callbacks
    uri = f"file://{folder}/resources".encode()
    slave.component = slave.fmi2Instantiate(
        model.encode(), 1, md.guid.encode(), uri, ctypes.byref(callbacks), 0, 1
    )
    result = {"model": model, "instantiated": bool(slave.component), "logs": logs, "rows": []}
    if slave.component:
        outputs = [
            v.valueReference
            for v in md.modelVariables
            if v.causality == "output" and v.type == "Real"
        ]
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        t = 0.0
        for _ in range(steps):
            slave.doStep(t, h)
            t += h
            result["rows"].append([float(x).hex() for x in slave.getReal(outputs)])
        slave.terminate()
        slave.freeInstance()
    return result


def main(argv):
    out, steps, h, fmus = argv[0], int(argv[1]), float(argv[2]), argv[3:]
    report = {
        "python": platform.python_version(),
        "executable": sys.executable,
        "fmus": [run(path, steps, h) for path in fmus],
    }
    with open(out, "w", encoding="utf-8") as f:
        json.dump(report, f)


if __name__ == "__main__":
    main(sys.argv[1:])
