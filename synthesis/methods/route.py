"""Route tracing: programmed motion along a prescribed trajectory, as a chain of two-point
problems solved by the direct method.

Problem (Voronov 2009, ch. 3, "the route problem"): a route ``phi(t)``, ``t in [t0, tf]``,
prescribes some components of the state (``route_index``); its ``eps``-neighbourhood is where
they may go.  Find a control ``u(t)`` whose trajectory of

    dx/dt = f(x, u),   x(t0) = x0   (x0 on the route)

stays in the neighbourhood on the whole of ``[t0, tf]``.  The interval is split by points
``tau_i``; on every stage the direct method (:mod:`synthesis.methods.direct_method`) solves the
two-point problem ``x(tau_{i-1}) -> x_S(tau_i) = phi(tau_i)`` from the state the previous stage
ended in; the split is chosen so that every stage's trajectory stays within ``eps`` of the route
(checked on every RK4 sub-step and between them -- the midpoints by cubic Hermite interpolation
of the trajectory, the peak of the parabola through the three deviations -- not only at the
``tau_i``), with as few stages as possible.

Partition rules:

``"halving"`` (the thesis' simplest rule)
    solve on the whole interval; where a stage's trajectory leaves the neighbourhood, halve that
    stage and solve both halves (the first from the stage's start, the second from where the
    first ended); repeat.  Finite by continuity; the stages are dyadic.
``"adaptive"``
    march from ``t0``: try a stage, and size the next attempt from the deviation just measured,
    as a step-size controller does: ``L_new = L (0.9 / d)^(1/p)`` with ``d`` the stage's largest
    deviation in units of ``eps`` and ``p`` the order of the deviation in the stage length
    (clipped to ``[L/4, 2 L]``).  A stage that fails is retried shorter; one that passes lets the
    next one grow.  Stages are not dyadic, so fewer of them are needed where the route is easy.

Control at the stage joints ([choice] ``joints``):

``"continuous"`` (default)
    a stage starts with the control the previous one ended with (its first node is kept), and
    its end value is free (the correction basis is blended to 0 at the stage start only): the
    gimbal rates are continuous across the joints, as torque motors need, and nothing forces
    them to stop at every joint.
``"zero"``
    every stage starts and ends with ``u = 0`` (the thesis' two-point problem as it stands,
    ``u(tau_i) = 0``): continuous too, but the motion stops being driven at every joint.

The route is any callable ``phi(t) -> values`` (one value per prescribed component), or a
:class:`RouteTable` of samples (cubic Hermite interpolation when rates are given, else a cubic
spline).

References
----------
S.A. Voronov, PhD thesis (2009), ch. 3 (the route problem as a finite chain of two-point
problems; the halving rule), Example 3.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from descent_fmus.synthesis.methods.direct_method import (BoundaryProblem, ConvergenceError,
                                                          DirectResult, control_energy, solve)

__all__ = ["RouteTable", "RouteProblem", "RouteResult", "RouteError", "RouteNotTracedError",
           "trace_route", "route_values", "RULES", "JOINTS"]

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


def _deviation(pb: RouteProblem, t, X, U):
    """``|x_S - phi|`` on the sub-steps ``t`` (len(t), r) and between them (len(t) - 1, r).

    Between two sub-steps: the trajectory at the midpoint by cubic Hermite interpolation with
    the rates ``f(x, u)`` (error O(h^4)), the route there, and the extremum of the parabola
    through the signed deviations at the two sub-steps and the midpoint (a peak between samples
    is caught to O(h^3)); the larger of the midpoint and the extremum.
    """
    idx = list(pb.route_index)
    F = np.array([pb.rhs(tuple(x), tuple(u)) for x, u in zip(X, U)])[:, idx]
    Xs = X[:, idx]
    h = np.diff(t)[:, None]
    mid = 0.5 * (Xs[:-1] + Xs[1:]) + (h / 8.0) * (F[:-1] - F[1:])
    tt = np.concatenate([t, 0.5 * (t[:-1] + t[1:])])
    phi = route_values(pb.route, tt)
    e = Xs - phi[:len(t)]
    em = mid - phi[len(t):]
    e0, e1 = e[:-1], e[1:]
    b, a = 0.5 * (e1 - e0), 0.5 * (e1 + e0) - em           # p(s) = em + b s + a s^2, |s| <= 1
    with np.errstate(divide="ignore", invalid="ignore"):
        s_star = np.where(a != 0.0, -b / (2.0 * a), 2.0)
        peak = np.where(np.abs(s_star) < 1.0, em - b * b / (4.0 * a), 0.0)
    return np.abs(e), np.maximum(np.abs(em), np.abs(peak))


def _substeps(span: float, intervals: int, dt: float) -> int:
    return max(2, 2 * int(math.ceil(span / intervals / dt / 2 - 1e-9)))


class _Tracer:
    """Solves stages and keeps the record of attempts."""

    def __init__(self, pb: RouteProblem):
        self.pb = pb
        self.eps = pb.eps_vector()
        self.idx = list(pb.route_index)
        self.attempts = []
        self.min_len = (pb.tf - pb.t0) / pb.max_stages * (1 - 1e-9)
        if pb.rule == "adaptive" and pb.quantum:
            self.min_len = max(self.min_len, pb.quantum * (1 - 1e-9))

    def stage(self, a: float, b: float, x_a, u_a):
        """Solve the stage [a, b] from ``x_a`` with the control starting at ``u_a``; returns
        (DirectResult or None, deviation in units of eps, reason)."""
        pb = self.pb
        target = route_values(pb.route, [b])[0]
        cont = pb.joints == "continuous"
        n = pb.intervals
        bp = BoundaryProblem(rhs=pb.rhs, x0=tuple(x_a), t0=a, tf=b,
                             target_index=tuple(pb.route_index), target_value=tuple(target),
                             n_u=pb.n_u, intervals=n, substeps=_substeps(b - a, n, pb.dt),
                             blend=pb.blend, jac=pb.jac, free_end=cont, u_max=pb.u_max,
                             minimize_energy=pb.minimize_energy)
        guess = np.tile(np.asarray(u_a, float), (n + 1, 1)) if cont else None
        try:
            res = solve(bp, controls=guess, tol=pb.stage_tol, max_iter=pb.max_iter)
        except ConvergenceError as exc:           # includes a singular Gram system
            rec = dict(t0=a, tf=b, ok=False, max_deviation=None, iterations=None,
                       reason=f"two-point problem failed: {exc}")
            self.attempts.append(rec)
            return None, math.inf, rec["reason"]
        d = max(float(np.max(v / self.eps))
                for v in _deviation(pb, res.t, res.states, res.control(res.t)))
        ok = d <= 1.0
        self.attempts.append(dict(t0=a, tf=b, ok=ok, max_deviation=d, iterations=res.iterations,
                                  reason="" if ok else "left the eps-neighbourhood"))
        return res, d, ("" if ok else "left the eps-neighbourhood")

    def give_up(self, a, b, reason):
        raise RouteNotTracedError(
            f"the route cannot be traced within eps: the stage [{a:g}, {b:g}] s "
            f"({reason}) would need stages shorter than (tf - t0)/max_stages = "
            f"{self.min_len:.4g} s", self.attempts)

    @staticmethod
    def end_of(res: DirectResult):
        return tuple(res.states[-1]), tuple(res.controls[-1])

    def halving(self, a, b, x_a, u_a):
        res, d, why = self.stage(a, b, x_a, u_a)
        if res is not None and d <= 1.0:
            return [res]
        m = 0.5 * (a + b)
        if m - a < self.min_len:
            self.give_up(a, b, why)
        left = self.halving(a, m, x_a, u_a)
        x_m, u_m = self.end_of(left[-1])
        return left + self.halving(m, b, x_m, u_m)

    def adaptive(self, x0, u0):
        pb = self.pb
        a, x_a, u_a = pb.t0, x0, u0
        L = pb.tf - pb.t0
        out = []
        q = pb.quantum
        while a < pb.tf - 1e-12 * (pb.tf - pb.t0):
            if q:
                L = max(q, round(L / q) * q)
            b = min(pb.tf, a + L)
            if pb.tf - b < 0.25 * L:            # no sliver at the end
                b = pb.tf
            res, d, why = self.stage(a, b, x_a, u_a)
            grow = 0.9 * (1.0 / d) ** (1.0 / pb.order) if d > 0 else 2.0
            if res is not None and d <= 1.0:
                out.append(res)
                x_a, u_a = self.end_of(res)
                L = (b - a) * min(2.0, max(1.0, grow))
                a = b
                continue
            if b - a <= self.min_len:
                self.give_up(a, b, why)
            L = max(self.min_len, (b - a) * (min(0.5, max(0.25, grow)) if d < math.inf else 0.5))
        return out


def trace_route(problem: RouteProblem) -> RouteResult:
    """Trace the route (module docstring): split ``[t0, tf]`` by the partition rule, solve every
    stage by the direct method, check the deviation on every sub-step.

    Raises
    ------
    RouteError
        An ill-posed problem (route away from the initial state, eps <= 0, ...), before any solve.
    RouteNotTracedError
        No partition within ``max_stages`` keeps the trajectory within eps.
    """
    t_start = time.perf_counter()
    pb = problem.validate()
    tracer = _Tracer(pb)
    u0 = tuple(float(v) for v in pb.u0) if pb.u0 is not None else (0.0,) * pb.n_u
    x0 = tuple(float(v) for v in pb.x0)
    if pb.rule == "halving":
        stages = tracer.halving(pb.t0, pb.tf, x0, u0)
    else:
        stages = tracer.adaptive(x0, u0)
    ts = [stages[0].t[:1]] + [s.t[1:] for s in stages]
    xs = [stages[0].states[:1]] + [s.states[1:] for s in stages]
    tn = [stages[0].t_nodes[:1]] + [s.t_nodes[1:] for s in stages]
    un = [stages[0].controls[:1]] + [s.controls[1:] for s in stages]
    t, X = np.concatenate(ts), np.concatenate(xs)
    t_nodes, controls = np.concatenate(tn), np.concatenate(un)
    U = np.stack([np.interp(t, t_nodes, c) for c in controls.T], -1)
    dev, between = _deviation(pb, t, X, U)
    return RouteResult(stages=stages, t=t, states=X, deviation=dev, t_nodes=t_nodes,
                       controls=controls, seconds=time.perf_counter() - t_start,
                       attempts=tracer.attempts, eps=tracer.eps, rule=pb.rule,
                       mid_deviation=between)
