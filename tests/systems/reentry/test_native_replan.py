"""The native re-planner (``replan = 1`` in the native GuidedNetworkOperatorController).

Oracles:

* the on-board linear-programme solver (``c/lp.h``, called through :func:`linprog_c`) against
  SciPy's HiGHS (:func:`scipy.optimize.linprog`) on the re-planner's own programmes
  (:func:`lp_problems` of random predictions) and on general dense programmes: the same verdict
  (optimal / infeasible), the optimal value to 1e-9 relative, and -- on the re-planner's
  programmes, whose optimum is unique -- the step to 1e-7;
* the pythonfmu ``GuidedNetworkOperatorController`` with ``replan = 1``, flown by the Python
  master: with no linear-programming step (``replan_iterations = 0``: the plan's predictions,
  its loads, the floor and Brent's offset) every output at every communication point bit for
  bit; with the default step, where the two implementations' programmes differ only by the
  solvers' rounding, the landing to 1 mm and the peak load to 1e-6 relative on the committed
  law (the measured differences are ~1e-9 m and ~1e-11).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from descent_fmus.models.controllers.reentry_replan import PLAN_KNOTS, lp_problems
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
from descent_fmus.synthesis.methods.law import NetworkOperator

from fmi_calls import bits

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (CI installs gcc)")

GUIDED_LAW = "synthesis/systems/reentry/guided_law.json"


def _linprog_c(**kw):
    from descent_fmus.synthesis.systems.reentry.native.onboard_lp import linprog_c
    return linprog_c(**kw)


def _random_replan_problem(rng, far: bool):
    """The re-planner's two programmes at random predictions (sizes as in flight: K weights,
    5-300 load samples, miss derivatives of ~km per unit weight; a miss of ~100 m, or of
    ~30 km if ``far``: beyond what the trust region can null)."""
    k, n = len(PLAN_KNOTS), int(rng.integers(5, 300))
    c = rng.uniform(-0.3, 0.3, k)
    return k, lp_problems(m0=rng.normal(0.0, 3e4 if far else 300.0), l0=rng.uniform(3.0, 10.0, n),
                          dm=rng.normal(0.0, 3e3, k), G=rng.normal(0.0, 3.0, (n, k)), c=c,
                          c_max=0.3, trust=0.1, effort=0.02, floor=rng.uniform(0.0, 9.0))


def test_onboard_lp_solves_the_replanners_programmes_as_highs():
    rng = np.random.default_rng(20261126)
    verdicts = {0: 0, 2: 0}
    for trial in range(150):
        k, problems = _random_replan_problem(rng, far=trial % 5 == 0)
        for kw in problems:
            want = linprog(**kw, method="highs")
            got = _linprog_c(**kw)
            assert (got.status == 0) == (want.status == 0), (got, want.status)
            verdicts[got.status] += 1
            if want.status == 0:
                assert got.fun == pytest.approx(want.fun, rel=1e-9, abs=1e-12)
                if kw is problems[0]:        # the minimax step is unique here
                    assert np.max(np.abs(got.x[:k] - want.x[:k])) <= 1e-7
    # both verdicts occur: the miss can and cannot be nulled within the trust region
    assert verdicts[0] > 100 and verdicts[2] > 10


def test_onboard_lp_on_general_programmes():
    # dense programmes with free, one-sided and boxed variables, inequality and equality rows;
    # some infeasible, some unbounded (lp.h reports both as status 2)
    rng = np.random.default_rng(7)
    seen = set()
    for trial in range(120):
        n, m_ub, m_eq = int(rng.integers(1, 8)), int(rng.integers(0, 30)), int(rng.integers(0, 3))
        kw = dict(c=rng.normal(size=n), A_ub=rng.normal(size=(m_ub, n)),
                  b_ub=rng.normal(size=m_ub) + (1.0 if trial % 3 else -1.0),
                  A_eq=rng.normal(size=(m_eq, n)), b_eq=rng.normal(size=m_eq),
                  bounds=[[(None, None), (0.0, None), (-1.0, 2.0), (None, 3.0)][j % 4]
                          for j in rng.integers(0, 4, n)])
        want = linprog(**kw, method="highs")
        got = _linprog_c(**kw)
        seen.add(want.status)
        assert got.status == (0 if want.status == 0 else 2), (trial, got, want.message)
        if want.status == 0:
            assert got.fun == pytest.approx(want.fun, rel=1e-9, abs=1e-9)
            x = got.x
            if m_ub:
                assert np.max(kw["A_ub"] @ x - kw["b_ub"]) <= 1e-9
            if m_eq:
                assert np.max(np.abs(kw["A_eq"] @ x - kw["b_eq"])) <= 1e-9
    assert seen >= {0, 2, 3}                 # optimal, infeasible and unbounded cases met


@pytest.mark.parametrize("kw, match", [
    (dict(c=[1.0, 2.0], A_ub=[[1.0, 2.0, 3.0]], b_ub=[1.0]), "3 columns|2 columns"),
    (dict(c=[1.0, 2.0], A_ub=[[1.0, 2.0]], b_ub=[1.0, 2.0]), "b_ub has 2"),
    (dict(c=[1.0, float("nan")]), "non-finite"),
    (dict(c=[1.0, 2.0], bounds=[(0.0, 1.0)]), "1 pairs for 2"),
    (dict(c=[1.0], bounds=[(float("inf"), None)]), "lower < inf"),
])
def test_onboard_lp_refuses_malformed_programmes(kw, match):
    with pytest.raises(ValueError, match=match):
        _linprog_c(**kw)


@pytest.fixture(scope="module")
def guided_twin(native_twin):
    """The native guided controller, built from this checkout's C once per session
    (tests/conftest.py; its builder: build_guided_controller)."""
    return native_twin("GuidedNetworkOperatorController")


def _samples(n: int):
    """``n`` samples of the scale-height family (the density profile's shape off: the profile
    fit and the plan both act; some beyond any constant control's reach)."""
    from descent_fmus.synthesis.systems.reentry.error_families import family_samples
    from descent_fmus.synthesis.systems.reentry.robust_study import plant_values
    return [(plant_values(s.plant), s.plant.h0) for s in family_samples("scale-height", n, 3)]


def _fly_both(fmu_dir, twin, settings, samples):
    from descent_fmus.synthesis.registry import get_problem
    wiring = get_problem("reentry-guided").wiring
    law = NetworkOperator.load(GUIDED_LAW).start_values()
    runs = []
    for ctrl in (fmu_dir / "GuidedNetworkOperatorController.fmu", twin):
        with ClosedLoop(wiring, fmu_dir / "Reentry.fmu", ctrl, record=("load",)) as loop:
            runs.append([loop.run(p, dict(law, replan=1, h0_line=h0, **v), record=True)
                         for v in settings for p, h0 in samples])
    return runs


#: the settings without an LP step the two tests below fly (the first: the plain re-planner)
NO_LP = [{"replan_iterations": 0},
         {"replan_iterations": 0, "correction_gate": 20.0, "noise": 0.05, "noise_seed": 3}]


@pytest.fixture(scope="module")
def no_lp_flights(fmu_dir, guided_twin):
    """``(pythonfmu flights, twin flights)`` of :data:`NO_LP` x 4 samples, flown once for the
    two tests below (the first flight: NO_LP[0] from the first sample)."""
    return _fly_both(fmu_dir, guided_twin, NO_LP, _samples(4))


def test_replan_twin_without_lp_steps_flies_bit_for_bit(no_lp_flights):
    # the plan's predictions, recorded loads, running peak, plan values and Brent's offset are
    # the Python's operation for operation: with no LP step every number is equal
    py, c = no_lp_flights
    for want, got in zip(py, c):
        assert got.final == want.final
        for name in ("ctrl.u[1]", "load"):
            assert [bits(v) for v in got[name]] == [bits(v) for v in want[name]], name


def test_replan_twin_outputs_without_lp_steps_at_every_step(fmu_dir, guided_twin,
                                                            no_lp_flights):
    # the controllers alone fed one recorded flight (the pythonfmu re-planner's): the plan's
    # correction, its predicted miss and the predictions made, equal at every communication
    # point
    from descent_fmus.synthesis.fmi.slave import load_slave
    from test_native_guided import INPUTS
    from fmi_calls import start
    (p, h0) = _samples(4)[0]                               # one the plan lands
    values = dict(NetworkOperator.load(GUIDED_LAW).start_values(), replan=1,
                  replan_iterations=0, h0_line=h0)
    assert NO_LP[0] == {"replan_iterations": 0}
    flight = no_lp_flights[0][0]                           # NO_LP[0] from (p, h0)
    assert flight.start == p
    names = ("u[1]", "correction", "predicted_miss", "drag_factor_log")
    seqs = []
    for k, path in enumerate((fmu_dir / "GuidedNetworkOperatorController.fmu", guided_twin)):
        fmu = load_slave(path, f"r{k}", [])
        try:
            vr = start(fmu, values)
            seq = []
            for i in range(len(flight.time)):
                fmu.setReal([vr[n] for n in INPUTS], [float(flight[v][i])
                                                       for v in INPUTS.values()])
                seq.append([bits(v) for v in fmu.getReal([vr[n] for n in names])]
                           + fmu.getInteger([vr["predictions"]]))
                fmu.doStep(float(flight.time[i]), 1.0)
            seqs.append(seq)
        finally:
            fmu.freeInstance()
    assert seqs[0] == seqs[1]
    assert seqs[0][-1][-1] > 20                           # predictions were made
    assert len({row[1] for row in seqs[0]}) > 20          # the plan's correction moved


@pytest.mark.slow
def test_replan_twin_flies_as_the_pythonfmu_replanner(fmu_dir, guided_twin):
    # the default one LP step a cycle: the landing and the peak load agree to the solvers'
    # rounding on the committed law (measured: 1e-9 m, 1e-11 relative)
    samples = _samples(6)
    py, c = _fly_both(fmu_dir, guided_twin, [{}], samples)
    for want, got in zip(py, c):
        assert got.final["status"] == want.final["status"] == 1
        assert got.final["L"] == pytest.approx(want.final["L"], abs=1e-3)
        assert got.final["load_max"] == pytest.approx(want.final["load_max"], rel=1e-6)
    # some samples land (the plan acted), some are beyond reach (the fallback programme)
    assert {abs(r.final["L"] - 1.4e6) < 1.0 for r in py} == {True, False}


def test_replan_twin_refuses_a_prediction_step_it_cannot_record(fmu_dir, guided_twin):
    from descent_fmus.synthesis.fmi.slave import load_slave
    from fmi_calls import start
    log = []
    fmu = load_slave(guided_twin, "r", log)
    try:
        with pytest.raises(Exception):
            start(fmu, {"replan": 1, "dt_pred": 1e-4})
        assert "dt_pred" in log[0] and "native re-planner" in log[0]
        start(fmu, {"replan": 1})                        # usable again
        start(fmu, {"replan": 0, "dt_pred": 1e-4})       # the single correction records none
    finally:
        fmu.freeInstance()


def test_problem_option_replan_flies_every_law_re_planned(fmu_dir):
    # synthesize reentry-guided --option replan=1: the runner sets replan = 1 over every law's
    # start values, on the evaluator's path (the law as an array) as on the Python master (a
    # dict); the flights equal the Python master's with replan = 1 set by hand (the same
    # native FMUs: bitwise) and differ from the single correction's
    from descent_fmus.synthesis.registry import get_problem
    problem = get_problem("reentry-guided")
    twins = (fmu_dir / "native" / "Reentry.fmu",
             fmu_dir / "native" / "GuidedNetworkOperatorController.fmu")
    if not twins[1].is_file():
        pytest.skip("no native twins in the FMU folder")
    replanned = problem.with_option("replan", "1")
    assert dict(replanned.controller_values) == {"replan": 1}
    assert "replan 1" in replanned.source and replanned.source != problem.source
    assert replanned.with_option("replan", "0").controller_values == ()
    law = problem.basic()
    states = replanned.initial_states[:3]
    sub = replanned.with_(initial_states=states)
    loop = sub.runner.load(sub.wiring, *problem.fmu_paths(fmu_dir))
    try:
        assert loop.path == "native-c"
        got = [r.final for r in sub.runner.flights(loop, sub, law)]
        single = [r.final for r in sub.runner.flights(loop, problem.with_(initial_states=states),
                                                      law)]
    finally:
        loop.close()
    with ClosedLoop(problem.wiring, *twins) as master:
        want = [master.run(s, {**law.start_values(), "replan": 1}).final for s in states]
    assert got == want
    assert all(g["load_max"] != s["load_max"] for g, s in zip(got, single))


@pytest.mark.parametrize("value", ["2", "yes", ""])
def test_problem_option_replan_refuses_other_values(value):
    from descent_fmus.synthesis.registry import get_problem
    with pytest.raises(ValueError, match="replan must be 0 or 1"):
        get_problem("reentry-guided").with_option("replan", value)


@pytest.mark.parametrize("pairs", [(("replan",),), ((1, 1.0),), (("replan", float("nan")),)])
def test_problem_controller_values_must_be_name_number_pairs(pairs):
    from descent_fmus.synthesis.registry import get_problem
    with pytest.raises(ValueError, match="controller_values"):
        get_problem("reentry-guided").with_(controller_values=pairs)
