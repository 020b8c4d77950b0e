"""S2 -- asymmetric capsule in the Mars atmosphere: descent + quasi-linear angle of attack.

Planar point-mass descent over a spherical, non-rotating Mars with an exponential atmosphere
(state ``V`` [m/s], path angle ``gamma`` [rad], altitude ``h`` [m], range ``s`` [m])::

    dV/dt     = -q Cd S / m - g sin(gamma)           q = rho V^2 / 2,  rho = rho0 exp(-h / Hs)
    dgamma/dt = (V / r - g / V) cos(gamma)           g = g0 (R / r)^2,  r = R + h
    dh/dt     = V sin(gamma)
    ds/dt     = R V cos(gamma) / r

gives the dynamic pressure ``q(t)`` and its rate ``dq/dt = q (-dh/dt / Hs + 2 dV/dt / V)``.  From
them (seed 001, eq. 1; SPEC S2)::

    omega^2   = -mz_alpha q S L / I                  (precession frequency without roll)
    omega_dot = omega dq/dt / (2 q)                  (= eps f3 of eq. 1)
    omega_a   = sqrt(Ix_bar^2 omega_x^2 / 4 + omega^2),   Ix_bar = Ix / I
    dalpha/dt = -omega omega_dot alpha / (2 omega_a^2) - eps cos(theta + theta1) u / (2 omega_a)
    dtheta/dt = omega_x - omega_1,   omega_1 = Ix_bar omega_x / 2 + omega_a

``alpha`` is the spatial angle of attack [rad] (amplitude of the precession mode omega_1),
``theta`` the fast phase [rad], ``u = m^A`` the control (normalised asymmetry moment).  The
paper's ``eps f1`` is the physical adiabatic term (``omega_dot`` is ``d omega / dt``, itself of
order eps); ``eps`` scales the asymmetry moment: ``eps u`` is its angular acceleration [rad/s^2].

The flight ends at the first time ``h`` reaches ``h_end`` (located inside the RK4 step).  This
module is the one definition of these equations: the :class:`MarsCapsule` FMU, the rigid-body
plant of :mod:`models.mars_6dof` (descent and aerodynamics) and the in-process code
(:func:`simulate`, tests, benchmarks) call the same functions.

References
----------
Seed 001: V.V. Lyubimov, E.V. Kurkina, "Optimal control of the angle of attack of an asymmetric
spacecraft in the Mars atmosphere", eqs. (1), (17) and section 4 (Mars Polar Lander data).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from descent_fmus.models.fmu_support import ParameterError, SlaveBase, require_finite, require_positive
from descent_fmus.models.integrators import DIVERGED, EVENT, advance_to

__all__ = ["MarsParams", "descent", "precession", "rhs", "observe", "initial_state",
           "Flight", "simulate", "MarsCapsule", "DT_INTEGRATION", "STEP", "T_MAX"]

#: Default RK4 sub-step of the averaged plant [s] (tests/test_mars.py: against solve_ivp).
DT_INTEGRATION = 0.1
#: Default communication step of the closed loop [s] (= synthesis.systems.mars.wiring.STEP).
STEP = 0.05
#: Time limit of a flight [s] (the default descent reaches h_end at t ~ 660 s).
T_MAX = 1500.0


@dataclass(frozen=True)
class MarsParams:
    """Parameters of the S2 plants (SI units); defaults = the scenario of SPEC S2.

    Values marked [choice] are ours (the paper gives no aerodynamic or atmospheric data and no
    control parameters); models/README.md gives the reason for each.
    """

    m: float = 576.0              #: capsule mass [kg] (paper)
    Ix: float = 270.0             #: axial moment of inertia [kg m^2] (paper)
    I: float = 443.0              #: transverse moment of inertia Iy = Iz [kg m^2] (paper)
    S: float = 4.91               #: midsection area pi 1.25^2 [m^2] (paper's base radius)
    L: float = 2.0                #: reference length [m] (paper's cone height)
    Cd: float = 1.6               #: drag coefficient [1] ([choice])
    mz_alpha: float = -0.1        #: restoring-moment slope [1/rad] ([choice])
    rho0: float = 0.020           #: surface density of the exponential atmosphere [kg/m^3]
    Hs: float = 11_100.0          #: density scale height [m] ([choice])
    g0: float = 3.86              #: surface gravity [m/s^2] (paper)
    R: float = 3_390_000.0        #: Mars mean radius [m] (paper)
    V0: float = 3400.0            #: entry speed [m/s] (paper)
    h0: float = 120_000.0         #: entry altitude [m] (paper)
    gamma0: float = -0.017        #: entry path angle [rad] (paper)
    h_end: float = 10_000.0       #: altitude that ends the descent [m] ([choice])
    omega_x: float = 5.0          #: constant roll rate [rad/s] ([choice])
    theta1: float = 0.3           #: phase of the asymmetry [rad] ([choice])
    eps: float = 1.0              #: asymmetry-moment scale: eps u in [rad/s^2] ([choice])
    alpha0: float = 0.2           #: initial spatial angle of attack [rad] ([choice])
    theta0: float = 0.0           #: initial fast phase [rad] ([choice])

    def validate(self) -> "MarsParams":
        """Raise :class:`ParameterError` naming the first invalid parameter."""
        for f in fields(self):
            require_finite(f.name, getattr(self, f.name))
        for name in ("Ix", "I"):
            if getattr(self, name) <= 0.0:
                raise ParameterError(f"parameter {name} (moment of inertia) must be > 0 kg m2, "
                                     f"got {getattr(self, name)!r}")
        if self.Ix > 2.0 * self.I:
            raise ParameterError(f"moments of inertia violate Ix <= Iy + Iz = 2 I: Ix={self.Ix}, "
                                 f"I={self.I} kg m2")
        if self.omega_x <= 0.0:
            raise ParameterError(f"parameter omega_x (roll rate) must be > 0 rad/s: the model "
                                 f"and the law assume a constant positive roll rate, got "
                                 f"{self.omega_x!r}")
        if self.mz_alpha >= 0.0:
            raise ParameterError(f"parameter mz_alpha must be < 0 (statically stable capsule), "
                                 f"got {self.mz_alpha!r}")
        for name in ("m", "S", "L", "Cd", "rho0", "Hs", "g0", "R", "V0", "h0", "eps"):
            require_positive(name, getattr(self, name))
        if not 0.0 <= self.h_end < self.h0:
            raise ParameterError(f"parameter h_end must satisfy 0 <= h_end < h0, got "
                                 f"h_end={self.h_end}, h0={self.h0}")
        if not -math.pi / 2 < self.gamma0 < math.pi / 2:
            raise ParameterError(f"parameter gamma0 must be in (-pi/2, pi/2) rad, got "
                                 f"{self.gamma0}")
        if not 0.0 <= self.alpha0 < math.pi / 2:
            raise ParameterError(f"parameter alpha0 must be in [0, pi/2) rad, got {self.alpha0}")
        return self

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

    def with_(self, **changes) -> "MarsParams":
        return replace(self, **changes)


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
    """Precession frequencies from the dynamic pressure (seed 001, eq. 1).

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


class Flight:
    """Advance a Mars plant with RK4 sub-steps and stop exactly at ``h = h_end``.

    The one integrator of the S2 plants: both FMUs own one, in-process code uses the same class.

    Parameters
    ----------
    p : MarsParams
        Validated on construction.
    dt : float
        RK4 sub-step [s].
    f, x0, args, obs : optional
        Right-hand side, initial state, its constants and the output function (defaults: the
        averaged plant of this module); the altitude must be state element 2.
    """

    def __init__(self, p: MarsParams, dt: float = DT_INTEGRATION, f=rhs, x0=None, args=None,
                 obs=observe):
        self.p = p.validate()
        if not (math.isfinite(dt) and dt > 0.0):
            raise ParameterError(f"integration step dt must be > 0 s, got {dt!r}")
        self.dt, self.f, self.obs_fn = dt, f, obs
        self.args = p.constants() if args is None else args
        self.x0 = initial_state(p) if x0 is None else tuple(x0)
        self.reset()

    def reset(self):
        self.t = 0.0
        self.x = self.x0
        self.done = False
        self.diverged = False
        self.t_end = math.nan
        self._obs = None

    def outputs(self) -> tuple:
        """Output tuple at the current state (cached until the next step)."""
        if self._obs is None:
            self._obs = self.obs_fn(self.x, self.args)
        return self._obs

    def advance(self, t_end: float, u: float) -> None:
        """Integrate from ``self.t`` to ``t_end`` [s] with the control held at ``u``."""
        if self.done or self.diverged:
            return
        h_end = self.p.h_end
        self._obs = None
        self.x, self.t, outcome = advance_to(self.f, self.x, self.t, t_end, self.dt,
                                             (u,) + self.args, event=lambda y: y[2] - h_end)
        if outcome == EVENT:
            self.done = True
            self.t_end = self.t
        elif outcome == DIVERGED:   # e.g. V -> 0 with absurd parameters
            self.diverged = True


def simulate(p: MarsParams = MarsParams(), control=None, step: float = STEP,
             dt: float = DT_INTEGRATION, t_max: float = T_MAX, record: bool = True,
             flight: Flight | None = None):
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
    flight : Flight, optional
        Another plant's integrator (e.g. :func:`models.mars_6dof.flight`).

    Returns
    -------
    (Flight, dict)
        The finished integrator and ``{"t": [...], "u": [...], name: [...]}`` (lists).
    """
    fl = flight or Flight(p, dt)
    names = OUTPUTS if flight is None else getattr(flight, "names", OUTPUTS)
    rec = {"t": [], "u": []}
    rec.update({n: [] for n in names})
    k = 0
    while True:
        y = fl.outputs()
        u = control(y) if control is not None else 0.0
        if record:
            rec["t"].append(fl.t)
            rec["u"].append(u)
            for n, v in zip(names, y):
                rec[n].append(v)
        if fl.done or fl.diverged or fl.t >= t_max - 1e-9:
            break
        k += 1
        fl.advance(min(k * step, t_max), u)
    return fl, rec


class MarsCapsule(SlaveBase):
    """FMU of the averaged S2 plant: input ``u``; outputs alpha, theta, omega, ... (OUTPUTS)."""

    params_class = MarsParams

    description = ("S2 asymmetric capsule descending in the Mars atmosphere: point-mass descent "
                   "+ quasi-linear angle-of-attack equations; seed 001, Lyubimov & Kurkina")

    #: (name, description) of the parameters, in MarsParams order.
    PARAMETERS = [
        ("m", "capsule mass [kg]"), ("Ix", "axial moment of inertia [kg m2]"),
        ("I", "transverse moment of inertia Iy = Iz [kg m2]"), ("S", "midsection area [m2]"),
        ("L", "reference length of the moment coefficient [m]"),
        ("Cd", "drag coefficient [1]"), ("mz_alpha", "restoring-moment slope (< 0) [1/rad]"),
        ("rho0", "surface density of the exponential atmosphere [kg/m3]"),
        ("Hs", "density scale height [m]"), ("g0", "surface gravity [m/s2]"),
        ("R", "Mars radius [m]"), ("V0", "entry speed [m/s]"), ("h0", "entry altitude [m]"),
        ("gamma0", "entry path angle [rad]"), ("h_end", "altitude that ends the descent [m]"),
        ("omega_x", "constant roll rate (> 0) [rad/s]"),
        ("theta1", "phase of the asymmetry relative to theta [rad]"),
        ("eps", "asymmetry-moment scale: eps*u is an angular acceleration [rad/s2]"),
        ("alpha0", "initial spatial angle of attack [rad]"),
        ("theta0", "initial fast phase [rad]")]
    OUTPUT_DESCRIPTIONS = {
        "alpha": "spatial angle of attack [rad]", "theta": "fast phase [rad]",
        "omega": "precession frequency sqrt(-mz_alpha q S L / I) [rad/s]",
        "omega_dot": "rate of omega [rad/s2]",
        "omega_a": "sqrt(Ix_bar^2 omega_x^2/4 + omega^2) [rad/s]",
        "q": "dynamic pressure [Pa]", "q_dot": "rate of the dynamic pressure [Pa/s]",
        "theta_dot": "omega_x - omega_1 (near 0: resonance, model not valid) [rad/s]",
        "h": "altitude [m]", "V": "speed [m/s]", "gamma": "flight-path angle [rad]",
        "s": "range along the surface [m]",
        "wx": "body rate about the symmetry axis [rad/s]",
        "wy": "body rate about y [rad/s]", "wz": "body rate about z [rad/s]",
        "alpha_m1": "amplitude of the omega_1 precession mode (the averaged alpha) [rad]",
        "theta_m1": "phase theta of the omega_1 precession mode [rad]",
        "alpha_m2": "amplitude of the omega_2 precession mode [rad]"}
    DT = DT_INTEGRATION

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters(self.PARAMETERS)
        self.parameter("dt", self.DT, "RK4 sub-step of the internal integration [s]")
        self.input("u", 0.0, "control m^A: normalised asymmetry moment [1]")
        fl = lambda: self._fl  # noqa: E731
        for k, name in enumerate(self.output_names()):
            self.output(name, self.OUTPUT_DESCRIPTIONS[name],
                        getter=lambda k=k: fl().outputs()[k])
        self.output("t_end", "time the descent reached h_end, -1 before [s]",
                    getter=lambda: fl().t_end if fl().done else -1.0)
        self.int_output("done", "1 from the time h <= h_end on (2 if the integration "
                        "diverged) [1]", getter=lambda: 2 if fl().diverged else int(fl().done))
        self.apply_resource_defaults()
        self.prepare()

    def output_names(self):
        return OUTPUTS

    def make_flight(self, p: MarsParams) -> Flight:
        return Flight(p, self.dt)

    def prepare(self) -> None:
        try:
            self._fl = self.make_flight(self.params())
        except ParameterError:
            # invalid start values: keep a default plant until exit_initialization_mode reports
            self._fl = self.make_flight(MarsParams())

    def do_step(self, current_time: float, step_size: float) -> bool:
        u = self.u if math.isfinite(self.u) else 0.0
        self._fl.advance(current_time + step_size, u)
        return True
