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
spline).  The problem, the route table and the result are stated in
:mod:`synthesis.methods.route_problem`; this module is the tracer.

References
----------
S.A. Voronov, PhD thesis (2009), ch. 3 (the route problem as a finite chain of two-point
problems; the halving rule), Example 3.
"""
from __future__ import annotations

import math
import time

import numpy as np

from descent_fmus.synthesis.methods.direct_method import (BoundaryProblem, ConvergenceError,
                                                          DirectResult, solve)
from descent_fmus.synthesis.methods.route_problem import (RouteNotTracedError, RouteProblem,
                                                          RouteResult, route_values)

__all__ = ["trace_route"]

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
