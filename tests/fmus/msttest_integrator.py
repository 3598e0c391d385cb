"""Test FMU: scalar integrator x' = k * u, exact for an input held over the step.

Output ``x`` is a state: it does not depend directly on the input (declared in
``OUTPUT_DEPENDENCIES``, patched into ModelStructure by ``build.py``). If the step
would pass ``t_fail`` the FMU refuses it with fmi2Discard and a log message; past
``t_raise`` the Python code raises (pythonfmu turns that into an FMI error). Both let
the tests exercise the master's failure handling.
"""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Status

#: output name -> input names it depends on directly (ModelStructure/Outputs)
OUTPUT_DEPENDENCIES = {"x": []}


class MstIntegrator(Fmi2Slave):
    author = "drillstring tests"
    description = "x' = k*u with x(0) = x0; refuses steps beyond t_fail"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x0 = 0.0
        self.k = 1.0
        self.t_fail = 1.0e300
        self.t_raise = 1.0e300
        self.u = 0.0
        self.x = 0.0
        par = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
        self.register_variable(Real("x0", description="initial state", **par))
        self.register_variable(Real("k", description="gain", **par))
        self.register_variable(Real("t_fail", description="refuse steps past this", **par))
        self.register_variable(Real("t_raise", description="raise in steps past this", **par))
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("x", causality=Fmi2Causality.output))

    def enter_initialization_mode(self):
        self.x = self.x0

    def do_step(self, current_time, step_size):
        if current_time + step_size > self.t_raise:
            raise RuntimeError(f"integrator blew up at t={current_time!r}")
        if current_time + step_size > self.t_fail:
            self.log(
                f"refusing step from t={current_time!r} by h={step_size!r}: "
                f"t_fail={self.t_fail!r} would be passed",
                Fmi2Status.discard,
            )
            return False
        self.x += self.k * self.u * step_size
        return True
