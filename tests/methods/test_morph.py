"""Function-preserving starts of new forms (``ga.morph``): a child of another form than its
parent takes, before it is flown, the constants that make its law match its parent's at probe
points (docs/methods/network_operator.md, "Function-preserving starts")."""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.synthesis.methods.encoding import GrayCodec, StructureCodec
from descent_fmus.synthesis.methods.form_search import preserving_constants
from descent_fmus.synthesis.methods.ga_config import GAConfig
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.structures import probe_inputs
from descent_fmus.synthesis.methods.variational_ga import VariationalGA, _Member

BASIC = NetworkOperator.linear([[-0.5, -0.3]], [0.0], bounds=[(-10.0, 10.0)], size=24)


def _with(psi_entries, law=BASIC):
    psi = law.psi.copy()
    for (i, j), op in psi_entries.items():
        psi[i, j] = op
    return law.with_structure(psi, list(law.q))


def test_a_change_that_can_be_undone_is_undone():
    # x1's product arc through z^3 (rho14): (q1 x1)^3 matches q1 x1 only near |q1 x1| = 1; an
    # identity arc put on as z (rho1) is the parent itself: the fit keeps q1 (closed form)
    same = _with({(5, 7): 1})
    q = preserving_constants(BASIC, same, [0], probe_inputs(BASIC, 16))
    assert q == pytest.approx(BASIC.q, abs=1e-9)
    # -z (rho3) on the arc: the closed-form answer is q1 -> -q1 (u unchanged everywhere)
    neg = _with({(5, 7): 3})
    q = preserving_constants(BASIC, neg, [0], probe_inputs(BASIC, 16))
    assert q[0] == pytest.approx(0.5, abs=1e-6) and q[1:] == BASIC.q[1:]
    pts = probe_inputs(BASIC, 32, seed=3)
    assert np.max(np.abs(np.array(neg.with_q(q).raw_points(pts)) -
                         np.array(BASIC.raw_points(pts)))) < 1e-6


def _ga(morph: int):
    codec = GrayCodec(3, 11, 31, -1024.0, 1024.0)
    return VariationalGA(codec, BASIC.q, np.random.default_rng(7),
                         GAConfig(population=16, crossovers=8, lchr=2, morph=morph,
                                  basis_rule="compromise"),
                         StructureCodec(24, 5, (1, 3, 4, 10), (1, 2)), BASIC.psi,
                         BASIC.with_structure)


def test_morph_off_draws_the_same_children_and_on_morphs_a_new_form():
    runs = {}
    for morph in (0, 16):
        ga = _ga(morph)
        ga.tell(np.arange(16.0)[:, None])                     # the initial population
        kids = ga._children()
        runs[morph] = [k.variations for k in kids]
        # a child of the basic member with -z (rho3) put on x1's product arc: q1 flips sign
        parent = ga.pop[0]
        child = _Member([(0, 5, 7, 3), StructureCodec.IDENTITY], parent.bits.copy())
        ga._morph(child, parent)
        q1 = ga.params.decode(child.bits)[0]
        assert q1 == (pytest.approx(0.5, abs=ga.params.step) if morph else -0.5)
    # the same random numbers either way: the same forms are drawn
    assert runs[0] == runs[16]


def test_morph_is_a_validated_setting():
    with pytest.raises(ValueError, match="morph"):
        GAConfig(morph=-1)
