"""The structure search's own steps beside the lab's variational GA (a mixin of
:class:`~synthesis.methods.variational_ga.VariationalGA`): which forms are promising enough to
have their parameters tuned (successive halving: :mod:`synthesis.methods.refinement`), when
the search has stalled and restarts around its best law, and the statistics of a run
(evaluations per phase, how many beat the best law).  docs/methods/network_operator.md records
each choice with its measurement.
"""
from __future__ import annotations

import numpy as np

from descent_fmus.synthesis.methods.form_algebra import (form_skeleton, preserving_constants,
                                                        touched_constants, upstream)
from descent_fmus.synthesis.methods.pareto import dominance_counts

__all__ = ["FormSearch", "ISLAND_EPOCHS", "SCREEN_FACTORS", "form_skeleton",
           "preserving_constants", "touched_constants", "upstream"]

#: [choice] a new island is started only when the flights left hold this many epochs of the
#: structure search (docs/methods/network_operator.md, "islands")
ISLAND_EPOCHS = 3
#: [choice] the screening's moves, in this order (the first ``screen_evals`` are flown): the
#: constants a form's variations touched times the first factor, the others times the second.
#: What a new form's inherited constants most often miss is their scale (an operation put on
#: an arc, ssqrt(q x) for q x, wants other gains), and the rest of the law its balance with
#: them (mintime-di's switching form from its tuned linear parent: touched x 64, the rest x 4):
#: decades of the touched ones both ways first, then both grown, a sign flip, finer steps
#: (docs/methods/network_operator.md, "Screening new forms")
SCREEN_FACTORS = ((4.0, 1.0), (0.25, 1.0), (16.0, 1.0), (1 / 16, 1.0), (8.0, 2.0),
                  (16.0, 2.0), (64.0, 4.0), (-1.0, 1.0), (2.0, 1.0), (64.0, 1.0), (32.0, 4.0),
                  (0.5, 0.5))


class FormSearch:
    """Mixed into the variational GA: uses its ``pop``, ``F``, ``CV``, ``target``, ``cfg``,
    ``refine_cfg``, ``stats`` and ``_structure_key``."""

    def _count(self, phase: str, members) -> None:
        """The search's statistics (:attr:`stats`): evaluations per phase, and how many of
        them beat the population's best law by the target; of the children, how many have a
        structure no member had before in this process (``children_new_form``) and how many
        of those beat the best law (``children_new_form_better``)."""
        st = self.stats
        st[phase] = st.get(phase, 0) + len(members)
        new = self._new_forms(members) if phase == "children" else [False] * len(members)
        if self.target is None or not self.pop:
            return
        k = int(self.target.order(self.F, self.CV)[0])
        best = self.pop[k]
        wins = [self.target.better(m.f, best.f, m.cv, best.cv) for m in members]
        st[phase + "_better"] = st.get(phase + "_better", 0) + int(sum(wins))
        if phase == "children":
            st["children_new_form_better"] = st.get("children_new_form_better", 0) + int(
                sum(w and n for w, n in zip(wins, new)))

    def _new_forms(self, members) -> list:
        """Whether each member's structure is one not seen before (counted in
        ``children_new_form``); the structures of the population count as seen.  The set
        of seen structures is not in the checkpoint: after a resume it starts again from
        the population's (a statistic only; the search does not read it)."""
        seen = self.__dict__.setdefault("_seen_forms", set())
        if not seen:
            seen.update(self._structure_key(m) for m in self.pop)
        out = []
        for m in members:
            key = self._structure_key(m)
            out.append(key not in seen)
            seen.add(key)
        self.stats["children_new_form"] = self.stats.get("children_new_form", 0) + sum(out)
        return out

    def _new_weights(self, child, parent) -> None:
        """With weighted arcs on (``weighted_arcs``): the constants that ``child``'s form reads
        and ``parent``'s does not start at the grid value nearest 0 (a weighted arc's own
        weight: the child starts as its parent).  Costs no flights."""
        if not self.cfg.weighted_arcs or self.structure is None:
            return
        codec, nx = self.params, self.structure.n_sources - self.params.n
        old, new = self.matrix(parent), self.matrix(child)
        fresh = [c for c in range(codec.n)
                 if new[nx + c, nx + c + 1:].any() and not old[nx + c, nx + c + 1:].any()]
        if fresh:
            q, zero = codec.decode(child.bits), codec.grid([0.0])[0]
            for c in fresh:
                q[c] = zero
            child.bits = codec.encode(q)
            self.stats["new_weights"] = self.stats.get("new_weights", 0) + 1

    def _morph(self, child, parent) -> None:
        """A child of another form than ``parent`` takes function-preserving constants
        (``morph`` probe points; :func:`preserving_constants` on the constants its change
        touched): it starts where its parent is.  Costs no flights."""
        n, codec = self.cfg.morph, self.params
        if not n or self.structure is None:
            return
        psi0, psi = self.matrix(parent), self.matrix(child)
        if np.array_equal(psi0, psi):
            return
        idx = touched_constants(psi0, psi, self.structure.n_sources - codec.n, codec.n)
        q = codec.decode(child.bits)
        mom, kid = self.decode(psi0, q), self.decode(psi, q)
        if not idx or not hasattr(kid, "raw_points"):
            return
        from descent_fmus.synthesis.methods.structures import probe_inputs
        q = preserving_constants(mom, kid, idx, probe_inputs(mom, n), codec.lo,
                                 codec.hi - codec.step)
        child.bits = codec.encode(q)
        self.stats["morphed"] = self.stats.get("morphed", 0) + 1

    def _screen_members(self) -> list:
        """The screening's candidates (``screen``): up to ``screen`` new forms (the eligible
        ones of :meth:`_promising` after the best member; more of them: at evenly spaced ranks,
        since their untuned values say little), each with the constants its variations touched
        (:func:`touched_constants`, against the basis) and the others times each of the first
        ``screen_evals`` pairs of :data:`SCREEN_FACTORS` (a touched constant at 0 as if it
        were 1).  Reads
        no random numbers; the member indices are kept for :meth:`_finish_screen`."""
        cfg, codec = self.refine_cfg, self.params
        self._screen_k = []
        if not (cfg.forms and cfg.screen) or self.structure is None or self.target is None:
            return []
        forms = self._eligible()[1:]
        if len(forms) > cfg.screen:
            forms = [forms[int(r)] for r in np.floor(np.arange(cfg.screen) * len(forms)
                                                     / cfg.screen)]
        out = []
        for k in forms:
            rows = self._scaled_rows(self.pop[k], cfg.screen_evals)
            out += rows
            self._screen_k += [k] * len(rows)
        return out

    def _scaled_rows(self, m, n: int) -> list:
        """Copies of member ``m`` with the constants its variations touched (against the
        basis, :func:`touched_constants`) and the others times each of the first ``n`` pairs
        of :data:`SCREEN_FACTORS` (a touched constant at 0 as if it were 1); none when its
        change touches no constant."""
        codec = self.params
        nx = self.structure.n_sources - codec.n
        idx = touched_constants(self.psi0, self.matrix(m), nx, codec.n)
        if not idx:
            return []
        q = np.array(codec.decode(m.bits))
        base = np.where(q[idx] == 0.0, 1.0, q[idx])
        rest = np.setdiff1d(np.arange(codec.n), idx)
        out = []
        for touched, others in SCREEN_FACTORS[:n]:
            q2 = q.copy()
            q2[idx], q2[rest] = base * touched, q[rest] * others
            out.append(type(m)(list(m.variations), codec.encode(q2)))
        return out

    def _finish_screen(self, members) -> None:
        """Each screened member takes the best of its flights when it beats its own value
        (then the halving ranks the forms by these values)."""
        for k, m in zip(self._screen_k, members):
            old = self.pop[k]
            if self.target.better(m.f, old.f, m.cv, old.cv):
                self.pop[k] = m
        self.stats["screened_forms"] = self.stats.get("screened_forms", 0) + len(
            set(self._screen_k))
        self.lh = dominance_counts(self.F, self.CV)
        self._screen_k = []

    def _eligible(self, n: int | None = None, spread: bool = False) -> list:
        """Member indices in the target's order with distinct structures; with ``forms``, also
        distinct objectives and, after the first, only structures not tuned before; at most
        ``n`` unless ``spread``."""
        picks, seen, values = [], set(), set()
        forms = self.refine_cfg.forms
        skeletons = forms and self.refine_cfg.distinct == "skeleton"
        for k in self.target.order(self.F, self.CV):
            if n is not None and len(picks) >= n and not spread:
                break
            m = self.pop[int(k)]
            key, f = self._structure_key(m), (m.cv, *m.f.tolist())
            if key in seen or (forms and (f in values or (picks and key in
                                                         self.refinement.pool))):
                continue
            if skeletons:
                sk = self._skeleton(m)
                if picks and (sk in seen or sk in self.tuned_skeletons):
                    continue
                seen.add(sk)
            seen.add(key)
            values.add(f)
            picks.append(int(k))
        return picks

    @property
    def tuned_skeletons(self) -> set:
        """The skeletons of the forms the halving tuned (``distinct = 'skeleton'``; in the
        checkpoint)."""
        return self.__dict__.setdefault("_tuned_skeletons", set())

    def _skeleton(self, m) -> str:
        """:func:`form_skeleton` of member ``m``'s law (its matrix key when the decoded law
        has no matrix)."""
        law = self.decode(self.matrix(m), self.params.decode(m.bits))
        if not hasattr(law, "outputs"):
            return self._structure_key(m)
        return form_skeleton(law.psi, law.nx, len(law.q), law.outputs)

    def _promising(self, n: int) -> list:
        """The ``n`` best members by the target with distinct structures; with ``forms``, also
        distinct objectives (two members with equal objectives most often fly one law) and,
        after the best member, only forms whose parameters were not tuned before (new
        forms).  With ``pick = 'spread'`` the new forms after the best member are taken at
        evenly spaced ranks of all the eligible ones (the first of them, then on down the
        order) instead of the top ones: a new form is judged with its parents' parameters,
        tuned for another form."""
        forms = self.refine_cfg.forms
        spread = forms and self._spread_picks()
        picks = self._eligible(n, spread)
        if spread and len(picks) > n:
            rest = picks[1:]
            ranks = np.floor(np.arange(n - 1) * len(rest) / (n - 1)).astype(int)
            picks = [picks[0]] + [rest[int(r)] for r in ranks]
        picks = picks[:n]
        if forms and self.refine_cfg.distinct == "skeleton":
            self.tuned_skeletons.update(self._skeleton(self.pop[k]) for k in picks)
        if forms:
            self.stats["new_form_picks"] = [self._structure_key(self.pop[k])
                                            for k in picks[1:]]
        return picks

    def _spread_picks(self) -> bool:
        """Whether this epoch's halving spreads its new forms (``pick``): always ('spread'),
        never ('best'), or ('adaptive') when the best law now is none of the new forms the
        last halving tuned (they did not win: look further down the order); the first
        halving takes the top ones."""
        pick = self.refine_cfg.pick
        if pick != "adaptive":
            return pick == "spread"
        last = self.stats.get("new_form_picks")
        if not last or self.target is None:
            return False
        best = self.pop[int(self.target.order(self.F, self.CV)[0])]
        spread = self._structure_key(best) not in last
        self.stats["spread_epochs"] = self.stats.get("spread_epochs", 0) + int(spread)
        return spread

    def _fresh_starts(self, starts: list) -> list:
        """``starts`` (``(index, member, structure key)``) with ``form_starts - 1`` fresh
        starts (random bits, as the initial population's) after each new form's own: a new
        form needs other constants than the ones it inherited, and one CMA-ES from them may
        settle in their basin."""
        extra = self.refine_cfg.form_starts - 1
        if extra <= 0:
            return starts
        out = []
        for k, m, key in starts:
            out.append((k, m, key))
            if key not in self.refinement.pool:
                out += [(k, m, key, self.rng.integers(0, 2, self.params.n_bits).astype(np.uint8))
                        for _ in range(extra)]
        return out

    def _rest(self, n: int) -> int:
        """The flights the winner of this epoch's refinement (``n`` searches) gets beyond its
        last rung (``rest``): the flights left after the refinement, when they cannot hold
        one more epoch (its children and refinement), else 0."""
        cfg = self.refine_cfg
        if not cfg.rest or not self.flights:
            return 0
        left = self.flights - self.evaluations - cfg.epoch_evals(n)
        epoch = self.cfg.epoch * 4 * self.cfg.crossovers + cfg.epoch_evals()
        return max(0, left) if left < epoch else 0

    def _log_epoch(self, k: int) -> None:
        """One row of ``stats["epochs"]`` at every epoch (member ``k`` the best law by the
        target): generation, evaluations, the best law's target value, the population's
        diversity (distinct structures, the share of members with the best law's structure,
        the mean number of matrix entries in which a member differs from the best law's) and
        the children flown and accepted into the population since the previous epoch.  Reads
        no random numbers: a run with the log is the run without it."""
        st, pop = self.stats, self.pop
        best = self.matrix(pop[k])
        keys = [self._structure_key(m) for m in pop]
        dist = [int(np.count_nonzero(self.matrix(m) != best)) for m in pop]
        log = st.setdefault("epochs", [])
        last = log[-1] if log else {"children": 0, "accepted": 0}
        log.append({"gen": int(self.generation), "evals": int(self.evaluations),
                    "best": float(pop[k].f[self.target.objective]),
                    "forms": len(set(keys)),
                    "share_best": round(keys.count(keys[k]) / len(pop), 4),
                    "dist": round(float(np.mean(dist)), 3),
                    "children": st.get("children", 0) - last.get("children_total", 0),
                    "accepted": st.get("accepted", 0) - last.get("accepted_total", 0),
                    "children_total": st.get("children", 0),
                    "accepted_total": st.get("accepted", 0),
                    "restarts": st.get("restarts", 0),
                    "islands": st.get("islands", 0)})

    def _stalled(self, best) -> bool:
        """Whether the best law by the target has not improved for ``restart_epochs`` epochs
        (then counted from 0 again)."""
        if not self.cfg.restart_epochs or self.target is None:
            return False
        key = self.target.keys(best.f[None, :], [best.cv])[0]
        mark = self.stats.get("restart_mark")
        if mark is None or key[0] < mark[0] or (key[0] == mark[0] and key[1] < mark[1]
                                                  - self.cfg.stall_gain * abs(mark[1])):
            self.stats["restart_mark"], self.stats["stall"] = list(key), 0
            return False
        self.stats["stall"] = self.stats.get("stall", 0) + 1
        if self.stats["stall"] < self.cfg.restart_epochs:
            return False
        self.stats["stall"] = 0
        return True

    def _restart(self, members, best) -> list:
        """The members of the next epoch after a stall (``restart_from``): ``'best'``, every
        member off the Pareto set gets new random variations and parameters drawn as the
        initial population's (half at random, half the best law's with a few bits flipped);
        ``'islands'``, :meth:`_next_island`."""
        if self.cfg.restart_from == "islands":
            island = self._next_island(best)
            if island is not None:
                self.stats["restarts"] = self.stats.get("restarts", 0) + 1
            return members if island is None else island
        self.stats["restarts"] = self.stats.get("restarts", 0) + 1
        rng, n_bits = self.rng, self.params.n_bits
        for i, (m, lh) in enumerate(zip(members[1:], self.lh[1:])):
            if lh > 0:
                m.variations = [self.structure.random(rng) for _ in range(self._lchr)]
                if i % 2:
                    m.bits = rng.integers(0, 2, n_bits).astype(np.uint8)
                else:
                    m.bits = best.bits.copy()
                    for k in rng.integers(0, n_bits, 1 + int(rng.integers(0, 4))):
                        m.bits[k] ^= 1
        return members

    def _next_island(self, best) -> list:
        """Islands in turn: when the stalled population's best law ``best`` is the run's best
        (no island running, or the island beat the law it left), that law is kept aside and a
        new population is drawn from the tuned basic solution as the initial one was (new
        structure draws: another basin); when an island stalls below the law kept aside, the
        search goes back to that law (a population drawn around it).  The stall mark starts
        again with the new population.  None (no restart) when a new island is due but the
        flights left cannot hold ``ISLAND_EPOCHS`` epochs: an island needs room to grow."""
        elite = self._elite
        if elite is None or not self.target.better(elite["f"], best.f, elite["cv"], best.cv):
            if not self._island_room():
                return None
            self._elite = {"psi": self._stalled_matrix(best), "bits": best.bits.copy(),
                           "f": best.f.copy(), "cv": best.cv}
            psi, bits = self._island_centre(best)
            self.stats["islands"] = self.stats.get("islands", 0) + 1
        else:
            psi, bits = elite["psi"], elite["bits"]
            self._elite = None
        self.psi0 = np.array(psi, dtype=int)
        self.q0 = self.params.decode(bits)
        members = self._initial_members()
        members[0].bits = bits.copy()
        self.stats["restart_mark"], self.stats["stall"] = None, 0
        return members

    def _island_centre(self, best) -> tuple:
        """``(matrix, bits)`` a new island is drawn around (``island_from``): the tuned basic
        solution ('basic'); that solution's matrix with ``island_variations`` (0: ``lchr``)
        random variations applied, drawn anew for each island, and its bits ('varied':
        another form near the basic law each time); or the member of the stalled
        population's Pareto set whose matrix is farthest from the best law's ('archive': a
        second form already flown, tuned with the population; the basic solution when there
        is none)."""
        psi, bits = self._origin
        how = self.cfg.island_from
        if how == "varied" and self._lchr:
            n = self.cfg.island_variations or self._lchr
            var = [self.structure.random(self.rng) for _ in range(n)]
            return self.structure.apply(np.array(psi, dtype=int), var), bits
        if how == "archive":
            ref = self._stalled_matrix(best)
            far, pick = 0, None
            for k in np.flatnonzero(self.lh == 0):
                m = self.pop[int(k)]
                mat = self._stalled_matrix(m)
                d = int(np.count_nonzero(mat != ref))
                if d > far:
                    far, pick = d, (mat, m.bits.copy())
            if pick is not None:
                self.stats["island_archive"] = self.stats.get("island_archive", 0) + 1
                return pick
        return psi, bits

    def _stalled_matrix(self, member):
        """``member``'s matrix in the stalled population: its variations applied to that
        population's basis (``_epoch_psi``, kept by the epoch before the basis moves to the
        best law's matrix; re-applying a variation list to its own result is not always the
        same matrix: 138 of 20 000 random 8-variation lists of parking.toml's basic matrix)."""
        base = getattr(self, "_epoch_psi", None)
        return self.structure.apply(self.psi0 if base is None else base, member.variations)

    def _island_over(self, best) -> bool:
        """Whether an island running below the law kept aside must give the flights left to
        that law: they no longer hold ``ISLAND_EPOCHS`` epochs (the last epochs go to the
        best basin found)."""
        e = self._elite
        return e is not None and not self._island_room() and self.target.better(
            e["f"], best.f, e["cv"], best.cv)

    def _island_room(self) -> bool:
        """Whether the flights left (none counted: yes) hold ``ISLAND_EPOCHS`` epochs of the
        structure search (each its children and the refinement after it)."""
        return self._room(ISLAND_EPOCHS)

    def _room(self, epochs: int, spend: int = 0) -> bool:
        """Whether the flights left after ``spend`` more (none counted: yes) hold ``epochs``
        epochs of the structure search (each its children and the refinement after it)."""
        if not self.flights:
            return True
        epoch = self.cfg.epoch * 4 * self.cfg.crossovers + self.refine_cfg.epoch_evals()
        return self.flights - self.evaluations - spend >= epochs * epoch

    def _island_state(self) -> dict:
        """The islands' part of the checkpoint."""
        from descent_fmus.synthesis.methods.encoding import bits_text
        o, e = self._origin, self._elite
        return {"origin": None if o is None else [o[0].tolist(), bits_text(o[1])],
                "elite": None if e is None else {"psi": np.asarray(e["psi"]).tolist(),
                                                 "b": bits_text(e["bits"]),
                                                 "f": e["f"].tolist(), "cv": e["cv"]}}

    def _load_island_state(self, st: dict) -> None:
        from descent_fmus.synthesis.methods.encoding import bits_array
        o, e = st.get("origin"), st.get("elite")
        self._origin = None if o is None else (np.array(o[0], dtype=int), bits_array(o[1]))
        self._elite = None if e is None else {"psi": np.array(e["psi"], dtype=int),
                                              "bits": bits_array(e["b"]),
                                              "f": np.array(e["f"], float), "cv": e["cv"]}
