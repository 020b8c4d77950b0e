"""Forms by skeleton (``[refine] distinct = 'skeleton'``): a law's expression with its constants
abstracted, and the successive halving's new forms taken by it, so a twin of the best law in
another matrix takes no slot; the one-operation neighbourhood sweep of the tuned basic law
(``[refine] sweep``) that flies each new skeleton once (docs/methods/network_operator.md, "The
one-operation neighbourhood of the tuned basic law, and forms by skeleton")."""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.synthesis.methods.encoding import StructureCodec
from descent_fmus.synthesis.methods.form_search import form_skeleton
from descent_fmus.synthesis.methods.refinement import RefineConfig
from descent_fmus.synthesis.methods.settings import SettingError
from descent_fmus.synthesis.methods.variational_ga import _Member
from test_screen import BASIC, SSQRT, _ga

CODEC = StructureCodec(24, 5)
#: variations of BASIC (u = q1 x1 + q2 x2 + q3 at node 7, identities to node 23) that leave
#: its form: x1 added into the sum (x1 + q1 x1 = (1 + q1) x1), the arc q1 x1 -> sum negated,
#: sin(q3) added further down (a constant), the chain's node 9 turned into a product (of one
#: term: the same value), or an atan2 (of one term: the same value too)
TWINS = {"x1 into the sum": (2, 0, 7, 1), "a negated arc": (0, 5, 7, 3),
         "sin of a constant": (2, 4, 9, 12), "a one-term product": (1, 0, 9, 2),
         "a one-term atan2": (1, 0, 9, 9)}
#: variations that make another form: x1's product through ssqrt; sgn of x2's product added to
#: the chain; the sum made a product
NEW = {"ssqrt": (SSQRT, "+[c,u4(c*x0),x1]"),
       "sgn": ((2, 6, 8, 10), "+[c,u10(c*x1),x0,x1]"), "product": ((1, 0, 7, 2), "c**[x0,x1]"),
       "ssqrt of x1, scaled after": ((0, 0, 5, 4), "+[c,u4(x0),x1]")}


def _skeleton(variation) -> str:
    psi = CODEC.apply(BASIC.psi, [variation])
    return form_skeleton(psi, BASIC.nx, len(BASIC.q), BASIC.outputs)


def test_the_linear_laws_skeleton_and_its_twins():
    # hand count: u = q1 x1 + q2 x2 + q3 -> one constant, x1 and x2 (inputs x0, x1)
    assert form_skeleton(BASIC.psi, BASIC.nx, len(BASIC.q), BASIC.outputs) == "+[c,x0,x1]"
    for name, v in TWINS.items():
        psi = CODEC.apply(BASIC.psi, [v])
        assert not np.array_equal(psi, BASIC.psi), name        # another matrix ...
        assert _skeleton(v) == "+[c,x0,x1]", name              # ... the same form
    # the twins fly the basic law's function (the oracle: the law itself at 64 states) up to
    # the constants: x1 into the sum is the basic law with q1 + 1, the negated arc with -q1
    rng = np.random.default_rng(0)
    for x in rng.uniform(-2.0, 2.0, (64, 2)):
        twin = BASIC.with_structure(CODEC.apply(BASIC.psi, [TWINS["x1 into the sum"]]), BASIC.q)
        moved = BASIC.with_q([BASIC.q[0] + 1.0, *BASIC.q[1:]])
        assert twin.raw(x)[0] == pytest.approx(moved.raw(x)[0], abs=1e-12)
        neg = BASIC.with_structure(CODEC.apply(BASIC.psi, [TWINS["a negated arc"]]), BASIC.q)
        flipped = BASIC.with_q([-BASIC.q[0], *BASIC.q[1:]])
        assert neg.raw(x)[0] == pytest.approx(flipped.raw(x)[0], abs=1e-12)


def test_a_new_operation_on_a_path_from_an_input_is_a_new_skeleton():
    for name, (v, want) in NEW.items():
        assert _skeleton(v) == want, name
    assert len({_skeleton(v) for v, _ in NEW.values()} | {"+[c,x0,x1]"}) == 5


def _population(ga):
    """The best law (1.0), two twins of it (1.01, 1.02: by matrix the top new forms), then
    the three new forms (1.4, 1.5, 3.0)."""
    bits = ga.params.encode(BASIC.q)
    rows = [([], 1.0), ([TWINS["x1 into the sum"]], 1.01), ([TWINS["a negated arc"]], 1.02),
            ([NEW["ssqrt"][0]], 1.4), ([NEW["sgn"][0]], 1.5), ([NEW["product"][0]], 3.0)]
    ga.pop = [_Member(v + [StructureCodec.IDENTITY] * (2 - len(v)), bits.copy(), np.array([f]))
              for v, f in rows]
    ga.lh = np.arange(len(rows))
    ga.refinement.searches = None


def test_the_halving_takes_new_skeletons_not_twins_of_the_best_law():
    ga = _ga(screen=0)
    ga.tell(np.ones((len(ga.ask()), 1)))                        # the initial population
    _population(ga)
    ga.refine_cfg = RefineConfig(basis=0, evals=40, forms=4, pick="best")
    assert ga._promising(4) == [0, 1, 2, 3]                    # by matrix: two twins
    ga.refine_cfg = RefineConfig(basis=0, evals=40, forms=4, pick="best", distinct="skeleton")
    assert ga._promising(4) == [0, 3, 4, 5]                    # by skeleton: three new forms
    assert ga.tuned_skeletons == {"+[c,x0,x1]"} | {NEW[k][1] for k in ("ssqrt", "sgn",
                                                                     "product")}
    # the next halving: every skeleton was tuned, so the best law alone (a twin of a tuned
    # form in yet another matrix takes no slot either)
    assert ga._promising(4) == [0]
    # the checkpoint keeps them: a resumed search picks the same
    st = ga.state()
    assert st["tuned_skeletons"] == sorted(ga.tuned_skeletons)
    again = _ga(screen=0).load_state(st)
    again.refine_cfg = ga.refine_cfg
    assert again._promising(4) == [0]


def test_distinct_is_checked():
    with pytest.raises(SettingError, match="refine.distinct"):
        RefineConfig(distinct="formula")


def _swept_ga(flights, **refine):
    """A GA on the toy objective of the screening tests with the sweep on (``refine``: more
    RefineConfig settings) and a flight budget (0: none), flown to the end of its basis
    search."""
    from test_screen import _toy
    from descent_fmus.synthesis.methods.ga_config import GAConfig
    from descent_fmus.synthesis.methods.encoding import GrayCodec
    from descent_fmus.synthesis.methods.pareto import Target
    from descent_fmus.synthesis.methods.variational_ga import VariationalGA
    ga = VariationalGA(GrayCodec(3, 11, 31, -1024.0, 1024.0), BASIC.q, np.random.default_rng(7),
                       GAConfig(population=16, crossovers=4, lchr=2, epoch=2),
                       StructureCodec(24, 5, (1, 4, 10), (1, 2)), BASIC.psi,
                       BASIC.with_structure, target=Target(0),
                       refine=RefineConfig(basis=16, evals=40, forms=4, sweep=8, **refine),
                       flights=flights)
    while ga.refinement.active or not ga.pop:     # the initial population, the basis
        ga.tell(_toy([c.law for c in ga.ask()]))
    return ga


def test_the_sweep_flies_each_one_operation_neighbour_once_per_skeleton():
    """The neighbourhood sweep (``[refine] sweep``) on the toy objective of the screening
    tests: the ssqrt form's closed-form best q1 is 16 x the inherited -20, the third pair of
    SCREEN_FACTORS."""
    from test_screen import Q1_STAR, _toy
    run = _swept_ga
    # an epoch is 2 generations x 4 crossovers x 4 children + the halving's 4 x 10 + 2 x 10
    # + 20 = 112 flights: a budget that leaves less after the sweep's 80 flies none of it
    ga = run(flights=200)           # (room for the basis search to stop at its budget)
    left = 200 - ga.evaluations - 80
    assert 0 < left < 112 and ga._pending is None and ga.stats["sweep_skipped"] == 80
    ga = run(flights=ga.evaluations + 80 + 112)            # just room: the sweep is due
    assert ga._pending[0] == "sweep"
    ga = run(flights=0)                                    # no budget counted: due
    # hand count, unary set (id, ssqrt, sgn): ssqrt and sgn on x1 -> q1 x1, on x2 -> q2 x2, on
    # q1 x1 -> sum, on q2 x2 -> sum and on the sum's first chain arc (the later chain arcs
    # and the constants' arcs give no new skeleton): 10 forms, 8 flights each, one batch
    members = ga._pending[1]
    assert len(members) == 10 * 8
    ga.tell(_toy([ga.candidate(m).law for m in members]))
    assert ga.stats["sweep"] == 80 and ga.stats["swept_forms"] == 10
    # the ssqrt form (toy value 0.5 + (q1 / Q1_STAR - 1)^2) joined the population at its
    # closed-form optimum q1 = 16 x -20 = Q1_STAR: the best law now, 0.5 (the basic form: 1)
    best = ga.pop[int(ga.target.order(ga.F, ga.CV)[0])]
    assert best.f[0] == pytest.approx(0.5, abs=1e-12)
    assert ga.params.decode(best.bits)[0] == pytest.approx(Q1_STAR, rel=1e-9)
    assert np.array_equal(ga.matrix(best), CODEC.apply(BASIC.psi, [SSQRT]))
    # off (sweep = 0): no sweep phase, the same search as before
    assert RefineConfig().sweep == 0


def test_sweep_products_adds_each_input_into_each_product_it_does_not_feed():
    """``[refine] sweep_products = 4``: after the unary sweep's 10 forms (the same 80 flights
    as without it), every input brought through each unary operation into a product node it
    does not feed. Hand count on BASIC (node 5 = q1 x1, node 6 = q2 x2; unary set id, ssqrt,
    sgn): x2 into node 5 and x1 into node 6, three operations each, 6 forms (q1 x1 f(x2), q2
    x2 f(x1): no two share a skeleton), 4 flights each."""
    plain = _swept_ga(0)._pending[1]
    ga = _swept_ga(0, sweep_products=4)
    members = ga._pending[1]
    assert len(members) == 80 + 6 * 4
    assert [m.variations for m in members[:80]] == [m.variations for m in plain]
    added = [m.variations[0] for m in members[80::4]]
    assert added == [(2, 1, 5, 1), (2, 1, 5, 4), (2, 1, 5, 10),
                     (2, 0, 6, 1), (2, 0, 6, 4), (2, 0, 6, 10)]
    # each is the basic law with one more factor in a product: q1 x1 x2 in place of q1 x1
    psi = CODEC.apply(BASIC.psi, [added[0]])
    assert form_skeleton(psi, BASIC.nx, len(BASIC.q), BASIC.outputs) == "+[*[x0,x1],c,x1]"
    assert ga._sweep_k[80:] == [12 + k // 4 for k in range(24)]      # (the 10 before: 2..11)
    # the gate: every one-operation form is offered, a product form only when its best
    # flight beats the tuned basic law (oracle: the toy values of the flights, grouped here)
    from test_screen import _toy
    F = _toy([ga.candidate(m).law for m in members])
    best = {}
    for k, f in zip(ga._sweep_k, F[:, 0]):
        best[k] = min(f, best.get(k, np.inf))
    basis = ga.pop[0].f[0]
    want = 10 + sum(best[k] < basis for k in range(12, 18))
    offered = []
    ga._insert = lambda m: offered.append(m)
    ga.tell(F)
    # (the toy gives every product form 3.0 at best, the basis 1.0: none of the six joins;
    # without the gate all 16 forms would)
    assert len(offered) == want == ga.stats["swept_forms"] == 10
    with pytest.raises(SettingError, match="refine.sweep_products"):
        RefineConfig(sweep_products=13)


def test_sweep_coupling_brings_an_output_into_the_products_of_a_later_one():
    """``[refine] sweep_coupling = 4`` on a two-output linear law (hand count of
    NetworkOperator.linear's layout, 24 nodes: inputs 0-1, constants 2-7, output 1's products
    8 and 9, its sum 10 and chain 11-15, output 2's products 16 and 17, its sum 18 and chain
    19-23): output 1's node 15 through each unary operation (id, ssqrt, sgn) into output 2's
    products 16 and 17, 6 forms of 4 flights each, after the one-operation sweep's flights
    (the same as without the setting); a one-output law has none."""
    from descent_fmus.synthesis.methods.encoding import GrayCodec
    from descent_fmus.synthesis.methods.ga_config import GAConfig
    from descent_fmus.synthesis.methods.law import NetworkOperator
    from descent_fmus.synthesis.methods.pareto import Target
    from descent_fmus.synthesis.methods.variational_ga import VariationalGA
    law = NetworkOperator.linear([[-0.5, 0.0], [0.0, -1.0]], [0.0, 0.0],
                                 bounds=[(-1.0, 1.0), (-3.0, 3.0)], size=24)
    assert list(law.outputs) == [16, 24]

    def swept(**refine):
        ga = VariationalGA(GrayCodec(6, 11, 31, -1024.0, 1024.0), law.q,
                           np.random.default_rng(7), GAConfig(population=16, crossovers=4,
                                                              lchr=2, epoch=2),
                           StructureCodec(24, 8, (1, 4, 10), (1, 2)), law.psi,
                           law.with_structure, target=Target(0),
                           refine=RefineConfig(basis=16, evals=40, forms=4, sweep=8, **refine),
                           flights=0)
        while ga.refinement.active or not ga.pop:
            cands = ga.ask()      # any objective of the laws: the sum of their squared q
            ga.tell(np.array([[float(np.sum(np.square(c.law.q)))] for c in cands]))
        return ga._pending[1]

    plain, coupled = swept(), swept(sweep_coupling=4)
    n = len(plain)
    assert len(coupled) == n + 6 * 4
    assert [m.variations for m in coupled[:n]] == [m.variations for m in plain]
    assert [m.variations[0] for m in coupled[n::4]] == [
        (2, 15, 16, 1), (2, 15, 16, 4), (2, 15, 16, 10),
        (2, 15, 17, 1), (2, 15, 17, 4), (2, 15, 17, 10)]
    # the first: output 2's term q x0 times output 1's value (x0 and x1 are inputs 0 and 1)
    psi = StructureCodec(24, 8).apply(law.psi, [(2, 15, 16, 1)])
    assert form_skeleton(psi, 2, 6, law.outputs).split("; ")[1] == \
        "+[*[+[c,x0,x1],x0],c,x1]"
    one = [m.variations for m in _swept_ga(0, sweep_coupling=4)._pending[1]]
    assert one == [m.variations for m in _swept_ga(0)._pending[1]]      # one output: none
    with pytest.raises(SettingError, match="refine.sweep_coupling"):
        RefineConfig(sweep_coupling=13)


def test_sweep_keep_lets_only_the_best_swept_forms_join():
    """``[refine] sweep_keep = 2``: of the 10 swept forms of the test above, only the two
    whose best flight is lowest (the oracle: the toy values of the flights, grouped by form
    here) are offered to the population; the ssqrt form at its closed-form optimum among them."""
    from test_screen import _toy
    ga = _swept_ga(0, sweep_keep=2)
    members = ga._pending[1]
    forms = list(ga._sweep_k)
    F = _toy([ga.candidate(m).law for m in members])
    values = F[:, 0].copy()
    offered = []
    ga._insert = lambda m: offered.append(float(m.f[0]))
    ga.tell(F)
    best = {}
    for k, v in zip(forms, values):
        best[k] = min(v, best.get(k, np.inf))
    assert len(best) == 10
    assert sorted(offered) == sorted(best.values())[:2]
    assert min(offered) == pytest.approx(0.5, abs=1e-12)       # the ssqrt form's optimum
    assert ga.stats["swept_forms"] == 2
    with pytest.raises(SettingError, match="refine.sweep_keep"):
        RefineConfig(sweep_keep=-1)


def test_sweep_tune_starts_the_halving_on_the_swept_forms_at_once():
    """``[refine] sweep_tune = 1``: once the sweep's flights are told, the next batch is the
    halving's (no generation before it), whose first search starts from the best law -- the
    swept ssqrt form at its closed-form optimum (toy value 0.5, as in the sweep test above);
    a checkpoint taken between the sweep and the halving resumes to the same batch.  Off, the
    first generation's children come first (the halving waits for the first epoch)."""
    from test_screen import _toy
    for tune, phase in ((1, "refine"), (0, "children")):
        ga = _swept_ga(0, sweep_tune=tune)
        assert ga._pending[0] == "sweep"
        ga.tell(_toy([ga.candidate(m).law for m in ga._pending[1]]))
        st = ga.state()
        batch = [c.law.q for c in ga.ask()]
        assert ga._pending[0] == phase and ga.generation == 0
        if tune:
            first = ga.refinement.searches[0]
            assert first.best_f[0] == pytest.approx(0.5, abs=1e-12)
            assert first.member == int(ga.target.order(ga.F, ga.CV)[0])
            assert 2 <= len(ga.refinement.searches) <= 4      # and other forms (forms = 4)
            again = _swept_ga(0, sweep_tune=tune).load_state(st)
            assert [c.law.q for c in again.ask()] == batch
    with pytest.raises(SettingError, match="refine.sweep_tune"):
        RefineConfig(sweep_tune=2)


def _fly_phases(ga, evaluations: int) -> list:
    """Fly ``ga`` on the toy objective for ``evaluations`` more flights; the phases flown."""
    from test_screen import _toy
    phases, end = [], ga.evaluations + evaluations
    while ga.evaluations < end:
        members = ga.ask()
        phases.append(ga._pending[0])
        ga.tell(_toy([c.law for c in members]))
    return phases


def test_resweep_sweeps_the_stalled_best_laws_neighbourhood_once_then_restarts():
    """``[refine] resweep = 1``: after the first sweep the toy's ssqrt form sits at its
    closed-form optimum (0.5), so the search stalls (ga restart_epochs = 2 epochs without a
    10 % gain).  At that stall the best law becomes the basis and its neighbourhood is swept
    (flown right after the epoch's population) instead of an island; at the next stall of the
    same best form the search restarts as without the setting (an island)."""
    from test_screen import _toy
    ga = _swept_ga(0, resweep=1)
    ga.tell(_toy([ga.candidate(m).law for m in ga._pending[1]]))    # the first sweep
    phases = _fly_phases(ga, 4000)
    k = phases.index("sweep")                       # the resweep: right after an epoch
    assert phases[k - 1] == "epoch" and ga.stats["resweeps"] == 1
    # its centre: the best law's form (the ssqrt form), which was the epoch's new basis
    assert ga.stats["sweep_centres"] == [NEW["ssqrt"][1]]
    assert phases.count("sweep") == 1               # one sweep per form, resweep = 1
    assert ga.stats.get("islands", 0) >= 1          # the next stall: an island
    # a checkpoint after the resweep resumes to the same future (the centres in its stats)
    while not ga.at_boundary():
        ga.tell(_toy([c.law for c in ga.ask()]))
    st = ga.state()
    again = _swept_ga(0, resweep=1).load_state(st)
    assert again.stats["sweep_centres"] == ga.stats["sweep_centres"]
    assert _fly_phases(again, 600) == _fly_phases(ga, 600)
    assert np.array_equal(again.F, ga.F)
    for key in ("resweeps", "sweep_centres", "islands", "swept_forms"):
        assert again.stats.get(key) == ga.stats.get(key), key
    # without the setting the first stall makes the island: the same run, no second sweep
    off = _swept_ga(0)
    off.tell(_toy([off.candidate(m).law for m in off._pending[1]]))
    phases_off = _fly_phases(off, 4000)
    assert "sweep" not in phases_off and "resweeps" not in off.stats
    assert off.stats.get("islands", 0) >= 1
    with pytest.raises(SettingError, match="refine.resweep"):
        RefineConfig(resweep=-1)
