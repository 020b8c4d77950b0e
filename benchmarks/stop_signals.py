"""Benchmark: signals sent at random moments of a run's refinement phase always end it as a stop.

Starts ``descent-fmus synthesize reentry`` (a small recipe, ``--workers 1``: the FMUs -- the
pythonfmu controller among them -- run in the CLI's own process, and the end of the basic
solution's search flies the refined law again for the input scaling), waits for the line
announcing the refinement, sends SIGTERM or SIGINT (alternately) a random 0.05-0.6 s later and
counts how each run ended: 143/130 with its one line is a stop; 2 (an FMU error) or a negative
code (a crash) is what issue 40 measured before the fix.  Prints the counts and, with
``--json``, them as JSON.

    python benchmarks/stop_signals.py [--runs 50] [--fmus DIR] [--seed 1]
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--fmus", type=Path, default=None)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    rng = random.Random(args.seed)
    codes: collections.Counter = collections.Counter()
    bad = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.runs):
            sig = (signal.SIGTERM, signal.SIGINT)[k % 2]
            delay = rng.uniform(0.05, 0.6)
            code, last, valid = one_run(Path(tmp) / f"run{k}", args.fmus, sig, delay)
            stop = code == 128 + sig and "interrupted by" in last and valid
            codes["stop" if stop else f"exit {code}"] += 1
            if not stop:
                bad.append({"run": k, "signal": signal.Signals(sig).name, "delay": delay,
                            "exit": code, "last line": last, "checkpoint valid": valid})
            print(f"run {k + 1}/{args.runs}: {signal.Signals(sig).name} after {delay:.2f} s "
                  f"-> exit {code}{'' if stop else ' NOT A STOP: ' + last}", file=sys.stderr)
    result = {"runs": args.runs, "outcomes": dict(codes), "not_a_stop": bad}
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print(f"{codes['stop']} of {args.runs} signals ended the run as a stop "
              f"(130/143, its one line, a valid checkpoint); others: "
              f"{ {k: v for k, v in codes.items() if k != 'stop'} or 'none'}")
    return 0 if not bad else 1


if __name__ == "__main__":
    sys.exit(main())
