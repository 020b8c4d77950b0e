"""The variational genetic algorithm of the network-operator method (basic-solution principle).

An individual is a list of ``lchr`` small variations of the basic matrix plus the parameters q as
a Gray-coded bit string (:mod:`synthesis.methods.encoding`).  Evaluating it means: start from the
basic matrix, apply the variations in order (an inapplicable one is skipped), decode q, fly the
closed loop.  Ranking is by ``Lh``, the number of population members that constraint-dominate an
individual (:mod:`synthesis.methods.pareto`; Pareto set: ``Lh = 0``).  Every ``epoch``
generations the individual closest to the utopia point becomes the new basic solution.

Ask/tell (:class:`~synthesis.methods.base.Method`); the random generator is injected; same
seed => same result; :meth:`VariationalGA.state` is a JSON-serialisable checkpoint.  The run's
archive of non-dominated laws belongs to the run loop, the parameter refinement by CMA-ES to
:class:`~synthesis.methods.refinement.Refinement`.

Its departures from the lab algorithm (the authors' Free-Pascal programs), each for a reason,
are listed in docs/methods/network_operator.md; the structure search's own steps are
:class:`~synthesis.methods.form_search.FormSearch` (tuning promising forms, restarts) and
:class:`~synthesis.methods.form_moves.FormMoves` (the elite's trimmed variation lists,
where a variation lands, the polish).

References
----------
A.I. Diveev, E.Yu. Shmalko (reentry paper), section "Синтез"; A.I. Diveev, E.A. Sofronova, "The
network operator method in control problems", Vestnik RUDN, 2007.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace

import numpy as np

from descent_fmus.synthesis.methods.base import Candidate, Method
from descent_fmus.synthesis.methods.encoding import (GrayCodec, StructureCodec, bits_array,
                                                     bits_text)
from descent_fmus.synthesis.methods.form_moves import FormMoves
from descent_fmus.synthesis.methods.form_search import FormSearch
from descent_fmus.synthesis.methods.ga_config import GAConfig
from descent_fmus.synthesis.methods.pareto import (Target, best_compromise, crowding_distance,
                                                   dominance_counts, dominance_matrix)
from descent_fmus.synthesis.methods.refinement import RefineConfig, Refinement

__all__ = ["VariationalGA"]

@dataclass
class _Member:
    variations: list
    bits: np.ndarray
    f: np.ndarray = field(default=None)
    cv: float = 0.0
    fresh: tuple | None = None        # (kind, op, whether it changed the law) of its new variation


def _default_decode(psi, q):
    return psi, q


class VariationalGA(FormSearch, FormMoves, Method):
    """Multi-objective variational GA (see the module docstring).

    Parameters
    ----------
    params : GrayCodec
        Coding of the parameters q.
    q0 : sequence of float
        Parameters of the basic solution.
    rng : numpy.random.Generator
        The only source of randomness.
    config : GAConfig
    structure : StructureCodec, optional
        Variations of the basic matrix ``psi0``; None for a pure parameter search.
    psi0 : ndarray, optional
        The basic matrix.
    decode : callable, optional
        ``decode(psi, q) -> law`` of a candidate (default: ``(psi, q)``).
    target : Target, optional
        The single objective of the refinement and of ``basis_rule='target'``.
    refine : RefineConfig, optional
        CMA-ES refinement of the parameters (default: off; a problem's recipe has it on).
    generations : int, optional
        Generations after which :meth:`finished` (default: never).

    Attributes
    ----------
    flights : int
        The run's flight budget (0 = none), for :meth:`RefineConfig.patience_for`.
    rescale : callable or None
        A hook the run may set: ``rescale(law) -> law or None``, called once with the basic
        solution when its refinement ends; a law returned (the same function in other input
        coordinates, e.g. where the refined law acts) becomes the template every candidate is
        decoded with, and the population is flown again in those coordinates.
    """

    def __init__(self, params: GrayCodec, q0, rng: np.random.Generator, config: GAConfig,
                 structure: StructureCodec | None = None, psi0=None, decode=None,
                 target: Target | None = None, refine: RefineConfig | None = None,
                 generations: int | None = None, flights: int = 0):
        refine = refine if refine is not None else RefineConfig(basis=0, evals=0)
        if (refine.active or config.basis_rule == "target") and target is None:
            raise ValueError("parameter refinement (refine evals or basis > 0) or basis_rule "
                             "'target' needs a target")
        self.params, self.cfg, self.rng, self.target = params, config, rng, target
        self.refine_cfg = refine
        self.refinement = Refinement(params, refine, target) if target is not None else None
        self._refine_due = False
        if structure is not None and config.weighted_arcs:
            structure = replace(structure, weighted=config.weighted_arcs, n_params=params.n)
        self.structure = structure
        self.psi0 = None if psi0 is None else np.array(psi0, dtype=int)
        self.q0 = list(q0)
        self.decode = decode or _default_decode
        self.generations, self.flights = generations, flights
        self.generation = 0
        self.evaluations = 0
        self.pop: list[_Member] = []
        self.lh = np.zeros(0, int)
        self._epoch_due = False
        self._pending_trim = []
        self.history = []             # per generation: (generation, evaluations, n_front, best)
        self.stats: dict = {}         # evaluations per phase and how many beat the best law
        self._lchr = config.lchr if structure is not None else 0
        self._pending = ("init", self._initial_members())
        self.rescale = None
        self._basis_refining = False
        self._polished = False         # the polish of the best law has started (``polish``)
        self._template = None          # the decoding law after a rescale (its dict)
        self._origin = None            # (matrix, bits) of the tuned basic solution
        self._elite = None             # islands: the run's best law while an island runs
        self._resweep = False          # the epoch flown next sweeps its basis (``resweep``)

    def _initial_members(self) -> list:
        params, rng, structure, lchr = self.params, self.rng, self.structure, self._lchr
        basis_bits = params.encode(self.q0)
        members = [_Member([StructureCodec.IDENTITY] * lchr, basis_bits)]
        while len(members) < self.cfg.population:
            if len(members) % 2:   # half random parameters, half the basis q with a few flips
                bits = rng.integers(0, 2, params.n_bits).astype(np.uint8)
            else:
                bits = basis_bits.copy()
                for k in rng.integers(0, params.n_bits, 1 + int(rng.integers(0, 4))):
                    bits[k] ^= 1
            var = [structure.random(rng) for _ in range(lchr)] if structure else []
            members.append(_Member(var, bits))
        return members

    # -- decoding -------------------------------------------------------------------------
    def matrix(self, member: _Member):
        if self.structure is None:
            return None
        return self.structure.apply(self.psi0, member.variations)

    def candidate(self, member: _Member) -> Candidate:
        return Candidate(self.decode(self.matrix(member), self.params.decode(member.bits)),
                         {"variations": [list(v) for v in member.variations]})

    @property
    def F(self) -> np.ndarray:
        return np.array([m.f for m in self.pop])

    @property
    def CV(self) -> np.ndarray:
        return np.array([m.cv for m in self.pop], float)

    # -- ask / tell -----------------------------------------------------------------------
    def ask(self) -> list[Candidate]:
        """Candidates to evaluate next (the initial population, children, a refinement's or
        an epoch's re-evaluations)."""
        if self._pending is None and self._refine_due and not self.refinement.active:
            self._refine_due = False
            self._start_refine()
        if self._pending is None and self._polish_due():
            self._start_polish()
        if self._pending is None and self.refinement is not None and self.refinement.active:
            members = [_Member(list(self.pop[k].variations), bits)
                       for k, bits in self.refinement.ask()]
            self._pending = ("refine", members)
        if self._pending is None:
            if self.generation > 0 and self.generation % self.cfg.epoch == 0 \
                    and self.structure is not None and self._epoch_due:
                self._epoch_due = False
                self._pending = ("epoch", self._new_basis())
            else:
                self._pending = ("children", self._children())
        return [self.candidate(m) for m in self._pending[1]]

    def tell(self, F, cv=None) -> None:
        """Objective rows and violations of the candidates of the last :meth:`ask`."""
        if self._pending is None:
            raise RuntimeError("tell() without a pending ask()")
        phase, members = self._pending
        F = np.asarray(F, float)
        cv = np.zeros(len(members)) if cv is None else np.asarray(cv, float)
        if F.shape[0] != len(members) or not np.all(np.isfinite(F)) \
                or cv.shape != (len(members),) or not np.all(np.isfinite(cv)):
            raise ValueError(f"expected {len(members)} finite objective rows and violations, "
                             f"got shapes {F.shape}, {cv.shape}")
        self.evaluations += len(members)
        for m, f, c in zip(members, F, cv):
            m.f, m.cv = f, float(c)
        self._pending = None
        self._count(phase, members)
        if phase in ("init", "epoch", "rescale"):
            self._new_population(phase, members)
        elif phase == "trim":
            self._finish_trim(members)
        elif phase == "refine":
            if self.refinement.tell(members):
                self._finish_refine()
        elif phase == "sweep":
            self._finish_sweep(members)
        elif phase == "screen":
            self._finish_screen(members)
            self._start_refine(screen=False)
        else:
            # [choice] the population's objective rows and violations as arrays made once
            # for the children of a generation and kept up to date by each replacement (the
            # same values as ``F`` / ``CV`` made afresh: one row written in place), not
            # rebuilt from the members twice per child and twice more per replacement
            FC = (self.F, self.CV)
            for child in members:
                accepted = self._insert(child, FC)
                if child.fresh is not None:
                    self._credit(child.fresh, accepted)
            self._decay_credit()
            self.generation += 1
            self._epoch_due = True
            front = self.F[self.lh == 0]
            self.history.append((self.generation, self.evaluations, int(len(front)),
                                 front.min(axis=0).tolist()))

    def _new_population(self, phase: str, members) -> None:
        self.pop = members
        self.lh = dominance_counts(self.F, self.CV)
        self._refine_due = self.refine_cfg.evals > 0
        if phase == "init" and self.refine_cfg.basis > 0:
            # the basic solution's parameters first, with a budget of their own: the
            # structure search then builds on a tuned basis
            self._refine_due = False
            self._start_refine(basis=True)
        if phase == "rescale":          # the sweep waited for the new coordinates
            self._start_sweep()
        if phase == "epoch":
            if self._resweep:                 # a stalled search: its best law's neighbours
                self._resweep = False
                self._start_sweep()
                if self._pending is not None:
                    self.stats["resweeps"] = self.stats.get("resweeps", 0) + 1
                    return
            self._pending_trim = self._trim_candidates()
            if self._pending_trim:
                self._pending = ("trim", [c for _, c in self._pending_trim])

    def at_boundary(self) -> bool:
        return self._pending is None

    def finished(self) -> bool:
        return (self.generations is not None and bool(self.pop) and self._pending is None
                and self.generation >= self.generations
                and not (self.refinement is not None and self.refinement.active))

    def status(self) -> dict:
        return {"gen": self.generation, "front": int(np.sum(self.lh == 0))}

    @property
    def phase(self) -> str:
        if not self.pop:
            return "flying the initial population"
        if self.refinement is not None and (self.refinement.active or self._refine_due):
            return "refining parameters by CMA-ES"
        return "searching structures and parameters"

    # -- generation -----------------------------------------------------------------------
    def _tournament(self) -> int:
        k = self.rng.integers(0, len(self.pop), self.cfg.ksearch)
        return int(k[np.argmin(self.lh[k])])

    def _mutate(self, m: _Member, bits: bool = True) -> None:
        if self.rng.random() < self.cfg.p_mutation:
            if self._lchr:
                v = self._variation(m)          # (drawn before the slot, as ever)
                k = int(self.rng.integers(0, self._lchr))
                before = self.matrix(m) if self.cfg.credit else None
                m.variations[k] = v
                if before is not None:
                    m.fresh = (v[0], v[3], not np.array_equal(before, self.matrix(m)))
            if bits:
                m.bits[int(self.rng.integers(0, self.params.n_bits))] ^= 1

    def _children(self) -> list:
        rng, cfg = self.rng, self.cfg
        children = []
        for _ in range(cfg.crossovers):
            a = self._tournament()
            b = int(rng.integers(0, len(self.pop)))
            lh = max(self.lh[a], self.lh[b])
            if rng.random() > (1.0 + cfg.alpha * lh) / (1.0 + lh):
                continue
            pa, pb = self.pop[a], self.pop[b]
            cb = int(rng.integers(1, self.params.n_bits)) if self.params.n_bits > 1 else 0
            cv = int(rng.integers(0, self._lchr + 1)) if self._lchr else 0
            bits1 = np.concatenate([pa.bits[:cb], pb.bits[cb:]])
            bits2 = np.concatenate([pb.bits[:cb], pa.bits[cb:]])
            var1 = pa.variations[:cv] + pb.variations[cv:]
            var2 = pb.variations[:cv] + pa.variations[cv:]
            for var, bits in ((list(pa.variations), bits1), (list(pb.variations), bits2),
                              (var1, bits1.copy()), (var2, bits2.copy())):
                child = _Member(list(var), bits.copy())
                if self._lchr and cfg.basis_q and rng.random() < cfg.basis_q:
                    child.bits = self.pop[0].bits.copy()
                    self._mutate(child, bits=False)
                else:
                    self._mutate(child)
                parent = pa if len(children) % 2 == 0 else pb
                self._new_weights(child, parent)
                self._morph(child, parent)
                children.append(child)
        return children

    def _replace(self, w: int, member: _Member, FC=None) -> None:
        """Member ``w`` becomes ``member``; the dominance counts follow incrementally.
        ``FC``: ``(F, CV)`` of the population as arrays, updated here in place (default:
        made from the members)."""
        F, C = (self.F, self.CV) if FC is None else FC
        old = self.pop[w]
        dom_old = dominance_matrix([old.f], [old.cv], F, C)[0]
        dom_new = dominance_matrix([member.f], [member.cv], F, C)[0]
        dominated_by = dominance_matrix(F, C, [member.f], [member.cv])[:, 0]
        self.lh = self.lh - dom_old + dom_new
        self.pop[w] = member
        self.lh[w] = int(dominated_by.sum()) - int(dominated_by[w])
        if FC is not None:
            F[w], C[w] = member.f, member.cv

    def _insert(self, child: _Member, FC=None) -> bool:
        """Offer ``child`` to the population (``FC``: as :meth:`_replace`); whether it
        entered."""
        if FC is None:
            FC = (self.F, self.CV)
        (F, C), f = FC, child.f
        if np.any(np.all(F == f, axis=1) & (C == child.cv)):
            return False                 # same objectives as a member: keep diversity
        lh_child = int(dominance_matrix(F, C, [f], [child.cv])[:, 0].sum())
        lh = self.lh.copy()
        lh[0] = -1                       # never replace individual 0 (the basic solution)
        worst_lh = lh.max()
        if lh_child > worst_lh or (lh_child == worst_lh and worst_lh > 0):
            return False
        cand = np.flatnonzero(lh == worst_lh)
        if lh_child == worst_lh:
            # whole population non-dominated: the child replaces the most crowded member if it
            # is itself less crowded there (keeps the front spreading instead of freezing)
            cd = crowding_distance(np.vstack([F[cand], f]))
            if cd[-1] <= cd[:-1].min():
                return False
            w = int(cand[np.argmin(cd[:-1])])
        elif len(cand) > 1:
            w = int(cand[np.argmin(crowding_distance(F[cand]))])
        else:
            w = int(cand[0])
        self._replace(w, child, FC)
        self.stats["accepted"] = self.stats.get("accepted", 0) + 1
        return True

    # -- epoch ----------------------------------------------------------------------------
    def _new_basis(self) -> list:
        # basis_rule "target": the best law by the target becomes the basis (member 0, never
        # replaced), so the law the run reports stays in the population and its parameter
        # search continues; "compromise": the member nearest the utopia point (the lab's rule,
        # which drops the old basis even when it is the best law by the target)
        k = int(self.target.order(self.F, self.CV)[0]) \
            if self.cfg.basis_rule == "target" and self.target is not None \
            else best_compromise(self.F, self.lh)
        best = self.pop[k]
        if self.target is not None:
            self._log_epoch(k)
        if self._origin is None:        # the tuned basic solution, where islands start
            self._origin = (self.psi0.copy(), self.pop[0].bits.copy())
        self._epoch_psi = self.psi0      # the stalled population's basis (islands' centres)
        self.psi0 = self.matrix(best)
        self.q0 = self.params.decode(best.bits)
        members = [_Member([StructureCodec.IDENTITY] * self._lchr, best.bits.copy())]
        members += [_Member(list(m.variations), m.bits.copy()) for m in self.pop[1:]]
        stalled, over = self._stalled(best), self._island_over(best)
        if over or (stalled and not self._claim_resweep(best)):
            members = self._restart(members, best)
        return members

    # -- parameter refinement (synthesis.methods.refinement) -------------------------------
    def _structure_key(self, m: _Member) -> str:
        if self.structure is None:
            return ""
        return hashlib.sha1(self.matrix(m).tobytes()).hexdigest()

    def _start_refine(self, basis: bool = False, screen: bool = True) -> None:
        """Refine member 0 alone (``basis``: ``starts`` searches) or the ``laws`` best members
        by the target with distinct structures (feasible first); with ``screen``, new forms
        are screened first (``refine screen``: the halving starts when they are flown)."""
        if screen and not basis:
            members = self._screen_members()
            if members:
                self._pending = ("screen", members)
                return
        self._basis_refining, patience = basis, 0
        if basis:
            picks, budget = [0] * self.refine_cfg.starts, self.refine_cfg.basis
            left = self.flights - self.evaluations - budget * len(picks) if self.flights \
                else None
            patience = self.refine_cfg.patience_for(left, self.cfg.epoch * 4 * self.cfg.crossovers)
        else:
            picks = self._promising(self.refine_cfg.forms or self.refine_cfg.laws)
            budget = self.refine_cfg.evals
        starts = [(k, self.pop[k], self._structure_key(self.pop[k])) for k in picks]
        rungs = None
        if self.refine_cfg.forms and not basis:
            starts = self._fresh_starts(starts)
            rungs = self.refine_cfg.rungs(len(starts))
            budget = rungs[-1] = rungs[-1] + self._rest(len(starts))
        self.refinement.start(starts, budget, self.rng, patience, rungs)

    def _finish_refine(self) -> None:
        """The refined parameters replace those of the members they started from."""
        for k, bits, f, cv in self.refinement.finish(self.pop, self._structure_key):
            self.pop[k] = _Member(list(self.pop[k].variations), bits, f, cv)
            if k == 0:
                self.q0 = self.params.decode(bits)
        self.lh = dominance_counts(self.F, self.CV)
        if self._basis_refining and self.rescale is not None and self._template is None:
            self._rescaled(self.rescale(self.candidate(self.pop[0]).law))
        if self._basis_refining and self._pending is None:
            self._start_sweep()
            if self._pending is not None and self.refine_cfg.sweep_tune:
                self._refine_due = True     # the halving once the swept forms are flown
        self._basis_refining = False

    def _rescaled(self, law) -> None:
        """Decode every candidate with ``law``'s input coordinates from now on (see
        :attr:`rescale`): the basis takes ``law``'s parameters, the other members keep their
        bits, and the whole population is flown again; CMA-ES searches of the old coordinates
        are dropped."""
        if law is None:
            return
        from descent_fmus.synthesis.methods.law import NetworkOperator
        self._template = law.to_dict(formula=False)
        self.decode = NetworkOperator.from_dict(self._template).with_structure
        self.q0 = list(law.q)
        members = [_Member(list(m.variations), m.bits.copy()) for m in self.pop]
        members[0].bits = self.params.encode(self.q0)
        self.refinement.pool.clear()
        self._pending = ("rescale", members)

    # -- checkpoint -----------------------------------------------------------------------
    def state(self) -> dict:
        """JSON-serialisable state (restores to the same future as an uninterrupted run)."""
        if self._pending is not None:
            raise RuntimeError("checkpoint only between tell() and ask()")
        return {
            "generation": self.generation, "evaluations": self.evaluations,
            "psi0": None if self.psi0 is None else self.psi0.tolist(), "q0": self.q0,
            "rng": self.rng.bit_generator.state, "epoch_due": self._epoch_due,
            "history": self.history,
            "population": [{"v": [list(v) for v in m.variations], "b": bits_text(m.bits),
                            "f": m.f.tolist(), "cv": m.cv} for m in self.pop],
            "refine_due": self._refine_due,
            "refine": None if self.refinement is None else self.refinement.state(),
            "template": self._template, "basis_refining": self._basis_refining,
            **({"polished": True} if self._polished else {}),
            "stats": self.stats, **self._island_state(),
            **({"tuned_skeletons": sorted(self.tuned_skeletons)} if self.tuned_skeletons
               else {}),
        }

    def load_state(self, st: dict) -> "VariationalGA":
        self.generation, self.evaluations = st["generation"], st["evaluations"]
        self.psi0 = None if st["psi0"] is None else np.array(st["psi0"], dtype=int)
        self.q0 = list(st["q0"])
        self.rng.bit_generator.state = st["rng"]
        self._epoch_due = st["epoch_due"]
        self.history = [tuple(h) for h in st["history"]]
        self.pop = [_Member([tuple(v) for v in m["v"]], bits_array(m["b"]),
                            np.array(m["f"], float), float(m.get("cv", 0.0)))
                    for m in st["population"]]
        self.lh = dominance_counts(self.F, self.CV)
        self._pending = None
        self._refine_due = st.get("refine_due", False)
        if self.refinement is not None:
            self.refinement.load_state(st.get("refine"), self.q0)
        self._template = st.get("template")
        self._basis_refining = st.get("basis_refining", False)
        self._polished = st.get("polished", False)
        self.stats = dict(st.get("stats", {}))
        self._tuned_skeletons = set(st.get("tuned_skeletons", []))
        self._load_island_state(st)
        if self._template is not None:
            from descent_fmus.synthesis.methods.law import NetworkOperator
            self.decode = NetworkOperator.from_dict(self._template).with_structure
        return self
