"""A plant of your own: a vertical hopper near the lunar surface (the tutorial's plant).

Written once in descent-fmus's model style -- the parameters as a dataclass, the right-hand side
as a plain function, an integrator, the FMU class -- so that one command gives both its
pythonfmu FMU and its native C twin, checked against each other bit for bit:

    descent-fmus build-plant docs/tutorials/hopper.py      # Hopper.fmu + native/Hopper.fmu here

State: altitude h [m], vertical speed v [m/s] (up positive), mass m [kg].  Input: throttle in
[0, 1] of the engine's maximum thrust F_max [N]; the exhaust speed c [m/s] sets the mass flow.

    dh/dt = v,   dv/dt = throttle F_max / m - g,   dm/dt = -throttle F_max / c

Integrated by RK4 on sub-steps of at most dt; touchdown (h = 0) is located inside the sub-step,
and the state freezes there (status 1).
"""
import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import (DIVERGED, EVENT, LEFT_DOMAIN, REACHED, Integrator,
                                             advance_to)
from descent_fmus.models.params import Params, param
from descent_fmus.models.traceable import clip, where


@dataclass(frozen=True)
class HopperParams(Params):
    """The hopper's parameters: default, unit and description, written once."""

    h0: float = param(10.0, "m", "initial altitude")
    v0: float = param(0.0, "m/s", "initial speed, up")
    m0: float = param(100.0, "kg", "initial mass", positive=True)
    g: float = param(1.62, "m/s2", "gravity", positive=True)
    F_max: float = param(500.0, "N", "maximum thrust", nonnegative=True)
    c: float = param(2000.0, "m/s", "exhaust speed", positive=True)


def rhs(x, u, F_max, g, c):
    """The hopper's right-hand side: x = (h, v, m), throttle u in [0, 1]."""
    h, v, m = x
    return (v, u * F_max / m - g, -u * F_max / c)


class HopperIntegrator(Integrator):
    """RK4 sub-steps of at most ``dt``; touchdown located in the sub-step (h = 0, REACHED)."""

    def __init__(self, p: HopperParams, dt: float):
        self.p = p.validate()
        super().__init__(dt)

    def initial_state(self) -> tuple:
        return (self.p.h0, self.p.v0, self.p.m0)

    def reset(self) -> None:
        super().reset()
        if self.p.h0 <= 0.0:                     # on the ground from the start
            self.end(REACHED, 0.0)

    def advance(self, t_end: float, u: float) -> None:
        """Integrate to ``t_end`` [s] with the throttle held at ``u`` (clipped to [0, 1])."""
        if self.status:
            return
        p = self.p
        x, t, outcome = advance_to(rhs, self.x, self.t, t_end, self.dt, (u, p.F_max, p.g, p.c),
                                   event=lambda y: y[0])
        self.x, self.t = x, t
        if outcome == EVENT:
            self.x = (0.0, x[1], x[2])           # on the ground
            self.end(REACHED, t)
        elif outcome == DIVERGED:
            self.end(LEFT_DOMAIN, t)


class Hopper(SlaveBase):
    """The hopper as an FMU: input ``throttle``; outputs h, v, m, fuel, ``status``, ``t_end``."""

    author = "a descent-fmus user"
    description = "Vertical hopper near the lunar surface (tutorial plant)"
    params_class = HopperParams

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()                        # h0, v0, m0, g, F_max, c from HopperParams
        self.parameter("dt", 0.01, "RK4 sub-step [s]")
        self.input("throttle", 0.0, "throttle, clipped to [0, 1] (NaN: 0) [1]")
        ig = lambda: self._ig  # noqa: E731
        self.output("h", "altitude [m]", getter=lambda: ig().x[0])
        self.output("v", "vertical speed, up [m/s]", getter=lambda: ig().x[1])
        self.output("m", "mass [kg]", getter=lambda: ig().x[2])
        self.output("fuel", "propellant used m0 - m [kg]", getter=lambda: ig().p.m0 - ig().x[2])
        self.status_outputs(lambda: ig().status, lambda: ig().t_end_output)
        self.prepare()

    def prepare(self) -> None:
        self._ig = HopperIntegrator(self.params(), self.dt)

    def do_step(self, current_time: float, step_size: float) -> bool:
        u = self.throttle
        u = where(math.isnan(u), 0.0, lambda: clip(u, 0.0, 1.0))
        self._ig.advance(current_time + step_size, u)
        return True
