"""Screening new forms before the successive halving (``[refine] screen``): the constants a
variation touches, a line search on them with a closed-form answer, and every screening
flight counted in the budget (docs/methods/network_operator.md, "Screening new forms")."""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.synthesis.methods.encoding import GrayCodec, StructureCodec
from descent_fmus.synthesis.methods.form_search import SCREEN_FACTORS, touched_constants
from descent_fmus.synthesis.methods.ga_config import GAConfig
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.pareto import ParetoArchive, Target
from descent_fmus.synthesis.methods.refinement import RefineConfig
from descent_fmus.synthesis.methods.variational_ga import VariationalGA, _Member

#: u = q1 x1 + q2 x2 + q3 (NetworkOperator.linear): nodes x1 0, x2 1, q1 2, q2 3, q3 4;
#: q1 x1 at node 5, q2 x2 at node 6, their sum (with q3) at node 7, a chain of identities to 23
BASIC = NetworkOperator.linear([[-20.0, -3.0]], [0.0], bounds=[(-1.0, 1.0)], size=24)
#: the form of the search5 finding: x1's product arc through ssqrt (rho4), u = ssqrt(q1 x1) + ..
SSQRT = (0, 5, 7, 4)
#: the closed-form best q1 of that form on the toy objective below: 16 x the inherited -20
Q1_STAR = -320.0


def test_touched_constants_are_those_upstream_of_the_changed_entries():
    psi0 = BASIC.psi
    # a new unary operation on the arc 5 -> 7 reads node 5 = q1 x1: q1 (index 0) alone
    assert touched_constants(psi0, StructureCodec(24, 5).apply(psi0, [SSQRT]), 2, 3) == [0]
    # an arc added from node 6 (q2 x2) into node 8: q2 alone
    assert touched_constants(psi0, StructureCodec(24, 5).apply(psi0, [(2, 6, 8, 10)]), 2, 3) \
        == [1]
    # a new binary operation at node 7 (the sum): every constant upstream of it
    assert touched_constants(psi0, StructureCodec(24, 5).apply(psi0, [(1, 0, 7, 2)]), 2, 3) \
        == [0, 1, 2]
    # an arc from an input (x1 -> 9): no constant upstream of x1, so those upstream of node 9
    assert touched_constants(psi0, StructureCodec(24, 5).apply(psi0, [(2, 0, 9, 4)]), 2, 3) \
        == [0, 1, 2]
    assert touched_constants(psi0, psi0, 2, 3) == []                    # no change


def _toy(laws) -> np.ndarray:
    """The toy objective (closed form): the basic form 1 (whatever its constants); the ssqrt
    form 0.5 + (q1 / Q1_STAR - 1)^2 (its best q1 is Q1_STAR, with its inherited q1 = -20 it
    is 1.4 -- worse than the basic form, as the switching form's first variation is on
    mintime-di); any other form 3."""
    ssqrt = StructureCodec(24, 5).apply(BASIC.psi, [SSQRT])
    out = []
    for law in laws:
        if np.array_equal(law.psi, BASIC.psi):
            out.append(1.0)
        elif np.array_equal(law.psi, ssqrt):
            out.append(0.5 + (law.q[0] / Q1_STAR - 1.0) ** 2)
        else:
            out.append(3.0)
    return np.array(out)[:, None]


def _ga(screen: int, flights: int = 0):
    codec = GrayCodec(3, 11, 31, -1024.0, 1024.0)          # mintime-di's code of q
    return VariationalGA(codec, BASIC.q, np.random.default_rng(7),
                         GAConfig(population=16, crossovers=4, lchr=2, epoch=2),
                         StructureCodec(24, 5, (1, 4, 10), (1, 2)), BASIC.psi,
                         BASIC.with_structure, target=Target(0),
                         refine=RefineConfig(basis=0, evals=40, forms=4, screen=screen),
                         flights=flights)


def _tell(ga):
    ga.tell(_toy([c.law for c in ga.ask()]))


def test_screening_finds_the_introduced_constants_closed_form_value():
    ga = _ga(screen=8)
    _tell(ga)                                                   # the initial population
    # a population of the basic law and one member with the ssqrt variation and the basic
    # law's constants (q1 = -20: 1.4, worse than the basic form's 1)
    ga.refinement.searches = None
    pop = [_Member([StructureCodec.IDENTITY] * 2, ga.params.encode(BASIC.q), np.array([1.0]))]
    pop.append(_Member([SSQRT, StructureCodec.IDENTITY], ga.params.encode(BASIC.q),
                       np.array([1.4])))
    pop += [_Member([(1, 0, 7 + k, 2), StructureCodec.IDENTITY], ga.params.encode(BASIC.q),
                    np.array([3.0 + k])) for k in range(1, 5)]  # four more forms, worse
    ga.pop, ga._pending, ga._refine_due = pop, None, True
    ga.lh = np.array([0, 1, 2, 3, 4, 5])
    cands = ga.ask()
    # 5 new forms screened, 8 flights each (the first 8 factors), one batch
    assert ga._pending[0] == "screen" and len(cands) == 5 * 8
    ssqrt = [c.law for c in cands if c.law.psi[5, 7] == 4]
    # q1 (the one touched) times each pair's first factor, kept in the code's range (-20 x 64
    # = -1280 is held at -1024), q2 and q3 times its second (q3 = 0 stays 0)
    assert [law.q[0] for law in ssqrt] == pytest.approx(
        [max(-1024.0, -20.0 * a) for a, _ in SCREEN_FACTORS[:8]])
    assert [law.q[1:] for law in ssqrt] == [pytest.approx([-3.0 * b, 0.0])
                                            for _, b in SCREEN_FACTORS[:8]]
    before = ga.evaluations
    ga.tell(_toy([c.law for c in cands]))
    assert ga.evaluations - before == 40 and ga.stats["screen"] == 40
    # the ssqrt member now holds q1 = -320 (factor 16): the toy's closed-form optimum, value
    # 0.5 exactly -- it ranks first, ahead of the basic form, for the halving to tune it
    assert ga.pop[1].f[0] == pytest.approx(0.5, abs=1e-12)
    assert ga.params.decode(ga.pop[1].bits)[0] == pytest.approx(Q1_STAR, abs=1e-6)
    assert ga.stats["screened_forms"] == 5
    # the halving starts at once, its first pick the screened form
    assert ga.refinement.active and ga.refinement.searches[0].member == 1


def test_every_screening_flight_is_counted_in_the_budget():
    from descent_fmus.synthesis.run.evaluation import Evaluation
    from descent_fmus.synthesis.run.loop import RunLoop
    cfg = RefineConfig(basis=0, evals=40, forms=4, screen=6, screen_evals=5)
    # a whole epoch's refinement: 6 x 5 screening + 4 x 10 + 2 x 10 + 1 x 20 (hand count)
    assert cfg.epoch_evals() == 30 + 80 and cfg.epoch_evals(4) == 80
    assert RefineConfig(basis=0, evals=40, forms=4).epoch_evals() == 80      # screen 0: off
    ga = _ga(screen=6, flights=900)
    ga.refine_cfg = cfg
    ga.refinement.cfg = cfg
    flown = []

    def evaluate(laws):
        flown.append(len(laws))
        F = _toy(laws)
        return Evaluation(F, np.zeros(len(F)), [{}] * len(F), len(F))
    loop = RunLoop(ga, evaluate, ParetoArchive(), flights=900).run()
    st = loop.method.stats
    assert st.get("screen", 0) > 0 and st["screened_forms"] > 0
    assert st["screen"] <= 5 * st["screened_forms"]              # at most 5 flights a form
    phases = sum(v for k, v in st.items() if k in ("init", "children", "epoch", "trim",
                                                   "refine", "screen", "rescale"))
    # every flight is in the GA's count, and the GA's count is the loop's
    assert phases == loop.method.evaluations == sum(flown)


def test_screen_off_is_the_previous_run_flight_for_flight():
    from descent_fmus.synthesis.run.evaluation import Evaluation
    from descent_fmus.synthesis.run.loop import RunLoop

    def run(ga):
        def evaluate(laws):
            F = _toy(laws)
            return Evaluation(F, np.zeros(len(F)), [{}] * len(F), len(F))
        return RunLoop(ga, evaluate, ParetoArchive(), flights=500).run().method
    a, b = run(_ga(screen=0, flights=500)), run(_ga(screen=0, flights=500))
    assert "screen" not in a.stats and np.array_equal(a.F, b.F)
    c = run(_ga(screen=4, flights=500))
    assert c.stats["screen"] > 0
