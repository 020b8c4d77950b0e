"""Benchmark: one S2 Mars closed-loop descent through the FMUs vs the same code in-process.

Prints the median wall time of a controlled descent (660.5 s simulated, communication step
0.05 s = 13 211 steps) for the averaged plant and the rigid-body plant, each through
``descent_fmus.synthesis.fmi.closed_loop.ClosedLoop`` (fmpy, FMU instances reused: reset + start values
per run), and the same functions in-process (``descent_fmus.models.mars.simulate`` with the law
of ``descent_fmus.models.controllers.mars_bellman``); plus the container FMU run by
``fmpy.simulate_fmu``.  No assertions (timings belong here, not in the tests).

    python benchmarks/mars.py [--repeat N] [--fmus DIR] [--json]
"""
from __future__ import annotations

import argparse
import json
import statistics
import timeit
from pathlib import Path

from descent_fmus.models.controllers.mars_bellman import feedback
from descent_fmus.models.mars import MarsParams, simulate
from descent_fmus.models.mars_6dof import OUTPUTS6, Mars6DOFIntegrator
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.systems.mars.flight import load_loop
from descent_fmus.synthesis.systems.mars.wiring import WIRING, WIRING_6DOF


def timed(fn, repeat):
    return statistics.median(timeit.repeat(fn, number=1, repeat=repeat))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--fmus", type=Path, default=None,
                    help="folder of the built FMUs (default: fmus/ or $DESCENT_FMUS_DIR)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    d = args.fmus or fmu_dir()
    p = MarsParams()
    step = WIRING.step
    law, law6 = feedback(), feedback(alpha_index=OUTPUTS6.index("alpha_m1"))
    rows = {}
    for name, wiring, in_proc in (
            ("averaged (MarsCapsule)", WIRING,
             lambda: simulate(p, law, step=step, record=False)),
            ("rigid body (MarsCapsule6DOF)", WIRING_6DOF,
             lambda: simulate(p, law6, step=step, record=False,
                              integrator=Mars6DOFIntegrator(p)))):
        with load_loop(d, wiring, record=()) as loop:
            loop.run()  # warm-up
            t_fmu = timed(loop.run, args.repeat)
        t_py = timed(in_proc, args.repeat)
        rows[name] = {"fmu_ms": t_fmu * 1e3, "in_process_ms": t_py * 1e3,
                      "ratio": t_fmu / t_py}
    from fmpy import simulate_fmu
    t_cont = timed(lambda: simulate_fmu(str(d / "MarsClosedLoop.fmu"), stop_time=661.0,
                                        output=["alpha"]), max(1, args.repeat // 2))
    rows["container FMU (fmpy simulate_fmu, incl. extract + instantiate)"] = {
        "fmu_ms": t_cont * 1e3}
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    n = round(660.5 / step)
    print(f"S2 controlled Mars descent: 660.5 s simulated, step {step} s ({n} steps)")
    print(f"{'plant':34s} {'FMU [ms]':>10s} {'in-proc [ms]':>13s} {'ratio':>7s} "
          f"{'us/step (FMU)':>14s}")
    for name, r in rows.items():
        if "in_process_ms" in r:
            print(f"{name:34s} {r['fmu_ms']:10.1f} {r['in_process_ms']:13.1f} "
                  f"{r['ratio']:7.2f} {r['fmu_ms'] * 1e3 / n:14.1f}")
        else:
            print(f"{name}: {r['fmu_ms']:.1f} ms")


if __name__ == "__main__":
    main()
