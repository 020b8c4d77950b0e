"""The benchmark suite's tables: per problem and method the median best value, its ratio to the
reference and the network operator's verdict against the best baseline.

The runs of ``benchmarks/suite/run.py`` are read back from their folders (:func:`run_dir`, one
per problem, method and seed): per method the median over the seeds of the best value of the
problem's target objective (the last point of ``summary["curve"]``, :func:`best_of`), its ratio
to the reference (``suite.reference``), whether the network operator is at least as good as the
best baseline on the median (:func:`verdict`), the form of its best law (new, or the basic
law's) and what that form bought (its median against ``nop-lchr0``'s, :func:`form_bought`).
``suite_report.py`` prints and plots the tables.
"""
from __future__ import annotations

import json
import math
import statistics
from pathlib import Path

import suite

__all__ = ["NETWORK_OPERATOR", "NOP_LCHR0", "VARIANTS", "CLEARLY", "READS_BUDGET", "methods_of",
           "is_baseline", "run_dir", "best_of", "tabulate", "verdict", "form_bought", "jsonable",
           "median_curve", "stored_runs", "at_budgets", "no_over_gp"]

NETWORK_OPERATOR = "network-operator"
#: the network operator's recipe with lchr = 0 (no structure variations: the basic law's
#: parameters only), beside it in every table: what the form alone bought
NOP_LCHR0 = "nop-lchr0"
#: method variants of the suite: (the method run, the recipe settings changed)
VARIANTS = {NOP_LCHR0: (NETWORK_OPERATOR, {"lchr": 0})}
#: the methods that read their flight budget (the registry hands it to the network operator
#: only: its epochs and refinement are sized by it); every other method (GP, CMA-ES) runs
#: generations until the flights end, so its value at N flights is read off a longer run's curve
READS_BUDGET = frozenset({NETWORK_OPERATOR, NOP_LCHR0})


def methods_of(problem) -> list:
    """The network operator first, then every registered method of the problem (the
    ``cma-<structure>`` baselines and the GP baseline ``gp``), all at the same flight budget."""
    from descent_fmus.synthesis.methods.registry import method_names
    names = method_names(problem)
    return [NETWORK_OPERATOR, *VARIANTS] + [m for m in names if m != NETWORK_OPERATOR]


def is_baseline(method: str) -> bool:
    """A method the network operator is compared with (not it, nor a variant of it)."""
    return method != NETWORK_OPERATOR and method not in VARIANTS


def run_dir(out: Path, name: str, method: str, seed: int) -> Path:
    return Path(out) / name / f"{method}-s{seed}"



# -- tabulating --------------------------------------------------------------------------------
def best_of(summary: dict) -> float:
    """The best value of the target objective over the run (its learning curve's last point;
    NaN if no law met the problem's constraints)."""
    c = summary.get("curve") or []
    return float(c[-1][1]) if c else math.nan


def value_at(curve, flights: int) -> float:
    """The best value of a run's learning curve after at most ``flights`` flights (NaN before
    its first point): what the run had found at that budget.  A method that does not read its
    budget (GP: generations until the flights end) gives at N flights of a longer run what a
    run of budget N gives, up to the generation that straddles N (not counted here)."""
    vals = [float(v) for n, v in curve if n <= flights]
    return vals[-1] if vals else math.nan


def _median(values) -> float:
    """The median, a run without a feasible law (NaN) counting as the worst (inf)."""
    return statistics.median([v if v == v else math.inf for v in values]) if values \
        else math.nan


def tabulate(names, seeds, out: Path, fmus=None) -> dict:
    """Every problem's rows (one per method), its reference and the verdicts."""
    table = {}
    for name in names:
        spec = suite.SPECS[name]
        problem = suite.load(name, fmus)
        ref = suite.reference(name, problem, fmus)
        rows = []
        for method in methods_of(problem):
            runs = {}
            for seed in seeds:
                d = run_dir(out, name, method, seed)
                f = d / "summary.json"
                if f.is_file():
                    runs[seed] = json.loads(f.read_text())
            if not runs:
                continue
            vals = [best_of(runs[s]) if s in runs else math.nan for s in seeds]
            med = _median(vals)
            row = {"method": method, "values": vals, "median": med,
                   "ratio": suite.ratio(med, ref["value"]) if spec.ratio else None,
                   "flights": [runs[s].get("flights") if s in runs else None for s in seeds],
                   "seconds": [round(runs[s].get("seconds", 0.0)) if s in runs else None
                               for s in seeds],
                   "curves": {s: runs[s].get("curve", []) for s in runs}}
            # the run whose value is the median (the law shown for the method)
            ok = [s for s in seeds if s in runs]
            mid = min(ok, key=lambda s: abs(best_of(runs[s]) - med)
                      if best_of(runs[s]) == best_of(runs[s]) and med < math.inf else math.inf)
            st = runs[mid].get("structure", {})
            row.update(median_seed=mid, keeps_basic_form=st.get("best_law_keeps_basic_form"),
                       law=st.get("best_law"), details="")
            pj = run_dir(out, name, method, mid) / "pareto.json"
            if pj.is_file():
                law = suite.best_law(problem, json.loads(pj.read_text()))
                if law is not None:
                    row["details"] = suite.law_details(name, problem, law, fmus)
            rows.append(row)
        ref_details = ""
        if name in suite.PARKING:
            d = ref["details"]
            ref_details = (f"parks every start: mean final distance {d['mean_distance']:.2g} m, "
                           f"heading error {d['mean_heading']:.2g} rad")
        elif name == "cartpole":
            from descent_fmus.synthesis.methods.law import NetworkOperator  # noqa: F401
            ref_details = ("the basic law (LQR of the linearisation): "
                           + suite.law_details(name, problem, problem.basic(), fmus))
        table[name] = {"reference": ref["value"], "reference_label": ref["label"],
                       "methods": methods_of(problem),
                       "reference_note": ref_details, "plot": spec.plot,
                       "goal": spec.goal, "goal_ratio": spec.goal_ratio,
                       "goals": budget_goals(spec, ref["value"]), "rows": rows,
                       "verdict": verdict(rows, ref["value"], spec.goal_ratio,
                                          spec.goal_value)}
        table[name]["reference_details"] = jsonable(ref["details"])
    return table


#: "clearly better": the network operator's median at most this fraction of the best baseline's
CLEARLY = 0.9


def budget_goals(spec, ref) -> dict:
    """``{flights: the largest value meeting the goal}`` of a problem: its goal at its own
    budget (``goal_ratio`` x the reference, or ``goal_value``) and its ``goal_at``."""
    out = {}
    if spec.goal_ratio is not None and ref:
        out[spec.flights] = spec.goal_ratio * ref
    elif spec.goal_value is not None:
        out[spec.flights] = spec.goal_value
    out.update(dict(spec.goal_at))
    return out


def seeds_meeting(values, bound) -> list:
    """``[seeds whose value is at most bound, seeds with a value]`` (the seed count behind a
    median: a median of three meets a goal when two seeds do)."""
    got = [v for v in values if v is not None and v == v]
    return [sum(v <= bound for v in got), len(got)]


def verdict(rows, ref, goal_ratio, goal_value=None) -> dict:
    """Against the best baseline on the median: ``at_least_as_good``, ``clearly_better``
    (median <= 0.9 x the best baseline's), the ratio of the two, the goal met (median
    <= goal_ratio x the reference, or <= goal_value) and the seeds that meet it
    (``seeds_meeting_goal``, :func:`seeds_meeting`)."""
    no = next((r for r in rows if r["method"] == NETWORK_OPERATOR), None)
    base = [r for r in rows if is_baseline(r["method"])]
    out = {}
    if no is not None:
        out.update(form_bought(no, next((r for r in rows if r["method"] == NOP_LCHR0), None)))
        n = no["median"]
        bound = goal_ratio * ref if goal_ratio is not None and ref else goal_value
        if bound is not None:
            out["goal_met"] = bool(n == n and n <= bound)
            out["seeds_meeting_goal"] = seeds_meeting(no["values"], bound)
    if no is None or not base:
        return out
    best = min(base, key=lambda r: r["median"] if r["median"] == r["median"] else math.inf)
    b, n = best["median"], no["median"]
    out["best_baseline"] = best["method"]
    if n == n and b == b:
        out["no_over_best_baseline"] = n / b if b > 0 else (1.0 if n == b else math.inf)
        out["at_least_as_good"] = n <= b * (1 + 1e-9) or n <= b + 1e-12
        out["clearly_better"] = n <= CLEARLY * b
    elif n == n:                           # no baseline met the constraints
        out.update(at_least_as_good=True, clearly_better=True, no_over_best_baseline=0.0)
    else:
        out.update(at_least_as_good=False, clearly_better=False)
    return out


def form_bought(no: dict, lchr0: dict | None) -> dict:
    """Whether the network operator's best law (of its median seed) has a new form, and its
    median over the same recipe's without structure variations (:data:`NOP_LCHR0`)."""
    keeps = no.get("keeps_basic_form")
    out = {"new_form": None if keeps is None else not keeps}
    if lchr0 is not None:
        n, z = no["median"], lchr0["median"]
        out["lchr0_median"] = z
        if n == n and z == z and z != math.inf:
            out["no_over_lchr0"] = n / z if z > 0 else (1.0 if n == z else math.inf)
    return out


# -- every method at fixed budgets, and the median learning curves -----------------------------
def stored_runs(dirs, name: str, method: str, seeds) -> dict:
    """``{seed: [run, ...]}``: the runs of a method in every folder of ``dirs`` (run.py's
    ``--out``, then ``--also``), each ``{"budget": flights asked (run.json), "flights": flown,
    "curve": [[flights, value], ...], "dir": its folder}``.  A run stopped before its end
    (no summary) counts by its checkpoint's curve and flights, with no budget (its value is
    read only for a method that does not read its budget)."""
    out = {}
    for d in dirs:
        for seed in seeds:
            rd = run_dir(d, name, method, seed)
            rj, sj, ck = rd / "run.json", rd / "summary.json", rd / "checkpoint.json"
            if sj.is_file():
                s = json.loads(sj.read_text())
                flights = s.get("flights") or 0
                budget = (json.loads(rj.read_text()).get("budget") or {}).get("flights") \
                    if rj.is_file() else None
            elif ck.is_file():
                s = json.loads(ck.read_text())
                flights, budget = s.get("simulated") or 0, None
            else:
                continue
            out.setdefault(seed, []).append({"budget": budget, "flights": flights,
                                             "curve": s.get("curve") or [], "dir": str(rd)})
    return out


def value_at_budget(method: str, runs, flights: int):
    """One seed's value at ``flights`` flights: for a method of :data:`READS_BUDGET` the best
    of a run of exactly that budget, for any other the curve of a run flown at least that far
    (:func:`value_at`; NaN if no law was feasible by then); None if no run gives it."""
    for r in runs:
        if method in READS_BUDGET:
            if r["budget"] == flights:
                return best_of(r)
        elif r["flights"] >= flights:
            return value_at(r["curve"], flights)
    return None


def _ratio(a, b):
    return a / b if a == a and b == b and 0 < b < math.inf and a < math.inf else None


def at_budgets(table: dict, dirs, seeds, budgets) -> dict:
    """Per problem of ``table`` (:func:`tabulate`'s) every method's values at each of
    ``budgets`` flights (per seed, None where no run gives it; the median over the seeds
    that have one), the network operator against GP (:func:`no_over_gp`: ``no_over_gp``,
    what it reads in ``no_over_gp_of``, and above a reference the ratio of the raw values
    too, ``values_no_over_gp``); and per method and seed its longest run's curve
    (``curves``, ``ends``) for :func:`median_curve`."""
    out = {}
    for name, t in table.items():
        ref, rows = t["reference"], []
        for method in t.get("methods") or [r["method"] for r in t["rows"]]:
            runs = stored_runs(dirs, name, method, seeds)
            if not runs:
                continue
            vals = {n: [value_at_budget(method, runs.get(s, []), n) for s in seeds]
                    for n in budgets}
            longest = {s: max(rs, key=lambda r: r["flights"]) for s, rs in runs.items()}
            goals = t.get("goals", {})
            rows.append({"method": method, "values": vals,
                         "median": {n: _median([v for v in vals[n] if v is not None])
                                    for n in budgets},
                         "meeting": {n: seeds_meeting(vals[n], goals[n])
                                     for n in budgets if n in goals},
                         "curves": {s: r["curve"] for s, r in longest.items()},
                         "ends": {s: r["flights"] for s, r in longest.items()}})
        by = {r["method"]: r["median"] for r in rows}
        res = {"reference": ref, "plot": t.get("plot"), "goal_ratio": t.get("goal_ratio"),
               "goals": t.get("goals", {}),
               "budgets": list(budgets), "rows": rows,
               **no_over_gp(by.get(NETWORK_OPERATOR, {}), by.get("gp", {}), ref,
                            t.get("plot"), budgets)}
        out[name] = res
    return out


def no_over_gp(no: dict, gp: dict, ref, plot, budgets) -> dict:
    """The network operator's median over GP's at each budget (``{flights: median}`` each),
    as the issue's goal "<= 0.5 x GP" reads it: [choice] where the value lies above a
    reference (``plot = "excess"``: the minimum-time problems, lq, reentry-second) the ratio
    of their **excesses** over it, (NO - ref) / (GP - ref) -- a ratio of raw times can never
    reach 0.5, both being at least the optimum -- with the raw ratio beside it
    (``values_no_over_gp``); elsewhere (a reference of 0: parking) the ratio of the values.
    ``no_over_gp_of`` says which ("excess over the reference" or "value")."""
    raw = {n: _ratio(no.get(n, math.nan), gp.get(n, math.nan)) for n in budgets}
    if plot == "excess" and ref is not None:
        return {"no_over_gp": {n: _ratio(no.get(n, math.nan) - ref, gp.get(n, math.nan) - ref)
                               for n in budgets},
                "no_over_gp_of": "excess over the reference", "values_no_over_gp": raw}
    return {"no_over_gp": raw, "no_over_gp_of": "value"}


def median_curve(curves: dict, ends: dict) -> list:
    """The median over the seeds of their best-so-far curves (``{seed: [[flights, value],
    ...]}``) at every flight count where one of them steps, up to the shortest run's end
    (``ends``: ``{seed: flights flown}``), that end included; a seed before its first point
    counts as the worst (inf), and points whose median is inf are left out."""
    import bisect
    curves = {s: c for s, c in curves.items() if c}
    if not curves:
        return []
    end = min(ends[s] for s in curves)
    keys = {s: [n for n, _ in c] for s, c in curves.items()}

    def at(s, n):
        i = bisect.bisect_right(keys[s], n)
        return float(curves[s][i - 1][1]) if i else math.nan

    out = []
    for n in sorted({n for k in keys.values() for n in k if n <= end}):
        m = _median([at(s, n) for s in curves])
        if m < math.inf and (not out or m != out[-1][1]):
            out.append([n, m])
    if out and out[-1][0] < end:
        out.append([end, out[-1][1]])
    return out


def jsonable(x):
    import numpy as np
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, complex):
        return [x.real, x.imag]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return x
