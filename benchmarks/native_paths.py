"""Benchmark: S1 flights per second on every closed-loop path, in one run, with their ratios.

1. pythonfmu plant + pythonfmu controller through the Python master (``ClosedLoop``);
2. the native twins (``fmus/native/``) through the Python master;
3. the native twins in fmpy's container FMU, one call per flight, timed as the evaluator flies a
   law: ``LawFlyer.fly`` (the law's start values, the run, the objectives) over a set of distinct
   laws;
4. the native twins under the C master, one call per flight -- the evaluator's path, timed the
   same way;
5. pure C: the same two native FMUs and the same C master driven by ``benchmarks/c_master.c``
   (no Python in the process).

Then a worker's resident size over a long run: ``--long`` flights (default 100 000) through the
evaluator's native path, the RSS printed at the start (after a warm-up), every tenth and at the
end.  The paths are measured in interleaved rounds (the median of each): a machine whose load
changes slows them alike.  Targets: path 4 >= 50x path 1 and within 2x of path 5; the RSS flat.

    python benchmarks/native_paths.py [--fmus DIR] [--long N] [--json]

Needs ``python build_fmus.py`` (with the native plant twin) and a C compiler.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

from fmpy import extract, read_model_description

from descent_fmus.synthesis.fmi.c_master_loop import STOP_OPS, STOP_TYPES
from descent_fmus.synthesis.fmi.loop import open_loop
from descent_fmus.synthesis.fmi.native.builders.build import COMPILE_FLAGS, c_file, find_compiler
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.run.flights import LawFlyer

HERE = Path(__file__).resolve().parent


def machine() -> str:
    cpu = next((line.split(":", 1)[1].strip() for line in
                Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("model name")),
               platform.processor()) if Path("/proc/cpuinfo").exists() else platform.processor()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, "
            f"Python {platform.python_version()}, load average {load:.2f}")


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def s1_laws(n: int = 16) -> list:
    """The GA's basic solution and ``n - 1`` structural variations of it (distinct laws)."""
    import numpy as np

    from descent_fmus.synthesis.methods.encoding import StructureCodec
    from descent_fmus.synthesis.systems.reentry.laws import synthesis_basic_law
    basic = synthesis_basic_law()
    codec = StructureCodec(basic.size, basic.nx + len(basic.q))
    rng = np.random.default_rng(11)
    out = [basic]
    while len(out) < n:
        psi = codec.apply(basic.psi, [codec.random(rng) for _ in range(8)])
        out.append(basic.with_structure(psi, list(np.asarray(basic.q) *
                                                  rng.uniform(0.5, 1.5, len(basic.q)))))
    return out


class Master:
    """The Python master on two FMUs, loaded once; ``rate(seconds)`` flies laws in turn."""

    def __init__(self, problem, plant, ctrl, laws):
        self.state, self.laws = problem.initial_states[0], laws
        self.loop = open_loop(problem.wiring, plant, ctrl, "master")
        self.final = self.loop.run(self.state, laws[0].start_values()).final

    def rate(self, seconds: float) -> float:
        n, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            self.loop.run(self.state, self.laws[n % len(self.laws)].start_values())
            n += 1
        return n / (time.perf_counter() - t0)


class Evaluator:
    """``LawFlyer.fly`` (the evaluator's per-process flyer) on the problem's FMUs; ``loop``: fly
    through that loop instead of the one the runner chooses."""

    def __init__(self, problem, plant, ctrl, laws, loop=None):
        self.laws = laws
        self.flyer = LawFlyer(problem, str(plant), str(ctrl))
        if loop is not None:
            self.flyer.loop.close()
            self.flyer.loop = loop
        self.path = self.flyer.loop.path
        self.f = self.flyer.fly(laws[0])[0].f

    def rate(self, seconds: float) -> float:
        n, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            self.flyer.fly(self.laws[n % len(self.laws)])
            n += 1
        return n / (time.perf_counter() - t0)


class CMaster:
    """The C master driven by ``benchmarks/c_master.c`` on the two native FMUs, the first
    law."""

    def __init__(self, problem, plant_twin, ctrl_twin, law, work: Path):
        self.exe = work / "c_master"
        master, fmi2 = c_file("master.c"), c_file("fmi2FunctionTypes.h").parent
        subprocess.run([find_compiler(), *COMPILE_FLAGS[1:4], "-I", str(master.parent), "-I",
                        str(fmi2), "-o", str(self.exe), str(HERE / "c_master.c"), str(master),
                        "-ldl", "-lm"], check=True)
        self.libs, lines, var = [], [], {}
        for tag, path, values in (("p", plant_twin, problem.initial_states[0]),
                                  ("c", ctrl_twin, law.start_values())):
            md = read_model_description(str(path))
            d = Path(extract(str(path), unzipdir=str(work / path.stem)))
            self.libs += [str(d / "binaries" / "linux64" /
                              f"{md.coSimulation.modelIdentifier}.so"), md.guid]
            var[tag] = {v.name: v for v in md.modelVariables}
            for name, value in values.items():
                v = var[tag][name]
                text = float.hex(float(value)) if v.type == "Real" else str(int(value))
                lines.append(f"{tag} {'R' if v.type == 'Real' else 'I'} {v.valueReference} "
                             f"{text}")
        w, pv, cv = problem.wiring, var["p"], var["c"]
        lines += [f"y {pv[a].valueReference} {cv[b].valueReference}" for a, b in w.to_controller]
        lines += [f"u {cv[a].valueReference} {pv[b].valueReference}" for a, b in w.to_plant]
        lines += [f"o {pv[n].valueReference}" for n in ("L", "load_max")]
        lines += [f"h {float.hex(w.step)}", f"t {float.hex(w.stop_time)}"]
        if w.stop is not None:
            sv = pv[w.stop.output]
            lines.append(f"s {STOP_TYPES[sv.type]} {sv.valueReference} {STOP_OPS[w.stop.op]} "
                         f"{w.stop.value!r} {w.stop.check_every}")
        self.spec = work / "spec.txt"
        self.spec.write_text("\n".join(lines) + "\n")
        self.per_flight, self.final = 1e-3, None
        self.rate(0.05)

    def rate(self, seconds: float) -> float:
        flights = max(20, int(seconds / self.per_flight))
        res = subprocess.run([str(self.exe), *self.libs, str(self.spec), str(flights)],
                             capture_output=True, text=True, check=True)
        self.per_flight = float(res.stderr.split("seconds_per_flight")[1])
        self.final = [float.fromhex(v) for v in res.stdout.split()]
        return 1.0 / self.per_flight


def rates(paths: dict, seconds: float, rounds: int) -> dict:
    """Median flights/s of every path over ``rounds`` rounds, the paths interleaved in each
    round (a machine whose load changes slows them alike)."""
    got = {name: [] for name in paths}
    for _ in range(rounds):
        for name, path in paths.items():
            got[name].append(path.rate(seconds / rounds))
    return {name: statistics.median(v) for name, v in got.items()}


def fmus_and_twins(problem, folder: Path) -> tuple:
    """``(plant, controller, (native plant, native controller))`` of the problem's FMUs in
    ``folder``; exits saying what to build if a twin is missing."""
    from descent_fmus.synthesis.fmi.native_loop import native_fmus
    plant, ctrl = problem.fmu_paths(folder)
    twins = native_fmus(problem.wiring, plant, ctrl)
    if twins is None:
        raise SystemExit(f"native FMUs of {plant.name}, {ctrl.name} missing in "
                         f"{plant.parent / 'native'} (python build_fmus.py)")
    return plant, ctrl, twins


def print_rates(title: str, rates_: dict, ratios: dict) -> None:
    """The table of flights/s and ms a flight per path, then the ratios."""
    print(title)
    print(f"{'path':36s} {'flights/s':>10s} {'ms/flight':>10s}")
    for name, r in rates_.items():
        print(f"{name:36s} {r:10.1f} {1e3 / r:10.3f}")
    for name, r in ratios.items():
        print(f"  {name}: {r:.1f}x")


def long_run(problem, plant, ctrl, laws, flights: int) -> list:
    """``(flights so far, RSS [MB])`` at the start, every tenth of the run and at the end."""
    flyer = LawFlyer(problem, str(plant), str(ctrl))
    try:
        for law in laws:
            flyer.fly(law)                                # warm-up: every layout cached
        rows = [(0, rss_mb())]
        for k in range(1, flights + 1):
            out, err = flyer.fly(laws[k % len(laws)])
            if err:
                raise RuntimeError(err)
            if k % max(1, flights // 10) == 0 or k == flights:
                rows.append((k, rss_mb()))
        return rows
    finally:
        flyer.close()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    ap.add_argument("--seconds", type=float, default=8.0, help="time per path [s]")
    ap.add_argument("--rounds", type=int, default=8, help="rounds the paths take in turn")
    ap.add_argument("--long", type=int, default=100_000, help="flights of the RSS run")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    problem = get_problem("reentry")
    plant, ctrl, twins = fmus_and_twins(problem, args.fmus)
    laws = s1_laws()
    with tempfile.TemporaryDirectory(prefix="native_paths_") as tmp:
        paths = {"pythonfmu, Python master": Master(problem, plant, ctrl, laws),
                 "native, Python master": Master(problem, *twins, laws),
                 "native, fmpy container": Evaluator(
                     problem, plant, ctrl, laws,
                     open_loop(problem.wiring, *twins, "native-container")),
                 "native, C master (evaluator)": Evaluator(problem, plant, ctrl, laws),
                 "native, pure C master": CMaster(problem, *twins, laws[0], Path(tmp))}
        want = paths["pythonfmu, Python master"].final
        assert paths["native, Python master"].final == want, "the twins fly differently"
        assert paths["native, pure C master"].final == [want["L"], want["load_max"]], \
            "the C master flies differently"
        measured = rates(paths, args.seconds * len(paths), args.rounds)
        ev = paths["native, C master (evaluator)"]
        path, f = ev.path, ev.f
        assert paths["native, fmpy container"].f == f, "the container flies differently"
        for name in ("native, fmpy container", "native, C master (evaluator)"):
            paths[name].flyer.close()
        for name in ("pythonfmu, Python master", "native, Python master"):
            paths[name].loop.close()
    rss = long_run(problem, plant, ctrl, laws, args.long)
    rates_ = measured
    e, py = rates_["native, C master (evaluator)"], rates_["pythonfmu, Python master"]
    report = {"machine": machine(), "evaluator_path": path, "flights_per_s": rates_,
              "ratios": {"evaluator / pythonfmu (target >= 50)": e / py,
                         "pure C / evaluator (target <= 2)": rates_["native, pure C master"] / e,
                         "native master / pythonfmu": rates_["native, Python master"] / py,
                         "fmpy container / pythonfmu": rates_["native, fmpy container"] / py},
              "rss_mb": rss, "objectives_basic_law": f}
    if args.json:
        print(json.dumps(report, indent=1))
        return
    print_rates(f"S1 reentry, nominal flight, 16 distinct laws, median of {args.rounds} "
                f"interleaved rounds; {report['machine']}", rates_, report["ratios"])
    print(f"evaluator's path: {path}; RSS over {args.long} flights [MB]: "
          + ", ".join(f"{k}: {m:.1f}" for k, m in rss))


if __name__ == "__main__":
    main()
