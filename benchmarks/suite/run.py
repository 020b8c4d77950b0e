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
``nop-lchr0``'s); and a table of every method at fixed budgets (``--at``, default 5 000 and
20 000 flights: the median over the seeds, the values per seed, the network operator over GP
as the goal reads it: above a reference, the ratio of their excesses over it).  Finished runs are reused; a run that stopped early (interrupted) is resumed.
This script runs the syntheses (one process each) and is the command line; the tables are
built by ``suite_table.py`` and printed and plotted by ``suite_report.py``.

    python benchmarks/suite/run.py                                   # everything (hours)
    python benchmarks/suite/run.py --problems lq parking --seeds 1 --workers 2
    python benchmarks/suite/run.py --problems hopper --methods network-operator   # one method
    python benchmarks/suite/run.py --no-run                          # re-tabulate runs/suite
    python benchmarks/suite/run.py --no-run --json                   # the tables as JSON
    python benchmarks/suite/run.py --no-run --out A --also B --plot docs/figures/suite-baselines.png

``--workers N`` runs N syntheses at once (one process each, every synthesis in one process):
the flights of the suite's plants (native twins built by ``descent-fmus build-plant``) are
short, so separate runs use the cores better than a pool inside one run.  ``--flights N``
overrides every problem's budget (smoke tests).
Writes ``<out>/table.json`` and one figure per half, ``docs/figures/suite-tuning.png`` and
``suite-held-out.png`` (``--plot``: every method's median learning curve over the seeds and each
seed's, from the longest run of each in ``--out`` and ``--also``); a malformed ``--split`` file ends with one line (exit 2).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
import time
from concurrent.futures import as_completed
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(HERE))

import split  # noqa: E402
import suite  # noqa: E402

from suite_report import figure_path, plot, print_budgets, print_table  # noqa: E402
from suite_table import (NETWORK_OPERATOR, VARIANTS, at_budgets, jsonable,  # noqa: E402
                         methods_of, run_dir, tabulate)


# -- running ------------------------------------------------------------------------------------
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
        record = run_one(json.loads(job_json))
    except BaseException as exc:                      # noqa: BLE001 -- reported to the parent
        record, code = {"error": f"{type(exc).__name__}: {exc}"}, 1
    try:
        print(json.dumps(record), flush=True)
    except OSError:                                   # the parent is gone (stopped suite)
        print(f"run.py: the suite's parent process is gone; this run's record: {record}",
              file=sys.stderr)
        code = 1
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
    ap.add_argument("--at", type=int, nargs="*", default=[5000, 20000], metavar="FLIGHTS",
                    help="the table of every method at these budgets (default 5000 20000): "
                         "GP and CMA-ES read off any run flown that far, the network operator "
                         "(it reads its budget) from a run of that budget")
    ap.add_argument("--also", type=Path, nargs="+", default=[], metavar="DIR",
                    help="more run folders (the layout of --out, e.g. the network operator "
                         "at another budget) read for that table and the figures, never run")
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
    at = at_budgets(table, [args.out, *args.also], args.seeds, args.at)
    wall = time.perf_counter() - t0
    parts = {half: {n: dict(table[n], half=half) for n in halves[half] if n in table}
             for half, _ in split.HALVES}
    args.out.mkdir(parents=True, exist_ok=True)
    budgets = {n: {k: v for k, v in t.items() if k != "rows"} | {"rows": [
        {k: v for k, v in r.items() if k not in ("curves", "ends")} for r in t["rows"]]}
        for n, t in at.items()}
    (args.out / "table.json").write_text(json.dumps(jsonable(dict(split=halves, **parts,
                                                                  at_budgets=budgets)),
                                                    indent=1))
    if args.json:
        print(json.dumps(jsonable(dict(split=halves, at_budgets=budgets, **{
            half: {n: {k: v for k, v in t.items() if k != "reference_details"}
                   for n, t in part.items()} for half, part in parts.items()})), indent=1))
    else:
        for half, title in split.HALVES:
            if parts[half]:
                print(f"\n######## {title}: {', '.join(parts[half])}")
                print_table(parts[half], args.seeds)
                if args.at:
                    print_budgets({n: at[n] for n in parts[half]}, args.seeds)
        if not args.no_run:
            print(f"\nwall time of this invocation: {wall:.0f} s ({os.cpu_count()} cores)")
    if args.plot:
        for half, title in split.HALVES:
            if parts[half]:
                path = figure_path(args.plot, half)
                plot({n: at[n] for n in parts[half]}, path, title)
                print(f"figure: {path}", file=sys.stderr if args.json else sys.stdout)


if __name__ == "__main__":
    main()
