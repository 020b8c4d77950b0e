#!/usr/bin/env python
"""Learning curves of the network operator's structure search: the best value of a problem's
target against flights, per seed, with the search's own statistics (distinct structures in the
population, how many flights went to children / to CMA-ES tuning, how often a child improved
the best law).  Every flight goes through the FMUs by the run's evaluator.

    python benchmarks/search/curves.py benchmarks/suite/parking.toml --flights 5000 --seeds 1 2 3
    python benchmarks/search/curves.py benchmarks/search/mintime.toml --flights 5000 \\
        --set forms=0 --json            # a recipe setting changed (forms=0: the old recipe)

Plants are built on first use (``python -m pythonfmu build``) into the problem file's folder's
``build/``.  Prints, per seed, the best value at a few flight marks, and the median over seeds.
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
PLANTS = {"Unicycle": ROOT / "benchmarks/suite/plants/unicycle.py",
          "LQPlant": ROOT / "benchmarks/suite/plants/lq.py",
          "CartPole": ROOT / "benchmarks/suite/plants/cartpole.py",
          "DoubleIntegrator": HERE / "plants/double_integrator.py"}


def _build(problem_file: Path) -> None:
    """Build the plant FMU the problem file names if its source is one of :data:`PLANTS`."""
    text = problem_file.read_text()
    for name, src in PLANTS.items():
        fmu = problem_file.parent / "build" / f"{name}.fmu"
        if f"build/{name}.fmu" in text and (not fmu.is_file()
                                           or fmu.stat().st_mtime < src.stat().st_mtime):
            fmu.parent.mkdir(exist_ok=True)
            subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f", str(src), "-d",
                            str(fmu.parent)], check=True, capture_output=True)


def _value(v: str):
    for cast in (int, float):
        try:
            return cast(v)
        except ValueError:
            pass
    return v


def run(problem_file: Path, flights: int, seed: int, changes: dict, fmu_dir: Path) -> dict:
    """One run: its curve [(flights, best target value)] and the search's statistics."""
    from descent_fmus.synthesis.methods.pareto import ParetoArchive
    from descent_fmus.synthesis.methods.registry import NETWORK_OPERATOR, cma_target, make_method
    from descent_fmus.synthesis.problems.files import load_problem_file
    from descent_fmus.synthesis.run.evaluation import Evaluator
    from descent_fmus.synthesis.run.loop import RunLoop
    problem = load_problem_file(problem_file, fmu_dir).tuned(
        flights=flights, seed=seed, generations=10 ** 6, **changes)
    method = make_method(NETWORK_OPERATOR, problem)
    target = cma_target(problem)
    ev = Evaluator(problem, fmu_dir, workers=1, fail_loudly=True)
    curve = []

    def boundary(loop):
        k = target.best(loop.archive.F, loop.archive.cv)
        if k is not None:
            v = float(loop.archive.F[k][target.objective])
            if not curve or v < curve[-1][1]:
                curve.append((loop.flights, v))
                print(f"seed {seed}: {loop.flights} flights, best {v:.6g}", file=sys.stderr,
                      flush=True)

    t0 = time.perf_counter()
    loop = RunLoop(method, ev.evaluate, ParetoArchive(), flights=flights, on_boundary=boundary)
    loop.run()
    ev.close()
    pop = method.pop
    keys = {method._structure_key(m) for m in pop}
    k = target.best(loop.archive.F, loop.archive.cv)
    best = loop.archive.items[k][0].law
    return {"seed": seed, "curve": curve, "flights": loop.flights,
            "seconds": time.perf_counter() - t0, "distinct_structures": len(keys),
            "population": len(pop), "stats": dict(getattr(method, "stats", {})),
            "best_formula": best.formula() if hasattr(best, "formula") else None}


def at(curve, mark):
    vals = [v for f, v in curve if f <= mark]
    return vals[-1] if vals else float("nan")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", type=Path)
    ap.add_argument("--flights", type=int, default=5000)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a recipe setting, named as on the command line (population=64)")
    ap.add_argument("--marks", type=int, nargs="+", default=[1000, 2000, 5000, 10000, 20000])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    changes = {k: _value(v) for k, v in (s.split("=", 1) for s in args.set)}
    problem_file = args.problem.resolve()
    _build(problem_file)
    fmu_dir = ROOT / "fmus"
    runs = [run(problem_file, args.flights, s, changes, fmu_dir) for s in args.seeds]
    marks = [m for m in args.marks if m <= args.flights] + [args.flights]
    marks = sorted(set(marks))
    table = {m: [at(r["curve"], m) for r in runs] for m in marks}
    out = {"problem": str(args.problem), "changes": changes, "runs": runs,
           "median": {m: statistics.median(v) for m, v in table.items()}}
    if args.json:
        print(json.dumps(out))
        return 0
    for r in runs:
        print(f"seed {r['seed']}: " + "  ".join(f"{m}: {at(r['curve'], m):.4g}" for m in marks)
              + f"  ({r['seconds']:.0f} s, {r['distinct_structures']}/{r['population']} "
                f"distinct structures) {r['stats']}")
        print(f"   best: {r['best_formula']}")
    print("median: " + "  ".join(f"{m}: {v:.4g}" for m, v in out["median"].items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
