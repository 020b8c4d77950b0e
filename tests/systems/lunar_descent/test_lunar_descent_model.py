"""S5 plant in-process (models.lunar_descent): against an independent solve_ivp run and closed
forms, integration accuracy, the status convention, bad parameters."""
from __future__ import annotations

import math

import pytest
from scipy.integrate import solve_ivp

from descent_fmus.models.integrators import CRASHED, LEFT_DOMAIN, REACHED, RUNNING
from descent_fmus.models.lunar_descent import (G_TILDE, DescentIntegrator, DescentParams,
                                               simulate)
from descent_fmus.models.params import ParameterError
from descent_fmus.synthesis.systems.lunar_descent.problems import (INITIAL_SET,
                                                                    synthesis_basic_law)
from descent_fmus.synthesis.systems.lunar_descent.study import fly_in_process


def _paper_rhs(t, x, tilt, p0=440.0, pud=319.0, g0=1.623, r0=1_738_400.0):
    # Diveev et al. (2013) eqs. (1)-(6), written out again here (independent of models/), with
    # the law u1 = theta + pi + tilt applied continuously, u2 = 0
    V, th, h, _, m = x
    u1 = th + math.pi + tilt
    W = 9.80665 * p0 / m
    g = g0 * (r0 / (r0 + h)) ** 2
    return [W * math.cos(u1 - th) - g * math.cos(th),
            (W * math.sin(u1 - th) + g * math.sin(th)) / V,
            V * math.cos(th), V * math.sin(th) / (r0 + h), -p0 / pud]


def test_plant_against_solve_ivp_and_orientation_numbers():
    # oracle: an independent scipy.integrate.solve_ivp (DOP853) run of the paper's equations;
    # orientation numbers of the scenario [choice] (models/README.md): tilt 0.4 rad reaches
    # 50 m/s at h ~ 8.8 km after ~443 s with ~610 kg used; tilt 0.3 crashes at V ~ 750 m/s.
    x0 = [1690.0, math.pi / 2, 18_000.0, 0.0, 1400.0]
    ev = lambda t, x, tilt: x[0] - 50.0  # noqa: E731
    ev.terminal = True
    ref = solve_ivp(_paper_rhs, (0, 600), x0, args=(0.4,), method="DOP853", rtol=1e-11,
                    atol=1e-9, events=ev)
    t_ref, x_ref = ref.t_events[0][0], ref.y_events[0][0]
    p = DescentParams(V_lo=45.0, V_hi=50.0, h_lo=0.0, h_hi=1e5)   # box = "V reaches 50 m/s"
    fi = simulate(p, lambda t, x: (x[1] + math.pi + 0.4, 0.0), step=0.05, dt=0.05)
    assert fi.status == REACHED
    assert fi.t == pytest.approx(t_ref, abs=0.05)                  # zero-order hold of 0.05 s
    assert fi.x[2] == pytest.approx(x_ref[2], abs=1.0)
    assert fi.x[4] == pytest.approx(x_ref[4], abs=0.1)
    assert (t_ref, x_ref[2], 1400 - x_ref[4]) == pytest.approx((443, 8800, 610), rel=0.01)
    crash = simulate(DescentParams(), lambda t, x: (x[1] + math.pi + 0.3, 0.0))
    assert crash.status == CRASHED and abs(crash.x[2]) < 1e-6
    assert crash.x[0] == pytest.approx(750, rel=0.01)


def test_pure_braking_is_tsiolkovsky():
    # closed form: horizontal pure braking without gravity. W = g~ k P / m and
    # dm/dt = -k P / P_ud give dV = g~ P_ud dm / m, the rocket equation
    # V0 - V = g~ P_ud ln(m0/m) for any thrust factor k, and m = m0 - k P t / P_ud
    for k_P, u2 in ((1.0, 0.0), (1.03, 25.0)):
        p = DescentParams(g0=1e-12, k_P=k_P, P_ud=322.19)
        fi = simulate(p, lambda t, x: (1.5 * math.pi, u2), t_plus=200.0)
        m = 1400.0 - k_P * (440.0 + u2) * 200.0 / 322.19
        assert fi.x[4] == pytest.approx(m, rel=1e-12)
        assert fi.x[0] == pytest.approx(1690.0 - G_TILDE * 322.19 * math.log(1400.0 / m),
                                        rel=1e-10)
        assert fi.x[2] == pytest.approx(18_000.0, abs=1e-6)    # theta stays pi/2
        assert fi.status == RUNNING and fi.t_end_output == -1.0  # t+ is no event


def test_step_halving_and_integration_accuracy():
    # oracle: the same flight with a halved communication step and a 4x finer RK4 sub-step
    law = synthesis_basic_law()
    for th, h0 in INITIAL_SET:
        a = fly_in_process(law, th, h0)                       # STEP = dt = 1 s
        b = fly_in_process(law, th, h0, step=0.5)             # halved communication step
        c = fly_in_process(law, th, h0, dt=0.25)              # 4x finer RK4 sub-step
        assert a.status == b.status == c.status == REACHED
        assert abs(a.x[2] - b.x[2]) < 3.0 and abs(a.x[0] - b.x[0]) < 0.1
        assert abs(a.x[2] - c.x[2]) < 0.05 and abs(a.x[4] - c.x[4]) < 1e-3


def test_status_convention_at_each_end():
    # REACHED in the box, CRASHED at h = 0, LEFT_DOMAIN at V = 1 m/s (V_STALL); t_end is the
    # located event time and the state is frozen afterwards (models/integrators.py convention)
    law = synthesis_basic_law()
    th, h0 = INITIAL_SET[-1]
    box = fly_in_process(law, th, h0)
    assert box.status == REACHED and box.t_end == box.t and box.t_end_output == box.t_end
    p = DescentParams()
    assert 40.0 <= box.x[0] <= 60.0 + 1e-6 and 1500.0 - 1e-6 <= box.x[2] <= 2500.0
    x, t = box.x, box.t
    box.advance(box.t + 50.0, math.pi, 0.0)                   # frozen: nothing moves
    assert (box.x, box.t, box.status) == (x, t, REACHED)
    crash = simulate(p, lambda t, x: (x[1] + math.pi + 0.3, 0.0))
    assert crash.status == CRASHED and crash.t_end == crash.t and abs(crash.x[2]) < 1e-6
    stall = simulate(p, lambda t, x: (x[1] + math.pi + 0.4, 0.0))
    assert stall.status == LEFT_DOMAIN and stall.x[0] == pytest.approx(1.0, abs=1e-6)
    fresh = DescentIntegrator(p)
    assert fresh.running and fresh.t_end_output == -1.0 and fresh.h_min == p.h0


def test_bad_parameters_in_process():
    for kw, msg in [({"P_ud": -1.0}, "P_ud must be > 0"), ({"theta0": 4.0}, "theta0"),
                    ({"V_lo": 70.0}, "V_lo < V_hi"), ({"m0": math.nan}, "m0 must be finite"),
                    ({"V0": 50.0, "h0": 2000.0}, "inside the terminal box"),
                    ({"P0": 30.0}, "P0 must exceed")]:
        with pytest.raises(ParameterError, match=msg):
            DescentParams(**kw).validate()
    with pytest.raises(ParameterError, match="dt must be > 0"):
        DescentIntegrator(DescentParams(), dt=0.0)
