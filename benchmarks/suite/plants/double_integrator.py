"""A double integrator with a bounded input, for the suite's minimum-time problem; pythonfmu only.

Build: ``python -m pythonfmu build -f benchmarks/suite/plants/double_integrator.py -d DIR``.

    dx1/dt = x2,   dx2/dt = u,   |u| <= u_max

The input is clipped to [-u_max, u_max] and held over the communication step, so each step is
exact (x1 += x2 h + u h^2 / 2, x2 += u h).  Besides the state the plant outputs ``tgo``, the
least time to bring the state to the origin with |u| <= u_max (the closed form of the
time-optimal problem, Pontryagin's bang-bang law with one switch on the curve
x1 = -x2 |x2| / (2 u_max)):

    tgo = (x2 + 2 sqrt(u_max x1 + x2^2 / 2)) / u_max     above the curve (u = -u_max first)
    tgo = (-x2 + 2 sqrt(-u_max x1 + x2^2 / 2)) / u_max   below it        (u = +u_max first)

A problem file uses it for its stop condition (the target set tgo <= tau) and its objective;
it is never an input of the law.
"""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial


def time_to_go(x1, x2, u_max):
    """The least time from (x1, x2) to the origin with |u| <= u_max."""
    s = u_max * x1 + 0.5 * x2 * abs(x2)          # > 0: above the switching curve
    if s > 0.0:
        return (x2 + 2.0 * math.sqrt(u_max * x1 + 0.5 * x2 * x2)) / u_max
    # on the curve both branches agree; max(): rounding there must not reach sqrt(< 0)
    return (-x2 + 2.0 * math.sqrt(max(-u_max * x1 + 0.5 * x2 * x2, 0.0))) / u_max


class DoubleIntegrator(Fmi2Slave):

    author = "descent-fmus benchmark suite"
    description = "Double integrator, |u| <= u_max, with its time to go (suite: mintime-di)"

    PARAMETERS = (("x10", 1.0, "initial x1"), ("x20", 0.0, "initial x2"),
                  ("u_max", 1.0, "input bound"))

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, value, desc in self.PARAMETERS:
            setattr(self, name, value)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed, description=desc))
        self.u = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous,
                                    description="control, clipped to +-u_max, held over the step"))
        self._start()
        for name, desc in (("x1", "position"), ("x2", "velocity"),
                           ("tgo", "least time to the origin with |u| <= u_max")):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        initial=Fmi2Initial.exact, description=desc))

    def _start(self):
        self.x1, self.x2 = self.x10, self.x20
        self.tgo = time_to_go(self.x1, self.x2, self.u_max)

    def exit_initialization_mode(self):
        self._start()

    def do_step(self, current_time, step_size):
        u = self.u
        u = 0.0 if u != u else min(max(u, -self.u_max), self.u_max)     # NaN: no thrust
        h = step_size
        self.x1 += self.x2 * h + 0.5 * u * h * h
        self.x2 += u * h
        self.tgo = time_to_go(self.x1, self.x2, self.u_max)
        return True
