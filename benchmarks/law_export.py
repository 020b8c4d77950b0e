"""Benchmark: exporting the Pareto laws of a synthesis run -- interpreter vs compiled native.

A default ``synthesize reentry`` run ends with about 100 Pareto laws.  This script exports N
laws (the laws of a finished run's pareto.json, or N laws the GA's variations make from the
reentry basic law) the way ``synthesize`` does by default (law.json with the readable formula,
law.h/law.c, the native law FMU: the interpreter with the law's start values, no compile), and
the way it did before (the same files with a law FMU compiled per law, 4 threads), and prints
the export times and rates side by side (target: 100 laws <= 1 s).  The readable formulas
(SymPy) are timed apart: a run computes them in its report (pareto.csv) before the export,
which then finds them cached.  It also exports a few laws the full pythonfmu way (controller +
closed-loop FMU + SSP), a few the way ``synthesize --export all`` does (native law FMU +
closed-loop FMU + SSP, the archives written from their components' compressed members), and
times one closed-loop flight with the native law against the pythonfmu controller.

    python benchmarks/law_export.py [--laws 100] [--run DIR] [--fmus DIR] [--full 3]
                                    [--closed 20] [--json]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.fmi.law_files import export_law_files
from descent_fmus.synthesis.methods.encoding import StructureCodec
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.registry import get_problem

sys.path.insert(0, str(Path(__file__).resolve().parent))
from native_paths import machine  # noqa: E402  (the machine line every benchmark prints)


def ga_laws(n: int, seed: int = 0) -> list:
    """``n`` laws as the GA makes them: rounds of 8 structural variations of the basic law."""
    problem = get_problem("reentry")
    basic = problem.basic()
    codec = StructureCodec(basic.size, basic.nx + len(basic.q), problem.unary, problem.binary)
    rng = np.random.default_rng(seed)
    laws = []
    while len(laws) < n:
        psi = basic.psi
        for _ in range(int(rng.integers(1, 4))):
            psi = codec.apply(psi, [codec.random(rng) for _ in range(8)])
        laws.append(basic.with_structure(psi, list(rng.uniform(0.0, 16.0, len(basic.q)))))
    return laws


def export_all(laws, folder: Path, compiled: bool, problem) -> tuple[float, float]:
    """``(wall, CPU)`` seconds to export ``laws`` into ``folder/<k>`` as a run does: the
    interpreter law FMUs in one thread, the compiled ones in 4 (the run's pool while a compile
    per law waited); the CPU time of this process and of the compilers it ran (on a busy
    machine the CPU time is what a quiet one would take)."""
    def one(k):
        export_law_files(laws[k], folder / str(k), law_fmu="native", compiled=compiled,
                         identifier=f"ReentryLaw{k}", problem=problem)
    def cpu():
        kids = resource.getrusage(resource.RUSAGE_CHILDREN)
        return time.process_time() + kids.ru_utime + kids.ru_stime
    t0, c0 = time.perf_counter(), cpu()
    with ThreadPoolExecutor(max_workers=min(4, os.cpu_count() or 1) if compiled else 1) as pool:
        list(pool.map(one, range(len(laws))))
    return time.perf_counter() - t0, cpu() - c0


def folder_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in Path(path).rglob("*") if p.is_file())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--laws", type=int, default=100)
    ap.add_argument("--full", type=int, default=3, help="laws also exported the old way")
    ap.add_argument("--closed", type=int, default=20,
                    help="laws also exported with their closed loops (--export all)")
    ap.add_argument("--run", type=Path, default=None, help="a finished run: its Pareto laws")
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    problem = get_problem("reentry")
    if args.run:
        laws = [NetworkOperator.from_dict(r["law"])
                for r in json.loads((args.run / "pareto.json").read_text())][:args.laws]
    else:
        laws = ga_laws(args.laws)
    out = {}
    with tempfile.TemporaryDirectory(prefix="law_export_") as tmp:
        tmp = Path(tmp)
        export_all(laws[:1], tmp / "warm", False, problem)   # the interpreter: built or found
        export_all(laws[:1], tmp / "warm_c", True, problem)  # the wrapper's object, compiled
        t_read = []
        for law in laws:
            t1 = time.perf_counter()
            law.readable()
            t_read.append(time.perf_counter() - t1)
        t_compact, cpu_compact = export_all(laws, tmp / "compact", False, problem)
        t_compiled, cpu_compiled = export_all(laws, tmp / "compiled", True, problem)
        fmus = sorted((tmp / "compact").rglob("*.fmu"))
        sizes = [p.stat().st_size for p in fmus]
        out["laws"] = len(laws)
        out["export_s"] = t_compact
        out["export_laws_per_s"] = len(laws) / t_compact
        out["export_cpu_s"] = cpu_compact
        out["export_compiled_cpu_s"] = cpu_compiled
        out["export_compiled_s"] = t_compiled
        out["export_compiled_laws_per_s"] = len(laws) / t_compiled
        out["speedup"] = t_compiled / t_compact
        out["readable_s"] = sum(t_read)
        out["compact_total_MB"] = folder_bytes(tmp / "compact") / 2 ** 20
        out["native_fmu_KB_mean"] = statistics.mean(sizes) / 1024
        out["native_fmu_KB_max"] = max(sizes) / 1024
        out["readable_s_per_law_median"] = statistics.median(t_read)
        out["readable_s_per_law_max"] = max(t_read)
        t0 = time.perf_counter()
        for k, law in enumerate(laws[:args.full]):
            export_law_files(law, tmp / "full" / str(k), law_fmu="python", fmu_dir=args.fmus,
                             problem=problem, closed_loop=True)
        t_full = (time.perf_counter() - t0) / max(1, args.full)
        full_per_law = folder_bytes(tmp / "full") / max(1, args.full)
        out["full_python_MB_per_law"] = full_per_law / 2 ** 20
        out["full_python_s_per_law"] = t_full
        out["size_ratio_full_to_compact"] = full_per_law / (out["compact_total_MB"] * 2 ** 20
                                                            / len(laws))
        t0 = time.perf_counter()
        for k, law in enumerate(laws[:args.closed]):
            export_law_files(law, tmp / "all" / str(k), law_fmu="native", fmu_dir=args.fmus,
                             problem=problem, closed_loop=True, identifier=f"ReentryLaw{k}")
        n_all = max(1, min(args.closed, len(laws)))
        out["export_all_s_per_law"] = (time.perf_counter() - t0) / n_all
        out["export_all_MB_per_law"] = folder_bytes(tmp / "all") / n_all / 2 ** 20
        # one closed-loop flight: pythonfmu controller vs native law (the same law)
        from descent_fmus.synthesis.fmi.loop import open_loop
        law = NetworkOperator.load(Path(__file__).resolve().parent.parent / "tests" /
                                   "reference" / "reentry_best_law.json")
        native = export_law_files(law, tmp / "flight", law_fmu="native")["controller_fmu"]
        times = {}
        for name, ctrl, sv in (("pythonfmu", args.fmus / "NetworkOperatorController.fmu",
                                law.start_values()), ("native", native, {})):
            with open_loop(problem.wiring, args.fmus / "Reentry.fmu", ctrl, "master") as loop:
                loop.run(controller_values=sv)
                ts = []
                for _ in range(10):
                    t1 = time.perf_counter()
                    loop.run(controller_values=sv)
                    ts.append(time.perf_counter() - t1)
            times[name] = statistics.median(ts)
        out["flight_ms_pythonfmu_controller"] = 1e3 * times["pythonfmu"]
        out["flight_ms_native_law"] = 1e3 * times["native"]
        out["flight_speedup"] = times["pythonfmu"] / times["native"]
    out["machine"] = machine()
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(out["machine"])
        print(f"export of {out['laws']} laws (law.json, law.h/law.c, native law FMU; readable "
              f"forms cached as in a run): interpreter {out['export_s']:.2f} s "
              f"({out['export_laws_per_s']:.0f} laws/s; target: 100 laws <= 1 s) vs compiled "
              f"per law {out['export_compiled_s']:.2f} s ({out['export_compiled_laws_per_s']:.0f}"
              f" laws/s, 4 threads): {out['speedup']:.1f}x; CPU time {out['export_cpu_s']:.2f} s "
              f"vs {out['export_compiled_cpu_s']:.1f} s (the compilers included)")
        print(f"readable forms (SymPy, computed by the report before the export): "
              f"{out['readable_s']:.2f} s for {out['laws']} laws (median "
              f"{out['readable_s_per_law_median']:.3f} s, max "
              f"{out['readable_s_per_law_max']:.2f} s a law); {out['compact_total_MB']:.1f} MB")
        print(f"native law FMU: {out['native_fmu_KB_mean']:.0f} KB mean, "
              f"{out['native_fmu_KB_max']:.0f} KB max (target <= 200 KB)")
        print(f"old export (pythonfmu controller + closed loop + SSP): "
              f"{out['full_python_MB_per_law']:.2f} MB and {out['full_python_s_per_law']:.2f} s "
              f"a law -> {out['size_ratio_full_to_compact']:.0f}x the compact size")
        print(f"--export all (native law FMU + closed-loop FMU + SSP): "
              f"{out['export_all_s_per_law']:.3f} s and {out['export_all_MB_per_law']:.2f} MB "
              f"a law")
        print(f"one reentry flight: {out['flight_ms_pythonfmu_controller']:.1f} ms with the "
              f"pythonfmu controller, {out['flight_ms_native_law']:.1f} ms with the native law "
              f"({out['flight_speedup']:.1f}x)")


if __name__ == "__main__":
    main()
