"""Fixed-structure policy search (CMA-ES over q) and the baseline law structures.

Oracles: the closed forms of a polynomial and of a one-hidden-layer tanh network (evaluated here
with numpy), a quadratic bowl whose minimum is known, and an uninterrupted run (for the
checkpoint).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.cma import CMA
from descent_fmus.synthesis.methods.pareto import Target
from descent_fmus.synthesis.methods.policy_search import PolicySearch
from descent_fmus.synthesis.methods.structures import monomials, polynomial_law, tanh_network_law
from descent_fmus.synthesis.run.evaluation import Evaluation
from descent_fmus.synthesis.run.loop import RunLoop

TEMPLATE = NetworkOperator.linear([[1.0, 1.0]], bounds=[(-0.2, 0.2)], input_names=["a", "b"],
                                  input_scale=[10.0, 2.0])


def test_monomials_of_a_cubic_in_two_inputs():
    # C(2 + 3, 3) - 1 = 9 monomials of degree 1..3
    assert monomials(2, 3) == [(1, 0), (0, 1), (2, 0), (1, 1), (0, 2), (3, 0), (2, 1), (1, 2),
                               (0, 3)]
    assert len(monomials(4, 2)) == 14


def test_polynomial_law_is_the_polynomial():
    c = np.linspace(-0.3, 0.4, 10)
    law = polynomial_law(TEMPLATE, 3, c, size=32)
    for x in [(0.05, -0.3), (-0.01, 0.2), (0.0, 0.0)]:
        a, b = 10 * x[0], 2 * x[1]          # the template's input scaling
        ref = c[0] + sum(ci * a ** i * b ** j for ci, (i, j) in zip(c[1:], monomials(2, 3)))
        assert law.raw(x)[0] == pytest.approx(ref, rel=1e-14, abs=1e-15)
        assert law(x)[0] == min(max(ref, -0.2), 0.2)
    assert law.size == 32 and len(law.q) == 10
    law.start_values()                        # fits the generic controller FMU


def test_tanh_network_law_is_the_network():
    law = tanh_network_law(TEMPLATE, hidden=3, seed=4)
    q = np.array(law.q)
    W, v, c = q[:9].reshape(3, 3), q[9:12], q[12]
    for x in [(0.05, -0.3), (-0.02, 0.4)]:
        s = np.array([10 * x[0], 2 * x[1], 1.0])
        ref = c + float(v @ np.tanh(W @ s / 2))
        assert law.raw(x)[0] == pytest.approx(ref, rel=1e-13)
    law.start_values()
    with pytest.raises(ValueError, match="13 parameters"):
        tanh_network_law(TEMPLATE, 3, weights=[0.0] * 12)


def test_target_scalar_and_feasibility():
    t = Target(0, 1, 1000.0, weight=10.0)
    F = np.array([[8.3, 900.0], [8.2, 1100.0], [8.4, 10.0]])
    assert t.feasible(F).tolist() == [True, False, True]
    assert t.scalar(F) == pytest.approx([8.3, 8.2 + 10 * 0.1, 8.4])
    assert t.best(F) == 0
    assert t.best(F[1:2]) is None


def run(search, objectives, evaluations):
    """The package's one run loop until ``evaluations`` candidates in all (whole generations)."""
    def evaluate(laws):
        F = np.atleast_2d(objectives(laws))
        return Evaluation(F, np.zeros(len(F)), [{}] * len(F), len(F))
    RunLoop(search, evaluate, flights=evaluations, flights_done=search.evaluations).run()
    return search


def _bowl(laws):
    # objective 1: distance of q from (0.3, -0.2, 0.1); objective 2: |q1| as a "miss"
    q = np.array([law.q for law in laws])
    return np.c_[((q - [0.3, -0.2, 0.1]) ** 2).sum(axis=1), np.abs(q[:, 0]) * 1000]


def _search(seed):
    law = NetworkOperator.linear([[1.0, 1.0]], bias=[0.5], bounds=[(-1, 1)])
    return PolicySearch(law, Target(0, 1, 250.0), seed=seed, sigma=0.3)


def test_policy_search_finds_the_constrained_minimum():
    # min |q - (0.3, -0.2, 0.1)|^2 subject to 1000 |q1| < 250: the minimum lies on the
    # constraint, q = (0.25, -0.2, 0.1), objective 0.05^2 = 0.0025 (closed form)
    s = run(_search(3), _bowl, 600)
    assert s.best_f[1] < 250.0
    assert s.best_f[0] == pytest.approx(0.0025, abs=2e-5)
    assert s.best_law.q == pytest.approx([0.25, -0.2, 0.1], abs=2e-3)


def test_policy_search_is_seeded_and_resumes_from_its_state():
    a = run(_search(5), _bowl, 300)
    b = run(_search(5), _bowl, 300)
    assert a.best_law.q == b.best_law.q
    c = run(_search(5), _bowl, 120)
    state = json.loads(json.dumps(c.state()))
    d = run(_search(99).load_state(state), _bowl, 300)
    assert d.evaluations == a.evaluations
    assert d.best_law.q == a.best_law.q and np.array_equal(d.best_f, a.best_f)
    assert run(_search(6), _bowl, 300).best_law.q != a.best_law.q


def test_cma_restarts_with_a_larger_population():
    # IPOP: once the step size has collapsed the search restarts with twice the population
    law = NetworkOperator.linear([[1.0]], bounds=[(-1, 1)])
    s = PolicySearch(law, Target(0), seed=1, sigma=0.3, restart_sigma=1e-2)
    p0 = s.popsize
    run(s, lambda laws: np.array([[(lw.q[0] - 0.1) ** 2 + (lw.q[1] + 0.3) ** 2] for lw in laws]),
        400)
    assert s.restarts >= 1 and s.popsize == p0 * 2 ** s.restarts


def test_cma_restart_steps_relative_to_the_restart_point():
    # a restart's step is relative to the point it restarts from (scale max(|x|, floor), the
    # definition in CMA): parameters that grew a thousandfold keep steps of their own size.
    # Oracle: the bowl's minimum at (2000, -500), far from the start (1, 1).
    bowl = lambda xs: [float(((x[0] - 2000.0) / 1000) ** 2 + ((x[1] + 500.0) / 1000) ** 2)
                       for x in xs]  # noqa: E731
    c = CMA([1.0, 1.0], 0.3, seed=5)
    for _ in range(200):
        c.tell(bowl(c.ask()))
    assert c.best_x == pytest.approx([2000.0, -500.0], abs=1.0)
    c.restart()
    assert np.array_equal(c.scale, np.maximum(np.abs(c.best_x), 0.1))
    spread = np.std(np.array(c.ask()), axis=0) / np.abs(c.best_x)
    assert np.all((spread > 0.1) & (spread < 0.6))        # ~sigma0 = 0.3 of each coordinate
    fixed = CMA([1.0, 1.0], 0.3, seed=5, scale=[1.0, 2.0])   # a given scale stays as given
    fixed.tell(bowl(fixed.ask()))
    fixed.restart()
    assert np.array_equal(fixed.scale, [1.0, 2.0])


def test_cma_candidates_are_mapped_and_bounded():
    c = CMA([0.5, -0.5], 0.5, seed=2, bounds=(-1.0, 1.0), x_map=lambda x: np.round(x, 2))
    xs = c.ask()
    assert all(np.all(np.abs(x) <= 1.0) and np.array_equal(x, np.round(x, 2)) for x in xs)
    with pytest.raises(ValueError, match="finite values"):
        c.tell([math.nan] * len(xs))


def test_spawned_search_keeps_the_step_size_and_covariance_at_a_new_mean():
    # a warm start for a neighbouring structure: the parent's adaptation (sigma, covariance,
    # population) at the child's start point, with the child's own random stream
    parent = CMA([0.5, -0.5, 0.2], 0.3, seed=3)
    bowl = lambda xs: [float(np.sum((x - [0.1, 0.2, 0.3]) ** 2)) for x in xs]  # noqa: E731
    for _ in range(30):
        parent.tell(bowl(parent.ask()))
    child = parent.spawn([1.0, 1.0, 1.0], seed=9)
    assert child.sigma == parent.sigma and child.popsize == parent.popsize
    assert np.array_equal(child.es.C, parent.es.C)
    assert child.es.mean * child.scale == pytest.approx([1.0, 1.0, 1.0], rel=1e-12)
    assert child.best_x is None and child.restarts == 0
    again = parent.spawn([1.0, 1.0, 1.0], seed=9)          # seeded: the same candidates
    a, b = child.ask(), parent.ask()
    assert not np.allclose(a[0] - [1.0, 1.0, 1.0], b[0] - parent.es.mean * parent.scale)
    assert all(np.array_equal(x, y) for x, y in zip(again.ask(), a))


def test_cma_restart_bookkeeping_survives_a_checkpoint():
    # IPOP restarts live in CMA (one definition for the baselines and the GA): a search
    # restored from its state continues exactly as the uninterrupted one, restarts included
    f = lambda xs: [float((x[0] - 0.1) ** 2 + (x[1] + 0.3) ** 2) for x in xs]  # noqa: E731

    def run(c, n):
        for _ in range(n):
            c.tell(f(c.ask()))
        return c
    a = run(CMA([0.5, 0.5], 0.3, seed=4, restart_sigma=1e-2, restart_stall=20), 150)
    b = run(CMA([0.5, 0.5], 0.3, seed=4, restart_sigma=1e-2, restart_stall=20), 70)
    c = run(CMA([0.0, 0.0], 0.3, seed=1).load_state(b.state()), 80)
    assert a.restarts >= 1 and c.restarts == a.restarts and c.popsize == a.popsize
    assert c.best_x == a.best_x and c.best_key == a.best_key


def test_cma_stall_gain_restarts_a_creeping_search():
    # stall_gain (the definition in CMA.tell): a generation ends the stall count only if its
    # best beats the best at the count's last end by more than that share.  A search whose
    # best creeps by 1e-9 (relative 1e-10) every generation: with stall_gain 1e-4 its IPOP
    # restart (restart_stall 60) fires at exactly the 61st generation (the first ends the
    # count: it beats no value at all, then 60 stall); with 0 (every better value ends the
    # count) it never fires
    def creep(c, gens, gain):
        for g in range(gens):
            c.tell([10.0 - 1e-9 * g] * len(c.ask()), stall_gain=gain)
        return c
    c = creep(CMA([0.5, 0.5], 0.3, seed=4, restart_stall=60), 60, 1e-4)
    assert c.restarts == 0 and c.stall == 59
    assert creep(c, 1, 1e-4).restarts == 1 and c.stall == 0
    plain = creep(CMA([0.5, 0.5], 0.3, seed=4, restart_stall=60), 200, 0.0)
    assert plain.restarts == 0 and plain.stall == 0
    # a lower violation always ends the count, however small the value's gain
    v = CMA([0.5, 0.5], 0.3, seed=4, restart_stall=60)
    for g in range(100):
        v.tell([(1.0 - 1e-3 * g, 10.0)] * len(v.ask()), stall_gain=1e-4)
    assert v.restarts == 0 and v.stall == 0
    # the mark survives a checkpoint: a restored search restarts at the same generation
    a = creep(CMA([0.5, 0.5], 0.3, seed=4, restart_stall=60), 30, 1e-4)
    b = CMA([0.0, 0.0], 0.3, seed=1).load_state(a.state())
    for g in range(30, 61):
        b.tell([10.0 - 1e-9 * g] * len(b.ask()), stall_gain=1e-4)
    assert b.restarts == 1 and b.stall_mark == (0.0, 10.0)
    assert creep(a, 30, 1e-4).restarts == 0 and creep(a, 1, 1e-4).restarts == 1
