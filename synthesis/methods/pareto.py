"""Pareto utilities for minimisation problems: dominance counts, fronts, crowding, hypervolume."""
from __future__ import annotations

import numpy as np

__all__ = ["dominates", "dominance_counts", "non_dominated", "non_dominated_sort",
           "crowding_distance", "hypervolume_2d", "igd"]


def dominates(a, b) -> bool:
    """True if ``a`` Pareto-dominates ``b`` (all objectives <=, at least one <)."""
    a, b = np.asarray(a), np.asarray(b)
    return bool(np.all(a <= b) and np.any(a < b))


def dominance_counts(F) -> np.ndarray:
    """For each row of ``F`` (n x m): how many rows dominate it (the GA's ``Lh``)."""
    F = np.asarray(F, float)
    le = np.all(F[:, None, :] <= F[None, :, :], axis=2)   # le[i, j]: F_i <= F_j everywhere
    lt = np.any(F[:, None, :] < F[None, :, :], axis=2)
    dom = le & lt                                          # dom[i, j]: i dominates j
    return dom.sum(axis=0)


def non_dominated(F) -> np.ndarray:
    """Indices of the non-dominated rows of ``F``."""
    return np.flatnonzero(dominance_counts(F) == 0)


def non_dominated_sort(F) -> list[np.ndarray]:
    """Fronts (lists of row indices), best first (Deb's fast non-dominated sorting)."""
    F = np.asarray(F, float)
    n = len(F)
    le = np.all(F[:, None, :] <= F[None, :, :], axis=2)
    lt = np.any(F[:, None, :] < F[None, :, :], axis=2)
    dom = le & lt
    count = dom.sum(axis=0)
    fronts = []
    current = np.flatnonzero(count == 0)
    assigned = np.zeros(n, bool)
    while len(current):
        fronts.append(current)
        assigned[current] = True
        count = count - dom[current].sum(axis=0)
        current = np.flatnonzero((count == 0) & ~assigned)
    return fronts


def crowding_distance(F) -> np.ndarray:
    """NSGA-II crowding distance of each row (boundary points get +inf)."""
    F = np.asarray(F, float)
    n, m = F.shape
    d = np.zeros(n)
    if n <= 2:
        return np.full(n, np.inf)
    for k in range(m):
        order = np.argsort(F[:, k], kind="stable")
        span = F[order[-1], k] - F[order[0], k]
        d[order[0]] = d[order[-1]] = np.inf
        if span > 0:
            d[order[1:-1]] += (F[order[2:], k] - F[order[:-2], k]) / span
    return d


def hypervolume_2d(F, ref) -> float:
    """Exact hypervolume dominated by the points ``F`` (n x 2) and bounded by ``ref``."""
    F = np.asarray(F, float)
    ref = np.asarray(ref, float)
    F = F[np.all(F < ref, axis=1)]
    if not len(F):
        return 0.0
    F = F[non_dominated(F)]
    F = F[np.argsort(F[:, 0])]
    hv, prev_y = 0.0, ref[1]
    for x, y in F:
        if y < prev_y:
            hv += (ref[0] - x) * (prev_y - y)
            prev_y = y
    return float(hv)


def igd(F, reference_front) -> float:
    """Inverted generational distance of ``F`` to a sampled reference front."""
    F, R = np.asarray(F, float), np.asarray(reference_front, float)
    d = np.sqrt(((R[:, None, :] - F[None, :, :]) ** 2).sum(axis=2))
    return float(d.min(axis=1).mean())
