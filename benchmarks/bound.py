"""Benchmark: the S1 bounds (zero miss, miss <= 1 km) by the old route and by the new one.

* old route: SLSQP from u = 0 with every load sample of the flight in the NLP (about 1 200
  constraints), the bound at 1 km from the zero-miss program;
* new route (:func:`synthesis.systems.reentry.bound.reference_bounds`, what ``synthesize
  reentry`` computes once and caches): the zero-miss bound from the same bound on grids 8, 4 and
  2 times coarser, only the samples near the peak in the NLP.

Both use the same flight (its sensitivities: tangent-linear RK4, vectorised over the sub-steps).
On the default scenario a third row, "shipped", is what ``synthesize reentry`` reads on a fresh
machine: the bounds shipped with the package (``bound_data.py``) when their content key is
current, with the seconds it takes to read them.
Prints each route's seconds (the median of ``--repeat`` interleaved runs), SLSQP iterations,
both bounds' values, their differences and the time ratio old / new, with the machine's load
average.  Timings are measured, never asserted.

    python benchmarks/bound.py [--scenario default|second] [--repeat N] [--json]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import time

from descent_fmus.models.reentry import SECOND_SCENARIO, ReentryParams
from descent_fmus.synthesis.systems.reentry.bound import optimize_open_loop, reference_bounds
from descent_fmus.synthesis.systems.reentry.objectives import ON_TARGET

SCENARIOS = {"default": ReentryParams(), "second": SECOND_SCENARIO}


def old_route(p: ReentryParams):
    """The bounds as computed before: from u = 0, every sample in the NLP."""
    zero = optimize_open_loop(p, near_peak=1.0)
    return zero, optimize_open_loop(p, miss_tol=ON_TARGET, u0=zero.u, near_peak=1.0)


def timed(route, p):
    t0 = time.perf_counter()
    zero, tol = route(p)
    return time.perf_counter() - t0, zero, tol


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", choices=sorted(SCENARIOS), default="default")
    ap.add_argument("--repeat", type=int, default=1, help="interleaved runs of each route")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    p = SCENARIOS[args.scenario]
    runs = {"old": [], "new": []}
    routes = {"old": old_route, "new": lambda p: reference_bounds(ON_TARGET, p)}
    load = [os.getloadavg()[0]]
    for _ in range(args.repeat):
        for name, route in routes.items():
            runs[name].append(timed(route, p))
        load.append(os.getloadavg()[0])
    out = {"scenario": args.scenario, "load_average": load}
    for name, rs in runs.items():
        _, zero, tol = rs[-1]
        out[name] = {"seconds": statistics.median(r[0] for r in rs),
                     "zero_miss": zero.J1, "miss_1km": tol.J1,
                     "iterations": [zero.info["iterations"], tol.info["iterations"]]}
    if args.scenario == "default":     # what a run reads: the bounds shipped with the package
        from descent_fmus.synthesis.systems.reentry.bound_data import bound_key, shipped_bounds
        t0 = time.perf_counter()
        shipped = shipped_bounds(bound_key())
        if shipped is not None:
            out["shipped"] = {"seconds": time.perf_counter() - t0, "zero_miss": shipped[0].J1,
                              "miss_1km": shipped[1].J1, "iterations": [0, 0]}
    out["diff_zero_miss"] = out["new"]["zero_miss"] - out["old"]["zero_miss"]
    out["diff_1km"] = out["new"]["miss_1km"] - out["old"]["miss_1km"]
    out["ratio_old_new"] = out["old"]["seconds"] / out["new"]["seconds"]
    if args.json:
        print(json.dumps(out, indent=1))
        return out
    print(f"S1 bounds, {args.scenario} scenario ({args.repeat} run(s) each, load average "
          f"{', '.join(f'{v:.2f}' for v in load)})")
    for name in ("old", "new", "shipped"):
        if name not in out:
            continue
        r = out[name]
        print(f"  {name}: {r['seconds']:7.2f} s  zero miss {r['zero_miss']:.10f}  "
              f"miss <= 1 km {r['miss_1km']:.10f}  SLSQP iterations {r['iterations']}")
    print(f"  new - old: zero miss {out['diff_zero_miss']:+.2e}, miss <= 1 km "
          f"{out['diff_1km']:+.2e};  old / new time: {out['ratio_old_new']:.2f}")
    return out


if __name__ == "__main__":
    main()
