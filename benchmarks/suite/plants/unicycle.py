"""A unicycle (kinematic car) to be parked, for the benchmark suite.

Written once in the package's model style; ``descent-fmus build-plant
benchmarks/suite/plants/unicycle.py -d DIR`` builds its pythonfmu FMU and its native C twin.

State: position x, y [m] and heading theta [rad] (kept wrapped to (-pi, pi]).  Inputs: speed
v [m/s] and turn rate omega [rad/s], clipped to [-v_max, v_max], [-omega_max, omega_max] (NaN:
0) and held over the communication step, so each step is an exact arc (a straight line when
omega = 0):

    dx/dt = v cos theta,   dy/dt = v sin theta,   dtheta/dt = omega

The target is the origin with heading 0.  Besides the Cartesian state the plant outputs the polar
coordinates of Aicardi et al. (1995): rho = |(x, y)|, phi = the direction from the vehicle to the
target, atan2(-y, -x), and alpha = phi - theta (both wrapped to (-pi, pi]; phi = 0 at rho = 0),
so that a problem can give a law either set of inputs.
"""
import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import Integrator
from descent_fmus.models.params import Params, param
from descent_fmus.models.traceable import clip, where

TWO_PI = 2.0 * math.pi


def wrap(a):
    """The angle ``a`` in (-pi, pi]."""
    a = math.fmod(a, TWO_PI)
    return where(a > math.pi, lambda: a - TWO_PI,
                 lambda: where(a <= -math.pi, lambda: a + TWO_PI, a))


@dataclass(frozen=True)
class UnicycleParams(Params):
    x0: float = param(-2.0, "m", "initial x")
    y0: float = param(0.0, "m", "initial y")
    theta0: float = param(0.0, "rad", "initial heading")
    v_max: float = param(1.0, "m/s", "speed bound", nonnegative=True)
    omega_max: float = param(3.0, "rad/s", "turn-rate bound", nonnegative=True)


def arc(x, v, w, h):
    """The state (x, y, theta) after ``h`` [s] at speed ``v`` and turn rate ``w``, held: an
    exact arc, or a straight line where |w| h <= 1e-9 (the arc's limit, to O(w h))."""
    px, py, th = x
    th1 = th + w * h
    if abs(w) * h > 1e-9:
        return (px + v / w * (math.sin(th1) - math.sin(th)),
                py - v / w * (math.cos(th1) - math.cos(th)), wrap(th1))
    thm = th + 0.5 * w * h
    return (px + v * h * math.cos(thm), py + v * h * math.sin(thm), wrap(th1))


class UnicycleIntegrator(Integrator):
    """One exact arc per communication step (no sub-steps)."""

    def __init__(self, p: UnicycleParams):
        self.p = p.validate()
        super().__init__(None)

    def initial_state(self) -> tuple:
        return (self.p.x0, self.p.y0, self.p.theta0)

    def advance(self, t_end: float, h: float, v: float, w: float) -> None:
        """The step of ``h`` [s] ending at ``t_end`` [s]."""
        self.x, self.t = arc(self.x, v, w, h), t_end


class Unicycle(SlaveBase):

    author = "descent-fmus benchmark suite"
    description = "Unicycle to park at the origin with heading 0 (suite: parking)"
    params_class = UnicycleParams

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self.input("v", 0.0, "speed [m/s], held over the step")
        self.input("omega", 0.0, "turn rate [rad/s], held over the step")
        for name, desc in (("x", "position x [m]"), ("y", "position y [m]"),
                           ("theta", "heading in (-pi, pi] [rad]"),
                           ("rho", "distance to the target [m]"),
                           ("phi", "direction from the vehicle to the target [rad]"),
                           ("alpha", "phi - theta in (-pi, pi] [rad]")):
            self.output(name, desc)
        self.status_outputs(lambda: self._ig.status, lambda: self._ig.t_end_output)
        self.prepare()

    def prepare(self) -> None:
        self._ig = UnicycleIntegrator(self.params())
        self._publish()

    def _publish(self) -> None:
        x, y, th = self._ig.x
        self.x, self.y, self.theta = x, y, wrap(th)
        self.rho = math.hypot(x, y)
        self.phi = where(self.rho > 0.0, lambda: math.atan2(-y, -x), 0.0)
        self.alpha = wrap(self.phi - self.theta)

    def do_step(self, current_time: float, step_size: float) -> bool:
        v = clip(self.v, -self.v_max, self.v_max)
        w = clip(self.omega, -self.omega_max, self.omega_max)
        self._ig.advance(current_time + step_size, step_size, where(v != v, 0.0, v),
                         where(w != w, 0.0, w))
        self._publish()
        return True
