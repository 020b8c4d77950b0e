"""S3 lunar landing in-process: closed form, switching curve, exact optimum, plant integrator.

Sources (named per test): Mozzhorina (2017) Table 2; independent SciPy solve_ivp (DOP853) runs of
the plant equations; the closed-form optimum ``optimal_landing`` (itself checked against
solve_ivp here).
"""
from __future__ import annotations

import math
from dataclasses import fields

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from descent_fmus.models.controllers.lunar_landing_program import ProgramParams, program_flow
from descent_fmus.models.controllers.lunar_landing_switch import SwitchLaw, SwitchParams
from descent_fmus.models.integrators import LEFT_DOMAIN, REACHED, RUNNING
from descent_fmus.models.lunar_landing import (InfeasibleLandingError, LanderIntegrator,
                                               LanderParams, constant_flow_state,
                                               optimal_landing, switch_height)
from descent_fmus.models.params import ParameterError
from descent_fmus.synthesis.systems.lunar_landing.problems import PAPER_TABLE2, program_defaults

P = LanderParams()
EXACT = optimal_landing(P)


def ivp(x0, u, t_end, p=P):
    """Independent reference: DOP853 on dh/dt = -V, dV/dt = gL - beta u/m, dm/dt = -u."""
    sol = solve_ivp(lambda t, x: [-x[1], p.gL - p.beta * u / x[2], -u], (0.0, t_end), x0,
                    method="DOP853", rtol=1e-13, atol=1e-12)
    return sol.y[:, -1]


def fly_program(p=P, dt=0.01, max_steps=3000):
    """The exact optimum of ``P`` flown open loop by the integrator (program_flow per step)."""
    fi = LanderIntegrator(p)
    k = 0
    while fi.running and k < max_steps:
        fi.advance((k + 1) * dt, program_flow(k * dt, dt, EXACT.t_switch, EXACT.T, P.umax))
        k += 1
    return fi


def test_closed_form_optimum_reproduces_table2():
    # Mozzhorina (2017) Table 2 "shooting" row with umax = 14.57 (the printed 15.74 is a misprint)
    assert round(EXACT.t_switch, 4) == PAPER_TABLE2["t_switch"]
    assert round(EXACT.T, 4) == PAPER_TABLE2["T"]
    assert round(EXACT.h_switch, 4) == PAPER_TABLE2["h_switch"]
    assert round(EXACT.fuel, 2) == PAPER_TABLE2["fuel"]
    assert round(EXACT.psi1, 6) == PAPER_TABLE2["psi1"]
    # V at the switch is V0 + gL t_switch on the coast (15.87021); the paper's 15.85820 is not
    # consistent with its own t_switch (it would need t = 4.7273 s), and its psi3(0) = -0.017990
    # differs from the exact -0.0179985 by 5e-4 relative -- both reported, not asserted.
    assert EXACT.V_switch == pytest.approx(P.V0 + P.gL * EXACT.t_switch, rel=1e-15)
    with pytest.raises(AssertionError):
        assert round(EXACT.V_switch, 5) == PAPER_TABLE2["V_switch"]


def test_closed_form_optimum_lands_in_an_independent_integration():
    # oracle: solve_ivp -- coast to t_switch, full thrust to T: h(T) = V(T) = 0 to its accuracy
    xs = ivp([P.h0, P.V0, P.m0], 0.0, EXACT.t_switch)
    xT = ivp(xs, P.umax, EXACT.T - EXACT.t_switch)
    assert abs(xT[0]) < 1e-8 and abs(xT[1]) < 1e-9
    assert P.m0 - xT[2] == pytest.approx(EXACT.fuel, rel=1e-12)
    assert xs[0] == pytest.approx(EXACT.h_switch, rel=1e-12)


@pytest.mark.parametrize("u,s", [(0.0, 3.0), (14.57, 0.01), (14.57, 11.7), (3.3, 5.0)])
def test_constant_flow_closed_form_matches_solve_ivp(u, s):
    # oracle: solve_ivp (DOP853, rtol 1e-13) of the same equations
    x0 = (120.0, 11.0, 14_950.0)
    got = constant_flow_state(x0, u, s, P.gL, P.beta)
    want = ivp(list(x0), u, s)
    assert np.allclose(got, want, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("V,m", [(15.0, 15000.0), (5.0, 14900.0), (0.3, 14850.0)])
def test_switching_curve_is_the_full_thrust_arc_to_zero(V, m):
    # oracle: solve_ivp with a V = 0 event -- full thrust from (h_sw(V, m), V, m) reaches V = 0
    # exactly at h = 0
    h = switch_height(V, m, P.umax, P.gL, P.beta)
    ev = lambda t, x: x[1]  # noqa: E731
    ev.terminal = True
    sol = solve_ivp(lambda t, x: [-x[1], P.gL - P.beta * P.umax / x[2], -P.umax], (0, 100),
                    [h, V, m], method="DOP853", rtol=1e-13, atol=1e-12, events=ev)
    assert abs(sol.y_events[0][0][0]) < 1e-8 * max(h, 1.0)
    assert switch_height(-1.0, m, P.umax, P.gL, P.beta) == 0.0   # going up: no thrust needed


def test_infeasible_data_are_rejected_with_the_reason():
    with pytest.raises(InfeasibleLandingError, match="cannot even hold the lander"):
        optimal_landing(P.with_(umax=7.0))          # thrust 1.42 m/s^2 < gL
    with pytest.raises(InfeasibleLandingError, match="below the ground"):
        optimal_landing(P.with_(umax=8.5))          # feasible thrust, too little to stop in 150 m
    with pytest.raises(InfeasibleLandingError, match="below the ground"):
        optimal_landing(P.with_(h0=10.0, V0=20.0))


def test_parameters_are_validated_naming_the_parameter():
    with pytest.raises(ParameterError, match="umax must be > 0"):
        P.with_(umax=-1.0).validate()
    with pytest.raises(ParameterError, match="h0 must be >= 0"):
        P.with_(h0=-1.0).validate()
    with pytest.raises(ParameterError, match="gL must be finite"):
        P.with_(gL=math.nan).validate()
    with pytest.raises(ParameterError, match="m_dry"):
        LanderIntegrator(P, m_dry=P.m0)
    with pytest.raises(ParameterError, match="dt"):
        LanderIntegrator(P, dt=0.0)
    with pytest.raises(ParameterError, match="t_off"):
        ProgramParams(t_off=1.0).validate()
    with pytest.raises(ParameterError, match="estimate_g"):
        SwitchParams(estimate_g=2).validate()


def test_every_parameter_has_a_unit_and_a_description():
    for cls in (LanderParams, ProgramParams, SwitchParams):
        for f in fields(cls):
            assert f.metadata["unit"] and f.metadata["description"], (cls.__name__, f.name)


def test_controller_defaults_come_from_the_plant_and_the_exact_optimum():
    # oracle: the closed form -- the program FMU's default times are the exact optimum of the
    # default scenario to the last bit, and the closed loop's build-time defaults equal them
    assert ProgramParams().t_switch == EXACT.t_switch
    assert ProgramParams().t_off == EXACT.T
    assert program_defaults() == {"t_switch": EXACT.t_switch, "t_off": EXACT.T,
                                  "umax": P.umax}
    s = SwitchParams()
    assert (s.umax, s.beta, s.g_nominal) == (P.umax, P.beta, P.gL)
    law = SwitchLaw()
    assert (law.umax, law.beta, law.g_nominal, law.dt) == (s.umax, s.beta, s.g_nominal, s.step)


def test_plant_integrator_matches_solve_ivp_through_the_optimal_program():
    # oracle: the closed-form optimum (checked against solve_ivp above)
    fi = fly_program()
    # step-averaged switch: O(dt^2) altitude error -> touchdown speed ~7 mm/s, fuel exact
    assert fi.status == REACHED and abs(fi.V_touchdown) < 0.05
    assert P.m0 - fi.x[2] == pytest.approx(EXACT.fuel, rel=1e-9)
    assert fi.t_end == pytest.approx(EXACT.T, abs=0.01)


def test_status_convention_of_the_integrator():
    # RUNNING (t_end NaN, published as -1) until touchdown; REACHED at h = 0 with t_end the
    # touchdown time (oracle: the closed-form T = 16.408 s); the state is frozen from then on
    fi = LanderIntegrator(P)
    assert fi.status == RUNNING and fi.running and fi.t_end_output == -1.0
    assert math.isnan(fi.V_touchdown)
    fi = fly_program()
    assert fi.status == REACHED and not fi.running
    assert fi.x[0] == 0.0 and fi.t_end_output == fi.t_end and 16.0 < fi.t_end < 16.5
    x, t_end = fi.x, fi.t_end
    fi.advance(fi.t + 1.0, P.umax)
    assert fi.x == x and fi.t_end == t_end and fi.status == REACHED
    # a start on the ground has touched down at t = 0
    fi = LanderIntegrator(P.with_(h0=0.0))
    assert fi.status == REACHED and fi.t_end == 0.0 and fi.V_touchdown == P.V0
    fi.reset()
    assert fi.status == REACHED
    # a diverged integration (a non-finite state, forced here) leaves the domain and freezes
    fi = LanderIntegrator(P)
    fi.advance(0.01, 0.0)
    fi.x = (math.inf, P.V0, P.m0)
    fi.advance(0.02, 0.0)
    assert fi.status == LEFT_DOMAIN and fi.t_end == pytest.approx(0.01)
    fi.advance(0.03, 0.0)
    assert fi.status == LEFT_DOMAIN and fi.t_end == pytest.approx(0.01)
