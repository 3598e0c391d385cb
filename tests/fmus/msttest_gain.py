"""Test FMU: static gain y = k * u + b (direct feedthrough, no state)."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

#: output name -> input names it depends on directly (ModelStructure/Outputs)
OUTPUT_DEPENDENCIES = {"y": ["u"]}


class MstGain(Fmi2Slave):
    author = "drillstring tests"
    description = "y = k*u + b, evaluated whenever y is read"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.k = 1.0
        self.b = 0.0
        self.u = 0.0
        par = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
        self.register_variable(Real("k", description="gain", **par))
        self.register_variable(Real("b", description="offset", **par))
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(
            Real("y", causality=Fmi2Causality.output, getter=lambda: self.k * self.u + self.b)
        )

    def do_step(self, current_time, step_size):
        return True
