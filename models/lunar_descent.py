"""S5 -- descent from lunar orbit into a terminal box (braking phase), two controls.

State ``x = (V, theta, h, phi, m)``: speed V [m/s], angle theta [rad] of the velocity from the
local upward vertical (pi/2 = horizontal, dh/dt = V cos theta), altitude h [m], range angle phi
[rad], mass m [kg].  Controls: ``u1`` [rad] thrust direction from the same vertical (pure braking
is ``u1 = theta + pi``), ``u2`` [kgf] change of the thrust.

    dV/dt     = W cos(u1 - theta) - g cos theta
    dtheta/dt = (W sin(u1 - theta) + g sin theta) / V
    dh/dt     = V cos theta
    dphi/dt   = V sin theta / R
    dm/dt     = -k_P (P0 + u2) / P_ud

with ``W = g~ k_P (P0 + u2) / m``, ``g = g0 (R0 / (R0 + h))^2``, ``R = R0 + h``; ``k_P`` is the
thrust factor of the dispersion study (1 nominal; a thrust error at fixed specific impulse
changes the mass flow by the same factor).

The flight ends at the first time V is in [Vf-, Vf+] and h in [hf-, hf+] (the terminal box),
at a crash (h = 0), when the model leaves its domain (V < V_STALL, where theta is undefined, or
m <= 0), or at t+.  Every end is located inside the RK4 sub-step.  The FMU publishes the end with
the plant status convention (:mod:`models.integrators`): ``status`` = REACHED in the box, CRASHED
at h = 0, LEFT_DOMAIN outside the model's domain, and ``t_end``.

This module holds the only definition of these equations: the :class:`LunarDescent` FMU and
the in-process code (tests, quick scans, the benchmark) use the same functions.

References
----------
A.I. Diveev et al., "Синтез управления спуском космического аппарата на поверхность Луны
методом сетевого оператора", Vestnik MGTU im. Baumana, ser. Priborostroenie, 2013, no. 4,
eqs. (1)-(6); the scenario numbers are our [choice] (models/README.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import (CRASHED, DIVERGED, EVENT, LEFT_DOMAIN, REACHED,
                                             Integrator, advance_to)
from descent_fmus.models.params import ParameterError, Params, param
from descent_fmus.models.traceable import first_smallest, maximum, minimum

__all__ = ["DescentParams", "rhs", "box_distance", "controller_inputs", "DescentIntegrator",
           "simulate", "LunarDescent", "U1_BOUNDS", "U2_BOUNDS", "T_PLUS", "G_TILDE",
           "V_STALL", "DT_INTEGRATION"]

#: Thrust-direction bounds [rad] ([choice]: from straight down to straight up).
U1_BOUNDS = (math.pi, 2.0 * math.pi)
#: Thrust-change bounds [kgf] ([choice], models/README.md).
U2_BOUNDS = (-40.0, 40.0)
#: Final time t+ [s] ([choice], models/README.md).
T_PLUS = 600.0
#: Standard gravity g~ converting kgf to N [m/s^2] (Diveev et al. 2013, eq. 6).
G_TILDE = 9.80665
#: Speed below which the flight leaves the model's domain [m/s]: dtheta/dt has V in the
#: denominator, so the angle is undefined at V = 0 ([choice], models/README.md).
V_STALL = 1.0
#: Default RK4 sub-step [s] (accuracy: models/README.md, tests/systems/lunar_descent/test_lunar_descent_model.py).
DT_INTEGRATION = 1.0


@dataclass(frozen=True)
class DescentParams(Params):
    """Parameters of the S5 plant (SI units; thrust in kgf as in the paper); defaults = the
    default scenario with theta0 = 90 deg and h0 = 18 km (the centre of the initial set).

    m0, V0 and the terminal box are our [choice] (models/README.md, S5 scenario).
    """

    P0: float = param(440.0, "kgf", "nominal thrust", positive=True)
    P_ud: float = param(319.0, "s", "specific impulse", positive=True)
    k_P: float = param(1.0, "1", "thrust factor (dispersion; scales thrust and mass flow)",
                       positive=True)
    g0: float = param(1.623, "m/s2", "lunar surface gravity", positive=True)
    R0: float = param(1_738_400.0, "m", "mean lunar radius", positive=True)
    m0: float = param(1400.0, "kg", "initial mass", positive=True)
    V0: float = param(1690.0, "m/s", "initial speed", positive=True)
    theta0: float = param(math.pi / 2, "rad", "initial angle of the velocity from the upward "
                          "vertical")
    h0: float = param(18_000.0, "m", "initial altitude", positive=True)
    phi0: float = param(0.0, "rad", "initial range angle")
    V_lo: float = param(40.0, "m/s", "terminal box: lower speed Vf-")
    V_hi: float = param(60.0, "m/s", "terminal box: upper speed Vf+")
    h_lo: float = param(1500.0, "m", "terminal box: lower altitude hf-")
    h_hi: float = param(2500.0, "m", "terminal box: upper altitude hf+")

    @property
    def Vf(self) -> float:
        """Target speed of J2: the centre of the box [m/s]."""
        return 0.5 * (self.V_lo + self.V_hi)

    @property
    def hf(self) -> float:
        """Target altitude of J1: the centre of the box [m]."""
        return 0.5 * (self.h_lo + self.h_hi)

    def check(self) -> None:
        if self.P0 + U2_BOUNDS[0] <= 0.0:
            raise ParameterError(f"parameter P0 must exceed {-U2_BOUNDS[0]} kgf (the thrust "
                                 f"change reaches {U2_BOUNDS[0]} kgf), got {self.P0}")
        if not 0.0 <= self.theta0 <= math.pi:
            raise ParameterError(f"parameter theta0 must be in [0, pi] rad, got {self.theta0}")
        if not V_STALL < self.V_lo < self.V_hi:
            raise ParameterError(f"need {V_STALL} < V_lo < V_hi [m/s], got V_lo={self.V_lo}, "
                                 f"V_hi={self.V_hi}")
        if not 0.0 <= self.h_lo < self.h_hi:
            raise ParameterError(f"need 0 <= h_lo < h_hi [m], got h_lo={self.h_lo}, "
                                 f"h_hi={self.h_hi}")
        if self.V_lo <= self.V0 <= self.V_hi and self.h_lo <= self.h0 <= self.h_hi:
            raise ParameterError("the initial state (V0, h0) lies inside the terminal box; "
                                 "there is nothing to fly")

    def constants(self) -> tuple:
        """The argument tuple of :func:`rhs` after the controls: (g~ k_P, k_P / P_ud, P0, g0,
        R0)."""
        return (G_TILDE * self.k_P, self.k_P / self.P_ud, self.P0, self.g0, self.R0)

    def initial_state(self) -> tuple:
        """(V0 [m/s], theta0 [rad], h0 [m], phi0 [rad], m0 [kg])."""
        return (self.V0, self.theta0, self.h0, self.phi0, self.m0)


def rhs(x, u1, u2, gk, fk, P0, g0, R0):
    """Right-hand side of Diveev et al. (2013), eqs. (1)-(6).

    Parameters
    ----------
    x : tuple of 5 float
        (V [m/s], theta [rad], h [m], phi [rad], m [kg]).
    u1 : float
        Thrust direction from the upward vertical [rad].
    u2 : float
        Thrust change [kgf].
    gk, fk, P0, g0, R0 : float
        ``g~ k_P`` [m/s^2], ``k_P / P_ud`` [1/s], ``P0`` [kgf], ``g0`` [m/s^2], ``R0`` [m]
        (:meth:`DescentParams.constants`).
    """
    V, th, h, _, m = x
    P = P0 + u2
    W = gk * P / m
    R = R0 + h
    g = g0 * (R0 / R) ** 2
    s, c = math.sin(th), math.cos(th)
    a = u1 - th
    return (W * math.cos(a) - g * c, (W * math.sin(a) + g * s) / V, V * c, V * s / R, -fk * P)


def box_distance(x, p: DescentParams) -> float:
    """max(V - Vf+, Vf- - V, h - hf+, hf- - h) with h in km-equivalents of V: <= 0 inside.

    The altitude terms are divided by 50 (1 km of altitude weighs as 20 m/s) only to keep the
    event function well scaled; the box itself is exact.
    """
    V, h = x[0], x[2]
    return maximum(V - p.V_hi, p.V_lo - V, (h - p.h_hi) / 50.0, (p.h_lo - h) / 50.0)


#: Scales of the controller inputs ([choice], models/README.md).
H_SCALE = 10_000.0    # [m]
V_SCALE = 1000.0      # [m/s]


def controller_inputs(x, p: DescentParams) -> tuple:
    """The inputs the control law reads (plant outputs ``y1..y4``) [choice].

    y1 = theta [rad] (so that u1 = y1 + pi + tilt is pure braking plus a tilt);
    y2 = (h - hf) / 10 km; y3 = (V - Vf) / 1000 m/s; y4 = (dh/dt) / 100 m/s = V cos theta / 100.
    """
    V, th, h = x[0], x[1], x[2]
    return (th, (h - p.hf) / H_SCALE, (V - p.Vf) / V_SCALE, V * math.cos(th) / 100.0)


class DescentIntegrator(Integrator):
    """Advance the S5 plant with RK4 sub-steps; locate the box entry, a crash or a stall.

    The one integrator of the plant (on the project's one stepping loop,
    :func:`models.integrators.advance_to`, with the earliest of the three events as its event
    function): the :class:`LunarDescent` FMU owns one, and in-process code
    (:func:`simulate`) uses the same class.  ``status`` becomes ``REACHED`` in the terminal box,
    ``CRASHED`` at h = 0 and ``LEFT_DOMAIN`` at V = V_STALL, m = 0 or a non-finite state; after
    that the state is frozen.  ``h_min`` is the minimum altitude so far [m].

    Parameters
    ----------
    p : DescentParams
        Plant parameters (validated here).
    dt : float
        RK4 sub-step [s].
    """

    def __init__(self, p: DescentParams, dt: float = DT_INTEGRATION):
        self.p = p.validate()
        self.args = p.constants()
        super().__init__(dt)

    def initial_state(self) -> tuple:
        return self.p.initial_state()

    def reset(self):
        super().reset()
        self.h_min = self.x[2]

    def _events(self, x):
        """(status, value) pairs; the flight ends with that status where the value reaches 0."""
        return ((CRASHED, x[2]), (LEFT_DOMAIN, minimum(x[0] - V_STALL, x[4])),
                (REACHED, box_distance(x, self.p)))

    def _event(self, x) -> float:
        # the earliest of the three events: min of continuous functions, zero where one is
        return minimum(x[2], x[0] - V_STALL, x[4], box_distance(x, self.p))

    def _sample(self, x, k1) -> None:
        if x[2] < self.h_min:
            self.h_min = x[2]

    def advance(self, t_end: float, u1: float, u2: float) -> None:
        """Integrate from ``self.t`` to ``t_end`` [s] with the controls held at (u1 [rad],
        u2 [kgf])."""
        if self.status:
            return
        x, t, outcome = advance_to(rhs, self.x, self.t, t_end, self.dt, (u1, u2) + self.args,
                                   self._event, self._sample)
        self.x, self.t = x, t
        self._sample(x, None)
        if outcome == EVENT:
            # which event: the one whose function is (to the location tolerance) zero
            self.end(first_smallest(self._events(x))[0], t)
        elif outcome == DIVERGED:
            self.end(LEFT_DOMAIN, t)


def simulate(p: DescentParams = DescentParams(), control=lambda t, x: (1.5 * math.pi, 0.0),
             step: float = 1.0, t_plus: float = T_PLUS, dt: float = DT_INTEGRATION,
             trace: list | None = None) -> DescentIntegrator:
    """Fly S5 in-process with ``(u1, u2) = control(t, x)`` held over communication steps
    ``step`` [s].

    Controls are clipped to :data:`U1_BOUNDS` and :data:`U2_BOUNDS` as in the FMU.  If
    ``trace`` is a list, ``(t, V, theta, h, phi, m, u1, u2)`` is appended at every step.
    Returns the finished :class:`DescentIntegrator` (``status``, ``t_end``, ``x``, ``h_min``).
    """
    fi = DescentIntegrator(p, dt)
    k = 0
    while fi.running and fi.t < t_plus - 1e-9:
        u1, u2 = control(fi.t, fi.x)
        u1 = min(max(u1, U1_BOUNDS[0]), U1_BOUNDS[1])
        u2 = min(max(u2, U2_BOUNDS[0]), U2_BOUNDS[1])
        if trace is not None:
            trace.append((fi.t,) + tuple(fi.x) + (u1, u2))
        k += 1
        fi.advance(min(k * step, t_plus), u1, u2)
    if trace is not None:
        trace.append((fi.t,) + tuple(fi.x) + (math.nan, math.nan))
    return fi


class LunarDescent(SlaveBase):
    """FMU of the S5 plant: inputs ``u1``, ``u2``; outputs the state, the controller inputs
    ``y1..y4``, fuel used, minimum altitude, ``status`` and ``t_end``."""

    params_class = DescentParams

    description = ("S5 descent from lunar orbit into a terminal box (V, theta, h, phi, m; thrust "
                   "direction u1 and thrust change u2); Diveev et al. 2013")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self.parameter("dt", DT_INTEGRATION, "RK4 sub-step of the internal integration [s]")
        self.input("u1", 1.5 * math.pi, "thrust direction from the upward vertical, clipped to "
                   "[pi, 2 pi] [rad]")
        self.input("u2", 0.0, "thrust change, clipped to [-40, 40] [kgf]")
        for name, desc in [("V", "speed [m/s]"),
                           ("theta", "angle of the velocity from the upward vertical [rad]"),
                           ("h", "altitude [m]"), ("phi", "range angle [rad]"),
                           ("m", "mass [kg]"), ("fuel", "propellant used m0 - m [kg]"),
                           ("h_min", "minimum altitude so far [m]"),
                           ("y1", "controller input: theta [rad]"),
                           ("y2", "controller input: (h - hf) / 10 km [1]"),
                           ("y3", "controller input: (V - Vf) / 1000 m/s [1]"),
                           ("y4", "controller input: dh/dt / 100 m/s [1]")]:
            self.output(name, desc)
        # status: 1 in the terminal box, 2 crashed (h = 0), 3 left the model's domain
        # (V < 1 m/s, m <= 0, non-finite)
        self.status_outputs(lambda: self._fi.status, lambda: self._fi.t_end_output)
        self.apply_resource_defaults()
        self.prepare()

    def prepare(self) -> None:
        self._fi = DescentIntegrator(self.params(), self.dt)
        self._publish()

    def _publish(self) -> None:
        fi = self._fi
        x = fi.x
        self.V, self.theta, self.h, self.phi, self.m = x
        self.fuel = fi.p.m0 - x[4]
        self.h_min = fi.h_min
        self.y1, self.y2, self.y3, self.y4 = controller_inputs(x, fi.p)

    def do_step(self, current_time: float, step_size: float) -> bool:
        u1, u2 = self.u1, self.u2
        if not math.isfinite(u1):
            u1 = 1.5 * math.pi      # a non-finite command: horizontal thrust, logged by nobody
        if not math.isfinite(u2):
            u2 = 0.0
        self._fi.advance(current_time + step_size, min(max(u1, U1_BOUNDS[0]), U1_BOUNDS[1]),
                         min(max(u2, U2_BOUNDS[0]), U2_BOUNDS[1]))
        self._publish()
        return True
