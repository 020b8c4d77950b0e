"""A harmonic oscillator with a bounded input, for the suite's second minimum-time problem.

Written once in the package's model style; ``descent-fmus build-plant
benchmarks/suite/plants/oscillator.py -d DIR`` builds its pythonfmu FMU and its native C twin.

    dx1/dt = x2,   dx2/dt = -x1 + u,   |u| <= u_max

The input is clipped to [-u_max, u_max] (NaN: 0) and held over the communication step, so each
step is exact: the state turns clockwise about (u, 0) by the angle h,

    x1 - u <- (x1 - u) cos h + x2 sin h,   x2 <- -(x1 - u) sin h + x2 cos h.

Besides the state the plant outputs ``r = max(|x1|, |x2|)``, the distance to the origin in the
maximum norm (a problem file's target box |x1|, |x2| <= eps is ``r <= eps``).
"""
import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import Integrator
from descent_fmus.models.params import Params, param
from descent_fmus.models.traceable import clip, maximum, where


@dataclass(frozen=True)
class OscillatorParams(Params):
    x10: float = param(1.0, "1", "initial x1")
    x20: float = param(0.0, "1", "initial x2")
    u_max: float = param(1.0, "1", "input bound", nonnegative=True)


class OscillatorStep(Integrator):
    """One exact step per communication step (no sub-steps)."""

    def __init__(self, p: OscillatorParams):
        self.p = p.validate()
        super().__init__(None)

    def initial_state(self) -> tuple:
        return (self.p.x10, self.p.x20)

    def advance(self, t_end: float, h: float, u: float) -> None:
        """The step of ``h`` [s] ending at ``t_end`` [s] under ``u``, held."""
        x1, x2 = self.x
        c, s = math.cos(h), math.sin(h)
        z = x1 - u
        self.x, self.t = (u + z * c + x2 * s, -z * s + x2 * c), t_end


class Oscillator(SlaveBase):

    author = "descent-fmus benchmark suite"
    description = "Harmonic oscillator x'' + x = u, |u| <= u_max (suite: mintime-osc)"
    params_class = OscillatorParams

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self.input("u", 0.0, "control, clipped to +-u_max, held over the step")
        for name, desc in (("x1", "position"), ("x2", "velocity"), ("r", "max(|x1|, |x2|)")):
            self.output(name, desc)
        self.status_outputs(lambda: self._ig.status, lambda: self._ig.t_end_output)
        self.prepare()

    def prepare(self) -> None:
        self._ig = OscillatorStep(self.params())
        self._publish()

    def _publish(self) -> None:
        self.x1, self.x2 = self._ig.x
        self.r = maximum(abs(self.x1), abs(self.x2))

    def do_step(self, current_time: float, step_size: float) -> bool:
        u = self.u
        u = where(u != u, 0.0, lambda: clip(u, -self.u_max, self.u_max))     # NaN: no force
        self._ig.advance(current_time + step_size, step_size, u)
        self._publish()
        return True
