"""S4 route problem, Voronov (2009) ch. 3 Example 3: the tracer follows another craft's
reorientation within eps = 5e-5 on lambda0..3 and omega, in process and through the FMUs.

Sources: Voronov (2009), Example 3 (eps = 5e-5, 32 stages of 1/32 of the interval: the count to
beat; the route craft's two-point problem with u(0) = u(T) = 0); independent SciPy solve_ivp
(DOP853) runs of the programs checked densely against the route; closed forms (the first
integrals, the pyramid's singularity measure); the in-process programs for the FMU replays.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from descent_fmus.models.controllers.program_table import program_values
from descent_fmus.models.integrators import RUNNING
from descent_fmus.models.telescope_dynamics import inertial_momentum, make_rigid_rhs
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.methods.route_problem import RouteError, RouteNotTracedError
from descent_fmus.synthesis.systems.telescope.reorientation import (RateLimitTooSmallError,
                                                                    STATE_NAMES)
from descent_fmus.synthesis.systems.telescope.route import (EPS, PAPER_STAGES, ROUTE_CRAFT,
                                                            ROUTE_LAM_END, ROUTE_T, ROUTE_W_END,
                                                            ROUTE_X0, TRACER, make_route,
                                                            replay_route, trace)
from descent_fmus.synthesis.systems.telescope.wiring import plant_values, wiring


@pytest.fixture(scope="module")
def route():
    return make_route()


@pytest.fixture(scope="module")
def traced(route):
    return trace(route=route)                 # halving, continuous joints (the defaults)


def _dop853_deviation(rt, per_interval=8):
    """Independent check: DOP853 (rtol 1e-11) on every linear piece of the traced program from
    the tracer's initial state; the deviation from the route on ``per_interval`` + 1 points of
    every piece; and the end state."""
    f = make_rigid_rhs(rt.params)
    r = rt.result
    x = np.array(rt.x0, float)
    tn, P = r.t_nodes, r.controls
    worst = 0.0
    for i in range(len(tn) - 1):
        def rhs(t, y, i=i):
            return f(tuple(y), tuple(P[i] + (P[i + 1] - P[i]) * (t - tn[i]) / (tn[i + 1] - tn[i])))
        ts = np.linspace(tn[i], tn[i + 1], per_interval + 1)
        sol = solve_ivp(rhs, (tn[i], tn[i + 1]), x, method="DOP853", rtol=1e-11, atol=1e-13,
                        t_eval=ts)
        worst = max(worst, float(np.max(np.abs(sol.y[:7].T - rt.route.table(ts)))))
        x = sol.y[:, -1]
    return worst, x


def test_the_route_is_the_route_crafts_reorientation(route):
    r = route.result
    # Voronov (2009), Example 3: the route solves the two-point problem (to 1e-7, as Example 1)
    target = np.array(ROUTE_LAM_END + ROUTE_W_END)
    assert np.max(np.abs(r.states[-1, :7] - target)) < 1e-7
    assert np.all(r.controls[0] == 0.0) and np.all(r.controls[-1] == 0.0)
    assert r.controls.shape[1] == ROUTE_CRAFT.n_gyros == 4
    # closed form: the route table passes through the solution's sub-steps
    np.testing.assert_allclose(route.table(r.t[::97]), r.states[::97, :7], atol=1e-15)
    np.testing.assert_allclose(route.table([0.0])[0], ROUTE_X0[:7], atol=1e-15)


def test_example_3_is_traced_within_eps_with_fewer_stages_than_the_thesis(traced):
    r = traced.result
    # Voronov (2009), Example 3: accuracy 5e-5 on lambda0..3, omega; 32 stages
    assert r.max_relative_deviation <= 1.0
    assert 1 < r.n_stages <= PAPER_STAGES
    # halving: dyadic stages
    k = np.log2(ROUTE_T / np.diff(r.tau))
    assert np.allclose(k, np.round(k), atol=1e-9)
    # gimbal rates continuous across the joints, starting from rest
    for a, b in zip(r.stages, r.stages[1:]):
        np.testing.assert_array_equal(a.controls[-1], b.controls[0])
    assert np.all(r.controls[0] == 0.0)


def test_the_trace_holds_in_an_independent_dense_integration(traced):
    # oracle: DOP853 of the whole program, the deviation on 8 points per control interval
    # (between the solver's RK4 sub-steps too)
    worst, x_end = _dop853_deviation(traced)
    assert worst <= EPS
    assert np.max(np.abs(x_end[:7] - traced.result.states[-1, :7])) < 1e-9
    # closed form: the tracer's inertial angular momentum is a first integral
    K0 = inertial_momentum(traced.x0, TRACER)
    assert np.linalg.norm(inertial_momentum(x_end, TRACER) - K0) < 1e-8


def test_tracer_starts_in_the_pyramids_symmetric_state(traced):
    s = traced.summary()
    # closed form: six gyrodynes at 20 deg from the height, beta = 0 (tangential rotors):
    # C C^T = h^2 diag(3 cos^2 a, 3 cos^2 a, 6 sin^2 a) -> det/h^6 = 54 cos^4 a sin^2 a
    a = np.radians(20.0)
    assert s["sing_min"] <= 54 * np.cos(a) ** 4 * np.sin(a) ** 2 + 1e-12
    assert s["sing_min"] > 1.0                       # far from a singular gimbal state
    assert s["momentum_drift"] < 1e-9


def test_fmu_replay_of_the_trace_stays_within_eps(traced, fmu_dir):
    # oracle: the in-process trace -- ProgramController (node times of the stages) + Telescope
    # (the tracer's six-gyrodyne pyramid as parameters) by fmpy
    rep = replay_route(traced, fmu_dir)
    assert rep["replay_max_deviation"] <= EPS
    assert rep["replay_error_vs_solver"] < 1e-10
    assert rep["replay_status"] == RUNNING


def test_the_route_crafts_program_through_the_same_plant_fmu(route, fmu_dir):
    # the plant FMU parameterised as the four-gyrodyne route craft replays its program
    r = route.result
    names = list(STATE_NAMES)
    with ClosedLoop(wiring("Telescope"), fmu_dir / "Telescope.fmu",
                    fmu_dir / "ProgramController.fmu") as cl:
        out = cl.run(plant_values=plant_values(ROUTE_CRAFT, dt=float(r.t[1] - r.t[0]),
                                               state=ROUTE_X0),
                     controller_values=program_values(ROUTE_T, r.controls), stop_time=ROUTE_T,
                     step=0.5)
    final = np.array([out.final[n] for n in names])
    # oracle: the in-process solution (same RK4 sub-steps, first-order hold)
    assert np.max(np.abs(final - r.states[-1, :7])) < 1e-12
    assert out.final["beta5"] == 0.0 and out.final["beta6"] == 0.0       # not in use


def test_rate_limited_route(route):
    u_max = 0.03                         # rad/s; the unlimited trace peaks at ~0.043
    rt = trace(route=route, rule="adaptive", u_max=u_max)
    r = rt.result
    assert r.max_relative_deviation <= 1.0 and r.n_stages <= PAPER_STAGES
    assert np.max(np.abs(r.controls)) == u_max           # binds; linear between the nodes
    worst, _ = _dop853_deviation(rt, per_interval=4)
    assert worst <= EPS


def test_bad_route_problems_end_with_a_message(route):
    with pytest.raises(RouteError, match="starts away from the initial state"):
        trace(route=route, w0=(0.0, np.radians(0.3), 0.0))
    with pytest.raises(RouteError, match="eps must be > 0"):
        trace(route=route, eps=0.0)
    # closed form: a rate limit too small to follow the route's gyro momentum is refused before
    # tracing (a limit that passes it but is still too small ends after a bounded number of
    # halvings: tests/methods/test_route.py)
    with pytest.raises(RateLimitTooSmallError, match="too small for the route"):
        trace(route=route, u_max=0.005)
    with pytest.raises(RouteNotTracedError, match="cannot be traced"):
        trace(route=route, u_max=0.015, max_stages=1)
