"""A double integrator driven to the origin in minimum time (bang-bang optimum); pythonfmu only.

Build: ``python -m pythonfmu build -f benchmarks/search/plants/double_integrator.py -d DIR``.

    dx/dt = v,   dv/dt = u,   |u| <= 1   (u held over the communication step: exact update)

Outputs x, v and r = |(x, v)| (the distance to the origin in the phase plane: a problem file
stops the flight when r falls below a small value).  The time-optimal feedback is
u = -sgn(x + v |v| / 2) (Pontryagin; e.g. Bryson & Ho, Applied Optimal Control, sec. 7.2).
"""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial


class DoubleIntegrator(Fmi2Slave):

    author = "descent-fmus search benchmarks"
    description = "Double integrator, |u| <= 1, to be brought to the origin in minimum time"

    PARAMETERS = (("x0", 1.0, "initial position"), ("v0", 0.0, "initial speed"),
                  ("u_max", 1.0, "control bound"))

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, value, desc in self.PARAMETERS:
            setattr(self, name, value)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed, description=desc))
        self.u = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous,
                                    description="control, held over the step"))
        self.x, self.v, self.r = self.x0, self.v0, 0.0
        for name, desc in (("x", "position"), ("v", "speed"),
                           ("r", "distance to the origin in the phase plane")):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        initial=Fmi2Initial.exact, description=desc))
        self._publish()

    def _publish(self):
        self.r = math.hypot(self.x, self.v)

    def exit_initialization_mode(self):
        self.x, self.v = self.x0, self.v0
        self._publish()

    def do_step(self, current_time, step_size):
        u = self.u if self.u == self.u else 0.0
        u = min(max(u, -self.u_max), self.u_max)
        h = step_size
        self.x += self.v * h + 0.5 * u * h * h
        self.v += u * h
        self._publish()
        return True
