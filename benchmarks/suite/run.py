#!/usr/bin/env python
"""The benchmark suite: the network operator against every fixed-structure CMA-ES baseline of each
problem, at the same flight budget, against a reference computed by other means; the tuning
problems and the held-out ones reported apart.

For every problem of ``--problems`` (benchmarks/suite/suite.py), every method that applies to it
(``network-operator`` with the problem's own recipe -- the package's default recipe, or the
registered recipe of reentry-second and lunar-descent --, ``nop-lchr0``: the same recipe with
lchr = 0, the basic law's form only, and every ``cma-<structure>`` of
:func:`synthesis.methods.registry.method_names`) and every seed, one synthesis run through the
FMUs (``run_synthesis``, the same evaluator for all) with the problem's flight budget; then a
table per half of ``split.toml`` (the held-out protocol: the default recipe is tuned on the
tuning half only): per method the median over the seeds of the best value of the problem's
target objective (the last point of ``summary["curve"]``), its ratio to the reference, whether
the network operator is at least as good as the best baseline on the median, the form of its
best law (new, or the basic law's) and what that form bought (its median against
``nop-lchr0``'s).  Finished runs are reused; a run that stopped early (interrupted) is resumed.

    python benchmarks/suite/run.py                                   # everything (hours)
    python benchmarks/suite/run.py --problems lq parking --seeds 1 --workers 2
    python benchmarks/suite/run.py --problems hopper --methods network-operator   # one method
    python benchmarks/suite/run.py --no-run                          # re-tabulate runs/suite
    python benchmarks/suite/run.py --no-run --json                   # the tables as JSON

``--workers N`` runs N syntheses at once (one process each, every synthesis in one process):
the flights of the suite's plants (native twins built by ``descent-fmus build-plant``) are
short, so separate runs use the cores better than a pool inside one run.  ``--flights N``
overrides every problem's budget (smoke tests).
Writes ``<out>/table.json`` and one figure per half, ``docs/figures/suite-tuning.png`` and
``suite-held-out.png`` (``--plot``); a malformed ``--split`` file ends with one line (exit 2).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import statistics
import sys
import time
from concurrent.futures import as_completed
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(HERE))

import split  # noqa: E402
import suite  # noqa: E402

NETWORK_OPERATOR = "network-operator"
#: the network operator's recipe with lchr = 0 (no structure variations: the basic law's
#: parameters only), beside it in every table: what the form alone bought
NOP_LCHR0 = "nop-lchr0"
#: method variants of the suite: (the method run, the recipe settings changed)
VARIANTS = {NOP_LCHR0: (NETWORK_OPERATOR, {"lchr": 0})}


# -- running ------------------------------------------------------------------------------------
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


def finished(d: Path, flights: int) -> dict | None:
    """The summary of a finished run in ``d`` with at least ``flights`` flights, else None."""
    f = d / "summary.json"
    if not f.is_file():
        return None
    s = json.loads(f.read_text())
    return s if s.get("flights", 0) >= flights else None


def run_one(job: dict) -> dict:
    """One synthesis: the problem loaded, tuned to the budget and seed, run (resumed if a
    checkpoint is there); returns a short record."""
    from descent_fmus.synthesis.run.loop import run_synthesis
    d = Path(job["dir"])
    method, settings = VARIANTS.get(job["method"], (job["method"], {}))
    if method == NETWORK_OPERATOR:
        settings = {**job.get("settings", {}), **settings}
    problem = suite.load(job["problem"], job["fmus"], build=False).tuned(
        flights=job["flights"], seed=job["seed"], generations=10 ** 6, **settings)
    t0 = time.perf_counter()
    resume = (d / "checkpoint.json").is_file()
    if resume and (d / "summary.json").is_file():
        (d / "summary.json").unlink()                 # a shorter finished run: resumed
    s = run_synthesis(problem, d, job["fmus"], method=method, workers=1,
                      resume=resume, progress=False, export=False, reference=False)
    return {**job, "seconds": time.perf_counter() - t0, "flights_done": s.get("flights"),
            "interrupted": bool(s.get("interrupted"))}


def _child(job_json: str) -> None:
    """``run.py --job JSON``: one run in this process, its record printed as the last line;
    the process ends without the interpreter's teardown (pythonfmu FMUs loaded in a process
    were seen, rarely, to make it abort there: the package's CLI ends the same way)."""
    from descent_fmus.synthesis.cli.main import exit_without_teardown
    code = 0
    try:
        print(json.dumps(run_one(json.loads(job_json))), flush=True)
    except BaseException as exc:                      # noqa: BLE001 -- reported to the parent
        print(json.dumps({"error": f"{type(exc).__name__}: {exc}"}), flush=True)
        code = 1
    sys.stdout.flush()
    sys.stderr.flush()
    exit_without_teardown(code)


def _launch(job: dict) -> dict:
    import subprocess
    log = Path(job["dir"]).with_suffix(".log")
    with open(log, "a") as err:
        r = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--job",
                            json.dumps(job)], stdout=subprocess.PIPE, stderr=err, text=True)
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("{")]
    rec = json.loads(lines[-1]) if lines else {"error": f"exit code {r.returncode} (see {log})"}
    if "error" in rec:
        raise RuntimeError(rec["error"])
    return rec


def run_all(names, seeds, out: Path, fmus, workers: int, flights_override=None,
            methods=None, settings=None) -> None:
    """Every run of the suite not finished yet (of ``methods`` only, if given), ``workers`` at
    once (one process each), the longest first; ``settings`` (``{name: value}`` as on the
    command line of ``synthesize``) change the recipe of every network-operator run."""
    from concurrent.futures import ThreadPoolExecutor

    from descent_fmus.synthesis.paths import fmu_dir
    fmus = str(fmus or fmu_dir())
    jobs = []
    for name in names:
        spec = suite.SPECS[name]
        problem = suite.load(name, fmus)               # builds the plants once, here
        flights = flights_override or spec.flights
        for method in methods_of(problem):
            if methods and method not in methods:
                continue
            for seed in seeds:
                d = run_dir(out, name, method, seed)
                if finished(d, flights):
                    continue
                d.parent.mkdir(parents=True, exist_ok=True)
                jobs.append({"problem": name, "method": method, "seed": seed,
                             "flights": flights, "dir": str(d), "fmus": fmus,
                             "settings": dict(settings or {}),
                             "cost": flights * _flight_cost(name)})
    if not jobs:
        return
    jobs.sort(key=lambda j: -j["cost"])
    print(f"suite: {len(jobs)} runs to do, {workers} at a time", flush=True)
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(_launch, j): j for j in jobs}
        for k, fut in enumerate(as_completed(futures), 1):
            j = futures[fut]
            try:
                r = fut.result()
                print(f"[{k}/{len(jobs)} {time.perf_counter() - t0:6.0f} s] {j['problem']} "
                      f"{j['method']} seed {j['seed']}: {r['flights_done']} flights in "
                      f"{r['seconds']:.0f} s", flush=True)
            except Exception as exc:       # one failed run does not stop the suite
                print(f"[{k}/{len(jobs)}] {j['problem']} {j['method']} seed {j['seed']}: "
                      f"FAILED: {exc}", flush=True)


#: relative cost of a flight per problem (seconds on this machine, for the job order only)
_COSTS = {"lunar-descent": 0.08, "cartpole": 0.06, "hopper": 0.05, "lq": 0.035,
          "parking": 0.03, "reentry-second": 0.004, "parking-box": 0.05,
          "mintime-di": 0.02, "mintime-osc": 0.03}


def recipe_settings(items) -> dict:
    """``["refine_basis_patience=0", "lchr=12"]`` -> ``{name: int or float value}``, checked
    against the recipe's settings (ValueError with one line naming the bad one)."""
    from descent_fmus.synthesis.problems.contract import recipe
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"--set {item!r}: give NAME=VALUE")
        try:
            out[name.strip()] = int(value) if re.fullmatch(r"[+-]?\d+", value.strip()) \
                else float(value)
        except ValueError:
            out[name.strip()] = value.strip()
    recipe(**out)                                       # unknown names, bad values: raise
    return out


def _flight_cost(name: str) -> float:
    return _COSTS.get(name, 0.05)


# -- tabulating --------------------------------------------------------------------------------
def best_of(summary: dict) -> float:
    """The best value of the target objective over the run (its learning curve's last point;
    NaN if no law met the problem's constraints)."""
    c = summary.get("curve") or []
    return float(c[-1][1]) if c else math.nan


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
                       "reference_note": ref_details, "plot": spec.plot,
                       "goal": spec.goal, "goal_ratio": spec.goal_ratio, "rows": rows,
                       "verdict": verdict(rows, ref["value"], spec.goal_ratio,
                                          spec.goal_value)}
        table[name]["reference_details"] = _jsonable(ref["details"])
    return table


#: "clearly better": the network operator's median at most this fraction of the best baseline's
CLEARLY = 0.9


def verdict(rows, ref, goal_ratio, goal_value=None) -> dict:
    """Against the best baseline on the median: ``at_least_as_good``, ``clearly_better``
    (median <= 0.9 x the best baseline's), the ratio of the two, and the goal met (median
    <= goal_ratio x the reference, or <= goal_value)."""
    no = next((r for r in rows if r["method"] == NETWORK_OPERATOR), None)
    base = [r for r in rows if is_baseline(r["method"])]
    out = {}
    if no is not None:
        out.update(form_bought(no, next((r for r in rows if r["method"] == NOP_LCHR0), None)))
        n = no["median"]
        if goal_ratio is not None and ref:
            out["goal_met"] = bool(n == n and n / ref <= goal_ratio)
        elif goal_value is not None:
            out["goal_met"] = bool(n == n and n <= goal_value)
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


def _jsonable(x):
    import numpy as np
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, complex):
        return [x.real, x.imag]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return x


def _fmt(v, digits=5) -> str:
    if v is None or v != v:
        return "-"
    if v == math.inf:
        return "inf"
    a = abs(v)
    if a != 0 and (a < 1e-3 or a >= 1e5):
        return f"{v:.3e}"
    return f"{v:.{digits}g}"


def print_table(table: dict, seeds) -> None:
    for name, t in table.items():
        print(f"\n== {name}: reference {_fmt(t['reference'], 7)} ({t['reference_label']}); "
              f"goal: {t['goal']}")
        if t.get("reference_note"):
            print(f"  reference: {t['reference_note']}")
        print(f"  {'method':18s} {'median':>11s} {'ratio':>9s}  per seed "
              f"({', '.join(map(str, seeds))})")
        for r in t["rows"]:
            per = ", ".join(_fmt(v) for v in r["values"])
            print(f"  {r['method']:18s} {_fmt(r['median'], 7):>11s} {_fmt(r['ratio'], 5):>9s}"
                  f"  {per}" + (f"  [{r['details']}]" if r.get("details") else ""))
        v = t["verdict"]
        if "best_baseline" in v:
            print(f"  network operator / best baseline ({v['best_baseline']}): "
                  f"{_fmt(v.get('no_over_best_baseline'), 4)}; at least as good: "
                  f"{'yes' if v.get('at_least_as_good') else 'no'}; clearly better (<= "
                  f"{CLEARLY} x): {'yes' if v.get('clearly_better') else 'no'}")
        if "goal_met" in v:
            print(f"  goal met: {'yes' if v['goal_met'] else 'no'}")
        no = next((r for r in t["rows"] if r["method"] == NETWORK_OPERATOR), None)
        if no is not None:
            form = ("keeps the basic law's form" if no["keeps_basic_form"]
                    else "a new form" if no["keeps_basic_form"] is not None else "?")
            print(f"  network operator's best law (seed {no['median_seed']}, {form}): "
                  f"{no['law']}")
        if "lchr0_median" in v:
            print(f"  the same recipe without structure variations ({NOP_LCHR0}): median "
                  f"{_fmt(v['lchr0_median'], 7)}; network operator / it: "
                  f"{_fmt(v.get('no_over_lchr0'), 4)} (what the form bought, if the form is new)")


# -- the figure --------------------------------------------------------------------------------
def plot(table: dict, path: Path, title: str = "") -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = list(table)
    cols = min(3, len(names))
    rows = math.ceil(len(names) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(max(5.2 * cols, 7.0), 4.0 * rows),
                             squeeze=False)
    for ax, name in zip(axes.ravel(), names):
        t = table[name]
        ref = t["reference"]
        excess = t.get("plot") == "excess" and ref
        low = []
        for k, r in enumerate(t["rows"]):
            for j, (seed, curve) in enumerate(sorted(r["curves"].items(),
                                                     key=lambda kv: int(kv[0]))):
                if not curve:
                    continue
                n, v = map(list, zip(*curve))
                n.append(max(n[-1], max(f or 0 for f in r["flights"])))
                v.append(v[-1])
                if excess:
                    v = [max(x / ref - 1.0, 1e-12) for x in v]
                low.append(min(v))
                ax.step(n, v, where="post", color=f"C{k}", alpha=0.85, lw=1.2,
                        label=r["method"] if j == 0 else None)
        if excess:
            if t.get("goal_ratio"):
                ax.axhline(t["goal_ratio"] - 1.0, color="k", ls=":", lw=1,
                           label=f"goal {t['goal_ratio']:g} x reference")
            ax.set_ylabel("value / reference - 1")
        elif ref is not None and (not low or ref > 1e-3 * min(low)):
            ax.axhline(ref, color="k", ls="--", lw=1, label=f"reference {ref:.4g}")
        elif ref is not None:
            ax.text(0.02, 0.02, f"reference {ref:.2g} (off the scale)", transform=ax.transAxes,
                    fontsize=8)
        ax.set_yscale("log")
        ax.set_xlabel("flights")
        ax.set_title(name, fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    for ax in axes.ravel()[len(names):]:
        ax.axis("off")
    fig.suptitle("benchmark suite" + (f": {title}" if title else "") + "\nthe best value "
                 "of the target objective against flights, every method and seed",
                 fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def figure_path(base: Path, half: str) -> Path:
    """The learning-curve figure of one half: ``suite.png`` -> ``suite-tuning.png``,
    ``suite-held-out.png``."""
    return base.with_name(f"{base.stem}-{half.replace('_', '-')}{base.suffix}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", nargs="+", default=list(suite.ORDER), choices=suite.ORDER)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--methods", nargs="+", default=None,
                    help="run only these methods (the table still shows every finished run)")
    ap.add_argument("--flights", type=int, default=None,
                    help="flight budget of every run (default: each problem's own)")
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "suite")
    ap.add_argument("--workers", type=int, default=2, help="runs at once (one process each)")
    ap.add_argument("--fmus", type=Path, default=None, help="the package's FMU folder")
    ap.add_argument("--split", type=Path, default=split.SPLIT,
                    help="the held-out protocol: tuning and held-out problems (split.toml)")
    ap.add_argument("--no-run", action="store_true",
                    help="run nothing: tabulate the runs in --out as they are")
    ap.add_argument("--json", action="store_true", help="print the table as JSON")
    ap.add_argument("--plot", type=lambda v: Path(v) if v else None,
                    default=ROOT / "docs" / "figures" / "suite.png",
                    help="the learning-curve figures, one per half (default "
                         "docs/figures/suite-tuning.png and suite-held-out.png; '' for none)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a recipe setting of every network-operator run, named as in "
                         "synthesize's options (refine_basis_patience=0, lchr=12; "
                         "repeatable): an A/B of the recipe, in its own --out")
    ap.add_argument("--job", help=argparse.SUPPRESS)        # one run (the runner's child)
    args = ap.parse_args(argv)
    if args.job:
        _child(args.job)
    try:
        halves = split.read_split(args.split, suite.ORDER)
        settings = recipe_settings(args.set)
    except (split.SplitError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    t0 = time.perf_counter()
    if not args.no_run:
        run_all(args.problems, args.seeds, args.out, args.fmus, args.workers, args.flights,
                args.methods, settings)
    table = tabulate(args.problems, args.seeds, args.out, args.fmus)
    wall = time.perf_counter() - t0
    parts = {half: {n: dict(table[n], half=half) for n in halves[half] if n in table}
             for half, _ in split.HALVES}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "table.json").write_text(json.dumps(_jsonable(dict(split=halves, **parts)),
                                                    indent=1))
    if args.json:
        print(json.dumps(_jsonable(dict(split=halves, **{
            half: {n: {k: v for k, v in t.items() if k != "reference_details"}
                   for n, t in part.items()} for half, part in parts.items()})), indent=1))
    else:
        for half, title in split.HALVES:
            if parts[half]:
                print(f"\n######## {title}: {', '.join(parts[half])}")
                print_table(parts[half], args.seeds)
        if not args.no_run:
            print(f"\nwall time of this invocation: {wall:.0f} s ({os.cpu_count()} cores)")
    if args.plot:
        for half, title in split.HALVES:
            if parts[half]:
                path = figure_path(args.plot, half)
                plot(parts[half], path, title)
                print(f"figure: {path}", file=sys.stderr if args.json else sys.stdout)


if __name__ == "__main__":
    main()
