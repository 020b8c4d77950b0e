"""The structure search's own steps beside the lab's variational GA (a mixin of
:class:`~synthesis.methods.variational_ga.VariationalGA`): which forms are promising enough to
have their parameters tuned (successive halving: :mod:`synthesis.methods.refinement`), when
the search has stalled and restarts around its best law, and the statistics of a run
(evaluations per phase, how many beat the best law).  docs/methods/network_operator.md records
each choice with its measurement.
"""
from __future__ import annotations

import numpy as np

__all__ = ["FormSearch", "RESTART_GAIN"]

#: [choice] an epoch whose best law beats the best at the last mark by less than this share
#: counts as a stalled one (``restart_epochs``)
RESTART_GAIN = 1e-3


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

    def _promising(self, n: int) -> list:
        """The ``n`` best members by the target with distinct structures; with ``forms``, also
        distinct objectives (two members with equal objectives most often fly one law) and,
        after the best member, only forms whose parameters were not tuned before (new
        forms).  With ``pick = 'spread'`` the new forms after the best member are taken at
        evenly spaced ranks of all the eligible ones (the first of them, then on down the
        order) instead of the top ones: a new form is judged with its parents' parameters,
        tuned for another form."""
        picks, seen, values = [], set(), set()
        forms = self.refine_cfg.forms
        spread = forms and self._spread_picks()
        for k in self.target.order(self.F, self.CV):
            if len(picks) >= n and not spread:
                break
            m = self.pop[int(k)]
            key, f = self._structure_key(m), (m.cv, *m.f.tolist())
            if key in seen or (forms and (f in values or (picks and key in
                                                         self.refinement.pool))):
                continue
            seen.add(key)
            values.add(f)
            picks.append(int(k))
        if spread and len(picks) > n:
            rest = picks[1:]
            ranks = np.floor(np.arange(n - 1) * len(rest) / (n - 1)).astype(int)
            picks = [picks[0]] + [rest[int(r)] for r in ranks]
        picks = picks[:n]
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

    def _stalled(self, best) -> bool:
        """Whether the best law by the target has not improved for ``restart_epochs`` epochs
        (then counted from 0 again)."""
        if not self.cfg.restart_epochs or self.target is None:
            return False
        key = self.target.keys(best.f[None, :], [best.cv])[0]
        mark = self.stats.get("restart_mark")
        if mark is None or key[0] < mark[0] or (key[0] == mark[0] and key[1] < mark[1]
                                                  - RESTART_GAIN * abs(mark[1])):
            self.stats["restart_mark"], self.stats["stall"] = list(key), 0
            return False
        self.stats["stall"] = self.stats.get("stall", 0) + 1
        if self.stats["stall"] < self.cfg.restart_epochs:
            return False
        self.stats["stall"] = 0
        return True

    def _restart(self, members, best) -> None:
        """A restart of the structure search around the best law: every member off the Pareto
        set gets new random variations and parameters drawn as the initial population's (half
        at random, half the basis's with a few bits flipped)."""
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
        self.stats["restarts"] = self.stats.get("restarts", 0) + 1
