"""Benchmark: one S2 Mars closed-loop descent through the FMUs vs the same code in-process.

Prints the median wall time of a controlled descent (660.5 s simulated, communication step
0.05 s = 13 211 steps) for the averaged plant and the rigid-body plant, each through
``synthesis.cosim.ClosedLoop`` (fmpy, FMU instances reused: reset + start values per run), and the
same functions in-process (``models.mars.simulate`` with the law of
``models.controllers.mars_bellman``); plus the container FMU run by ``fmpy.simulate_fmu``.
No assertions (timings belong here, not in the tests).

    python benchmarks/mars.py [--repeat N] [--fmus DIR] [--json]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import timeit
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from descent_fmus.models.controllers import mars_bellman as mb  # noqa: E402
from descent_fmus.models.mars import MarsParams, simulate  # noqa: E402
from descent_fmus.models.mars_6dof import OUTPUTS6, flight  # noqa: E402
from descent_fmus.synthesis.cosim import ClosedLoop  # noqa: E402
from descent_fmus.synthesis.scenarios import mars as spec  # noqa: E402


def timed(fn, repeat):
    return statistics.median(timeit.repeat(fn, number=1, repeat=repeat))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--fmus", type=Path,
                    default=Path(os.environ.get("DESCENT_FMUS_DIR", ROOT / "fmus")))
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    p = MarsParams()
    i1 = OUTPUTS6.index("alpha_m1")
    law = lambda y: mb.control(*y[:5], mb.B, mb.C, p.theta1, mb.U_MAX)[0]  # noqa: E731
    law6 = lambda y: mb.control(y[i1], y[i1 + 1], *y[2:5], mb.B, mb.C, p.theta1,  # noqa: E731
                                mb.U_MAX)[0]
    rows = {}
    for name, wiring, plant, in_proc in (
            ("averaged (MarsCapsule)", spec.WIRING, "MarsCapsule",
             lambda: simulate(p, law, step=spec.STEP, record=False)),
            ("rigid body (MarsCapsule6DOF)", spec.WIRING_6DOF, "MarsCapsule6DOF",
             lambda: simulate(p, law6, step=spec.STEP, record=False, flight=flight(p)))):
        with ClosedLoop(wiring, args.fmus / f"{plant}.fmu",
                        args.fmus / "MarsBellmanController.fmu") as loop:
            loop.run()  # warm-up
            t_fmu = timed(loop.run, args.repeat)
        t_py = timed(in_proc, args.repeat)
        rows[name] = {"fmu_ms": t_fmu * 1e3, "in_process_ms": t_py * 1e3,
                      "ratio": t_fmu / t_py}
    from fmpy import simulate_fmu
    t_cont = timed(lambda: simulate_fmu(str(args.fmus / "MarsClosedLoop.fmu"), stop_time=661.0,
                                        output=["alpha"]), max(1, args.repeat // 2))
    rows["container FMU (fmpy simulate_fmu, incl. extract + instantiate)"] = {
        "fmu_ms": t_cont * 1e3}
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    n = round(660.5 / spec.STEP)
    print(f"S2 controlled Mars descent: 660.5 s simulated, step {spec.STEP} s ({n} steps)")
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
