"""S1 plant: the Reentry FMU against an independent high-accuracy integration.

Oracle: scipy.integrate.solve_ivp (DOP853, rtol 1e-10) of the same right-hand side
(models.reentry.rhs) with an event at h = hf -- an independent integrator and event locator.
Acceptance bar: landing range within 20 m, max load within 1e-4 relative.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy import simulate_fmu
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

from descent_fmus.models.fmu_support import ParameterError
from descent_fmus.models.reentry import (ReentryParams, altitude, downrange, initial_state, loads, rhs,
                            simulate)
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law

P = ReentryParams()


def reference(u: float, p: ReentryParams = P):
    """Landing range, landing time and max load by DOP853 + dense output + refinement."""
    args = (u,) + p.constants()
    kd = p.constants()[1]

    def f(t, x):
        return rhs(tuple(x), *args)

    def hit(t, x):
        return math.hypot(x[0], x[2]) - p.Rz - p.hf
    hit.terminal, hit.direction = True, -1
    sol = solve_ivp(f, (0.0, 300.0), initial_state(p), method="DOP853", rtol=1e-10, atol=1e-6,
                    events=hit, dense_output=True)
    t_land = sol.t_events[0][0]
    x_land = sol.y_events[0][0]

    def load(t):
        x = tuple(sol.sol(t))
        return loads(x, rhs(x, *args), kd, p.lam, p.Rz, p.g0, u)[0]
    grid = np.linspace(0.0, t_land, 20001)
    vals = np.array([load(t) for t in grid])
    k = int(np.argmax(vals))
    if 0 < k < len(grid) - 1:
        res = minimize_scalar(lambda t: -load(t), bounds=(grid[k - 1], grid[k + 1]),
                              method="bounded", options={"xatol": 1e-6})
        jmax = max(-res.fun, vals[k])
    else:
        jmax = vals[k]
    return downrange(x_land, p.Rz), t_land, jmax


@pytest.mark.parametrize("u", [0.0, 0.2, -0.2])
def test_fmu_matches_solve_ivp(fmu_dir, u):
    L_ref, t_ref, j_ref = reference(u)
    res = simulate_fmu(str(fmu_dir / "Reentry.fmu"), start_values={"u": u}, stop_time=300.0,
                       output_interval=1.0, output=["L", "h", "load_max", "t_end", "status"])
    last = res[-1]
    assert last["status"] == 1                     # REACHED: h = hf
    # range at landing within 20 m of the DOP853 oracle
    assert abs(last["L"] - L_ref) < 20.0
    # the state stops exactly at hf (crossing located inside the step)
    assert abs(last["h"] - P.hf) < 1e-3
    assert abs(last["t_end"] - t_ref) < 1e-3
    # max load within 1e-4 relative of the oracle
    assert abs(last["load_max"] - j_ref) / j_ref < 1e-4


def test_uncontrolled_flight_lands_about_10_km_short():
    # reference point of the default scenario (independent high-accuracy integration when the
    # scenario was chosen): with u = 0 the capsule lands ~10 km short of Lf = 1400 km
    fi = simulate(P, lambda t, x: 0.0)
    short = P.Lf - downrange(fi.x, P.Rz)
    assert 8_000.0 < short < 12_000.0
    assert 260.0 < fi.t_end < 290.0           # the flight takes ~275 s


def test_rhs_at_a_point_matches_the_spec_formula():
    # eqs. (2)/(4) of Diveev & Shmalko evaluated by hand at x = (0, 7000, Rz + 50 km, -100), u = 0.1
    x = (0.0, 7000.0, P.Rz + 50_000.0, -100.0)
    r = P.Rz + 50_000.0
    v = math.hypot(7000.0, -100.0)
    drag = 1.1 * P.S * P.rho0 / P.m * v * math.exp(-P.lam * 50_000.0)
    expect = (7000.0, -drag * 7000.0, -100.0, -P.g0 * P.Rz ** 2 / r ** 2 - drag * (-100.0))
    got = rhs(x, 0.1, *P.constants())
    assert np.allclose(got, expect, rtol=1e-14, atol=1e-12)
    assert altitude(x, P.Rz) == pytest.approx(50_000.0, abs=1e-6)


@pytest.mark.parametrize("field, value, words", [
    ("m", -1.0, "m must be > 0"), ("rho0", math.nan, "rho0 must be finite"),
    ("hf", 2e5, "hf must satisfy"), ("beta0", 2.0, "beta0 must be in")])
def test_bad_parameters_in_process(field, value, words):
    with pytest.raises(ParameterError, match=words):
        ReentryParams(**{field: value}).validate()


def test_true_peak_of_a_sampled_flight_matches_solve_ivp(fmu_dir):
    # The basic law through the FMUs (1 s zero-order hold): the plant's load_max is the maximum
    # over time of the flight that happens, both one-sided loads at every control change
    # included.  Oracle: DOP853 (rtol 1e-12) re-integration with the same held controls, the
    # load on a 0.01 s grid of every hold interval plus both ends of it (the jumps).
    from descent_fmus.synthesis.systems.reentry.flight import fly
    f = fly(paper_basic_law(), fmu_dir=fmu_dir, record=True)
    u = f.result["ctrl.u[1]"]
    kd = P.constants()[1]
    x, peak = np.array(initial_state(P)), 0.0

    def hit(t, x):
        return math.hypot(x[0], x[2]) - P.Rz - P.hf
    hit.terminal, hit.direction = True, -1
    for k, uk in enumerate(u):
        args = (float(uk),) + P.constants()
        sol = solve_ivp(lambda t, y: rhs(tuple(y), *args), (k, k + 1.0), x, method="DOP853",
                        rtol=1e-12, atol=1e-8, events=hit, dense_output=True)
        for t in np.linspace(k, sol.t[-1], 101):
            y = tuple(sol.sol(t))
            peak = max(peak, loads(y, rhs(y, *args), kd, P.lam, P.Rz, P.g0, float(uk))[0])
        x = sol.y[:, -1]
        if sol.status == 1:
            break
    assert f.objectives["J1"] == pytest.approx(peak, rel=1e-4)
    # the true peak of the basic law is 8.820 (the right-hand values alone gave 8.765)
    assert peak == pytest.approx(8.820, abs=1e-3)


def test_rhs_jacobians_match_central_differences():
    # the hand-differentiated right-hand side (used by the open-loop bound's sensitivities)
    # against central differences of rhs itself, at a point of the entry corridor
    from descent_fmus.models.reentry import rhs_jacobians
    x, u, c = (3.0e5, 7200.0, P.Rz + 6.0e4, -350.0), 0.13, P.constants()
    fx, fu = rhs_jacobians(x, u, *c)
    for j, h in enumerate((1.0, 1e-3, 1.0, 1e-3)):
        xp, xm = list(x), list(x)
        xp[j] += h
        xm[j] -= h
        col = (np.array(rhs(tuple(xp), u, *c)) - np.array(rhs(tuple(xm), u, *c))) / (2 * h)
        assert np.allclose([row[j] for row in fx], col, rtol=1e-6, atol=1e-12)
    du = (np.array(rhs(x, u + 1e-6, *c)) - np.array(rhs(x, u - 1e-6, *c))) / 2e-6
    assert np.allclose(fu, du, rtol=1e-7, atol=1e-12)
