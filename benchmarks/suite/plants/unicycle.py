"""A unicycle (kinematic car) to be parked, for the benchmark suite; pythonfmu only.

Build: ``python -m pythonfmu build -f benchmarks/suite/plants/unicycle.py -d DIR``.

State: position x, y [m] and heading theta [rad] (reported wrapped to (-pi, pi]).  Inputs:
speed v [m/s] and turn rate omega [rad/s], clipped to [-v_max, v_max], [-omega_max, omega_max]
and held over the communication step, so each step is an exact arc (a straight line when
omega = 0):

    dx/dt = v cos theta,   dy/dt = v sin theta,   dtheta/dt = omega

The target is the origin with heading 0.  Besides the Cartesian state the plant outputs the polar
coordinates of Aicardi et al. (1995): rho = |(x, y)|, phi = the direction from the vehicle to the
target, atan2(-y, -x), and alpha = phi - theta (both wrapped to (-pi, pi]; phi = 0 at rho = 0),
so that a problem can give a law either set of inputs.
"""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial

TWO_PI = 2.0 * math.pi


def wrap(a):
    """The angle ``a`` in (-pi, pi]."""
    a = math.fmod(a, TWO_PI)
    if a > math.pi:
        a -= TWO_PI
    elif a <= -math.pi:
        a += TWO_PI
    return a


class Unicycle(Fmi2Slave):

    author = "descent-fmus benchmark suite"
    description = "Unicycle to park at the origin with heading 0 (suite: parking)"

    PARAMETERS = (("x0", -2.0, "initial x [m]"), ("y0", 0.0, "initial y [m]"),
                  ("theta0", 0.0, "initial heading [rad]"), ("v_max", 1.0, "speed bound [m/s]"),
                  ("omega_max", 3.0, "turn-rate bound [rad/s]"))

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, value, desc in self.PARAMETERS:
            setattr(self, name, value)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed, description=desc))
        self.v, self.omega = 0.0, 0.0
        for name, desc in (("v", "speed [m/s], held over the step"),
                           ("omega", "turn rate [rad/s], held over the step")):
            self.register_variable(Real(name, causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description=desc))
        self._th = 0.0
        self._start()
        for name, desc in (("x", "position x [m]"), ("y", "position y [m]"),
                           ("theta", "heading in (-pi, pi] [rad]"),
                           ("rho", "distance to the target [m]"),
                           ("phi", "direction from the vehicle to the target [rad]"),
                           ("alpha", "phi - theta in (-pi, pi] [rad]")):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        initial=Fmi2Initial.exact, description=desc))

    def _publish(self):
        self.theta = wrap(self._th)
        self.rho = math.hypot(self.x, self.y)
        self.phi = math.atan2(-self.y, -self.x) if self.rho > 0.0 else 0.0
        self.alpha = wrap(self.phi - self.theta)

    def _start(self):
        self.x, self.y, self._th = self.x0, self.y0, self.theta0
        self._publish()

    def exit_initialization_mode(self):
        self._start()

    def do_step(self, current_time, step_size):
        v = min(max(self.v, -self.v_max), self.v_max)
        w = min(max(self.omega, -self.omega_max), self.omega_max)
        if v != v:                      # NaN: stand still
            v = 0.0
        if w != w:
            w = 0.0
        th, h = self._th, step_size
        if abs(w) * h > 1e-9:           # an exact arc
            th1 = th + w * h
            self.x += v / w * (math.sin(th1) - math.sin(th))
            self.y -= v / w * (math.cos(th1) - math.cos(th))
        else:                           # a straight line (the arc's limit, to O(w h))
            th1 = th + w * h
            thm = th + 0.5 * w * h
            self.x += v * h * math.cos(thm)
            self.y += v * h * math.sin(thm)
        self._th = wrap(th1)
        self._publish()
        return True
