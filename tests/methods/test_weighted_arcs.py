"""Weighted arcs (``ga.weighted_arcs``): an added arc i->j through rho whose input is scaled by
an unused constant of its own, which starts at 0, so the child starts as its parent
(docs/methods/network_operator.md, "Weighted arcs")."""
from __future__ import annotations

import json

import numpy as np
import pytest

from descent_fmus.synthesis.methods.encoding import GrayCodec, StructureCodec
from descent_fmus.synthesis.methods.ga_config import GAConfig
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.structures import probe_inputs
from descent_fmus.synthesis.methods.variational_ga import VariationalGA, _Member

NX, NQ, SIZE = 2, 3, 9           # inputs 0-1, constants 2-4 (q3 unused), nodes 5-8


def _basic() -> NetworkOperator:
    """u = q1 x1 + q2 x2 (node 5 = q1 x1, node 6 = q2 x2, node 7 free, node 8 = their sum)."""
    psi = np.zeros((SIZE, SIZE), int)
    psi[5, 5] = psi[6, 6] = 2                        # products
    psi[0, 5] = psi[2, 5] = psi[1, 6] = psi[3, 6] = 1
    psi[8, 8], psi[5, 8], psi[6, 8] = 1, 1, 1        # the sum (output 9: 1-based)
    return NetworkOperator(psi, NX, [-3.0, -2.5, 0.0], outputs=[9], bounds=[(-1.0, 1.0)])


BASIC = _basic()
CODEC = GrayCodec(NQ, 11, 31, -1024.0, 1024.0)     # mintime-di's code: 0 is on its grid
ARC = (4, 6, 8, 30)              # x2's product node through ssq into the sum


def _codec(weighted=0.5, n_params=NQ) -> StructureCodec:
    return StructureCodec(SIZE, NX + NQ, (1, 3, 10, 30, 11), (1, 2), weighted, n_params)


def _gap(a, b, pts) -> float:
    return float(np.max(np.abs(np.subtract(a.raw_points(pts), b.raw_points(pts)))))


def test_the_weighted_arc_is_the_switching_form_and_neutral_at_zero():
    psi = _codec().apply(BASIC.psi, [ARC])
    # oracle, by hand: node 7 = q3 * x2's product node, into the sum through ssq
    assert psi[7, 7] == 2 and psi[4, 7] == 1 and psi[6, 7] == 1 and psi[7, 8] == 30
    assert np.count_nonzero(psi != BASIC.psi) == 4
    pts = probe_inputs(BASIC, 64, seed=2)
    assert _gap(BASIC, BASIC.with_structure(psi, [-3.0, -2.5, 0.0]), pts) <= 1e-12
    # with q3 = 0.7: u = q1 x1 + q2 x2 + ssq(0.7 q2 x2) (closed form, relative 1e-12)
    x = np.asarray(pts, float)
    z = 0.7 * -2.5 * x[:, 1]
    want = -3.0 * x[:, 0] - 2.5 * x[:, 1] + z * np.abs(z)
    got = np.ravel(BASIC.with_structure(psi, [-3.0, -2.5, 0.7]).raw_points(pts))
    assert np.max(np.abs(got - want)) <= 1e-12 * np.max(np.abs(want))


def test_skipped_when_not_neutral_or_nothing_is_free():
    codec = _codec()
    # cos(0) = 1 is not the unit 0 of a sum; sgn into a product node: sgn(0) = 0, not 1
    assert np.array_equal(codec.apply(BASIC.psi, [(4, 6, 8, 11)]), BASIC.psi)
    assert np.array_equal(codec.apply(BASIC.psi, [(4, 0, 5, 10)]), BASIC.psi)
    # a second weighted arc finds neither a free node nor an unused constant
    once = codec.apply(BASIC.psi, [ARC])
    assert np.array_equal(codec.apply(BASIC.psi, [ARC, (4, 5, 8, 3)]), once)
    # no unused constant (q3 read as a bias into the sum): skipped
    full = BASIC.psi.copy()
    full[4, 8] = 1
    assert np.array_equal(codec.apply(full, [ARC]), full)


def test_off_draws_exactly_the_old_variations():
    a, b = np.random.default_rng(5), np.random.default_rng(5)
    plain = StructureCodec(SIZE, NX + NQ, (1, 3, 10, 30, 11), (1, 2))
    old = [plain.random(a) for _ in range(200)]
    assert old == [_codec(0.0).random(b) for _ in range(200)]
    rng = np.random.default_rng(6)
    kinds = [_codec(0.5).random(rng)[0] for _ in range(400)]
    assert 150 < kinds.count(4) < 250            # about half: binomial(400, 0.5), 5 sigma


def _ga(weighted, morph=0):
    return VariationalGA(CODEC, BASIC.q, np.random.default_rng(3),
                         GAConfig(population=8, crossovers=4, lchr=2, morph=morph,
                                  basis_rule="compromise", weighted_arcs=weighted),
                         StructureCodec(SIZE, NX + NQ, (1, 3, 30), (1, 2)), BASIC.psi,
                         BASIC.with_structure)


@pytest.mark.parametrize("morph", [0, 16])
def test_the_child_starts_as_its_parent(morph):
    ga = _ga(0.5, morph)
    ga.tell(np.arange(8.0)[:, None])
    parent = ga.pop[0]
    bits = CODEC.encode([-3.0, -2.5, 37.25])          # an inherited, non-neutral weight
    child = _Member([ARC, StructureCodec.IDENTITY], bits)
    ga._new_weights(child, parent)
    ga._morph(child, parent)
    assert CODEC.decode(child.bits)[2] == 0.0
    mom, kid = ga.candidate(parent).law, ga.candidate(child).law
    assert not np.array_equal(kid.psi, mom.psi)
    # oracle: the parent's law, at 64 probe states
    assert _gap(mom, kid, probe_inputs(BASIC, 64, seed=4)) <= 1e-12


def test_off_leaves_the_inherited_weight():
    ga = _ga(0.0)
    ga.tell(np.arange(8.0)[:, None])
    child = _Member([ARC, StructureCodec.IDENTITY], CODEC.encode([-3.0, -2.5, 37.25]))
    ga._new_weights(child, ga.pop[0])
    assert CODEC.decode(child.bits)[2] == pytest.approx(37.25, abs=1e-6)


def test_checkpoint_round_trips_the_weighted_arc():
    ga = _ga(0.5)
    ga.tell(np.arange(8.0)[:, None])
    ga.pop[3] = _Member([ARC, (1, 0, 8, 3)], CODEC.encode([-3.0, -2.5, 0.0]), np.array([3.0]))
    st = json.loads(json.dumps(ga.state()))
    back = _ga(0.5).load_state(st)
    assert back.pop[3].variations == ga.pop[3].variations
    assert np.array_equal(back.matrix(back.pop[3]), ga.matrix(ga.pop[3]))
    assert back.matrix(back.pop[3])[7, 8] == 30
    # the same future: the next children are drawn alike
    a, b = ga._children(), back._children()
    assert [m.variations for m in a] == [m.variations for m in b]
    assert all(np.array_equal(x.bits, y.bits) for x, y in zip(a, b))


# -- room for weighted arcs in a `[basic_law] gains` law (search12) -----------------------------
from descent_fmus.synthesis.methods.law import NetworkOperator as _NOP   # noqa: E402
from descent_fmus.synthesis.methods.structures import with_room          # noqa: E402

G2, G3 = [[-1.0, -1.5]], [[-0.5, 0.25, 0.0], [0.0, -1.0, -1.0]]


def test_without_room_the_gains_layout_is_the_documented_one():
    # oracle, by hand: inputs 0-1, constants 2-4 (q1 q2 b); node 5 = q1 x1, 6 = q2 x2,
    # 7 = 5 + 6 + b, 8 = id(7) (the chain), output 9 (1-based)
    want = np.zeros((9, 9), int)
    want[5, 5] = want[6, 6] = 2
    want[0, 5] = want[2, 5] = want[1, 6] = want[3, 6] = 1
    want[7, 7] = want[5, 7] = want[6, 7] = want[4, 7] = 1
    want[8, 8] = want[7, 8] = 1
    for law in (_NOP.linear(G2, [0.5], size=9),
                _NOP.linear(G2, [0.5], size=9, spare_constants=0, free_nodes=0)):
        assert np.array_equal(law.psi, want) and law.outputs == [9]
        assert law.q == [-1.0, -1.5, 0.5]


@pytest.mark.parametrize("gains,bias,size", [(G2, [0.0], 24), (G3, [0.1, -0.2], 32)])
def test_the_room_is_inert_and_costs_no_node(gains, bias, size):
    bounds = [(-1.0, 1.0)] * len(gains)
    plain = _NOP.linear(gains, bias, bounds=bounds, size=size)
    roomy = with_room(plain)
    nx, nu = len(gains[0]), len(gains)
    assert roomy.size == size and len(roomy.q) == len(plain.q) + nx
    assert roomy.q[len(plain.q):] == [0.0] * nx
    # the spare constants are read by nothing; 2 free nodes per output, no arcs in or out
    ns = nx + len(roomy.q)
    for c in range(len(plain.q), len(roomy.q)):
        assert not roomy.psi[nx + c, ns:].any()
    free = [k for k in range(ns, size) if not roomy.psi[:, k].any() and not roomy.psi[k].any()]
    assert len(free) == 2 * nu
    # oracle: the closed form u = clip(G x + b) at 64 probe states (1e-12)
    pts = np.asarray(probe_inputs(plain, 64, seed=7, spread=3.0))
    want = np.clip(pts @ np.array(gains).T + np.array(bias), -1.0, 1.0)
    for law in (plain, roomy):
        got = np.array([law(x) for x in pts])
        assert np.max(np.abs(got - want)) <= 1e-12
    # the readable formula and the law file are those of the law without room
    assert roomy.formula() == plain.formula()
    back = _NOP.from_dict(json.loads(json.dumps(roomy.to_dict())))
    assert np.array_equal(back.psi, roomy.psi) and back.q == roomy.q
    # idempotent; other laws (here: a bias fed twice, not the layout) are left as they are
    assert with_room(roomy) is roomy
    other = plain.psi.copy()
    other[nx + len(plain.q) - 1, size - 1] = 1
    odd = plain.with_structure(other, plain.q)
    assert with_room(odd) is odd


def test_a_weighted_arc_on_the_roomy_gains_law_applies_and_starts_neutral():
    roomy = with_room(_NOP.linear(G2, [0.0], bounds=[(-1.0, 1.0)], size=24))
    nx, nq = 2, len(roomy.q)                     # constants 2..6 (q4, q5 spare), free 9, 10
    codec = StructureCodec(roomy.size, nx + nq, (1, 3, 10, 30, 11), (1, 2), 0.5, nq)
    arc = (4, 8, 11, 30)                         # x2's product node through ssq into the sum
    psi = codec.apply(roomy.psi, [arc])
    assert np.count_nonzero(psi != roomy.psi) == 4 and psi[9, 11] == 30 and psi[5, 9] == 1
    pts = probe_inputs(roomy, 64, seed=2)
    assert _gap(roomy, roomy.with_structure(psi, roomy.q), pts) <= 1e-12
    # a second one takes the other free node and spare constant, a third finds none
    two = codec.apply(roomy.psi, [arc, (4, 7, 11, 4)])
    assert np.count_nonzero(two != psi) == 4 and two[6, 10] == 1
    assert np.array_equal(codec.apply(roomy.psi, [arc, (4, 7, 11, 4), (4, 8, 11, 10)]), two)
    # with q4 = 0.7: u = -x1 - 1.5 x2 + ssq(0.7 (-1.5 x2)) (closed form, relative 1e-12)
    x = np.asarray(pts, float)
    z = 0.7 * -1.5 * x[:, 1]
    want = -x[:, 0] - 1.5 * x[:, 1] + z * np.abs(z)
    got = np.ravel(roomy.with_structure(psi, [-1.0, -1.5, 0.0, 0.7, 0.0]).raw_points(pts))
    assert np.max(np.abs(got - want)) <= 1e-12 * np.max(np.abs(want))
    assert "ssq" in roomy.with_structure(psi, [-1.0, -1.5, 0.0, 0.7, 0.0]).formula()


def test_the_roomy_law_exports_like_any_law():
    from descent_fmus.models.controllers.network_operator import L_MAX, NQ_MAX
    from descent_fmus.synthesis.fmi.native.builders.ccode import law_c
    # parking's layout: 3 inputs, 2 outputs, 32 nodes -- the controller FMU's capacity
    roomy = with_room(_NOP.linear(G3, [0.1, -0.2], bounds=[(-1.0, 1.0)] * 2, size=32))
    assert roomy.size <= L_MAX and len(roomy.q) == 11 <= NQ_MAX
    sv = roomy.start_values()
    assert sv["nq"] == 11 and [sv[f"q[{k + 1}]"] for k in range(11)] == roomy.q
    nx, nq = 3, 11
    codec = StructureCodec(roomy.size, nx + nq, (1, 30), (1, 2), 0.5, nq)
    psi = codec.apply(roomy.psi, [(4, 15, 19, 30)])      # y's product of output 1 into its sum
    law = roomy.with_structure(psi, roomy.q)
    _, c = law_c(law)
    # the weighted arc's node (18, 1-based: k = q9 * y's product) is computed, the other
    # free node of output 1 (19) is not
    assert "z18 " in c and "z19 " not in c
