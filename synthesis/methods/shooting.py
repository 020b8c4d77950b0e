"""Shooting method for Pontryagin boundary-value problems (state + adjoint, free final time).

A problem (:class:`PontryaginProblem`) is given as plain functions:

* ``rhs(y, u)`` -- derivative of ``y = (x, psi)`` (state and adjoint) in physical time;
* ``start(z)`` -- ``y(0)`` from the vector of unknowns ``z`` (missing initial adjoints...);
* ``final_time(z)`` -- the final time ``T`` (usually one of the unknowns);
* ``residuals(y_T, u_T, z)`` -- the boundary conditions at ``T`` that must vanish;
* ``control`` -- the Hamiltonian's maximiser: a :class:`BangBang` law on a switching function
  ``Phi(y)`` (``u = u_on`` where ``Phi > 0``, else ``u_off``) or any callable ``u = law(y)`` for
  interior (smooth) controls.

The system is integrated in normalised time ``tau = t / T`` on ``[0, 1]`` (the right-hand side
multiplied by ``T``), which turns the free final time into an ordinary unknown (Mozzhorina 2017).

Switch handling -- what keeps Newton convergent when the control is discontinuous:

``"interpolate"`` (the paper's, after Fedorenko)
    classical RK4 on ``n_steps`` equal steps; on a step where ``Phi`` changes sign the switch time
    is found by linear interpolation of ``Phi`` and the step is redone with the control averaged
    over it, ``u_avg = u_old (t_sw - t_k-1)/h + u_new (t_k - t_sw)/h``.  The residuals then depend
    continuously on the unknowns (the switch is not snapped to the grid).
``"event"``
    SciPy's DOP853 with the switch located as an event of ``Phi`` (to the integrator's tolerance,
    ``rtol = 1e-12``) and the integration restarted with the new control: the residuals are as
    smooth as the problem, and Newton converges quadratically to ~1e-12.

Newton (:func:`newton`): classical, or damped ("modified": the step is halved until the residual
norm decreases, never longer than the classical Newton step), with the Jacobian by forward finite
differences.  A Jacobian that is singular -- e.g. a guess whose switching function never changes
sign, so the end state does not depend on the adjoints (the paper's warning) -- raises
:class:`SingularJacobianError` with the reason, never a silent garbage answer.

References
----------
T.Yu. Mozzhorina, "Numerical solution to problems of optimal control with switching by
means of the shooting method", 2017 (method, switch interpolation and averaging, Newton);
R.P. Fedorenko, "Approximate solution of optimal control problems", Nauka, 1978.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from descent_fmus.synthesis.methods.shooting_newton import (NoConvergenceError, ShootingError,
                                                           SingularJacobianError, newton)

__all__ = ["BangBang", "PontryaginProblem", "Trajectory", "ShootingResult", "ShootingError",
           "SingularJacobianError", "NoConvergenceError", "integrate", "newton", "solve",
           "METHODS"]

METHODS = ("interpolate", "event")


@dataclass(frozen=True)
class BangBang:
    """Bang-bang maximiser of the Hamiltonian: ``u = u_on`` where ``switching(y) > 0``."""

    switching: Callable[[Sequence[float]], float]
    u_off: float
    u_on: float

    def of(self, phi: float) -> float:
        return self.u_on if phi > 0.0 else self.u_off


@dataclass(frozen=True)
class PontryaginProblem:
    """A Pontryagin boundary-value problem for the shooting method (see the module docstring).

    Attributes
    ----------
    name : str
    rhs : callable ``(y, u) -> sequence``
        ``dy/dt`` of ``y = (x, psi)`` in physical time.
    start : callable ``z -> sequence``
        ``y(0)``.
    final_time : callable ``z -> float``
        ``T`` [time units of ``rhs``].
    residuals : callable ``(y_T, u_T, z) -> sequence``
        Boundary conditions at ``T`` (zero at the solution); as many as unknowns.
    control : BangBang or callable ``y -> float``
    unknowns, residual_names : tuple of str
        Names for messages and reports.
    domain : callable ``z -> str or None``, optional
        A reason if ``z`` is outside the problem's domain (e.g. ``T <= 0``), else None.
    hint : str
        Advice appended to the message of a singular Jacobian (how to choose a guess).
    """

    name: str
    rhs: Callable
    start: Callable
    final_time: Callable
    residuals: Callable
    control: object
    unknowns: tuple
    residual_names: tuple
    domain: Callable | None = None
    hint: str = ""

    def u_of(self, y) -> float:
        c = self.control
        return c.of(c.switching(y)) if isinstance(c, BangBang) else float(c(y))


@dataclass
class Trajectory:
    """One integration of the Pontryagin system.

    ``t`` [time units] and ``y`` (rows = time points) are filled when recorded; ``u`` is the
    control on each interval (averaged on a switching step of the ``interpolate`` method);
    ``switches`` the switch times; ``y_T`` the end point.
    """

    T: float
    y_T: np.ndarray
    u_T: float
    switches: list
    t: np.ndarray | None = None
    y: np.ndarray | None = None
    u: np.ndarray | None = None


@dataclass
class ShootingResult:
    """Outcome of a shooting solve (python-control style: ``.success``, ``.z``, ...)."""

    success: bool
    z: np.ndarray
    residual: np.ndarray
    residual_norm: float          #: max-norm of the residuals at ``z``
    iterations: int               #: Newton steps taken
    initial_residual_norm: float  #: max-norm at the starting guess
    history: list                 #: (z, max-norm) after every step, the guess first
    method: str
    message: str
    trajectory: Trajectory | None = None
    evaluations: int = 0          #: integrations of the Pontryagin system
    extras: dict = field(default_factory=dict)


def _integrate_interpolate(pb: PontryaginProblem, y0, T, n_steps, record):
    """Classical RK4 in tau with the switch interpolated and the control averaged (Fedorenko).

    Works on tuples of floats (models.integrators.rk4_step): for a handful of components this
    is several times faster than NumPy arrays (measured: models/integrators.py).
    """
    from descent_fmus.models.integrators import rk4_step

    h = 1.0 / n_steps
    rhs = pb.rhs

    def f(y, u):
        return tuple(T * v for v in rhs(y, u))

    bang = pb.control if isinstance(pb.control, BangBang) else None
    y = tuple(float(v) for v in y0)
    phi = bang.switching(y) if bang else 0.0
    u = pb.u_of(y)
    switches = []
    ys, us = ([y], []) if record else (None, None)
    for k in range(n_steps):
        y1 = rk4_step(f, y, h, (u,))
        u_step = u
        if bang:
            phi1 = bang.switching(y1)
            u1 = bang.of(phi1)
            if u1 != u and phi1 != phi:
                theta = phi / (phi - phi1)           # linear interpolation of Phi in the step
                theta = min(max(theta, 0.0), 1.0)
                u_step = u * theta + u1 * (1.0 - theta)
                y1 = rk4_step(f, y, h, (u_step,))
                switches.append(T * (k + theta) * h)
                phi1 = bang.switching(y1)
                u1 = bang.of(phi1)
            u, phi = u1, phi1
        else:
            u = pb.u_of(y1)
        y = y1
        if record:
            ys.append(y)
            us.append(u_step)
        if not all(math.isfinite(v) for v in y):
            raise ShootingError(f"{pb.name}: the integration diverged at t = {T * (k + 1) * h:.6g}"
                                f" (non-finite state); the guess is too far from a solution")
    tr = Trajectory(T=T, y_T=np.array(y), u_T=pb.u_of(y), switches=switches)
    if record:
        tr.t = T * np.linspace(0.0, 1.0, n_steps + 1)
        tr.y = np.array(ys)
        tr.u = np.array(us + [us[-1] if us else u])
    return tr


def _integrate_event(pb: PontryaginProblem, y0, T, rtol, atol, record, max_switches=50):
    """DOP853 with the switch located as an event of Phi; the control is piecewise constant."""
    from scipy.integrate import solve_ivp

    y = np.array(y0, dtype=float)
    bang = pb.control if isinstance(pb.control, BangBang) else None
    ts, ys, us = [], [], []
    switches = []
    tau = 0.0
    if bang:
        u = bang.of(bang.switching(y))
        if bang.switching(y) == 0.0:   # on the switch: the side the flow goes to decides
            d = np.asarray(pb.rhs(y, bang.u_on), float)
            u = bang.of(bang.switching(y + 1e-9 * T * d))
    for _ in range(max_switches + 1):
        if bang:
            uu = u

            def f(_tau, yy, uu=uu):
                return T * np.asarray(pb.rhs(yy, uu), dtype=float)

            def ev(_tau, yy):
                return bang.switching(yy)
            ev.terminal = True
            ev.direction = -1.0 if u == bang.u_on else 1.0
            sol = solve_ivp(f, (tau, 1.0), y, method="DOP853", rtol=rtol, atol=atol,
                            events=ev, dense_output=False)
        else:
            def f(_tau, yy):
                return T * np.asarray(pb.rhs(yy, pb.u_of(yy)), dtype=float)
            sol = solve_ivp(f, (tau, 1.0), y, method="DOP853", rtol=rtol, atol=atol)
        if sol.status < 0 or not np.all(np.isfinite(sol.y)):
            raise ShootingError(f"{pb.name}: the integration failed at t = "
                                f"{T * sol.t[-1]:.6g} ({sol.message}); the guess is too far from "
                                f"a solution")
        if record:
            ts.append(sol.t)
            ys.append(sol.y.T)
            us.append(np.full(len(sol.t), pb.u_of(sol.y[:, 0]) if not bang else u))
        y = sol.y[:, -1].copy()
        if bang and sol.status == 1 and sol.t_events[0].size:
            tau = float(sol.t_events[0][0])
            y = np.asarray(sol.y_events[0][0], dtype=float)
            switches.append(T * tau)
            u = bang.u_off if u == bang.u_on else bang.u_on
            if tau >= 1.0:
                break
            continue
        break
    else:
        raise ShootingError(f"{pb.name}: more than {max_switches} switches -- chattering "
                            f"control; the guess is too far from a solution")
    tr = Trajectory(T=T, y_T=y, u_T=pb.u_of(y), switches=switches)
    if record:
        tr.t = T * np.concatenate(ts)
        tr.y = np.concatenate(ys)
        tr.u = np.concatenate(us)
    return tr


def integrate(pb: PontryaginProblem, z, method: str = "event", n_steps: int = 1000,
              rtol: float = 1e-12, atol: float = 1e-12, record: bool = False) -> Trajectory:
    """Integrate the Pontryagin system of ``pb`` for the unknowns ``z`` over ``[0, T]``.

    Parameters
    ----------
    method : {"interpolate", "event"}
        Switch handling (module docstring).
    n_steps : int
        RK4 steps of the ``interpolate`` method (the paper: 1000 -> 0.0164 s).
    rtol, atol : float
        Tolerances of the ``event`` method.
    record : bool
        Keep the whole trajectory (``Trajectory.t``, ``.y``, ``.u``).
    """
    z = np.asarray(z, dtype=float)
    if pb.domain is not None:
        why = pb.domain(z)
        if why:
            raise ShootingError(f"{pb.name}: {why}")
    T = float(pb.final_time(z))
    y0 = pb.start(z)
    if method == "interpolate":
        if int(n_steps) < 2:
            raise ValueError(f"n_steps must be >= 2, got {n_steps}")
        return _integrate_interpolate(pb, y0, T, int(n_steps), record)
    if method == "event":
        return _integrate_event(pb, y0, T, rtol, atol, record)
    raise ValueError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")


def _singular_message(pb, z, tr, sv):
    names = ", ".join(f"{n} = {v:.6g}" for n, v in zip(pb.unknowns, z))
    msg = (f"{pb.name}: the Jacobian of the residuals is singular at {names} "
           f"(singular values {', '.join(f'{s:.3g}' for s in sv)})")
    if isinstance(pb.control, BangBang) and tr is not None and not tr.switches:
        msg += ("; the switching function keeps one sign on the whole [0, T], so the control "
                "never switches and the end state does not depend on the adjoints (the paper's "
                "warning)")
    if pb.hint:
        msg += f". {pb.hint}"
    return msg


def solve(pb: PontryaginProblem, z0, method: str = "event", tol: float | None = None,
          n_steps: int = 1000, damped: bool = False, max_iter: int = 50, rtol: float = 1e-12,
          atol: float = 1e-12, fd_step: float | None = None) -> ShootingResult:
    """Shoot: find the unknowns ``z`` of ``pb`` from the guess ``z0``.

    Parameters
    ----------
    method : {"interpolate", "event"}
        Switch handling (module docstring).
    tol : float, optional
        Max-norm of the residuals to stop at; default 1e-5 for ``interpolate`` (the paper's
        criterion) and 1e-10 for ``event``.
    n_steps : int
        RK4 steps of ``interpolate``.
    damped : bool
        Modified (damped) Newton instead of the classical one.
    fd_step : float, optional
        Relative finite-difference step of the Jacobian; default 1e-7 (``interpolate``) and
        1e-6 (``event``: larger than the integrator's error so the differences are clean).

    Raises
    ------
    SingularJacobianError
        The Jacobian is singular (e.g. no switch for this guess), with the reason.
    ShootingError
        Integration failure, guess outside the domain, or no convergence.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    z0 = np.asarray(z0, dtype=float)
    if z0.shape != (len(pb.unknowns),):
        raise ValueError(f"{pb.name}: need {len(pb.unknowns)} unknowns "
                         f"({', '.join(pb.unknowns)}), got {z0.size}")
    if not np.all(np.isfinite(z0)):
        raise ValueError(f"{pb.name}: the starting guess must be finite, got {z0}")
    if tol is None:
        tol = 1e-5 if method == "interpolate" else 1e-10
    if fd_step is None:
        fd_step = 1e-7 if method == "interpolate" else 1e-6

    last = {}

    def fun(z):
        tr = integrate(pb, z, method, n_steps, rtol, atol)
        last["tr"] = tr
        return np.asarray(pb.residuals(tr.y_T, tr.u_T, z), dtype=float)

    def on_singular(z, sv):
        try:
            tr = integrate(pb, z, method, n_steps, rtol, atol)
        except ShootingError:
            tr = None
        return _singular_message(pb, z, tr, sv)

    out = newton(fun, z0, tol=tol, max_iter=max_iter, damped=damped, fd_step=fd_step,
                 domain=pb.domain, on_singular=on_singular)
    if not out["success"]:
        raise NoConvergenceError(f"{pb.name}: {out['message']} from the guess "
                                 + ", ".join(f"{n} = {v:.6g}" for n, v in zip(pb.unknowns, z0)))
    tr = integrate(pb, out["z"], method, n_steps, rtol, atol, record=True)
    return ShootingResult(success=True, z=out["z"], residual=out["r"],
                          residual_norm=float(np.max(np.abs(out["r"]))),
                          iterations=out["iterations"],
                          initial_residual_norm=out["history"][0][1], history=out["history"],
                          method=method, message=out["message"], trajectory=tr,
                          evaluations=out["evaluations"])
