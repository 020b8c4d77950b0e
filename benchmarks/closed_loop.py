"""Benchmark: one closed-loop reentry flight through the FMUs vs the same code in-process.

Prints the median wall time of a flight (FMU instances reused: reset + new start values per run)
and the ratio to the in-process run of the same functions (models.reentry.ReentryIntegrator and
the network-operator evaluation, no FMI).  Goal: <= 20 ms per flight, ratio <= 2.

    python benchmarks/closed_loop.py [--repeat N] [--fmus DIR]
"""
from __future__ import annotations

import argparse
import json
import statistics
import timeit
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

from descent_fmus.models.reentry import ReentryParams, deviations, simulate
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.systems.reentry import wiring as spec
from descent_fmus.synthesis.systems.reentry.flight import fly, load_loop
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law, paper_law


def timed(fn, repeat):
    return statistics.median(timeit.repeat(fn, number=1, repeat=repeat))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=30)
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    p = ReentryParams()
    rows = {}
    with load_loop(args.fmus, record=()) as loop:
        for name, law in (("basic law", paper_basic_law()),
                          ("paper 16-node law", paper_law())):
            fly(law, loop=loop)  # warm-up
            t_fmu = timed(lambda: fly(law, loop=loop), args.repeat)
            t_py = timed(lambda: simulate(p, lambda t, x: law(deviations(x, p))[0],
                                          step=spec.STEP), args.repeat)
            rows[name] = {"fmu_ms": t_fmu * 1e3, "in_process_ms": t_py * 1e3,
                          "ratio": t_fmu / t_py, "flights_per_s": 1.0 / t_fmu}
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    print(f"closed-loop reentry flight (~272 s simulated, step {spec.STEP} s, RK4 sub-step 0.5 s)")
    print(f"{'law':20s} {'FMU [ms]':>10s} {'in-proc [ms]':>13s} {'ratio':>7s} {'flights/s':>10s}")
    for name, r in rows.items():
        print(f"{name:20s} {r['fmu_ms']:10.2f} {r['in_process_ms']:13.2f} {r['ratio']:7.2f} "
              f"{r['flights_per_s']:10.1f}")


if __name__ == "__main__":
    main()
