"""A double integrator with a bounded input, for the suite's minimum-time problem.

Written once in the package's model style; ``descent-fmus build-plant
benchmarks/suite/plants/double_integrator.py -d DIR`` builds its pythonfmu FMU and its native C
twin.

    dx1/dt = x2,   dx2/dt = u,   |u| <= u_max

The input is clipped to [-u_max, u_max] (NaN: 0) and held over the communication step, so each
step is exact (x1 += x2 h + u h^2 / 2, x2 += u h).  Besides the state the plant outputs ``tgo``,
the least time to bring the state to the origin with |u| <= u_max (the closed form of the
time-optimal problem, Pontryagin's bang-bang law with one switch on the curve
x1 = -x2 |x2| / (2 u_max)):

    tgo = (x2 + 2 sqrt(u_max x1 + x2^2 / 2)) / u_max     above the curve (u = -u_max first)
    tgo = (-x2 + 2 sqrt(-u_max x1 + x2^2 / 2)) / u_max   below it        (u = +u_max first)

A problem file uses it for its stop condition (the target set tgo <= tau) and its objective;
it is never an input of the law.
"""
import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import Integrator
from descent_fmus.models.params import Params, param
from descent_fmus.models.traceable import clip, maximum, where


def time_to_go(x1, x2, u_max):
    """The least time from (x1, x2) to the origin with |u| <= u_max."""
    s = u_max * x1 + 0.5 * x2 * abs(x2)          # > 0: above the switching curve
    # on the curve both branches agree; max(): rounding there must not reach sqrt(< 0)
    return where(s > 0.0, lambda: (x2 + 2.0 * math.sqrt(u_max * x1 + 0.5 * x2 * x2)) / u_max,
                 lambda: (-x2 + 2.0 * math.sqrt(maximum(-u_max * x1 + 0.5 * x2 * x2, 0.0)))
                 / u_max)


@dataclass(frozen=True)
class DoubleIntegratorParams(Params):
    x10: float = param(1.0, "1", "initial x1")
    x20: float = param(0.0, "1", "initial x2")
    u_max: float = param(1.0, "1", "input bound", positive=True)


class DoubleIntegratorStep(Integrator):
    """One exact step per communication step (no sub-steps)."""

    def __init__(self, p: DoubleIntegratorParams):
        self.p = p.validate()
        super().__init__(None)

    def initial_state(self) -> tuple:
        return (self.p.x10, self.p.x20)

    def advance(self, t_end: float, h: float, u: float) -> None:
        """The step of ``h`` [s] ending at ``t_end`` [s] under ``u``, held."""
        x1, x2 = self.x
        self.x, self.t = (x1 + (x2 * h + 0.5 * u * h * h), x2 + u * h), t_end


class DoubleIntegrator(SlaveBase):

    author = "descent-fmus benchmark suite"
    description = "Double integrator, |u| <= u_max, with its time to go (suite: mintime-di)"
    params_class = DoubleIntegratorParams

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self.input("u", 0.0, "control, clipped to +-u_max, held over the step")
        for name, desc in (("x1", "position"), ("x2", "velocity"),
                           ("tgo", "least time to the origin with |u| <= u_max")):
            self.output(name, desc)
        self.status_outputs(lambda: self._ig.status, lambda: self._ig.t_end_output)
        self.prepare()

    def prepare(self) -> None:
        self._ig = DoubleIntegratorStep(self.params())
        self._publish()

    def _publish(self) -> None:
        self.x1, self.x2 = self._ig.x
        self.tgo = time_to_go(self.x1, self.x2, self.u_max)

    def do_step(self, current_time: float, step_size: float) -> bool:
        u = self.u
        u = where(u != u, 0.0, lambda: clip(u, -self.u_max, self.u_max))     # NaN: no thrust
        self._ig.advance(current_time + step_size, step_size, u)
        self._publish()
        return True
