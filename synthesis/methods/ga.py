"""The variational genetic algorithm of the network-operator method (basic-solution principle).

An individual is a list of ``lchr`` small variations of the basic matrix plus the parameters q as a
Gray-coded bit string.  Evaluating it means: start from the basic matrix, apply the variations in
order (an inapplicable one is skipped), decode q, fly the closed loop.  Ranking is by ``Lh``, the
number of population members that dominate an individual (Pareto set: ``Lh = 0``).  Every
``epoch`` generations the individual closest to the utopia point becomes the new basic solution.

Ask/tell interface (as pymoo's algorithms): :meth:`VariationalGA.ask` returns decoded candidates,
:meth:`VariationalGA.tell` takes their objective vectors; :meth:`VariationalGA.run` is the loop.
The random generator is injected; same seed => same result.  :meth:`state` / :meth:`from_state`
give a JSON-serialisable checkpoint (population, basis, generator state).

Departures from the lab algorithm (the authors' Free-Pascal programs), each for a reason:

* the children of a generation are produced first and evaluated as one batch (so a worker pool or
  a Dask cluster can evaluate them in parallel), then inserted one by one exactly as in the lab
  algorithm (a child replaces the worst individual, never individual 0, if its ``Lh`` is smaller);
* among equally bad individuals the most crowded one is replaced (NSGA-II crowding distance),
  and once the whole population is non-dominated a non-dominated child replaces the most crowded
  member if it is less crowded itself (the lab rule would freeze the population there), which
  keeps the front spread; a child whose objectives equal an existing member's is dropped;
* the epoch normalises the objectives over the current Pareto set, not the whole population, so a
  few penalised laws (a flight that never reaches hf) do not flatten the normalisation;
* an external archive keeps the non-dominated laws of the whole run (capped by crowding): an
  epoch re-reads every variation list against the new basis and would otherwise lose good laws;
  the result of a run is the archive;
* optional parameter refinement (``refine_evals > 0``): after the initial population and after
  every epoch, CMA-ES (:class:`synthesis.methods.baselines.CMA`) tunes the parameters q of
  the best members by a single-objective target (distinct structures), on the Gray code's grid;
  the best refined q replaces the member's, and a structure refined again continues its
  CMA-ES.  The Gray-coded bit flips search q poorly on the rugged landscapes of closed-loop
  laws; CMA-ES adapts its steps and their correlations.

References
----------
A.I. Diveev, E.Yu. Shmalko (reentry paper), section "Синтез"; A.I. Diveev, E.A. Sofronova, "The network operator
method in control problems", Vestnik RUDN, 2007.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from descent_fmus.synthesis.methods.pareto import crowding_distance, dominance_counts

__all__ = ["GrayCodec", "StructureCodec", "VariationalGA", "GAConfig"]


def _bits_text(bits) -> str:
    return "".join(map(str, np.asarray(bits).tolist()))


def _bits_array(text: str) -> np.ndarray:
    return (np.frombuffer(text.encode(), dtype=np.uint8) - ord("0")).copy()


# -- parameters: Gray-coded bit strings ---------------------------------------------------------
@dataclass(frozen=True)
class GrayCodec:
    """``n`` parameters, each ``int_bits + frac_bits`` Gray-coded bits mapped to ``[lo, hi)``.

    With the defaults (4 + 12 bits, [0, 16)) a parameter is an integer part of 4 bits and a
    fractional part of 12 bits, step 2^-12, as in the lab programs.
    """

    n: int
    int_bits: int = 4
    frac_bits: int = 12
    lo: float = 0.0
    hi: float = 16.0

    @property
    def bits_per(self) -> int:
        return self.int_bits + self.frac_bits

    @property
    def n_bits(self) -> int:
        return self.n * self.bits_per

    def decode(self, bits) -> list:
        bits = np.asarray(bits, dtype=np.uint8).reshape(self.n, self.bits_per)
        # Gray -> binary: b_k = g_0 xor ... xor g_k
        binary = np.bitwise_xor.accumulate(bits, axis=1)
        weights = 1 << np.arange(self.bits_per - 1, -1, -1, dtype=np.int64)
        ints = binary.astype(np.int64) @ weights
        return list(self.lo + (self.hi - self.lo) * ints / float(1 << self.bits_per))

    def encode(self, values) -> np.ndarray:
        values = np.asarray(values, float)
        full = 1 << self.bits_per
        ints = np.clip(np.round((values - self.lo) / (self.hi - self.lo) * full), 0, full - 1)
        ints = ints.astype(np.int64)
        gray = ints ^ (ints >> 1)
        shifts = np.arange(self.bits_per - 1, -1, -1)
        return ((gray[:, None] >> shifts[None, :]) & 1).astype(np.uint8).ravel()


# -- structure: variations of a network-operator matrix ------------------------------------------
@dataclass
class StructureCodec:
    """Small variations (kind, i, j, op) of an upper-triangular matrix (0-based node numbers).

    kinds: 0 replace the unary operation on an existing arc i->j; 1 replace the binary
    operation at non-source node j; 2 add an arc i->j with unary operation ``op`` (target a
    non-source node that has a binary operation); 3 remove the arc i->j if node j keeps another
    incoming arc and node i another outgoing arc.  A variation with ``j < n_sources`` (such as
    (0, 0, 0, 0)) is the identity.
    """

    size: int
    n_sources: int
    unary: tuple = tuple(range(1, 29))
    binary: tuple = (1, 2, 3, 4)

    IDENTITY = (0, 0, 0, 0)

    def random(self, rng: np.random.Generator) -> tuple:
        kind = int(rng.integers(0, 4))
        j = int(rng.integers(self.n_sources, self.size))
        i = int(rng.integers(0, j))
        ops = self.binary if kind == 1 else self.unary
        return (kind, i, j, int(ops[int(rng.integers(0, len(ops)))]))

    def apply(self, psi: np.ndarray, variations) -> np.ndarray:
        """A copy of ``psi`` with the applicable variations applied in order."""
        psi = psi.copy()
        for kind, i, j, op in variations:
            if j < self.n_sources or i >= j or j >= self.size:
                continue
            if kind == 0:
                if psi[i, j]:
                    psi[i, j] = op
            elif kind == 1:
                if psi[j, j]:
                    psi[j, j] = op
            elif kind == 2:
                if not psi[i, j] and psi[j, j]:
                    psi[i, j] = op
            elif kind == 3:
                if psi[i, j] and np.count_nonzero(psi[:j, j]) > 1 \
                        and np.count_nonzero(psi[i, i + 1:]) > 1:
                    psi[i, j] = 0
        return psi


@dataclass
class GAConfig:
    """Sizes and rates of the variational GA (defaults: see models/README.md / the CLI)."""

    population: int = 256
    crossovers: int = 32        #: RR crossover attempts per generation (4 children each)
    lchr: int = 8               #: variations per individual
    epoch: int = 12             #: generations between basis changes (Epo)
    p_mutation: float = 0.7
    alpha: float = 0.4          #: crossover probability (1 + alpha Lh) / (1 + Lh)
    ksearch: int = 4            #: tournament size for parent 1
    elite_trim: int = 4         #: individuals whose variation lists are trimmed per epoch
    refine_evals: int = 0       #: CMA-ES evaluations per refined law at each epoch (0 = off)
    refine_laws: int = 1        #: laws refined per epoch: the best by the target (distinct
                                #: structures)
    refine_basis: int = 0       #: CMA-ES evaluations on the basis's parameters after the
                                #: initial population, before the structure search (0 = off)
    refine_sigma: float = 0.3   #: initial CMA-ES step, relative to each parameter's size
    refine_popsize: int = 0     #: CMA-ES candidates per generation (0 = pycma's default)
    basis_rule: str = "compromise"  #: the epoch's new basis: "compromise" (nearest the utopia
                                    #: point, the lab's rule) or "target" (best by the target)

    def __post_init__(self):
        if self.basis_rule not in ("compromise", "target"):
            raise ValueError(f"basis_rule must be 'compromise' or 'target', got "
                             f"{self.basis_rule!r}")
        if self.population < 4:
            raise ValueError(f"population must be >= 4, got {self.population}")
        if self.crossovers < 1:
            raise ValueError(f"crossovers must be >= 1, got {self.crossovers}")
        if self.lchr < 0 or self.epoch < 1 or not 0 <= self.p_mutation <= 1:
            raise ValueError("need lchr >= 0, epoch >= 1 and 0 <= p_mutation <= 1")
        if self.refine_evals < 0 or self.refine_laws < 1 or not self.refine_sigma > 0 \
                or self.refine_popsize < 0 or self.refine_basis < 0:
            raise ValueError("need refine_evals >= 0, refine_basis >= 0, refine_laws >= 1, "
                             "refine_sigma > 0 and refine_popsize >= 0")


@dataclass
class _Member:
    variations: list
    bits: np.ndarray
    f: np.ndarray = field(default=None)


class VariationalGA:
    """Multi-objective variational GA with an ask/tell interface.

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
        ``decode(psi, q) -> candidate`` handed to the evaluator (default: ``(psi, q)``).
    """

    def __init__(self, params: GrayCodec, q0, rng: np.random.Generator, config: GAConfig,
                 structure: StructureCodec | None = None, psi0=None, decode=None,
                 archive_max: int = 200, target=None):
        self.params, self.cfg, self.rng = params, config, rng
        if (config.refine_evals or config.refine_basis or config.basis_rule == "target") \
                and target is None:
            raise ValueError("parameter refinement (refine_evals > 0) or basis_rule 'target' "
                             "needs a target")
        self.target = target
        self._refine = None           # the running CMA-ES refinements (see _start_refine)
        self._refine_due = False
        self._cma_pool = {}           # structure key -> (CMA, bits of its best q) to continue
        self.archive_max = archive_max
        self.structure = structure
        self.psi0 = None if psi0 is None else np.array(psi0, dtype=int)
        self.q0 = list(q0)
        self.decode = decode or (lambda psi, q: (psi, q))
        self.generation = 0
        self.evaluations = 0
        self.pop: list[_Member] = []
        self.lh = np.zeros(0, int)
        self._pending = None          # (phase, members) awaiting tell()
        self._epoch_due = False
        self._pending_trim = []
        self.history = []             # per generation: (generation, evaluations, n_front, best)
        self.archive = []             # non-dominated (psi, bits, f, variations) of the whole run
        lchr = config.lchr if structure is not None else 0
        self._lchr = lchr
        basis_bits = params.encode(self.q0)
        members = [_Member([StructureCodec.IDENTITY] * lchr, basis_bits)]
        while len(members) < config.population:
            if len(members) % 2:   # half random parameters, half the basis q with a few flips
                bits = rng.integers(0, 2, params.n_bits).astype(np.uint8)
            else:
                bits = basis_bits.copy()
                for k in rng.integers(0, params.n_bits, 1 + int(rng.integers(0, 4))):
                    bits[k] ^= 1
            var = [structure.random(rng) for _ in range(lchr)] if structure else []
            members.append(_Member(var, bits))
        self._pending = ("init", members)

    # -- decoding -------------------------------------------------------------------------
    def matrix(self, member: _Member):
        if self.structure is None:
            return None
        return self.structure.apply(self.psi0, member.variations)

    def candidate(self, member: _Member):
        return self.decode(self.matrix(member), self.params.decode(member.bits))

    # -- ask / tell -----------------------------------------------------------------------
    def ask(self) -> list:
        """Candidates to evaluate next (the initial population, children, or re-evaluations)."""
        if self._pending is None and self._refine_due and self._refine is None:
            self._refine_due = False
            self._start_refine()
        if self._pending is None and self._refine is not None:
            self._pending = ("refine", self._refine_members())
        if self._pending is None:
            if self.generation > 0 and self.generation % self.cfg.epoch == 0 \
                    and self.structure is not None and self._epoch_due:
                self._epoch_due = False
                self._pending = ("epoch", self._new_basis())
            else:
                self._pending = ("children", self._children())
        return [self.candidate(m) for m in self._pending[1]]

    def tell(self, F) -> None:
        """Objective vectors (rows) of the candidates of the last :meth:`ask`, same order."""
        if self._pending is None:
            raise RuntimeError("tell() without a pending ask()")
        phase, members = self._pending
        F = np.asarray(F, float)
        if F.shape[0] != len(members) or not np.all(np.isfinite(F)):
            raise ValueError(f"expected {len(members)} finite objective rows, got shape "
                             f"{F.shape}")
        self.evaluations += len(members)
        for m, f in zip(members, F):
            m.f = f
            self._archive(m)
        self._pending = None
        if phase in ("init", "epoch"):
            self.pop = members
            self.lh = dominance_counts(self.F)
            self._refine_due = self.cfg.refine_evals > 0
            if phase == "init" and self.cfg.refine_basis > 0:
                # the basic solution's parameters first, with a budget of their own: the
                # structure search then builds on a tuned basis
                self._refine_due = False
                self._start_refine(basis=True)
            if phase == "epoch":
                self._pending_trim = self._trim_candidates()
                if self._pending_trim:
                    self._pending = ("trim", [c for _, c in self._pending_trim])
                    return
            return
        if phase == "trim":
            self._finish_trim(members)
            return
        if phase == "refine":
            self._tell_refine(members, F)
            return
        for child in members:
            self._insert(child)
        self.generation += 1
        self._epoch_due = True
        front = self.F[self.lh == 0]
        self.history.append((self.generation, self.evaluations, int(len(front)),
                             front.min(axis=0).tolist()))

    def _archive(self, m: _Member) -> None:
        f = m.f
        if self.archive:
            A = np.array([a[2] for a in self.archive])
            if np.any(np.all(A <= f, axis=1)):
                return                   # weakly dominated by an archived law: adds nothing
            beaten = np.all(f <= A, axis=1) & np.any(f < A, axis=1)
            keep = [a for a, b in zip(self.archive, beaten) if not b]
        else:
            keep = []
        keep.append((self.matrix(m), m.bits.copy(), f.copy(), list(m.variations)))
        if len(keep) > self.archive_max:
            cd = crowding_distance(np.array([a[2] for a in keep]))
            del keep[int(np.argmin(cd))]
        self.archive = keep

    @property
    def F(self) -> np.ndarray:
        return np.array([m.f for m in self.pop])

    def pareto(self) -> list:
        """(candidate, objectives, variations) of the run's Pareto set (the archive), sorted by
        objective 1; the variations are relative to the basis current when the law was found."""
        arch = sorted(self.archive, key=lambda a: tuple(a[2]))
        return [(self.decode(psi, self.params.decode(bits)), f.copy(), list(v))
                for psi, bits, f, v in arch]

    def run(self, evaluate, generations: int, callback=None):
        """Evaluate the initial population, then ``generations`` generations.

        ``evaluate(candidates) -> F`` (rows); ``callback(ga)`` after every generation.
        """
        target = self.generation + generations
        while self.generation < target or self._pending is not None or not self.pop \
                or self._refine is not None:
            cands = self.ask()
            self.tell(evaluate(cands))
            if callback is not None and self._pending is None:
                callback(self)
        return self

    # -- generation -----------------------------------------------------------------------
    def _tournament(self) -> int:
        k = self.rng.integers(0, len(self.pop), self.cfg.ksearch)
        return int(k[np.argmin(self.lh[k])])

    def _mutate(self, m: _Member) -> None:
        if self.rng.random() < self.cfg.p_mutation:
            if self._lchr:
                m.variations[int(self.rng.integers(0, self._lchr))] = \
                    self.structure.random(self.rng)
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
                self._mutate(child)
                children.append(child)
        return children

    def _insert(self, child: _Member) -> None:
        F = self.F
        f = child.f
        if np.any(np.all(F == f, axis=1)):
            return                       # same objectives as a member: keep diversity
        dominated_by = np.all(F <= f, axis=1) & np.any(F < f, axis=1)
        lh_child = int(dominated_by.sum())
        lh = self.lh.copy()
        lh[0] = -1                       # never replace individual 0 (the basic solution)
        worst_lh = lh.max()
        if lh_child > worst_lh or (lh_child == worst_lh and worst_lh > 0):
            return
        cand = np.flatnonzero(lh == worst_lh)
        if lh_child == worst_lh:
            # whole population non-dominated: the child replaces the most crowded member if it
            # is itself less crowded there (keeps the front spreading instead of freezing)
            cd = crowding_distance(np.vstack([F[cand], f]))
            if cd[-1] <= cd[:-1].min():
                return
            w = int(cand[np.argmin(cd[:-1])])
        elif len(cand) > 1:
            w = int(cand[np.argmin(crowding_distance(F[cand]))])
        else:
            w = int(cand[0])
        old = self.pop[w].f
        # incremental update of the dominance counts
        dom_old = np.all(old <= F, axis=1) & np.any(old < F, axis=1)
        dom_new = np.all(f <= F, axis=1) & np.any(f < F, axis=1)
        self.lh = self.lh - dom_old + dom_new
        self.pop[w] = child
        self.lh[w] = lh_child - int(dominated_by[w])

    # -- epoch ----------------------------------------------------------------------------
    def _best_compromise(self) -> int:
        idx = np.flatnonzero(self.lh == 0)
        F = self.F[idx]
        lo, hi = F.min(axis=0), F.max(axis=0)
        span = np.where(hi > lo, hi - lo, 1.0)
        d = np.sqrt((((F - lo) / span) ** 2).sum(axis=1))
        return int(idx[np.argmin(d)])

    def _target_order(self) -> np.ndarray:
        """Population indices, best by the target first: the members that meet the constraint
        by their objective, then the others by the penalised scalar (a law just past the
        constraint with a lower objective is not the best law)."""
        F, t = self.F, self.target
        feasible = t.feasible(F)
        rank = np.where(feasible, F[:, t.objective], t.scalar(F))
        return np.lexsort((rank, ~feasible))

    def _new_basis(self) -> list:
        # basis_rule "target": the best law by the target becomes the basis (member 0, never
        # replaced), so the law the run reports stays in the population and its parameter
        # search continues; "compromise": the member nearest the utopia point (the lab's rule,
        # which drops the old basis even when it is the best law by the target)
        k = int(self._target_order()[0]) \
            if self.cfg.basis_rule == "target" and self.target is not None \
            else self._best_compromise()
        best = self.pop[k]
        self.psi0 = self.matrix(best)
        self.q0 = self.params.decode(best.bits)
        members = [_Member([StructureCodec.IDENTITY] * self._lchr, best.bits.copy())]
        members += [_Member(list(m.variations), m.bits.copy()) for m in self.pop[1:]]
        return members

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
                out.append(((int(k), n), _Member(list(m.variations[:n]) +
                                                 [StructureCodec.IDENTITY] * (self._lchr - n),
                                                 m.bits.copy())))
        return out

    def _finish_trim(self, evaluated) -> None:
        best = {}
        for ((k, n), _), m in zip(self._pending_trim, evaluated):
            if k in best:
                continue
            if np.all(m.f <= self.pop[k].f):     # a shorter prefix that worsens nothing
                best[k] = m
        F = self.F
        for k, m in best.items():
            old = self.pop[k].f
            dom_old = np.all(old <= F, axis=1) & np.any(old < F, axis=1)
            dom_new = np.all(m.f <= F, axis=1) & np.any(m.f < F, axis=1)
            self.pop[k] = m
            F[k] = m.f
            self.lh = self.lh - dom_old + dom_new
        if best:
            self.lh = dominance_counts(self.F)
        self._pending_trim = []

    # -- parameter refinement by CMA-ES ----------------------------------------------------
    def _start_refine(self, basis: bool = False) -> None:
        """CMA-ES on the parameters of the best members by the target with distinct structures
        (``refine_laws`` of them, feasible first; the basis among them if it is one of the best),
        ``refine_evals`` each; with ``basis``, on the basis (member 0 of the initial
        population) alone, ``refine_basis`` evaluations.  A structure refined before continues
        its CMA-ES (mean, step size and covariance kept: one long search per structure rather
        than restarts); otherwise a copy of the latest search starts at the member's q."""
        if basis:
            picks, budget = [0], self.cfg.refine_basis
        else:
            picks, seen = [], set()
            for k in self._target_order():
                if len(picks) >= self.cfg.refine_laws:
                    break
                key = self._structure_key(self.pop[int(k)])
                if key not in seen:
                    seen.add(key)
                    picks.append(int(k))
            budget = self.cfg.refine_evals
        searches = []
        for k in picks:
            seed = int(self.rng.integers(0, 2 ** 31 - 1))
            m = self.pop[k]
            old = self._cma_pool.pop(self._structure_key(m), None)
            q = self.params.decode(m.bits)
            if old is not None:
                searches.append(old[0])
            elif self._cma_pool:
                # a structure not refined before: warm start from the latest search (most
                # often its parent's, whose step size and covariance fit a neighbouring law)
                searches.append(next(reversed(self._cma_pool.values()))[0].spawn(q, seed))
            else:
                searches.append(self._new_cma(q, seed))
        self._refine = {"members": picks, "cma": searches, "evals": [0] * len(picks),
                        "budget": budget,
                        "best": [(self.pop[k].bits.copy(), self.pop[k].f.copy())
                                 for k in picks]}

    def _structure_key(self, m: _Member) -> str:
        if self.structure is None:
            return ""
        return hashlib.sha1(self.matrix(m).tobytes()).hexdigest()

    def _new_cma(self, q, seed):
        from descent_fmus.synthesis.methods.baselines import CMA, IPOP_SIGMA, IPOP_STALL
        p = self.params
        step = (p.hi - p.lo) / float(1 << p.bits_per)
        grid = lambda x: p.decode(p.encode(x))  # noqa: E731  (what the Gray code can hold)
        return CMA(q, self.cfg.refine_sigma, seed, popsize=self.cfg.refine_popsize or None,
                   bounds=(p.lo, p.hi - step), x_map=grid, restart_sigma=IPOP_SIGMA,
                   restart_stall=IPOP_STALL)

    def _refine_members(self) -> list:
        r = self._refine
        out = []
        for k, c, n in zip(r["members"], r["cma"], r["evals"]):
            if n >= r["budget"]:
                continue
            var = list(self.pop[k].variations)
            out += [_Member(list(var), self.params.encode(x)) for x in c.ask()]
        return out

    def _better(self, f, g) -> bool:
        """Is objective row f better than g for the target (feasible first, then objective)?"""
        t = self.target
        fs, gs = t.feasible(f)[0], t.feasible(g)[0]
        if fs != gs:
            return bool(fs)
        if fs:
            return f[t.objective] < g[t.objective]
        return t.scalar(f)[0] < t.scalar(g)[0]

    def _tell_refine(self, members, F) -> None:
        r = self._refine
        i = 0
        for j, (c, n) in enumerate(zip(r["cma"], r["evals"])):
            if n >= r["budget"]:
                continue
            m = c.popsize
            rows = F[i:i + m]
            c.tell(self.target.scalar(rows))
            for mem in members[i:i + m]:
                if self._better(mem.f, r["best"][j][1]):
                    r["best"][j] = (mem.bits.copy(), mem.f.copy())
            r["evals"][j] += m
            i += m
        if all(n >= r["budget"] for n in r["evals"]):
            self._finish_refine()

    def _finish_refine(self) -> None:
        """The refined parameters replace those of the members they started from."""
        r = self._refine
        for k, (bits, f), c in zip(r["members"], r["best"], r["cma"]):
            if self._better(f, self.pop[k].f):
                self.pop[k] = _Member(list(self.pop[k].variations), bits.copy(), f.copy())
                if k == 0:
                    self.q0 = self.params.decode(bits)
            self._cma_pool[self._structure_key(self.pop[k])] = (c, _bits_text(self.pop[k].bits))
        while len(self._cma_pool) > self.cfg.refine_laws * 4:     # oldest first
            del self._cma_pool[next(iter(self._cma_pool))]
        self.lh = dominance_counts(self.F)
        self._refine = None

    def _refine_state(self):
        pool = [{"key": k, "cma": c.state(), "b": b} for k, (c, b) in self._cma_pool.items()]
        r = self._refine
        if r is None:
            return {"pool": pool}
        return {"pool": pool, "members": r["members"], "evals": r["evals"],
                "budget": r["budget"], "cma": [c.state() for c in r["cma"]],
                "best": [{"b": _bits_text(b), "f": f.tolist()} for b, f in r["best"]]}

    def _load_refine_state(self, st) -> None:
        st = st or {}
        self._cma_pool = {a["key"]: (self._new_cma(self.q0, 1).load_state(a["cma"]), a["b"])
                          for a in st.get("pool", [])}
        if "members" not in st:
            self._refine = None
            return
        self._refine = {"members": list(st["members"]), "evals": list(st["evals"]),
                        "budget": st.get("budget", self.cfg.refine_evals),
                        "cma": [self._new_cma(self.q0, 1).load_state(t) for t in st["cma"]],
                        "best": [(_bits_array(b["b"]), np.array(b["f"], float))
                                 for b in st["best"]]}

    # -- checkpoint -----------------------------------------------------------------------
    def state(self) -> dict:
        """JSON-serialisable state (restores to the same future as an uninterrupted run)."""
        if self._pending is not None:
            raise RuntimeError("checkpoint only between tell() and ask()")
        return {
            "generation": self.generation, "evaluations": self.evaluations,
            "psi0": None if self.psi0 is None else self.psi0.tolist(), "q0": self.q0,
            "rng": self.rng.bit_generator.state, "epoch_due": getattr(self, "_epoch_due", False),
            "history": self.history,
            "population": [{"v": [list(v) for v in m.variations],
                            "b": "".join(map(str, m.bits.tolist())), "f": m.f.tolist()}
                           for m in self.pop],
            "archive": [{"psi": None if psi is None else psi.tolist(),
                         "b": "".join(map(str, bits.tolist())), "f": f.tolist(),
                         "v": [list(x) for x in v]} for psi, bits, f, v in self.archive],
            "refine_due": self._refine_due, "refine": self._refine_state(),
        }

    def load_state(self, st: dict) -> "VariationalGA":
        self.generation, self.evaluations = st["generation"], st["evaluations"]
        self.psi0 = None if st["psi0"] is None else np.array(st["psi0"], dtype=int)
        self.q0 = list(st["q0"])
        self.rng.bit_generator.state = st["rng"]
        self._epoch_due = st["epoch_due"]
        self.history = [tuple(h) for h in st["history"]]
        self.pop = [_Member([tuple(v) for v in m["v"]],
                            np.frombuffer(m["b"].encode(), dtype=np.uint8) - ord("0"),
                            np.array(m["f"], float)) for m in st["population"]]
        for m in self.pop:
            m.bits = m.bits.copy()
        self.archive = [(None if a["psi"] is None else np.array(a["psi"], dtype=int),
                         (np.frombuffer(a["b"].encode(), dtype=np.uint8) - ord("0")).copy(),
                         np.array(a["f"], float), [tuple(x) for x in a["v"]])
                        for a in st["archive"]]
        self.lh = dominance_counts(self.F)
        self._pending = None
        self._refine_due = st.get("refine_due", False)
        self._load_refine_state(st.get("refine"))
        return self
