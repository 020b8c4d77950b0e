"""The benchmark suite's plants: built into FMUs as a user would, and flown with Python laws.

:func:`build_plants` builds the suite's plant files (:data:`PLANT_SOURCES`) with ``descent-fmus
build-plant`` into ``build/``; :class:`PlantFlyer` flies a plant FMU (fmpy, the master's order:
read the outputs at t_k, compute u_k, step) under a Python law or an open-loop program -- the
references of ``references.py`` are flown so --; :func:`fly_law` flies a network-operator law
through the package's closed loop and :func:`objective_of` scores it with the package's
evaluator (the numbers a synthesis run sees).
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

__all__ = ["SUITE", "ROOT", "BUILD", "TUTORIAL", "PLANT_SOURCES", "build_plants", "PlantFlyer",
           "fly_law", "objective_of"]

SUITE = Path(__file__).resolve().parent
ROOT = SUITE.parent.parent
BUILD = SUITE / "build"
TUTORIAL = ROOT / "docs" / "tutorials"

#: plant FMUs the suite builds at run time: model identifier -> the plant file
PLANT_SOURCES = {"LQPlant": SUITE / "plants" / "lq.py",
                 "CartPole": SUITE / "plants" / "cartpole.py",
                 "Unicycle": SUITE / "plants" / "unicycle.py",
                 "DoubleIntegrator": SUITE / "plants" / "double_integrator.py",
                 "Oscillator": SUITE / "plants" / "oscillator.py",
                 "Hopper": TUTORIAL / "hopper.py"}


# -- building the plants -------------------------------------------------------------------------
def build_plants(dest: Path = BUILD, names=None, force: bool = False) -> dict:
    """Build the suite's plants into ``dest`` with ``descent-fmus build-plant`` (as a user
    would: each plant file gives its pythonfmu FMU and, beside it in ``native/``, its native C
    twin checked bit for bit, which the problems then fly), each only if missing or older than
    its source; copy the tutorial's ``hopper.toml`` beside its FMU.  Returns {identifier: FMU
    path}."""
    from concurrent.futures import ThreadPoolExecutor

    from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    native = find_compiler() is not None
    out, todo = {}, []
    for name, src in PLANT_SOURCES.items():
        if names is not None and name not in names:
            continue
        fmu = dest / f"{name}.fmu"
        out[name] = fmu
        if force or not fmu.is_file() or fmu.stat().st_mtime < src.stat().st_mtime or (
                native and not (dest / "native" / fmu.name).is_file()):
            todo.append(src)

    def build(src):
        r = subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main",
                            "build-plant", str(src), "-d", str(dest)], capture_output=True,
                           text=True)
        if r.returncode != 0:
            raise RuntimeError(f"build-plant {src.name}: "
                               f"{(r.stderr or r.stdout).strip().splitlines()[-1:]}")
    with ThreadPoolExecutor(max_workers=2) as pool:
        list(pool.map(build, todo))
    if names is None or "Hopper" in names:
        shutil.copyfile(TUTORIAL / "hopper.toml", dest / "hopper.toml")
    return out


# -- flying a plant FMU with a Python law ------------------------------------------------------
class PlantFlyer:
    """A plant FMU loaded once (fmpy), flown from start values under a Python law or an
    open-loop program, in the closed loop's order: at t_k read the outputs, compute u_k (clipped
    to the bounds, as the controller FMU clips), set it, step to t_k+1."""

    def __init__(self, fmu):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave
        self.path = Path(fmu)
        self.md = read_model_description(str(self.path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.outputs = [v.name for v in self.md.modelVariables if v.causality == "output"
                        and v.type == "Real"]
        self._dir = extract(str(self.path))
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self._dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName="plant")
        self.fmu.instantiate()
        self._fresh = True

    def defaults(self) -> dict:
        """The plant's declared start values of its Real parameters."""
        return {v.name: float(v.start) for v in self.md.modelVariables
                if v.causality == "parameter" and v.type == "Real"}

    def fly(self, start: dict, law, inputs, step: float, stop_time: float, bounds=None,
            record: bool = False) -> dict:
        """One flight.  ``law(outputs: dict) -> sequence`` of the values of ``inputs`` (or a
        sequence of such vectors, one per step: an open-loop program); ``bounds`` [(lo, hi)]
        clip them.  Returns the final outputs (and ``trace``: outputs per communication point
        with ``t`` and the applied ``u``, with ``record``)."""
        f = self.fmu
        if not self._fresh:
            f.reset()
        self._fresh = False
        f.setReal([self.vr[k] for k in start], [float(v) for v in start.values()])
        f.setupExperiment(startTime=0.0, stopTime=stop_time)
        f.enterInitializationMode()
        f.exitInitializationMode()
        out_vr = [self.vr[n] for n in self.outputs]
        in_vr = [self.vr[n] for n in inputs]
        n = int(round(stop_time / step))
        trace = {"t": [], "u": [], **{k: [] for k in self.outputs}}
        for k in range(n + 1):
            y = dict(zip(self.outputs, f.getReal(out_vr)))
            if record:
                trace["t"].append(k * step)
                for name in self.outputs:
                    trace[name].append(y[name])
            if k == n:
                break
            u = law[k] if not callable(law) else law(y)
            u = [float(v) for v in np.atleast_1d(u)]
            if bounds is not None:
                u = [min(max(v, lo), hi) for v, (lo, hi) in zip(u, bounds)]
            if record:
                trace["u"].append(u)
            f.setReal(in_vr, u)
            f.doStep(currentCommunicationPoint=k * step, communicationStepSize=step)
        out = dict(zip(self.outputs, f.getReal(out_vr)))
        if record:
            out["trace"] = {k: np.asarray(v) for k, v in trace.items()}
        return out

    def close(self) -> None:
        try:
            self.fmu.terminate()
            self.fmu.freeInstance()
        finally:
            shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def fly_law(problem, law, fmu_dir=None) -> list:
    """The final plant outputs of a network-operator ``law`` flown from every initial state of
    ``problem`` through its closed loop (plant FMU and the controller FMU), one dict per
    start."""
    from descent_fmus.synthesis.fmi.loop import open_loop
    from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir
    plant, ctrl = problem.fmu_paths(fmu_dir or default_fmu_dir())
    loop = open_loop(problem.wiring, plant, ctrl, native=False)
    try:
        return [loop.run(plant_values=s, controller_values=law.start_values()).final
                for s in problem.initial_states]
    finally:
        loop.close()


def objective_of(problem, law, fmu_dir=None) -> tuple:
    """The objectives and total constraint violation of ``law`` on ``problem``, through the
    package's evaluator (the numbers a synthesis run sees)."""
    from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir
    from descent_fmus.synthesis.run.evaluation import Evaluator
    ev = Evaluator(problem, fmu_dir or default_fmu_dir())
    try:
        r = ev.evaluate([law])
        return tuple(float(v) for v in r.F[0]), float(r.cv[0])
    finally:
        ev.close()
