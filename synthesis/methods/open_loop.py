"""Best open-loop program by direct transcription: minimise the peak of a sampled quantity.

A piecewise-constant program ``u = (u_1, ..., u_N)`` (bounded) is sought that minimises the
maximum of the samples ``g_i(u)`` of a flight under equality constraints ``e(u) = 0``
(epigraph form, solved with SciPy's SLSQP)::

    minimise s  over (u, s)   subject to  g_i(u) <= s,  e(u) = 0,  lo <= u_k <= hi.

The flight is a black box ``fly(u) -> (g, e)`` with ``g`` of a fixed length (pad with a value
below the peak); gradients are forward differences of flights unless the flight gives them
(``with_jacobian``: ``fly(u) -> (g, e, dg/du, de/du)``).  With ``eq_tol > 0`` the equality
becomes ``|e| <= eq_tol`` (two inequalities).
No feedback law can beat the best program on the nominal flight, which makes this the bound a
synthesis compares with.
"""
from __future__ import annotations

import time

import numpy as np
from scipy.optimize import minimize

__all__ = ["minimax_program"]


def minimax_program(fly, n: int, bounds: tuple, u0=None, eq_scale: float = 1.0,
                    maxiter: int = 200, tol: float = 1e-9, fd_step: float = 1e-6,
                    progress=None, eq_tol: float = 0.0,
                    with_jacobian: bool = False) -> tuple[np.ndarray, dict]:
    """Minimise ``max_i g_i(u)`` subject to ``e(u) = 0`` over ``n`` bounded values.

    Parameters
    ----------
    fly : callable
        ``fly(u) -> (g, e)``: ``g`` an array of fixed length, ``e`` a scalar or an array.
    n : int
        Number of program values.
    bounds : (float, float)
        Bounds of every value.
    u0 : array-like, optional
        Starting program (default zeros, clipped to the bounds).
    eq_scale : float
        Factor applied to ``e`` (keeps the equality constraint well scaled).
    maxiter, tol : SLSQP limits.
    fd_step : float
        Forward-difference step of the gradients (taken backwards at the upper bound).
    eq_tol : float
        Allowed ``|e|`` (in the units of ``e``, before ``eq_scale``); 0 = equality.
    with_jacobian : bool
        ``fly`` also returns the Jacobians ``(g, e, dg/du, de/du)``: no finite differences.
    progress : callable, optional
        ``progress(iteration, peak, |e|)`` after every SLSQP iteration.

    Returns
    -------
    (u, info)
        The program (clipped to the bounds) and solver information.
    """
    if n < 1:
        raise ValueError(f"the program needs at least one value, got n = {n}")
    lo, hi = bounds
    cache = {}

    def run(u):
        g, e = fly(u)[:2]
        return np.asarray(g, float), np.atleast_1d(np.asarray(e, float)) * eq_scale

    def eval_with_jac(z):
        key = z.tobytes()
        if key in cache:
            return cache[key]
        u = z[:-1]
        if with_jacobian:
            g0, e0, jg, je = fly(u)
            cache.clear()
            cache[key] = (np.asarray(g0, float), np.atleast_1d(np.asarray(e0, float)) * eq_scale,
                          np.asarray(jg, float), np.atleast_2d(np.asarray(je, float)) * eq_scale)
            return cache[key]
        g0, e0 = run(u)
        jg = np.zeros((len(g0), n))
        je = np.zeros((len(e0), n))
        for k in range(n):
            du = u.copy()
            du[k] += fd_step if du[k] + fd_step <= hi else -fd_step
            h = du[k] - u[k]
            gk, ek = run(du)
            jg[:, k] = (gk - g0) / h
            je[:, k] = (ek - e0) / h
        cache.clear()
        cache[key] = (g0, e0, jg, je)
        return cache[key]

    cons = [
        {"type": "ineq", "fun": lambda z: z[-1] - eval_with_jac(z)[0],
         "jac": lambda z: np.hstack([-eval_with_jac(z)[2], np.ones((len(eval_with_jac(z)[0]),
                                                                    1))])},
    ]
    if eq_tol > 0:
        t = eq_tol * eq_scale
        cons += [
            {"type": "ineq", "fun": lambda z: t - eval_with_jac(z)[1],
             "jac": lambda z: np.hstack([-eval_with_jac(z)[3],
                                         np.zeros((len(eval_with_jac(z)[1]), 1))])},
            {"type": "ineq", "fun": lambda z: t + eval_with_jac(z)[1],
             "jac": lambda z: np.hstack([eval_with_jac(z)[3],
                                         np.zeros((len(eval_with_jac(z)[1]), 1))])}]
    else:
        cons.append({"type": "eq", "fun": lambda z: eval_with_jac(z)[1],
                     "jac": lambda z: np.hstack([eval_with_jac(z)[3],
                                                 np.zeros((len(eval_with_jac(z)[1]), 1))])})
    u_start = np.zeros(n) if u0 is None else np.asarray(u0, float)
    u_start = np.clip(u_start, lo, hi)
    z0 = np.append(u_start, run(u_start)[0].max())
    it = [0]

    def callback(z):
        it[0] += 1
        if progress is not None:
            g, e = run(z[:-1])
            progress(it[0], float(g.max()), float(np.abs(e).max() / eq_scale))

    t0 = time.perf_counter()
    res = minimize(lambda z: z[-1], z0, jac=lambda z: np.append(np.zeros(n), 1.0),
                   method="SLSQP", bounds=[(lo, hi)] * n + [(None, None)], constraints=cons,
                   callback=callback, options={"maxiter": maxiter, "ftol": tol})
    return np.clip(res.x[:-1], lo, hi), {"success": bool(res.success),
                                         "message": str(res.message),
                                         "iterations": int(res.nit),
                                         "seconds": time.perf_counter() - t0}
