"""Ranking for minimisation problems with constraints: one dominance definition for the whole
package, the run archive, crowding, hypervolume, and the scalar target of CMA-ES.

**Constraint-domination** (Deb's rule, as in NSGA-II): each candidate has an objective vector
``f`` and a total constraint violation ``cv >= 0`` (0 = feasible).  ``a`` dominates ``b`` if

* ``a`` is feasible and ``b`` is not; or
* both are infeasible and ``cv_a < cv_b``; or
* both are feasible and ``f_a`` Pareto-dominates ``f_b`` (all objectives <=, at least one <).

Without constraints (every ``cv = 0``) it is plain Pareto dominance.  The variational GA, the
run archive and the CMA-ES target (:class:`Target`) all rank by it, so "feasible first, then
Pareto rank" means the same everywhere.

References
----------
K. Deb, "An efficient constraint handling method for genetic algorithms", CMAME 186 (2000);
K. Deb et al., "A fast and elitist multiobjective genetic algorithm: NSGA-II", IEEE TEC 6 (2002).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["dominates", "weakly_dominates", "dominance_matrix", "dominance_counts",
           "non_dominated", "non_dominated_sort", "best_compromise", "crowding_distance", "hypervolume_2d", "igd",
           "ParetoArchive", "Target"]


def _cv(cv, n: int) -> np.ndarray:
    return np.zeros(n) if cv is None else np.asarray(cv, float).reshape(n)


def dominates(a, b, cv_a: float = 0.0, cv_b: float = 0.0) -> bool:
    """True if ``a`` constraint-dominates ``b`` (see the module docstring)."""
    if cv_a > 0.0 or cv_b > 0.0:
        return cv_a < cv_b
    a, b = np.asarray(a), np.asarray(b)
    return bool(np.all(a <= b) and np.any(a < b))


def weakly_dominates(a, b, cv_a: float = 0.0, cv_b: float = 0.0) -> bool:
    """True if ``a`` is at least as good as ``b``: ``b`` adds nothing beside ``a`` (a smaller
    violation, or the same violation and objectives no worse)."""
    if cv_a != cv_b:
        return cv_a < cv_b
    return bool(np.all(np.asarray(a) <= np.asarray(b)))


def dominance_matrix(F, cv=None, G=None, cv_g=None) -> np.ndarray:
    """``D[i, j]``: row ``i`` of ``F`` constraint-dominates row ``j`` of ``G`` (default ``F``)."""
    F = np.atleast_2d(np.asarray(F, float))
    G = F if G is None else np.atleast_2d(np.asarray(G, float))
    cf = _cv(cv, len(F))
    cg = cf if G is F and cv_g is None else _cv(cv_g, len(G))
    le = np.all(F[:, None, :] <= G[None, :, :], axis=2)
    lt = np.any(F[:, None, :] < G[None, :, :], axis=2)
    pareto = le & lt
    if not (cf.any() or cg.any()):
        return pareto
    feas_f, feas_g = cf[:, None] == 0.0, cg[None, :] == 0.0
    return np.where(feas_f & feas_g, pareto, cf[:, None] < cg[None, :])


def dominance_counts(F, cv=None) -> np.ndarray:
    """For each row of ``F`` (n x m): how many rows constraint-dominate it (the GA's ``Lh``)."""
    return dominance_matrix(F, cv).sum(axis=0)


def non_dominated(F, cv=None) -> np.ndarray:
    """Indices of the non-dominated rows of ``F``."""
    return np.flatnonzero(dominance_counts(F, cv) == 0)


def best_compromise(F, lh) -> int:
    """The row of ``F`` among the non-dominated ones (``lh == 0``) nearest the utopia point,
    each objective scaled to the front's span (the lab's basis rule "compromise")."""
    idx = np.flatnonzero(np.asarray(lh) == 0)
    F = np.asarray(F)[idx]
    lo, hi = F.min(axis=0), F.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    return int(idx[np.argmin(np.sqrt((((F - lo) / span) ** 2).sum(axis=1)))])


def non_dominated_sort(F, cv=None) -> list[np.ndarray]:
    """Fronts (lists of row indices), best first (Deb's fast non-dominated sorting)."""
    dom = dominance_matrix(F, cv)
    n = len(dom)
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


class ParetoArchive:
    """The non-dominated candidates of a whole run (the result of every method).

    Items are ``(item, f, cv)``; a new item enters unless an archived one weakly
    constraint-dominates it, and removes the archived items it dominates, so the archive holds
    only feasible items once one is feasible.  Over ``cap`` items, the most crowded goes.
    """

    def __init__(self, cap: int = 200):
        self.items: list = []
        self.cap = int(cap)
        self._cache: tuple = (None, None, None)

    def __len__(self) -> int:
        return len(self.items)

    def _arrays(self) -> tuple:
        """The archived objective rows and violations as arrays (kept while :attr:`items` is
        the same list)."""
        if self._cache[0] is not self.items:
            self._cache = (self.items, np.array([g for _, g, _ in self.items], float),
                           np.array([c for _, _, c in self.items], float))
        return self._cache[1:]

    def add(self, item, f, cv: float = 0.0) -> bool:
        """Offer one candidate; True if it entered the archive.  The same tests as
        :func:`weakly_dominates` and :func:`dominates` against every archived item, made on
        arrays (one offer per law flown: element-wise they were 7 % of a search)."""
        f, cv = np.asarray(f, float).copy(), float(cv)
        keep = []
        if self.items:
            G, C = self._arrays()
            if _weakly_dominated(G, C, f[None, :], np.array([cv])).any():
                return False
            dom = np.where((cv > 0.0) | (C > 0.0), cv < C,
                           np.all(f <= G, axis=1) & np.any(f < G, axis=1))
            keep = [a for a, d in zip(self.items, dom.tolist()) if not d]
        keep.append((item, f, cv))
        if len(keep) > self.cap:
            del keep[int(np.argmin(crowding_distance(np.array([g for _, g, _ in keep]))))]
        self.items = keep
        return True

    def add_many(self, items, F, cv) -> None:
        """:meth:`add` of each item in turn (a batch of laws flown).  [choice] The offers an
        archived item already weakly dominates are dropped at once: weak constraint-dominance
        is transitive, so an item that leaves the archive during the batch leaves it for one
        that weakly dominates those offers too; only the cap removes an item that nothing
        dominates, so with room for the whole batch (and finite values: a NaN breaks the
        transitivity) the result is :meth:`add`'s, one by one."""
        if not len(items):
            return
        F = np.asarray(F, float).reshape(len(items), -1)
        cv = np.asarray(cv, float).reshape(len(items))
        offer = range(len(items))
        if self.items and len(self.items) + len(items) <= self.cap:
            G, C = self._arrays()
            if np.isfinite(G).all() and np.isfinite(C).all() and np.isfinite(F).all() \
                    and np.isfinite(cv).all():
                offer = np.flatnonzero(~_weakly_dominated(G, C, F, cv).any(axis=0)).tolist()
        for k in offer:
            self.add(items[k], F[k], cv[k])

    @property
    def F(self) -> np.ndarray:
        return np.array([f for _, f, _ in self.items])

    @property
    def cv(self) -> np.ndarray:
        return np.array([c for _, _, c in self.items])

    def sorted(self) -> list:
        """The items ``(item, f, cv)`` sorted by (violation, objective 1, objective 2, ...)."""
        return sorted(self.items, key=lambda a: (a[2],) + tuple(a[1]))


def _weakly_dominated(G, C, F, cv) -> np.ndarray:
    """``[i, k]``: archived row ``G[i]`` (violation ``C[i]``) weakly constraint-dominates the
    offer ``F[k]`` (violation ``cv[k]``) -- :func:`weakly_dominates` on arrays."""
    return np.where(C[:, None] == cv[None, :], np.all(G[:, None, :] <= F[None, :, :], axis=2),
                    C[:, None] < cv[None, :])


@dataclass(frozen=True)
class Target:
    """The single objective CMA-ES minimises: ``F[objective]`` subject to
    ``F[constraint] < limit`` (no constraint: ``constraint=None``), after the problem's own
    constraints (a candidate with a smaller total violation ``cv`` is always better).

    ``scalar(F) = F[objective] + weight * max(0, F[constraint] / limit - 1)``; ``feasible(F)``
    tells the rows that meet the target's constraint (what a report counts); :meth:`keys` give
    the order CMA-ES and the GA's refinement rank by.
    """

    objective: int = 0
    constraint: int | None = None
    limit: float = math.inf
    weight: float = 10.0

    def feasible(self, F, cv=None) -> np.ndarray:
        F = np.atleast_2d(np.asarray(F, float))
        ok = _cv(cv, len(F)) == 0.0
        if self.constraint is None:
            return ok
        return ok & (F[:, self.constraint] < self.limit)

    def scalar(self, F) -> np.ndarray:
        F = np.atleast_2d(np.asarray(F, float))
        s = F[:, self.objective].copy()
        if self.constraint is not None and math.isfinite(self.limit):
            excess = F[:, self.constraint] / self.limit - 1.0
            s += self.weight * np.maximum(excess, 0.0)
        return s

    def keys(self, F, cv=None) -> list:
        """Per row ``(violation, scalar)``: compare as tuples (smaller is better)."""
        F = np.atleast_2d(np.asarray(F, float))
        return list(zip(_cv(cv, len(F)).tolist(), self.scalar(F).tolist()))

    def order(self, F, cv=None) -> np.ndarray:
        """Row indices, best first: the problem's constraints first (smaller violation), then
        the rows that meet the target's constraint by their objective, then the others by the
        penalised scalar (a law just past the constraint with a lower objective is not the best
        law)."""
        F = np.atleast_2d(np.asarray(F, float))
        c = _cv(cv, len(F))
        ok = self.feasible(F, c)
        rank = np.where(ok, F[:, self.objective], self.scalar(F))
        return np.lexsort((rank, ~ok, c))

    def better(self, f, g, cv_f: float = 0.0, cv_g: float = 0.0) -> bool:
        """Is row ``f`` better than row ``g`` by :meth:`order`?"""
        if cv_f != cv_g:
            return cv_f < cv_g
        # :meth:`feasible` and :meth:`scalar` of one row, on floats (the same IEEE operations;
        # CMA-ES's refinement asks this of every law it flies)
        fs, gs = self._feasible_row(f), self._feasible_row(g)
        if fs != gs:
            return fs
        if fs:
            return bool(f[self.objective] < g[self.objective])
        return self._scalar_row(f) < self._scalar_row(g)

    def _feasible_row(self, f) -> bool:
        return self.constraint is None or float(f[self.constraint]) < self.limit

    def _scalar_row(self, f) -> float:
        s = float(f[self.objective])
        if self.constraint is not None and math.isfinite(self.limit):
            s += self.weight * max(float(f[self.constraint]) / self.limit - 1.0, 0.0)
        return s

    def best(self, F, cv=None) -> int | None:
        """Index of the best row that meets the constraints and the target's constraint (lowest
        objective), None if there is none."""
        F = np.atleast_2d(np.asarray(F, float))
        ok = np.flatnonzero(self.feasible(F, cv))
        return None if not len(ok) else int(ok[np.argmin(F[ok, self.objective])])
