"""A cart-pole (the classic under-actuated plant) for the benchmark suite, pythonfmu only.

Build: ``python -m pythonfmu build -f benchmarks/suite/plants/cartpole.py -d DIR``.

State: cart position x [m] and speed xdot [m/s], pole angle theta [rad] from upright (positive
clockwise, as in Barto, Sutton & Anderson 1983) and its rate thetadot [rad/s].  Input: the force
F [N] on the cart, clipped to [-F_max, F_max] and held over the communication step.  Equations
(Barto et al. 1983, frictionless; l is the pole's half-length):

    thetaddot = (g sin th - cos th (F + m_p l thd^2 sin th) / M) / (l (4/3 - m_p cos^2 th / M))
    xddot     = (F + m_p l thd^2 sin th) / M - m_p l thetaddot cos th / M,      M = m_c + m_p

Integrated by RK4 with ``n_sub`` sub-steps per communication step, together with

    J        = integral(x^2 + 0.1 xdot^2 + 10 theta^2 + 0.1 thetadot^2 + 0.01 F^2) dt
    tilt_max = max |theta| over the sub-steps so far (the pole has fallen past 90 deg = pi/2)
"""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial


class CartPole(Fmi2Slave):

    author = "descent-fmus benchmark suite"
    description = "Cart-pole with its running quadratic cost and peak tilt (suite: cartpole)"

    PARAMETERS = (("x0", 0.0, "initial cart position [m]"), ("xdot0", 0.0, "initial cart speed"),
                  ("theta0", 0.0, "initial pole angle [rad]"),
                  ("thetadot0", 0.0, "initial pole rate [rad/s]"),
                  ("m_c", 1.0, "cart mass [kg]"), ("m_p", 0.1, "pole mass [kg]"),
                  ("l", 0.5, "pole half-length [m]"), ("g", 9.81, "gravity [m/s2]"),
                  ("F_max", 30.0, "force bound [N]"),
                  ("w_x", 1.0, "cost weight of x^2"), ("w_xdot", 0.1, "cost weight of xdot^2"),
                  ("w_theta", 10.0, "cost weight of theta^2"),
                  ("w_thetadot", 0.1, "cost weight of thetadot^2"),
                  ("w_F", 0.01, "cost weight of F^2"),
                  ("n_sub", 4.0, "RK4 sub-steps per communication step"))

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, value, desc in self.PARAMETERS:
            setattr(self, name, value)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed, description=desc))
        self.F = 0.0
        self.register_variable(Real("F", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous,
                                    description="force on the cart [N], held over the step"))
        self._start()
        for name, desc in (("x", "cart position [m]"), ("xdot", "cart speed [m/s]"),
                           ("theta", "pole angle from upright [rad]"),
                           ("thetadot", "pole rate [rad/s]"), ("J", "running cost so far"),
                           ("tilt_max", "max |theta| so far [rad]")):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        initial=Fmi2Initial.exact, description=desc))

    def _start(self):
        self.x, self.xdot, self.theta, self.thetadot = (self.x0, self.xdot0, self.theta0,
                                                        self.thetadot0)
        self.J, self.tilt_max = 0.0, abs(self.theta0)

    def exit_initialization_mode(self):
        self._start()

    def do_step(self, current_time, step_size):
        F = min(max(self.F, -self.F_max), self.F_max)
        if F != F:                   # NaN: no force
            F = 0.0
        n = max(1, int(self.n_sub + 0.5))
        h = step_size / n
        mp, l, g = self.m_p, self.l, self.g
        M = self.m_c + mp
        mpl, c43 = mp * l, 4.0 / 3.0
        wx, wxd, wth, wthd = self.w_x, self.w_xdot, self.w_theta, self.w_thetadot
        cF = self.w_F * F * F
        sin, cos = math.sin, math.cos

        def rhs(x, xd, th, thd):
            st, ct = sin(th), cos(th)
            tmp = (F + mpl * thd * thd * st) / M
            thdd = (g * st - ct * tmp) / (l * (c43 - mp * ct * ct / M))
            return (xd, tmp - mpl * thdd * ct / M, thd, thdd,
                    wx * x * x + wxd * xd * xd + wth * th * th + wthd * thd * thd + cF)

        x, xd, th, thd, J = self.x, self.xdot, self.theta, self.thetadot, self.J
        tilt = self.tilt_max
        for _ in range(n):
            a1, b1, c1, d1, e1 = rhs(x, xd, th, thd)
            hh = 0.5 * h
            a2, b2, c2, d2, e2 = rhs(x + hh * a1, xd + hh * b1, th + hh * c1, thd + hh * d1)
            a3, b3, c3, d3, e3 = rhs(x + hh * a2, xd + hh * b2, th + hh * c2, thd + hh * d2)
            a4, b4, c4, d4, e4 = rhs(x + h * a3, xd + h * b3, th + h * c3, thd + h * d3)
            h6 = h / 6.0
            x += h6 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            xd += h6 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
            th += h6 * (c1 + 2.0 * c2 + 2.0 * c3 + c4)
            thd += h6 * (d1 + 2.0 * d2 + 2.0 * d3 + d4)
            J += h6 * (e1 + 2.0 * e2 + 2.0 * e3 + e4)
            if abs(th) > tilt:
                tilt = abs(th)
        self.x, self.xdot, self.theta, self.thetadot, self.J = x, xd, th, thd, J
        self.tilt_max = tilt
        return True
