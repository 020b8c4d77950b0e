"""Which new forms the structure search's successive halving tunes (``[refine] pick``):
docs/methods/network_operator.md, "The structure search"."""
from __future__ import annotations

import dataclasses

import pytest

from descent_fmus.synthesis.methods.refinement import RefineConfig
from descent_fmus.synthesis.methods.settings import SettingError
from test_search import _stall_ga, _stalled_objectives


def _eligible(ga) -> list:
    """Every member _promising may pick, in its order ('best' with no limit)."""
    ga.refine_cfg = RefineConfig(basis=0, evals=40, forms=4, pick="best")
    return ga._promising(10 ** 6)


def test_spread_picks_the_best_then_evenly_spaced_new_forms():
    ga, psi0 = _stall_ga(5, 10)
    ga.tell(_stalled_objectives(psi0)([c.law for c in ga.ask()]))        # initial population
    order = _eligible(ga)
    assert len(order) >= 7                  # enough distinct forms for the ranks to differ
    ga.refine_cfg = RefineConfig(basis=0, evals=40, forms=4, pick="best")
    assert ga._promising(4) == order[:4]    # the previous rule: the top four
    ga.refine_cfg = dataclasses.replace(ga.refine_cfg, pick="spread")
    picks = ga._promising(4)
    rest = order[1:]
    # hand count: the best, then ranks 0, len/3 and 2 len/3 (floored) of the others
    assert picks == [order[0], rest[0], rest[len(rest) // 3], rest[2 * len(rest) // 3]]
    assert len(set(picks)) == 4 and picks != order[:4]
    # fewer eligible forms than picks: every one, as 'best' gives them
    assert ga._promising(len(order) + 3) == order


def test_pick_is_checked():
    with pytest.raises(SettingError, match="refine.pick"):
        RefineConfig(pick="random")


def test_adaptive_spreads_only_after_the_tuned_new_forms_lost():
    ga, psi0 = _stall_ga(5, 10)
    ga.tell(_stalled_objectives(psi0)([c.law for c in ga.ask()]))        # initial population
    order = _eligible(ga)
    ga.refine_cfg = RefineConfig(basis=0, evals=40, forms=4, pick="adaptive")
    ga.stats.pop("new_form_picks", None)
    top = ga._promising(4)
    assert top == order[:4]                 # the first halving: the top new forms
    # it recorded the new forms it picked (not the best member)
    assert ga.stats["new_form_picks"] == [ga._structure_key(ga.pop[k]) for k in order[1:4]]
    # the best law now is one of them (a new form won): the top ones again
    ga.stats["new_form_picks"] = [ga._structure_key(ga.pop[order[0]])]
    assert ga._promising(4) == order[:4]
    # the best law is none of them (they lost): spread, as 'spread' picks
    ga.stats["new_form_picks"] = ["not a structure of the population"]
    spread = ga._promising(4)
    ga.refine_cfg = dataclasses.replace(ga.refine_cfg, pick="spread")
    assert spread == ga._promising(4) != order[:4]
    assert ga.stats["spread_epochs"] == 1
