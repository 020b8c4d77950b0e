"""A linear plant with a quadratic cost: the suite's problem with a known optimum.

Written with pythonfmu only, as a user's plant would be; the suite builds it at run time
(``python -m pythonfmu build -f benchmarks/suite/plants/lq.py -d DIR``).

    dx1/dt = x2
    dx2/dt = a21 x1 + a22 x2 + b u          (a21 = 1 > 0: unstable open loop)
    dJ/dt  = q1 x1^2 + q2 x2^2 + r u^2      (the running cost, integrated with the state)

The input ``u`` is held over each communication step (clipped to [-u_max, u_max]: wide, never
reached by the laws of the suite).  The state and the cost are integrated together by RK4 with
``n_sub`` sub-steps per communication step (default 8 over the 0.1 s step: the cost of a flight
agrees with its exact value to ~1e-9 relative), so ``final(J)`` is the continuous cost of the
sampled-data (zero-order-hold) flight.
"""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial


class LQPlant(Fmi2Slave):

    author = "descent-fmus benchmark suite"
    description = "Unstable 2-state linear plant with its running quadratic cost (suite: lq)"

    PARAMETERS = (("x10", 1.0, "initial x1"), ("x20", 0.0, "initial x2"),
                  ("a21", 1.0, "A[2,1]"), ("a22", -0.5, "A[2,2]"), ("b", 1.0, "B[2]"),
                  ("q1", 1.0, "cost weight of x1^2"), ("q2", 0.1, "cost weight of x2^2"),
                  ("r", 0.1, "cost weight of u^2"), ("u_max", 1000.0, "input bound"),
                  ("n_sub", 8.0, "RK4 sub-steps per communication step"))

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
        self.x1, self.x2, self.J = self.x10, self.x20, 0.0
        for name, desc in (("x1", "state 1"), ("x2", "state 2"),
                           ("J", "running cost integral(q1 x1^2 + q2 x2^2 + r u^2) so far")):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        initial=Fmi2Initial.exact, description=desc))

    def exit_initialization_mode(self):
        self.x1, self.x2, self.J = self.x10, self.x20, 0.0

    def do_step(self, current_time, step_size):
        u = min(max(self.u, -self.u_max), self.u_max)
        a21, a22, bu = self.a21, self.a22, self.b * u
        q1, q2, ru2 = self.q1, self.q2, self.r * u * u
        n = max(1, int(self.n_sub + 0.5))
        h = step_size / n
        x1, x2, J = self.x1, self.x2, self.J
        for _ in range(n):
            # RK4 on (x1, x2, J); the cost's derivative depends on the state only
            k1a, k1b = x2, a21 * x1 + a22 * x2 + bu
            k1c = q1 * x1 * x1 + q2 * x2 * x2 + ru2
            y1, y2 = x1 + 0.5 * h * k1a, x2 + 0.5 * h * k1b
            k2a, k2b = y2, a21 * y1 + a22 * y2 + bu
            k2c = q1 * y1 * y1 + q2 * y2 * y2 + ru2
            y1, y2 = x1 + 0.5 * h * k2a, x2 + 0.5 * h * k2b
            k3a, k3b = y2, a21 * y1 + a22 * y2 + bu
            k3c = q1 * y1 * y1 + q2 * y2 * y2 + ru2
            y1, y2 = x1 + h * k3a, x2 + h * k3b
            k4a, k4b = y2, a21 * y1 + a22 * y2 + bu
            k4c = q1 * y1 * y1 + q2 * y2 * y2 + ru2
            x1 += h / 6.0 * (k1a + 2.0 * k2a + 2.0 * k3a + k4a)
            x2 += h / 6.0 * (k1b + 2.0 * k2b + 2.0 * k3b + k4b)
            J += h / 6.0 * (k1c + 2.0 * k2c + 2.0 * k3c + k4c)
        self.x1, self.x2, self.J = x1, x2, J
        return True
