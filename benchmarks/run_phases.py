"""Benchmark: where the README's main job spends its time, on a fresh machine and on a warm one.

Runs ``descent-fmus synthesize reentry`` (the default problem and budget, one seed) twice in
the same session on the native FMUs and prints the phase split of each from its
``summary.json`` (``timings``), side by side:

* **native, cold cache** -- an empty cache folder (``$DESCENT_FMUS_CACHE``): what a run pays
  after the cache folder was cleared -- the S1 bounds (read from the package's shipped copy
  when its content key is current, else solved), the C master's, the probes' and the
  interpreter law FMU's compiles (on a fresh machine ``build_fmus.py`` has made them: see
  ``--cold``), every Pareto law's readable formula;
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

With ``--cold`` a **fresh machine** instead (:func:`fresh_machine`): the code copied without
any bytecode, empty cache and matplotlib folders (no font list), bytecode written as Python
does by default, ``build_fmus.py`` of that code into its own FMU folder (timed apart), then the
main job cold and warm; with ``--before REV`` the same for REV's code, interleaved, and whether
the two codes' ``pareto.json`` are byte-identical.  (The plain cold cache above empties only
the cache folder: the font list and the bytecode of the checkout are already there -- or,
with ``PYTHONDONTWRITEBYTECODE`` set, the bytecode is never kept and every run compiles it.)

    python benchmarks/run_phases.py [--flights N] [--seed S] [--workers W] [--pythonfmu]
                                    [--before REV] [--cold] [--json]

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


def run(fmus: Path, out: Path, cache: Path, args, source: Path | None = None,
        env: dict | None = None) -> dict:
    """One ``synthesize reentry`` run: its summary, with the wall time of the whole command
    (``source``: the code of :func:`source_tree` instead of this checkout's; ``env``: the
    environment instead of this process's)."""
    cmd = [sys.executable, "-m", "descent_fmus.synthesis.cli.main", "synthesize", "reentry",
           *(["--seed", str(args.seed)] if args.seed is not None else []),
           "--workers", str(args.workers), "--fmus", str(fmus),
           "--out", str(out), "--quiet", "--json"]
    if args.flights:
        cmd += ["--flights", str(args.flights)]
    env = dict(os.environ if env is None else env, DESCENT_FMUS_CACHE=str(cache))
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


# -- a fresh machine (--cold) ------------------------------------------------------------------
def fresh_machine(rev: str | None, root: Path) -> dict:
    """A fresh machine's state under ``root``: the code (this checkout's working tree, or git
    revision ``rev``) copied without any bytecode, an empty cache folder, an empty matplotlib
    folder (no font list) and an environment that writes bytecode as Python does by default
    (``PYTHONDONTWRITEBYTECODE`` removed); then ``build_fmus.py`` of that code into its own FMU
    folder, timed -- the state README line 1 leaves before its main job."""
    here = HERE.parent
    src = root / "src"
    (src / "descent_fmus").mkdir(parents=True)
    if rev is None:
        for name in ("models", "synthesis"):
            shutil.copytree(here / name, src / "descent_fmus" / name,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        shutil.copy(here / "build_fmus.py", src / "build_fmus.py")
    else:
        for names, dest in ((["models", "synthesis"], src / "descent_fmus"),
                            (["build_fmus.py"], src)):
            archive = subprocess.run(["git", "-C", str(here), "archive", rev, *names],
                                     capture_output=True, check=True).stdout
            subprocess.run(["tar", "-x", "-C", str(dest)], input=archive, check=True)
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONDONTWRITEBYTECODE", "PYTHONPYCACHEPREFIX", "DESCENT_FMUS_DIR")}
    env.update(PYTHONPATH=os.pathsep.join([str(src), env.get("PYTHONPATH", "")]),
               MPLCONFIGDIR=str(root / "mpl"))
    cache = root / "cache"
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, str(src / "build_fmus.py"), "--out", str(root / "fmus")],
                         capture_output=True, text=True, env=dict(env, DESCENT_FMUS_CACHE=str(cache)))
    if res.returncode != 0:
        raise SystemExit(f"build_fmus.py failed ({res.returncode}):\n{res.stderr[-3000:]}")
    return {"env": env, "cache": cache, "fmus": root / "fmus",
            "build": time.perf_counter() - t0}


def same_pareto(a: Path, b: Path, roots=()) -> str | None:
    """None if two runs' ``pareto.json`` are byte-identical once each run folder's path (and
    each of ``roots``, their machines' folders) is replaced by the same placeholder, else the
    first line that differs."""
    def text(run: Path) -> list:
        t = (run / "pareto.json").read_text().replace(str(run), "RUN")
        for root in roots:
            t = t.replace(str(root), "ROOT")
        return t.splitlines()
    ta, tb = text(a), text(b)
    diff = [f"{x!r} != {y!r}" for x, y in zip(ta, tb) if x != y]
    return diff[0] if diff else None if len(ta) == len(tb) else "lengths differ"


def cold_main(args) -> int:
    """``--cold``: the main job on a fresh machine (:func:`fresh_machine`), then again warm;
    with ``--before REV`` the same for REV's code, interleaved (build, build, cold, cold,
    warm, warm), each in its own fresh state."""
    codes = {"after": None, **({f"before ({args.before})": args.before} if args.before else {})}
    rows, load, builds, outs = {}, [os.getloadavg()[0]], {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        machines = {}
        for k, (name, rev) in enumerate(codes.items()):
            machines[name] = fresh_machine(rev, tmp / f"m{k}")
            builds[name] = machines[name]["build"]
            load.append(os.getloadavg()[0])
        for state in ("cold", "warm"):
            for k, (name, m) in enumerate(machines.items()):
                out = tmp / f"run-{k}-{state}"
                rows[f"{name}, {state}"] = run(m["fmus"], out, m["cache"], args, env=m["env"])
                outs[f"{name}, {state}"] = out
                load.append(os.getloadavg()[0])
        figures = _figures(rows)
        roots = [tmp / f"m{k}" for k in range(len(codes))]
        same = {n: same_pareto(outs[n], outs[f"after, {n.split(', ')[1]}"], roots)
                for n in outs if not n.startswith("after")}
    if args.json:
        print(json.dumps({"machine": machine(), "load_average": load, "fmu_build": builds,
                          "runs": figures, "pareto_json_differences": same}, indent=1))
        return 0
    print(f"machine: {machine()}")
    print("a fresh machine: the code without bytecode, empty cache and matplotlib folders, "
          "build_fmus.py, then the main job twice (cold, warm)")
    print(f"load average (1 min) before and after each build and run: "
          f"{', '.join(f'{v:.2f}' for v in load)}")
    print("build_fmus.py: " + ", ".join(f"{n} {t:.1f} s" for n, t in builds.items()))
    _table(figures)
    for n, diff in same.items():
        print(f"{n}: pareto.json " + ("byte-identical to after's" if diff is None else
                                      f"DIFFERS from after's: {diff}"))
    return 0


def _figures(rows: dict) -> dict:
    figures = {name: {"wall": s["wall"], "flight_path": s.get("flight_path"),
                      "flights": s["flights"], "pareto_size": s["pareto_size"],
                      "J1_over_bound": s.get("ratio_to_bound"),
                      **{k: s["timings"].get(k, 0.0) for k in PHASES}}
               for name, s in rows.items()}
    for f in figures.values():      # start-up, imports, workers' start and stop, summary
        f["other"] = f["wall"] - sum(f[k] for k in PHASES)
    return figures


def _table(figures: dict) -> None:
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


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--fmus", type=Path, default=None, help="FMU folder (default: fmus/)")
    p.add_argument("--flights", type=int, default=None,
                   help="flight budget (default: the problem's, 20 000)")
    p.add_argument("--seed", type=int, default=None,
                   help="default: the problem's, as README line 1's command runs it")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--pythonfmu", action="store_true",
                   help="also a run on the pythonfmu FMUs only (cold cache), first")
    p.add_argument("--before", metavar="REV", default=None,
                   help="also the code at git revision REV (e.g. main), warm cache, run "
                        "after this checkout's warm run: before and after side by side")
    p.add_argument("--cold", action="store_true",
                   help="a fresh machine instead: the code copied without bytecode, empty "
                        "cache and matplotlib folders, its own build_fmus.py, then the main "
                        "job cold and warm (with --before: the same for REV, interleaved)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = p.parse_args(argv)
    if args.cold:
        return cold_main(args)
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
    figures = _figures(rows)
    if args.json:
        print(json.dumps({"machine": machine(), "load_average": load, "runs": figures},
                         indent=1))
        return 0
    print(f"machine: {machine()}")
    print(f"load average (1 min) before and after each run: "
          f"{', '.join(f'{v:.2f}' for v in load)}")
    _table(figures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
