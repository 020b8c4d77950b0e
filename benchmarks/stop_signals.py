"""Benchmark: signals sent at random moments always end a run as a stop, never as an FMU error.

Two scenes, 50 signals each by default (SIGTERM and SIGINT alternately):

* ``--scene run`` -- ``descent-fmus synthesize reentry`` (a small recipe, ``--workers 1``: the
  FMUs run in the CLI's own process; the end of the basic solution's search flies the refined
  law again for the input scaling), the signal a random 0.05-0.6 s after the line announcing
  the refinement;
* ``--scene fmu-calls`` -- a process flying the reentry closed loop (both FMUs pythonfmu: most of
  a flight is their Python code) over and over through ``ClosedLoop.run`` inside
  ``graceful_signals()`` and no critical section, the signal a random 0.05-0.6 s after its first
  flight: the stop must still come out of the program's code.  ``--unsafe`` switches off the
  deferral out of an FMU's code (the handler before the deferral) to show what it prevents.

Each run's end is counted: 143/130 with its one line (and, for ``run``, a valid checkpoint) is a
stop; 2 is an FMU error, a negative code a crash.  Prints the counts (``--json``: as JSON).

    python benchmarks/stop_signals.py [--scene run|fmu-calls] [--runs 50] [--unsafe] [--seed 1]
"""
from __future__ import annotations

import argparse
import collections
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ARGS = ["reentry", "--population", "16", "--crossovers", "4", "--lchr", "4", "--epoch", "2",
        "--seed", "3", "--generations", "3", "--refine-basis", "300", "--refine-evals", "40",
        "--flights", "500", "--workers", "1", "--no-reference", "--no-export"]
PHASE = "refining parameters"


def one_run(out: Path, fmus, sig: int, delay: float) -> tuple:
    """``(exit code, last line of stderr, the checkpoint parses)`` of one run stopped by
    ``sig`` ``delay`` seconds into the refinement."""
    cmd = [sys.executable, "-m", "descent_fmus.synthesis.cli.main", "synthesize", *ARGS,
           "--out", str(out)] + (["--fmus", str(fmus)] if fmus else [])
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, start_new_session=True,
                            env=dict(os.environ, PYTHONUNBUFFERED="1"))
    seen = []
    for line in proc.stderr:
        seen.append(line)
        if PHASE in line:
            break
    time.sleep(delay)
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass
    rest = proc.stderr.read()
    proc.wait(60)
    lines = ("".join(seen) + rest).strip().splitlines()
    ck = out / "checkpoint.json"
    try:
        valid = not ck.exists() or "simulated" in json.loads(ck.read_text())
    except ValueError:
        valid = False
    return proc.returncode, lines[-1] if lines else "", valid


def fmu_calls_child(unsafe: bool) -> int:
    """The ``fmu-calls`` scene's process: flights until a signal; its exit code says how the
    signal came out (128 + signal: a stop; 2: an FMU error)."""
    from descent_fmus.synthesis.fmi.slave import FMUError
    from descent_fmus.synthesis.run import signals
    from descent_fmus.synthesis.systems.reentry.flight import load_loop, scenario_params
    from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law
    from descent_fmus.synthesis.systems.reentry.wiring import plant_values
    if unsafe:
        signals._inside_fmu = lambda frame: False
    loop = load_loop()
    start, law = plant_values(scenario_params("default")), paper_basic_law().start_values()
    try:
        with signals.graceful_signals():
            loop.run(start, law)
            print("ready", flush=True)
            while True:
                loop.run(start, law)
    except signals.RunInterrupted as exc:
        print(f"interrupted by {exc.signal_name}", file=sys.stderr)
        return exc.exit_code
    except FMUError as exc:
        print(f"FMU error: {exc}", file=sys.stderr)
        return 2


def one_child(sig: int, delay: float, unsafe: bool) -> tuple:
    """``(exit code, last line of stderr, True)`` of one ``fmu-calls`` process."""
    cmd = [sys.executable, __file__, "--child"] + (["--unsafe"] if unsafe else [])
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    proc.stdout.readline()
    time.sleep(delay)
    os.killpg(proc.pid, sig)
    _, err = proc.communicate(timeout=60)
    lines = err.strip().splitlines()
    return proc.returncode, lines[-1] if lines else "", True


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--fmus", type=Path, default=None)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--scene", choices=("run", "fmu-calls"), default="run")
    ap.add_argument("--unsafe", action="store_true")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        return fmu_calls_child(args.unsafe)
    rng = random.Random(args.seed)
    codes: collections.Counter = collections.Counter()
    bad = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.runs):
            sig = (signal.SIGTERM, signal.SIGINT)[k % 2]
            delay = rng.uniform(0.05, 0.6)
            code, last, valid = (one_run(Path(tmp) / f"run{k}", args.fmus, sig, delay)
                                 if args.scene == "run" else
                                 one_child(sig, delay, args.unsafe))
            stop = code == 128 + sig and "interrupted by" in last and valid
            codes["stop" if stop else f"exit {code}"] += 1
            if not stop:
                bad.append({"run": k, "signal": signal.Signals(sig).name, "delay": delay,
                            "exit": code, "last line": last, "checkpoint valid": valid})
            print(f"run {k + 1}/{args.runs}: {signal.Signals(sig).name} after {delay:.2f} s "
                  f"-> exit {code}{'' if stop else ' NOT A STOP: ' + last}", file=sys.stderr)
    result = {"scene": args.scene, "unsafe": args.unsafe, "runs": args.runs,
              "outcomes": dict(codes), "not_a_stop": bad}
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print(f"{codes['stop']} of {args.runs} signals ended the run as a stop "
              f"(130/143, its one line, a valid checkpoint); others: "
              f"{ {k: v for k, v in codes.items() if k != 'stop'} or 'none'}")
    return 0 if not bad else 1


if __name__ == "__main__":
    sys.exit(main())
