"""A linear plant with a quadratic cost: the suite's problem with a known optimum.

Written once in the package's model style; ``descent-fmus build-plant
benchmarks/suite/plants/lq.py -d DIR`` builds its pythonfmu FMU and its native C twin (the
suite's runner does, into ``build/``).

    dx1/dt = x2
    dx2/dt = a21 x1 + a22 x2 + b u          (a21 = 1 > 0: unstable open loop)
    dJ/dt  = q1 x1^2 + q2 x2^2 + r u^2      (the running cost, integrated with the state)

The input ``u`` is held over each communication step (clipped to [-u_max, u_max]: wide, never
reached by the laws of the suite).  The state and the cost are integrated together by RK4 with
``n_sub`` sub-steps per communication step (default 8 over the 0.1 s step: the cost of a flight
agrees with its exact value to ~1e-9 relative), so ``final(J)`` is the continuous cost of the
sampled-data (zero-order-hold) flight.  A flight whose state overflows ends with status 3, the
state frozen at its last finite value.
"""
import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import DIVERGED, LEFT_DOMAIN, Integrator, advance_to
from descent_fmus.models.params import ParameterError, Params, param
from descent_fmus.models.traceable import clip


@dataclass(frozen=True)
class LQParams(Params):
    x10: float = param(1.0, "1", "initial x1")
    x20: float = param(0.0, "1", "initial x2")
    a21: float = param(1.0, "1", "A[2,1]")
    a22: float = param(-0.5, "1", "A[2,2]")
    b: float = param(1.0, "1", "B[2]")
    q1: float = param(1.0, "1", "cost weight of x1^2")
    q2: float = param(0.1, "1", "cost weight of x2^2")
    r: float = param(0.1, "1", "cost weight of u^2")
    u_max: float = param(1000.0, "1", "input bound", nonnegative=True)
    n_sub: float = param(8.0, "1", "RK4 sub-steps per communication step")

    def check(self) -> None:
        if self.n_sub < 1.0 or self.n_sub != math.floor(self.n_sub):
            raise ParameterError(f"parameter n_sub must be a whole number >= 1, got "
                                 f"{self.n_sub!r}")


def rhs(x, bu, ru2, a21, a22, q1, q2):
    """(x1, x2, J)' with the input's terms b u and r u^2 held over the step."""
    x1, x2, _ = x
    return (x2, a21 * x1 + a22 * x2 + bu, q1 * x1 * x1 + q2 * x2 * x2 + ru2)


class LQIntegrator(Integrator):
    """``n_sub`` RK4 sub-steps per communication step, on (x1, x2, J)."""

    def __init__(self, p: LQParams):
        self.p = p.validate()
        super().__init__(None)

    def initial_state(self) -> tuple:
        return (self.p.x10, self.p.x20, 0.0)

    def advance(self, t_end: float, u: float) -> None:
        if self.status:
            return
        p = self.p
        x, t, outcome = advance_to(rhs, self.x, self.t, t_end, (t_end - self.t) / p.n_sub,
                                   (p.b * u, p.r * u * u, p.a21, p.a22, p.q1, p.q2))
        self.x, self.t = x, t
        if outcome == DIVERGED:
            self.end(LEFT_DOMAIN, t)


class LQPlant(SlaveBase):

    author = "descent-fmus benchmark suite"
    description = "Unstable 2-state linear plant with its running quadratic cost (suite: lq)"
    params_class = LQParams

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self.input("u", 0.0, "control, held over the step")
        ig = lambda: self._ig  # noqa: E731
        self.output("x1", "state 1", getter=lambda: ig().x[0])
        self.output("x2", "state 2", getter=lambda: ig().x[1])
        self.output("J", "running cost integral(q1 x1^2 + q2 x2^2 + r u^2) so far",
                    getter=lambda: ig().x[2])
        self.status_outputs(lambda: ig().status, lambda: ig().t_end_output)
        self.prepare()

    def prepare(self) -> None:
        self._ig = LQIntegrator(self.params())

    def do_step(self, current_time: float, step_size: float) -> bool:
        self._ig.advance(current_time + step_size, clip(self.u, -self.u_max, self.u_max))
        return True
