"""Benchmark: the wall time of the test suite as a newcomer and CI run it.

Runs, from the checkout's top folder and as written there,

* **README line 2** -- the test command of the README's first block (the tests without the
  ``slow`` marker, in parallel), and
* **the slow set** -- the command of ``.ci/run`` that runs the tests marked ``slow`` (CI runs
  both, so every test still runs in CI),

and prints the wall time of each, pytest's own count line, and the machine: its cores and the
load average sampled every 5 s during each run (the load of other work on the machine slows the
tests alike; a figure is comparable only with the load beside it).  Target: README line 2
<= 6 min wall on 2 cores.

    python benchmarks/tests_time.py [--only readme|slow] [--json]

Needs the venv of README line 1 (``.venv/``) and the built FMUs.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
from native_paths import machine  # noqa: E402  (the machine line every benchmark prints)


def readme_line_2() -> str:
    """The second command line of the README's first bash block (the test command)."""
    text = (ROOT / "README.md").read_text()
    block = text.split("```bash\n", 1)[1].split("```", 1)[0]
    return block.splitlines()[1].strip()


def slow_command() -> str:
    """The command of ``.ci/run`` that runs the tests marked slow."""
    for line in (ROOT / ".ci" / "run").read_text().splitlines():
        if "pytest" in line and re.search(r"-m\s+['\"]?slow\b", line):
            return line.strip()
    raise SystemExit(".ci/run has no command that runs the tests marked slow ('-m slow')")


def timed(command: str) -> dict:
    """``command`` run by bash in the checkout: wall time, pytest's last line, exit code and the
    load average (1 min) sampled every 5 s meanwhile."""
    loads, done = [], threading.Event()

    def sample():
        while not done.wait(5.0):
            loads.append(os.getloadavg()[0])
    sampler = threading.Thread(target=sample, daemon=True)
    loads.append(os.getloadavg()[0])
    sampler.start()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    res = subprocess.run(["bash", "-c", command], cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    done.set()
    sampler.join()
    lines = [ln for ln in res.stdout.splitlines() if ln.strip()]
    summary = next((ln.strip("= ") for ln in reversed(lines)
                    if re.search(r"\d+ (passed|failed|error)", ln)), lines[-1] if lines else "")
    return {"command": command, "wall_s": round(wall, 1), "cpu_s": round(cpu, 1),
            "cpu_per_core_s": round(cpu / os.cpu_count(), 1), "pytest": summary,
            "exit_code": res.returncode, "load_min": round(min(loads), 2),
            "load_mean": round(sum(loads) / len(loads), 2), "load_max": round(max(loads), 2)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", choices=("readme", "slow"), default=None,
                   help="run one of the two sets only")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = p.parse_args(argv)
    if not (ROOT / ".venv" / "bin" / "python").exists():
        print(f"error: no venv at {ROOT / '.venv'}: run README line 1 first", file=sys.stderr)
        return 2
    sets = {"README line 2": readme_line_2(), "slow set (.ci/run)": slow_command()}
    if args.only:
        sets = {k: v for k, v in sets.items() if k.startswith(args.only.replace("readme",
                                                                                "README"))}
    rows = {}
    for name, command in sets.items():
        rows[name] = timed(command)
        if not args.json:
            r = rows[name]
            print(f"{name}: {r['wall_s'] / 60:.1f} min ({r['wall_s']:.0f} s), {r['pytest']}, "
                  f"exit {r['exit_code']}; load average {r['load_min']:.1f} .. "
                  f"{r['load_max']:.1f} (mean {r['load_mean']:.1f}); CPU {r['cpu_s']:.0f} s "
                  f"= {r['cpu_per_core_s'] / 60:.1f} min per core\n    {r['command']}",
                  flush=True)
    if args.json:
        print(json.dumps({"machine": machine(), "cores": os.cpu_count(), "runs": rows},
                         indent=1))
    else:
        print(f"machine: {machine()}")
        if "README line 2" in rows:
            print(f"README line 2: {rows['README line 2']['wall_s'] / 60:.1f} min "
                  f"(target <= 6 min on 2 cores)")
    return 0 if all(r["exit_code"] == 0 for r in rows.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
