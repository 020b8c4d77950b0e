"""The closed loop as one fmpy container FMU: plant and controller inside, every plant output
exposed, every parameter of both exposed -- extracted and instantiated once per process, reset
per flight, one ``doStep`` over the whole horizon (the container steps its components on the
wiring's communication grid itself).  It is the very FMU users get, and faster than the Python
master for the same law (``benchmarks/reentry_robust.py`` measures the ratio).  The plant
freezes once its stop condition holds, so the steps after it cost little and change nothing.
"""
from __future__ import annotations

import math
import shutil
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoopResult, Wiring
from descent_fmus.synthesis.fmi.slave import FMUError, load_slave

__all__ = ["ContainerLoop"]

_NONE = object()


class ContainerLoop:
    """Plant and controller as one fmpy container FMU, loaded once, reset per flight.

    Same ``run`` interface as :class:`~synthesis.fmi.closed_loop.ClosedLoop` for final outputs (no
    recording): ``run(plant_values, controller_values)`` returns a
    :class:`~synthesis.fmi.closed_loop.ClosedLoopResult` whose ``final`` holds every plant output.

    The container is built here from the two FMUs
    (``synthesis.fmi.containers.closed_loop_fmu``) with every plant output exposed and every
    parameter of both components exposed under its own name (``plant.NAME`` /
    ``controller.NAME`` if both components have it).
    """

    #: The closed-loop path, in one word (what a run reports).
    path = "container"

    def __init__(self, wiring: Wiring, plant_fmu, controller_fmu):
        from fmpy import read_model_description

        from descent_fmus.synthesis.fmi.containers import closed_loop_fmu
        self.wiring = wiring
        mds = {"plant": read_model_description(str(plant_fmu)),
               "controller": read_model_description(str(controller_fmu))}
        params = {r: [v for v in md.modelVariables if v.causality == "parameter"]
                  for r, md in mds.items()}
        both = {v.name for v in params["plant"]} & {v.name for v in params["controller"]}
        self._names = {}                    # (role, component name) -> container name
        parameters = []
        for role, vs in params.items():
            for v in vs:
                cname = f"{role}.{v.name}" if v.name in both else v.name
                self._names[(role, v.name)] = cname
                parameters.append((cname, role, v.name))
        taken = {c for c, _, _ in parameters}
        self._outputs = [v for v in mds["plant"].modelVariables
                         if v.causality == "output" and v.type in ("Real", "Integer", "Boolean")
                         and v.name not in taken]
        exposed = tuple((v.name, "plant", v.name) for v in self._outputs)
        self._tmp = tempfile.mkdtemp(prefix="descent_container_loop_")
        path = Path(self._tmp) / f"{wiring.name}.fmu"
        self.log: list[str] = []
        try:
            closed_loop_fmu(replace(wiring, exposed=exposed), plant_fmu, controller_fmu, path,
                            parameters=tuple(parameters), starts=False)
            self.fmu = load_slave(path, "container", self.log, validate=False,
                                  logging_on=False)
        finally:             # extracted by now: the archive is not needed any more
            shutil.rmtree(self._tmp, ignore_errors=True)
        md = self.fmu.model
        self._vars = {v.name: v for v in md.modelVariables}
        # after a reset every component holds its own start values (the container re-applies
        # none: built with starts=False); a run sets only what differs from them
        self._starts = {}
        for (role, name), cname in self._names.items():
            v = next(x for x in params[role] if x.name == name)
            if v.start is not None and cname in self._vars \
                    and self._vars[cname].start is None:
                try:
                    self._starts[cname] = int(v.start) if v.type == "Integer" else \
                        float(v.start)
                except (TypeError, ValueError):
                    pass
        self._out_vr = {t: [self._vars[v.name].valueReference for v in self._outputs
                            if v.type == t] for t in ("Real", "Integer", "Boolean")}
        self._out_names = {t: [v.name for v in self._outputs if v.type == t]
                           for t in ("Real", "Integer", "Boolean")}
        self._used = False

    def close(self) -> None:
        self.fmu.free()

    def remove_files(self) -> None:
        """Delete the extracted folder (files only: no FMU call)."""
        self.fmu.remove_files()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _set(self, values: dict) -> None:
        """Set the values that differ from the components' defaults, one FMI call per type."""
        batch = {"Real": {}, "Integer": {}, "Boolean": {}}
        for name, value in values.items():
            if self._starts.get(name, _NONE) == value:
                continue
            v = self._vars.get(name)
            if v is None:
                raise KeyError(f"{self.wiring.name} has no parameter {name!r}")
            if v.type == "Real" and not math.isfinite(float(value)):
                raise ValueError(f"{self.wiring.name}: value of {name} must be finite, got "
                                 f"{value!r}")
            batch["Real" if v.type == "Real" else
                  "Boolean" if v.type == "Boolean" else "Integer"][v.valueReference] = value
        for kind, setter, conv in (("Real", self.fmu.setReal, float),
                                   ("Integer", self.fmu.setInteger, int),
                                   ("Boolean", self.fmu.setBoolean, bool)):
            if batch[kind]:
                setter(list(batch[kind]), [conv(x) for x in batch[kind].values()])

    def run(self, plant_values: dict | None = None, controller_values: dict | None = None,
            stop_time: float | None = None, record: bool = False, **_) -> ClosedLoopResult:
        """One flight from t = 0 to the stop time in one ``doStep``; the final plant outputs."""
        if record:
            raise ValueError("the container path records no trajectory; use ClosedLoop")
        t_end = self.wiring.stop_time if stop_time is None else float(stop_time)
        values = {self._names.get(("plant", k), k): v for k, v in (plant_values or {}).items()}
        values.update({self._names.get(("controller", k), k): v
                       for k, v in (controller_values or {}).items()})
        fmu = self.fmu
        del self.log[:]
        try:
            if self._used:
                fmu.reset()
            self._used = True
            self._set(values)
            fmu.setupExperiment(startTime=0.0, stopTime=t_end)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            fmu.doStep(0.0, t_end)
            final = {}
            for kind, get, conv in (("Real", fmu.getReal, float), ("Integer", fmu.getInteger, int),
                                    ("Boolean", fmu.getBoolean, int)):
                if self._out_vr[kind]:
                    final.update(zip(self._out_names[kind],
                                     map(conv, get(self._out_vr[kind]))))
        except (KeyError, ValueError):
            raise
        except Exception as exc:
            said = "; ".join(m.strip() for m in self.log if m.strip())
            raise FMUError(f"{self.wiring.name} (container): {said or exc}") from None
        stop = self.wiring.stop
        stopped = bool(stop is not None and stop.output in final and stop.holds(final[stop.output]))
        return ClosedLoopResult(time=np.zeros(0), outputs={}, final=final, stopped=stopped,
                                steps=int(math.ceil(t_end / self.wiring.step - 1e-9)),
                                t_final=t_end, start=dict(plant_values or {}))
