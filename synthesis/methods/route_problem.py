"""The route problem's statement: the route (:class:`RouteTable`, :func:`route_values`), the
problem (:class:`RouteProblem`, its checks), the traced route (:class:`RouteResult`) and the
errors; the partition rules and joint choices they name.

The tracer that solves a :class:`RouteProblem` is :func:`synthesis.methods.route.trace_route`
(its docstring states the problem and the rules).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from descent_fmus.synthesis.methods.direct_method import ConvergenceError, control_energy

__all__ = ["RouteTable", "RouteProblem", "RouteResult", "RouteError", "RouteNotTracedError",
           "route_values", "RULES", "JOINTS"]

#: Partition rules and control-joint choices.
RULES = ("halving", "adaptive")
JOINTS = ("continuous", "zero")


class RouteError(ValueError):
    """The route problem is ill-posed (a route starting away from the initial state, eps <= 0,
    an interval of zero length, ...)."""


class RouteNotTracedError(ConvergenceError):
    """No partition within the limits (``max_stages``) keeps the trajectory within ``eps``;
    ``.history`` lists the attempted stages."""


@dataclass(frozen=True)
class RouteTable:
    """A route given by samples: times ``t`` (n,), values (n, r) and optionally their rates
    (n, r) for cubic Hermite interpolation (else a not-a-knot cubic spline).

    Calling it with a time (or an array of times) inside ``[t[0], t[-1]]`` returns the
    interpolated values ((r,) or (len(t), r)).
    """

    t: np.ndarray
    values: np.ndarray
    rates: np.ndarray | None = None

    def __post_init__(self):
        from scipy.interpolate import CubicHermiteSpline, CubicSpline
        t = np.asarray(self.t, float)
        v = np.asarray(self.values, float)
        if v.ndim == 1:
            v = v[:, None]
        if t.ndim != 1 or len(t) < 2 or v.shape[0] != len(t) or not np.all(np.diff(t) > 0):
            raise RouteError("a route table needs >= 2 increasing times and one row of values "
                             "per time")
        if not np.all(np.isfinite(v)):
            raise RouteError("a route table must hold finite values")
        if self.rates is not None:
            r = np.asarray(self.rates, float).reshape(v.shape)
            spline = CubicHermiteSpline(t, v, r, axis=0)
        else:
            spline = CubicSpline(t, v, axis=0)
        object.__setattr__(self, "_spline", spline)

    def __call__(self, t):
        t = np.asarray(t, float)
        lo, hi = float(self.t[0]), float(self.t[-1])
        span = hi - lo
        if np.any(t < lo - 1e-9 * span) or np.any(t > hi + 1e-9 * span):
            raise RouteError(f"time outside the route table [{lo:g}, {hi:g}]")
        return self._spline(np.clip(t, lo, hi))


def route_values(route, times) -> np.ndarray:
    """``route`` at every time of ``times``, shape (len(times), r): one vectorised call if the
    callable accepts an array, else one call per time."""
    times = np.asarray(times, float)
    try:
        v = np.asarray(route(times), float)
        if v.ndim == 2 and v.shape[0] == len(times):
            return v
    except (TypeError, ValueError) as exc:
        if isinstance(exc, RouteError):
            raise
    return np.array([np.atleast_1d(np.asarray(route(float(t)), float)) for t in times])


@dataclass(frozen=True)
class RouteProblem:
    """Trace the route ``route`` (prescribing ``x[route_index]``) within ``eps`` from ``x0``.

    Attributes
    ----------
    rhs : callable
        ``f(x, u)`` on tuples of floats.
    x0 : tuple
        Initial state at ``t0``; ``x0[route_index]`` must be within ``eps`` of ``route(t0)``.
    route : callable
        ``phi(t)`` -> the prescribed components (a :class:`RouteTable` or any function).
    route_index : tuple of int
        The state components the route prescribes.
    t0, tf : float
        The interval [s].
    eps : float or tuple
        Allowed deviation, one value or one per prescribed component (> 0).
    n_u : int
        Number of controls.
    jac : callable or None
        Analytic Jacobian ``jac(X, U) -> (A, B)`` of ``rhs`` (``None``: finite differences).
    intervals : int
        Control intervals per stage (the control is piecewise linear on each stage's grid).
    dt : float
        Largest RK4 sub-step [s]; the deviation is checked on every sub-step.
    tol : float or None
        End accuracy of every stage's two-point problem (default ``min(eps) / 100``).
    joints : {"continuous", "zero"}
        The control at the stage joints (module docstring).
    u0 : tuple or None
        Control at ``t0`` (default zero; ``joints="continuous"`` only).
    rule : {"halving", "adaptive"}
        The partition rule (module docstring).
    max_stages : int
        Bound on the partition: no stage shorter than ``(tf - t0) / max_stages``.
    order : float
        ``adaptive``: assumed order ``p`` of the deviation in the stage length.
    quantum : float or None
        ``adaptive``: stage lengths are whole multiples of this [s] (e.g. the control intervals
        per stage times the RK4 sub-step, so that every control node falls on a grid a replay can
        step on); ``None``: any length.
    u_max, minimize_energy, blend, max_iter
        Passed to every stage's two-point problem (rate limits, minimum energy, end blending,
        iteration limit).
    """

    rhs: object
    x0: tuple
    route: object
    route_index: tuple
    t0: float
    tf: float
    eps: object
    n_u: int
    jac: object = None
    intervals: int = 8
    dt: float = 0.025
    tol: float | None = None
    joints: str = "continuous"
    u0: tuple | None = None
    rule: str = "halving"
    max_stages: int = 256
    order: float = 3.0
    quantum: float | None = None
    u_max: object = None
    minimize_energy: bool = False
    blend: float = 0.1
    max_iter: int = 20

    def validate(self) -> "RouteProblem":
        if not (math.isfinite(self.t0) and math.isfinite(self.tf) and self.tf > self.t0):
            raise RouteError(f"need tf > t0, got t0 = {self.t0}, tf = {self.tf}")
        eps = self.eps_vector()
        if not np.all(np.isfinite(eps)) or np.any(eps <= 0):
            raise RouteError(f"eps must be > 0 (and finite), got {self.eps!r}")
        if self.rule not in RULES:
            raise RouteError(f"unknown partition rule {self.rule!r}; use one of {RULES}")
        if self.joints not in JOINTS:
            raise RouteError(f"unknown joint choice {self.joints!r}; use one of {JOINTS}")
        if self.intervals < 2 or not self.dt > 0 or self.max_stages < 1:
            raise RouteError("need intervals >= 2, dt > 0 and max_stages >= 1")
        if self.quantum is not None and not 0 < self.quantum <= (self.tf - self.t0):
            raise RouteError(f"quantum must be in (0, tf - t0], got {self.quantum}")
        if self.tol is not None and not 0 < self.tol < float(np.min(eps)):
            raise RouteError(f"the stage tolerance must be in (0, eps), got {self.tol}")
        if self.u0 is not None and len(self.u0) != self.n_u:
            raise RouteError(f"u0 needs {self.n_u} values, got {len(self.u0)}")
        if self.u0 is not None and self.joints == "zero" and any(self.u0):
            raise RouteError("joints 'zero' start every stage with u = 0: u0 must be zero")
        start = route_values(self.route, [self.t0])[0]
        if start.shape != (len(self.route_index),):
            raise RouteError(f"the route gives {start.size} values, the problem prescribes "
                             f"{len(self.route_index)} components")
        x0 = np.asarray(self.x0, float)
        off = np.abs(x0[list(self.route_index)] - start) / eps
        if not np.all(np.isfinite(off)) or np.max(off) > 1.0:
            k = int(np.nanargmax(np.where(np.isfinite(off), off, np.inf)))
            raise RouteError(
                f"the route starts away from the initial state: component "
                f"{self.route_index[k]} is {x0[self.route_index[k]]:.6g} at t0 but the route "
                f"has {start[k]:.6g} (|difference| {abs(x0[self.route_index[k]] - start[k]):.3g}"
                f" > eps {eps[k]:.3g})")
        return self

    def eps_vector(self) -> np.ndarray:
        eps = np.asarray(self.eps, float)
        if eps.ndim > 1 or (eps.ndim == 1 and len(eps) != len(self.route_index)):
            raise RouteError(f"eps needs one value or {len(self.route_index)} (one per "
                             f"prescribed component), got {self.eps!r}")
        return np.broadcast_to(eps, (len(self.route_index),)).copy()

    @property
    def stage_tol(self) -> float:
        return self.tol if self.tol is not None else float(np.min(self.eps_vector())) / 100.0


@dataclass
class RouteResult:
    """A traced route.

    Attributes
    ----------
    stages : list of DirectResult
        One per stage, in time order (``t_nodes[0]``, ``t_nodes[-1]`` are its ``tau``).
    t, states : ndarray
        Every RK4 sub-step of the whole motion and the state there.
    deviation : ndarray
        ``|x_S(t) - phi(t)|`` on the sub-steps, (len(t), r).
    mid_deviation : ndarray
        The same between the sub-steps, (len(t) - 1, r): the larger of the deviation at the
        midpoint (cubic Hermite interpolation of the trajectory) and the extremum of the parabola
        through the deviations at the two sub-steps and the midpoint.  The check is on both.
    t_nodes, controls : ndarray
        The whole program: node times and values (piecewise linear between them; the stage
        grids joined, the joint nodes shared).
    seconds : float
        Wall time [s].
    attempts : list of dict
        Every stage solved: ``t0``, ``tf``, ``ok``, ``max_deviation`` (in units of eps, or
        None if the two-point problem failed), ``iterations``, ``reason``.
    eps : ndarray
        The allowed deviation per prescribed component.
    """

    stages: list
    t: np.ndarray
    states: np.ndarray
    deviation: np.ndarray
    t_nodes: np.ndarray
    controls: np.ndarray
    seconds: float
    attempts: list = field(default_factory=list)
    eps: np.ndarray | None = None
    rule: str = "halving"
    mid_deviation: np.ndarray | None = None

    @property
    def n_stages(self) -> int:
        return len(self.stages)

    @property
    def tau(self) -> list:
        """The partition points ``t0 = tau_0 < ... < tau_k = tf``."""
        return [float(s.t_nodes[0]) for s in self.stages] + [float(self.stages[-1].t_nodes[-1])]

    @property
    def max_deviation(self) -> np.ndarray:
        """Largest deviation per prescribed component over the sub-steps and their midpoints."""
        return np.maximum(np.max(self.deviation, axis=0), np.max(self.mid_deviation, axis=0))

    @property
    def max_relative_deviation(self) -> float:
        """Largest deviation in units of eps (<= 1: the route is traced)."""
        return float(np.max(self.max_deviation / self.eps))

    @property
    def energy(self) -> float:
        return control_energy(self.t_nodes, self.controls)

    def control(self, t) -> np.ndarray:
        """u(t) by linear interpolation of the program, shape (len(t), n_u)."""
        t = np.atleast_1d(np.asarray(t, float))
        return np.stack([np.interp(t, self.t_nodes, c) for c in self.controls.T], -1)
