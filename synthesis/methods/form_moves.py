"""Moves of the structure search beside the lab's variational GA (a mixin of
:class:`~synthesis.methods.variational_ga.VariationalGA`): the lab's elite step (prefixes of
the variation lists of a few Pareto members, ``elite_trim``), the neighbourhood sweep of the
tuned basic law (``refine sweep``, ``sweep_products``, ``sweep_coupling``), where a random
structure variation lands (``ga arc_ops``) and how its kind and operation are drawn (``ga
credit``), and the polish of the best law at the end of the flight budget (``refine
polish``).  The last three are
settings, off by default; docs/benchmarks/suite.md (search15 to search21) records what each
did.
"""
from __future__ import annotations

import numpy as np

from descent_fmus.synthesis.methods.encoding import StructureCodec
from descent_fmus.synthesis.methods.form_algebra import upstream
from descent_fmus.synthesis.methods.pareto import dominance_counts

__all__ = ["CREDIT_DECAY", "FormMoves", "SWEEP_EPOCHS"]

#: [choice] the neighbourhood sweep (``refine sweep``) is flown only when the flights left
#: after it hold this many epochs of the structure search: its forms are tuned by the
#: halving after an epoch (docs/methods/network_operator.md, "The one-operation neighbourhood")
SWEEP_EPOCHS = 1

#: [choice] the credit of variation kinds and operations (``ga credit``) shrinks by this
#: factor each generation (a half-life of about 14 generations): what improved the population
#: lately, not at the start of the run
CREDIT_DECAY = 0.95


class FormMoves:
    """Mixed into the variational GA (and its :class:`FormSearch` mixin: ``_skeleton``,
    ``_scaled_rows``, ``_room``): uses its ``structure``, ``rng``, ``cfg``,
    ``refine_cfg``, ``refinement``, ``target``, ``pop``, ``F``, ``CV``, ``flights``,
    ``evaluations``, ``generation``, ``stats``, ``lh``, ``_lchr``, ``_pending_trim``,
    ``matrix`` and ``_structure_key``."""

    def _trim_candidates(self) -> list:
        """Prefixes of the variation lists of a few Pareto members (the lab's elite step)."""
        front = [k for k in np.flatnonzero(self.lh == 0) if k != 0]
        if not front or self.cfg.elite_trim <= 0:
            return []
        picks = self.rng.choice(front, size=min(self.cfg.elite_trim, len(front)), replace=False)
        out = []
        for k in picks:
            m = self.pop[int(k)]
            for n in range(self._lchr):
                out.append(((int(k), n), type(m)(list(m.variations[:n]) +
                                                 [StructureCodec.IDENTITY] * (self._lchr - n),
                                                 m.bits.copy())))
        return out

    def _finish_trim(self, evaluated) -> None:
        best = {}
        for ((k, n), _), m in zip(self._pending_trim, evaluated):
            if k in best:
                continue
            old = self.pop[k]
            if m.cv <= old.cv and np.all(m.f <= old.f):   # a shorter prefix, nothing worse
                best[k] = m
        for k, m in best.items():
            self.pop[k] = m
        if best:
            self.lh = dominance_counts(self.F, self.CV)
        self._pending_trim = []

    def _variation(self, m) -> tuple:
        """A random structure variation for member ``m`` (its kind and operation drawn by
        their credit with ``credit``); with ``arc_ops``, one that changes an arc's operation
        (kind 0) is put on one of ``m``'s arcs, drawn uniformly (both off: as drawn, as before
        the settings existed)."""
        v = self.structure.random(self.rng, self._credit_pick if self.cfg.credit else None)
        if self.cfg.arc_ops and v[0] == 0:
            psi = self.matrix(m)
            n = self.structure.n_sources
            i, j = np.nonzero(np.triu(psi[:, n:], 1 - n))
            if len(i):
                k = int(self.rng.integers(0, len(i)))
                v = (0, int(i[k]), int(j[k]) + n, v[3])
        return v

    def _credit_pick(self, table: str, n: int) -> int:
        """A random variation's kind or operation index below ``n`` (``ga credit``): with
        probability ``credit`` in proportion to the credit of ``table`` (:meth:`_credit`: the
        share of draws whose child changed and entered the population, Laplace-smoothed), else
        uniform."""
        tries, wins = self.stats.get("credit", {}).get(table, ([0.0] * n, [0.0] * n))
        if self.rng.random() >= self.cfg.credit:
            return int(self.rng.integers(0, n))
        rate = (np.asarray(wins) + 1.0) / (np.asarray(tries) + 2.0)
        return int(self.rng.choice(n, p=rate / rate.sum()))

    def _credit(self, fresh: tuple, accepted: bool) -> None:
        """A child with a fresh variation ``(kind, op, changed)`` was offered to the
        population: a try of its kind (every draw: one that changed nothing, as most arc
        changes and removals drawn at random do, wins nothing), and when it changed the law a
        try of its operation; each a win when the changed child entered."""
        kind, op, changed = fresh
        s = self.structure
        tables = self.stats.setdefault("credit", {})
        picks = [("kind", kind, 4)] if kind < 4 else []
        if changed:
            ops, table = (s.binary, "binary") if kind == 1 else (s.unary, "unary")
            picks.append((table, ops.index(op), len(ops)))
        for table, k, n in picks:
            tries, wins = tables.setdefault(table, ([0.0] * n, [0.0] * n))
            tries[k] += 1.0
            wins[k] += 1.0 if (accepted and changed) else 0.0

    def _decay_credit(self) -> None:
        """Each generation the credit counts shrink by :data:`CREDIT_DECAY`: recent
        generations weigh most."""
        for tries, wins in self.stats.get("credit", {}).values():
            for t in (tries, wins):
                t[:] = [c * CREDIT_DECAY for c in t]

    def _start_sweep(self) -> None:
        """The neighbourhood sweep of the tuned basic law (``refine sweep``), pending."""
        sweep = self._sweep_members()
        if sweep:
            self._pending = ("sweep", sweep)

    def _sweep_members(self) -> list:
        """The neighbourhood sweep's candidates (``sweep``), once, when the basic solution's
        search ends: every form one changed unary operation away from the tuned basic law
        (each arc of its matrix, each operation of the structure's set, in matrix order),
        then with ``sweep_products`` every form one added arc away that brings an input
        (through each operation) into a product node it does not feed, and with
        ``sweep_coupling`` one that brings another output's node into one
        (:meth:`_coupling_moves`); each taken once per skeleton (:func:`form_skeleton`: not
        the basic law's, nor another neighbour's) and flown with the basic law's constants
        scaled as the screening does (:meth:`_scaled_rows`: the first ``sweep``,
        ``sweep_products`` or ``sweep_coupling`` pairs).  Reads no random numbers; each candidate's form is kept for :meth:`_finish_sweep`.  None when
        the flights left after them would not hold ``SWEEP_EPOCHS`` epochs of the structure
        search: the swept forms are tuned by the halving after an epoch."""
        self._sweep_k = []
        n = self.refine_cfg.sweep
        if not n or self.structure is None or self.target is None or not self._lchr:
            return []
        basis = self.pop[0]
        psi = self.matrix(basis)
        seen, out = {self._skeleton(basis)}, []
        moves = [(0, int(i), int(j), int(op), n) for i, j in zip(*np.nonzero(np.triu(psi, 1)))
                 for op in self.structure.unary if op != psi[i, j]]
        if self.refine_cfg.sweep_products:
            moves += [(2, i, int(j), int(op), self.refine_cfg.sweep_products)
                      for j in np.flatnonzero(np.diag(psi) == 2)      # 2: a product node
                      for i in range(self.structure.n_sources - self.params.n)
                      if i < j and not psi[i, j] for op in self.structure.unary]
        moves += self._coupling_moves(psi, basis)
        for kind, i, j, op, times in moves:
            m = type(basis)([(kind, i, j, op)] + list(basis.variations[1:]), basis.bits.copy())
            if (sk := self._skeleton(m)) not in seen:
                seen.add(sk)
                rows = self._scaled_rows(m, times)
                out += rows
                self._sweep_k += [len(seen)] * len(rows)
        if not self._room(SWEEP_EPOCHS, len(out)):
            self.stats["sweep_skipped"] = len(out)
            self._sweep_k = []
            return []
        return out

    def _coupling_moves(self, psi, basis) -> list:
        """With ``sweep_coupling``: the sweep's moves that bring an output's node (before the
        bound), through each unary operation, into every product node of another output's
        law that it does not feed (the matrix is upper triangular: a later output's), as
        ``(2, node, product, op, flights)``."""
        times = self.refine_cfg.sweep_coupling
        if not times:
            return []
        law = self.decode(psi, self.params.decode(basis.bits))
        ends = [int(o) - 1 for o in getattr(law, "outputs", ())]
        moves = []
        for j in np.flatnonzero(np.diag(psi) == 2):         # 2: a product node
            feeds = upstream(psi, [int(j)])
            moves += [(2, o, int(j), int(op), times) for o in ends
                      if o < j and not feeds[o]
                      for op in self.structure.unary]
        return moves

    def _claim_resweep(self, best) -> bool:
        """Whether a stalled search sweeps the neighbourhood of its best law ``best`` (the
        epoch's new basis) instead of restarting (``refine resweep``): sweeps left, ``best``'s
        form not swept before and flights left for two epochs (the sweep counted as one; one
        that turns out not to fit when its forms are counted is not flown, and the search goes
        on to its next stall).  If so, the form is recorded as a sweep centre and the sweep
        is marked to start when the epoch's population is flown."""
        n = self.refine_cfg.resweep
        if not n or not self.refine_cfg.sweep or self.stats.get("resweeps", 0) >= n \
                or not self._room(SWEEP_EPOCHS + 1):
            return False
        centres = self.stats.setdefault("sweep_centres", [])
        sk = self._skeleton(best)
        if sk in centres:
            return False
        centres.append(sk)
        self._resweep = True
        return True

    def _finish_sweep(self, members) -> None:
        """The best flight of each swept form joins the population as a child does -- a form
        of ``sweep_products`` or ``sweep_coupling`` (its move an added arc, kind 2) only when
        it beats the tuned basic law; with ``sweep_keep``, only that many forms, the best by the target (ties:
        the sweep's order)."""
        best, basis = {}, self.pop[0]
        for k, m in zip(self._sweep_k, members):
            if k not in best or self.target.better(m.f, best[k].f, m.cv, best[k].cv):
                best[k] = m
        forms = [m for m in best.values() if m.variations[0][0] != 2
                 or self.target.better(m.f, basis.f, m.cv, basis.cv)]
        keep = self.refine_cfg.sweep_keep
        if keep and len(forms) > keep:
            order = self.target.order(np.array([m.f for m in forms]), [m.cv for m in forms])
            forms = [forms[int(i)] for i in order[:keep]]
        for m in forms:
            self._insert(m)
        self.stats["swept_forms"] = self.stats.get("swept_forms", 0) + len(forms)
        self._sweep_k = []

    def _polish_due(self) -> bool:
        """Whether the polish (``polish``) starts now: it has not, no refinement runs, the
        structure search has begun (the basis search is over) and only the ``polish`` share of
        the flight budget is left."""
        share = self.refine_cfg.polish if self.refinement is not None else 0.0
        if not share or self._polished or not self.flights or self.generation == 0 \
                or self.refinement.active or self.target is None:
            return False
        return self.flights - self.evaluations <= share * self.flights

    def _start_polish(self) -> None:
        """The best law by the target gets a fresh CMA-ES of its own on its parameters, with
        every flight left (the run's budget ends it)."""
        self._polished, self._refine_due = True, False
        k = int(self.target.order(self.F, self.CV)[0])
        m = self.pop[k]
        left = self.flights - self.evaluations
        self.refinement.start([(k, m, self._structure_key(m), m.bits.copy())], left, self.rng)
        self.stats["polish"] = {"member": k, "at": int(self.evaluations), "flights": int(left),
                                "from": m.f.tolist()}
