#!/usr/bin/env python
"""S4 benchmark: run times of the direct method beside the thesis' figures (Voronov 2009).

Prints, with the median of several solves where it is cheap:

* Example 1 (rigid) and Example 2 (flexible, reduced algorithm): iterations, wall time and the
  ratio to the thesis' 1.7 s (Athlon 64 3000+, 1 core, 1.8 GHz); the FMU replay time if the FMUs
  are built ($DESCENT_FMUS_DIR or fmus/);
* Example 1 with the gimbal-rate limit 0.1 rad/s and with the minimum-energy option: iterations,
  time, max |u|, int |u|^2 dt (beside 0.552 of the plain method and 0.251 of CasADi + IPOPT);
* Example 3, the route: the route craft's reorientation, the trace by halving and by the
  adaptive rule (stages beside the thesis' 32, stage solves, time, max deviation), with the rate
  limit 0.03 rad/s, and the FMU replay.

No assertions.  The machine's load changes wall times: run it alone, e.g. with
``OPENBLAS_NUM_THREADS=1`` (the matrices are small; BLAS threads only contend).

Usage: ``python benchmarks/telescope.py [--repeat N] [--fmus DIR] [--no-route]``.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.systems.telescope.reorientation import (ENERGY_REFERENCE,
                                                                    PAPER_ITERATIONS,
                                                                    PAPER_SECONDS,
                                                                    U_MAX_DEFAULT, replay,
                                                                    reorient)


def _examples_1_2(args, fmus):
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
        else:
            print(f"{'':24s}  max |u| {abs(r.controls).max():.4f} rad/s, int |u|^2 dt "
                  f"{r.energy:.4f}")
        if (fmus / "ProgramController.fmu").is_file():
            rep = replay(ro, fmus)
            print(f"{'':24s}  FMU replay (fmpy, step 0.5 s): {rep['replay_seconds']:.3f} s, "
                  f"error vs target {rep['replay_error_vs_target']:.1e}")


def _options():
    for tag, kw in (("rate limit 0.1 rad/s", dict(u_max=U_MAX_DEFAULT)),
                    ("minimum energy", dict(min_energy=True)),
                    ("both", dict(u_max=U_MAX_DEFAULT, min_energy=True))):
        ro = reorient(**kw)
        r = ro.result
        print(f"{tag:24s}: {r.iterations} iterations, miss {r.max_miss:.1e}, "
              f"{r.seconds:.2f} s; max |u| {abs(r.controls).max():.4f} rad/s, int |u|^2 dt "
              f"{r.energy:.4f} (CasADi + IPOPT: {ENERGY_REFERENCE}; target <= "
              f"{1.05 * ENERGY_REFERENCE:.3f})")


def _route(fmus):
    from descent_fmus.synthesis.systems.telescope.route import (PAPER_STAGES, make_route,
                                                                replay_route, trace)
    t0 = time.perf_counter()
    route = make_route()
    print(f"route (Example 3): the route craft's reorientation {time.perf_counter() - t0:.2f} s "
          f"({route.result.iterations} iterations); thesis: {PAPER_STAGES} stages")
    for rule, joints, u_max in (("halving", "continuous", None), ("adaptive", "continuous", None),
                                ("halving", "zero", None), ("halving", "continuous", 0.03),
                                ("adaptive", "continuous", 0.03)):
        rt = trace(route=route, rule=rule, joints=joints, u_max=u_max)
        s = rt.summary()
        print(f"  {rule:8s} {joints:10s} u_max {str(u_max):5s}: {s['stages']:3d} stages, "
              f"{s['stage_solves']:3d} stage solves, {s['seconds']:6.2f} s, max deviation "
              f"{s['max_deviation']:.2e} ({s['max_relative_deviation']:.3f} eps), max |u| "
              f"{s['u_peak']:.4f}")
        if (fmus / "ProgramController.fmu").is_file() and rule == "halving" and u_max is None \
                and joints == "continuous":
            rep = replay_route(rt, fmus)
            print(f"  {'':37s}FMU replay: {rep['replay_seconds']:.2f} s for "
                  f"{rep['replay_points']} steps of {rep['replay_step']:.4f} s, max deviation "
                  f"{rep['replay_max_deviation']:.2e}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--fmus", type=Path, default=None,
                    help="folder of the built FMUs (default: fmus/ or $DESCENT_FMUS_DIR)")
    ap.add_argument("--no-route", action="store_true", help="skip Example 3")
    args = ap.parse_args(argv)
    fmus = args.fmus or fmu_dir()
    reorient()  # warm-up (imports, caches)
    _examples_1_2(args, fmus)
    _options()
    if not args.no_route:
        _route(fmus)
    return 0


if __name__ == "__main__":
    sys.exit(main())
