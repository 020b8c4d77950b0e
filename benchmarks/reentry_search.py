#!/usr/bin/env python
"""S1: the network operator against fixed-structure CMA-ES baselines on the same flight budget.

For every method (``network-operator``, ``cma-basic``, ``cma-polynomial``, ``cma-tanh``) and
seed, one ``synthesize reentry`` run through the FMUs (the same evaluator) up to the largest
mark; prints the best J1 with miss < 1 km after each mark of flights (simulated closed loops),
its ratio to the bound (the best 1 s program at miss <= 1 km), and writes the learning curves
as a PNG.  Runs are kept in ``--out`` and reused when the script is run again; a run that
stopped short of the largest mark (interrupted, or run for smaller marks) is resumed to it.

    python benchmarks/reentry_search.py                       # 3 seeds x 4 methods, 81k flights
    python benchmarks/reentry_search.py --marks 10000 20000 --seeds 1 --plot curves.png
    python benchmarks/reentry_search.py --no-run --plot curves.png   # table + plot of --out as is

On a 2-core machine a run takes about 10 min per 30 000 flights with 2 workers: the full table
(12 runs of 81 000 flights) is several hours.  Timings are measured, never asserted.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
METHODS = ("network-operator", "cma-basic", "cma-polynomial", "cma-tanh")


def best_after(curve, mark, flights=None):
    """Best J1 (miss < 1 km) among the curve's points with at most ``mark`` flights; NaN if
    none, or if the run spent fewer than ``mark`` flights (``flights``: it never got there)."""
    if flights is not None and flights < mark:
        return float("nan")
    vals = [j for n, j in curve if n <= mark]
    return min(vals) if vals else float("nan")


def main(argv=None):
    from descent_fmus.synthesis.paths import fmu_dir
    from descent_fmus.synthesis.registry import get_problem
    from descent_fmus.synthesis.run.loop import run_synthesis
    from descent_fmus.synthesis.systems.reentry.reports import bound_reference

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    ap.add_argument("--marks", type=int, nargs="+", default=[10_000, 20_000, 40_000, 81_000])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "reentry_search")
    ap.add_argument("--fmus", type=Path, default=None)
    ap.add_argument("--plot", type=Path, default=None, help="PNG of the learning curves")
    ap.add_argument("--no-run", action="store_true",
                    help="run nothing: tabulate and plot the runs in --out as they are (a mark "
                         "beyond a run's flights prints as -)")
    args = ap.parse_args(argv)
    fmus = args.fmus or fmu_dir()
    problem = get_problem("reentry")
    flights = max(args.marks)
    args.out.mkdir(parents=True, exist_ok=True)
    bound = bound_reference(args.out)[1]
    results = {}
    for method in args.methods:
        for seed in args.seeds:
            d = args.out / f"{method}-s{seed}"
            summary = d / "summary.json"
            s = json.loads(summary.read_text()) if summary.exists() else None
            if args.no_run and s is None:
                print(f"{method} seed {seed}: no run in {d}")
                continue
            if not args.no_run and s is not None and s.get("flights", 0) < flights:
                s = None                           # a shorter run: resumed to the mark
            if s is None:
                run = problem.tuned(seed=seed, flights=flights, generations=10 ** 6)
                t0 = time.perf_counter()
                s = run_synthesis(run, d, fmus, workers=args.workers,
                                  resume=(d / "checkpoint.json").exists(), progress=True,
                                  export=False, reference=False, method=method)
                print(f"{method} seed {seed}: {s['flights']} flights in "
                      f"{time.perf_counter() - t0:.0f} s ({s['evaluations_per_second']:.0f}/s)")
            results[(method, seed)] = s
    print(f"\nbest J1 with miss < 1 km after N flights (bound at miss <= 1 km: {bound:.4f}; "
          f"ratio in brackets)")
    head = f"{'method':18s} {'seed':>4s} " + " ".join(f"{m:>17d}" for m in args.marks)
    print(head)
    table = []
    for (method, seed), s in results.items():
        vals = [best_after(s["curve"], m, s.get("flights")) for m in args.marks]
        table.append({"method": method, "seed": seed,
                      "best": [None if v != v else v for v in vals],
                      "seconds": s["seconds"], "flights": s["flights"]})
        print(f"{method:18s} {seed:4d} " + " ".join(
            f"{v:9.4f} ({v / bound:.4f})" if v == v else f"{'-':>17s}" for v in vals))
    (args.out / "table.json").write_text(json.dumps({"bound": bound, "marks": args.marks,
                                                     "rows": table}, indent=1))
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, (ax, bx) = plt.subplots(1, 2, figsize=(13, 5))
        labelled = set()
        for k, method in enumerate(args.methods):
            for seed in args.seeds:
                s = results.get((method, seed))
                if not s or not s["curve"]:
                    continue
                n, j = map(list, zip(*s["curve"]))
                n.append(max(n[-1], s["flights"]))          # the step runs to the run's end
                j.append(j[-1])
                label = None if method in labelled else method
                labelled.add(method)
                ax.step(n, j, where="post", color=f"C{k}", alpha=0.8, label=label)
                bx.step(n, [v - bound for v in j], where="post", color=f"C{k}", alpha=0.8)
        ax.axhline(bound, color="k", ls="--", lw=1, label=f"bound (miss <= 1 km) {bound:.4f}")
        for a, level in ((ax, 1.005 * bound), (bx, 0.005 * bound)):
            a.axhline(level, color="k", ls=":", lw=1, label="1.005 x bound" if a is ax else None)
            a.set_xlabel("flights (closed-loop simulations)")
            a.grid(alpha=0.3, which="both")
        ax.set(ylabel="best J1 with miss < 1 km", ylim=(bound - 0.02, bound + 0.4),
               title="S1: network operator vs CMA-ES baselines, seeds "
                     f"{', '.join(map(str, args.seeds))}")
        bx.set(yscale="log", ylim=(1e-4, 1.0), ylabel="best J1 - bound",
               title="the same, above the bound (log scale)")
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=110)
        plt.close(fig)
        print(f"learning curves: {args.plot}")


if __name__ == "__main__":
    main()
