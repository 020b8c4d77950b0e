"""The objective and constraint functions of a problem file: expressions of a flight's signals
(:mod:`synthesis.problems.expressions`), aggregated over the initial states.  Everything here
pickles (the problem is sent to the worker processes)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from descent_fmus.synthesis.problems.contract import AGGREGATES
from descent_fmus.synthesis.problems.expressions import Expression, reduce_signal

__all__ = ["FileObjective", "FileObjectives", "FlightExpression"]


@dataclass(frozen=True)
class FlightExpression:
    """One expression evaluated on one flight: the reductions of its signals (``final`` from
    the plant's final outputs), plus ``unmet_stop_penalty`` for a flight the stop condition
    never ended."""

    expression: Expression
    law_outputs: tuple        # (signal name "u1", controller output "u[1]") pairs
    has_stop: bool = False
    unmet_stop_penalty: float = 0.0

    def __call__(self, r) -> float:
        law = dict(self.law_outputs)
        values = {}
        for fn, name in self.expression.reductions:
            if name in law:
                x = r.outputs.get("ctrl." + law[name], ())
                final = float(x[-1]) if len(x) else math.nan
            else:
                x = r.outputs.get(name, ())
                final = float(r.final[name])
            values[(fn, name)] = reduce_signal(fn, r.time, x, final)
        special = {"tf": r.t_final, "stopped": 1.0 if r.stopped else 0.0}
        v = self.expression.evaluate(values, special)
        if self.has_stop and not r.stopped and self.unmet_stop_penalty:
            v += self.unmet_stop_penalty
        return v


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
