"""Benchmark: does the S1 search run at the evaluator's pace?

Runs ``descent-fmus synthesize reentry`` (the default problem and budget, one seed, the bound
skipped: ``--no-reference``) ``--repeat`` times and prints, per run and as medians:

* the search's laws per second (laws flown / the search phase's wall seconds);
* the flights' own time: the workers' measured compute seconds per law, summed, over the
  number of workers (what the search would take if the method cost nothing), and the seconds
  the main process waited for the workers;
* the ratio search wall / flights' own time (target <= 2) and the laws/s target (>= 5 000 on 2
  workers), beside the ceiling the flights set: laws / their own time (the pace of a search
  whose method cost nothing);
* the phase split (scaling, search, checkpoints, export, report), with the export's share of
  the whole command;
* the main process's CPU seconds over the whole command (``getrusage``, the workers not
  counted): the search's own work, less inflated by other jobs on the cores than its wall time;
  and its main thread's alone (``RUSAGE_THREAD``): the serial part, where the process's other
  threads (the small batches' second C master, the pool's threads, pycma's import) run beside it.

Timings are measured, never asserted; the machine's load average is printed beside them.

With ``--before REV`` each run is followed by the same run on the code of git revision REV
(interleaved A/B: the load drifts alike for both), and both medians are printed.

    python benchmarks/search_pace.py [--flights N] [--seed S] [--workers W] [--repeat R]
                                     [--before REV] [--json]

Needs ``python build_fmus.py``.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from run_phases import source_tree  # noqa: E402  (the code of a git revision)

PHASES = ("scaling", "search", "checkpoints", "export", "report")
#: The command line run in a process that reports its own CPU seconds at the end (the main
#: process's, without the workers': a figure that grows less with other jobs' load than the
#: wall time does).
_CPU_WRAPPER = ("import resource, sys\n"
                "from descent_fmus.synthesis.cli.main import main\n"
                "try:\n    rc = main(sys.argv[1:])\nexcept SystemExit as stop:\n"
                "    rc = stop.code\n"
                "r = resource.getrusage(resource.RUSAGE_SELF)\n"
                "print('main-process-cpu', r.ru_utime + r.ru_stime, file=sys.stderr)\n"
                "r = resource.getrusage(resource.RUSAGE_THREAD)\n"
                "print('main-thread-cpu', r.ru_utime + r.ru_stime, file=sys.stderr)\n"
                "sys.exit(rc)\n")


def run(out: Path, args, source: Path | None = None) -> dict:
    """One run's figures (see the module docstring); ``source``: the code of
    :func:`run_phases.source_tree` instead of this checkout's."""
    cmd = [sys.executable, "-c", _CPU_WRAPPER, "synthesize", "reentry",
           "--workers", str(args.workers), "--out", str(out), "--no-reference", "--quiet",
           "--json"]
    if args.seed is not None:
        cmd += ["--seed", str(args.seed)]
    if args.flights:
        cmd += ["--flights", str(args.flights)]
    env = dict(os.environ)
    if source is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(source), env.get("PYTHONPATH", "")])
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if res.returncode != 0:
        raise SystemExit(f"synthesize failed ({res.returncode}):\n{res.stderr[-3000:]}")
    s = json.loads(res.stdout)
    t, fl = s["timings"], s["flight_seconds"]
    cpu = [float(line.split()[1]) for line in res.stderr.splitlines()
           if line.startswith("main-process-cpu ")]
    thread = [float(line.split()[1]) for line in res.stderr.splitlines()
              if line.startswith("main-thread-cpu ")]
    return {"wall": wall, "load": load, "laws": s["simulated"], "main_cpu": cpu[-1],
            "main_thread_cpu": thread[-1],
            "laws_per_s": s["simulated"] / t["search"], "own": fl["own"], "waited": fl["waited"],
            "ratio": t["search"] / max(fl["own"], 1e-9),
            "ceiling": s["simulated"] / max(fl["own"], 1e-9),
            "export_share": t.get("export", 0.0) / wall,
            **{k: t.get(k, 0.0) for k in PHASES}}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flights", type=int, default=0, help="flight budget (default: the problem's)")
    ap.add_argument("--seed", type=int, default=None, help="default: the problem's")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--before", metavar="REV", default=None,
                    help="also the code at git revision REV (e.g. main), runs interleaved "
                         "with this checkout's: before and after side by side")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    runs, before = [], []
    with tempfile.TemporaryDirectory() as tmp:
        source = source_tree(args.before, Path(tmp)) if args.before else None
        for i in range(args.repeat):
            runs.append(run(Path(tmp) / f"run{i}", args))
            if source is not None:
                before.append(run(Path(tmp) / f"before{i}", args, source))
    keys = ("wall", "laws", "laws_per_s", "ceiling", "own", "waited", "ratio", "main_cpu",
            "main_thread_cpu", "export_share") + PHASES
    med = {k: statistics.median(r[k] for r in runs) for k in keys}
    out = {"runs": runs, "median": med, "workers": args.workers}
    if before:
        out.update(before_rev=args.before, before_runs=before,
                   before_median={k: statistics.median(r[k] for r in before) for k in keys})
    if args.json:
        print(json.dumps(out, indent=1))
        return out
    print(f"S1 search, {args.workers} workers, seed {args.seed or 'of the problem'}, "
          f"{len(runs)} run(s)" + (f", interleaved with {args.before}'s" if before else ""))
    rows = [(f"load {r['load']:.1f}", r) for r in runs] + [("median", med)]
    if before:
        rows = [(f"this, load {r['load']:.1f}", r) for r in runs] + [("this, median", med)] \
            + [(f"{args.before}, load {r['load']:.1f}", r) for r in before] \
            + [(f"{args.before}, median", out["before_median"])]
    for tag, r in rows:
        print(f"  [{tag}] {r['laws']:.0f} laws: search {r['search']:.1f} s = "
              f"{r['laws_per_s']:.0f} laws/s (target >= 5000; the flights' ceiling "
              f"{r['ceiling']:.0f}); flights' own time "
              f"{r['own']:.1f} s, waited {r['waited']:.1f} s; search / own = {r['ratio']:.2f} "
              f"(target <= 2); the main process's CPU {r['main_cpu']:.1f} s (its main "
              f"thread {r['main_thread_cpu']:.1f} s); export {r['export']:.1f} s ({100 * r['export_share']:.0f} % of "
              f"{r['wall']:.1f} s); " + ", ".join(f"{k} {r[k]:.1f}" for k in PHASES
                                                    if k not in ("search", "export")))
    return out


if __name__ == "__main__":
    main()
