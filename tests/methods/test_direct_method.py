"""The direct (Newton-Kantorovich) method on problems with known answers.

Sources: closed forms (linear systems: one Newton step is exact; a rotation angle with the
first integral x1^2 + x2^2 = 1; the minimum-energy control of a double integrator in the
piecewise-linear class; the energy of piecewise-linear controls), an independent SciPy solve_ivp
(DOP853) run of the computed control, and Voronov (2009) ch. 2 for the end-blended basis
(u(t0) = u(tf) = 0).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from descent_fmus.synthesis.methods.direct_method import (BoundaryProblem, ConvergenceError,
                                                          SaturatedError, blend_window,
                                                          control_energy, mass_matrix, simulate,
                                                          solve)


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


# -- rate limits and minimum energy ---------------------------------------------------------------
def _di_problem(**kw):
    return BoundaryProblem(rhs=double_integrator, x0=(0.0, 0.0), tf=2.0, target_index=(0, 1),
                           target_value=(1.0, 0.0), n_u=1, intervals=20, substeps=4, jac=di_jac,
                           **kw)


def _di_replay(res):
    # independent: DOP853 on every linear piece of the computed control
    x = np.array([0.0, 0.0])
    tn, P = res.t_nodes, res.controls[:, 0]
    for i in range(len(tn) - 1):
        def f(t, y, i=i):
            return double_integrator(y, (P[i] + (P[i + 1] - P[i]) * (t - tn[i])
                                         / (tn[i + 1] - tn[i]),))
        x = solve_ivp(f, (tn[i], tn[i + 1]), x, method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]
    return x


def test_control_energy_and_mass_matrix_closed_forms():
    # closed form: u = c on [0, T] -> c^2 T; u linear 0 -> 1 on [0, 1] -> 1/3
    assert control_energy([0.0, 2.0, 5.0], [[3.0], [3.0], [3.0]]) == pytest.approx(45.0)
    assert control_energy([0.0, 1.0], [[0.0], [1.0]]) == pytest.approx(1.0 / 3.0)
    p = np.array([0.3, -1.0, 2.0, 0.5])
    t = np.array([0.0, 0.5, 1.5, 1.75])
    assert p @ mass_matrix(t) @ p == pytest.approx(control_energy(t, p[:, None]), rel=1e-14)


def test_one_sided_blend_window_keeps_the_end_free():
    w = blend_window(np.linspace(0, 10, 101), 0.0, 10.0, 0.2, at_end=False)
    assert w[0] == 0.0 and np.all(w[20:] == 1.0)


def test_rate_limit_is_respected_everywhere_and_the_target_reached():
    free = solve(_di_problem(), tol=1e-10)
    u_max = 1.3                              # below the unconstrained peak
    assert np.max(np.abs(free.controls)) > 1.6
    res = solve(_di_problem(u_max=u_max), tol=1e-10)
    # piecewise linear between nodes within the limit: within it everywhere
    assert np.max(np.abs(res.controls)) == pytest.approx(u_max, abs=1e-15)
    assert np.all(np.abs(res.controls) <= u_max)
    assert res.controls[0, 0] == 0.0 and res.controls[-1, 0] == 0.0
    # oracle: an independent DOP853 run of the limited control hits the target
    np.testing.assert_allclose(_di_replay(res), [1.0, 0.0], atol=1e-10)


def test_too_small_rate_limit_stops_with_an_error_after_bounded_work():
    # closed form: |u| <= 0.5 moves the mass at most 0.5 * 1^2 = 0.5 < 1 in 2 s
    with pytest.raises(SaturatedError, match="too small") as exc:
        solve(_di_problem(u_max=0.5), tol=1e-10, max_iter=20)
    assert len(exc.value.history) <= 21
    with pytest.raises(ValueError, match="u_max"):
        _di_problem(u_max=-1.0).validate()


def test_minimum_energy_control_is_the_closed_form_optimum():
    res = solve(_di_problem(minimize_energy=True), tol=1e-10)
    # oracle (closed form for the piecewise-linear class): x(T) and v(T) are linear in the
    # interior node values p_i (v(T) = sum p_i dt, x(T) = sum p_i (T - t_i) dt, the hat
    # functions' integrals), the energy is p^T M p; the optimum of the equality-constrained
    # quadratic programme is p = M^-1 G^T (G M^-1 G^T)^-1 b
    t = np.linspace(0.0, 2.0, 21)
    dt = t[1] - t[0]
    G = np.stack([np.full(19, dt), (2.0 - t[1:-1]) * dt])
    M = mass_matrix(t)[1:-1, 1:-1]
    Mi_Gt = np.linalg.solve(M, G.T)
    p = Mi_Gt @ np.linalg.solve(G @ Mi_Gt, [0.0, 1.0])          # v(T) = 0, x(T) = 1
    np.testing.assert_allclose(res.controls[1:-1, 0], p, atol=1e-10)
    assert res.controls[0, 0] == 0.0 and res.controls[-1, 0] == 0.0
    assert res.energy == pytest.approx(p @ M @ p, rel=1e-10)
    # and it is less than the plain method's (a feasible, not minimal) control
    assert res.energy < solve(_di_problem(), tol=1e-10).energy
    np.testing.assert_allclose(_di_replay(res), [1.0, 0.0], atol=1e-10)


def test_minimum_energy_on_a_nonlinear_plant_satisfies_the_optimality_conditions():
    # the pendulum swing with least energy: the end conditions met, and the energy is
    # stationary -- a small feasible perturbation (restored by the plain method) costs more
    pb = BoundaryProblem(rhs=pendulum, x0=(0.0, 0.0), tf=5.0, target_index=(0, 1),
                         target_value=(math.pi / 2, 0.0), n_u=1, intervals=25, substeps=16,
                         minimize_energy=True)
    res = solve(pb, tol=1e-9)
    assert res.max_miss < 1e-9
    plain = solve(BoundaryProblem(rhs=pendulum, x0=(0.0, 0.0), tf=5.0, target_index=(0, 1),
                                  target_value=(math.pi / 2, 0.0), n_u=1, intervals=25,
                                  substeps=16), tol=1e-9)
    assert res.energy < plain.energy
    rng = np.random.default_rng(3)
    for _ in range(3):
        guess = res.controls.copy()
        guess[1:-1] += 0.02 * rng.standard_normal(guess[1:-1].shape)
        other = solve(BoundaryProblem(rhs=pendulum, x0=(0.0, 0.0), tf=5.0, target_index=(0, 1),
                                      target_value=(math.pi / 2, 0.0), n_u=1, intervals=25,
                                      substeps=16), controls=guess, tol=1e-9)
        assert other.energy > res.energy
