"""Benchmark: the cost of S1's on-board re-planning against the single correction c.

Flies the committed guided law through the FMUs (Reentry + GuidedNetworkOperatorController,
the Python master) on the first ``--samples`` held-out samples of each error family, once with
the single correction (replan = 0) and once re-planned (replan = 1), in interleaved rounds, and
prints per guidance the median CPU time and wall time of a flight.  CPU time is the robust
number on a machine shared with other jobs.

    python benchmarks/reentry_robust_replan.py [--errors spec scale-height] [--samples 8]
        [--repeat 2] [--fmus DIR] [--json]
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.systems.reentry.error_families import FAMILIES, family_samples
from descent_fmus.synthesis.systems.reentry.guidance import GUIDED_WIRING, default_guided_law
from descent_fmus.synthesis.systems.reentry.wiring import plant_values

OPTIONS = {"single correction c (replan = 0)": {"replan": 0},
           "re-planned (replan = 1)": {"replan": 1}}


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
    times = {n: {"cpu": [], "wall": []} for n in OPTIONS}
    with ClosedLoop(GUIDED_WIRING, args.fmus / "Reentry.fmu",
                    args.fmus / "GuidedNetworkOperatorController.fmu") as loop:
        for _ in range(args.repeat):
            for s in samples:
                for name, params in OPTIONS.items():      # interleaved
                    cv = {**law, **s.sensing, **params, "h0_line": s.plant.h0}
                    w0, c0 = time.perf_counter(), time.process_time()
                    try:
                        loop.run(plant_values(s.plant), cv)
                    except KeyError as exc:           # FMUs built before the re-planner
                        raise SystemExit(f"{exc.args[0]}: rebuild the FMUs "
                                         f"(python build_fmus.py)") from None
                    times[name]["cpu"].append(time.process_time() - c0)
                    times[name]["wall"].append(time.perf_counter() - w0)
    out = {n: {"cpu_s": statistics.median(v["cpu"]), "wall_s": statistics.median(v["wall"])}
           for n, v in times.items()}
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"{len(samples)} flights x {args.repeat} ({', '.join(args.errors)}), medians:")
        for n, r in out.items():
            print(f"  {n:34s} CPU {r['cpu_s']:.2f} s  wall {r['wall_s']:.2f} s per flight")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
