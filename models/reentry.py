"""S1 -- planar atmospheric descent of a capsule's centre of mass (Earth).

State ``x = (x1, x2, x3, x4)``: ``x1, x3`` position [m] and ``x2, x4`` velocity [m/s] in a
geocentric Cartesian frame; control ``u`` in ``[-0.2, 0.2]`` is the relative change of drag.

    dx1/dt = x2
    dx2/dt = -g0 Rz^2 x1 / r^3 - (1+u) S rho0 / m * x2 * v * exp(-lam (r - Rz))
    dx3/dt = x4
    dx4/dt = -g0 Rz^2 x3 / r^3 - (1+u) S rho0 / m * x4 * v * exp(-lam (r - Rz))

The flight ends at the first time the altitude ``h = r - Rz`` reaches ``hf`` (located inside the
integration step) or at ``t+``.

This module holds the only definition of these equations; the :class:`Reentry` FMU and the
in-process code (tests, open-loop optimisation) call the same functions.

References
----------
A.I. Diveev, E.Yu. Shmalko, "Multicriterial structural-parametric synthesis of the control
system for spacecraft descent by the network operator method" (Vestnik RUDN), eqs. (1)-(8),
(11)-(23).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import (EVENT, LEFT_DOMAIN, REACHED, DIVERGED, Integrator,
                                             advance_to)
from descent_fmus.models.params import ParameterError, Params, param

__all__ = ["ReentryParams", "SECOND_SCENARIO", "rhs", "rhs_jacobians", "initial_state",
           "altitude", "downrange", "deviations", "loads", "simulate", "ReentryIntegrator",
           "Reentry", "U_BOUNDS", "T_PLUS"]

#: Control bounds (relative change of drag).
U_BOUNDS = (-0.2, 0.2)
#: Final time limit t+ [s].
T_PLUS = 300.0
#: Default RK4 sub-step inside the FMU [s] (accuracy: see models/README.md).
DT_INTEGRATION = 0.5


@dataclass(frozen=True)
class ReentryParams(Params):
    """Parameters of the S1 plant (SI units); defaults = the default scenario.

    The paper gives no entry conditions: V0, h0 and beta0 are our [choice] (models/README.md,
    "S1 entry conditions").
    """

    m: float = param(5000.0, "kg", "capsule mass", positive=True)
    S: float = param(3.5, "m2", "reference area", positive=True)
    rho0: float = param(1.22, "kg/m3", "sea-level air density", positive=True)
    lam: float = param(1.35e-4, "1/m", "inverse density scale height", positive=True)
    g0: float = param(9.81, "m/s2", "surface gravity", positive=True)
    Rz: float = param(6_371_000.0, "m", "Earth radius", positive=True)
    V0: float = param(7500.0, "m/s", "entry speed", positive=True)
    h0: float = param(100_000.0, "m", "entry altitude", positive=True)
    beta0: float = param(math.radians(-2.1), "rad", "entry path angle")
    hf: float = param(10_000.0, "m", "final altitude")
    Lf: float = param(1_400_000.0, "m", "required down-range at hf", positive=True)

    def check(self) -> None:
        if not 0.0 <= self.hf < self.h0:
            raise ParameterError(f"parameter hf must satisfy 0 <= hf < h0, got hf={self.hf}, "
                                 f"h0={self.h0}")
        if not -math.pi / 2 < self.beta0 < math.pi / 2:
            raise ParameterError(f"parameter beta0 must be in (-pi/2, pi/2) rad, got {self.beta0}")

    def constants(self) -> tuple:
        """The argument tuple of :func:`rhs` after the control: (g0 Rz^2, S rho0/m, lam, Rz)."""
        return (self.g0 * self.Rz ** 2, self.S * self.rho0 / self.m, self.lam, self.Rz)


#: The second scenario, for robustness checks ([choice], models/README.md).
SECOND_SCENARIO = ReentryParams(V0=8000.0, h0=80_000.0, beta0=math.radians(-1.6))


def rhs(x, u, gm, kd, lam, rz):
    """Right-hand side of S1 eqs. (1)-(4).

    Parameters
    ----------
    x : tuple of 4 float
        State (x1 [m], x2 [m/s], x3 [m], x4 [m/s]).
    u : float
        Relative change of drag [-].
    gm, kd, lam, rz : float
        ``g0 Rz^2`` [m^3/s^2], ``S rho0 / m`` [1/m], ``lam`` [1/m], ``Rz`` [m]
        (:meth:`ReentryParams.constants`).
    """
    x1, x2, x3, x4 = x
    r2 = x1 * x1 + x3 * x3
    r = math.sqrt(r2)
    g = gm / (r2 * r)
    d = (1.0 + u) * kd * math.sqrt(x2 * x2 + x4 * x4) * math.exp(-lam * (r - rz))
    return (x2, -g * x1 - d * x2, x4, -g * x3 - d * x4)


def rhs_jacobians(x, u, gm, kd, lam, rz):
    """Partial derivatives of :func:`rhs`: ``(f_x, f_u)``, ``f_x[i][j] = d f_i / d x_j`` (4 x 4
    nested tuples) and ``f_u[i] = d f_i / d u`` (the same equations, differentiated by hand; the
    open-loop bound propagates sensitivities with them)."""
    x1, x2, x3, x4 = x
    r2 = x1 * x1 + x3 * x3
    r = math.sqrt(r2)
    g = gm / (r2 * r)
    v = math.sqrt(x2 * x2 + x4 * x4)
    e = kd * v * math.exp(-lam * (r - rz))       # drag factor per unit (1 + u)
    d = (1.0 + u) * e
    g1, g3 = -3.0 * g * x1 / r2, -3.0 * g * x3 / r2             # dg/dx1, dg/dx3
    d1, d3 = -d * lam * x1 / r, -d * lam * x3 / r               # dd/dx1, dd/dx3
    iv2 = 1.0 / (v * v) if v > 0.0 else 0.0
    d2, d4 = d * x2 * iv2, d * x4 * iv2                         # dd/dx2, dd/dx4
    fx = ((0.0, 1.0, 0.0, 0.0),
          (-g - x1 * g1 - x2 * d1, -d - x2 * d2, -x1 * g3 - x2 * d3, -x2 * d4),
          (0.0, 0.0, 0.0, 1.0),
          (-x3 * g1 - x4 * d1, -x4 * d2, -g - x3 * g3 - x4 * d3, -d - x4 * d4))
    fu = (0.0, -e * x2, 0.0, -e * x4)
    return fx, fu


def initial_state(p: ReentryParams) -> tuple:
    """S1 eq. (5): (0, V0 cos beta0, Rz + h0, V0 sin beta0)."""
    return (0.0, p.V0 * math.cos(p.beta0), p.Rz + p.h0, p.V0 * math.sin(p.beta0))


def altitude(x, rz: float) -> float:
    """Altitude h = r - Rz [m] (eq. 11)."""
    return math.hypot(x[0], x[2]) - rz


def downrange(x, rz: float) -> float:
    """Down-range L = Rz atan(x1/x3) [m] (eq. 12; the paper's eq. 8 prints atan(x4/x2), a misprint)."""
    return rz * math.atan2(x[0], x[2])


def deviations(x, p: ReentryParams):
    """Controller inputs (y1, y2): deviations from the straight line (0, h0)-(Lf, hf) in (L, h).

    ``y1`` [-] is the relative altitude deviation (eq. 15), ``y2`` [rad] the difference between
    the flight-path angle and the angle of the straight line to the target (eq. 23).
    """
    x1, x2, x3, x4 = x
    r = math.hypot(x1, x3)
    h = r - p.Rz
    L = p.Rz * math.atan2(x1, x3)
    y1 = h / p.h0 - ((p.hf / p.h0 - 1.0) / p.Lf * L + 1.0)
    den = p.Rz * (x2 * x3 - x1 * x4)
    gamma = math.atan((x1 * x2 + x3 * x4) * r / den) if den != 0.0 else math.copysign(
        math.pi / 2, x1 * x2 + x3 * x4)
    to_go = p.Lf - L
    gamma_line = math.atan((h - p.hf) / to_go) if to_go != 0.0 else math.copysign(
        math.pi / 2, h - p.hf)
    return y1, gamma - gamma_line


def loads(x, dx, kd: float, lam: float, rz: float, g0: float, u: float):
    """(load, aero_load) [-] at state ``x`` with derivative ``dx``.

    ``load`` is the paper's J1 integrand r^2 sqrt(dx2^2 + dx4^2) / (Rz^2 g0) (eq. 7, total
    acceleration); ``aero_load`` the drag acceleration over g0.
    """
    x1, x2, x3, x4 = x
    r2 = x1 * x1 + x3 * x3
    load = r2 * math.hypot(dx[1], dx[3]) / (rz * rz * g0)
    v2 = x2 * x2 + x4 * x4
    aero = (1.0 + u) * kd * v2 * math.exp(-lam * (math.sqrt(r2) - rz)) / g0
    return load, aero


class ReentryIntegrator(Integrator):
    """Advance the S1 plant with RK4 sub-steps, stop exactly at h = hf, track the maximum loads.

    The one integrator of the plant: the :class:`Reentry` FMU owns one, and in-process code
    (:func:`simulate`) uses the same class.  ``status`` becomes ``REACHED`` at h = hf and
    ``LEFT_DOMAIN`` if the integration diverges.
    """

    def __init__(self, p: ReentryParams, dt: float = DT_INTEGRATION, trace: bool = False):
        self.p = p.validate()
        #: list of the load at every sample if ``trace`` (open-loop optimisation), else None
        self.trace = [] if trace else None
        self.args = p.constants()
        super().__init__(dt)

    def initial_state(self) -> tuple:
        return initial_state(self.p)

    def reset(self):
        super().reset()
        if self.trace is not None:
            self.trace.clear()
        self.load_max = 0.0
        self.aero_load_max = 0.0
        self.u = 0.0
        self._sample(self.x, rhs(self.x, 0.0, *self.args), 0.0)

    def _sample(self, x, dx, u):
        p = self.p
        self.load, self.aero_load = loads(x, dx, self.args[1], p.lam, p.Rz, p.g0, u)
        if self.load > self.load_max:
            self.load_max = self.load
        if self.aero_load > self.aero_load_max:
            self.aero_load_max = self.aero_load
        if self.trace is not None:
            self.trace.append(self.load)

    def advance(self, t_end: float, u: float) -> None:
        """Integrate from ``self.t`` to ``t_end`` with the control held at ``u``."""
        if self.status:
            return
        args = (u,) + self.args
        rz_hf = self.p.Rz + self.p.hf
        self.x, self.t, outcome = advance_to(
            rhs, self.x, self.t, t_end, self.dt, args,
            event=lambda y: math.hypot(y[0], y[2]) - rz_hf,
            on_step=lambda y, k1: self._sample(y, k1, u))
        if outcome == EVENT:
            self.end(REACHED, self.t)
            self._sample(self.x, rhs(self.x, *args), u)
        elif outcome == DIVERGED:
            self.end(LEFT_DOMAIN, self.t)
        else:
            # the left-hand value at t_end: the load with the control held over this step.  The
            # next step starts with the right-hand value (its own control), so both one-sided
            # loads of a control change are measured -- the load jumps there with the drag.
            self._sample(self.x, rhs(self.x, *args), u)
        self.u = u


def simulate(p: ReentryParams = ReentryParams(), control=lambda t, x: 0.0, step: float = 1.0,
             t_plus: float = T_PLUS, dt: float = DT_INTEGRATION,
             trace: bool = False) -> ReentryIntegrator:
    """Fly S1 in-process with ``u = control(t, x)`` held over communication steps ``step`` [s].

    Returns the finished :class:`ReentryIntegrator` (``status``, ``t_end``, ``x``,
    ``load_max``, and the load at every sample in ``trace`` if requested).
    """
    fi = ReentryIntegrator(p, dt, trace)
    k = 0
    while fi.running and fi.t < t_plus - 1e-9:
        u = min(max(control(fi.t, fi.x), U_BOUNDS[0]), U_BOUNDS[1])
        k += 1
        fi.advance(min(k * step, t_plus), u)
    return fi


class Reentry(SlaveBase):
    """FMU of the S1 plant: input ``u``, outputs the state, altitude, range, loads, y1, y2."""

    params_class = ReentryParams

    description = ("S1 Earth atmospheric descent of a capsule (planar, geocentric Cartesian); "
                   "Diveev & Shmalko")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self.parameter("dt", DT_INTEGRATION, "RK4 sub-step of the internal integration [s]")
        self.input("u", 0.0, "relative change of drag, clipped to [-0.2, 0.2] [1]")
        # Outputs are plain attributes refreshed once per step by _publish (cheap getters: the
        # closed loop reads them every communication step).
        for k in range(4):
            unit = "m" if k % 2 == 0 else "m/s"
            self.output(f"x{k + 1}", f"state x{k + 1} [{unit}]")
        self.output("h", "altitude r - Rz [m]")
        self.output("L", "down-range Rz atan(x1/x3) [m]")
        self.output("load", "load factor r2 |a| / (Rz2 g0) (J1 integrand) [1]")
        self.output("aero_load", "drag acceleration / g0 [1]")
        self.output("load_max", "running maximum of load over all sub-steps (J1) [1]")
        self.output("aero_load_max", "running maximum of aero_load [1]")
        self.output("y1", "relative altitude deviation from the line (0,h0)-(Lf,hf) [1]")
        self.output("y2", "path-angle deviation from the line to the target [rad]")
        self.status_outputs(lambda: self._fi.status, lambda: self._fi.t_end_output)
        self.apply_resource_defaults()
        self.prepare()

    def prepare(self) -> None:
        self._fi = ReentryIntegrator(self.params(), self.dt)
        self._publish()

    def _publish(self) -> None:
        fi = self._fi
        x, rz = fi.x, fi.p.Rz
        self.x1, self.x2, self.x3, self.x4 = x
        self.h = altitude(x, rz)
        self.L = downrange(x, rz)
        self.load, self.aero_load = fi.load, fi.aero_load
        self.load_max, self.aero_load_max = fi.load_max, fi.aero_load_max
        self.y1, self.y2 = deviations(x, fi.p)

    def do_step(self, current_time: float, step_size: float) -> bool:
        u = self.u
        if not math.isfinite(u):
            u = 0.0
        self._fi.advance(current_time + step_size, min(max(u, U_BOUNDS[0]), U_BOUNDS[1]))
        self._publish()
        return True
