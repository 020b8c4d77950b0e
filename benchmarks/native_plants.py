"""Benchmark: ms per flight of every plant FMU, pythonfmu against native, through one fmpy master.

For each native plant of the systems (``synthesis.registry.native_plants``): a flight is what
a Python master does with the plant -- reset, initialisation, then per communication step set
the inputs of a fixed program, ``doStep`` and read every output -- until the horizon or a
non-zero ``status``.
The same loop (fmpy's ``FMU2Slave``) flies ``fmus/<Plant>.fmu`` (pythonfmu: Python's RK4 behind
the C++ bridge) and ``fmus/native/<Plant>.fmu`` (C generated from the same Python), in
interleaved rounds (the median of each, so that a change of the machine's load slows both
alike).  Prints ms per flight of each and their ratio; the native plant's share of a flight
is small, the rest is the master's ctypes calls.

    python benchmarks/native_plants.py [--fmus DIR] [--rounds N] [--plant NAME ...] [--json]

Needs ``python build_fmus.py`` (with a C compiler for the native plants).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import time
from pathlib import Path

from descent_fmus.synthesis.fmi.slave import load_slave
from descent_fmus.synthesis.registry import native_plants
from descent_fmus.synthesis.paths import fmu_dir


def _gimbals(t: float) -> dict:
    out = {f"u[{j + 1}]": 0.01 * math.sin(0.2 * t + j) for j in range(6)}
    out.update({f"du[{j + 1}]": 0.002 * math.cos(0.2 * t + j) for j in range(6)})
    return out


#: per plant: (communication step [s], horizon [s], input program t -> {input: value})
PROGRAMS = {
    "Reentry": (1.0, 300.0, lambda t: {"u": 0.2 * math.sin(0.05 * t)}),
    "MarsCapsule": (0.05, 200.0, lambda t: {"u": math.copysign(1.0, math.sin(0.4 * t))}),
    "MarsCapsule6DOF": (0.05, 200.0, lambda t: {"u": math.copysign(1.0, math.sin(0.4 * t))}),
    "LunarLander": (0.01, 30.0, lambda t: {"u": 14.57 if t > 4.2 else 0.0}),
    "LunarDescent": (1.0, 600.0, lambda t: {"u1": math.pi + 0.3, "u2": 40.0}),
    "Telescope": (1.0, 40.0, _gimbals),
    "FlexibleTelescope": (1.0, 40.0, _gimbals),
}


class Flight:
    """One FMU and the value references of its inputs and outputs."""

    def __init__(self, path, name: str):
        self.fmu = load_slave(path, name)
        vr = {v.name: v for v in self.fmu.model.modelVariables}
        self.vr = {n: v.valueReference for n, v in vr.items()}
        self.reals = [v.valueReference for v in vr.values()
                      if v.causality == "output" and v.type == "Real"]
        self.status = [vr["status"].valueReference]

    def fly(self, step: float, horizon: float, program) -> tuple[int, float]:
        """One flight; (steps, final time)."""
        f = self.fmu
        f.reset()
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.exitInitializationMode()
        names = list(program(0.0))
        refs = [self.vr[n] for n in names]
        k, n = 0, int(round(horizon / step))
        while k < n:
            t = k * step
            inputs = program(t)
            f.setReal(refs, [inputs[n_] for n_ in names])
            f.doStep(t, step)
            k += 1
            f.getReal(self.reals)
            if f.getInteger(self.status)[0]:
                break
        return k, k * step

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def bench(name: str, folder, rounds: int) -> dict:
    step, horizon, program = PROGRAMS[name]
    py = Flight(folder / f"{name}.fmu", "py")
    c = Flight(folder / "native" / f"{name}.fmu", "native")
    times = {"pythonfmu": [], "native": []}
    steps = None
    try:
        for _ in range(rounds):
            for label, flight in (("pythonfmu", py), ("native", c)):
                t0 = time.perf_counter()
                k, _ = flight.fly(step, horizon, program)
                times[label].append(time.perf_counter() - t0)
                if steps not in (None, k):
                    raise RuntimeError(f"{name}: the two FMUs flew {steps} and {k} steps")
                steps = k
    finally:
        py.free()
        c.free()
    ms = {k: 1e3 * statistics.median(v) for k, v in times.items()}
    return {"plant": name, "steps": steps, "step": step, "pythonfmu_ms": ms["pythonfmu"],
            "native_ms": ms["native"], "ratio": ms["pythonfmu"] / ms["native"]}


def machine() -> str:
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
            f"{platform.python_version()}, load average {load:.2f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmus", help="FMU folder (default: the project's fmus/)")
    ap.add_argument("--rounds", type=int, default=5, help="flights per FMU (median; default 5)")
    ap.add_argument("--plant", nargs="+", choices=sorted(PROGRAMS), help="only these plants")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = ap.parse_args(argv)
    folder = Path(args.fmus) if args.fmus else fmu_dir()
    plants = native_plants()
    missing = [n for n in args.plant or plants if not (folder / "native" / f"{n}.fmu").is_file()]
    if missing:
        print(f"native plants missing in {folder / 'native'}: {', '.join(missing)} (run python "
              f"build_fmus.py)")
        return 2
    rows = [bench(name, folder, args.rounds) for name in args.plant or plants]
    if args.json:
        print(json.dumps({"machine": machine(), "rows": rows}, indent=1))
        return 0
    print(f"# {machine()}; median of {args.rounds} flights each, the same fmpy master loop")
    print(f"{'plant':<18} {'steps':>6} {'pythonfmu ms':>13} {'native ms':>10} {'ratio':>7}")
    for r in rows:
        print(f"{r['plant']:<18} {r['steps']:>6} {r['pythonfmu_ms']:>13.2f} "
              f"{r['native_ms']:>10.2f} {r['ratio']:>6.1f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
