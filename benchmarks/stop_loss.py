"""Benchmark: how much work a stop costs -- the interrupted run plus its resume, minus one run.

Runs ``descent-fmus synthesize PROBLEM`` three times in a scratch folder: uninterrupted; stopped
by SIGINT (Ctrl-C) once a share ``--at`` of its flight budget has been flown (counted from the
checkpoint and the journal); resumed.  Prints the wall and CPU seconds of each and the loss
``interrupted + resume - uninterrupted`` (CPU seconds: less sensitive to a shared machine's
load than wall time; both include the resume's start-up), and checks that the resumed Pareto
set equals the uninterrupted one.  ``--no-journal`` makes the resume ignore the journal of the
flights after the last checkpoint (the behaviour before the journal: they are flown again).

    python benchmarks/stop_loss.py reentry --flights 3000 [--at 0.5] [--workers 1]
    python benchmarks/stop_loss.py lunar-descent --flights 6000 --workers 2
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: the CLI, optionally with the resume blind to the journal
PROGRAM = ("import sys; from descent_fmus.synthesis.run.folder import RunFolder\n"
           "if sys.argv.pop(1) == 'blind': RunFolder.journaled = lambda self: []\n"
           "from descent_fmus.synthesis.cli.main import entry; entry()")


def _flown(out: Path) -> int:
    """Flights covered by the checkpoint and the journal so far."""
    try:
        n = json.loads((out / "checkpoint.json").read_text())["simulated"]
    except (OSError, ValueError, KeyError):
        n = 0
    try:
        n += (out / "journal.jsonl").read_bytes().count(b"\n")
    except OSError:
        pass
    return n


def _run(args: list, blind: bool, stop_at: int | None = None) -> dict:
    """Wall and CPU seconds of one run (its children's CPU included)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", PROGRAM, "blind" if blind else "seen",
                             *args], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    out = Path(args[args.index("--out") + 1])
    while stop_at is not None and proc.poll() is None and _flown(out) < stop_at:
        time.sleep(0.05)
    if stop_at is not None and proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
    code = proc.wait()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"exit": code, "wall": time.perf_counter() - t0, "cpu": cpu}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem")
    ap.add_argument("--flights", type=int, required=True)
    ap.add_argument("--at", type=float, default=0.5, help="share of the flights flown when "
                    "the SIGINT comes")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--no-journal", action="store_true")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        base = ["synthesize", args.problem, "--flights", str(args.flights), "--workers",
                str(args.workers), "--no-reference", "--no-export", "--quiet"]
        ref = _run(base + ["--out", f"{tmp}/ref"], False)
        cut = _run(base + ["--out", f"{tmp}/run"], False, int(args.at * args.flights))
        flown_at_stop = _flown(Path(tmp) / "run")
        done = _run(base + ["--out", f"{tmp}/run", "--resume"], args.no_journal)
        same = (Path(tmp) / "ref/pareto.csv").read_bytes() == \
            (Path(tmp) / "run/pareto.csv").read_bytes()
    loss = {k: cut[k] + done[k] - ref[k] for k in ("wall", "cpu")}
    result = {"problem": args.problem, "flights": args.flights, "at": args.at,
              "journal": not args.no_journal, "uninterrupted": ref, "interrupted": cut,
              "flown_at_stop": flown_at_stop, "resumed": done, "loss_seconds": loss,
              "same_pareto_set": same}
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print(f"{args.problem}, {args.flights} flights, SIGINT at {flown_at_stop} flown, "
              f"journal {'on' if result['journal'] else 'ignored'}: uninterrupted "
              f"{ref['wall']:.1f} s wall / {ref['cpu']:.1f} s CPU; interrupted {cut['wall']:.1f}"
              f" / {cut['cpu']:.1f}; resumed {done['wall']:.1f} / {done['cpu']:.1f} -> loss "
              f"{loss['wall']:.1f} s wall, {loss['cpu']:.1f} s CPU; same Pareto set: {same}")
    return 0 if same and cut["exit"] == 130 and done["exit"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
