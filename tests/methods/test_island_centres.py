"""Where a new island starts (``island_from``): the tuned basic solution ('basic', the
default: tests/methods/test_islands.py), that solution with random variations drawn anew for
each island ('varied'), or the stalled population's Pareto member of another form farthest
from the best law ('archive').  Closed-form toy problems (no FMU); the oracles are hand
counts of matrix entries and the codec's own ``apply`` (docs/methods/network_operator.md,
"islands from varied basic solutions")."""
from __future__ import annotations

import json

import numpy as np
import pytest

from descent_fmus.synthesis.methods.encoding import StructureCodec
from descent_fmus.synthesis.methods.ga_config import GAConfig

from test_islands import BASIC, _basis_best, _ga, _run


def _island_ga(seed: int, island_from: str, generations=None, island_variations: int = 0):
    # island_variations 0: lchr (4 here) variations, the hand counts below
    return _ga(seed, generations, island_from=island_from, island_variations=island_variations)


def _stalled(ga):
    """The initial population flown; the tuned basic solution recorded as an epoch would."""
    ga.tell(_basis_best([c.law for c in ga.ask()]))
    ga._origin = (BASIC.psi.copy(), ga.pop[0].bits.copy())
    ga._epoch_psi = BASIC.psi.copy()
    return ga


def test_a_varied_island_starts_from_the_basic_solution_with_lchr_random_variations():
    ga = _stalled(_island_ga(5, "varied"))
    origin_bits = ga.pop[0].bits.copy()
    state = ga.rng.bit_generator.state
    members = ga._restart(None, ga.pop[0])
    # the centre is the basic matrix with the 4 (lchr) variations drawn next from the run's
    # generator: the oracle redraws them from the same state and applies them with the codec
    rng = np.random.default_rng()
    rng.bit_generator.state = state
    drawn = [ga.structure.random(rng) for _ in range(4)]
    assert np.array_equal(ga.psi0, ga.structure.apply(BASIC.psi, drawn))
    # at most one entry per variation differs from the basic matrix; the parameters are the
    # tuned basic solution's, member 0 the centre itself
    assert int(np.count_nonzero(ga.psi0 != BASIC.psi)) <= 4
    assert np.array_equal(members[0].bits, origin_bits)
    assert all(v == StructureCodec.IDENTITY for v in members[0].variations)
    assert ga.stats["islands"] == 1


def test_varied_islands_take_turns_with_the_best_law_and_the_run_resumes():
    # stalls at epochs 3, 6, 9 (the hand count of test_islands.py): 3 restarts.  A varied
    # centre is another form than the basic law, which is the best law of this toy problem
    # (value 1, every other form 2 or more): the first island stalls below the law kept
    # aside and goes back to it (restart 2), the third restart is a new island: 2 islands
    a = _run(_island_ga(3, "varied", 60))
    assert a.stats["restarts"] == 3 and a.stats["islands"] == 2
    assert [e["islands"] for e in a.stats["epochs"]] == [0, 0, 0, 1, 1, 1, 1, 1, 1, 2, 2]
    # the same seed, the same run; a JSON checkpoint resumes it to the same end
    c = _run(_island_ga(3, "varied", 32))
    d = _run(_island_ga(999, "varied", 60).load_state(json.loads(json.dumps(c.state()))))
    assert np.array_equal(a.F, d.F) and a.evaluations == d.evaluations


def test_an_archive_island_starts_from_the_farthest_pareto_form():
    ga = _stalled(_island_ga(5, "archive"))
    n0 = BASIC.nx + len(BASIC.q)
    arcs = [(i, j) for j in range(n0, BASIC.size) for i in range(j) if BASIC.psi[i, j] == 1]
    for m in ga.pop:
        m.variations = [StructureCodec.IDENTITY] * 4
    # member 1: one arc's operation changed (1 entry from the best, the basic law); member
    # 2: two arcs changed (2 entries); member 3: three arcs, but dominated
    (i1, j1), (i2, j2), (i3, j3) = arcs[:3]
    ga.pop[1].variations[0] = (0, i1, j1, 3)
    ga.pop[2].variations[:2] = [(0, i1, j1, 3), (0, i2, j2, 3)]
    ga.pop[3].variations[:3] = [(0, i1, j1, 3), (0, i2, j2, 3), (0, i3, j3, 3)]
    F = np.full((16, 2), 9.0)
    F[0], F[1], F[2], F[3] = [1.0, 5.0], [2.0, 4.0], [3.0, 3.0], [4.0, 4.0]
    for m, f in zip(ga.pop, F):
        m.f, m.cv = f, 0.0
    from descent_fmus.synthesis.methods.pareto import dominance_counts
    ga.lh = dominance_counts(ga.F, ga.CV)
    assert list(np.flatnonzero(ga.lh == 0)) == [0, 1, 2]     # hand count: 3 dominated by 2
    best = ga.pop[0]
    members = ga._restart(None, best)
    # the centre is member 2's matrix (2 entries from the best's, the farthest Pareto form;
    # member 3 is farther but dominated) with member 2's bits
    want = ga.structure.apply(BASIC.psi, ga.pop[2].variations)
    assert int(np.count_nonzero(want != BASIC.psi)) == 2
    assert np.array_equal(ga.psi0, want)
    assert np.array_equal(members[0].bits, ga.pop[2].bits)
    assert ga.stats["island_archive"] == 1 and ga.stats["islands"] == 1


def test_an_archive_island_without_another_pareto_form_starts_at_the_basic_solution():
    ga = _stalled(_island_ga(5, "archive"))
    for m in ga.pop:
        m.variations = [StructureCodec.IDENTITY] * 4     # every member the basic form
    origin = ga.pop[0].bits.copy()
    members = ga._restart(None, ga.pop[0])
    assert np.array_equal(ga.psi0, BASIC.psi) and np.array_equal(members[0].bits, origin)
    assert "island_archive" not in ga.stats


def test_island_from_is_checked_and_varied_by_default():
    # the [choice] of the methods page: islands drawn around the tuned basic solution with 2
    # random variations
    assert GAConfig().island_from == "varied" and GAConfig().island_variations == 2
    with pytest.raises(ValueError, match="island_from"):
        GAConfig(island_from="elsewhere")


def test_the_law_kept_aside_is_the_best_laws_matrix_after_the_basis_moved():
    # the epoch moves the basis to the best law's matrix before the restart; the law kept
    # aside must be that matrix, not the best law's variations applied to it once more (a
    # variation list applied twice is not always the matrix applied once: a removal or an
    # added arc can enable another variation of the list).  The oracle is the codec's own
    # apply on the stalled basis; without the fix this test fails
    ga = _stalled(_island_ga(5, "basic"))
    rng = np.random.default_rng(11)
    for _ in range(2000):                       # a non-idempotent list (0.7 % of draws)
        var = [ga.structure.random(rng) for _ in range(4)]
        once = ga.structure.apply(BASIC.psi, var)
        if not np.array_equal(ga.structure.apply(once, var), once):
            break
    else:
        pytest.fail("no non-idempotent variation list drawn")
    best = ga.pop[3]
    best.variations, best.f = var, np.array([0.5, 0.0])
    ga._epoch_psi = BASIC.psi.copy()
    ga.psi0 = once.copy()                       # the epoch's move of the basis
    ga._restart(None, best)
    assert np.array_equal(ga._elite["psi"], once)


def test_island_variations_sets_how_far_a_varied_centre_is_drawn():
    ga = _stalled(_island_ga(5, "varied"))
    ga.cfg = GAConfig(**{**ga.cfg.__dict__, "island_variations": 2})
    state = ga.rng.bit_generator.state
    ga._restart(None, ga.pop[0])
    rng = np.random.default_rng()
    rng.bit_generator.state = state
    drawn = [ga.structure.random(rng) for _ in range(2)]   # 2 draws, not lchr = 4
    assert np.array_equal(ga.psi0, ga.structure.apply(BASIC.psi, drawn))
    assert int(np.count_nonzero(ga.psi0 != BASIC.psi)) <= 2
