#!/usr/bin/env python
"""S5: the network operator against a fixed-structure CMA-ES baseline on the same budget.

The baseline is CMA-ES over the 8 gains of the designer's basic law (the GA's first basic
solution), every candidate flown from the 5 initial states by the same FMU evaluator; its target
is J1 (sum of |hf - h(tf)| + penalties over the initial set).  A polynomial or a tanh network in
the 4 controller inputs with 2 outputs does not fit the generic controller FMU (32 nodes, 16
parameters), so they are not run here.  The network operator's run is ``synthesize
lunar-descent`` with its default budget (run it separately, or pass ``--network-operator DIR``
to read its summary); the baseline gets as many evaluations as that run simulated.

    python benchmarks/lunar_descent_search.py --flights 8664 --seed 1 --out runs/s5_cma
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def basic_gains() -> dict:
    from descent_fmus.synthesis.systems.lunar_descent.problems import synthesis_basic_law
    return {"basic": synthesis_basic_law()}


def main(argv=None):
    from descent_fmus.synthesis.methods.pareto import Target
    from descent_fmus.synthesis.paths import fmu_dir
    from descent_fmus.synthesis.registry import get_problem
    from descent_fmus.synthesis.run.loop import run_synthesis

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flights", type=int, default=8664,
                    help="law evaluations (5 flights each) of the baseline")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "lunar_descent_cma")
    ap.add_argument("--network-operator", type=Path, default=None,
                    help="folder of a finished synthesize lunar-descent run to compare with")
    ap.add_argument("--fmus", type=Path, default=None)
    args = ap.parse_args(argv)
    problem = get_problem("lunar-descent").with_(target=Target(0), baselines=basic_gains)
    problem = problem.tuned(seed=args.seed, flights=args.flights)
    s = run_synthesis(problem, args.out, args.fmus or fmu_dir(), workers=args.workers,
                      resume=(args.out / "checkpoint.json").exists(), progress=True,
                      export=False, reference=False, method="cma-basic")
    best = min(s["pareto"], key=lambda r: r["J1"])
    print(f"cma-basic (seed {args.seed}): {s['flights']} law evaluations in {s['seconds']:.0f} s; "
          f"best J1 = {best['J1']:.3f} m (J2 = {best['J2']:.2f} m/s, in box "
          f"{best.get('in_box')}/5), front of {len(s['pareto'])} laws")
    if args.network_operator:
        no = json.loads((args.network_operator / "summary.json").read_text())
        nb = min(no["pareto"], key=lambda r: r["J1"])
        print(f"network operator: {no['simulated']} law evaluations; best J1 = {nb['J1']:.3f} m "
              f"(J2 = {nb['J2']:.2f} m/s)")


if __name__ == "__main__":
    main()
