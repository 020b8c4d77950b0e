"""A genetic-programming baseline (``synthesize --method gp``): DEAP's stock tree GP, one tree
per controller output, flown through the same evaluator as every other method.

An individual is one expression tree per output of the problem's basic law, over its inputs,
ephemeral constants and the problem's operation set (:mod:`synthesis.methods.gp_trees`: the
network operator's own functions).  Each generation (DEAP's ``eaSimple``): tournament
selection, one-point subtree crossover of pairs (one output's trees) and uniform subtree
mutation, with a static depth limit and the generic controller FMU's capacity as bloat control;
only changed individuals are flown (and compiled: a law is kept by its trees, :data:`LAW_CACHE`).
Every individual is compiled into a
:class:`~synthesis.methods.law.NetworkOperator` law, so the run loop flies, counts, archives and
exports it like the laws of any other method.

The fitness is the problem's CMA-ES target (:func:`synthesis.methods.registry.cma_target`):
``(constraint violation, target scalar)`` compared as tuples.  DEAP draws from Python's
``random`` module; the search keeps its own generator state and swaps it in around every call
into DEAP (and back out), so a seed reproduces a run exactly, also across ``--resume``, and
nothing else in the process sees or disturbs the stream.

References
----------
J.R. Koza, "Genetic Programming", MIT Press 1992 (tournament selection, subtree crossover,
depth limit 17); F.-A. Fortin et al., "DEAP: Evolutionary Algorithms Made Easy", JMLR 13 (2012).
"""
from __future__ import annotations

import contextlib
import functools
import operator
import random
from collections import OrderedDict

import numpy as np
from deap import base, gp, tools

from descent_fmus.synthesis.methods.base import Candidate, Method
from descent_fmus.synthesis.methods.gp_config import GPConfig
from descent_fmus.synthesis.methods.gp_trees import (compile_trees, primitive_set,
                                                     tree_from_tokens, tree_key, tree_to_tokens)
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.law_fmu import CapacityError
from descent_fmus.synthesis.methods.pareto import Target

__all__ = ["GPConfig", "GeneticProgramming"]

#: Attempts at an initial individual that fits the controller before the search gives up.
INIT_ATTEMPTS = 1000
#: Compiled laws kept by their trees (least recently used out first): a converged population
#: varies into trees it has had before, whose law is then not compiled again (the compile is
#: deterministic, so the search is the same with or without it; 4 096 laws of at most 32
#: nodes are a few tens of MB).
LAW_CACHE = 4096


class _Fitness(base.Fitness):
    """(constraint violation, target scalar), both minimised, compared as tuples."""

    weights = (-1.0, -1.0)


class Individual(list):
    """One tree per output, with its fitness and (once compiled) its law."""

    def __init__(self, trees):
        super().__init__(trees)
        self.fitness = _Fitness()
        self.law = None


class GeneticProgramming(Method):
    """DEAP's stock GP over one tree per output (see the module docstring).

    Parameters
    ----------
    template : NetworkOperator
        The problem's basic law: its inputs, outputs, bounds and input scaling are every law's.
    target : Target
        What the fitness minimises.
    config : GPConfig
    unary, binary : sequence of int
        The problem's operation numbers (the primitives).
    seed : int
    generations : int
        The method's own end (0 = none: the run's flight budget ends it).
    """

    def __init__(self, template: NetworkOperator, target: Target, config: GPConfig,
                 unary, binary, seed: int = 1, generations: int = 0):
        self.template, self.target, self.config = template, target, config
        self.generations = int(generations)
        self.pset = primitive_set(template.nx, unary, binary, config.const_range)
        self.toolbox = self._toolbox()
        rng = random.Random(seed)
        self._rng_state = rng.getstate()
        self.population: list = []
        self.generation = self.evaluations = 0
        self.best = None                 # best fitness key so far
        self._pending = None
        self.law_cache = LAW_CACHE
        self._laws: OrderedDict = OrderedDict()      # trees' keys -> law (None: too big)
        self.cache_hits = 0

    def _toolbox(self) -> base.Toolbox:
        c, tb = self.config, base.Toolbox()
        limit = gp.staticLimit(key=operator.attrgetter("height"), max_value=c.max_depth)
        tb.register("expr", gp.genHalfAndHalf, pset=self.pset, min_=1, max_=c.init_depth)
        tb.register("select", tools.selTournament, tournsize=c.tournament)
        tb.register("mate", gp.cxOnePoint)
        tb.register("mutate", gp.mutUniform, pset=self.pset,
                    expr=functools.partial(gp.genFull, min_=0, max_=c.mutation_depth))
        tb.decorate("mate", limit)
        tb.decorate("mutate", limit)
        return tb

    @contextlib.contextmanager
    def _random(self):
        """The search's generator state in Python's ``random`` for DEAP (restored after)."""
        outer = random.getstate()
        random.setstate(self._rng_state)
        try:
            yield
        finally:
            self._rng_state = random.getstate()
            random.setstate(outer)

    # -- individuals ----------------------------------------------------------------------------
    def _fits(self, ind: Individual) -> bool:
        """Compile the individual's law (kept; from the cache if these trees were compiled
        before); False if the controller cannot hold it (the individual's law unchanged)."""
        key = tuple(tree_key(t) for t in ind)
        if key in self._laws:
            self._laws.move_to_end(key)
            self.cache_hits += 1
            law = self._laws[key]
        else:
            try:
                law = compile_trees(list(ind), self.pset, self.template)
            except CapacityError:
                law = None
            if self.law_cache:
                self._laws[key] = law
                if len(self._laws) > self.law_cache:
                    self._laws.popitem(last=False)
        if law is None:
            return False
        ind.law = law
        return True

    def _initial(self) -> list:
        n = len(self.template.outputs)
        pop = []
        for _ in range(self.config.population):
            for _ in range(INIT_ATTEMPTS):
                ind = Individual([gp.PrimitiveTree(self.toolbox.expr()) for _ in range(n)])
                if self._fits(ind):
                    break
            else:
                raise ValueError(f"gp: no initial tree of depth <= {self.config.init_depth} "
                                 f"fits the controller FMU; lower gp.init_depth")
            pop.append(ind)
        return pop

    def _vary(self, child: Individual, k: int, tree) -> None:
        """``child`` with tree ``k`` replaced, if the law still fits (else it stays)."""
        if tree_key(tree) == tree_key(child[k]):     # str(tree) == str(child[k]), cheaper
            return
        old = child[k]
        child[k] = tree
        if self._fits(child):
            del child.fitness.values
        else:                                       # DEAP's staticLimit: keep the parent's
            child[k] = old

    def _offspring(self) -> list:
        """The next generation (``eaSimple``'s select and ``varAnd``), bounded."""
        c, tb, n = self.config, self.toolbox, len(self.template.outputs)
        off = [_clone(ind) for ind in tb.select(self.population, len(self.population))]
        for i in range(1, len(off), 2):
            if random.random() < c.p_crossover:
                k = random.randrange(n)
                t1, t2 = tb.mate(_copy_tree(off[i - 1][k]), _copy_tree(off[i][k]))
                self._vary(off[i - 1], k, t1)
                self._vary(off[i], k, t2)
        for ind in off:
            if random.random() < c.p_mutation:
                k = random.randrange(n)
                (t,) = tb.mutate(_copy_tree(ind[k]))
                self._vary(ind, k, t)
        return off

    # -- ask / tell -------------------------------------------------------------------------------
    def ask(self) -> list[Candidate]:
        """The individuals of the next generation that have no fitness yet, as laws."""
        if self._pending is None:
            with self._random():
                self.population = self._offspring() if self.population else self._initial()
            self._pending = [i for i, ind in enumerate(self.population)
                             if not ind.fitness.valid]
            for i in self._pending:
                if self.population[i].law is None:
                    self._fits(self.population[i])
        return [Candidate(self.population[i].law,
                          {"trees": [str(t) for t in self.population[i]]})
                for i in self._pending]

    def tell(self, F, cv=None) -> None:
        """Objective rows and violations of the laws of the last :meth:`ask`."""
        if self._pending is None:
            raise RuntimeError("tell() without a pending ask()")
        n = len(self._pending)                # 0: no offspring changed (a small population)
        F = np.asarray(F, float).reshape(n, -1) if n else np.zeros((0, 1))
        cv = np.zeros(n) if cv is None else np.asarray(cv, float).reshape(-1)
        if not np.all(np.isfinite(F)) or cv.shape != (n,):
            raise ValueError(f"expected {len(self._pending)} finite objective rows")
        for i, key in zip(self._pending, self.target.keys(F, cv)):
            self.population[i].fitness.values = key
            if self.best is None or key < self.best:
                self.best = key
        self.evaluations += len(self._pending)
        self.generation += 1
        self._pending = None

    def finished(self) -> bool:
        return bool(self.generations) and self.generation >= self.generations

    def status(self) -> dict:
        sizes = [ind.law.size for ind in self.population if ind.law is not None]
        out = {"gen": self.generation}
        if sizes:
            out["nodes"] = f"{np.mean(sizes):.1f}"
        return out

    @property
    def phase(self) -> str:
        return "genetic programming over one tree per output"

    # -- checkpoint -------------------------------------------------------------------------------
    def state(self) -> dict:
        """JSON-serialisable: the generator state, the population's trees and fitnesses."""
        if self._pending is not None:
            raise RuntimeError("checkpoint only between tell() and ask()")
        version, internal, gauss = self._rng_state
        return {"random": [version, list(internal), gauss],
                "population": [{"trees": [tree_to_tokens(t) for t in ind],
                                "fitness": list(ind.fitness.values) if ind.fitness.valid
                                else None} for ind in self.population],
                "generation": self.generation, "evaluations": self.evaluations,
                "best": None if self.best is None else list(self.best)}

    def load_state(self, st: dict) -> "GeneticProgramming":
        """Restore a :meth:`state` of a search built with the same settings and problem."""
        version, internal, gauss = st["random"]
        self._rng_state = (version, tuple(internal), gauss)
        self.population = []
        for rec in st["population"]:
            ind = Individual([tree_from_tokens(t, self.pset) for t in rec["trees"]])
            if rec["fitness"] is not None:
                ind.fitness.values = tuple(rec["fitness"])
            self.population.append(ind)
        self.generation, self.evaluations = st["generation"], st["evaluations"]
        self.best = None if st["best"] is None else tuple(st["best"])
        self._pending = None
        return self


def _copy_tree(tree) -> gp.PrimitiveTree:
    return gp.PrimitiveTree(list(tree))


def _clone(ind: Individual) -> Individual:
    """A copy with its own trees (the nodes are shared: DEAP never changes a node), fitness
    and law."""
    new = Individual([_copy_tree(t) for t in ind])
    if ind.fitness.valid:
        new.fitness.values = ind.fitness.values
    new.law = ind.law
    return new
