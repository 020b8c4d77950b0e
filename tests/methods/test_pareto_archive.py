"""The run's Pareto archive: its array tests make the same decisions as the element-wise rule.

Oracle: :func:`weakly_dominates` and :func:`dominates` applied item by item (the archive's rule
before its tests were made on arrays), on random offers with ties, violations and NaN.
"""
from __future__ import annotations

import numpy as np

from descent_fmus.synthesis.methods.pareto import (ParetoArchive, best_compromise,
                                                   crowding_distance, dominates, weakly_dominates)


def _elementwise_add(items: list, cap: int, item, f, cv: float) -> tuple[bool, list]:
    f = np.asarray(f, float)
    if any(weakly_dominates(g, f, c, cv) for _, g, c in items):
        return False, items
    keep = [a for a in items if not dominates(f, a[1], cv, a[2])] + [(item, f, cv)]
    if len(keep) > cap:
        del keep[int(np.argmin(crowding_distance(np.array([g for _, g, _ in keep]))))]
    return True, keep


def test_archive_decisions_equal_the_elementwise_rule():
    rng = np.random.default_rng(1)
    for _ in range(5):
        archive, items = ParetoArchive(cap=20), []
        for i in range(1500):
            f = np.round(rng.random(2) * 10, 1)           # a coarse grid: many ties
            if rng.random() < 0.01:
                f[0] = np.nan
            cv = 0.0 if rng.random() < 0.8 else float(np.round(rng.random(), 1))
            entered, items = _elementwise_add(items, 20, i, f, cv)
            assert archive.add(i, f, cv) == entered
            assert [a[0] for a in archive.items] == [a[0] for a in items]


def test_archive_items_replaced_from_outside():
    # a resumed run sets the items of a new archive: the arrays follow the list
    archive = ParetoArchive()
    archive.add("a", [1.0, 1.0])
    archive.items = [("b", np.array([2.0, 0.5]), 0.0)]
    assert not archive.add("c", [3.0, 0.6])          # dominated by b, not by the gone a
    assert archive.add("d", [1.5, 0.7])
    assert [a[0] for a in archive.items] == ["b", "d"]


def test_a_batch_offered_at_once_is_offered_one_by_one():
    # oracle: add() of each offer in turn; batches with ties, violations, NaN (in objectives
    # and violations: a NaN breaks the dominance's transitivity), an archive with room for the
    # batch (the batch's own test) and one without (the cap removes undominated items)
    rng = np.random.default_rng(7)
    for cap, m in ((100_000, 2), (100_000, 3), (3, 2), (6, 3)):
        one, many = ParetoArchive(cap=cap), ParetoArchive(cap=cap)
        for b in range(300):
            n = int(rng.integers(1, 12))
            F = np.round(rng.random((n, m)) * 10, 1)
            cv = np.where(rng.random(n) < 0.8, 0.0, np.round(rng.random(n), 1))
            if b % 10 == 9:
                F[0, 1] = np.nan
            if b % 10 == 4:
                cv[-1] = np.nan
            items = [(b, k) for k in range(n)]
            for k in range(n):
                one.add(items[k], F[k], cv[k])
            many.add_many(items, F, cv)
            assert [a[0] for a in many.items] == [a[0] for a in one.items]
            assert all(np.array_equal(a[1], c[1], equal_nan=True)
                       and np.array_equal(a[2], c[2], equal_nan=True)
                       for a, c in zip(many.items, one.items))
        assert 1 < len(one) <= cap


def test_a_batch_with_a_nan_violation_is_offered_one_by_one():
    # oracle: add() in turn -- a law with a NaN violation removes the feasible a, which alone
    # weakly dominated the third offer: that offer enters (no transitivity through a NaN)
    one, many = ParetoArchive(), ParetoArchive()
    for archive in (one, many):
        archive.add("a", [1.0, 1.0], 0.0)
    F, cv = np.array([[0.0, 0.0], [2.0, 2.0]]), np.array([np.nan, 0.0])
    for k in range(2):
        one.add(k, F[k], cv[k])
    many.add_many([0, 1], F, cv)
    assert [a[0] for a in many.items] == [a[0] for a in one.items] == [0, 1]


def test_a_batch_past_the_cap_is_offered_one_by_one():
    # oracle: add() in turn -- with a cap of 3 the second offer pushes the archived (4, 5) out
    # by crowding, and the third offer, (4, 5) again, which it alone weakly dominated, enters
    start, F = [[6.0, 0.0], [3.0, 6.0], [4.0, 5.0]], np.array([[8.0, 3.0], [5.0, 1.0],
                                                                [4.0, 5.0]])
    one, many = ParetoArchive(cap=3), ParetoArchive(cap=3)
    for archive in (one, many):
        for i, f in enumerate(start):
            archive.add(("start", i), f)
    for k in range(3):
        one.add(k, F[k], 0.0)
    many.add_many([0, 1, 2], F, np.zeros(3))
    assert [a[0] for a in many.items] == [a[0] for a in one.items] \
        == [("start", 0), ("start", 1), 2]


def test_an_empty_batch_changes_nothing():
    # a generation whose laws were all answered without a flight offers no law (oracle: add()
    # never called); it raised on the reshape of an empty objective array
    archive = ParetoArchive(cap=3)
    archive.add("a", [1.0, 2.0])
    archive.add_many([], np.empty((0,)), np.empty((0,)))
    archive.add_many([], [], [])
    assert [a[0] for a in archive.items] == ["a"]
    empty = ParetoArchive(cap=3)
    empty.add_many([], [], [])
    assert empty.items == []


def test_best_compromise_is_the_front_member_nearest_the_utopia_point():
    # closed form: the front (lh == 0) spans [0, 10] x [0, 1]; scaled, the rows are (0, 1),
    # (1, 0), (0.4, 0.3) at distances 1, 1, 0.5 from the utopia point (0, 0); the dominated
    # row 3 lies nearer still (0.1, 0.1 scaled) and is not eligible
    F = np.array([[0.0, 1.0], [10.0, 0.0], [4.0, 0.3], [1.0, 0.1]])
    assert best_compromise(F, [0, 0, 0, 2]) == 2
    assert best_compromise(F, [0, 0, 0, 0]) == 3
    # one front member: itself, whatever its values (a zero span is scaled by 1)
    assert best_compromise(F, [1, 1, 0, 1]) == 2
