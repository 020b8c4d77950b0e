"""S2 -- asymmetric capsule in the Mars atmosphere: descent + quasi-linear angle of attack.

Planar point-mass descent over a spherical, non-rotating Mars with an exponential atmosphere
(state ``V`` [m/s], path angle ``gamma`` [rad], altitude ``h`` [m], range ``s`` [m])::

    dV/dt     = -q Cd S / m - g sin(gamma)           q = rho V^2 / 2,  rho = rho0 exp(-h / Hs)
    dgamma/dt = (V / r - g / V) cos(gamma)           g = g0 (R / r)^2,  r = R + h
    dh/dt     = V sin(gamma)
    ds/dt     = R V cos(gamma) / r

gives the dynamic pressure ``q(t)`` and its rate ``dq/dt = q (-dh/dt / Hs + 2 dV/dt / V)``.  From
them (Lyubimov & Kurkina, eq. 1)::

    omega^2   = -mz_alpha q S L / I                  (precession frequency without roll)
    omega_dot = omega dq/dt / (2 q)                  (= eps f3 of eq. 1)
    omega_a   = sqrt(Ix_bar^2 omega_x^2 / 4 + omega^2),   Ix_bar = Ix / I
    dalpha/dt = -omega omega_dot alpha / (2 omega_a^2) - eps cos(theta + theta1) u / (2 omega_a)
    dtheta/dt = omega_x - omega_1,   omega_1 = Ix_bar omega_x / 2 + omega_a

``alpha`` is the spatial angle of attack [rad] (amplitude of the precession mode omega_1),
``theta`` the fast phase [rad], ``u = m^A`` the control (normalised asymmetry moment).  The
paper's ``eps f1`` is the physical adiabatic term (``omega_dot`` is ``d omega / dt``, itself of
order eps); ``eps`` scales the asymmetry moment: ``eps u`` is its angular acceleration [rad/s^2].

The flight ends at the first time ``h`` reaches ``h_end`` (located inside the RK4 step): the
plant's ``status`` becomes REACHED (LEFT_DOMAIN if the integration diverges).  This module is the
one definition of these equations: the :class:`MarsCapsule` FMU, the rigid-body plant of
:mod:`descent_fmus.models.mars_6dof` (descent and aerodynamics) and the in-process code
(:func:`simulate`, tests, benchmarks) call the same functions.

References
----------
V.V. Lyubimov, E.V. Kurkina, "Optimal control of the angle of attack of an asymmetric spacecraft
in the Mars atmosphere", eqs. (1), (17) and section 4 (Mars Polar Lander data).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import (DIVERGED, EVENT, LEFT_DOMAIN, REACHED, Integrator,
                                             advance_to)
from descent_fmus.models.params import ParameterError, Params, param

__all__ = ["MarsParams", "descent", "precession", "rhs", "observe", "initial_state",
           "MarsIntegrator", "simulate", "MarsCapsule", "OUTPUTS", "DT_INTEGRATION", "STEP",
           "T_MAX"]

#: Default RK4 sub-step of the averaged plant [s] (tests/systems/mars/test_mars_fmus.py: against solve_ivp).
DT_INTEGRATION = 0.1
#: Communication step of the closed loops [s]: over one step the held control sees the phase
#: theta advance by theta_dot * STEP <= 0.1 rad (theta_dot <= 1.95 rad/s).  Halving it changes
#: alpha(150 s) by 0.3 % and alpha_end by 0.9 %; doubling it (0.1 s) by 1.5 % and 4.6 %
#: (models/README.md, tests/systems/mars/test_mars_loop.py).
STEP = 0.05
#: Time limit of a flight [s] (the default descent reaches h_end = 10 km at t = 660.5 s).
T_MAX = 1500.0


@dataclass(frozen=True)
class MarsParams(Params):
    """Parameters of the S2 plants (SI units); defaults = the default scenario.

    Values marked [choice] are ours (the paper gives no aerodynamic or atmospheric data and no
    control parameters); models/README.md gives the reason for each.  The others are the
    paper's (Mars Polar Lander data).
    """

    m: float = param(576.0, "kg", "capsule mass", positive=True)
    Ix: float = param(270.0, "kg.m2", "axial moment of inertia", positive=True)
    I: float = param(443.0, "kg.m2", "transverse moment of inertia Iy = Iz", positive=True)
    S: float = param(4.91, "m2", "midsection area pi 1.25^2 (the paper's base radius)",
                     positive=True)
    L: float = param(2.0, "m", "reference length of the moment coefficient (the paper's cone "
                     "height)", positive=True)
    Cd: float = param(1.6, "1", "drag coefficient", positive=True)                # [choice]
    mz_alpha: float = param(-0.1, "1/rad", "restoring-moment slope (< 0)")          # [choice]
    rho0: float = param(0.020, "kg/m3", "surface density of the exponential atmosphere",
                        positive=True)                                              # [choice]
    Hs: float = param(11_100.0, "m", "density scale height", positive=True)        # [choice]
    g0: float = param(3.86, "m/s2", "surface gravity", positive=True)
    R: float = param(3_390_000.0, "m", "Mars radius", positive=True)
    V0: float = param(3400.0, "m/s", "entry speed", positive=True)
    h0: float = param(120_000.0, "m", "entry altitude", positive=True)
    gamma0: float = param(-0.017, "rad", "entry path angle")
    h_end: float = param(10_000.0, "m", "altitude that ends the descent")          # [choice]
    omega_x: float = param(5.0, "rad/s", "constant roll rate (> 0: the model and the law "
                           "assume a constant positive roll rate)", positive=True)  # [choice]
    theta1: float = param(0.3, "rad", "phase of the asymmetry relative to theta")   # [choice]
    eps: float = param(1.0, "rad/s2", "asymmetry-moment scale: eps*u is an angular "
                       "acceleration", positive=True)                               # [choice]
    alpha0: float = param(0.2, "rad", "initial spatial angle of attack")            # [choice]
    theta0: float = param(0.0, "rad", "initial fast phase")                         # [choice]

    def check(self) -> None:
        if self.Ix > 2.0 * self.I:
            raise ParameterError(f"moments of inertia violate Ix <= Iy + Iz = 2 I: Ix={self.Ix}, "
                                 f"I={self.I} kg m2")
        if self.mz_alpha >= 0.0:
            raise ParameterError(f"parameter mz_alpha must be < 0 (statically stable capsule), "
                                 f"got {self.mz_alpha!r}")
        if not 0.0 <= self.h_end < self.h0:
            raise ParameterError(f"parameter h_end must satisfy 0 <= h_end < h0, got "
                                 f"h_end={self.h_end}, h0={self.h0}")
        if not -math.pi / 2 < self.gamma0 < math.pi / 2:
            raise ParameterError(f"parameter gamma0 must be in (-pi/2, pi/2) rad, got "
                                 f"{self.gamma0}")
        if not 0.0 <= self.alpha0 < math.pi / 2:
            raise ParameterError(f"parameter alpha0 must be in [0, pi/2) rad, got {self.alpha0}")

    @property
    def ix_bar(self) -> float:
        """Ix / I [1]."""
        return self.Ix / self.I

    def constants(self) -> tuple:
        """Argument tuple of :func:`rhs` after the control.

        ``(Cd S / m [m^2/kg], -mz_alpha S L / I [1/(Pa s^2)], Ix/I [1], g0 [m/s^2], R [m],
        rho0 [kg/m^3], 1/Hs [1/m], omega_x [rad/s], theta1 [rad], eps [rad/s^2])``.
        """
        return (self.Cd * self.S / self.m, -self.mz_alpha * self.S * self.L / self.I,
                self.ix_bar, self.g0, self.R, self.rho0, 1.0 / self.Hs, self.omega_x,
                self.theta1, self.eps)


def descent(V, gamma, h, kd, g0, R, rho0, inv_hs):
    """Point-mass descent rates and the dynamic pressure.

    Parameters
    ----------
    V, gamma, h : float
        Speed [m/s], path angle [rad], altitude [m].
    kd, g0, R, rho0, inv_hs : float
        ``Cd S / m`` [m^2/kg], surface gravity [m/s^2], radius [m], surface density [kg/m^3],
        ``1 / Hs`` [1/m].

    Returns
    -------
    tuple
        ``(dV/dt [m/s^2], dgamma/dt [rad/s], dh/dt [m/s], ds/dt [m/s], q [Pa], dq/dt [Pa/s])``.
    """
    r = R + h
    q = 0.5 * rho0 * math.exp(-h * inv_hs) * V * V
    g = g0 * (R / r) ** 2
    sg, cg = math.sin(gamma), math.cos(gamma)
    dV = -q * kd - g * sg
    dh = V * sg
    dq = q * (-dh * inv_hs + 2.0 * dV / V)
    return dV, (V / r - g / V) * cg, dh, R * V * cg / r, q, dq


def precession(q, dq, kw, ix_bar, omega_x):
    """Precession frequencies from the dynamic pressure (Lyubimov & Kurkina, eq. 1).

    Parameters
    ----------
    q, dq : float
        Dynamic pressure [Pa] and its rate [Pa/s].
    kw : float
        ``-mz_alpha S L / I`` [1/(Pa s^2)], so that ``omega^2 = kw q``.
    ix_bar, omega_x : float
        ``Ix / I`` [1] and roll rate [rad/s].

    Returns
    -------
    tuple
        ``(omega [rad/s], omega_dot [rad/s^2], omega_a [rad/s])``.
    """
    w = math.sqrt(kw * q)
    wd = 0.5 * w * dq / q if q > 0.0 else 0.0
    half = 0.5 * ix_bar * omega_x
    return w, wd, math.sqrt(half * half + kw * q)


def rhs(x, u, kd, kw, ix_bar, g0, R, rho0, inv_hs, omega_x, theta1, eps):
    """Right-hand side of the averaged S2 plant, state ``(V, gamma, h, s, alpha, theta)``.

    ``u`` is the control ``m^A`` [1]; the rest is :meth:`MarsParams.constants`.
    """
    V, gamma, h, _, alpha, theta = x
    dV, dg, dh, ds, q, dq = descent(V, gamma, h, kd, g0, R, rho0, inv_hs)
    w, wd, wa = precession(q, dq, kw, ix_bar, omega_x)
    da = -w * wd * alpha / (2.0 * wa * wa) - eps * math.cos(theta + theta1) * u / (2.0 * wa)
    return dV, dg, dh, ds, da, omega_x - 0.5 * ix_bar * omega_x - wa


def observe(x, args):
    """Outputs of the averaged plant at state ``x`` (``args`` = :meth:`MarsParams.constants`).

    Returns ``(alpha, theta, omega, omega_dot, omega_a, q, q_dot, theta_dot, h, V, gamma, s)``.
    """
    kd, kw, ix_bar, g0, R, rho0, inv_hs, omega_x, _, _ = args
    V, gamma, h, s, alpha, theta = x
    _, _, _, _, q, dq = descent(V, gamma, h, kd, g0, R, rho0, inv_hs)
    w, wd, wa = precession(q, dq, kw, ix_bar, omega_x)
    return (alpha, theta, w, wd, wa, q, dq, omega_x - 0.5 * ix_bar * omega_x - wa, h, V, gamma,
            s)


#: Names of :func:`observe`'s values (also the FMU's Real outputs).
OUTPUTS = ("alpha", "theta", "omega", "omega_dot", "omega_a", "q", "q_dot", "theta_dot", "h",
           "V", "gamma", "s")


def initial_state(p: MarsParams) -> tuple:
    """``(V0, gamma0, h0, 0, alpha0, theta0)``."""
    return (p.V0, p.gamma0, p.h0, 0.0, p.alpha0, p.theta0)


class MarsIntegrator(Integrator):
    """Advance the averaged S2 plant with RK4 sub-steps and stop exactly at ``h = h_end``.

    The one integrator of the S2 plants: the :class:`MarsCapsule` FMU owns one, in-process code
    (:func:`simulate`) uses the same class, and the rigid-body plant
    (:class:`descent_fmus.models.mars_6dof.Mars6DOFIntegrator`) subclasses it with its own
    right-hand side, initial state and outputs (the altitude must be state element 2).
    ``status`` becomes ``REACHED`` at h = h_end and ``LEFT_DOMAIN`` if the integration diverges
    (e.g. V -> 0 with absurd parameters).

    Parameters
    ----------
    p : MarsParams
        Validated on construction.
    dt : float
        RK4 sub-step [s] (> 0).
    """

    #: right-hand side ``f(x, u, *p.constants())`` and output function ``observe(x, args)``
    f = staticmethod(rhs)
    observe = staticmethod(observe)
    #: names of the values :meth:`outputs` returns (the FMU's Real outputs besides ``t_end``)
    names = OUTPUTS

    def __init__(self, p: MarsParams, dt: float = DT_INTEGRATION):
        self.p = p.validate()
        self.args = p.constants()
        super().__init__(dt)

    def initial_state(self) -> tuple:
        return initial_state(self.p)

    def reset(self) -> None:
        super().reset()
        self._obs = None

    def outputs(self) -> tuple:
        """Output tuple at the current state (cached until the next step)."""
        if self._obs is None:
            self._obs = self.observe(self.x, self.args)
        return self._obs

    def advance(self, t_end: float, u: float) -> None:
        """Integrate from ``self.t`` to ``t_end`` [s] with the control held at ``u``."""
        if self.status:
            return
        h_end = self.p.h_end
        self._obs = None
        self.x, self.t, outcome = advance_to(self.f, self.x, self.t, t_end, self.dt,
                                             (u,) + self.args, event=lambda y: y[2] - h_end)
        if outcome == EVENT:
            self.end(REACHED, self.t)
        elif outcome == DIVERGED:
            self.end(LEFT_DOMAIN, self.t)


def simulate(p: MarsParams = MarsParams(), control=None, step: float = STEP,
             dt: float = DT_INTEGRATION, t_max: float = T_MAX, record: bool = True,
             integrator: MarsIntegrator | None = None):
    """Fly an S2 plant in-process, ``u = control(outputs)`` held over communication steps.

    Parameters
    ----------
    p : MarsParams
    control : callable or None
        ``control(outputs) -> u`` with the plant's output tuple (None: u = 0).
    step, dt, t_max : float
        Communication step, RK4 sub-step and time limit [s].
    record : bool
        Keep the outputs and u at every communication point.
    integrator : MarsIntegrator, optional
        Another plant's integrator (e.g. a
        :class:`~descent_fmus.models.mars_6dof.Mars6DOFIntegrator`); default the averaged plant
        with ``p`` and ``dt``.

    Returns
    -------
    (MarsIntegrator, dict)
        The finished integrator and ``{"t": [...], "u": [...], name: [...]}`` (lists).
    """
    fl = integrator or MarsIntegrator(p, dt)
    rec = {"t": [], "u": []}
    rec.update({n: [] for n in fl.names})
    k = 0
    while True:
        y = fl.outputs()
        u = control(y) if control is not None else 0.0
        if record:
            rec["t"].append(fl.t)
            rec["u"].append(u)
            for n, v in zip(fl.names, y):
                rec[n].append(v)
        if fl.status or fl.t >= t_max - 1e-9:
            break
        k += 1
        fl.advance(min(k * step, t_max), u)
    return fl, rec


class MarsCapsule(SlaveBase):
    """FMU of the averaged S2 plant: input ``u``; outputs alpha, theta, omega, ... (OUTPUTS),
    ``status`` and ``t_end``."""

    params_class = MarsParams
    #: the plant's integrator (its ``names`` are the Real outputs)
    integrator = MarsIntegrator
    #: default RK4 sub-step [s]
    DT = DT_INTEGRATION

    description = ("S2 asymmetric capsule descending in the Mars atmosphere: point-mass descent "
                   "+ quasi-linear angle-of-attack equations; Lyubimov & Kurkina")

    OUTPUT_DESCRIPTIONS = {
        "alpha": "spatial angle of attack [rad]", "theta": "fast phase [rad]",
        "omega": "precession frequency sqrt(-mz_alpha q S L / I) [rad/s]",
        "omega_dot": "rate of omega [rad/s2]",
        "omega_a": "sqrt(Ix_bar^2 omega_x^2/4 + omega^2) [rad/s]",
        "q": "dynamic pressure [Pa]", "q_dot": "rate of the dynamic pressure [Pa/s]",
        "theta_dot": "omega_x - omega_1 (near 0: resonance, model not valid) [rad/s]",
        "h": "altitude [m]", "V": "speed [m/s]", "gamma": "flight-path angle [rad]",
        "s": "range along the surface [m]"}

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self.parameter("dt", self.DT, "RK4 sub-step of the internal integration [s]")
        self.input("u", 0.0, "control m^A: normalised asymmetry moment [1]")
        fl = lambda: self._fl  # noqa: E731
        for k, name in enumerate(self.integrator.names):
            self.output(name, self.OUTPUT_DESCRIPTIONS[name],
                        getter=lambda k=k: fl().outputs()[k])
        self.status_outputs(lambda: fl().status, lambda: fl().t_end_output)
        self.apply_resource_defaults()
        self.prepare()

    def prepare(self) -> None:
        try:
            self._fl = self.integrator(self.params(), self.dt)
        except ParameterError:
            # invalid start values: keep a default plant until exit_initialization_mode reports
            self._fl = self.integrator(MarsParams(), self.DT)

    def do_step(self, current_time: float, step_size: float) -> bool:
        u = self.u if math.isfinite(self.u) else 0.0
        self._fl.advance(current_time + step_size, u)
        return True
