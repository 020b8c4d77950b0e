"""The objective and constraint functions of a problem file: expressions of a flight's signals
(:mod:`synthesis.problems.expressions`), aggregated over the initial states.  Everything here
pickles (the problem is sent to the worker processes)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from descent_fmus.synthesis.problems.contract import AGGREGATES
from descent_fmus.synthesis.problems.expressions import Expression

__all__ = ["FileObjective", "FileObjectives", "FlightExpression"]


@dataclass(frozen=True)
class FlightExpression:
    """One expression evaluated on one flight: each of its reductions (``final`` from the
    plant's final outputs, ``initial`` from the outputs the loop read at t = 0 when it read
    them there, the others from the recorded signals), plus ``unmet_stop_penalty`` for a
    flight the stop condition never ended."""

    expression: Expression
    law_outputs: tuple        # (signal name "u1", controller output "u[1]") pairs
    has_stop: bool = False
    unmet_stop_penalty: float = 0.0

    def __call__(self, r) -> float:
        expr, law = self.expression, dict(self.law_outputs)
        special = {"tf": r.t_final, "stopped": 1.0 if r.stopped else 0.0}
        values = []
        for k, term in enumerate(expr.terms):
            if term.function == "final":
                point = {s: _final(r, s, law) for s in term.signals}
                values.append(expr.at_point(k, point, special))
            elif term.function == "initial" and all(s in r.initial for s in term.signals):
                values.append(expr.at_point(k, {s: r.initial[s] for s in term.signals}, special))
            else:
                recorded = {s: _recorded(r, s, law) for s in term.signals}
                values.append(expr.reduce(k, np.asarray(r.time, dtype=float), recorded,
                                          special))
        v = expr.evaluate(values, special)
        if self.has_stop and not r.stopped and self.unmet_stop_penalty:
            v += self.unmet_stop_penalty
        return v


def _recorded(r, name: str, law: dict) -> np.ndarray:
    """Signal ``name`` at every communication point of flight ``r`` (empty if not recorded)."""
    x = r.outputs.get("ctrl." + law[name] if name in law else name, ())
    return np.asarray(x, dtype=float)


def _final(r, name: str, law: dict) -> float:
    """Signal ``name`` at the end of flight ``r``: a plant output from the plant's final
    outputs, a law output from its recording (NaN if none)."""
    if name in law:
        x = r.outputs.get("ctrl." + law[name], ())
        return float(x[-1]) if len(x) else math.nan
    return float(r.final[name])


@dataclass(frozen=True)
class FileObjective:
    name: str
    flight: FlightExpression
    over: str


@dataclass(frozen=True)
class FileObjectives:
    """The objective function of a problem file: per flight, every objective's expression;
    the values aggregated over the initial states (sum, mean, max or min)."""

    objectives: tuple

    def __call__(self, results):
        f = [AGGREGATES[ob.over]([ob.flight(r) for r in results]) for ob in self.objectives]
        return tuple(f), {"stopped": sum(bool(r.stopped) for r in results)}
