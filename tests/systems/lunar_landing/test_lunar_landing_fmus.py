"""S3 lunar landing through the FMUs: plant and controller FMUs, closed loops, dispersion.

Sources (named per test): the closed-form optimum ``optimal_landing`` (checked against an
independent solve_ivp run in test_lunar_landing_model.py beside this file); the in-process run
of the same functions; the acceptance bar |V| < 0.05 m/s at touchdown ([choice],
models/README.md) over the dispersion h0, V0 +-10 % and gL +-2 %.
"""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.models.integrators import REACHED, RUNNING
from descent_fmus.models.lunar_landing import LanderParams, optimal_landing

P = LanderParams()
EXACT = optimal_landing(P)


@pytest.fixture(scope="module")
def loops(fmu_dir):
    from descent_fmus.synthesis.systems.lunar_landing.study import LandingLoops
    with LandingLoops(fmu_dir) as lp:
        yield lp


def test_program_and_feedback_fmus_land_softly_from_the_nominal_start(loops):
    # oracle: the closed-form optimum; acceptance |V| < 0.05 m/s at h = 0 for both laws
    for law in ("program", "feedback"):
        td, _ = loops.fly(law)
        assert td.touched_down and abs(td.V_touchdown) < 0.05, law
        assert td.fuel == pytest.approx(EXACT.fuel, rel=2e-3), law   # near the optimum
        assert td.t_touchdown == pytest.approx(EXACT.T, abs=0.02), law


def test_plant_fmu_status_convention(loops):
    # status 0 RUNNING with t_end = -1 while flying, 1 REACHED at touchdown with t_end its time
    # (oracle: the closed-form T = 16.408 s); the closed loop stops there (STATUS_STOP) with
    # h = 0 and V = V_touchdown
    td, res = loops.fly("feedback", record=True)
    f = res.final
    assert res.stopped and f["status"] == REACHED
    assert f["t_end"] == td.t_touchdown and 16.0 < f["t_end"] < 16.5
    assert f["h"] == 0.0 and f["V"] == f["V_touchdown"]
    assert res.time[-1] >= f["t_end"] > res.time[-2]
    # stopped before touchdown: still running
    res = loops.loops["feedback"].run({}, dict(loops.feedback_values, estimate_g=1),
                                      stop_time=5.0)
    assert not res.stopped and res.final["status"] == RUNNING and res.final["t_end"] == -1.0
    assert res.final["V_touchdown"] == 0.0 and res.final["h"] > 0.0


def test_feedback_fmu_equals_the_in_process_law(loops):
    # oracle: the in-process loop of LanderIntegrator + SwitchLaw gives the same touchdown (same
    # floats in, same operations)
    td, _ = loops.fly("feedback", h0=140.0, V0=9.0, gL=1.60)
    p = P.with_(h0=140.0, V0=9.0, gL=1.60)
    from descent_fmus.synthesis.systems.lunar_landing.study import fly_feedback_in_process
    fi, _ = fly_feedback_in_process(p)
    assert fi.status == REACHED
    assert td.V_touchdown == pytest.approx(fi.V_touchdown, abs=1e-9)
    assert td.fuel == pytest.approx(P.m0 - fi.x[2], abs=1e-6)


def test_dispersion_feedback_lands_softly_program_does_not(loops):
    # acceptance |V| < 0.05 m/s: seeded dispersion of h0, V0 (+-10 %) and gL (+-2 %) plus the
    # 8 corners of the box
    from descent_fmus.synthesis.systems.lunar_landing.study import dispersion, dispersion_table
    rows = dispersion(loops, n=12, seed=2017)
    assert len(rows) == 12 + 8
    _, s = dispersion_table(rows)
    assert s["feedback"]["soft"] == len(rows)                 # every start: |V| < 0.05 m/s
    assert s["feedback"]["worst_speed"] < 0.01
    assert s["feedback"]["max_fuel_excess"] < 0.5            # kg above each start's optimum
    assert s["program"]["soft"] == 0                         # the open-loop program never does
    assert s["program"]["worst_speed"] > 5.0


def test_dispersion_samples_are_the_seeded_uniform_box():
    # oracle: numpy's seeded uniform draws mapped by hand (c (1 + w r)), then the 8 corners
    from descent_fmus.synthesis.systems.lunar_landing.study import DISPERSION, dispersion_box
    pts = dispersion_box(P).sample(5, 2017, corners=True)
    r = np.random.default_rng(2017).uniform(-1.0, 1.0, (5, 3))
    for pt, row in zip(pts, r):
        assert pt == {k: getattr(P, k) * (1.0 + DISPERSION[k] * v)
                      for k, v in zip(("h0", "V0", "gL"), row)}
    assert pts[-1] == {"h0": 165.0, "V0": 8.2 * 1.1, "gL": 1.62 * 1.02}
    assert len(pts) == 13


def test_feedback_without_gravity_estimate_fails_on_gl_dispersion(loops):
    # the [choice] of the gravity estimate (models/README.md): with gL 2 % above the nominal the
    # curve from the nominal gL is too low and the lander hits at ~2 m/s
    td, _ = loops.fly("feedback", gL=P.gL * 1.02, estimate_g=False)
    assert td.touched_down and abs(td.V_touchdown) > 1.0
    td, _ = loops.fly("feedback", gL=P.gL * 1.02, estimate_g=True)
    assert abs(td.V_touchdown) < 0.05


def test_container_fmus_run_with_fmpy_simulate(fmu_dir, loops):
    # oracle: the fmpy-master result of the same FMUs (LandingLoops) -- the closed-loop FMUs that
    # `fmpy simulate` runs give the same touchdown
    from fmpy import simulate_fmu
    for name, law in (("LunarLanderProgramClosedLoop", "program"),
                      ("LunarLanderFeedbackClosedLoop", "feedback")):
        res = simulate_fmu(str(fmu_dir / f"{name}.fmu"), stop_time=20.0,
                           output=["h", "V_touchdown", "status", "t_end", "fuel"])
        td, _ = loops.fly(law)
        assert res["status"][-1] == REACHED
        assert res["t_end"][-1] == pytest.approx(td.t_touchdown, abs=1e-12)
        assert res["V_touchdown"][-1] == pytest.approx(td.V_touchdown, abs=1e-12)
        assert res["fuel"][-1] == pytest.approx(td.fuel, abs=1e-9)
    # dispersed start values through the container's parameters: the container propagates its
    # connections during initialisation, so the FMUs must show their start values already then
    # (a stale V once became a "gravity" of 81.65 m/s^2 in the feedback law's estimate)
    res = simulate_fmu(str(fmu_dir / "LunarLanderFeedbackClosedLoop.fmu"), stop_time=30.0,
                       start_values={"h0": 160.0, "V0": 9.0, "gL": 1.65},
                       output=["V_touchdown", "status", "g_est"])
    td, _ = loops.fly("feedback", h0=160.0, V0=9.0, gL=1.65)
    assert res["status"][-1] == REACHED and abs(res["V_touchdown"][-1]) < 0.05
    assert res["g_est"][-1] == pytest.approx(1.65, rel=1e-9)
    assert res["V_touchdown"][-1] == pytest.approx(td.V_touchdown, abs=1e-9)


def test_program_closed_loop_carries_the_exact_optimum(fmu_dir):
    # oracle: the closed form -- the start values computed at build time (program_defaults)
    from fmpy import read_model_description
    md = read_model_description(str(fmu_dir / "LunarLanderProgramClosedLoop.fmu"))
    starts = {v.name: v.start for v in md.modelVariables}
    assert float(starts["t_switch"]) == EXACT.t_switch
    assert float(starts["t_off"]) == EXACT.T


def test_fmus_reject_bad_parameters(fmu_dir):
    from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
    from descent_fmus.synthesis.fmi.slave import FMUError
    from descent_fmus.synthesis.systems.lunar_landing.problems import (FEEDBACK_WIRING,
                                                                       PROGRAM_WIRING)
    with ClosedLoop(FEEDBACK_WIRING, fmu_dir / "LunarLander.fmu",
                    fmu_dir / "LandingSwitch.fmu") as loop:
        with pytest.raises(FMUError, match="umax"):
            loop.run({"umax": -1.0})
        with pytest.raises(FMUError, match="m_dry"):
            loop.run({"m_dry": 20000.0})
        with pytest.raises(FMUError, match="estimate_g"):
            loop.run({}, {"estimate_g": 3})
    with ClosedLoop(PROGRAM_WIRING, fmu_dir / "LunarLander.fmu",
                    fmu_dir / "LandingProgram.fmu") as loop:
        with pytest.raises(FMUError, match="t_off"):
            loop.run({}, {"t_off": -5.0})
