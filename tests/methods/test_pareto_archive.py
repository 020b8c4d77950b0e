"""The run's Pareto archive: its array tests make the same decisions as the element-wise rule.

Oracle: :func:`weakly_dominates` and :func:`dominates` applied item by item (the archive's rule
before its tests were made on arrays), on random offers with ties, violations and NaN.
"""
from __future__ import annotations

import numpy as np

from descent_fmus.synthesis.methods.pareto import (ParetoArchive, crowding_distance, dominates,
                                                   weakly_dominates)


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
