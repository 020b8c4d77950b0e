"""Benchmark: closed-loop evaluations per second through the FMUs.

Evaluates the same batch of distinct laws (random parameters of the basic law and random
variations of it, as the GA produces them) with 1 and 2 local workers and on a Dask
LocalCluster of 2 single-threaded worker processes.  Goal: >= 100 evaluations/s on 2 cores
(the paper's budget, population 1000 x 200 generations, in well under an hour).

    python benchmarks/evaluator.py [--n 600] [--fmus DIR] [--json]
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path


from descent_fmus.synthesis.run.evaluation import Evaluator
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.methods.registry import make_method

PROBLEM = get_problem("reentry")


def laws(n: int, seed: int = 0):
    # the GA's initial population: basis + random variations and q
    return [c.law for c in make_method("network-operator",
                                       PROBLEM.tuned(population=n, seed=seed)).ask()]


def rate(batch, fmus, **kw) -> float:
    with Evaluator(PROBLEM, fmus, **kw) as ev:
        ev.evaluate(batch[:8])                      # start-up (imports, FMU loading)
        ev.cache.clear()
        n0, t0 = ev.simulated, time.perf_counter()
        ev.evaluate(batch)                          # duplicates are simulated once
        return (ev.simulated - n0) / (time.perf_counter() - t0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=600)
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    batch = laws(args.n)
    out = {"1 worker (in-process)": rate(batch, args.fmus),
           "2 local workers": rate(batch, args.fmus, workers=2)}
    from distributed import LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        out["Dask LocalCluster (2 workers)"] = rate(batch, args.fmus,
                                                    scheduler=cluster.scheduler_address)
    if args.json:
        print(json.dumps(out, indent=1))
        return
    base = out["1 worker (in-process)"]
    print(f"closed-loop reentry evaluations through the FMUs, batch of {args.n} distinct laws")
    for name, r in out.items():
        print(f"  {name:32s} {r:7.1f} evaluations/s   speed-up {r / base:4.2f}x")
    paper = 1000 * 200
    best = max(out.values())
    print(f"  paper's budget (population 1000 x 200 generations = {paper} evaluations): "
          f"{paper / best / 60:.1f} min at the best rate")


if __name__ == "__main__":
    main()
