"""Fixed-structure policy search: CMA-ES over the parameters q of one law structure.

A *baseline* is a law structure (the basic law, a polynomial in the controller inputs, a small
tanh network -- :mod:`synthesis.methods.structures`) plus its parameters q; :class:`PolicySearch`
tunes q by CMA-ES (:class:`~synthesis.methods.cma.CMA`) with every candidate flown by the same
evaluator as the network-operator synthesis, so the laws it finds are start values of the same
generic controller FMU and export like any other law (``synthesize --method cma-NAME``).

CMA-ES minimises one number; a multi-objective problem gives it through its
:class:`~synthesis.methods.pareto.Target` (objective ``objective`` subject to objective
``constraint`` < ``limit``), after the problem's constraints.

References
----------
N. Hansen, "The CMA Evolution Strategy: A Tutorial", arXiv:1604.00772.
"""
from __future__ import annotations

import numpy as np

from descent_fmus.synthesis.methods.base import Candidate, Method
from descent_fmus.synthesis.methods.cma import CMA, IPOP_SIGMA, IPOP_STALL
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.pareto import Target

__all__ = ["PolicySearch"]


class PolicySearch(Method):
    """CMA-ES over the parameters q of a fixed law structure (ask/tell, checkpointable).

    Parameters
    ----------
    structure : NetworkOperator
        The law; its q is the start point.
    target : Target
    seed, sigma, scale, popsize, bounds, scale_floor, restart_sigma, restart_stall :
        Options of :class:`~synthesis.methods.cma.CMA` (``sigma`` relative to the scale of
        each q).
    """

    def __init__(self, structure: NetworkOperator, target: Target, seed: int = 1,
                 sigma: float = 0.3, scale=None, popsize: int | None = None,
                 bounds: tuple | None = None, scale_floor: float = 0.1,
                 restart_sigma: float = IPOP_SIGMA, restart_stall: int = IPOP_STALL):
        self.structure = structure
        self.target = target
        self.cma = CMA(structure.q, sigma, seed, scale, popsize, bounds, scale_floor,
                       restart_sigma=restart_sigma, restart_stall=restart_stall)
        self.evaluations = 0
        self.generation = 0
        self.best_law, self.best_f = None, None          # best feasible law and its objectives
        self.history = []            # per generation: (evaluations, best feasible objective)
        self._pending = None

    @property
    def restarts(self) -> int:
        """IPOP restarts so far (:class:`~synthesis.methods.cma.CMA`)."""
        return self.cma.restarts

    @property
    def popsize(self) -> int:
        return self.cma.popsize

    @property
    def sigma(self) -> float:
        return self.cma.sigma

    def ask(self) -> list[Candidate]:
        """Candidate laws of the next CMA-ES generation."""
        if self._pending is None:
            self._pending = [self.structure.with_q([float(v) for v in x])
                             for x in self.cma.ask()]
        return [Candidate(law) for law in self._pending]

    def tell(self, F, cv=None) -> None:
        """Objective rows and violations of the candidates of the last :meth:`ask`."""
        if self._pending is None:
            raise RuntimeError("tell() without a pending ask()")
        F = np.atleast_2d(np.asarray(F, float))
        cv = np.zeros(len(F)) if cv is None else np.asarray(cv, float)
        if len(F) != len(self._pending) or not np.all(np.isfinite(F)) \
                or cv.shape != (len(F),):
            raise ValueError(f"expected {len(self._pending)} finite objective rows, got shape "
                             f"{F.shape}")
        self.cma.tell(self.target.keys(F, cv))
        k = self.target.best(F, cv)
        obj = self.target.objective
        if k is not None and (self.best_f is None or F[k, obj] < self.best_f[obj]):
            self.best_law, self.best_f = self._pending[k], F[k].copy()
        self._pending = None
        self.evaluations += len(F)
        self.generation += 1
        self.history.append((self.evaluations, None if self.best_f is None
                             else float(self.best_f[obj])))

    def status(self) -> dict:
        return {"sigma": f"{self.sigma:.3g}", "restarts": self.restarts}

    @property
    def phase(self) -> str:
        return "CMA-ES over the structure's parameters"

    # -- checkpoint -----------------------------------------------------------------------
    def state(self) -> dict:
        """JSON-serialisable state (the pickled optimiser and its generator, base64)."""
        if self._pending is not None:
            raise RuntimeError("checkpoint only between tell() and ask()")
        return {"cma": self.cma.state(), "evaluations": self.evaluations,
                "generations": self.generation, "restarts": self.restarts,
                "best_law": None if self.best_law is None else self.best_law.to_dict(),
                "best_f": None if self.best_f is None else self.best_f.tolist(),
                "history": self.history}

    def load_state(self, st: dict) -> "PolicySearch":
        """Restore a :meth:`state` of a search with the same structure and options."""
        self.cma.load_state(st["cma"])
        self.evaluations, self.generation = st["evaluations"], st["generations"]
        self.best_law = (None if st["best_law"] is None
                         else NetworkOperator.from_dict(st["best_law"]))
        self.best_f = None if st["best_f"] is None else np.array(st["best_f"], float)
        self.history = [tuple(h) for h in st["history"]]
        self._pending = None
        return self
