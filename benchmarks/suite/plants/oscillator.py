"""A harmonic oscillator with a bounded input, for the suite's second minimum-time problem;
pythonfmu only.

Build: ``python -m pythonfmu build -f benchmarks/suite/plants/oscillator.py -d DIR``.

    dx1/dt = x2,   dx2/dt = -x1 + u,   |u| <= u_max

The input is clipped to [-u_max, u_max] and held over the communication step, so each step is
exact: the state turns clockwise about (u, 0) by the angle h,

    x1 - u <- (x1 - u) cos h + x2 sin h,   x2 <- -(x1 - u) sin h + x2 cos h.

Besides the state the plant outputs ``r = max(|x1|, |x2|)``, the distance to the origin in the
maximum norm (a problem file's target box |x1|, |x2| <= eps is ``r <= eps``).
"""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial


class Oscillator(Fmi2Slave):

    author = "descent-fmus benchmark suite"
    description = "Harmonic oscillator x'' + x = u, |u| <= u_max (suite: mintime-osc)"

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
                           ("r", "max(|x1|, |x2|)")):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        initial=Fmi2Initial.exact, description=desc))

    def _publish(self):
        self.r = max(abs(self.x1), abs(self.x2))

    def _start(self):
        self.x1, self.x2 = self.x10, self.x20
        self._publish()

    def exit_initialization_mode(self):
        self._start()

    def do_step(self, current_time, step_size):
        u = self.u
        u = 0.0 if u != u else min(max(u, -self.u_max), self.u_max)     # NaN: no force
        c, s = math.cos(step_size), math.sin(step_size)
        z = self.x1 - u
        self.x1, self.x2 = u + z * c + self.x2 * s, -z * s + self.x2 * c
        self._publish()
        return True
