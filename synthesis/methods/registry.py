"""The synthesis methods by name: ``synthesize --method NAME``.

Built in: ``network-operator`` (the variational GA with CMA-ES refinement,
:class:`~synthesis.methods.variational_ga.VariationalGA`) and the family ``cma-<structure>``
(CMA-ES over the parameters of one of the problem's fixed structures,
:class:`~synthesis.methods.policy_search.PolicySearch`) and ``gp`` (a genetic-programming
baseline, :class:`~synthesis.methods.gp.GeneticProgramming`).  Adding a method is one class (a
:class:`~synthesis.methods.base.Method`) and one :func:`register` call.

A method is built from a problem (read by duck typing: its basic law, recipe, target and
baselines), so methods know no system and import no problem module.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from descent_fmus.synthesis.methods.base import Method

__all__ = ["MethodEntry", "register", "unregister", "method_names", "make_method",
           "UnknownMethodError", "NETWORK_OPERATOR", "GP", "baseline_structures", "cma_target"]

NETWORK_OPERATOR = "network-operator"
GP = "gp"


class UnknownMethodError(ValueError):
    """No method of that name applies to the problem."""


@dataclass(frozen=True)
class MethodEntry:
    """A registered method, or a family of them.

    Attributes
    ----------
    name : str
        The method's name, or a family's prefix ending in ``-`` (e.g. ``"cma-"``).
    build : callable
        ``build(problem, variant) -> Method``; ``variant`` is the name after a family's prefix
        (None for a single method).
    variants : callable, optional
        ``variants(problem) -> list of str``: a family's members for that problem.
    needs_flights : bool
        The method has no end of its own: a run needs a flight budget.
    summary : str
    """

    name: str
    build: Callable
    variants: Callable | None = None
    needs_flights: bool = False
    summary: str = ""


_ENTRIES: dict = {}


def register(entry: MethodEntry) -> None:
    """Add a method (a later entry of the same name replaces the earlier one)."""
    _ENTRIES[entry.name] = entry


def unregister(name: str) -> None:
    _ENTRIES.pop(name, None)


def _names(problem) -> dict:
    out = {}
    for e in _ENTRIES.values():
        if e.variants is None:
            out[e.name] = (e, None)
        else:
            for v in e.variants(problem):
                out[e.name + v] = (e, v)
    return out


def method_names(problem) -> list:
    """The methods that apply to ``problem``."""
    return list(_names(problem))


def entry_of(name: str, problem) -> MethodEntry:
    names = _names(problem)
    if name not in names:
        raise UnknownMethodError(f"unknown method {name!r} for problem {problem.name}; "
                                 f"available: {', '.join(names)}")
    return names[name][0]


def make_method(name: str, problem) -> Method:
    """The method ``name`` built for ``problem`` (UnknownMethodError if it does not apply)."""
    entry_of(name, problem)
    entry, variant = _names(problem)[name]
    return entry.build(problem, variant)


# -- the built-in methods ------------------------------------------------------------------------
def _network_operator(problem, variant=None) -> Method:
    from descent_fmus.synthesis.methods.encoding import GrayCodec, StructureCodec
    from descent_fmus.synthesis.methods.variational_ga import VariationalGA
    basic = problem.basic()
    ib, fb, lo, hi = problem.q_bits
    structure = StructureCodec(basic.size, basic.nx + len(basic.q), problem.unary,
                               problem.binary)
    uses_target = problem.refine.active or problem.ga.basis_rule == "target"
    return VariationalGA(GrayCodec(len(basic.q), ib, fb, lo, hi), basic.q,
                         np.random.default_rng(problem.budget.seed), problem.ga, structure,
                         basic.psi, basic.with_structure,
                         target=cma_target(problem) if uses_target else None,
                         refine=problem.refine, generations=problem.budget.generations,
                         flights=problem.budget.flights)


def baseline_structures(problem) -> dict:
    """The problem's fixed structures (its own, else the defaults built from its basic law's
    inputs and outputs: :func:`synthesis.methods.structures.default_baselines`)."""
    if problem.baselines is not None:
        return problem.baselines()
    from descent_fmus.synthesis.methods.structures import default_baselines
    return default_baselines(problem.basic())


def cma_target(problem):
    """What CMA-ES minimises for ``problem``: its target, else its first objective (after its
    constraints)."""
    from descent_fmus.synthesis.methods.pareto import Target
    return problem.target if problem.target is not None else Target(0)


def _policy_search(problem, variant) -> Method:
    from descent_fmus.synthesis.methods.policy_search import PolicySearch
    return PolicySearch(baseline_structures(problem)[variant], cma_target(problem),
                        seed=problem.budget.seed)


def _genetic_programming(problem, variant=None) -> Method:
    from descent_fmus.synthesis.methods.gp import GeneticProgramming
    return GeneticProgramming(problem.basic(), cma_target(problem), problem.gp, problem.unary,
                              problem.binary, seed=problem.budget.seed,
                              generations=problem.budget.generations)


register(MethodEntry(NETWORK_OPERATOR, _network_operator,
                     summary="the variational GA of the network operator (structure and "
                             "parameters), with CMA-ES refinement of promising laws"))
register(MethodEntry("cma-", _policy_search, variants=lambda p: list(baseline_structures(p)),
                     needs_flights=True,
                     summary="CMA-ES over the parameters of one fixed law structure"))
register(MethodEntry(GP, _genetic_programming,
                     summary="genetic programming (DEAP): one tree per output over the "
                             "problem's operations, compiled into network-operator laws"))
