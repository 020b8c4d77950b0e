"""The direct (Newton-Kantorovich) method on problems with known answers.

Sources: closed forms (linear systems: one Newton step is exact; a rotation angle with the
first integral x1^2 + x2^2 = 1), an independent SciPy solve_ivp (DOP853) run of the computed
control, and Voronov (2009) ch. 2 for the end-blended basis (u(t0) = u(tf) = 0).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from descent_fmus.synthesis.methods.direct_method import (BoundaryProblem, ConvergenceError,
                                                          blend_window, simulate, solve)


def double_integrator(x, u):
    return (x[1], u[0])


def di_jac(X, U):
    n = len(X)
    A = np.zeros((n, 2, 2))
    A[:, 0, 1] = 1.0
    B = np.zeros((n, 2, 1))
    B[:, 1, 0] = 1.0
    return A, B


def test_blend_window_vanishes_at_both_ends_and_is_one_inside():
    t = np.linspace(0, 10, 101)
    w = blend_window(t, 0.0, 10.0, 0.2)
    assert w[0] == 0.0 and w[-1] == 0.0                     # Voronov (2009): du(t0) = du(tf) = 0
    assert np.all(w[20:81] == 1.0)
    assert np.all(np.diff(w[:21]) >= 0) and np.all(w >= 0) and np.all(w <= 1)


def test_linear_system_is_solved_in_one_iteration():
    # closed form: for a linear system the Newton step is exact (up to rounding)
    pb = BoundaryProblem(rhs=double_integrator, x0=(0.0, 0.0), tf=2.0, target_index=(0, 1),
                         target_value=(1.0, 0.0), n_u=1, intervals=20, substeps=4, jac=di_jac)
    res = solve(pb, tol=1e-10)
    assert res.iterations == 1
    assert res.max_miss < 1e-12
    assert res.controls[0, 0] == 0.0 and res.controls[-1, 0] == 0.0


def test_finite_difference_jacobian_gives_the_same_solution():
    pb = BoundaryProblem(rhs=double_integrator, x0=(0.0, 0.0), tf=2.0, target_index=(0, 1),
                         target_value=(1.0, 0.0), n_u=1, intervals=20, substeps=4)
    res_fd = solve(pb, tol=1e-10)
    pb2 = BoundaryProblem(rhs=double_integrator, x0=(0.0, 0.0), tf=2.0, target_index=(0, 1),
                          target_value=(1.0, 0.0), n_u=1, intervals=20, substeps=4, jac=di_jac)
    res = solve(pb2, tol=1e-10)
    np.testing.assert_allclose(res_fd.controls, res.controls, atol=1e-7)


def pendulum(x, u):
    # driven damped pendulum: theta'' = -sin(theta) - 0.1 theta' + u
    return (x[1], -math.sin(x[0]) - 0.1 * x[1] + u[0])


def test_nonlinear_pendulum_swing_matches_independent_solve_ivp():
    target = (math.pi / 2, 0.0)
    pb = BoundaryProblem(rhs=pendulum, x0=(0.0, 0.0), tf=5.0, target_index=(0, 1),
                         target_value=target, n_u=1, intervals=25, substeps=16)
    res = solve(pb, tol=1e-9)
    assert res.iterations <= 6
    assert res.max_miss < 1e-9

    # independent check: DOP853 (rtol 1e-12) on each linear piece of the computed control; the
    # difference is the RK4 error of the solver's sub-steps (h = 0.0125 s)
    x = np.array([0.0, 0.0])
    tn, P = res.t_nodes, res.controls[:, 0]
    for i in range(len(tn) - 1):
        def f(t, y, i=i):
            u = P[i] + (P[i + 1] - P[i]) * (t - tn[i]) / (tn[i + 1] - tn[i])
            return pendulum(y, (u,))
        x = solve_ivp(f, (tn[i], tn[i + 1]), x, method="DOP853", rtol=1e-12, atol=1e-13).y[:, -1]
    assert np.max(np.abs(x - np.array(target))) < 1e-8


def rotor(x, u):
    # a unit vector turned by the rate u: first integral x1^2 + x2^2 = 1 -> rank-1 end conditions
    return (-x[1] * u[0], x[0] * u[0])


def test_dependent_end_conditions_are_selected_adaptively():
    a = 1.0  # rad; closed form: theta(T) = integral of u = a
    pb = BoundaryProblem(rhs=rotor, x0=(1.0, 0.0), tf=1.0, target_index=(0, 1),
                         target_value=(math.cos(a), math.sin(a)), n_u=1, intervals=10, substeps=20)
    # (fine sub-steps: RK4 must keep x1^2 + x2^2 = 1 to << 1e-10, else the target is off the
    # discrete system's invariant circle)
    res = solve(pb, tol=1e-10)
    assert res.max_miss < 1e-10
    assert all(len(h["selected"]) == 1 for h in res.history[1:])   # rank 1, one row kept
    # closed form: the turned angle is the integral of the piecewise-linear u (trapezoid)
    u, t = res.controls[:, 0], res.t_nodes
    assert float(np.sum(0.5 * (u[1:] + u[:-1]) * np.diff(t))) == pytest.approx(a, abs=1e-9)


def test_uncontrollable_component_stops_with_an_error_not_a_loop():
    def f(x, u):
        return (u[0], 0.0)          # x2 cannot be steered
    pb = BoundaryProblem(rhs=f, x0=(0.0, 0.0), tf=1.0, target_index=(0, 1),
                         target_value=(1.0, 1.0), n_u=1, intervals=4, substeps=2)
    with pytest.raises(ConvergenceError) as exc:
        solve(pb, tol=1e-8, max_iter=5)
    assert exc.value.history


def test_simulate_uses_linear_control_within_intervals():
    # x' = u with u linear from 0 to 1 over [0, 1]: x(1) = 0.5 exactly (RK4 is exact here)
    t, X, U = simulate(lambda x, u: (u[0],), (0.0,), np.array([0.0, 1.0]),
                       np.array([[0.0], [1.0]]), 4)
    assert X[-1, 0] == pytest.approx(0.5, abs=1e-15)
    np.testing.assert_allclose(U[:, 0], [0, 0.25, 0.5, 0.75, 1.0])


def test_bad_problem_definitions_are_rejected():
    with pytest.raises(ValueError, match="even number of substeps"):
        BoundaryProblem(rhs=rotor, x0=(1.0, 0.0), tf=1.0, target_index=(0,), target_value=(1,),
                        n_u=1, substeps=3).validate()
    with pytest.raises(ValueError, match="tf > t0"):
        BoundaryProblem(rhs=rotor, x0=(1.0, 0.0), tf=-1.0, target_index=(0,),
                        target_value=(1,), n_u=1).validate()
