"""S2 Mars capsule in-process: the law's formulas, the averaged plant, the status convention.

Oracles: the law's formulas (Lyubimov & Kurkina, eqs. 14, 15-17), the closed form of the
uncontrolled averaged equation (alpha ~ omega_a^(-1/2)), the plant's own event condition.
"""
from __future__ import annotations

import math
import random

import pytest

from descent_fmus.models.controllers import mars_bellman as mb
from descent_fmus.models.integrators import LEFT_DOMAIN, REACHED, RUNNING
from descent_fmus.models.mars import OUTPUTS, MarsIntegrator, MarsParams, simulate
from descent_fmus.models.mars_6dof import OUTPUTS6, Mars6DOFIntegrator
from descent_fmus.models.params import ParameterError

P = MarsParams()


def random_law_inputs(rng):
    """(alpha, theta, omega, omega_dot, omega_a) drawn over the ranges of a descent and beyond."""
    wa = rng.uniform(0.2, 4.0)
    w = rng.uniform(0.0, wa)
    return (rng.uniform(0.0, 0.5), rng.uniform(-10.0, 10.0), w, rng.uniform(-0.5, 0.5), wa)


# -- the law ---------------------------------------------------------------------------------------
def test_consistent_root_solves_eq14_to_rounding():
    # oracle: eq. (14) of Lyubimov & Kurkina, b - A w wd/wa^2 - A^2/(8 c wa^2) = 0, whose
    # positive root A is
    rng = random.Random(7)
    for _ in range(2000):
        _, _, w, wd, wa = random_law_inputs(rng)
        wd *= 10.0 ** rng.uniform(-3, 2)           # also omega omega_dot >> sqrt(b / c)
        b, c = 10.0 ** rng.uniform(-3, 2), 10.0 ** rng.uniform(-2, 3)
        A = mb.consistent_gain(w, wd, wa, b, c)
        assert A > 0.0
        # residual relative to the size of the terms (rounding: a few ulp)
        scale = b + abs(A * w * wd) / wa ** 2 + A * A / (8 * c * wa ** 2)
        assert abs(mb.bellman_residual(A, w, wd, wa, b, c)) <= 1e-13 * scale


def test_paper_root_does_not_solve_eq14_and_guards():
    # oracle: the paper's printed root (15) and guards (16), written out here
    b, c, wa, w = 1.0, 100.0, 2.0, 1.0
    # guards of eq. (16): omega_dot >= 0 -> no control; D < 0 -> no control
    assert mb.paper_gain(w, 0.0, wa, b, c) == 0.0
    assert mb.paper_gain(w, 0.3, wa, b, c) == 0.0
    wd = -0.01       # D = (w wd / wa^2)^2 - b / (4 c wa^2) = 6.25e-6 - 6.25e-4 < 0
    assert mb.paper_gain(w, wd, wa, b, c) == 0.0
    assert mb.control(0.1, 0.0, w, wd, wa, b, c, 0.0, 1.0, mb.PAPER) == (0.0, 0.0)
    # where the guards pass, A is the printed formula (15): A_1 = 8 c wa^2 (-x + sqrt(D))
    wd = -1.0        # x = -0.25, D = 0.0625 - 6.25e-4 > 0
    x = w * wd / wa ** 2
    D = x * x - b / (4 * c * wa ** 2)
    A = mb.paper_gain(w, wd, wa, b, c)
    assert A == pytest.approx(8 * c * wa ** 2 * (-x + math.sqrt(D)), rel=1e-14)
    # ... which does not solve eq. (14) (a sign and a factor are off)
    assert abs(mb.bellman_residual(A, w, wd, wa, b, c)) > 0.1 * b
    u, _ = mb.control(0.1, 0.0, w, wd, wa, b, c, 0.0, 1e9, mb.PAPER)
    assert u == pytest.approx(A * 0.1 / (2 * c * wa), rel=1e-14)


def test_feedback_is_the_law_on_the_plant_outputs():
    # oracle: control() of eq. (17) called on the output tuple by hand
    law = mb.MarsBellmanParams(b=0.5, c=20.0, theta1=-0.7, u_max=0.05)
    y = MarsIntegrator(P).outputs()
    assert mb.feedback(law)(y) == mb.control(*y[:5], 0.5, 20.0, -0.7, 0.05)[0]
    y6 = Mars6DOFIntegrator(P).outputs()
    i = OUTPUTS6.index("alpha_m1")
    assert (mb.feedback(law, alpha_index=i)(y6)
            == mb.control(y6[i], y6[i + 1], *y6[2:5], 0.5, 20.0, -0.7, 0.05)[0])


# -- the plant ---------------------------------------------------------------------------------
def test_uncontrolled_alpha_follows_closed_form():
    # oracle, closed form: u = 0: dalpha/alpha = -w dw / (2 wa^2) = -d(wa^2) / (4 wa^2)
    # =>  alpha wa^(1/2) = const
    fl, rec = simulate(P, None)
    wa0, wa1 = rec["omega_a"][0], rec["omega_a"][-1]
    assert fl.outputs()[0] == pytest.approx(P.alpha0 * math.sqrt(wa0 / wa1), rel=1e-7)


def test_status_reached_at_h_end_and_frozen():
    # oracle: the plant's terminal condition h = h_end (located inside the RK4 step)
    fl = MarsIntegrator(P)
    assert fl.status == RUNNING and fl.t_end_output == -1.0
    fl, _ = simulate(P, None, record=False)
    assert fl.status == REACHED
    assert fl.t_end_output == fl.t_end == fl.t
    assert fl.x[2] == pytest.approx(P.h_end, abs=1e-3)
    x, t = fl.x, fl.t
    fl.advance(fl.t + 10.0, 0.01)               # frozen once the status is non-zero
    assert (fl.x, fl.t, fl.status) == (x, t, REACHED)


def test_status_left_domain_when_the_integration_diverges():
    # an absurd atmosphere (rho0 = 1e6 kg/m3, no decay with altitude) overflows on the first
    # sub-step: the flight ends at t = 0 with status LEFT_DOMAIN, the state kept finite
    fl, _ = simulate(MarsParams(rho0=1e6, Hs=1e6), None, record=False)
    assert fl.status == LEFT_DOMAIN
    assert fl.t_end_output == 0.0
    assert all(math.isfinite(v) for v in fl.x)


def test_in_process_parameter_errors():
    with pytest.raises(ParameterError, match="omega_x"):
        MarsParams(omega_x=0.0).validate()
    with pytest.raises(ParameterError, match="Ix"):
        Mars6DOFIntegrator(MarsParams(Ix=-1.0))
    with pytest.raises(ParameterError, match="dt"):
        MarsIntegrator(P, dt=0.0)
    with pytest.raises(ParameterError, match="u_max"):
        mb.MarsBellmanParams(u_max=-1.0).validate()


def test_outputs_tables_are_consistent():
    assert OUTPUTS6[:len(OUTPUTS)] == OUTPUTS
    assert MarsIntegrator.names == OUTPUTS and Mars6DOFIntegrator.names == OUTPUTS6
