"""Benchmark: the cost of S1's on-board re-planning, in Python and native, against the single correction c.

Flies the committed guided law through the FMUs on the first ``--samples`` held-out samples of
each error family, once with the single correction (replan = 0) and once re-planned
(replan = 1), each on two paths -- the pythonfmu controller on the Python master (the
re-planner's linear programmes SciPy's HiGHS) and the native twins under the C master (the
re-planner in C, ``lp.h``) -- in interleaved rounds, and prints per path and guidance the median
CPU time and wall time of a flight, and the ratios.  Then one linear programme of the
re-planner's size (K = 9 weights, ~280 load samples) solved by HiGHS and by ``lp.h``.  CPU time
is the robust number on a machine shared with other jobs.

    python benchmarks/reentry_robust_replan.py [--errors spec scale-height] [--samples 8]
        [--repeat 2] [--fmus DIR] [--json]
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.fmi.loop import open_loop
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.systems.reentry.error_families import FAMILIES, family_samples
from descent_fmus.synthesis.systems.reentry.guidance import GUIDED_WIRING, default_guided_law
from descent_fmus.synthesis.systems.reentry.wiring import plant_values

OPTIONS = {"single correction c (replan = 0)": {"replan": 0},
           "re-planned (replan = 1)": {"replan": 1}}


def _loops(fmus: Path) -> dict:
    """The two paths: the pythonfmu FMUs on the Python master, the native twins on the C
    master (absent without a compiler or the twins)."""
    loops = {"pythonfmu, Python master": open_loop(GUIDED_WIRING, fmus / "Reentry.fmu",
                                                   fmus / "GuidedNetworkOperatorController.fmu",
                                                   "master")}
    native = fmus / "native"
    if (native / "GuidedNetworkOperatorController.fmu").is_file():
        try:
            loops["native, C master"] = open_loop(
                GUIDED_WIRING, native / "Reentry.fmu",
                native / "GuidedNetworkOperatorController.fmu", "native-c")
        except Exception as exc:                 # no compiler: the Python path alone
            print(f"native path skipped: {exc}")
    return loops


def _lp_rates(repeat: int = 200) -> dict:
    """Median seconds of one re-planner-sized programme with HiGHS and with lp.h."""
    from scipy.optimize import linprog

    from descent_fmus.models.controllers.reentry_replan import PLAN_KNOTS, lp_problems
    from descent_fmus.synthesis.systems.reentry.native.onboard_lp import linprog_c
    rng = np.random.default_rng(1)
    k = len(PLAN_KNOTS)
    problems = [lp_problems(rng.normal(0.0, 300.0), rng.uniform(3.0, 10.0, 280),
                            rng.normal(0.0, 3e3, k), rng.normal(0.0, 3.0, (280, k)),
                            rng.uniform(-0.3, 0.3, k), 0.3, 0.1, 0.02, 5.0)[0]
                for _ in range(repeat)]
    out = {}
    for name, solve in (("HiGHS (SciPy)", lambda kw: linprog(**kw, method="highs")),
                        ("lp.h (ctypes call)", lambda kw: linprog_c(**kw))):
        solve(problems[0])
        t = []
        for kw in problems:
            t0 = time.perf_counter()
            solve(kw)
            t.append(time.perf_counter() - t0)
        out[name] = statistics.median(t)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--errors", nargs="+", default=["spec", "scale-height"], choices=FAMILIES)
    ap.add_argument("--samples", type=int, default=8)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    law = default_guided_law().start_values()
    samples = [s for f in args.errors for s in family_samples(f, args.samples, 7)]
    loops = _loops(args.fmus)
    times = {(p, n): {"cpu": [], "wall": []} for p in loops for n in OPTIONS}
    try:
        for _ in range(args.repeat):
            for s in samples:
                for (path, name), rows in times.items():      # interleaved
                    cv = {**law, **s.sensing, **OPTIONS[name], "h0_line": s.plant.h0}
                    w0, c0 = time.perf_counter(), time.process_time()
                    try:
                        loops[path].run(plant_values(s.plant), cv)
                    except KeyError as exc:           # FMUs built before the re-planner
                        raise SystemExit(f"{exc.args[0]}: rebuild the FMUs "
                                         f"(python build_fmus.py)") from None
                    rows["cpu"].append(time.process_time() - c0)
                    rows["wall"].append(time.perf_counter() - w0)
    finally:
        for loop in loops.values():
            loop.close()
    flights = {f"{p} | {n}": {"cpu_s": statistics.median(v["cpu"]),
                              "wall_s": statistics.median(v["wall"])}
               for (p, n), v in times.items()}
    lp = _lp_rates()
    out = {"flights": flights, "lp_s": lp}
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    print(f"{len(samples)} flights x {args.repeat} ({', '.join(args.errors)}), medians:")
    for n, r in flights.items():
        print(f"  {n:62s} CPU {r['cpu_s'] * 1e3:8.2f} ms  wall {r['wall_s'] * 1e3:8.2f} ms")
    py, nat = "pythonfmu, Python master", "native, C master"
    if nat in loops:
        for n in OPTIONS:
            ratio = flights[f"{py} | {n}"]["cpu_s"] / flights[f"{nat} | {n}"]["cpu_s"]
            print(f"  native / pythonfmu speed-up, {n}: {ratio:.1f}x (CPU)")
        cost = flights[f"{nat} | re-planned (replan = 1)"]["cpu_s"] / \
            flights[f"{nat} | single correction c (replan = 0)"]["cpu_s"]
        print(f"  native: a re-planned flight costs {cost:.1f}x a single-correction flight")
    print("one re-planner programme (9 weights, 280 load rows), median:")
    for n, t in lp.items():
        print(f"  {n:20s} {t * 1e3:.3f} ms")
    print(f"  HiGHS / lp.h: {lp['HiGHS (SciPy)'] / lp['lp.h (ctypes call)']:.1f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
