"""Route tracing (the route problem as a chain of two-point problems) on a plant with a known
answer: a double integrator following the route x = sin t, v = cos t (exactly followed by
u = -sin t).

Sources: closed forms (the route, cubic Hermite interpolation exact for cubics, the dyadic
stages of halving), an independent SciPy solve_ivp (DOP853) run of the whole traced program
checked densely against the route, and Voronov (2009) ch. 3 (the halving rule; a finite chain).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from descent_fmus.synthesis.methods.route import trace_route
from descent_fmus.synthesis.methods.route_problem import (RouteError, RouteNotTracedError,
                                                          RouteProblem, RouteTable, route_values)
from test_direct_method import di_jac, double_integrator

TF = 2.0 * math.pi
EPS = 2e-3


f, jac = double_integrator, di_jac


def sine(t):
    t = np.asarray(t, float)
    return np.stack([np.sin(t), np.cos(t)], -1)


def problem(**kw):
    base = dict(rhs=f, x0=(0.0, 1.0), route=sine, route_index=(0, 1), t0=0.0, tf=TF, eps=EPS,
                n_u=1, jac=jac, intervals=6, dt=0.05)
    base.update(kw)
    return RouteProblem(**base)


def dense_deviation(res, x0=(0.0, 1.0)):
    """Independent check: DOP853 on every linear piece of the traced program, the deviation
    from the route evaluated on 20 points per piece."""
    x = np.array(x0, float)
    tn, P = res.t_nodes, res.controls[:, 0]
    worst = 0.0
    for i in range(len(tn) - 1):
        def rhs(t, y, i=i):
            return f(y, (P[i] + (P[i + 1] - P[i]) * (t - tn[i]) / (tn[i + 1] - tn[i]),))
        ts = np.linspace(tn[i], tn[i + 1], 21)
        sol = solve_ivp(rhs, (tn[i], tn[i + 1]), x, method="DOP853", rtol=1e-12, atol=1e-14,
                        t_eval=ts)
        worst = max(worst, float(np.max(np.abs(sol.y.T - sine(ts)))))
        x = sol.y[:, -1]
    return worst


@pytest.fixture(scope="module")
def halved():
    return trace_route(problem())


def test_halving_traces_the_route_within_eps_everywhere(halved):
    r = halved
    assert r.max_relative_deviation <= 1.0
    # oracle: an independent integration of the whole program, checked densely
    assert dense_deviation(r) <= EPS
    # Voronov (2009): the halving rule gives dyadic stages, and needs more than one here
    lengths = np.diff(r.tau)
    k = np.log2(TF / lengths)
    assert r.n_stages > 1 and np.allclose(k, np.round(k), atol=1e-9)
    assert r.tau[0] == 0.0 and r.tau[-1] == pytest.approx(TF)


def test_controls_are_continuous_across_the_joints(halved):
    for a, b in zip(halved.stages, halved.stages[1:]):
        np.testing.assert_array_equal(a.controls[-1], b.controls[0])
        np.testing.assert_array_equal(a.states[-1], b.states[0])     # the chain of states
    assert halved.controls[0, 0] == 0.0                               # u(t0) = u0 = 0
    # closed form: the route needs u = -sin t; the program is close to it
    assert np.max(np.abs(halved.controls[:, 0] + np.sin(halved.t_nodes))) < 0.2


def test_zero_joints_stop_the_control_at_every_joint():
    r = trace_route(problem(joints="zero"))
    assert r.max_relative_deviation <= 1.0
    for s in r.stages:
        assert s.controls[0, 0] == 0.0 and s.controls[-1, 0] == 0.0
    assert dense_deviation(r) <= EPS


def test_adaptive_rule_traces_the_route_with_stages_on_the_quantum():
    r = trace_route(problem(rule="adaptive", quantum=0.3))
    assert r.max_relative_deviation <= 1.0
    assert dense_deviation(r) <= EPS
    inner = np.diff(r.tau)[:-1]          # every stage but the last is a multiple of the quantum
    assert np.allclose(inner / 0.3, np.round(inner / 0.3), atol=1e-9)


def test_rate_limited_trace_respects_the_limit():
    u_max = 1.0                          # the route needs |u| = |sin t| <= 1; the trace peaks
    assert np.max(np.abs(trace_route(problem()).controls)) > u_max      # above it unlimited
    r = trace_route(problem(u_max=u_max))
    assert r.max_relative_deviation <= 1.0
    assert np.max(np.abs(r.controls)) == u_max                          # the limit binds
    assert dense_deviation(r) <= EPS
    # closed form: while sin t > 0.9 (0.9 s around pi/2) the route's speed grows by
    # 2 sin(0.45) = 0.870, |u| <= 0.9 gives at most 0.81: 0.06 > 2 eps apart -- a bounded failure
    with pytest.raises(RouteNotTracedError, match="cannot be traced") as exc:
        trace_route(problem(u_max=0.9, max_stages=16))
    assert 1 <= len(exc.value.history) <= 2 * 16


def test_minimum_energy_stages():
    r = trace_route(problem(minimize_energy=True))
    assert r.max_relative_deviation <= 1.0
    assert dense_deviation(r) <= EPS


def test_a_table_route_gives_the_same_trace_as_the_function():
    t = np.linspace(0.0, TF, 400)
    table = RouteTable(t, sine(t), np.stack([np.cos(t), -np.sin(t)], -1))
    # closed form: the Hermite cubic between samples 0.016 apart is within h^4/384 |x''''|
    ts = np.linspace(0.0, TF, 1234)
    assert np.max(np.abs(table(ts) - sine(ts))) < 2e-10
    r = trace_route(problem(route=table))
    assert r.max_relative_deviation <= 1.0 and dense_deviation(r) <= EPS


def test_route_table_interpolation_is_exact_for_cubics():
    t = np.array([0.0, 0.7, 1.5, 3.0])
    p = lambda s: 1.0 - 2.0 * s + 0.5 * s ** 2 - 0.25 * s ** 3      # noqa: E731
    dp = lambda s: -2.0 + s - 0.75 * s ** 2                           # noqa: E731
    table = RouteTable(t, p(t)[:, None], dp(t)[:, None])
    s = np.linspace(0.0, 3.0, 50)
    np.testing.assert_allclose(table(s)[:, 0], p(s), atol=1e-13)
    # a spline without rates is exact for the cubic too (not-a-knot, 4 samples)
    np.testing.assert_allclose(RouteTable(t, p(t))(s)[:, 0], p(s), atol=1e-12)
    with pytest.raises(RouteError, match="outside"):
        table(3.5)


def test_route_values_accepts_scalar_functions():
    v = route_values(lambda t: (math.sin(t), math.cos(t)), [0.0, 1.0])
    np.testing.assert_allclose(v, sine([0.0, 1.0]))


@pytest.mark.parametrize("changes, message", [
    (dict(x0=(0.0, 1.1)), "starts away from the initial state"),
    (dict(eps=0.0), "eps must be > 0"),
    (dict(eps=-1e-3), "eps must be > 0"),
    (dict(tf=0.0), "tf > t0"),
    (dict(rule="thirds"), "partition rule"),
    (dict(joints="free"), "joint"),
    (dict(route=lambda t: np.zeros((np.size(t), 3))), "gives 3 values"),
])
def test_ill_posed_problems_are_refused_before_any_solve(changes, message):
    calls = []

    def counted(x, u):
        calls.append(1)
        return f(x, u)
    with pytest.raises(RouteError, match=message):
        trace_route(problem(rhs=counted, **changes))
    assert not calls


def test_bad_route_tables_are_refused():
    with pytest.raises(RouteError, match="increasing"):
        RouteTable([0.0, 0.0, 1.0], np.zeros((3, 2)))
    with pytest.raises(RouteError, match="finite"):
        RouteTable([0.0, 1.0], [[0.0], [math.nan]])
