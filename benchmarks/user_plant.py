"""Benchmark: a user's plant at native speed -- the twin ``descent-fmus build-plant`` makes against
the pythonfmu FMU of the same plant file.

1. **laws/s in the evaluator**: the suite's unicycle (benchmarks/suite/plants/unicycle.py; the
   parking problem's law, reading x, y, theta) flown from 12 Latin-hypercube starts per law on 2
   worker processes, one batch of the GA's first laws, pythonfmu FMU vs native twin; the
   objectives of the two batches must be bitwise equal.  The same for the tutorial's problem
   (the hopper, 6 starts a law).
2. **the tutorial end to end**: ``descent-fmus synthesize --problem hopper.toml`` with the
   file's own budget (docs/tutorials/own_plant.md, step 3), the plant's twin beside its FMU
   and without it; the wall time of the whole command and of its flights.

    python benchmarks/user_plant.py [--n 240] [--skip-tutorial] [--generations 10] [--json]

Targets: the twin >= 30x the pythonfmu rate in the evaluator; the tutorial >= 10x
faster end to end.
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SUITE = ROOT / "benchmarks" / "suite"
TUTORIAL = ROOT / "docs" / "tutorials"


def build(src: Path, dest: Path) -> None:
    subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main", "build-plant",
                    str(src), "-d", str(dest)], check=True, capture_output=True)


def unicycle_problem(work: Path, fmus: Path):
    """The parking problem on 12 Latin-hypercube starts, its plant built by build-plant."""
    from descent_fmus.synthesis.problems.dispersion import Box
    from descent_fmus.synthesis.problems.files import load_problem_file
    (work / "build").mkdir(parents=True, exist_ok=True)
    build(SUITE / "plants" / "unicycle.py", work / "build")
    shutil.copy(SUITE / "parking.toml", work / "parking.toml")
    problem = load_problem_file(work / "parking.toml", fmus)
    starts = Box.from_bounds({"x0": (-2.0, 2.0), "y0": (-2.0, 2.0),
                              "theta0": (-math.pi, math.pi)}).sample(12, 1, "lhs")
    return replace(problem, initial_states=tuple(starts))


def laws(problem, n: int, seed: int = 0) -> list:
    from descent_fmus.synthesis.methods.registry import make_method
    return [c.law for c in make_method("network-operator",
                                       problem.tuned(population=n, seed=seed)).ask()]


def rate(problem, batch, fmus, native) -> tuple:
    """(laws/s, path, objectives) of the batch on 2 workers with the runner's ``native``."""
    from descent_fmus.synthesis.run.evaluation import Evaluator
    p = replace(problem, runner=replace(problem.runner, native=native))
    with Evaluator(p, fmus, workers=2) as ev:
        ev.evaluate(batch[:8])                      # start-up (imports, FMU loading)
        ev.cache.clear()
        n0, t0 = ev.simulated, time.perf_counter()
        F = ev.evaluate(batch).F
        return (ev.simulated - n0) / (time.perf_counter() - t0), ev.path, F


def tutorial(work: Path, fmus: Path, native: bool, generations=None) -> dict:
    """The tutorial's synthesis, its whole command timed; the flights' seconds from its
    summary."""
    d = work / ("tutorial-native" if native else "tutorial-pythonfmu")
    d.mkdir(parents=True)
    t0 = time.perf_counter()
    if native:
        build(TUTORIAL / "hopper.py", d)           # step 1: build-plant (both FMUs, the check)
    else:
        src = work / "tutorial-native" / "Hopper.fmu"
        shutil.copy(src if src.is_file() else _built_hopper(work), d / "Hopper.fmu")
    shutil.copy(TUTORIAL / "hopper.toml", d / "hopper.toml")
    built = time.perf_counter() - t0
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main", "synthesize",
                    "--problem", str(d / "hopper.toml"), "--out", str(d / "run"), "--fmus",
                    str(fmus)] + (["--generations", str(generations)] if generations else []),
                   check=True, capture_output=True)
    wall = time.perf_counter() - t0
    s = json.loads((d / "run" / "summary.json").read_text())
    return {"wall_s": wall, "build_s": built if native else None,
            "simulated": s.get("simulated"), "flight_path": _path(d / "run"),
            "search_s": s.get("seconds"), "best_v_touchdown": min(
                r["v_touchdown"] for r in s.get("pareto", [{"v_touchdown": math.nan}]))}


def evaluator_rates(problem, fmus: Path, n: int) -> dict:
    """Laws/s of ``problem`` on 2 workers: ``n`` laws on pythonfmu, 20 n on the twin (the same
    first n: their objectives compared bytewise)."""
    big = laws(problem, 20 * n)
    small = big[:n]
    r_py, path_py, F_py = rate(problem, small, fmus, False)
    r_c, path_c, F_c = rate(problem, big, fmus, None)
    return {"starts": len(problem.initial_states), "workers": 2, "pythonfmu_laws_per_s": r_py,
            "pythonfmu_path": path_py, "native_laws_per_s": r_c, "native_path": path_c,
            "ratio": r_c / r_py,
            "objectives_bitwise_equal": F_py.tobytes() == F_c[:len(small)].tobytes()}


def hopper_problem(work: Path, fmus: Path):
    """The tutorial's problem, its plant built by build-plant beside its file."""
    from descent_fmus.synthesis.problems.files import load_problem_file
    d = work / "hopper"
    build(TUTORIAL / "hopper.py", d)
    shutil.copy(TUTORIAL / "hopper.toml", d / "hopper.toml")
    return load_problem_file(d / "hopper.toml", fmus)


def _built_hopper(work: Path) -> Path:
    d = work / "hopper-build"
    build(TUTORIAL / "hopper.py", d)
    return d / "Hopper.fmu"


def _path(run: Path) -> str:
    f = run / "run.json"
    return json.loads(f.read_text()).get("flight_path", "?") if f.is_file() else "?"


def main(argv=None):
    from descent_fmus.synthesis.paths import fmu_dir
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=240, help="laws of the pythonfmu batch (the "
                    "native batch is 20x larger)")
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    ap.add_argument("--skip-tutorial", action="store_true")
    ap.add_argument("--skip-evaluator", action="store_true")
    ap.add_argument("--generations", type=int, default=None, help="the tutorial's budget "
                    "(default: the file's, 30; the tutorial's quick run: 10)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    out = {}
    with tempfile.TemporaryDirectory(prefix="user_plant_") as tmp:
        work = Path(tmp)
        if not args.skip_evaluator:
            out["unicycle"] = evaluator_rates(unicycle_problem(work, args.fmus), args.fmus,
                                              args.n)
            out["hopper"] = evaluator_rates(hopper_problem(work, args.fmus), args.fmus, args.n)
        if not args.skip_tutorial:
            nat = tutorial(work, args.fmus, True, args.generations)
            py = tutorial(work, args.fmus, False, args.generations)
            out["tutorial"] = {"native": nat, "pythonfmu": py,
                               "ratio_wall": py["wall_s"] / nat["wall_s"]}
    if args.json:
        print(json.dumps(out, indent=1))
        return
    for name, label in (("unicycle", "unicycle (parking law"), ("hopper", "hopper (tutorial")):
        u = out.get(name)
        if not u:
            continue
        print(f"{label}, {u['starts']} starts a law, {u['workers']} workers): "
              f"pythonfmu {u['pythonfmu_laws_per_s']:.1f} laws/s ({u['pythonfmu_path']}), "
              f"native {u['native_laws_per_s']:.0f} laws/s ({u['native_path']}): "
              f"{u['ratio']:.0f}x (target 30x); objectives bitwise equal: "
              f"{u['objectives_bitwise_equal']}")
    if "tutorial" in out:
        t = out["tutorial"]
        for k in ("pythonfmu", "native"):
            r = t[k]
            print(f"tutorial synthesis, {k:9s}: {r['wall_s']:6.1f} s end to end "
                  + (f"(+ build-plant {r['build_s']:.1f} s) " if r["build_s"] else "") +
                  f"({r['simulated']} laws flown on the {r['flight_path']} path), best "
                  f"v_touchdown {r['best_v_touchdown']:.3g} m/s")
        print(f"tutorial end to end: {t['ratio_wall']:.1f}x faster (target 10x)")


if __name__ == "__main__":
    main()
