"""Reading a problem file's recipe: the budget, the variational GA and its Gray code, the CMA-ES
refinement and target, the fixed-structure baselines, the GP baseline (the ``[budget]``,
``[ga]``, ``[refine]``, ``[target]``, ``[baselines]`` and ``[gp]`` tables of
:mod:`synthesis.problems.files`)."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

from descent_fmus.models.controllers.operation_table import OperationNameError, operation_numbers
from descent_fmus.synthesis.methods.pareto import Target
from descent_fmus.synthesis.methods.ga_config import FILE_BINARY, FILE_UNARY
from descent_fmus.synthesis.problems.contract import DEFAULT_Q_BITS, Budget
from descent_fmus.synthesis.problems.file_reader import Reader, read_settings
from descent_fmus.synthesis.problems.limits import MAX_BASELINES

__all__ = ["read_recipe", "read_target", "read_baselines", "GA_EXTRA"]

#: keys of [ga] besides the GA's settings (the Gray code, the operations, older budget keys)
GA_EXTRA = ("q_range", "q_bits", "unary", "binary", "generations", "seed")
_TARGET_KEYS = {"objective", "constraint", "limit", "weight"}
_BASELINE_KEYS = {"kind", "degree", "hidden", "file", "scale", "offset", "seed", "q"}


def read_recipe(rd: Reader, data, law) -> tuple:
    """``({budget, ga, refine, gp}, q_bits, operations)`` of the [budget], [ga], [refine] and
    [gp] tables."""
    from descent_fmus.synthesis.methods.gp_config import GPConfig
    from descent_fmus.synthesis.methods.refinement import FILE_REFINE, RefineConfig
    from descent_fmus.synthesis.methods.ga_config import GAConfig
    ga = rd.table(data, "ga", required=False)
    budget_table = dict(rd.table(data, "budget", required=False))
    for k in ("generations", "seed"):              # older files keep them in [ga]
        if k in ga and k not in budget_table:
            budget_table[k] = ga[k]
    recipe = {"budget": read_settings(rd, budget_table, "budget", Budget()),
              "ga": read_settings(rd, ga, "ga", GAConfig(), GA_EXTRA),
              "refine": read_settings(rd, rd.table(data, "refine", required=False), "refine",
                                      RefineConfig(**FILE_REFINE)),
              "gp": read_settings(rd, rd.table(data, "gp", required=False), "gp", GPConfig())}
    return recipe, _q_bits(rd, ga, law), _operations(rd, ga)


def _q_bits(rd: Reader, ga: dict, law) -> tuple:
    q_lo, q_hi = DEFAULT_Q_BITS[2:]
    if "q_range" in ga:
        qr = ga["q_range"]
        if not (isinstance(qr, list) and len(qr) == 2 and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                for x in qr) and qr[0] < qr[1]):
            raise rd.error("ga.q_range", f"must be [min, max] with min < max, got {qr!r}")
        q_lo, q_hi = float(qr[0]), float(qr[1])
    q_ib, q_fb = DEFAULT_Q_BITS[:2]
    if "q_bits" in ga:
        # up to 48 bits: the Gray code decodes through int64 and float64 (exact to 2^53)
        qb = ga["q_bits"]
        if not (isinstance(qb, list) and len(qb) == 2 and all(
                isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in qb)
                and 1 <= sum(qb) <= 48):
            raise rd.error("ga.q_bits", f"must be [integer bits, fraction bits] with 1 to 48 "
                                        f"bits in all, got {qb!r}")
        q_ib, q_fb = qb
    if any(not q_lo <= v < q_hi for v in law.q):
        raise rd.error("ga.q_range", f"the basic law's parameters {law.q} must lie in "
                                     f"[{q_lo}, {q_hi})")
    return (q_ib, q_fb, q_lo, q_hi)


def _operations(rd: Reader, ga: dict) -> dict:
    """The operation sets of the variations: ``[ga] unary``/``binary``, lists of operation
    names or numbers (``["id", "neg", "wrap"]``, ``[1, 2, "atan2"]``); default the paper's set
    with the geometry operations (``FILE_UNARY``, ``FILE_BINARY``)."""
    ops = {}
    for key, default in (("unary", FILE_UNARY), ("binary", FILE_BINARY)):
        v = ga.get(key, list(default))
        if not (isinstance(v, list) and v and len(v) <= 64):
            raise rd.error(f"ga.{key}", f"must be a non-empty list of at most 64 operation "
                                        f"names or numbers, got {v!r}")
        try:
            ops[key] = operation_numbers(v, binary=key == "binary")
        except OperationNameError as exc:
            raise rd.error(f"ga.{key}", str(exc)) from None
    return ops


def read_target(rd: Reader, data, names) -> Target | None:
    if "target" not in data:
        return None
    t = rd.table(data, "target")
    rd.keys(t, "target", _TARGET_KEYS)

    def index(key):
        n = rd.string(t, "target", key)
        if n not in names:
            raise rd.error(f"target.{key}", f"{n!r} is not an objective (objectives: "
                                            f"{', '.join(names)})")
        return names.index(n)

    objective = index("objective")
    constraint = index("constraint") if "constraint" in t else None
    limit = float(rd.number(t, "target", "limit")) if constraint is not None else math.inf
    weight = float(rd.number(t, "target", "weight", 10.0, positive=True))
    return Target(objective, constraint, limit, weight)


def read_baselines(rd: Reader, data, path: Path, basic):
    """The ``[baselines]`` table as a picklable ``() -> {name: law}`` (or None)."""
    if "baselines" not in data:
        return None
    table = rd.table(data, "baselines")
    if not table:
        raise rd.error("baselines", "give at least one structure, e.g. "
                                    "linear = { kind = \"linear\" }")
    if len(table) > MAX_BASELINES:
        raise rd.error("baselines", f"{len(table)} structures; the documented maximum is "
                                    f"{MAX_BASELINES}")
    laws = {}
    for name, item in table.items():
        key = f"baselines.{name}"
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_-]*", name):
            raise rd.error(key, "use letters, digits, '-' and '_' (starting with a letter)")
        if not isinstance(item, dict):
            raise rd.error(key, "must be a table, e.g. { kind = \"polynomial\", degree = 3 }")
        rd.keys(item, key, _BASELINE_KEYS)
        laws[name] = _baseline(rd, item, key, path, basic)
    return _Structures(tuple(laws.items()))


def _baseline(rd: Reader, item: dict, key: str, path: Path, basic):
    """One baseline structure of the basic law's inputs and outputs, with its own input
    scaling (``scale``, ``offset``) and start parameters (``q``) if given."""
    from descent_fmus.synthesis.methods.law import MatrixError
    kind = rd.string(item, key, "kind")
    if kind in ("polynomial", "tanh") and len(basic.outputs) != 1:
        raise rd.error(f"{key}.kind", f"a {kind} structure drives one output; the law has "
                                      f"{len(basic.outputs)} (use linear or file)")
    scale = _vector(rd, item, key, "scale", basic.input_scale)
    offset = _vector(rd, item, key, "offset", basic.input_offset)
    try:
        law = _structure(rd, item, key, kind, path, basic, scale, offset)
        if "q" in item:
            law = law.with_q(_vector(rd, item, key, "q", law.q))
    except (MatrixError, ValueError, OSError) as exc:
        raise rd.error(key, str(exc)) from None
    return law


def _structure(rd: Reader, item, key, kind, path, basic, scale, offset):
    from descent_fmus.synthesis.methods.law import NetworkOperator
    from descent_fmus.synthesis.methods.structures import polynomial_law, tanh_network_law
    template = NetworkOperator(basic.psi, basic.nx, basic.q, basic.outputs, basic.bounds,
                               basic.input_names, scale, offset)
    if kind == "linear":
        return NetworkOperator.linear([[0.0] * basic.nx] * len(basic.outputs),
                                      bounds=basic.bounds, input_names=basic.input_names,
                                      input_scale=scale, input_offset=offset)
    if kind == "polynomial":
        degree = int(rd.number(item, key, "degree", 2, integer=True, positive=True))
        if degree > 3:
            raise rd.error(f"{key}.degree", f"must be 1, 2 or 3, got {degree}")
        return polynomial_law(template, degree)
    if kind == "tanh":
        hidden = int(rd.number(item, key, "hidden", 3, integer=True, positive=True))
        if hidden > 8:
            raise rd.error(f"{key}.hidden", f"must be 1..8 (the controller's parameters), got "
                                            f"{hidden}")
        return tanh_network_law(template, hidden,
                                seed=int(rd.number(item, key, "seed", 0, integer=True)))
    if kind == "file":
        law = NetworkOperator.load(path.parent / rd.string(item, key, "file"))
        return NetworkOperator(law.psi, law.nx, law.q, law.outputs, basic.bounds,
                               basic.input_names, scale, offset)
    raise rd.error(f"{key}.kind", f"must be linear, polynomial, tanh or file, got {kind!r}")


def _vector(rd: Reader, item: dict, key: str, name: str, default) -> list:
    if name not in item:
        return list(default)
    v = item[name]
    if not (isinstance(v, list) and len(v) == len(default) and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
            for x in v)):
        raise rd.error(f"{key}.{name}", f"must be a list of {len(default)} finite numbers "
                                        f"(one per law input), got {v!r}")
    return [float(x) for x in v]


@dataclass(frozen=True)
class _Structures:
    """A problem file's baseline structures (picklable ``() -> {name: law}``)."""

    items: tuple

    def __call__(self) -> dict:
        return dict(self.items)
