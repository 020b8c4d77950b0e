#!/usr/bin/env python
"""S4 benchmark: run time of the direct method (rigid and flexible) beside the thesis' 1.7 s.

Prints the median wall time of several solves, the iterations and the ratio to the paper's
figure (Voronov 2009, Example 1: 5 iterations, 1.7 s on an Athlon 64 3000+, 1 core, 1.8 GHz),
and the FMU replay time if the FMUs are built ($DESCENT_FMUS_DIR or fmus/).  No assertions.

Usage: ``python benchmarks/telescope.py [--repeat N] [--fmus DIR]``.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.systems.telescope.reorientation import (PAPER_ITERATIONS,
                                                                    PAPER_SECONDS, replay,
                                                                    reorient)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--fmus", type=Path, default=None,
                    help="folder of the built FMUs (default: fmus/ or $DESCENT_FMUS_DIR)")
    args = ap.parse_args(argv)
    fmus = args.fmus or fmu_dir()
    reorient()  # warm-up (imports, caches)
    print(f"paper (Voronov 2009, rigid): {PAPER_ITERATIONS} iterations to 1e-7, "
          f"{PAPER_SECONDS} s")
    for flex in (False, True):
        times, ro = [], None
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            ro = reorient(flexible=flex)
            times.append(ro.result.seconds if not flex else time.perf_counter() - t0)
        med = statistics.median(times)
        r = ro.result
        tag = "flexible (reduced alg.)" if flex else "rigid"
        solve_s = r.seconds
        print(f"{tag:24s}: {r.iterations} iterations to {ro.tol:g}, final miss "
              f"{r.max_miss:.1e}; solve {solve_s:.3f} s "
              f"(ratio to 1.7 s: {solve_s / PAPER_SECONDS:.3f})"
              + (f"; with the rigid solve + warm start and metrics {med:.3f} s median"
                 if flex else f"; median of {args.repeat}: {med:.3f} s "
                 f"(ratio {med / PAPER_SECONDS:.3f})"))
        print(f"{'':24s}  misses per iteration: "
              + ", ".join(f"{h['max_miss']:.1e}" for h in r.history))
        if flex:
            print(f"{'':24s}  rigid solution on the flexible model misses by "
                  f"{ro.rigid_on_flexible_miss:.1e}; reduced algorithm from it: "
                  f"{ro.warm_iterations} iterations")
        if (fmus / "ProgramController.fmu").is_file():
            rep = replay(ro, fmus)
            print(f"{'':24s}  FMU replay (fmpy, step 0.5 s): {rep['replay_seconds']:.3f} s, "
                  f"error vs target {rep['replay_error_vs_target']:.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
