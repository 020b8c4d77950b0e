"""S3 -- vertical lunar soft landing: the plant, the closed-form powered arc, the switching curve.

State ``x = (h, V, m)``: altitude [m], speed *downward* [m/s], mass [kg]; control ``u`` in
``[0, umax]`` is the fuel flow [kg/s]:

    dh/dt = -V
    dV/dt = gL - beta u / m
    dm/dt = -u

With ``u`` held constant the motion has a closed form (Tsiolkovsky): from ``(h, V, m)`` after a
time ``s`` with ``a = u / m``

    m(s) = m (1 - a s)
    V(s) = V + gL s + beta ln(1 - a s)
    h(s) = h - [V s + gL s^2 / 2 - beta (s + (1 - a s) ln(1 - a s) / a)]

(``u = 0``: the free-fall parabola).  The fuel-optimal landing is a coast followed by full thrust
down to ``h = V = 0`` (one switch, Mozzhorina 2017), so the *switching curve* ``h_sw(V, m)`` --
the height from which full thrust brings the speed to zero exactly at the ground -- is this
closed form evaluated at the stopping time.  It defines the feedback law of
:mod:`models.controllers.lunar_landing_switch` and, with the coast, the exact optimum
(:func:`optimal_landing`) that tests use as an oracle for the shooting solver.

This module holds the only definition of these equations; the :class:`LunarLander` FMU, the
controller FMUs and the in-process code (shooting problem, tests) call the same functions.

References
----------
T.Yu. Mozzhorina, "Numerical solution to problems of optimal control with switching by means of
the shooting method", Math. Modeling and Computational Methods, 2017, no. 2, eqs. (1)-(7).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import (DIVERGED, EVENT, LEFT_DOMAIN, REACHED, Integrator,
                                             advance_to)
from descent_fmus.models.params import ParameterError, Params, param
from descent_fmus.models.traceable import clip, where

__all__ = ["LanderParams", "InfeasibleLandingError", "rhs", "constant_flow_state",
           "stopping_time", "switch_height", "optimal_landing", "OptimalLanding",
           "LanderIntegrator", "LunarLander", "DT_INTEGRATION", "H_CONTACT", "M_DRY", "STEP",
           "solve_increasing"]

#: Default RK4 sub-step inside the FMU [s]: the powered arc is smooth (u constant inside a
#: communication step), so one RK4 step of 0.01 s has a local error below 1e-12 m.
DT_INTEGRATION = 0.01
#: Touchdown is declared at h <= H_CONTACT [m] (located inside the RK4 step).  A law that brakes
#: exactly onto h = V = 0 would otherwise hover at h ~ 1e-17 m, chattering, before rounding lets
#: it touch; 1 micrometre ends that without changing any reported digit.
H_CONTACT = 1e-6
#: Default mass below which the plant cuts the engine [kg] (a guard, never reached in a landing).
M_DRY = 1.0
#: Communication step of the landing closed loops [s], also the step the controller FMUs assume
#: before their first ``doStep``.
STEP = 0.01


class InfeasibleLandingError(ParameterError):
    """Full thrust cannot stop the lander (thrust-to-weight <= 1 or fuel cannot suffice)."""


@dataclass(frozen=True)
class LanderParams(Params):
    """Parameters of the S3 plant (SI units); defaults = the default scenario.

    ``umax`` is 14.57 kg/s: the paper prints 15.74, but all its numbers are reproduced with
    14.57 (the same digits transposed -- a misprint; [choice], models/README.md).
    """

    gL: float = param(1.62, "m/s2", "lunar gravity", positive=True)
    beta: float = param(3050.0, "m/s", "exhaust velocity", positive=True)
    umax: float = param(14.57, "kg/s", "maximum fuel flow (the paper's printed 15.74 is a "
                        "misprint of 14.57)", positive=True)
    h0: float = param(150.0, "m", "initial altitude")
    V0: float = param(8.2, "m/s", "initial downward speed")
    m0: float = param(15000.0, "kg", "initial mass", positive=True)

    def check(self) -> None:
        if self.h0 < 0.0:
            raise ParameterError(f"parameter h0 must be >= 0 m, got {self.h0}")

    def require_stoppable(self) -> "LanderParams":
        """Raise :class:`InfeasibleLandingError` unless full thrust exceeds the weight at m0."""
        self.validate()
        accel = self.beta * self.umax / self.m0
        if accel <= self.gL:
            raise InfeasibleLandingError(
                f"umax = {self.umax} kg/s gives a thrust acceleration beta*umax/m0 = "
                f"{accel:.4g} m/s^2 <= gL = {self.gL} m/s^2: full thrust cannot even hold the "
                f"lander, no soft landing exists; raise umax above "
                f"{self.gL * self.m0 / self.beta:.4g} kg/s")
        return self


def rhs(x, u, gL, beta):
    """Right-hand side of S3 eq. (1): ``(dh/dt, dV/dt, dm/dt)`` for state ``(h, V, m)``.

    Parameters
    ----------
    x : tuple of 3 float
        Altitude h [m], downward speed V [m/s], mass m [kg].
    u : float
        Fuel flow [kg/s].
    gL, beta : float
        Lunar gravity [m/s^2], exhaust velocity [m/s].
    """
    return (-x[1], gL - beta * u / x[2], -u)


def _log_terms(a, s):
    """``(ln(1 - a s), -(s + (1 - a s) ln(1 - a s) / a))`` without cancellation for small a s."""
    q = a * s
    lg = math.log1p(-q)
    if q < 0.05:
        # -(s + (1-q) ln(1-q)/a) = -s * sum_{k>=2} q^(k-1) / (k (k-1))   (series, q small;
        # 0.05^22 < 1e-28, so the truncation is far below rounding)
        acc, term = 0.0, 1.0
        for k in range(2, 24):
            acc += term / (k * (k - 1))
            term *= q
        return lg, -s * q * acc
    return lg, -(s + (1.0 - q) * lg / a)


def constant_flow_state(x, u, s, gL, beta):
    """State after a time ``s`` [s] with the fuel flow held at ``u`` [kg/s] (closed form).

    Parameters
    ----------
    x : tuple of 3 float
        Start state (h [m], V [m/s], m [kg]).
    u : float
        Fuel flow [kg/s], ``u s < m``.
    s : float
        Duration [s].
    gL, beta : float
        Gravity [m/s^2], exhaust velocity [m/s].

    Returns
    -------
    tuple of 3 float
        ``(h, V, m)`` at time ``s``.
    """
    h, V, m = x
    if u == 0.0:
        return (h - V * s - 0.5 * gL * s * s, V + gL * s, m)
    a = u / m
    lg, integral = _log_terms(a, s)          # integral = int_0^s ln(1 - a r) dr
    return (h - (V * s + 0.5 * gL * s * s + beta * integral), V + gL * s + beta * lg,
            m * (1.0 - a * s))


def solve_increasing(f, lo, hi, flo=None, fhi=None, xtol=0.0, max_iter=200):
    """Root of a continuous function with ``f(lo) < 0 < f(hi)`` (Illinois regula falsi + bisection).

    Pure Python (the controller FMU avoids importing SciPy); converges to adjacent floats.
    """
    flo = f(lo) if flo is None else flo
    fhi = f(hi) if fhi is None else fhi
    side = 0
    for it in range(max_iter):
        if it % 4 == 3:                      # a bisection now and then bounds the worst case
            x = 0.5 * (lo + hi)
        else:
            x = (lo * fhi - hi * flo) / (fhi - flo)
            if not lo < x < hi:
                x = 0.5 * (lo + hi)
        fx = f(x)
        if fx == 0.0 or hi - lo <= max(xtol, 4e-16 * abs(x)):
            return x
        if fx < 0.0:
            lo, flo = x, fx
            if side == -1:
                fhi *= 0.5
            side = -1
        else:
            hi, fhi = x, fx
            if side == 1:
                flo *= 0.5
            side = 1
    return 0.5 * (lo + hi)


def stopping_time(V, m, umax, gL, beta):
    """Time [s] for full thrust to bring the downward speed ``V >= 0`` [m/s] to zero.

    ``V(s) = V + gL s + beta ln(1 - umax s / m)`` is concave and decreasing when the thrust
    acceleration exceeds ``gL``; the root is found by Newton's method (monotone from the left
    for a concave decreasing function after one step) with a bracket safeguard.

    Raises
    ------
    InfeasibleLandingError
        If full thrust cannot stop the lander before the mass is used up.
    """
    if V <= 0.0:
        return 0.0
    a = umax / m
    if beta * a <= gL:
        raise InfeasibleLandingError(
            f"thrust acceleration beta*umax/m = {beta * a:.4g} m/s^2 <= gL = {gL} m/s^2: "
            f"full thrust cannot stop the lander")
    s_hi = (1.0 - 1e-15) / a
    lo, hi = 0.0, s_hi
    s = min(V / (beta * a - gL), 0.5 * s_hi)   # constant-mass estimate (an over-estimate)
    for _ in range(60):
        g = V + gL * s + beta * math.log1p(-a * s)
        if g > 0.0:
            lo = s
        else:
            hi = s
        dg = gL - beta * a / (1.0 - a * s)
        s_new = s - g / dg
        if not lo <= s_new <= hi:
            s_new = 0.5 * (lo + hi)
        if abs(s_new - s) <= 1e-15 * s:
            return s_new
        s = s_new
    if V + gL * hi + beta * math.log1p(-a * min(hi, s_hi)) > 0.0:
        raise InfeasibleLandingError("full thrust cannot stop the lander before its mass is "
                                     "used up")
    return s


def switch_height(V, m, umax, gL, beta):
    """Switching curve ``h_sw(V, m)`` [m]: full thrust from height h_sw stops exactly at h = 0.

    For ``V <= 0`` (not descending) the curve is 0: no thrust is needed while going up.
    """
    if V <= 0.0:
        return 0.0
    s = stopping_time(V, m, umax, gL, beta)
    h_end = constant_flow_state((0.0, V, m), umax, s, gL, beta)[0]
    return -h_end


@dataclass(frozen=True)
class OptimalLanding:
    """The exact fuel-optimal landing of S3 (coast, then full thrust to h = V = 0).

    Attributes
    ----------
    t_switch : float
        Engine-on time [s].
    T : float
        Final (touchdown) time [s].
    h_switch, V_switch : float
        Altitude [m] and downward speed [m/s] at the switch.
    fuel : float
        Fuel burnt [kg].
    psi1, psi2_0, psi3_0 : float
        Adjoints of the paper's Pontryagin system: psi1 (constant), psi2(0), psi3(0).
    """

    t_switch: float
    T: float
    h_switch: float
    V_switch: float
    fuel: float
    psi1: float
    psi2_0: float
    psi3_0: float


def optimal_landing(p: LanderParams = LanderParams()) -> OptimalLanding:
    """Exact optimum of S3 from the closed-form arcs (a test oracle; one scalar root).

    Unknown: the powered duration ``s``.  Full thrust for ``s`` ending at V = 0 fixes the speed at
    the switch, ``V_s = -gL s - beta ln(1 - umax s / m0)``; the coast fixes the switch time
    ``t_s = (V_s - V0) / gL`` and height; the remaining condition ``h(T) = 0`` is solved to
    adjacent floats.  The adjoints follow linearly from ``Phi(t_s) = 0`` and ``psi3(T) = 0``
    with ``psi2(t) = psi1 (V0/gL + t)`` (H = 0) and ``dpsi3/dt = -psi2 beta u / m^2``.

    Raises
    ------
    InfeasibleLandingError
        Thrust too small, or the lander is already too low/fast to stop (it would need to brake
        from the start and still touch down with V > 0).
    """
    p.require_stoppable()
    g, b, u, m0 = p.gL, p.beta, p.umax, p.m0
    a = u / m0

    def v_switch(s):
        return -g * s - b * math.log1p(-a * s)

    def h_err(s):            # height at the switch of the coast minus the curve's height
        vs = v_switch(s)
        ts = (vs - p.V0) / g
        hs = p.h0 - p.V0 * ts - 0.5 * g * ts * ts
        return hs - (-constant_flow_state((0.0, vs, m0), u, s, g, b)[0])

    # shortest powered arc: braking from the start (t_s = 0); if V0 <= 0 the coast first
    # passes its apex and any s >= 0 is reachable.  h_err decreases with s.
    s_min = stopping_time(p.V0, m0, u, g, b)
    f_lo = h_err(s_min)
    if f_lo < 0.0:
        raise InfeasibleLandingError(
            f"from h0 = {p.h0} m at V0 = {p.V0} m/s even full thrust from t = 0 brings the "
            f"speed to zero only {-f_lo:.4g} m below the ground: no soft landing exists (raise "
            f"umax or h0, or lower V0)")
    s_hi = (1.0 - 1e-9) / a
    if h_err(s_hi) > 0.0:
        raise InfeasibleLandingError("the fuel runs out before the lander can stop")
    s = solve_increasing(lambda z: -h_err(z), s_min, s_hi)
    vs = v_switch(s)
    ts = (vs - p.V0) / g
    hs = p.h0 - p.V0 * ts - 0.5 * g * ts * ts
    T = ts + s
    # adjoints: Phi(ts) = -psi2(ts) b/m0 - psi3_0 - 1 = 0 and psi3(T) = psi3_0 - psi1 b u I = 0,
    # I = int_ts^T (c + t) / m(t)^2 dt,  c = V0/g;  m(t) = m0 - u (t - ts)
    c = p.V0 / g + ts
    mf = m0 - u * s
    i0 = (1.0 / mf - 1.0 / m0) / u                           # int 1/m^2
    i1 = (m0 * i0 - math.log(m0 / mf) / u) / u               # int r/m^2, r = t - ts
    integral = c * i0 + i1
    # psi3_0 = psi1 b u I ;  -psi1 c b/m0 - psi1 b u I = 1
    psi1 = -1.0 / (b * c / m0 + b * u * integral)
    psi3 = psi1 * b * u * integral
    return OptimalLanding(t_switch=ts, T=T, h_switch=hs, V_switch=vs, fuel=u * s, psi1=psi1,
                          psi2_0=psi1 * p.V0 / g, psi3_0=psi3)


class LanderIntegrator(Integrator):
    """Advance the S3 plant with RK4 sub-steps; stop at touchdown (h = h_contact, in the step).

    The one integrator of the plant: the :class:`LunarLander` FMU owns one, and in-process code
    (``synthesis.systems.lunar_landing.study.fly_feedback_in_process``) uses the same class.
    ``u`` is clipped to ``[0, umax]`` and cut to 0 once the mass would fall below ``m_dry``.
    ``status`` becomes ``REACHED`` at touchdown (``t_end`` its time, ``V_touchdown`` the downward
    speed then) and ``LEFT_DOMAIN`` if the integration diverges; the state is frozen from then on.

    Parameters
    ----------
    p : LanderParams
    dt : float
        RK4 sub-step [s].
    m_dry : float
        Mass below which the engine is cut [kg], in (0, m0).
    h_contact : float
        Altitude at which touchdown is declared [m], >= 0.
    """

    def __init__(self, p: LanderParams, dt: float = DT_INTEGRATION, m_dry: float = M_DRY,
                 h_contact: float = H_CONTACT):
        self.p = p.validate()
        if not (math.isfinite(h_contact) and h_contact >= 0.0):
            raise ParameterError(f"parameter h_contact must be >= 0 m, got {h_contact!r}")
        if not (math.isfinite(m_dry) and 0.0 < m_dry < p.m0):
            raise ParameterError(f"parameter m_dry must be in (0, m0) kg, got {m_dry!r}")
        self.h_contact = h_contact
        self.m_dry = m_dry
        self.args = (p.gL, p.beta)
        super().__init__(dt)

    def initial_state(self) -> tuple:
        return (self.p.h0, self.p.V0, self.p.m0)

    def reset(self) -> None:
        super().reset()
        #: downward speed at touchdown [m/s] (NaN before)
        self.V_touchdown = math.nan
        if self.p.h0 <= self.h_contact:          # starts on the ground
            self.V_touchdown = self.p.V0
            self.end(REACHED, 0.0)

    def advance(self, t_end: float, u: float) -> None:
        """Integrate from ``self.t`` to ``t_end`` [s] with the fuel flow held at ``u`` [kg/s]."""
        if self.status:
            self.t = t_end
            return
        span = t_end - self.t
        if span <= 0.0:
            return
        # clipped to [0, umax] (a non-finite flow: 0), cut where the mass would fall below
        # m_dry in this step (models.traceable: one C conditional each in the native plant)
        u = where(math.isfinite(u), lambda: clip(u, 0.0, self.p.umax), 0.0)
        u = where(self.x[2] - u * span < self.m_dry, 0.0, u)
        hc = self.h_contact
        x, t, outcome = advance_to(rhs, self.x, self.t, t_end, self.dt, (u,) + self.args,
                                   event=lambda y: y[0] - hc, tol=1e-13)
        if outcome == EVENT:
            self.x = (0.0, x[1], x[2])
            self.V_touchdown = x[1]
            self.end(REACHED, t)
        else:
            self.x = x
            if outcome == DIVERGED:
                self.end(LEFT_DOMAIN, t)
        self.t = t_end


class LunarLander(SlaveBase):
    """FMU of the S3 plant: input fuel flow ``u``; outputs h, V, m, fuel, the touchdown speed and
    the plant status (``status`` 1 = REACHED at touchdown, ``t_end`` its time)."""

    params_class = LanderParams

    description = ("S3 vertical lunar soft landing (h, V downward, m; fuel flow input); "
                   "Mozzhorina 2017")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self.parameter("m_dry", M_DRY, "mass below which the engine is cut (guard) [kg]")
        self.parameter("dt", DT_INTEGRATION, "RK4 sub-step of the internal integration [s]")
        self.parameter("h_contact", H_CONTACT, "altitude at which touchdown is declared [m]")
        self.input("u", 0.0, "fuel flow, clipped to [0, umax] [kg/s]")
        fi = lambda: self._fi  # noqa: E731
        self.output("h", "altitude [m]", getter=lambda: fi().x[0])
        self.output("V", "downward speed [m/s]", getter=lambda: fi().x[1])
        self.output("m", "mass [kg]", getter=lambda: fi().x[2])
        self.output("fuel", "fuel used m0 - m [kg]", getter=lambda: fi().p.m0 - fi().x[2])
        self.output("V_touchdown", "downward speed at touchdown, 0 before [m/s]",
                    getter=lambda: fi().V_touchdown if fi().status == REACHED else 0.0)
        self.status_outputs(lambda: fi().status, lambda: fi().t_end_output)
        self.apply_resource_defaults()
        self.prepare()

    def check_parameters(self) -> None:
        super().check_parameters()
        if not 0.0 < self.m_dry < self.m0:
            raise ParameterError(f"parameter m_dry must be in (0, m0 = {self.m0}) kg, "
                                 f"got {self.m_dry}")
        if not 0.0 <= self.h_contact < 1.0:
            raise ParameterError(f"parameter h_contact must be in [0, 1) m, got {self.h_contact}")

    def prepare(self) -> None:
        self._fi = LanderIntegrator(self.params(), self.dt, self.m_dry, self.h_contact)

    def do_step(self, current_time: float, step_size: float) -> bool:
        self._fi.advance(current_time + step_size, self.u)
        return True
