"""S1 on-board re-planning (the shaped correction of the guided law) and the load oracle.

Oracles: the Reentry plant FMU flying the planned profile (the law plus the plan's correction
at the plant's own state, held as the prediction holds it) must land where the plan predicted
and peak at the load it predicted; the load oracle (a warm-started minimax program) must equal
a direct open-loop optimisation from scratch on the same sample.
"""
from __future__ import annotations

import math
from dataclasses import asdict

import pytest

from descent_fmus.models.controllers.reentry_npc import GuidedNetworkOperatorController
from descent_fmus.models.controllers.reentry_prediction import predict_flight
from descent_fmus.models.controllers.reentry_replan import (PLAN_KNOTS, plan_value,
                                                            plan_weights)
from descent_fmus.models.reentry import T_PLUS, ReentryParams, altitude, initial_state
from descent_fmus.synthesis.systems.reentry.guidance import default_guided_law

P0 = ReentryParams()


def test_plan_weights_are_a_partition_of_unity_of_hats():
    for h in [100e3, 85e3, 80e3, 71e3, 62e3, 55e3, 50e3, 40e3, 38e3, 30e3, 22e3, 10e3]:
        w = plan_weights(h)
        assert sum(w) == pytest.approx(1.0, abs=1e-15)
        assert all(0.0 <= v <= 1.0 for v in w) and sum(v > 0.0 for v in w) <= 2
    for j, h in enumerate(PLAN_KNOTS):
        assert plan_weights(h)[j] == 1.0
    # between two knots the two neighbours interpolate linearly
    h = 0.25 * PLAN_KNOTS[1] + 0.75 * PLAN_KNOTS[2]
    assert plan_weights(h)[1] == pytest.approx(0.25) and plan_weights(h)[2] == pytest.approx(0.75)
    assert plan_value([0.1] * len(PLAN_KNOTS), 45e3) == pytest.approx(0.1)


def _controller(**params):
    """The guided controller in process, the committed guided law, at the entry state."""
    c = GuidedNetworkOperatorController(instance_name="test", resources=".")
    c.vars.materialise()
    byname = {v.name: v for v in c.vars.values()}
    for name, value in {**default_guided_law().start_values(), **params}.items():
        byname[name].setter(value)
    c.exit_initialization_mode()
    return c, byname


def _replay(p: ReentryParams, control, fmu_dir, step: float = 2.0) -> dict:
    """The Reentry FMU under ``control(x)`` set at every communication point (``step`` s)."""
    from descent_fmus.synthesis.fmi.slave import load_slave
    fmu = load_slave(fmu_dir / "Reentry.fmu", "plant")
    vr = {v.name: v.valueReference for v in fmu.model.modelVariables}
    try:
        start = asdict(p)
        fmu.setReal([vr[k] for k in start], [float(v) for v in start.values()])
        fmu.setupExperiment(startTime=0.0, stopTime=2 * T_PLUS)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        t = 0.0
        while fmu.getInteger([vr["status"]])[0] == 0 and t < 2 * T_PLUS:
            x = tuple(fmu.getReal([vr[f"x{k}"] for k in range(1, 5)]))
            fmu.setReal([vr["u"]], [control(x)])
            fmu.doStep(t, step)
            t += step
        return {n: fmu.getReal([vr[n]])[0] for n in ("L", "load_max")}
    finally:
        fmu.free()


@pytest.mark.slow
def test_replanned_profile_replayed_through_the_plant_lands_where_predicted(fmu_dir):
    # a plant whose drag the model knows (nominal): the first cycle's plan from the entry
    # state, flown by the plant FMU as the prediction flies it (the law and the plan's
    # correction evaluated on the state every 2 s)
    p = P0.with_(V0=P0.V0 + 30.0)             # flies too far: the plan must brake
    c, var = _controller(replan=1, replan_iterations=2)
    x0 = initial_state(p)
    for k, name in enumerate(("nav_x1", "nav_x2", "nav_x3", "nav_x4")):
        var[name].setter(x0[k])
    from descent_fmus.models.reentry import deviations, loads, rhs
    y1, y2 = deviations(x0, p)
    var["x[1]"].setter(y1)
    var["x[2]"].setter(y2)
    gm, kd, lam, rz = P0.constants()
    var["a_drag"].setter(loads(x0, rhs(x0, 0.0, gm, kd, lam, rz), kd, lam, rz, P0.g0, 0.0)[1])
    c._outputs()                               # the first cycle: the plan is solved
    plan, predicted_miss = list(c._plan), c._miss
    assert any(abs(v) > 1e-3 for v in plan)    # it corrects
    prof = c.estimator().profile(c.a_drag, x0)
    control = c._predictor(x0, prof)(lambda xp: plan_value(plan, altitude(xp, P0.Rz)))
    rng, samples = predict_flight(x0, control, prof.kd, P0, 2.0, prof.lam)
    assert rng - P0.Lf == pytest.approx(predicted_miss, abs=1e-6)
    flown = _replay(p, control, fmu_dir)
    # the prediction's RK4 on 2 s steps against the plant's 0.5 s sub-steps: metres
    assert flown["L"] - P0.Lf == pytest.approx(predicted_miss, abs=25.0)
    assert abs(predicted_miss) <= c.tol + 1.0
    # the predicted peak (both ends of every 2 s step) against the plant's true peak (every
    # 0.5 s and both sides of every control change): the peak sits at a control change
    assert max(samples) == pytest.approx(flown["load_max"], rel=1e-3)


@pytest.mark.slow
@pytest.mark.parametrize("change", [dict(rho0=1.22 * 1.08, m=4850.0, V0=7530.0, lam=1.35e-4 * 1.03),
                                    dict(rho0=1.22 * 0.93, V0=7490.0, lam=1.35e-4 * 0.98)])
@pytest.mark.slow            # two open-loop optimisations per case (~30-50 s)
def test_load_oracle_equals_a_direct_open_loop_optimisation(change):
    from descent_fmus.synthesis.systems.reentry.bound import optimize_open_loop
    from descent_fmus.synthesis.systems.reentry.load_oracle import load_oracle
    from descent_fmus.synthesis.systems.reentry.oracle import oracle_bound
    p = P0.with_(**change)
    assert oracle_bound(p).exact                # a zero-miss program exists
    direct = optimize_open_loop(p, t_seg=1.0)   # from scratch (u = 0), tight tolerance
    assert direct.miss < 1.0
    assert load_oracle(p) == pytest.approx(direct.J1, rel=1e-4)
    assert math.isfinite(direct.J1)


def test_error_families_are_stratified_and_disjoint_from_the_synthesis_seed():
    from descent_fmus.synthesis.systems.reentry.error_families import FAMILIES, family_samples
    for name in FAMILIES:
        held = family_samples(name, 40, 7)
        # a Latin hypercube: every parameter has one value in each of the 40 strata of its box
        box = FAMILIES[name].box(P0)
        for iv in box.intervals:
            lo, hi = iv.value(-1.0), iv.value(1.0)
            vals = [getattr(s.plant, iv.name) if iv.name in asdict(s.plant) else s.sensing[iv.name]
                    for s in held]
            strata = sorted(int((v - lo) / (hi - lo) * 40) for v in vals)
            assert strata == list(range(40)), (name, iv.name)
        synth = {s.key() for s in family_samples(name, 40, 1)}
        assert not synth & {s.key() for s in held}
    assert any(s.sensing.get("noise", 0) > 0 for s in family_samples("accel", 10, 7))


def test_set_problem_options_draw_the_set_from_the_error_families():
    from descent_fmus.synthesis.registry import get_problem
    p = get_problem("reentry-guided")
    q = p.with_option("errors", "spec,scale-height").with_option("samples", "201")
    assert len(q.initial_states) == 201 and q.initial_states[0] == asdict(P0)
    lams = [s["lam"] for s in q.initial_states[1:]]
    assert sum(v == P0.lam for v in lams) == 100           # spec: the model's scale height
    assert sum(v != P0.lam for v in lams) == 100           # scale-height: lam +-5 %
    assert q.with_option("statistic", "p90").objectives.errors == ("spec", "scale-height")
    with pytest.raises(ValueError, match="unknown error family"):
        p.with_option("errors", "weather")
    with pytest.raises(ValueError, match="samples must be"):
        p.with_option("samples", "3")


def test_family_study_keeps_each_options_flights_and_reads_them_back(fmu_dir, tmp_path,
                                                                    monkeypatch):
    # oracle: the first call's own rows -- a second call with the same option, family and set
    # reads them back without flying; the same label with another law is flown again
    from descent_fmus.synthesis.systems.reentry import family_study as fs
    from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law, paper_law
    args = dict(families=["spec"], samples=3, seed=7, fmu_dir=fmu_dir, npc=False,
                oracle=False, basic=False, flown=tmp_path)
    first = fs.family_study({"law": paper_basic_law()}, **args)
    rows = first["scenarios"]["spec"]["results"]["law"]
    assert len(rows) == 3 and len(list(tmp_path.glob("*.json"))) == 1

    def no_flight(*a, **k):
        raise AssertionError("flown again")
    with monkeypatch.context() as m:
        m.setattr(fs, "fly_law", no_flight)
        again = fs.family_study({"law": paper_basic_law()}, **args)
        assert again["scenarios"]["spec"]["results"]["law"] == rows
        with pytest.raises(AssertionError, match="flown again"):
            fs.family_study({"law": paper_law()}, **args)
