"""The genetic-programming baseline (``--method gp``): trees compiled into network-operator laws,
seeded and checkpointable search, settings.

Oracles: DEAP's own evaluation of a tree (``gp.compile`` of the primitive set, whose functions
are the network operator's operation table) for the compiled law; node counts worked by hand
from the compilation rules of :mod:`synthesis.methods.gp_trees`; an uninterrupted run for a
resumed one; a second run of the same seed.
"""
from __future__ import annotations

import json
import math
import random

import numpy as np
import pytest
from deap import gp

from descent_fmus.models.controllers.network_operator import L_MAX
from descent_fmus.models.controllers.operation_table import BINARY, UNARY, UNIT, finite
from descent_fmus.synthesis.methods.gp import GeneticProgramming
from descent_fmus.synthesis.methods.gp_config import GPConfig
from descent_fmus.synthesis.methods.gp_trees import (_subtree_ends, compile_trees, law_size,
                                                     primitive_set, tree_from_tokens, tree_key,
                                                     tree_to_tokens, tree_value)
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.law_fmu import CapacityError
from descent_fmus.synthesis.methods.pareto import Target
from descent_fmus.synthesis.methods.settings import SettingError

ALL_UNARY, ALL_BINARY = list(range(1, len(UNARY))), list(range(1, len(BINARY)))


def _template(nx=3, nu=2):
    return NetworkOperator.linear([[0.0] * nx] * nu, bounds=[(-5.0, 5.0)] * nu)


def _tree(text, pset):
    return gp.PrimitiveTree.from_string(text, pset)


def test_compiled_trees_evaluate_as_deap_evaluates_them():
    # 200 random two-output individuals over every operation of the table (depth 1..3, random
    # constants), 5 random inputs each: the law's outputs equal DEAP's evaluation of the trees
    # exactly (same functions, same order of operations); the law fits the controller
    pset = primitive_set(3, ALL_UNARY, ALL_BINARY, 2.0)
    template = _template()
    rng = random.Random(7)
    random.seed(7)
    checked = 0
    while checked < 200:
        trees = [gp.PrimitiveTree(gp.genHalfAndHalf(pset, 1, 3)) for _ in range(2)]
        try:
            law = compile_trees(trees, pset, template)
        except CapacityError:
            continue
        assert law.size <= L_MAX and (law.size, len(law.q)) == law_size(3, trees, pset)
        for _ in range(5):
            x = [rng.uniform(-3.0, 3.0) for _ in range(3)]
            assert law.raw(x) == [tree_value(t, pset, x) for t in trees], [str(t) for t in trees]
        checked += 1


def test_a_binary_node_is_its_operation_from_the_unit_element():
    # chi(a, b) = finite(chi(finite(chi(unit, a)), b)): the node's evaluation rule, by hand
    pset = primitive_set(2, ALL_UNARY, ALL_BINARY, 1.0)
    a, b = 0.3, -1.7
    for k in ALL_BINARY:
        want = finite(BINARY[k](finite(BINARY[k](UNIT[k], a)), b))
        name = next(n for n, op in pset.law_ops.items()
                    if op == k and pset.mapping[n].arity == 2)
        assert pset.context[name](a, b) == want


def test_compilation_shares_nodes_and_keeps_the_order_of_arcs():
    pset = primitive_set(2, ALL_UNARY, [1, 2], 1.0)
    t = _template(2, 1)
    # add(x1, x1): the second operand is the first's node -> an identity copy node, then the
    # sum: 2 inputs + 2 nodes
    law = compile_trees([_tree("add(x1, x1)", pset)], pset, t)
    assert law.size == 4 and law.raw([0.25, 0.0]) == [0.5]
    # add(mul(x1, x2), x2): x2 (node 2) precedes the product (node 3) -> copied: 5 nodes
    law = compile_trees([_tree("add(mul(x1, x2), x2)", pset)], pset, t)
    assert law.size == 5 and law.raw([2.0, 3.0]) == [9.0]
    # a binary operation that does not commute: atan2(x1 x2, x1) -- x1 precedes the product, so
    # it is copied after it and the arcs enter in the tree's order (oracle: math.atan2)
    geo = primitive_set(2, [1], [2, 9], 1.0)
    law = compile_trees([_tree("atan2(mul(x1, x2), x1)", geo)], geo, t)
    assert law.size == 5 and law.raw([-0.5, 3.0]) == [math.atan2(-1.5, -0.5)]
    # sin(cos(x1)) at the root: cos an arc into a node of its own, sin an arc into the output
    law = compile_trees([_tree("sin(cos(x1))", pset)], pset, t)
    assert law.size == 4 and law.raw([0.5, 0.0]) == pytest.approx([np.sin(np.cos(0.5))],
                                                                  abs=1e-15)
    # a shared sub-tree and a shared constant: one node, one parameter, across two outputs
    trees = [tree_from_tokens(["add", "mul", "x1", 0.5, "x2"], pset),
             tree_from_tokens(["sin", "mul", "x1", 0.5], pset)]
    assert [tree_to_tokens(tr) for tr in trees] == [["add", "mul", "x1", 0.5, "x2"],
                                                    ["sin", "mul", "x1", 0.5]]
    law = compile_trees(trees, pset, _template(2, 2))
    # 2 inputs, 1 parameter; mul; the copy of x2 (it precedes mul), add; sin's output node
    assert len(law.q) == 1 and law.size == 2 + 1 + 1 + 2 + 1
    assert law.raw([0.6, 1.0]) == pytest.approx([1.3, np.sin(0.3)], abs=1e-15)


def test_tree_keys_and_subtree_ends_are_deaps_strings_and_searches():
    """The compiler's sub-tree key and ends (one pass each) against DEAP's own ``str`` and
    ``searchSubtree`` on random trees of every depth up to 9, with crossovers of a tree with
    a copy of itself (shared sub-trees, equal trees): the key is equal exactly when the
    strings are, so the compiled laws share the same nodes as with ``str`` keys."""
    pset = primitive_set(2, ALL_UNARY, ALL_BINARY, 1.0)
    rng_state = random.getstate()
    random.seed(5)
    try:
        pairs = equal = 0
        for _ in range(400):
            a = gp.PrimitiveTree(gp.genHalfAndHalf(pset, 1, random.randint(1, 9)))
            b, c = gp.cxOnePoint(gp.PrimitiveTree(list(a)), gp.PrimitiveTree(list(a)))
            for t in (a, b, c):
                assert _subtree_ends(t) == [t.searchSubtree(i).stop for i in range(len(t))]
                for i in range(len(t)):
                    for u in (a, b, c):
                        j = random.randrange(len(u))
                        ki = tree_key(t[i:_subtree_ends(t)[i]])
                        kj = tree_key(u[j:_subtree_ends(u)[j]])
                        si = str(gp.PrimitiveTree(t[i:t.searchSubtree(i).stop]))
                        sj = str(gp.PrimitiveTree(u[j:u.searchSubtree(j).stop]))
                        assert (ki == kj) == (si == sj)
                        pairs, equal = pairs + 1, equal + (si == sj)
    finally:
        random.setstate(rng_state)
    assert equal > 1000 and pairs - equal > 1000          # both cases met, many times


def test_a_law_beyond_the_controller_is_a_capacity_error():
    pset = primitive_set(2, [1, 3], [1], 1.0)
    deep = "x1"
    for _ in range(L_MAX):
        deep = f"neg(neg({deep}))"
    with pytest.raises(CapacityError, match="controller FMU holds 32"):
        compile_trees([_tree(deep, pset)], pset, _template(2, 1))


# -- the search ---------------------------------------------------------------------------------
_POINTS = np.random.default_rng(0).uniform(-1.0, 1.0, (16, 2))


def _fitness(laws):
    """Mean squared error to (sin(x1) x2, x1^2 + 0.5): a known symbolic-regression target."""
    want = np.stack([np.sin(_POINTS[:, 0]) * _POINTS[:, 1], _POINTS[:, 0] ** 2 + 0.5], 1)
    return [[float(np.mean((np.array([law(x) for x in _POINTS]) - want) ** 2))]
            for law in laws]


def _search(seed=1):
    return GeneticProgramming(_template(2, 2), Target(0), GPConfig(population=40),
                              ALL_UNARY, [1, 2, 3, 4], seed=seed)


def _run(m, generations):
    while m.generation < generations:
        m.tell(_fitness([c.law for c in m.ask()]))
    return m


def _trees(m):
    return [[str(t) for t in ind] for ind in m.population]


def test_the_law_cache_changes_nothing_but_the_compiles():
    """The same seed without the cache of compiled laws (oracle): the same trees, fitnesses and
    laws, generation for generation; with it, some individuals' laws came from the cache."""
    a = _run(_search(), 12)
    b = _search()
    b.law_cache = 0
    _run(b, 12)
    assert _trees(a) == _trees(b)
    assert [i.fitness.values for i in a.population] == [i.fitness.values for i in b.population]
    assert all(np.array_equal(i.law.psi, j.law.psi) and list(i.law.q) == list(j.law.q)
               for i, j in zip(a.population, b.population))
    assert a.cache_hits > 0 and b.cache_hits == 0 and len(b._laws) == 0


def test_a_seed_reproduces_the_search_and_a_resume_continues_it_exactly():
    a, b = _run(_search(), 8), _run(_search(), 8)
    assert _trees(a) == _trees(b) and a.best == b.best and a.evaluations == b.evaluations
    outer = random.getstate()
    c = _run(_search(), 3)
    assert random.getstate() == outer          # the search never moves the process's stream
    state = json.loads(json.dumps(c.state()))  # what a checkpoint keeps
    d = _run(_search(seed=99).load_state(state), 8)
    assert _trees(d) == _trees(a) and d.best == a.best and d.evaluations == a.evaluations
    assert _trees(_run(_search(seed=2), 8)) != _trees(a)
    # only changed individuals are flown: fewer than a population per generation after the first
    assert 40 < a.evaluations < 8 * 40
    assert a.best[1] < _fitness([NetworkOperator.linear([[0.0, 0.0]] * 2)])[0][0]


def test_offspring_beyond_the_depth_limit_keep_their_parents():
    m = GeneticProgramming(_template(2, 1), Target(0),
                           GPConfig(population=30, max_depth=3, init_depth=2,
                                    mutation_depth=2, p_mutation=1.0, p_crossover=1.0),
                           ALL_UNARY, [1, 2], seed=3)
    _run(m, 6)
    assert max(t.height for ind in m.population for t in ind) <= 3
    assert all(ind.law.size <= L_MAX for ind in m.population)


@pytest.mark.parametrize("changes, key", [({"population": 1}, "gp.population"),
                                          ({"tournament": 0}, "gp.tournament"),
                                          ({"p_crossover": 1.5}, "gp.p_crossover"),
                                          ({"init_depth": 5, "max_depth": 4}, "gp.init_depth"),
                                          ({"const_range": float("nan")}, "gp.const_range")])
def test_bad_settings_name_their_key(changes, key):
    with pytest.raises(SettingError, match=key.replace(".", r"\.")):
        GPConfig(**changes)


def test_bad_settings_on_the_command_line_and_in_a_file(hopper_dir, tmp_path, capsys):
    from descent_fmus.synthesis.cli.main import main
    from descent_fmus.synthesis.problems.files import ProblemFileError, load_problem_file
    with pytest.raises(SystemExit) as exc:
        main(["synthesize", "--problem", str(hopper_dir / "hopper.toml"), "--method", "gp",
              "--gp-population", "1", "--out", str(tmp_path / "run")])
    assert exc.value.code == 2 and "--gp-population: must be >= 2" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
    bad = hopper_dir / "hopper-bad-gp.toml"
    bad.write_text((hopper_dir / "hopper.toml").read_text() + "\n[gp]\ntournament = 0\n")
    with pytest.raises(ProblemFileError, match="gp.tournament"):
        load_problem_file(bad)
    good = hopper_dir / "hopper-gp.toml"
    good.write_text((hopper_dir / "hopper.toml").read_text() + "\n[gp]\npopulation = 12\n")
    assert load_problem_file(good).gp.population == 12


@pytest.mark.slow
def test_gp_flies_through_the_run_loop_reproducibly_and_resumes(hopper_dir, tmp_path):
    # the tutorial's hopper, 8 individuals, 16 flights: a second run of the same seed, stopped
    # after one generation and resumed from its checkpoint, gives the same Pareto set
    from descent_fmus.synthesis.problems.files import load_problem_file
    from descent_fmus.synthesis.run.loop import run_synthesis
    problem = load_problem_file(hopper_dir / "hopper.toml").tuned(flights=16, gp_population=8)
    kw = dict(method="gp", progress=False, export=False, reference=False)
    a = run_synthesis(problem, tmp_path / "a", hopper_dir, **kw)
    cut = run_synthesis(problem, tmp_path / "c", hopper_dir, stop_after=1, **kw)
    assert cut["interrupted"]
    c = run_synthesis(problem, tmp_path / "c", hopper_dir, resume=True, **kw)
    csv = (tmp_path / "a" / "pareto.csv").read_text()
    assert csv == (tmp_path / "c" / "pareto.csv").read_text()
    assert a["flights"] == c["flights"] >= 16
    rows = json.loads((tmp_path / "a" / "pareto.json").read_text())
    assert all(len(r["trees"]) == 1 for r in rows)     # one tree per output, reported


def test_gp_is_registered_for_every_problem_with_the_problems_operations():
    from descent_fmus.synthesis.methods.registry import make_method, method_names
    from descent_fmus.synthesis.registry import get_problem
    problem = get_problem("reentry").tuned(gp_population=6, seed=4)
    assert "gp" in method_names(problem)
    m = make_method("gp", problem)
    assert isinstance(m, GeneticProgramming) and m.config.population == 6
    ops = {a: sorted(k for n, k in m.pset.law_ops.items() if m.pset.mapping[n].arity == a)
           for a in (1, 2)}
    assert ops == {1: sorted(set(problem.unary) - {1}), 2: sorted(problem.binary)}
    laws = [c.law for c in m.ask()]
    assert len(laws) == 6 and all(law.nx == problem.basic().nx for law in laws)
    assert all(law.bounds == problem.basic().bounds for law in laws)
