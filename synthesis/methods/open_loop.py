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


class _Flights:
    """The flights of :func:`minimax_program`: samples ``g``, scaled equality residuals ``e`` and
    their Jacobians, the last point's kept (SLSQP asks for the constraints and their Jacobians
    at the same point one after the other; each may cost ``n + 1`` flights).

    Parameters
    ----------
    fly : callable
        ``fly(u) -> (g, e)`` (or ``(g, e, dg/du, de/du)`` with ``with_jacobian``).
    n : int
        Number of program values.
    hi : float
        Upper bound of the values (a difference step that would cross it is taken backwards).
    eq_scale : float
        Factor applied to ``e`` and its Jacobian.
    fd_step : float
        Forward-difference step.
    with_jacobian : bool
        ``fly`` gives the Jacobians.
    """

    def __init__(self, fly, n: int, hi: float, eq_scale: float, fd_step: float,
                 with_jacobian: bool):
        self.fly, self.n, self.hi = fly, n, hi
        self.eq_scale, self.fd_step, self.with_jacobian = eq_scale, fd_step, with_jacobian
        self._key, self._last = None, None

    def run(self, u):
        """``(g, e * eq_scale)`` of the program ``u``."""
        g, e = self.fly(u)[:2]
        return np.asarray(g, float), np.atleast_1d(np.asarray(e, float)) * self.eq_scale

    def __call__(self, z):
        """``(g, e, dg/du, de/du)`` at ``z = (u, s)`` (``e`` and ``de/du`` scaled)."""
        key = z.tobytes()
        if key != self._key:
            u = z[:-1]
            self._last = self._given(u) if self.with_jacobian else self._differences(u)
            self._key = key
        return self._last

    def _given(self, u):
        """The flight's own Jacobians."""
        g0, e0, jg, je = self.fly(u)
        return (np.asarray(g0, float), np.atleast_1d(np.asarray(e0, float)) * self.eq_scale,
                np.asarray(jg, float), np.atleast_2d(np.asarray(je, float)) * self.eq_scale)

    def _differences(self, u):
        """Forward differences, one flight per value (backwards at the upper bound)."""
        g0, e0 = self.run(u)
        jg = np.zeros((len(g0), self.n))
        je = np.zeros((len(e0), self.n))
        for k in range(self.n):
            du = u.copy()
            du[k] += self.fd_step if du[k] + self.fd_step <= self.hi else -self.fd_step
            h = du[k] - u[k]
            gk, ek = self.run(du)
            jg[:, k] = (gk - g0) / h
            je[:, k] = (ek - e0) / h
        return g0, e0, jg, je


def _peak_constraint(flights: _Flights) -> dict:
    """The epigraph constraint ``g_i(u) <= s`` for SLSQP (``z = (u, s)``)."""
    return {"type": "ineq", "fun": lambda z: z[-1] - flights(z)[0],
            "jac": lambda z: np.hstack([-flights(z)[2], np.ones((len(flights(z)[0]), 1))])}


def _equality_constraints(flights: _Flights, eq_tol: float, eq_scale: float) -> list:
    """``e(u) = 0`` for SLSQP, or ``|e(u)| <= eq_tol`` as two inequalities when ``eq_tol > 0``
    (``z = (u, s)``: the slack ``s`` does not enter)."""
    def jac(sign):
        return lambda z: np.hstack([sign * flights(z)[3], np.zeros((len(flights(z)[1]), 1))])

    if eq_tol > 0:
        t = eq_tol * eq_scale
        return [{"type": "ineq", "fun": lambda z: t - flights(z)[1], "jac": jac(-1.0)},
                {"type": "ineq", "fun": lambda z: t + flights(z)[1], "jac": jac(1.0)}]
    return [{"type": "eq", "fun": lambda z: flights(z)[1], "jac": jac(1.0)}]


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
    flights = _Flights(fly, n, hi, eq_scale, fd_step, with_jacobian)
    cons = [_peak_constraint(flights)] + _equality_constraints(flights, eq_tol, eq_scale)
    u_start = np.zeros(n) if u0 is None else np.asarray(u0, float)
    u_start = np.clip(u_start, lo, hi)
    z0 = np.append(u_start, flights.run(u_start)[0].max())
    it = [0]

    def callback(z):
        it[0] += 1
        if progress is not None:
            g, e = flights.run(z[:-1])
            progress(it[0], float(g.max()), float(np.abs(e).max() / eq_scale))

    t0 = time.perf_counter()
    res = minimize(lambda z: z[-1], z0, jac=lambda z: np.append(np.zeros(n), 1.0),
                   method="SLSQP", bounds=[(lo, hi)] * n + [(None, None)], constraints=cons,
                   callback=callback, options={"maxiter": maxiter, "ftol": tol})
    return np.clip(res.x[:-1], lo, hi), {"success": bool(res.success),
                                         "message": str(res.message),
                                         "iterations": int(res.nit),
                                         "seconds": time.perf_counter() - t0}
