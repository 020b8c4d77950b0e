"""The cart-pole's references: the LQR law of its linearisation and the best open-loop programs.

The LQR law of the linearisation at the upright (:func:`cartpole_lqr`, the sampled-data Riccati
solution of ``riccati.py`` with the cart-pole's cost weights) and, per start, the best open-loop
program found by trajectory optimisation (L-BFGS-B, in-process RK4 identical to the plant's,
:func:`cartpole_programs`), which ``references.py`` stores once and the suite replays through
the plant FMU.
"""
from __future__ import annotations

import math

import numpy as np

from riccati import sampled_lqr

__all__ = ["cartpole_rhs", "cartpole_lqr", "cartpole_program", "cartpole_start",
           "CARTPOLE_PARAMETRISATIONS", "cartpole_programs"]


def cartpole_rhs(p: dict):
    """The cart-pole's right-hand side (``plants/cartpole.py``) on arrays: f(s, F) with s of
    shape (..., 5) = (x, xdot, theta, thetadot, J)."""
    mc, mp, l, g = p["m_c"], p["m_p"], p["l"], p["g"]
    w = (p["w_x"], p["w_xdot"], p["w_theta"], p["w_thetadot"], p["w_F"])

    def f(s, F):
        x, xd, th, thd = s[..., 0], s[..., 1], s[..., 2], s[..., 3]
        st, ct = np.sin(th), np.cos(th)
        M = mc + mp
        tmp = (F + mp * l * thd * thd * st) / M
        thdd = (g * st - ct * tmp) / (l * (4.0 / 3.0 - mp * ct * ct / M))
        xdd = tmp - mp * l * thdd * ct / M
        c = w[0] * x * x + w[1] * xd * xd + w[2] * th * th + w[3] * thd * thd + w[4] * F * F
        return np.stack([xd, xdd, thd, thdd, c], -1)
    return f


def cartpole_lqr(p: dict, h: float) -> dict:
    """The LQR law of the cart-pole linearised at the upright, for the law sampled every h
    (:func:`sampled_lqr` with the plant's cost weights): u = -K (x, xdot, theta, thetadot)."""
    f = cartpole_rhs(p)
    s0, e = np.zeros(5), 1e-6
    A = np.zeros((4, 4))
    for i in range(4):
        d = np.zeros(5)
        d[i] = e
        A[:, i] = (f(s0 + d, 0.0)[:4] - f(s0 - d, 0.0)[:4]) / (2 * e)
    B = ((f(s0, e)[:4] - f(s0, -e)[:4]) / (2 * e)).reshape(4, 1)
    Q = np.diag([p["w_x"], p["w_xdot"], p["w_theta"], p["w_thetadot"]])
    R = np.array([[p["w_F"]]])
    d = sampled_lqr(A, B, Q, R, h)
    return {"A": A.tolist(), "B": B.ravel().tolist(), "K": d["K"].ravel().tolist()}


def _cartpole_fly(f, p, s0, V, K, h, n_sub, Fmax):
    """Flights of the programs u_k = Fmax tanh((v_k - K x_k) / Fmax) (rows of V) from s0: a
    feedback-parametrised open-loop program (any program within the bounds is one, and the
    parametrisation keeps the unstable pendulum's sensitivities bounded); (J, programs)."""
    V = np.atleast_2d(V)
    s = np.zeros((V.shape[0], 5))
    s[:, :4] = s0
    dt = h / n_sub
    U = np.empty_like(V)
    for k in range(V.shape[1]):
        F = Fmax * np.tanh((V[:, k] - s[:, :4] @ K) / Fmax)
        U[:, k] = F
        for _ in range(n_sub):
            k1 = f(s, F)
            k2 = f(s + 0.5 * dt * k1, F)
            k3 = f(s + 0.5 * dt * k2, F)
            k4 = f(s + dt * k3, F)
            s = s + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return s[:, 4], U


def cartpole_program(p: dict, s0, K, h: float, steps: int, v0=None,
                     maxiter: int = 3000) -> dict:
    """A locally optimal open-loop program from one start: L-BFGS-B over the feedforward v of
    :func:`_cartpole_fly` (forward-difference gradients, all perturbed flights in one batch),
    from ``v0`` (default 0: the smoothly saturated law -K x).  Any law's flight is a program, so
    no law does better from this start than the global optimum of this problem; L-BFGS-B finds
    a local one."""
    from scipy.optimize import minimize
    f = cartpole_rhs(p)
    K = np.asarray(K, float)
    n_sub, Fmax = int(p["n_sub"] + 0.5), p["F_max"]

    def fun(v):
        eps = 1e-7
        J, _ = _cartpole_fly(f, p, s0, np.vstack([v, v + eps * np.eye(steps)]), K, h, n_sub,
                             Fmax)
        return J[0], (J[1:] - J[0]) / eps

    start = np.zeros(steps) if v0 is None else np.asarray(v0, float)
    r = minimize(fun, start, jac=True, method="L-BFGS-B", options={"maxiter": maxiter})
    J, U = _cartpole_fly(f, p, s0, r.x, K, h, n_sub, Fmax)
    return {"J": float(J[0]), "u": U[0].tolist(), "v": r.x.tolist(), "iterations": int(r.nit),
            "message": str(r.message)}


def cartpole_start(state: dict) -> np.ndarray:
    return np.array([state.get("x0", 0.0), state.get("xdot0", 0.0), state.get("theta0", 0.0),
                     state.get("thetadot0", 0.0)])


#: gains of the programs' parametrisation, as multiples of the LQR gains: the optimum is the
#: same program problem for each, the local optimum L-BFGS-B reaches is not
CARTPOLE_PARAMETRISATIONS = (1.0, 1.5)


def cartpole_programs(problem, p: dict, K) -> list:
    """The best of several local optima per initial state of ``problem``: each parametrisation
    of :data:`CARTPOLE_PARAMETRISATIONS`, started from v = 0 and (continuation) from the best
    program of the next smaller angle of the same sign; starts in order of |theta0|."""
    h, T = problem.wiring.step, problem.wiring.stop_time
    steps = int(round(T / h))
    states = sorted(problem.initial_states, key=lambda s: abs(s.get("theta0", 0.0)))
    best, prev = {}, {}
    for s in states:
        s0 = cartpole_start(s)
        sign = math.copysign(1.0, s0[2])
        tries = []
        for m in CARTPOLE_PARAMETRISATIONS:
            Km = m * np.asarray(K, float)
            guesses = [None] + ([prev[sign][1]] if sign in prev and prev[sign][0] == m else [])
            for v0 in guesses:
                tries.append(dict(cartpole_program(p, s0, Km, h, steps, v0), gain_multiple=m,
                                  continued=v0 is not None))
        b = min(tries, key=lambda r: r["J"])
        prev[sign] = (b["gain_multiple"], b["v"])
        b = {k: v for k, v in b.items() if k != "v"}
        b["tries"] = [round(r["J"], 6) for r in tries]
        best[id(s)] = dict(b, start=s)
    # the cart-pole is odd-symmetric (sin, the force and every state change sign together, the
    # cost is even), so the negated program of the mirrored start is a program of this start
    # with the same cost, bit for bit: keep the better of the two
    out = []
    for s in problem.initial_states:
        b = best[id(s)]
        m = next((best[id(t)] for t in problem.initial_states
                  if all(t.get(k, 0.0) == -s.get(k, 0.0) for k in set(s) | set(t))), None)
        if m is not None and m["J"] < b["J"]:
            b = dict(m, u=[-v for v in m["u"]], start=s, mirrored=True)
        out.append(b)
    return out
