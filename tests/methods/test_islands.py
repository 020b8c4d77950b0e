"""Restarts of a stalled structure search from the basic solution (``restart_from =
"islands"``, ``island_from = "basic"``, the default; the others: test_island_centres.py) and
the per-epoch log of the search (``stats["epochs"]``), on closed-form toy problems (no FMU):
the islands are counted as designed (hand counts), start from the tuned basic solution, go
back to the run's best law when an island stalls below it, and resume from a JSON checkpoint
to the same run."""
from __future__ import annotations

import json

import numpy as np

from descent_fmus.synthesis.methods.encoding import GrayCodec, StructureCodec
from descent_fmus.synthesis.methods.ga_config import GAConfig
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.pareto import ParetoArchive, Target
from descent_fmus.synthesis.methods.refinement import RefineConfig
from descent_fmus.synthesis.methods.variational_ga import VariationalGA
from descent_fmus.synthesis.run.evaluation import Evaluation
from descent_fmus.synthesis.run.loop import RunLoop

BASIC = NetworkOperator.linear([[-1.0, -1.5]], bounds=[(-1.0, 1.0)], size=12)


def _ga(seed: int, generations: int | None, restart_from: str = "islands",
        stall_gain: float = 1e-3, island_from: str = "basic",
        island_variations: int = 0) -> VariationalGA:
    return VariationalGA(GrayCodec(len(BASIC.q), 6, 26, -32.0, 32.0), BASIC.q,
                         np.random.default_rng(seed),
                         GAConfig(population=16, crossovers=4, lchr=4, epoch=5,
                                  restart_epochs=2, restart_from=restart_from,
                                  stall_gain=stall_gain, island_from=island_from,
                                  island_variations=island_variations),
                         StructureCodec(BASIC.size, BASIC.nx + len(BASIC.q)), BASIC.psi,
                         BASIC.with_structure, target=Target(0),
                         refine=RefineConfig(basis=0, evals=0), generations=generations)


def _basis_best(laws) -> np.ndarray:
    """1 for the basic matrix, 2 + (changed entries) for any other: no law beats the basis,
    the search stalls from its first epoch."""
    return np.array([(1.0 if np.array_equal(law.psi, BASIC.psi)
                      else 2.0 + np.sum(law.psi != BASIC.psi), float(np.sum(np.abs(law.q))))
                     for law in laws])


def _run(ga: VariationalGA, objectives=_basis_best) -> VariationalGA:
    def evaluate(laws):
        F = objectives(laws)
        return Evaluation(F, np.zeros(len(F)), [{}] * len(F), len(F))
    return RunLoop(ga, evaluate, ParetoArchive()).run().method


def test_islands_are_counted_as_designed_and_resume():
    a = _run(_ga(3, 60))
    # epochs at generations 5, 10, ..., 55 (11); an island restarts the stall count: the
    # first epoch after it sets the mark, two stalled ones restart (epochs 3, 6, 9): 3
    # restarts (hand count), each a new island (the best law, the basic one, is the run's
    # best every time: nothing to go back to)
    assert a.stats["restarts"] == 3 and a.stats["islands"] == 3
    log = a.stats["epochs"]
    assert [e["gen"] for e in log] == list(range(5, 56, 5))
    assert [e["islands"] for e in log] == [0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3]
    # the log's columns: the best law is the basis (value 1), the children counted per epoch
    # sum to the run's children, and accepted ones never exceed them
    assert all(e["best"] == 1.0 for e in log)
    assert all(0 <= e["accepted"] <= e["children"] for e in log)
    assert log[-1]["children_total"] <= a.stats["children"]
    # 'best' restarts (the previous rule) count 5 on the same run (test_search.py): the
    # stall mark is kept there
    assert _run(_ga(3, 60, "best")).stats["restarts"] == 5
    # the same seed, the same run; a JSON checkpoint resumes it to the same end
    b = _run(_ga(3, 60))
    assert np.array_equal(a.F, b.F) and a.evaluations == b.evaluations
    c = _run(_ga(3, 32))
    state = json.loads(json.dumps(c.state()))
    d = _run(_ga(999, 60).load_state(state))
    assert np.array_equal(a.F, d.F) and d.stats["islands"] == 3


def test_an_island_starts_at_the_basic_solution_and_goes_back_to_the_best_law():
    ga = _ga(5, None)
    ga.tell(_basis_best([c.law for c in ga.ask()]))               # the initial population
    origin_bits = ga.pop[0].bits.copy()
    ga._origin = (BASIC.psi.copy(), origin_bits)
    # the run's best law: member 3 with other variations and parameters, better than all
    best = ga.pop[3]
    best.f = np.array([0.5, 0.0])
    best_psi = ga.matrix(best)
    members = ga._restart(None, best)
    # a new island: the basis is the basic solution (matrix and bits), member 0 its identity,
    # the other members drawn anew; the best law is kept aside
    assert np.array_equal(ga.psi0, BASIC.psi) and np.array_equal(members[0].bits, origin_bits)
    assert len(members) == 16 and all(v == StructureCodec.IDENTITY
                                      for v in members[0].variations)
    assert np.array_equal(ga._elite["psi"], best_psi) and ga._elite["f"][0] == 0.5
    assert ga.stats["islands"] == 1 and ga.stats["restart_mark"] is None
    # the island stalls at 0.8, worse than the law kept aside: back to that law (its matrix
    # the basis, its bits member 0's), nothing kept aside any more
    island_best = members[2]
    island_best.f, island_best.cv = np.array([0.8, 0.0]), 0.0
    back = ga._restart(None, island_best)
    assert np.array_equal(ga.psi0, best_psi) and np.array_equal(back[0].bits, best.bits)
    assert ga._elite is None and ga.stats["islands"] == 1 and ga.stats["restarts"] == 2
    # an island that beats the law kept aside is the run's best: the next stall starts a new
    # island and keeps the island's law aside
    ga._elite = {"psi": best_psi, "bits": best.bits.copy(), "f": np.array([0.5, 0.0]),
                 "cv": 0.0}
    island_best.f = np.array([0.3, 0.0])
    ga._restart(None, island_best)
    assert np.array_equal(ga.psi0, BASIC.psi) and ga._elite["f"][0] == 0.3
    assert ga.stats["islands"] == 2


def test_an_island_needs_room_for_three_epochs():
    ga = _ga(5, None)
    ga.refine_cfg = RefineConfig(basis=0, evals=0, forms=0)      # an epoch: its 80 children
    ga.tell(_basis_best([c.law for c in ga.ask()]))
    ga._origin = (BASIC.psi.copy(), ga.pop[0].bits.copy())
    members = [ga.pop[k] for k in range(16)]
    # 5 generations x 4 crossovers x 4 children = 80 a epoch, 3 epochs 240 (hand count)
    ga.flights, ga.evaluations = 1000, 761                     # 239 left: no island
    assert ga._restart(members, ga.pop[0]) is members and "restarts" not in ga.stats
    ga.evaluations = 760                                       # 240 left: an island
    assert ga._restart(members, ga.pop[0]) is not members and ga.stats["islands"] == 1
    # an island running below the law kept aside (value 1) is over when the flights left no
    # longer hold 3 epochs, stalled or not; going back to that law needs no room
    worse = ga.pop[1]
    worse.f = np.array([5.0, 0.0])
    assert not ga._island_over(worse)                          # 240 left: the island goes on
    ga.evaluations = 999
    assert ga._island_over(worse) and not ga._island_over(ga.pop[0])   # not if it is better
    assert ga._restart(members, worse) is not members and ga.stats["restarts"] == 2
    assert ga._elite is None and not ga._island_over(worse)


def test_the_epoch_log_counts_the_population_as_designed():
    ga = _ga(5, None)
    ga.tell(_basis_best([c.law for c in ga.ask()]))               # the initial population
    # every member the basic law, but members 1 and 2: one arc's unary operation replaced
    # (a different operation each), so 3 structures, the best law's (member 0) held by 14 of
    # 16 members, and a mean of 2 changed entries over 16 members from the best (hand count)
    n0 = BASIC.nx + len(BASIC.q)
    i, j = next((i, j) for j in range(n0, BASIC.size) for i in range(j)
                if BASIC.psi[i, j] == 1)
    for m in ga.pop:
        m.variations = [StructureCodec.IDENTITY] * 4
    ga.pop[1].variations[0] = (0, i, j, 2)
    ga.pop[2].variations[0] = (0, i, j, 3)
    ga.stats.update(children=40, accepted=10)
    ga._log_epoch(0)
    row = ga.stats["epochs"][-1]
    assert (row["forms"], row["share_best"], row["dist"]) == (3, 14 / 16, 2 / 16)
    assert row["best"] == ga.pop[0].f[0] == 1.0
    assert (row["children"], row["accepted"]) == (40, 10)
    # the next row counts the children since this one
    ga.stats.update(children=100, accepted=25)
    ga._log_epoch(0)
    assert (ga.stats["epochs"][-1]["children"], ga.stats["epochs"][-1]["accepted"]) == (60, 15)


def test_the_epoch_log_reads_no_random_numbers():
    # the log is a statistic: two runs whose only difference is the stall gain (no stall can
    # happen at the first epoch) fly the same laws and log the same row
    a, b = _run(_ga(7, 10, stall_gain=1e-3)), _run(_ga(7, 10, stall_gain=0.5))
    assert np.array_equal(a.F, b.F)
    assert a.stats["epochs"] == b.stats["epochs"] and len(a.stats["epochs"]) == 1
