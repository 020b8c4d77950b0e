"""Parameter refinement inside the network-operator search: CMA-ES on the parameters q of
promising structures.

The Gray-coded bit flips of the variational GA search q poorly on the rugged landscapes of
closed-loop laws; CMA-ES adapts its steps and their correlations.  After the initial population
(``basis`` evaluations on the basic solution alone -- ``starts`` independent searches of
``basis`` each, the best going on; continued past them while its IPOP restarts still improve
the law when the flight budget left could not hold one epoch of the structure search:
``basis_patience``) and after every epoch (``evals``
evaluations on each of the ``laws`` best members by the target, distinct structures), one
CMA-ES per chosen member tunes q on the Gray code's grid; the best refined q replaces the
member's.  A structure refined again continues its CMA-ES (mean, step size and covariance
kept: one long search per structure rather than restarts); a structure not refined before
starts from a copy of the latest search (most often its parent's, whose step size and
covariance fit a neighbouring law).

The GA owns the population; :class:`Refinement` owns the searches and says which members'
parameters to fly and which to replace.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from descent_fmus.synthesis.methods.cma import CMA, IPOP_STALL
from descent_fmus.synthesis.methods.encoding import GrayCodec, bits_array, bits_text
from descent_fmus.synthesis.methods.pareto import Target
from descent_fmus.synthesis.methods.settings import check_settings, setting

__all__ = ["RefineConfig", "Refinement", "FILE_REFINE"]

#: [choice] a problem file's refinement settings that differ from :class:`RefineConfig`'s
#: (registered systems keep those): ``pick = "spread"``, ``sweep = 8`` and
#: ``sweep_products = 8``, chosen on the suite's tuning half by the issue's goals
#: (docs/methods/network_operator.md "How a default is chosen", "pick"; docs/benchmarks/suite.md
#: "search16": the sweep judged over seeds 1-6; "search21": the products over 12 seeds)
FILE_REFINE = {"pick": "spread", "sweep": 8, "sweep_products": 8}

#: [choice] Epochs of the structure search the flights left after the basic solution's ``basis``
#: evaluations must hold for its CMA-ES to stop there (:meth:`RefineConfig.patience_for`): with
#: room for one epoch (its children and the refinement after it: a new form found in it gets its
#: parameters tuned) the structure search has the rest of the budget; with less, the basic
#: solution's search goes on.  Two (the previous release) gave the whole of mintime-di's 4 000
#: flights to that CMA-ES (0 structure generations; docs/methods/network_operator.md).
STRUCTURE_EPOCHS = 1
#: [choice] the basic solution's search never runs past ``PATIENCE_CAP`` times its ``basis``
#: budget (the run's flight budget ends it sooner)
PATIENCE_CAP = 10


@dataclass(frozen=True)
class RefineConfig:
    """CMA-ES refinement of the parameters inside the network-operator search (0 = off)."""

    basis: int = setting(1000, "CMA-ES evaluations on the basic solution's parameters before "
                               "the structure search (0 = none)", 0, 10_000_000)
    basis_patience: int = setting(1, "when the flight budget left after `basis` cannot hold "
                                     "one epoch of the structure search, the basic solution's "
                                     "CMA-ES goes on until this many IPOP restarts in a row "
                                     "have not improved its best law (0 = stop at `basis`)",
                                  0, 100)
    restart_gain: float = setting(1e-4, "an IPOP restart of the basic solution's search that "
                                        "improves its best value by less than this share is a "
                                        "failed one (basis_patience)", 0.0, 1.0)
    stall_gain: float = setting(1e-4, "when no epoch of the structure search fits "
                                      "(basis_patience applies), the basic solution's CMA-ES "
                                      "makes an IPOP restart once its best has improved by "
                                      "less than this share over 60 generations (0 = only "
                                      "after 60 generations without any better value)",
                                0.0, 1.0)
    step_restart: float = setting(0.0, "a refinement's CMA-ES makes an IPOP restart once its "
                                       "step size has fallen below this share of the initial "
                                       "one (0 = only after 60 generations without a better "
                                       "value)", 0.0, 1.0)
    evals: int = setting(200, "CMA-ES evaluations per refined law after every epoch (0 = the "
                              "GA alone)", 0, 10_000_000)
    laws: int = setting(1, "laws refined after every epoch: the best by the target, distinct "
                           "structures", 1, 64)
    sigma: float = setting(0.3, "initial CMA-ES step, relative to each parameter's size",
                           1e-12, 1e6)
    popsize: int = setting(0, "CMA-ES candidates per generation (0 = pycma's default "
                              "4 + 3 ln n)", 0, 10_000)
    starts: int = setting(1, "independent CMA-ES searches on the basic solution, each with "
                             "its own seed and the `basis` budget; the best one's law goes on "
                             "(several basins of a multimodal landscape instead of one)",
                          1, 64)
    forms: int = setting(4, "forms tuned after every epoch by successive halving: the best "
                            "members by the target with distinct structures each get a short "
                            "CMA-ES, the better half goes on with twice the evaluations, until "
                            "one has `evals` (0 = the `laws` best, `evals` each)", 0, 64)
    form_starts: int = setting(1, "CMA-ES searches per new form in the successive halving: "
                                  "from its own parameters and from form_starts - 1 random "
                                  "ones (drawn as the initial population's); the best counts",
                               1, 16)
    pick: str = setting("best", "which new forms the halving tunes after the best member: "
                                "'best' (the best by the target with its inherited "
                                "parameters), 'spread' (at evenly spaced ranks of the new "
                                "forms by the target: a form's untuned value is a poor guide "
                                "to its tuned one) or 'adaptive' ('best' until an epoch's "
                                "best law is none of the new forms tuned after the epoch "
                                "before, then 'spread'); default 'spread' in a problem "
                                "file, 'best' for a registered system",
                        choices=("best", "spread", "adaptive"))
    distinct: str = setting("matrix", "what makes a form new for the halving: 'matrix' (its "
                                      "matrix differs) or 'skeleton' (its expression with "
                                      "the constants abstracted differs from the best law's, "
                                      "from every other pick's and from every form tuned "
                                      "before: a twin of the best law in another matrix "
                                      "takes no slot)", choices=("matrix", "skeleton"))
    sweep: int = setting(0, "once the basic solution's search ends: every form one "
                            "changed unary operation away from the tuned basic law (one per "
                            "skeleton) is flown this many times, its touched constants and "
                            "the others scaled as the screening does, and the best flight "
                            "of each joins the population (0 = off; default 8 in a "
                            "problem file, 0 for a registered system)", 0, 12)
    sweep_products: int = setting(0, "with `sweep`: the sweep also flies every form one "
                                     "added arc away from the tuned basic law where the arc "
                                     "brings an input, through each unary operation, into a "
                                     "product node it does not feed (a term of one input "
                                     "times a function of another), this many times each; "
                                     "such a form joins the population only when it beats "
                                     "the tuned basic law (0 = off; default 8 in a problem "
                                     "file, 0 for a registered system)", 0, 12)
    sweep_coupling: int = setting(0, "with `sweep`: the sweep also flies every form one "
                                     "added arc away that brings another output's value "
                                     "(its node before the bound), through each unary "
                                     "operation, into a product node of a later output that "
                                     "it does not feed (one control's term times a function "
                                     "of another control: the law switches with the other's "
                                     "sign), this many times each; such a form joins the "
                                     "population only when it beats the tuned basic law "
                                     "(0 = off; a law of one output has none)", 0, 12)
    sweep_tune: int = setting(0, "with `sweep`: the halving tunes the swept forms as soon "
                                 "as they are flown (as it does after a resweep or a change "
                                 "of the input scales), not after the first epoch of the "
                                 "structure search (0 = off)", 0, 1)
    sweep_keep: int = setting(0, "of the swept forms (`sweep`), only this many join the "
                                 "population: the best by the target's value of their best "
                                 "flight (0 = every one)", 0, 10_000)
    resweep: int = setting(0, "with `sweep`: times a stalled structure search (ga "
                              "restart_epochs) sweeps the neighbourhood of its best law, as "
                              "`sweep` does the tuned basic law's, before it restarts: the "
                              "best law becomes the basis, its neighbours are flown and join "
                              "the population, and the halving tunes them at once; a best "
                              "law swept before, or no flights for the sweep and an epoch "
                              "after it, restarts as ever (0 = off)", 0, 100)
    screen: int = setting(0, "new forms screened after every epoch, before the halving: "
                             "each gets `screen_evals` flights of a search over the scale of "
                             "the constants its variations touched (and of the others), and "
                             "the halving ranks the forms by those values (0 = off; with "
                             "`forms` only)", 0, 1_000)
    screen_evals: int = setting(8, "flights per screened form (`screen`): the touched "
                                   "constants and the others times the first of a fixed list "
                                   "of factor pairs", 1, 12)
    polish: float = setting(0.0, "the last share of the flight budget goes to the best law "
                                 "by the target: the structure search stops when only this "
                                 "share of the flights is left (after a running refinement "
                                 "ends) and a fresh CMA-ES on that law's parameters flies the "
                                 "rest (0 = off)", 0.0, 0.9)
    rest: int = setting(0, "when the flights left after an epoch's refinement cannot hold "
                           "one more epoch, the refinement's winner goes on with them (its "
                           "last rung takes the rest; 0 = the GA goes on; with `forms` only)",
                        0, 1)

    def __post_init__(self):
        check_settings(self, "refine.")

    @property
    def active(self) -> bool:
        return bool(self.basis or self.evals)

    def rungs(self, n: int | None = None) -> list:
        """The successive-halving budgets per search (cumulative evaluations) for ``n``
        searches (default ``forms``), the last ``evals``: ``[evals / 2^K, ..., evals / 2,
        evals]`` with 2^K >= n (one rung ``[evals]`` for one search)."""
        n = max(self.forms if n is None else n, 1)
        k = max(0, math.ceil(math.log2(n)))
        return [max(1, self.evals >> (k - i)) for i in range(k + 1)]

    def epoch_evals(self, n: int | None = None) -> int:
        """Evaluations of the refinement after every epoch (at most; searches may stop earlier
        in a rung), with ``n`` searches in the halving (default ``forms``, and then the
        screening's flights too: a whole epoch's refinement)."""
        if not self.forms:
            return self.evals * self.laws
        total, alive, done = 0, n or self.forms, 0
        if n is None:
            total = self.screen * self.screen_evals
        for r in self.rungs(alive):
            total += alive * (r - done)
            alive, done = max(1, math.ceil(alive / 2)), r
        return total

    def patience_for(self, left: int | None, epoch_children: int) -> int:
        """The basis refinement's patience: ``basis_patience`` when the flights ``left`` after
        it (None: no flight budget) cannot hold ``STRUCTURE_EPOCHS`` epochs of the structure
        search (``epoch_children`` children and the refinement after each), else 0."""
        epochs = STRUCTURE_EPOCHS * (epoch_children + self.epoch_evals())
        return self.basis_patience if left is not None and left < epochs else 0


@dataclass
class _Search:
    """One running refinement: the member it started from, its CMA-ES and the best so far."""

    member: int
    cma: CMA
    evals: int
    best_bits: np.ndarray
    best_f: np.ndarray
    best_cv: float
    patience: int = 0             # failed restarts that end the search past its budget
    mark: tuple | None = None     # the CMA-ES's best key at its last restart
    restarts: int = 0
    failed: int = 0               # restarts in a row that did not improve on ``mark``
    cap: int | None = None        # successive halving: the current rung's budget
    alive: bool = True            # successive halving: not dropped at a rung

    def done(self, budget: int) -> bool:
        if not self.alive:
            return True
        if self.cap is not None:
            return self.evals >= self.cap
        return self.evals >= budget and (self.patience == 0 or self.failed >= self.patience
                                         or self.evals >= PATIENCE_CAP * budget)

    def count_restarts(self, gain: float) -> None:
        """After a tell: a new IPOP restart improved the best by the share ``gain`` (resets
        ``failed``) or not."""
        if not self.patience or self.cma.restarts == self.restarts:
            return
        self.restarts = self.cma.restarts
        key = self.cma.best_key
        old = self.mark
        better = old is None or key[0] < old[0] or (key[0] == old[0] and key[1] < old[1]
                                                    - gain * abs(old[1]))
        self.failed = 0 if better else self.failed + 1
        self.mark = key


class Refinement:
    """The CMA-ES searches of one GA run (see the module docstring).

    Parameters
    ----------
    codec : GrayCodec
        The GA's coding of q (candidates are rounded to its grid, kept in its range).
    config : RefineConfig
    target : Target
        The single objective CMA-ES minimises (after the problem's constraints).
    """

    def __init__(self, codec: GrayCodec, config: RefineConfig, target: Target):
        self.codec, self.cfg, self.target = codec, config, target
        self.pool: dict = {}          # structure key -> (CMA, bits of its best q) to continue
        self.searches: list[_Search] | None = None
        self.budget = 0
        self.rungs: list = []         # successive halving: the budgets of the rungs to come

    @property
    def active(self) -> bool:
        return self.searches is not None

    def new_cma(self, q, seed: int) -> CMA:
        p = self.codec
        # x_map: what the Gray code can hold; an IPOP restart after IPOP_STALL generations
        # without a better value, and (``step_restart``) once the step has collapsed
        return CMA(q, self.cfg.sigma, seed, popsize=self.cfg.popsize or None,
                   bounds=(p.lo, p.hi - p.step), x_map=p.grid,
                   restart_sigma=self.cfg.step_restart or None, restart_stall=IPOP_STALL)

    def start(self, picks, budget: int, rng: np.random.Generator, patience: int = 0,
              rungs=None) -> None:
        """Start a refinement of the members ``picks`` (``(index, member, structure key)``,
        or with a fourth item, the bits of a fresh start: a CMA-ES of its own from there),
        ``budget`` evaluations each (then on until ``patience`` IPOP restarts in a row fail to
        improve, if ``patience``); one seed per member is drawn from ``rng``.  With ``rungs``
        (increasing budgets, the last ``budget``): successive halving -- every search runs to
        the first rung, the better half (by the target) on to the next, and so on; a form
        not tuned before starts a CMA-ES of its own (the latest search's step and covariance
        fit another form's gains)."""
        searches = []
        for k, m, key, *fresh in picks:
            seed = int(rng.integers(0, 2 ** 31 - 1))
            if fresh:                  # a fresh start of a new form (``form_starts``)
                searches.append(_Search(k, self.new_cma(self.codec.decode(fresh[0]), seed), 0,
                                        m.bits.copy(), m.f.copy(), m.cv, patience))
                continue
            old = self.pool.pop(key, None)
            q = self.codec.decode(m.bits)
            if old is not None:
                cma = old[0]
            elif self.pool and not (rungs and len(rungs) > 1):
                cma = next(reversed(self.pool.values()))[0].spawn(q, seed)
            else:
                cma = self.new_cma(q, seed)
            searches.append(_Search(k, cma, 0, m.bits.copy(), m.f.copy(), m.cv, patience,
                                    restarts=cma.restarts))
        self.searches, self.budget = searches, budget
        rungs = list(rungs or [])
        self.rungs = rungs[1:] if len(rungs) > 1 and len(searches) > 1 else []
        for s in searches:
            s.cap = rungs[0] if self.rungs else None

    def _promote(self) -> bool:
        """Successive halving at the end of a rung: the better half of the live searches go
        on to the next rung's budget; False when no rung is left."""
        live = [s for s in self.searches if s.alive]
        if not self.rungs or len(live) <= 1:
            return False
        live.sort(key=lambda s: self.target.keys(s.best_f[None, :], [s.best_cv])[0])
        keep = max(1, math.ceil(len(live) / 2))
        cap = self.rungs.pop(0)
        for i, s in enumerate(live):
            s.alive, s.cap = i < keep, cap
        return True

    def ask(self) -> list:
        """``(member index, bits)`` of the next candidates of every search still running."""
        out = []
        for s in self.searches:
            if not s.done(self.budget):
                # a generation's parameters Gray-coded at once (the same bits as law by law)
                out += [(s.member, bits) for bits in self.codec.encode_rows(s.cma.ask_rows())]
        return out

    def tell(self, members) -> bool:
        """The evaluated members of the last :meth:`ask` (``f``, ``cv`` set), same order;
        True when every search is done."""
        i = 0
        for s in self.searches:
            if s.done(self.budget):
                continue
            n = s.cma.popsize
            rows = members[i:i + n]
            # [choice] where the whole budget is this CMA-ES (no epoch fits: ``patience``),
            # it stalls unless it improves by ``stall_gain``: a 1e-9 creep is no progress
            gain = self.cfg.stall_gain if s.patience else 0.0
            s.cma.tell(self.target.keys(np.array([m.f for m in rows]),
                                        [m.cv for m in rows]), stall_gain=gain)
            for m in rows:
                if self.target.better(m.f, s.best_f, m.cv, s.best_cv):
                    s.best_bits, s.best_f, s.best_cv = m.bits.copy(), m.f.copy(), m.cv
            s.evals += n
            s.count_restarts(self.cfg.restart_gain)
            i += n
        while all(s.done(self.budget) for s in self.searches):
            if not self._promote():
                return True
        return False

    def finish(self, pop, key) -> list:
        """End the refinement: ``(member index, bits, f, cv)`` of the members whose refined
        parameters beat their own (the GA replaces them); of several searches on one member
        (``starts``) the best counts.  Every search kept stays in the pool under its member's
        structure (``key(member)``) to continue later; beyond ``4 * laws`` searches the oldest
        go."""
        better, best = [], {}
        for s in self.searches:
            b = best.get(s.member)
            if b is None or self.target.better(s.best_f, b.best_f, s.best_cv, b.best_cv):
                best[s.member] = s
        for s in best.values():
            m = pop[s.member]
            bits = m.bits
            if self.target.better(s.best_f, m.f, s.best_cv, m.cv):
                better.append((s.member, s.best_bits.copy(), s.best_f.copy(), s.best_cv))
                bits = s.best_bits
            self.pool[key(m)] = (s.cma, bits_text(bits))
        while len(self.pool) > max(self.cfg.laws, self.cfg.forms) * 4:
            del self.pool[next(iter(self.pool))]
        self.searches, self.rungs = None, []
        return better

    # -- checkpoint -----------------------------------------------------------------------
    def state(self) -> dict:
        pool = [{"key": k, "cma": c.state(), "b": b} for k, (c, b) in self.pool.items()]
        if self.searches is None:
            return {"pool": pool}
        s = self.searches
        return {"pool": pool, "members": [x.member for x in s], "evals": [x.evals for x in s],
                "budget": self.budget, "cma": [x.cma.state() for x in s],
                "best": [{"b": bits_text(x.best_bits), "f": x.best_f.tolist(), "cv": x.best_cv}
                         for x in s],
                "patience": [[x.patience, x.mark and list(x.mark), x.restarts, x.failed]
                             for x in s],
                "halving": {"rungs": self.rungs, "caps": [x.cap for x in s],
                            "alive": [x.alive for x in s]}}

    def load_state(self, st, q0) -> None:
        st = st or {}
        self.pool = {a["key"]: (self.new_cma(q0, 1).load_state(a["cma"]), a["b"])
                     for a in st.get("pool", [])}
        if "members" not in st:
            self.searches = None
            return
        self.budget = st["budget"]
        patience = st.get("patience") or [[0, None, 0, 0]] * len(st["members"])
        self.searches = [_Search(k, self.new_cma(q0, 1).load_state(c), n, bits_array(b["b"]),
                                 np.array(b["f"], float), float(b.get("cv", 0.0)), pt[0],
                                 pt[1] and tuple(float(v) for v in pt[1]), pt[2], pt[3])
                         for k, n, c, b, pt in zip(st["members"], st["evals"], st["cma"],
                                                   st["best"], patience)]
        halving = st.get("halving") or {}
        self.rungs = list(halving.get("rungs", []))
        for s, cap, alive in zip(self.searches, halving.get("caps", []),
                                 halving.get("alive", [])):
            s.cap, s.alive = cap, alive
