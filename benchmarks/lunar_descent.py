"""Benchmark: S5 closed-loop cost -- one flight in-process vs through the FMUs, and laws/s of
the GA's evaluator (5 flights per law) on one worker.

    python benchmarks/lunar_descent.py [--n 40] [--fmus DIR] [--json]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.run.evaluation import Evaluator
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.systems.lunar_descent.problems import INITIAL_SET
from descent_fmus.synthesis.systems.lunar_descent.study import fly_in_process


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=40, help="distinct laws to evaluate")
    ap.add_argument("--fmus", type=Path, default=None,
                    help="folder of the built FMUs (default: fmus/ or $DESCENT_FMUS_DIR)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    prob = get_problem("lunar-descent")
    basic = prob.basic()
    t0 = time.perf_counter()
    for th, h0 in INITIAL_SET:
        fly_in_process(basic, th, h0)
    in_process = (time.perf_counter() - t0) / len(INITIAL_SET)
    rng = np.random.default_rng(0)
    laws = [basic.with_q(np.array(basic.q) * (1 + 0.05 * rng.standard_normal(len(basic.q))))
            for _ in range(args.n)]
    with Evaluator(prob, args.fmus or fmu_dir()) as ev:
        ev.evaluate([basic])                       # load and warm up
        t0 = time.perf_counter()
        ev.evaluate(laws)
        dt = time.perf_counter() - t0
    out = {"flight_in_process_s": in_process, "law_through_fmus_s": dt / args.n,
           "flight_through_fmus_s": dt / args.n / len(INITIAL_SET), "laws_per_s": args.n / dt}
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(f"one flight in-process {in_process * 1e3:.1f} ms, through the FMUs "
              f"{out['flight_through_fmus_s'] * 1e3:.1f} ms "
              f"(x{out['flight_through_fmus_s'] / in_process:.2f}); "
              f"{out['laws_per_s']:.1f} laws/s on one worker (5 flights per law)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
