"""S5 through the FMUs: the registered synthesis problem through the evaluator, the status
convention of the LunarDescent FMU, exported laws and the closed-loop FMU under fmpy simulate,
the committed synthesised law, bad input."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from fmpy import simulate_fmu

from descent_fmus.models.integrators import CRASHED, LEFT_DOMAIN, REACHED
from descent_fmus.models.lunar_descent import DescentParams, simulate
from descent_fmus.synthesis.fmi.slave import FMUError
from descent_fmus.synthesis.run.evaluation import Evaluator
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.run.loop import run_synthesis
from descent_fmus.synthesis.systems.lunar_descent.problems import (INITIAL_SET, initial_states,
                                                                    per_state,
                                                                    synthesis_basic_law, totals)
from descent_fmus.synthesis.systems.lunar_descent.study import fly_in_process, load_loop

ROOT = Path(__file__).resolve().parents[3]
REFERENCE_LAW = ROOT / "tests" / "reference" / "lunar_descent_law.json"
FINAL = ["V", "h", "h_min", "fuel", "t_end", "status"]


def _in_process_final(fi) -> dict:
    """The plant's final outputs of an in-process flight (DescentIntegrator)."""
    return {"V": fi.x[0], "h": fi.x[2], "h_min": fi.h_min, "fuel": 1400.0 - fi.x[4],
            "t_end": fi.t_end_output, "status": fi.status}


@pytest.fixture(scope="module")
def loop(fmu_dir):
    with load_loop(fmu_dir, record=()) as lp:
        yield lp


def test_evaluator_runs_the_registered_problem_through_the_fmus(fmu_dir):
    # oracle: the same laws flown in-process (models.lunar_descent.simulate, same equations)
    prob = get_problem("lunar-descent")
    basic = prob.basic()
    laws = [basic, basic.with_q([3.4] + basic.q[1:])]
    with Evaluator(prob, fmu_dir) as ev:        # built from FMU paths alone
        res = ev.evaluate(laws + laws)
        F, extras = res.F, res.extras
        assert ev.simulated == 2
    for law, f, ex in zip(laws, F, extras):
        rows = [per_state(_in_process_final(fly_in_process(law, th, h0)))
                for th, h0 in INITIAL_SET]
        (j1, j2), _ = totals(rows)
        assert f == pytest.approx((j1, j2), rel=1e-9, abs=1e-9)
    # the basic (designer's linear) law already reaches the box from every initial state;
    # 211.48 m, 50 m/s: the measured basic law (models/README.md, S5 basic law)
    assert extras[0]["in_box"] == 5 and extras[0]["h_min"] > 1500.0
    assert F[0] == pytest.approx((211.48, 50.0), abs=0.01)


@pytest.mark.parametrize("tilt, status", [(None, REACHED), (0.3, CRASHED), (0.4, LEFT_DOMAIN)])
def test_fmu_status_at_the_terminal_condition(loop, tilt, status):
    # status convention (models/integrators.py): 1 in the box, 2 at h = 0, 3 at V = 1 m/s;
    # t_end and the end state agree with the in-process integrator (same equations, oracle)
    th, h0 = INITIAL_SET[-1]
    if tilt is None:
        law = synthesis_basic_law()
        fi = fly_in_process(law, th, h0)
    else:   # u1 = theta + pi + tilt, u2 = 0 as a network-operator law
        law = synthesis_basic_law(q=(math.pi + tilt,) + (0.0,) * 7)
        fi = simulate(DescentParams(theta0=th, h0=h0),
                      lambda t, x: (x[1] + math.pi + tilt, 0.0))
    res = loop.run(plant_values={"theta0": th, "h0": h0},
                   controller_values=law.start_values())
    assert res.stopped and res.final["status"] == status == fi.status
    assert res.final["t_end"] == pytest.approx(fi.t_end, rel=1e-9)
    assert res.final["h"] == pytest.approx(fi.x[2], rel=1e-6, abs=1e-6)
    assert res.final["V"] == pytest.approx(fi.x[0], rel=1e-6, abs=1e-6)


def test_closed_loop_fmu_flies_the_basic_law(fmu_dir, loop):
    # the built LunarDescentClosedLoop.fmu carries the basic law as controller defaults: fmpy's
    # container gives the flight of the Python master (oracle: ClosedLoop.run)
    th, h0 = INITIAL_SET[0]
    res = simulate_fmu(str(fmu_dir / "LunarDescentClosedLoop.fmu"),
                       start_values={"theta0": th, "h0": h0}, output=FINAL)
    ref = loop.run(plant_values={"theta0": th, "h0": h0},
                   controller_values=synthesis_basic_law().start_values()).final
    last = res[-1]
    assert last["status"] == REACHED
    for name in ("V", "h", "h_min", "fuel", "t_end"):
        assert last[name] == pytest.approx(ref[name], rel=1e-12, abs=1e-9)


def test_exported_law_reproduces_its_pareto_row(fmu_dir, tmp_path):
    # oracle: the Pareto row computed by the evaluator (Python master) vs fmpy simulate of the
    # exported closed-loop FMU
    problem = get_problem("lunar-descent").tuned(population=6, crossovers=2, lchr=2, epoch=2,
                                                 generations=1, seed=3, refine_basis=200,
                                                 refine_starts=1)
    s = run_synthesis(problem, tmp_path / "run", fmu_dir, progress=False)
    row = s["pareto"][0]
    rows = []
    for th, h0 in INITIAL_SET:
        res = simulate_fmu(row["closed_loop_fmu"], start_values={"theta0": th, "h0": h0},
                           output=FINAL)
        rows.append(per_state({k: res[-1][k] for k in FINAL}))
    (j1, j2), _ = totals(rows)
    assert (j1, j2) == pytest.approx((row["J1"], row["J2"]), rel=1e-12, abs=1e-9)
    law = NetworkOperator.load(Path(row["closed_loop_fmu"]).parent / "law.json")
    assert law.formula(6) == row["formula"] and law.outputs == [26, 32]


def test_committed_synthesised_law(loop):
    # tests/reference/lunar_descent_law.json: Pareto law of `descent-fmus synthesize
    # lunar-descent` (default budget, GA seed 1; models/README.md); oracle: its J1, J2 recorded
    # in lunar_descent_law.meta.json.  Every initial state ends in the box, never below the
    # box floor, closer to the box centre in h than the basic law (211.48 m)
    law = NetworkOperator.load(REFERENCE_LAW)
    meta = json.loads(REFERENCE_LAW.with_suffix(".meta.json").read_text())
    rows = [per_state(loop.run(plant_values=s, controller_values=law.start_values()).final)
            for s in initial_states()]
    assert all(r["in_box"] for r in rows) and min(r["h_min"] for r in rows) >= 1500.0
    j1, j2 = sum(r["j1"] for r in rows), sum(r["j2"] for r in rows)
    assert (j1, j2) == pytest.approx((meta["J1"], meta["J2"]), rel=1e-9)
    assert j1 < 0.5 * 211.48 and j2 <= 50.0 + 1e-9


def test_fmu_bad_input(loop):
    with pytest.raises(FMUError, match="P_ud must be > 0"):
        loop.run(plant_values={"P_ud": -5.0})
    # the loop is still usable after the error
    res = loop.run(plant_values=initial_states()[0],
                   controller_values=synthesis_basic_law().start_values())
    assert res.final["status"] == REACHED
