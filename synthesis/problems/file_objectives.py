"""The ``[[objectives]]`` and ``[[constraints]]`` tables of a problem file, read into functions
of a flight (:mod:`.file_functions`) with one-line errors naming the key, and the plant signals
those functions need recorded."""
from __future__ import annotations

from descent_fmus.synthesis.problems.contract import AGGREGATES, Constraint
from descent_fmus.synthesis.problems.expressions import Expression, ExpressionError
from descent_fmus.synthesis.problems.file_functions import FileObjective, FlightExpression
from descent_fmus.synthesis.problems.file_reader import ControllerInfo, PlantInfo, Reader
from descent_fmus.synthesis.problems.limits import MAX_CONSTRAINTS, MAX_OBJECTIVES

__all__ = ["OBJECTIVE_KEYS", "CONSTRAINT_KEYS", "read_objectives", "read_constraints",
           "recorded_signals"]

#: the keys of an objective's and of a constraint's table
OBJECTIVE_KEYS = {"name", "flight", "over_states", "unmet_stop_penalty", "penalty"}
CONSTRAINT_KEYS = {"name", "flight", "sense", "bound", "over_states", "scale"}


def _flight_expression(rd: Reader, item: dict, key: str, plant: PlantInfo, ctrl: ControllerInfo,
                       signals, stop) -> FlightExpression:
    try:
        expr = Expression(rd.string(item, key, "flight"), signals)
    except ExpressionError as exc:
        raise rd.error(f"{key}.flight", str(exc)) from None
    for term in expr.terms:       # recorded signals are Reals; final() reads any type
        for sig in sorted(set(term.signals) - set(ctrl.law_signals) - set(plant.real_outputs)):
            if term.function != "final":
                raise rd.error(f"{key}.flight", f"{term} needs Real signals; {sig!r} is "
                                                f"{plant.vars[sig].type} (only final() reads "
                                                f"Integer and Boolean outputs)")
    unmet = float(rd.number(item, key, "unmet_stop_penalty", 0.0))
    if unmet and stop is None:
        raise rd.error(f"{key}.unmet_stop_penalty", "needs [simulation].stop (a flight can "
                                                    "only miss a stop condition it has)")
    return FlightExpression(expr, tuple(ctrl.law_signals.items()), stop is not None, unmet)


def _aggregate(rd: Reader, item: dict, key: str, default: str) -> str:
    over = rd.string(item, key, "over_states", default)
    if over not in AGGREGATES:
        raise rd.error(f"{key}.over_states", f"must be one of {', '.join(AGGREGATES)}, got "
                                             f"{over!r}")
    return over


def read_objectives(rd: Reader, data, plant, ctrl, signals, stop) -> tuple:
    objectives, names, penalty = [], [], []
    for key, ob in rd.items(data, "objectives", OBJECTIVE_KEYS, MAX_OBJECTIVES):
        oname = rd.string(ob, key, "name")
        if oname in names:
            raise rd.error(f"{key}.name", f"objective {oname!r} appears twice")
        flight = _flight_expression(rd, ob, key, plant, ctrl, signals, stop)
        objectives.append(FileObjective(oname, flight, _aggregate(rd, ob, key, "sum")))
        names.append(oname)
        penalty.append(float(rd.number(ob, key, "penalty", 1e9)))
    return objectives, names, penalty


def read_constraints(rd: Reader, data, plant, ctrl, signals, stop) -> list:
    if "constraints" not in data:
        return []
    out, names = [], set()
    for key, item in rd.items(data, "constraints", CONSTRAINT_KEYS, MAX_CONSTRAINTS):
        cname = rd.string(item, key, "name")
        if cname in names:
            raise rd.error(f"{key}.name", f"constraint {cname!r} appears twice")
        names.add(cname)
        flight = _flight_expression(rd, dict(item, unmet_stop_penalty=0.0), key, plant, ctrl,
                                    signals, stop)
        sense = rd.string(item, key, "sense", "<=")
        if sense not in ("<=", ">="):
            raise rd.error(f"{key}.sense", f"must be '<=' or '>=', got {sense!r}")
        scale = rd.number(item, key, "scale", 0.0)
        if "scale" in item and scale <= 0:
            raise rd.error(f"{key}.scale", f"must be > 0, got {scale!r}")
        out.append(Constraint(cname, flight, float(rd.number(item, key, "bound")), sense,
                              _aggregate(rd, item, key, "max"),
                              float(scale) if "scale" in item else None))
    return out


def recorded_signals(exprs, ctrl: ControllerInfo) -> tuple:
    """``(record, initial)``.  ``record``: the plant outputs named inside every reduction but
    ``final`` (read from the final outputs), then ``ctrl.u[k]`` of the law outputs named in any
    (they switch recording on).  When the only such reductions are ``initial`` of plant
    outputs, those outputs are ``initial`` instead (read at t = 0, recorded at no point where
    the loop can: the C master) and ``record`` is empty.  Both empty when every reduction is a
    ``final`` of plant outputs: the fastest flights."""
    law = ctrl.law_signals
    plant = {sig for e in exprs for fn, sig in e.reductions if fn != "final" and sig not in law}
    controller = {"ctrl." + law[sig] for e in exprs for _, sig in e.reductions if sig in law}
    if not controller and all(fn in ("final", "initial") for e in exprs
                              for fn, _ in e.reductions):
        return (), tuple(sorted(plant))
    return tuple(sorted(plant)) + tuple(sorted(controller)), ()
