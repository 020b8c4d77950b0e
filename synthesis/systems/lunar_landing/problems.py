"""S3 lunar soft landing: the Pontryagin problems for the shooting solver and the closed loops.

* :func:`landing_problem` -- the paper's P-system (Mozzhorina 2017, eqs. (1)-(7)): unknowns
  ``psi1(0), psi3(0), T``; residuals ``h(T), V(T), psi3(T)``; ``psi2(0) = psi1(0) V0 / gL``.
* :func:`moon_landing_problem` -- dymos' normalised moon-landing example (h0 = 1, v0 = -0.783,
  m0 = 1, thrust in [0, 1.227], dm/dt = -thrust / 2.349, maximise m_f; known m_f ~ 0.3953):
  the solver's second user.
* Closed loops: the LunarLander plant with the optimal *program* (engine on at t_switch,
  :data:`PROGRAM_WIRING`; its start values :func:`program_defaults` are computed when the
  closed-loop FMU is built) and with the optimal law as *feedback* (engine on at the switching
  curve, :data:`FEEDBACK_WIRING`).  Both stop at the plant's ``status`` (1 at touchdown).

Nothing here is computed at import time.

References
----------
T.Yu. Mozzhorina, 2017 (problem, Table 1 guesses, Table 2 numbers).
dymos ``examples/moon_landing`` (OpenMDAO/dymos) for the second problem.
"""
from __future__ import annotations

from descent_fmus.models.lunar_landing import STEP, LanderParams, optimal_landing
from descent_fmus.models.lunar_landing import rhs as lander_rhs
from descent_fmus.synthesis.fmi.closed_loop import STATUS_STOP, Wiring
from descent_fmus.synthesis.methods.shooting import BangBang, PontryaginProblem

__all__ = ["landing_problem", "paper_guess", "moon_landing_problem", "MOON", "PAPER_GUESSES",
           "PAPER_TABLE2", "PAPER_ITERATIONS", "PAPER_INITIAL_NORMS", "moon_guess",
           "PROGRAM_WIRING", "FEEDBACK_WIRING", "STEP", "STOP_TIME", "PLANT_PARAMETERS",
           "PROGRAM_LOOP_PARAMETERS", "FEEDBACK_LOOP_PARAMETERS", "program_defaults"]

#: Table 1 of Mozzhorina (2017): starting guesses (psi1(0), psi3(0), T) ...
PAPER_GUESSES = ((-0.15, -0.7, 15.0), (-0.10, -0.7954, 10.0), (-0.30, -0.0810, 20.0))
#: ... Newton iterations (classical = modified) and initial residual norms the paper reports.
PAPER_ITERATIONS = (4, 6, 5)
PAPER_INITIAL_NORMS = (2.170, 25.928, 187.70)
#: Table 2 of Mozzhorina (2017), "shooting" row (umax = 14.57, see models/README.md).
PAPER_TABLE2 = dict(t_switch=4.7347, T=16.4083, V_switch=15.85820, h_switch=93.0174, fuel=170.08,
                    psi1=-0.492987, psi3_0=-0.017990)


def landing_problem(p: LanderParams = LanderParams()) -> PontryaginProblem:
    """The paper's P-system for S3 as a :class:`PontryaginProblem`.

    ``y = (h, V, m, psi1, psi2, psi3)``; the state part of the right-hand side is
    :func:`models.lunar_landing.rhs`; adjoints ``dpsi1/dt = 0``, ``dpsi2/dt = psi1``,
    ``dpsi3/dt = -psi2 beta u / m^2``; switching function ``Phi = -psi2 beta / m - psi3 - 1``
    (``u = umax`` where ``Phi > 0``).
    """
    p = p.validate()
    g, b, umax = p.gL, p.beta, p.umax

    def rhs(y, u):
        dx = lander_rhs((y[0], y[1], y[2]), u, g, b)
        return (dx[0], dx[1], dx[2], 0.0, y[3], -y[4] * b * u / (y[2] * y[2]))

    def start(z):
        return (p.h0, p.V0, p.m0, z[0], z[0] * p.V0 / g, z[1])

    def residuals(y, u, z):
        return (y[0], y[1], y[5])

    def domain(z):
        T = z[2]
        if not T > 0.0:
            return f"final time T = {T:.6g} s must be > 0"
        if umax * T >= p.m0:
            return f"final time T = {T:.6g} s burns more than the whole mass at full thrust"
        return None

    return PontryaginProblem(
        name="lunar landing (S3)", rhs=rhs, start=start, final_time=lambda z: float(z[2]),
        residuals=residuals,
        control=BangBang(lambda y: -y[4] * b / y[2] - y[5] - 1.0, 0.0, umax),
        unknowns=("psi1(0)", "psi3(0)", "T"), residual_names=("h(T)", "V(T)", "psi3(T)"),
        domain=domain,
        hint=("Choose a guess whose switching function changes sign on [0, T], e.g. psi3(0) "
              "from the paper's eq. (8) for a switch at T/2 (descent-fmus lunar-landing solve "
              "--guess PSI1 auto T)"))


def paper_guess(psi1: float, T: float, p: LanderParams = LanderParams(),
                t_switch: float | None = None) -> tuple:
    """Mozzhorina (2017) eq. (8): the guess ``(psi1, psi3(0), T)`` whose ``psi3(0)`` puts the
    switch at ``t_switch`` [s] (default ``T/2``).

    Parameters
    ----------
    psi1 : float
        psi1(0) of the guess.
    T : float
        Final time of the guess [s].
    p : LanderParams
    t_switch : float, optional
        Switch time the guess aims at [s].
    """
    ts = 0.5 * T if t_switch is None else t_switch
    psi3 = -1.0 - psi1 * (p.V0 / p.gL + ts) * p.beta / p.m0
    return (psi1, psi3, T)


# --------------------------------------------------------------------------- dymos moon landing
#: dymos examples/moon_landing: h0, v0 (upward), m0, thrust bound, exhaust speed (normalised).
MOON = dict(h0=1.0, v0=-0.783, m0=1.0, thrust_max=1.227, c=2.349, g=1.0, m_f=0.3953)


def moon_landing_problem() -> PontryaginProblem:
    """dymos' moon landing as a :class:`PontryaginProblem` (Mayer cost ``-m(tf)``).

    ``y = (h, v, m, lh, lv, lm)`` with ``v`` upward; ``H = lh v + lv (F/m - 1) - lm F / c``
    minimised: ``F = Fmax`` where ``Phi = -(lv / m - lm / c) > 0``; adjoints ``lh' = 0``,
    ``lv' = -lh``, ``lm' = lv F / m^2``.  Unknowns ``lh, lv(0), lm(0), tf``; residuals ``h(tf)``,
    ``v(tf)``, ``lm(tf) + 1`` (transversality of ``-m(tf)``), ``H(tf)`` (free final time).
    """
    c, g, fmax = MOON["c"], MOON["g"], MOON["thrust_max"]

    def rhs(y, F):
        h, v, m, lh, lv, lm = y
        return (v, F / m - g, -F / c, 0.0, -lh, lv * F / (m * m))

    def hamiltonian(y, F):
        h, v, m, lh, lv, lm = y
        return lh * v + lv * (F / m - g) - lm * F / c

    def residuals(y, F, z):
        return (y[0], y[1], y[5] + 1.0, hamiltonian(y, F))

    def domain(z):
        tf = z[3]
        if not tf > 0.0:
            return f"final time tf = {tf:.6g} must be > 0"
        if fmax / c * tf >= MOON["m0"]:
            return f"final time tf = {tf:.6g} burns the whole mass at full thrust"
        return None

    return PontryaginProblem(
        name="dymos moon landing", rhs=rhs,
        start=lambda z: (MOON["h0"], MOON["v0"], MOON["m0"], z[0], z[1], z[2]),
        final_time=lambda z: float(z[3]), residuals=residuals,
        control=BangBang(lambda y: -(y[4] / y[2] - y[5] / c), 0.0, fmax),
        unknowns=("lh", "lv(0)", "lm(0)", "tf"), residual_names=("h", "v", "lm+1", "H"),
        domain=domain, hint=("Choose adjoints whose switching function changes sign on "
                             "[0, tf], e.g. moon_guess(lh, tf)"))


def moon_guess(lh: float, tf: float, t_switch: float | None = None) -> tuple:
    """A guess for :func:`moon_landing_problem` in the spirit of Mozzhorina (2017) eq. (8).

    ``lv(0)`` from ``H(0) = 0`` with the engine off, ``lm(0)`` from ``Phi(t_switch) = 0``
    (default ``t_switch = tf / 2``) -- a guess that switches once, so the Jacobian is regular.
    """
    ts = 0.5 * tf if t_switch is None else t_switch
    lv0 = lh * MOON["v0"] / MOON["g"]
    return (lh, lv0, MOON["c"] * (lv0 - lh * ts) / MOON["m0"], tf)


# --------------------------------------------------------------------------- closed loops
#: Final time of the closed loops [s]: 2.4x the nominal landing time, room for dispersed starts.
STOP_TIME = 40.0

_EXPOSED_PLANT = (("h", "plant", "h"), ("V", "plant", "V"), ("m", "plant", "m"),
                  ("fuel", "plant", "fuel"), ("V_touchdown", "plant", "V_touchdown"),
                  ("status", "plant", "status"), ("t_end", "plant", "t_end"))

#: Plant parameters both closed-loop FMUs expose: (container name, role, component variable).
PLANT_PARAMETERS = (("h0", "plant", "h0"), ("V0", "plant", "V0"), ("m0", "plant", "m0"),
                    ("gL", "plant", "gL"), ("umax", "plant", "umax"))
#: Parameters of LunarLanderProgramClosedLoop.fmu.
PROGRAM_LOOP_PARAMETERS = PLANT_PARAMETERS + (("t_switch", "controller", "t_switch"),
                                              ("t_off", "controller", "t_off"))
#: Parameters of LunarLanderFeedbackClosedLoop.fmu.
FEEDBACK_LOOP_PARAMETERS = PLANT_PARAMETERS + (("ctrl_umax", "controller", "umax"),
                                               ("g_nominal", "controller", "g_nominal"),
                                               ("estimate_g", "controller", "estimate_g"))

PROGRAM_WIRING = Wiring(
    name="LunarLanderProgramClosedLoop", plant="LunarLander", controller="LandingProgram",
    to_controller=(), to_plant=(("u", "u"),), step=STEP, stop_time=STOP_TIME, stop=STATUS_STOP,
    exposed=_EXPOSED_PLANT + (("u", "controller", "u"),),
    description=("S3 lunar landing (LunarLander) under the optimal open-loop program: engine off, "
                 "full thrust from t_switch to t_off (defaults: the exact optimum of the default "
                 "scenario, umax = 14.57 kg/s; Mozzhorina 2017)"))

FEEDBACK_WIRING = Wiring(
    name="LunarLanderFeedbackClosedLoop", plant="LunarLander", controller="LandingSwitch",
    to_controller=(("h", "h"), ("V", "V"), ("m", "m")), to_plant=(("u", "u"),), step=STEP,
    stop_time=STOP_TIME, stop=STATUS_STOP,
    exposed=_EXPOSED_PLANT + (("u", "controller", "u"), ("h_sw", "controller", "h_sw"),
                              ("g_est", "controller", "g_est")),
    description=("S3 lunar landing (LunarLander) under the optimal law as feedback: full thrust "
                 "once the state reaches the switching curve h = h_sw(V, m) (Mozzhorina 2017)"))


def program_defaults(p: LanderParams = LanderParams()) -> dict:
    """Start values of the LandingProgram FMU that fly the exact optimum of ``p``.

    ``{"t_switch", "t_off", "umax"}`` from :func:`models.lunar_landing.optimal_landing`; called
    by ``build_fmus.py`` for LunarLanderProgramClosedLoop (the default scenario) and by
    :class:`~synthesis.systems.lunar_landing.study.LandingLoops` for its nominal conditions.
    """
    opt = optimal_landing(p)
    return {"t_switch": opt.t_switch, "t_off": opt.T, "umax": p.umax}
