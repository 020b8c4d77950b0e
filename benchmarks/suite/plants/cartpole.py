"""A cart-pole (the classic under-actuated plant) for the benchmark suite.

Written once in the package's model style; ``descent-fmus build-plant
benchmarks/suite/plants/cartpole.py -d DIR`` builds its pythonfmu FMU and its native C twin.

State: cart position x [m] and speed xdot [m/s], pole angle theta [rad] from upright (positive
clockwise, as in Barto, Sutton & Anderson 1983) and its rate thetadot [rad/s].  Input: the force
F [N] on the cart, clipped to [-F_max, F_max] (NaN: 0) and held over the communication step.
Equations (Barto et al. 1983, frictionless; l is the pole's half-length):

    thetaddot = (g sin th - cos th (F + m_p l thd^2 sin th) / M) / (l (4/3 - m_p cos^2 th / M))
    xddot     = (F + m_p l thd^2 sin th) / M - m_p l thetaddot cos th / M,      M = m_c + m_p

Integrated by RK4 with ``n_sub`` sub-steps per communication step, together with

    J        = integral(x^2 + 0.1 xdot^2 + 10 theta^2 + 0.1 thetadot^2 + 0.01 F^2) dt
    tilt_max = max |theta| over the sub-steps so far (the pole has fallen past 90 deg = pi/2)
"""
import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import DIVERGED, LEFT_DOMAIN, Integrator, advance_to
from descent_fmus.models.params import ParameterError, Params, param
from descent_fmus.models.traceable import clip, maximum, where


@dataclass(frozen=True)
class CartPoleParams(Params):
    x0: float = param(0.0, "m", "initial cart position")
    xdot0: float = param(0.0, "m/s", "initial cart speed")
    theta0: float = param(0.0, "rad", "initial pole angle")
    thetadot0: float = param(0.0, "rad/s", "initial pole rate")
    m_c: float = param(1.0, "kg", "cart mass", positive=True)
    m_p: float = param(0.1, "kg", "pole mass", positive=True)
    l: float = param(0.5, "m", "pole half-length", positive=True)  # noqa: E741
    g: float = param(9.81, "m/s2", "gravity")
    F_max: float = param(30.0, "N", "force bound", nonnegative=True)
    w_x: float = param(1.0, "1", "cost weight of x^2")
    w_xdot: float = param(0.1, "1", "cost weight of xdot^2")
    w_theta: float = param(10.0, "1", "cost weight of theta^2")
    w_thetadot: float = param(0.1, "1", "cost weight of thetadot^2")
    w_F: float = param(0.01, "1", "cost weight of F^2")
    n_sub: float = param(4.0, "1", "RK4 sub-steps per communication step")

    def check(self) -> None:
        if self.n_sub < 1.0 or self.n_sub != math.floor(self.n_sub):
            raise ParameterError(f"parameter n_sub must be a whole number >= 1, got "
                                 f"{self.n_sub!r}")


def rhs(s, F, cF, mp, l, g, M, mpl, wx, wxd, wth, wthd):  # noqa: E741
    """(x, xdot, theta, thetadot, J)' under the force F held over the step (cF = w_F F^2)."""
    x, xd, th, thd, _ = s
    st, ct = math.sin(th), math.cos(th)
    tmp = (F + mpl * thd * thd * st) / M
    thdd = (g * st - ct * tmp) / (l * (4.0 / 3.0 - mp * ct * ct / M))
    return (xd, tmp - mpl * thdd * ct / M, thd, thdd,
            wx * x * x + wxd * xd * xd + wth * th * th + wthd * thd * thd + cF)


class CartPoleIntegrator(Integrator):
    """``n_sub`` RK4 sub-steps per communication step; ``tilt_max`` sampled at every one."""

    def __init__(self, p: CartPoleParams):
        self.p = p.validate()
        super().__init__(None)

    def initial_state(self) -> tuple:
        p = self.p
        return (p.x0, p.xdot0, p.theta0, p.thetadot0, 0.0)

    def reset(self) -> None:
        super().reset()
        self.tilt_max = abs(self.p.theta0)

    def _sample(self, x, k1=None) -> None:
        self.tilt_max = maximum(self.tilt_max, abs(x[2]))

    def advance(self, t_end: float, F: float) -> None:
        if self.status:
            return
        p = self.p
        mp = p.m_p
        args = (F, p.w_F * F * F, mp, p.l, p.g, p.m_c + mp, mp * p.l, p.w_x, p.w_xdot,
                p.w_theta, p.w_thetadot)
        x, t, outcome = advance_to(rhs, self.x, self.t, t_end, (t_end - self.t) / p.n_sub,
                                   args, on_step=self._sample)
        self.x, self.t = x, t
        self._sample(x)
        if outcome == DIVERGED:
            self.end(LEFT_DOMAIN, t)


class CartPole(SlaveBase):

    author = "descent-fmus benchmark suite"
    description = "Cart-pole with its running quadratic cost and peak tilt (suite: cartpole)"
    params_class = CartPoleParams

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self.input("F", 0.0, "force on the cart [N], held over the step")
        ig = lambda: self._ig  # noqa: E731
        for k, (name, desc) in enumerate((("x", "cart position [m]"),
                                          ("xdot", "cart speed [m/s]"),
                                          ("theta", "pole angle from upright [rad]"),
                                          ("thetadot", "pole rate [rad/s]"),
                                          ("J", "running cost so far"))):
            self.output(name, desc, getter=lambda k=k: ig().x[k])
        self.output("tilt_max", "max |theta| so far [rad]", getter=lambda: ig().tilt_max)
        self.status_outputs(lambda: ig().status, lambda: ig().t_end_output)
        self.prepare()

    def prepare(self) -> None:
        self._ig = CartPoleIntegrator(self.params())

    def do_step(self, current_time: float, step_size: float) -> bool:
        F = clip(self.F, -self.F_max, self.F_max)
        self._ig.advance(current_time + step_size, where(F != F, 0.0, F))
        return True
