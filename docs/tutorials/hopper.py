"""A plant FMU descent-fmus does not know: a vertical hopper near the lunar surface.

This is the "user's own plant" of the README tutorial; it uses only pythonfmu (no descent-fmus),
as a plant exported from another tool would.  Build it with

    pythonfmu build -f docs/tutorials/hopper.py -d docs/tutorials

State: altitude h [m], vertical speed v [m/s] (up positive), mass m [kg].  Input: throttle in
[0, 1] of the engine's maximum thrust F_max [N]; the exhaust speed c [m/s] sets the mass flow.

    dh/dt = v,   dv/dt = throttle F_max / m - g,   dm/dt = -throttle F_max / c

The state freezes once h <= 0 (touchdown).
"""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial


class Hopper(Fmi2Slave):

    author = "a descent-fmus user"
    description = "Vertical hopper near the lunar surface (tutorial plant)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.h0, self.v0, self.m0 = 10.0, 0.0, 100.0
        self.g, self.F_max, self.c = 1.62, 500.0, 2000.0
        self.throttle = 0.0
        self.h, self.v, self.m = self.h0, self.v0, self.m0
        for name, desc in (("h0", "initial altitude [m]"), ("v0", "initial speed, up [m/s]"),
                           ("m0", "initial mass [kg]"), ("g", "gravity [m/s2]"),
                           ("F_max", "maximum thrust [N]"), ("c", "exhaust speed [m/s]")):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed, description=desc))
        self.register_variable(Real("throttle", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous,
                                    description="throttle, clipped to [0, 1]"))
        for name, desc in (("h", "altitude [m]"), ("v", "vertical speed, up [m/s]"),
                           ("m", "mass [kg]")):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        initial=Fmi2Initial.exact, description=desc))

    def exit_initialization_mode(self):
        self.h, self.v, self.m = self.h0, self.v0, self.m0

    def _rhs(self, x, u):
        h, v, m = x
        return (v, u * self.F_max / m - self.g, -u * self.F_max / self.c)

    def do_step(self, current_time, step_size):
        if self.h <= 0.0:
            return True
        u = min(max(self.throttle, 0.0), 1.0)
        n = max(1, int(step_size / 0.01 + 0.5))
        dt = step_size / n
        x = (self.h, self.v, self.m)
        for _ in range(n):
            k1 = self._rhs(x, u)
            k2 = self._rhs(tuple(a + 0.5 * dt * b for a, b in zip(x, k1)), u)
            k3 = self._rhs(tuple(a + 0.5 * dt * b for a, b in zip(x, k2)), u)
            k4 = self._rhs(tuple(a + dt * b for a, b in zip(x, k3)), u)
            x = tuple(a + dt / 6.0 * (b1 + 2 * b2 + 2 * b3 + b4)
                      for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4))
            if x[0] <= 0.0:
                break
        self.h, self.v, self.m = x
        return True
