"""The one run loop, the method interface and the problem contract.

Oracles: the Pareto sets the registered problems gave before the run side was rebuilt around
the method interface (``tests/reference/pareto_pins.json``: the same problems, seeds and
budgets run by the code of commit e5eb9c6, exact to the last bit), a toy method whose every
number is known (it proposes given laws in a given order), and hand-made initial states.
"""
from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest

from descent_fmus.synthesis.methods.base import Candidate, Method
from descent_fmus.synthesis.methods.registry import MethodEntry, register, unregister
from descent_fmus.synthesis.problems.contract import Constraint
from descent_fmus.synthesis.problems.files import load_problem_file
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.run.loop import run_synthesis
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law

ROOT = Path(__file__).resolve().parents[2]
PINS = json.loads((ROOT / "tests/reference/pareto_pins.json").read_text())


def _pareto(problem, out: Path) -> list:
    rows = json.loads((out / "pareto.json").read_text())
    return [{"f": [r[n] for n in problem.objective_names], "q": r["law"]["q"],
             "psi_sha1": hashlib.sha1(np.asarray(r["law"]["psi"], dtype=np.int64).tobytes())
             .hexdigest()} for r in rows]


@pytest.mark.parametrize("name", list(PINS))
def test_registered_problems_give_their_pinned_pareto_sets(name, fmu_dir, tmp_path):
    # S1 (the full recipe: basis refinement, refinement per epoch, target basis rule, flight
    # budget; the GA alone; the cma-polynomial baseline; the robust variant), S5, and S1 as a
    # problem file: the same flights and the same Pareto set, bit for bit
    pin = PINS[name]
    problem = (load_problem_file(ROOT / pin["file"], fmu_dir) if "file" in pin
               else get_problem(pin["problem"])).tuned(**pin["settings"])
    if "q_bits" in pin:                 # the Gray code the configuration was pinned with
        problem = problem.with_(q_bits=tuple(pin["q_bits"]))
    s = run_synthesis(problem, tmp_path / "run", fmu_dir, method=pin["method"], progress=False,
                      export=False, reference=False)
    assert s["simulated"] == pin["simulated"]
    assert _pareto(problem, tmp_path / "run") == pin["pareto"]


# -- a toy method, registered here, through the loop and the command line ----------------------
class Ladder(Method):
    """Proposes the paper's basic law with q1 = 1, 2, 3, ... two laws per generation."""

    def __init__(self, problem, generations):
        self.basic, self.generations = paper_basic_law(), generations
        self.generation = self.evaluations = 0
        self.told = []

    def ask(self):
        k = 2 * self.generation
        return [Candidate(self.basic.with_q([float(k + 1 + i), 1.953125]), {"rung": k + i})
                for i in range(2)]

    def tell(self, F, cv):
        self.told += [list(f) for f in F]
        self.evaluations += len(F)
        self.generation += 1

    def finished(self):
        return self.generation >= self.generations

    def state(self):
        return {"generation": self.generation, "evaluations": self.evaluations,
                "told": self.told}

    def load_state(self, st):
        self.generation, self.evaluations, self.told = (st["generation"], st["evaluations"],
                                                        st["told"])
        return self


@pytest.fixture
def ladder():
    register(MethodEntry("ladder", lambda p, v: Ladder(p, p.budget.generations),
                         summary="a test method"))
    yield
    unregister("ladder")


def test_a_registered_method_runs_checkpoints_and_resumes(ladder, fmu_dir, tmp_path, capsys):
    from descent_fmus.synthesis.cli.main import main
    problem = get_problem("reentry").tuned(generations=4)
    # interrupted after 2 generations, resumed: the same archive and summary as one run
    cut = run_synthesis(problem, tmp_path / "b", fmu_dir, method="ladder", progress=False,
                        export=False, reference=False, stop_after=2)
    assert cut["interrupted"] and cut["generation"] == 2
    ck = json.loads((tmp_path / "b" / "checkpoint.json").read_text())
    assert ck["method"]["evaluations"] == 4 and ck["simulated"] == 4
    code = main(["synthesize", "reentry", "--method", "ladder", "--generations", "4",
                 "--workers", "1", "--no-export", "--no-reference", "--json", "--fmus",
                 str(fmu_dir), "--out", str(tmp_path / "a")])
    full = json.loads(capsys.readouterr().out)
    assert code == 0 and full["method"] == "ladder"
    assert full["generations"] == 4 and full["evaluations"] == 8 and full["flights"] == 8
    assert full["simulated"] == 9            # the report flies the problem's basic law too
    # why it ended: its 4 generations, 20 000 - 8 flights of the recipe's budget left
    assert (full["ended_by"], full["flights_left"]) == ("generations", 19992)
    done = run_synthesis(problem, tmp_path / "b", fmu_dir, method="ladder", resume=True,
                         progress=False, export=False, reference=False)
    assert (tmp_path / "a" / "pareto.csv").read_text() == \
        (tmp_path / "b" / "pareto.csv").read_text()
    assert done["generations"] == 4 and done["flights"] == 8
    # what the method reported with a law reaches pareto.json
    assert all("rung" in r for r in json.loads((tmp_path / "a" / "pareto.json").read_text()))


def test_the_loop_says_which_limit_ended_it():
    # oracle: the toy method's arithmetic -- two new laws a generation, each one flight
    from descent_fmus.synthesis.run.evaluation import Evaluation
    from descent_fmus.synthesis.run.loop import RunLoop

    def evaluate(laws):
        return Evaluation(np.zeros((len(laws), 2)), np.zeros(len(laws)), [{}] * len(laws),
                          len(laws))
    gens = RunLoop(Ladder(None, 3), evaluate, flights=100).run()
    assert gens.end_fields(3) == {
        "ended_by": "generations", "flights_left": 94,
        "ended_because": "the generation limit (3 generations) was reached, 94 of the 100 "
                         "flights left"}
    spent = RunLoop(Ladder(None, 50), evaluate, flights=7).run()     # 8 >= 7 after 4 gens
    assert spent.method.generation == 4 and spent.end_fields(50) == {
        "ended_by": "flights", "flights_left": 0,
        "ended_because": "the flight budget (7 flights) was spent"}
    clock = RunLoop(Ladder(None, 10 ** 9), evaluate, seconds=1e-9).run()
    assert clock.method.generation == 0 and clock.end_fields()["ended_by"] == "seconds"


def test_an_objective_reads_the_initial_state_it_was_flown_from(fmu_dir, tmp_path):
    # two initial states with different target ranges Lf: each flight's miss is judged against
    # its own Lf (read from the flight, no module constant of the initial states); the oracle
    # is a plain flight of each state with its own ReentryParams
    from descent_fmus.models.reentry import ReentryParams
    from descent_fmus.synthesis.run.evaluation import Evaluator
    from descent_fmus.synthesis.systems.reentry.flight import fly
    base = get_problem("reentry")
    lf = base.initial_states[0]["Lf"]
    states = (dict(base.initial_states[0]), dict(base.initial_states[0], Lf=lf + 5000.0))
    seen = []

    def objectives(flights):
        seen.extend(f.start["Lf"] for f in flights)
        miss = [abs(f.final["L"] - f.start["Lf"]) for f in flights]
        return tuple(miss), {}

    problem = base.with_(initial_states=states, objectives=objectives)
    with Evaluator(problem, fmu_dir) as ev:
        F = ev.evaluate([paper_basic_law()]).F
    assert seen == [lf, lf + 5000.0]
    for k, state in enumerate(states):
        ref = fly(paper_basic_law(), params=ReentryParams(**state), fmu_dir=fmu_dir)
        assert F[0, k] == pytest.approx(ref.objectives["J2"], rel=1e-12)


def test_constraints_rank_first_and_the_report_counts_them(fmu_dir, tmp_path):
    # a constraint no law can meet (max load below 1 g: the basic law peaks at 8.8 g): the run
    # still reports the least violating laws, says none is feasible and why
    problem = get_problem("reentry").tuned(population=8, crossovers=2, lchr=2, epoch=2,
                                            generations=2, refine_evals=0, refine_basis=0,
                                            flights=0, basis_rule="compromise")
    problem = problem.with_(constraints=(Constraint("load", _load_max, 1.0),))
    s = run_synthesis(problem, tmp_path / "run", fmu_dir, progress=False, export=False,
                      reference=False)
    feas = s["feasibility"]
    assert feas["infeasible"] == feas["evaluated"] > 0
    best = feas["best_infeasible"]
    assert best["constraints"]["load"]["bound"] == 1.0
    assert best["constraints"]["load"]["value"] == pytest.approx(best["violation"] + 1.0)
    assert all(not r["feasible"] for r in s["pareto"])
    # the archive keeps only the least violating laws: one violation value
    assert len({r["violation"] for r in s["pareto"]}) == 1
    assert s["pareto"][0]["violation"] == pytest.approx(best["violation"])
    assert math.isfinite(s["basic_law"]["violation"]) and s["basic_law"]["violation"] > 6.0


def _load_max(flight) -> float:
    return flight.final["load_max"]
