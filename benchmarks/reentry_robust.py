"""Benchmark: the S1 robust problems (reentry-sensed, reentry-sensed-y12, reentry-guided).

Prints

1. the closed-loop container FMU path (instantiated once, reset per flight, one doStep over the
   horizon: ``synthesis.fmi.container_loop.ContainerLoop``) against the Python master
   (``synthesis.fmi.closed_loop.ClosedLoop``) for the same law over the 16 points of the synthesis set,
   as ratios of wall time and of CPU time (median of interleaved repetitions), for the law of
   y1, y2 (NetworkOperatorController, 3 connections) and the law reading y3
   (SensedNetworkOperatorController, 8 connections: 7 to the controller, u back) and the guided
   law (GuidedNetworkOperatorController, the same connections plus the on-board predictions);
2. evaluations/s of one robust problem (``--problem``, default reentry-sensed) (laws/s and flights/s) with 1 and 2 local workers on the
   GA's first population, with racing (most of these random laws are stopped after the nominal
   flight, so a task is one short flight) and without racing (every law flies the whole set),
   and the 2-worker / 1-worker ratios;
3. the range of the wall time of the default budget with 2 workers: every law raced out as
   often as in the first population (low) or none (high).  A run's own log gives the real
   figure; later generations fly more of the set than the first.

    python benchmarks/reentry_robust.py [--problem NAME] [--repeat N] [--fmus DIR] [--json]

On a machine shared with other jobs the wall times spread widely; the CPU-time ratio of item 1
is the robust number.
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from descent_fmus.synthesis.fmi.loop import open_loop
from descent_fmus.synthesis.run.evaluation import Evaluator
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.problems.runner import Runner
from descent_fmus.synthesis.methods.registry import make_method
from descent_fmus.synthesis.systems.reentry.problems import set_problems


def _set_times(loop, problem, law):
    sv = law.start_values()
    w0, c0 = time.perf_counter(), time.process_time()
    for s in problem.initial_states:
        loop.run(plant_values=s, controller_values=sv)
    return time.perf_counter() - w0, time.process_time() - c0


def container_vs_master(problem, fmus: Path, repeat: int) -> dict:
    plant, ctrl = problem.fmu_paths(fmus)
    law = problem.basic()
    master, container = open_loop(problem.wiring, plant, ctrl, "master"), \
        open_loop(problem.wiring, plant, ctrl, "container")
    try:
        _set_times(master, problem, law)
        _set_times(container, problem, law)          # warm-up
        m, c = [], []
        for _ in range(repeat):
            m.append(_set_times(master, problem, law))
            c.append(_set_times(container, problem, law))
    finally:
        master.close()
        container.close()
    n = len(problem.initial_states)
    mw, mc = statistics.median(t[0] for t in m), statistics.median(t[1] for t in m)
    cw, cc = statistics.median(t[0] for t in c), statistics.median(t[1] for t in c)
    return {"connections": len(problem.wiring.to_controller) + len(problem.wiring.to_plant),
            "master_ms_per_flight": 1e3 * mw / n, "container_ms_per_flight": 1e3 * cw / n,
            "master_cpu_ms_per_flight": 1e3 * mc / n,
            "container_cpu_ms_per_flight": 1e3 * cc / n,
            "speedup_wall": mw / cw, "speedup_cpu": mc / cc}


def evaluation_rate(problem, fmus: Path, workers: int) -> dict:
    laws = [c.law for c in make_method("network-operator", problem).ask()]
    with Evaluator(problem, fmus, workers=workers) as ev:
        ev.evaluate(laws[:2 * workers])               # start-up (pool, FMU loading) excluded
        todo = laws[2 * workers:]
        t0 = time.perf_counter()
        extras = ev.evaluate(todo).extras
        dt = time.perf_counter() - t0
    flights = sum(e.get("flights", len(problem.initial_states)) for e in extras)
    return {"laws": len(todo), "seconds": dt, "laws_per_s": len(todo) / dt,
            "flights_per_s": flights / dt,
            "raced_out": sum(1 for e in extras if e.get("raced_out"))}


def budget_laws(problem) -> int:
    b, ga, r = problem.budget, problem.ga, problem.refine
    epochs = b.generations // ga.epoch
    n = ga.population + r.basis + b.generations * 4 * ga.crossovers + epochs * r.laws * r.evals
    return min(n, b.flights) if b.flights else n


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--problem", default="reentry-sensed",
                    help="problem of the evaluation rates (reentry-sensed, reentry-sensed-y12, "
                         "reentry-guided)")
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    problems = {p.name: p for p in set_problems()}
    out = {"container_vs_master": {}, "evaluations": {}}
    for name, pb in problems.items():
        out["container_vs_master"][name] = container_vs_master(pb, args.fmus, args.repeat)
    if args.problem not in problems:
        raise SystemExit(f"unknown problem {args.problem!r}; choose from {', '.join(problems)}")
    pb = problems[args.problem]
    for w in (1, 2):
        out["evaluations"][f"{w} worker(s)"] = evaluation_rate(pb, args.fmus, w)
    # the same laws without racing: every law flies the whole set
    full = pb.with_(runner=Runner(container=pb.runner.container, race=None))
    for w in (1, 2):
        out["evaluations"][f"{w} worker(s), no racing"] = evaluation_rate(full, args.fmus, w)
    ev = out["evaluations"]
    out["two_workers_speedup"] = ev["2 worker(s)"]["laws_per_s"] / ev["1 worker(s)"]["laws_per_s"]
    out["two_workers_speedup_no_racing"] = (ev["2 worker(s), no racing"]["laws_per_s"]
                                            / ev["1 worker(s), no racing"]["laws_per_s"])
    n = budget_laws(pb)
    out["default_budget"] = {
        "laws": n,
        "minutes_2_workers_low": n / ev["2 worker(s)"]["laws_per_s"] / 60.0,
        "minutes_2_workers_high": n / ev["2 worker(s), no racing"]["laws_per_s"] / 60.0}
    if args.json:
        print(json.dumps(out, indent=1))
        return
    print("container FMU path vs Python master (16 flights of the synthesis set, median of "
          f"{args.repeat})")
    for name, r in out["container_vs_master"].items():
        print(f"  {name:20s} {r['connections']} connections: master "
              f"{r['master_ms_per_flight']:.1f} ms/flight, container "
              f"{r['container_ms_per_flight']:.1f} ms/flight; speed-up "
              f"wall {r['speedup_wall']:.2f}x, CPU {r['speedup_cpu']:.2f}x")
    print(f"evaluations of {pb.name} (GA's first population)")
    for k, r in out["evaluations"].items():
        print(f"  {k}: {r['laws_per_s']:.2f} laws/s, {r['flights_per_s']:.1f} flights/s "
              f"({r['laws']} laws, {r['raced_out']} raced out)")
    print(f"  2 workers / 1 worker: {out['two_workers_speedup']:.2f}x racing on, "
          f"{out['two_workers_speedup_no_racing']:.2f}x without racing")
    d = out["default_budget"]
    print(f"default budget: ~{d['laws']} laws, {d['minutes_2_workers_low']:.1f} (every law raced "
          f"as in the first population) to {d['minutes_2_workers_high']:.1f} min (no racing) "
          f"with 2 workers")


if __name__ == "__main__":
    main()
