"""Test FMU: mass on a wall spring, coupled to a neighbour by a spring-damper.

    m x'' = -k x - kc (x - x_in) - dc (v - v_in) + F_ext

Outputs: the states x, v (no direct feedthrough) and the coupling force that the
spring-damper exerts on the neighbour, F_c = kc (x - x_in) + dc (v - v_in), which
depends directly on the inputs x_in, v_in. With the inputs held over a step the ODE is
linear with constant forcing, so ``do_step`` is exact (2x2 matrix exponential by
Cayley-Hamilton): the only error left in a co-simulation of two of these is the
coupling error, which is what the master's tests measure.
"""

import cmath
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

#: output name -> input names it depends on directly (ModelStructure/Outputs)
OUTPUT_DEPENDENCIES = {"x": [], "v": [], "F_c": ["x_in", "v_in"]}


class MstOscillator(Fmi2Slave):
    author = "drillstring tests"
    description = "m x'' = -k x - kc (x - x_in) - dc (v - v_in) + F_ext, exact steps"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.m = 1.0
        self.k = 1.0
        self.kc = 0.0
        self.dc = 0.0
        self.x0 = 0.0
        self.v0 = 0.0
        self.F_ext = 0.0
        self.x_in = 0.0
        self.v_in = 0.0
        self.x = 0.0
        self.v = 0.0
        par = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
        for name in ("m", "k", "kc", "dc", "x0", "v0"):
            self.register_variable(Real(name, **par))
        for name in ("F_ext", "x_in", "v_in"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        self.register_variable(Real("x", causality=Fmi2Causality.output))
        self.register_variable(Real("v", causality=Fmi2Causality.output))
        self.register_variable(
            Real(
                "F_c",
                causality=Fmi2Causality.output,
                getter=lambda: self.kc * (self.x - self.x_in) + self.dc * (self.v - self.v_in),
            )
        )

    def enter_initialization_mode(self):
        self.x = self.x0
        self.v = self.v0

    def do_step(self, current_time, step_size):
        h = step_size
        w2 = (self.k + self.kc) / self.m
        c = self.dc / self.m
        x_eq = (self.F_ext + self.kc * self.x_in + self.dc * self.v_in) / (self.k + self.kc)
        s = -0.5 * c
        q = cmath.sqrt(s * s - w2)
        ch = cmath.cosh(q * h).real
        shq = h if q == 0 else (cmath.sinh(q * h) / q).real
        es = math.exp(s * h)
        dx = self.x - x_eq
        dv = self.v
        self.x = x_eq + es * (ch * dx + shq * (0.5 * c * dx + dv))
        self.v = es * (ch * dv + shq * (-w2 * dx - 0.5 * c * dv))
        return True
