"""Benchmark: where the README's main job spends its time, on a fresh machine and on a warm one.

Runs ``descent-fmus synthesize reentry`` (the default problem and budget, one seed) twice in
the same session on the native FMUs and prints the phase split of each from its
``summary.json`` (``timings``), side by side:

* **native, cold cache** -- an empty cache folder (``$DESCENT_FMUS_CACHE``): what a fresh
  machine's first run pays -- the S1 bounds (read from the package's shipped copy when its
  content key is current, else solved), the C master's and the interpreter law FMU's compiles,
  every Pareto law's readable formula;
* **native, warm cache** -- the same command again with the cache the first run left.

With ``--pythonfmu`` a run on the pythonfmu FMUs only (a folder without ``native/``, the Python
master, its own empty cache) comes first.  The phases: scaling (the input scaling from the basic
law's flights), search (the GA and CMA-ES with their flights), checkpoints, reference (the
open-loop bound), export (the Pareto laws' files and FMUs), report (formulas, CSV/JSON, figure),
other (the wall time outside them: start-up and imports, the workers' start and stop, the
summary).  Targets (issue #41): cold <= 15 s, warm <= 10 s on 2 cores, the best law with miss
< 1 km <= 1.0005 x the bound.  The load average is printed before and after each run.

With ``--before REV`` the same command on the code of git revision REV (``git archive`` into a
temporary folder, first on ``PYTHONPATH``; this checkout's FMUs, cache and environment) runs
after the warm run, as one more column: before and after side by side.

    python benchmarks/run_phases.py [--flights N] [--seed S] [--workers W] [--pythonfmu]
                                    [--before REV] [--json]

Needs ``python build_fmus.py`` (with the native twins) and a C compiler.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from descent_fmus.synthesis.paths import fmu_dir

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from native_paths import machine  # noqa: E402  (the machine line every benchmark prints)

PHASES = ("scaling", "search", "checkpoints", "reference", "export", "report")


def source_tree(rev: str, tmp: Path) -> Path:
    """The package's code at git revision ``rev`` (``git archive`` of this repository), as a
    folder to put first on ``PYTHONPATH``: the same command then runs the code before a change
    (``--before REV``), with this checkout's FMUs and virtual environment."""
    root = HERE.parent
    dest = tmp / f"src-{rev.replace('/', '_')}"
    (dest / "descent_fmus").mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(root), "archive", rev, "models", "synthesis"],
                             capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(dest / "descent_fmus")], input=archive, check=True)
    return dest


def run(fmus: Path, out: Path, cache: Path, args, source: Path | None = None) -> dict:
    """One ``synthesize reentry`` run: its summary, with the wall time of the whole command
    (``source``: the code of :func:`source_tree` instead of this checkout's)."""
    cmd = [sys.executable, "-m", "descent_fmus.synthesis.cli.main", "synthesize", "reentry",
           "--seed", str(args.seed), "--workers", str(args.workers), "--fmus", str(fmus),
           "--out", str(out), "--quiet", "--json"]
    if args.flights:
        cmd += ["--flights", str(args.flights)]
    env = dict(os.environ, DESCENT_FMUS_CACHE=str(cache))
    if source is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(source), env.get("PYTHONPATH", "")])
    t0 = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if res.returncode != 0:
        raise SystemExit(f"synthesize failed ({res.returncode}):\n{res.stderr[-3000:]}")
    summary = json.loads(res.stdout)
    summary["wall"] = wall
    return summary


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--fmus", type=Path, default=None, help="FMU folder (default: fmus/)")
    p.add_argument("--flights", type=int, default=None,
                   help="flight budget (default: the problem's, 20 000)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--pythonfmu", action="store_true",
                   help="also a run on the pythonfmu FMUs only (cold cache), first")
    p.add_argument("--before", metavar="REV", default=None,
                   help="also the code at git revision REV (e.g. main), warm cache, run "
                        "after this checkout's warm run: before and after side by side")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = p.parse_args(argv)
    fmus = Path(args.fmus or fmu_dir())
    if not (fmus / "native" / "Reentry.fmu").is_file():
        raise SystemExit(f"no native twins in {fmus / 'native'}: run python build_fmus.py")
    rows, load = {}, [os.getloadavg()[0]]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if args.pythonfmu:
            python_only = tmp / "pythonfmu"
            python_only.mkdir()
            for f in fmus.glob("*.fmu"):
                shutil.copy(f, python_only / f.name)
            rows["pythonfmu, cold cache"] = run(python_only, tmp / "p", tmp / "pcache", args)
            load.append(os.getloadavg()[0])
        cache = tmp / "cache"
        rows["native, cold cache"] = run(fmus, tmp / "a", cache, args)
        load.append(os.getloadavg()[0])
        rows["native, warm cache"] = run(fmus, tmp / "b", cache, args)
        load.append(os.getloadavg()[0])
        if args.before:
            rows[f"{args.before}, warm cache"] = run(fmus, tmp / "c", cache, args,
                                                     source_tree(args.before, tmp))
            load.append(os.getloadavg()[0])
    figures = {name: {"wall": s["wall"], "flight_path": s.get("flight_path"),
                      "flights": s["flights"], "pareto_size": s["pareto_size"],
                      "J1_over_bound": s.get("ratio_to_bound"),
                      **{k: s["timings"].get(k, 0.0) for k in PHASES}}
               for name, s in rows.items()}
    for f in figures.values():      # start-up, imports, workers' start and stop, summary
        f["other"] = f["wall"] - sum(f[k] for k in PHASES)
    if args.json:
        print(json.dumps({"machine": machine(), "load_average": load, "runs": figures},
                         indent=1))
        return 0
    print(f"machine: {machine()}")
    print(f"load average (1 min) before and after each run: "
          f"{', '.join(f'{v:.2f}' for v in load)}")
    names = list(figures)
    print(f"{'phase':<12}" + "".join(f"{n:>26}" for n in names))
    for k in (*PHASES, "other", "wall"):
        print(f"{k:<12}" + "".join(f"{figures[n][k]:>14.2f} s "
                                   f"{100 * figures[n][k] / figures[n]['wall']:>5.0f} %"
                                   for n in names))
    for n in names:
        f = figures[n]
        ratio = f["J1_over_bound"]
        print(f"{n}: {f['flight_path']} path, {f['flights']} flights, {f['pareto_size']} "
              f"Pareto laws, best J1 with miss < 1 km = "
              + (f"{ratio:.5f} x the bound" if ratio is not None else "- (none)"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
