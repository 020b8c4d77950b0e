"""S2 Mars capsule: the closed loops through the FMUs -- acceptance and the rigid-body check.

Oracles: the paper's acceptance (Lyubimov & Kurkina, fig. 2: alpha_end < 0.01 rad with the law),
the closed form of the uncontrolled averaged equation (alpha ~ omega_a^(-1/2)), the in-process
simulation of the same functions, and the rigid-body plant (Euler's equations) for the
averaged one.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from descent_fmus.models.controllers import mars_bellman as mb
from descent_fmus.models.integrators import REACHED
from descent_fmus.models.mars import MarsParams, simulate
from descent_fmus.synthesis.systems.mars.flight import RECORD_6DOF, fly, load_loop
from descent_fmus.synthesis.systems.mars.wiring import WIRING, WIRING_6DOF, WIRING_6DOF_INSTANT

P = MarsParams()


@pytest.fixture(scope="module")
def runs(fmu_dir):
    with load_loop(fmu_dir) as loop:
        yield {"law": fly(loop, "law"),
               "none": fly(loop, "none", controller_values={"u_max": 0.0}),
               "paper": fly(loop, "paper", controller_values={"formula": mb.PAPER}),
               "half_step": fly(loop, "half", step=WIRING.step / 2, record=False)}


def test_acceptance_alpha_end_through_fmus(runs):
    law, none = runs["law"], runs["none"]
    assert law.result.stopped and none.result.stopped
    assert law.result.final["status"] == none.result.final["status"] == REACHED
    assert law.result.final["h"] == pytest.approx(P.h_end, abs=1e-3)
    # acceptance (Lyubimov & Kurkina, figs. 1-2): alpha_end < 0.01 rad with the law, >= 5x
    # larger without it
    assert law.alpha_end < 0.01
    assert none.alpha_end >= 5 * law.alpha_end
    # oracle, closed form: the uncontrolled run is alpha0 (wa0 / wa_end)^(1/2)
    wa = none.result["omega_a"]
    assert none.alpha_end == pytest.approx(P.alpha0 * math.sqrt(wa[0] / wa[-1]), rel=1e-6)


def test_paper_formula_rarely_acts_on_the_scenario(runs):
    # oracle: the uncontrolled run. The paper's printed root (15): with its guards (16) the
    # discriminant is negative all the way, so the run is the uncontrolled one
    assert runs["paper"].alpha_end == pytest.approx(runs["none"].alpha_end, rel=1e-12)
    assert np.all(runs["paper"].result["ctrl.u"] == 0.0)


def test_fmu_closed_loop_equals_in_process(runs):
    # oracle: the same functions in-process (models.mars.simulate, the law's feedback())
    law = runs["law"]
    fl, _ = simulate(P, mb.feedback(mb.MarsBellmanParams(theta1=P.theta1)), step=WIRING.step,
                     record=False)
    assert law.alpha_end == pytest.approx(fl.outputs()[0], rel=1e-9)
    assert law.result.final["t_end"] == pytest.approx(fl.t_end, abs=1e-9)


def test_communication_step_effect_is_small(runs):
    # oracle: the same loop with half the communication step. The control is held over a
    # step: halving the step changes alpha_end by ~1 % (measured 0.9 %)
    assert runs["half_step"].alpha_end == pytest.approx(runs["law"].alpha_end, rel=0.03)


def test_container_fmu_runs_the_same_loop(fmu_dir, runs):
    # oracle: the Python master's run of the same two FMUs
    from fmpy import simulate_fmu
    res = simulate_fmu(str(fmu_dir / "MarsClosedLoop.fmu"), stop_time=700.0,
                       output=["alpha", "status"])
    assert res["status"][-1] == REACHED
    assert res["alpha"][-1] == pytest.approx(runs["law"].alpha_end, rel=1e-9)


# -- the averaging against the rigid body ------------------------------------------------------
@pytest.fixture(scope="module")
def six_dof(fmu_dir):
    out = {}
    for key, wiring in (("mode1", WIRING_6DOF), ("instant", WIRING_6DOF_INSTANT)):
        with load_loop(fmu_dir, wiring, RECORD_6DOF) as loop:
            out[key] = loop.run(record=True)
            if key == "mode1":
                out["none"] = loop.run(controller_values={"u_max": 0.0}, record=True)
    return out


def test_6dof_flights_reach_h_end(six_dof):
    # oracle: the status convention (models/integrators.py) and the plant's terminal condition
    # h = h_end
    for r in six_dof.values():
        assert r.stopped and r.final["status"] == REACHED
        assert r.final["h"] == pytest.approx(P.h_end, abs=1e-3)


def test_6dof_uncontrolled_agrees_with_averaged(six_dof, runs):
    # oracle: the rigid-body plant. No control: the omega_1 amplitude of the rigid body follows
    # the averaged alpha (and its closed form) to 0.5 % over the whole descent (measured 0.35 %)
    r6, ra = six_dof["none"], runs["none"].result
    a_avg = np.interp(r6.time, ra.time, ra["alpha"])
    assert np.max(np.abs(r6["alpha_m1"] / a_avg - 1.0)) < 5e-3
    assert r6.final["alpha"] == pytest.approx(runs["none"].alpha_end, rel=5e-3)


def test_6dof_controlled_mode1_follows_averaged_and_meets_target(six_dof, runs):
    # oracle: the rigid-body plant, the law fed its omega_1 mode
    r6, ra = six_dof["mode1"], runs["law"].result
    a_avg = np.interp(r6.time, ra.time, ra["alpha"])
    big = a_avg > 1e-3
    # while the omega_1 mode dominates, amplitude within 10 % of the averaged model
    assert np.max(np.abs(r6["alpha_m1"][big] / a_avg[big] - 1.0)) < 0.1
    # the total angle ends at the omega_2 residue the saturated control excited (~1.4e-3 rad)
    assert r6.final["alpha"] < 0.01
    assert r6.final["alpha_m2"] > 10 * r6.final["alpha_m1"]


def test_6dof_instantaneous_feedback_breaks_down(six_dof):
    # oracle: the rigid-body plant; documented breakdown: fed the instantaneous angles, the law tracks the omega_2 mode once
    # it exceeds the omega_1 mode, and it destabilises it (models/README.md)
    r = six_dof["instant"]
    assert r.final["alpha"] > 0.1
    assert r.final["alpha_m2"] > 10 * r.final["alpha_m1"]
