"""Benchmark: where the README's main job spends its time, before and after the native path.

Runs ``descent-fmus synthesize reentry`` (the default problem and budget, one seed) twice in
the same session and prints the phase split of each from its ``summary.json`` (``timings``):

* **pythonfmu, cold** -- the pythonfmu FMUs only (a folder without ``native/``: the flights
  through the Python master) and an empty reference cache (the bound computed);
* **native, warm** -- the FMUs as ``build_fmus.py`` leaves them (the native twins in fmpy's
  container FMU) and the cache as the first run left it (the bound read back).

The phases: scaling (the input scaling from the basic law's flights), search (the GA and
CMA-ES with their flights), checkpoints, reference (the open-loop bound), export (the Pareto
laws' files and FMUs), report (the rest).  Target: the native run <= 60 s wall on 2 cores with
the same result quality (its J1 / bound is printed beside the other's).

    python benchmarks/run_phases.py [--flights N] [--seed S] [--workers W] [--json]

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


def run(fmus: Path, out: Path, cache: Path, args) -> dict:
    """One ``synthesize reentry`` run: its summary, with the wall time of the whole command."""
    cmd = [sys.executable, "-m", "descent_fmus.synthesis.cli.main", "synthesize", "reentry",
           "--seed", str(args.seed), "--workers", str(args.workers), "--fmus", str(fmus),
           "--out", str(out), "--quiet", "--json"]
    if args.flights:
        cmd += ["--flights", str(args.flights)]
    env = dict(os.environ, DESCENT_FMUS_CACHE=str(cache))
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
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = p.parse_args(argv)
    fmus = Path(args.fmus or fmu_dir())
    if not (fmus / "native" / "Reentry.fmu").is_file():
        raise SystemExit(f"no native twins in {fmus / 'native'}: run python build_fmus.py")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        python_only = tmp / "pythonfmu"
        python_only.mkdir()
        for f in fmus.glob("*.fmu"):
            shutil.copy(f, python_only / f.name)
        cache = tmp / "cache"
        rows = {"pythonfmu, cold cache": run(python_only, tmp / "a", cache, args),
                "native, warm cache": run(fmus, tmp / "b", cache, args)}
    figures = {name: {"wall": s["wall"], "flight_path": s.get("flight_path"),
                      "flights": s["flights"], "J1_over_bound": s.get("ratio_to_bound"),
                      **{k: s["timings"].get(k, 0.0) for k in PHASES}}
               for name, s in rows.items()}
    if args.json:
        print(json.dumps({"machine": machine(), "runs": figures}, indent=1))
        return 0
    print(f"machine: {machine()}")
    names = list(figures)
    print(f"{'phase':<12}" + "".join(f"{n:>26}" for n in names) + f"{'ratio':>8}")
    for k in (*PHASES, "wall"):
        a, b = (figures[n][k] for n in names)
        cells = "".join(f"{figures[n][k]:>14.1f} s {100 * figures[n][k] / figures[n]['wall']:>5.0f} %"
                        for n in names)
        print(f"{k:<12}{cells}{(a / b if b > 0 else float('inf')):>8.1f}")
    for n in names:
        f = figures[n]
        print(f"{n}: {f['flight_path']} path, {f['flights']} flights, "
              f"best J1 with miss < 1 km = {f['J1_over_bound']:.5f} x the bound")
    return 0


if __name__ == "__main__":
    sys.exit(main())
