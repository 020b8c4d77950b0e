"""Benchmark: S3 shooting solves and landing closed loops through the FMUs (no assertions).

Prints, for each switch method and each of the paper's three guesses, the median solve time,
the Newton iterations and the integrations per second; the closed-form oracle's time; the
median time of one closed-loop landing through the FMUs (program, feedback) with the rate in
communication steps per second, the in-process rate of the same code for comparison, and the
wall time of a dispersion study.

    python benchmarks/lunar_landing.py [--repeat N] [--fmus DIR] [--dispersion N] [--json]

References: Mozzhorina (2017), Table 1 guesses.
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from descent_fmus.models.lunar_landing import optimal_landing
from descent_fmus.synthesis.methods.shooting import solve
from descent_fmus.synthesis.systems.lunar_landing.problems import PAPER_GUESSES, landing_problem
from descent_fmus.synthesis.systems.lunar_landing.study import (LandingLoops, dispersion,
                                                                fly_feedback_in_process)


def timed(fn, repeat):
    ts, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), out


def in_process_feedback():
    return fly_feedback_in_process()[1]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--fmus", type=Path, default=None,
                    help="folder of the built FMUs (default: fmus/ of the checkout, or "
                         "$DESCENT_FMUS_DIR)")
    ap.add_argument("--dispersion", type=int, default=40)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    out = {"solves": []}
    pb = landing_problem()
    for method in ("interpolate", "event"):
        for g in PAPER_GUESSES:
            t, res = timed(lambda: solve(pb, g, method=method), args.repeat)
            row = dict(method=method, guess=list(g), seconds=t, iterations=res.iterations,
                       integrations=res.evaluations, integrations_per_s=res.evaluations / t,
                       residual=res.residual_norm)
            out["solves"].append(row)
            if not args.json:
                print(f"shooting {method:11} guess {str(g):22} {t * 1e3:8.1f} ms  "
                      f"{res.iterations} Newton its, {res.evaluations} integrations "
                      f"({res.evaluations / t:6.0f}/s), max|r| = {res.residual_norm:.1e}")
    t, _ = timed(optimal_landing, args.repeat * 20)
    out["closed_form_seconds"] = t
    if not args.json:
        print(f"closed-form optimum (oracle): {t * 1e6:.0f} us")
    t_ip, steps = timed(in_process_feedback, args.repeat)
    out["in_process_feedback"] = dict(seconds=t_ip, steps=steps, steps_per_s=steps / t_ip)
    t0 = time.perf_counter()
    with LandingLoops(args.fmus) as loops:
        load = time.perf_counter() - t0
        out["load_seconds"] = load
        for law in ("program", "feedback"):
            t, (td, res) = timed(lambda: loops.fly(law), args.repeat)
            out[law] = dict(seconds=t, steps=res.steps, steps_per_s=res.steps / t,
                            V_touchdown=td.V_touchdown)
            if not args.json:
                print(f"closed loop {law:8} (FMUs, fmpy master): {t * 1e3:7.1f} ms per landing, "
                      f"{res.steps} steps ({res.steps / t:7.0f} steps/s), "
                      f"V_td = {td.V_touchdown:+.4f} m/s")
        if not args.json:
            print(f"feedback in-process (same functions, no FMI): {t_ip * 1e3:7.1f} ms "
                  f"({steps / t_ip:7.0f} steps/s); FMU/in-process = "
                  f"{out['feedback']['seconds'] / t_ip:.2f}; FMU load {load * 1e3:.0f} ms")
        t0 = time.perf_counter()
        rows = dispersion(loops, n=args.dispersion)
        td = time.perf_counter() - t0
        out["dispersion"] = dict(starts=len(rows), seconds=td,
                                 landings_per_s=2 * len(rows) / td)
        if not args.json:
            print(f"dispersion: {len(rows)} starts x 2 laws in {td:.2f} s "
                  f"({2 * len(rows) / td:.1f} landings/s)")
    if args.json:
        print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
