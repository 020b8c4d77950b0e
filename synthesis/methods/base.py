"""The method interface: every synthesis method is a small ask/tell object.

A method proposes candidate laws (:meth:`Method.ask`) and learns their objective rows and
constraint violations (:meth:`Method.tell`); the one run loop (:mod:`synthesis.run.loop`)
evaluates the candidates, keeps the run's archive, spends the budget, checkpoints, handles
signals and writes the report.  A method never knows which backend flies its candidates, and
a backend never knows which method asks.

Anchors: pymoo's ``Algorithm`` (ask/tell, ``has_next``), python-control's problem / solve /
result objects.
"""
from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import Any, Mapping

__all__ = ["Candidate", "Method"]


@dataclass(frozen=True)
class Candidate:
    """A law to evaluate, and what the method reports with it.

    Attributes
    ----------
    law : object
        The candidate (a :class:`~synthesis.methods.law.NetworkOperator` for every method of
        a synthesis run).
    info : mapping
        JSON-able facts the method reports with the law if it reaches the Pareto set (e.g. the
        variations of the basic solution it was built from).
    """

    law: Any
    info: Mapping = field(default_factory=dict)


class Method(abc.ABC):
    """An ask/tell search over laws (see the module docstring).

    Subclasses implement :meth:`ask`, :meth:`tell`, :meth:`state` and :meth:`load_state`, and
    keep the counters :attr:`generation` and :attr:`evaluations` up to date.
    """

    #: generations finished (what ``--generations`` and a checkpoint count)
    generation: int = 0
    #: candidates told so far
    evaluations: int = 0

    @abc.abstractmethod
    def ask(self) -> list[Candidate]:
        """The candidates to evaluate next."""

    @abc.abstractmethod
    def tell(self, F, cv) -> None:
        """Objective rows ``F`` (n x m, finite) and total constraint violations ``cv`` (n,
        >= 0; 0 = feasible) of the candidates of the last :meth:`ask`, same order."""

    def at_boundary(self) -> bool:
        """Whether the method stands between two steps: :meth:`state` may be taken and the run
        may stop here (default: after every :meth:`tell`)."""
        return True

    def finished(self) -> bool:
        """The method's own end (e.g. its generations are done); the run loop also ends on
        its flight and time budgets."""
        return False

    @abc.abstractmethod
    def state(self) -> dict:
        """JSON-serialisable state; :meth:`load_state` of it continues exactly as an
        uninterrupted run (only asked for at a boundary)."""

    @abc.abstractmethod
    def load_state(self, state: dict) -> "Method":
        """Restore a :meth:`state` of a method built with the same settings."""

    def status(self) -> dict:
        """A few fields for the progress bar (e.g. the generation, CMA-ES's step size)."""
        return {}

    @property
    def phase(self) -> str:
        """What the method is doing, in a few words (the run announces each change)."""
        return "searching"
