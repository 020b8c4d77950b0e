"""Benchmark: S1 guided flights (the law plus the on-board predictor-corrector) per second on
every closed-loop path, in one run, with their ratios.

The committed guided law over the 16 dispersed samples of the ``reentry-guided`` problem, each
path flying the samples in turn:

1. pythonfmu plant + pythonfmu ``GuidedNetworkOperatorController`` through the Python master;
2. the native twins (``fmus/native/``) through the Python master;
3. the native twins in fmpy's container FMU, one call per flight;
4. the native twins under the C master, one call per flight (the evaluator's path).

The paths are measured in interleaved rounds (the median of each).  Every path's final outputs
are checked equal first.  Then, with ``--synthesis``, the default ``synthesize reentry-guided``
run on the evaluator's path (wall time; the pythonfmu path of the same run is ``--fmus`` of a
folder without ``native/``).

    python benchmarks/guided_paths.py [--fmus DIR] [--synthesis] [--json]

Needs ``python build_fmus.py`` with a C compiler (the native twins).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from native_paths import fmus_and_twins, machine, print_rates, rates

from descent_fmus.synthesis.fmi.loop import open_loop
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.registry import get_problem

ROOT = Path(__file__).resolve().parent.parent
GUIDED_LAW = ROOT / "synthesis" / "systems" / "reentry" / "guided_law.json"


class Flier:
    """A loop on two FMUs flying the samples in turn; ``rate(seconds)`` in flights/s."""

    def __init__(self, loop, states, values):
        self.loop, self.states, self.values = loop, states, values
        self.finals = [loop.run(s, values).final for s in states]

    def rate(self, seconds: float) -> float:
        n, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            self.loop.run(self.states[n % len(self.states)], self.values)
            n += 1
        return n / (time.perf_counter() - t0)


def synthesis_seconds(fmus: Path) -> float:
    """Wall time of the default ``synthesize reentry-guided`` run (no export, no reference)."""
    with tempfile.TemporaryDirectory(prefix="guided_run_") as out:
        t0 = time.perf_counter()
        subprocess.run([str(Path(sys.executable).parent / "descent-fmus"), "synthesize",
                        "reentry-guided", "--out", out, "--fmus", str(fmus), "--quiet",
                        "--no-export"], check=True, stdout=subprocess.DEVNULL)
        return time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    ap.add_argument("--seconds", type=float, default=6.0, help="time per path [s]")
    ap.add_argument("--rounds", type=int, default=6, help="rounds the paths take in turn")
    ap.add_argument("--synthesis", action="store_true",
                    help="also time the default synthesize reentry-guided run")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    problem = get_problem("reentry-guided")
    plant, ctrl, twins = fmus_and_twins(problem, args.fmus)
    values = NetworkOperator.load(GUIDED_LAW).start_values()
    states = problem.initial_states
    w = problem.wiring
    loops = {"pythonfmu, Python master": open_loop(w, plant, ctrl, "master"),
             "native, Python master": open_loop(w, *twins, "native-master"),
             "native, fmpy container": open_loop(w, *twins, "native-container"),
             "native, C master (evaluator)": open_loop(w, *twins, "native-c")}
    try:
        paths = {name: Flier(loop, states, values) for name, loop in loops.items()}
        want = paths["pythonfmu, Python master"].finals
        for name, p in paths.items():
            assert p.finals == want, f"{name} flies differently"
        measured = rates(paths, args.seconds * len(paths), args.rounds)
    finally:
        for loop in loops.values():
            loop.close()
    py = measured["pythonfmu, Python master"]
    report = {"machine": machine(), "flights_per_s": measured,
              "ratios": {name + " / pythonfmu": r / py for name, r in measured.items()
                         if not name.startswith("pythonfmu")}}
    if args.synthesis:
        report["synthesis_seconds (target <= 120)"] = synthesis_seconds(args.fmus)
    if args.json:
        print(json.dumps(report, indent=1))
        return
    print_rates(f"S1 guided law over the 16 samples of reentry-guided, median of {args.rounds} "
                f"interleaved rounds; {report['machine']}", measured, report["ratios"])
    if args.synthesis:
        print(f"synthesize reentry-guided (default budget, no export): "
              f"{report['synthesis_seconds (target <= 120)']:.1f} s")


if __name__ == "__main__":
    main()
