"""Closed-loop co-simulation of a plant FMU and a controller FMU with fmpy.

Both FMUs are extracted and instantiated once; every run resets them, applies new start values
and steps them on the communication grid ``t_k = t0 + k*h`` (integer ``k``, no drift).

Master algorithm (one communication step, Gauss-Seidel with a direct feed-through controller):
read the plant outputs at ``t_k``, set them as controller inputs, read the controller outputs
(``u_k = phi(y(t_k))``), set them as plant inputs, then ``doStep`` both FMUs over ``[t_k, t_k+h]``.
This is also what fmpy's container FMU does (connections are updated after initialisation and
after every step, plant -> controller first), so ``fmus/*ClosedLoop.fmu`` run by ``fmpy simulate``
gives the same trajectory as :meth:`ClosedLoop.run`.

The hot loop calls fmpy's ``fmi2GetReal``/``fmi2SetReal``/``fmi2DoStep`` bindings with
pre-allocated ctypes buffers: the per-step cost is dominated by the FMUs themselves.
"""
from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fmpy.fmi2 import fmi2True

from descent_fmus.synthesis.fmi.description.declared import declared_starts
from descent_fmus.synthesis.fmi.slave import CFunctions, FMUError, load_slave, not_an_output

__all__ = ["Wiring", "Stop", "STATUS_STOP", "ClosedLoop", "ClosedLoopResult"]


@dataclass(frozen=True)
class Stop:
    """When a flight ends before the stop time: plant output ``output`` compared with ``value``.

    Attributes
    ----------
    output : str
        A plant output (Real, Integer or Boolean).
    op : {"!=", "<=", ">="}
        The flight ends at the first communication point where ``output op value`` holds.
    value : float
    check_every : int
        Read the output every this many steps (> 1 only for plants that freeze their state once
        the condition holds, as the plants of this project do with their ``status``: the steps
        after it change nothing).
    """

    output: str = "status"
    op: str = "!="
    value: float = 0.0
    check_every: int = 1

    def __post_init__(self):
        if self.op not in ("!=", "<=", ">="):
            raise ValueError(f"stop condition operator must be '!=', '<=' or '>=', got "
                             f"{self.op!r}")
        if self.check_every < 1:
            raise ValueError(f"check_every must be >= 1, got {self.check_every}")

    def holds(self, v: float) -> bool:
        if self.op == "!=":
            return v != self.value
        return v <= self.value if self.op == "<=" else v >= self.value


#: The plant status convention of this project: the flight ends when ``status`` is non-zero (the
#: plant freezes then, so the flag need not be read every step).
STATUS_STOP = Stop("status", "!=", 0.0, check_every=8)


@dataclass(frozen=True)
class Wiring:
    """How a plant and a controller are connected -- one definition for every tool.

    Used by :class:`ClosedLoop` (fmpy master in Python), by ``synthesis.fmi.containers`` for the
    container FMU and the SSP file, and by the GA's evaluator.

    Attributes
    ----------
    name : str
        Name of the closed-loop system (also of its container FMU), e.g. ``"ReentryClosedLoop"``.
    plant, controller : str
        Model identifiers (= FMU file stems) of the two components.
    to_controller : tuple of (str, str)
        (plant output, controller input) pairs.
    to_plant : tuple of (str, str)
        (controller output, plant input) pairs.
    step : float
        Communication step [s].
    stop_time : float
        Final time t+ [s].
    stop : Stop or None
        What ends a flight before ``stop_time`` (the plants of this project: :data:`STATUS_STOP`).
    exposed : tuple of (str, str, str)
        (container name, "plant" | "controller", component variable) shown by the container FMU.
    """

    name: str
    plant: str
    controller: str
    to_controller: tuple
    to_plant: tuple
    step: float
    stop_time: float
    stop: Stop | None = None
    exposed: tuple = ()
    description: str = ""


@dataclass
class ClosedLoopResult:
    """Outcome of one closed-loop run.

    Attributes
    ----------
    time : ndarray
        Communication points [s] up to the stop.
    outputs : dict of str -> ndarray
        Recorded plant outputs and controller outputs (``"ctrl." + name``) at ``time``.
    final : dict of str -> float or int
        Every plant output (Real, Integer, Boolean) at the end of the run.
    stopped : bool
        True if the stop condition ended the run before ``stop_time``.
    steps : int
        Communication steps taken.
    t_final : float
        Time of the last communication point [s] (the stop, or the stop time).
    start : dict
        The plant start values the run was flown from (the initial state; what an objective
        reads to judge the flight against its own conditions).
    initial : dict
        Plant outputs read at t = 0 after the first exchange of values, where a recording
        takes its first sample, by name: those a loop was asked to read there without a
        recording (:class:`~synthesis.fmi.c_master_loop.CMasterLoop`'s ``initial``).
    """

    time: np.ndarray
    outputs: dict
    final: dict
    stopped: bool
    steps: int
    t_final: float = 0.0
    start: dict = field(default_factory=dict)
    initial: dict = field(default_factory=dict)

    def __getitem__(self, name):
        return self.outputs[name]


_NO_START = object()


class _Component:
    """One FMU instance with name -> (type, value reference) look-up and set helpers."""

    def __init__(self, path, role: str):
        self.log: list[str] = []
        self.path = Path(path)
        self.fmu = load_slave(path, role, self.log)
        self.md = self.fmu.model
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.starts = declared_starts(self.md)
        self.role = role

    def var(self, name):
        try:
            return self.vars[name]
        except KeyError:
            raise KeyError(f"{self.md.modelName} has no variable {name!r}") from None

    def vr(self, name) -> int:
        return self.var(name).valueReference

    def set_values(self, values: dict) -> None:
        """Set start values by name; values equal to the declared start are skipped (after a
        reset the FMU holds its declared start values, FMI 2.0 sec. 2.2.7)."""
        reals, ints = ([], []), ([], [])
        starts = self.starts
        for name, value in values.items():
            if starts.get(name, _NO_START) == value:
                continue
            v = self.var(name)
            if v.type == "Real":
                value = float(value)
                if not math.isfinite(value):
                    raise ValueError(f"{self.md.modelName}: value of {name} must be finite, "
                                     f"got {value!r}")
                reals[0].append(v.valueReference)
                reals[1].append(value)
            elif v.type in ("Integer", "Enumeration"):
                ints[0].append(v.valueReference)
                ints[1].append(int(value))
            elif v.type == "Boolean":
                self.fmu.setBoolean([v.valueReference], [bool(value)])
            else:
                raise TypeError(f"cannot set {v.type} variable {name}")
        if reals[0]:
            self.fmu.setReal(*reals)
        if ints[0]:
            self.fmu.setInteger(*ints)

    def call(self, what, fn, *args):
        del self.log[:]
        try:
            return fn(*args)
        except Exception as exc:  # fmpy raises FMICallException; add what the FMU said
            # pythonfmu adds its own line after the FMU's message ("Fatal py exception
            # encountered: [call] ..."): it repeats the message or says nothing more
            said = "; ".join(m.strip() for m in self.log
                             if m.strip() and not m.lstrip().startswith("Fatal py exception"))
            raise FMUError(f"{self.md.modelName}: {what} failed"
                           + (f": {said}" if said else f" ({exc})")) from None

    def free(self):
        self.fmu.free()


class ClosedLoop:
    """A plant FMU and a controller FMU in closed loop, loaded once and reset per run.

    Parameters
    ----------
    wiring : Wiring
        The connections and the communication step.
    plant_fmu, controller_fmu : path-like
        The FMU files.
    record : sequence of str, optional
        Plant outputs to record at every communication point (the connected ones are always
        available); controller outputs as ``"ctrl.<name>"``.
    """
    path = "master"     # the closed-loop path in one word (the runner's "native-master": twins)

    def __init__(self, wiring: Wiring, plant_fmu, controller_fmu, record=()):
        self.wiring = wiring
        self.plant = _Component(plant_fmu, "plant")
        try:
            self.ctrl = _Component(controller_fmu, "controller")
        except Exception:
            self.plant.free()
            raise
        p, c = self.plant, self.ctrl
        self._y_vr = (ctypes.c_uint * len(wiring.to_controller))(
            *[p.vr(a) for a, _ in wiring.to_controller])
        self._x_vr = (ctypes.c_uint * len(wiring.to_controller))(
            *[c.vr(b) for _, b in wiring.to_controller])
        self._u_vr = (ctypes.c_uint * len(wiring.to_plant))(*[c.vr(a) for a, _ in wiring.to_plant])
        self._pu_vr = (ctypes.c_uint * len(wiring.to_plant))(*[p.vr(b) for _, b in wiring.to_plant])
        self._y = (ctypes.c_double * len(wiring.to_controller))()
        self._u = (ctypes.c_double * len(wiring.to_plant))()
        stop = wiring.stop
        self._stop_vr = self._stop_type = None
        if stop is not None:
            sv = p.var(stop.output)
            if sv.causality != "output":
                raise KeyError(not_an_output(p.md, stop.output))
            self._stop_vr = (ctypes.c_uint * 1)(sv.valueReference)
            self._stop_type = sv.type
        self._stop_buf = ((ctypes.c_double if self._stop_type == "Real" else ctypes.c_int)
                          * 1)()
        self.record = list(record)
        self._plant_out = {t: [v for v in p.md.modelVariables
                               if v.causality == "output" and v.type == t]
                           for t in ("Real", "Integer", "Boolean")}

    def close(self):
        self.plant.free()
        self.ctrl.free()

    def remove_files(self) -> None:
        """Delete the folders the two FMUs were extracted to (files only: no FMU call)."""
        self.plant.fmu.remove_files()
        self.ctrl.fmu.remove_files()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _init(self, comp: _Component, values: dict, t0: float, t1: float):
        fmu = comp.fmu
        comp.call("reset", fmu.reset)
        comp.set_values(values)  # ValueError/KeyError name the offending variable
        comp.call("setupExperiment", fmu.setupExperiment, None, t0, t1)
        comp.call("enterInitializationMode", fmu.enterInitializationMode)
        comp.call("exitInitializationMode", fmu.exitInitializationMode)

    def run(self, plant_values: dict | None = None, controller_values: dict | None = None,
            stop_time: float | None = None, step: float | None = None,
            record: bool = False, scheme: str = "gauss-seidel") -> ClosedLoopResult:
        """Fly one closed loop from t = 0; stop on the plant's stop flag or at ``stop_time``.

        Parameters
        ----------
        plant_values, controller_values : dict, optional
            Start values (parameters) by variable name.
        stop_time, step : float, optional
            Override the wiring's t+ and communication step [s].
        record : bool
            Record the trajectories (``self.record`` plus the connected signals).
        scheme : {"gauss-seidel", "jacobi"}
            "gauss-seidel" (default, as fmpy's container FMU): ``u_k = phi(y(t_k))``.
            "jacobi": all outputs are read before any input is set, so the controller output
            applied over ``[t_k, t_k+1]`` is ``phi(y(t_k-1))`` -- the scheme of hosts such as ecos.
        """
        if scheme not in ("gauss-seidel", "jacobi"):
            raise ValueError(f"unknown scheme {scheme!r}; use 'gauss-seidel' or 'jacobi'")
        w = self.wiring
        t_end = w.stop_time if stop_time is None else float(stop_time)
        h = w.step if step is None else float(step)
        if not (h > 0 and math.isfinite(h) and t_end > 0 and math.isfinite(t_end)):
            raise ValueError(f"need a finite step > 0 and stop time > 0, got step={h}, "
                             f"stop_time={t_end}")
        self._init(self.plant, plant_values or {}, 0.0, t_end)
        self._init(self.ctrl, controller_values or {}, 0.0, t_end)
        rec = _Recording(self, record)
        try:
            k, stopped = self._fly(t_end, h, scheme == "jacobi", rec)
        except Exception as exc:  # fmpy raises FMICallException on an error status
            said = "; ".join(m.strip() for m in self.plant.log + self.ctrl.log if m.strip())
            raise FMUError(f"{w.name}: an FMU call failed at t = {rec.t} s: " +
                           (said or str(exc))) from None
        return ClosedLoopResult(time=np.array(rec.times), outputs=rec.outputs(w),
                                final=self._final_outputs(), stopped=stopped, steps=k,
                                t_final=min(k * h, t_end), start=dict(plant_values or {}))

    def _fly(self, t_end: float, h: float, jacobi: bool, rec: "_Recording") -> tuple:
        """The stepping loop on the grid ``t_k = k h``: ``(steps taken, stopped)``."""
        pf, cf = self.plant.fmu, self.ctrl.fmu
        pc, cc = pf.component, cf.component
        # the FMI functions of the shared libraries fmpy loaded, called directly (fmpy's
        # per-call wrapper costs ~1 us, as much as the call itself); statuses are checked below
        pfn, cfn = CFunctions(pf.dll), CFunctions(cf.dll)
        get_real_p, set_real_p, step_p = pfn["fmi2GetReal"], pfn["fmi2SetReal"], pfn["fmi2DoStep"]
        set_real_c, get_real_c, step_c = cfn["fmi2SetReal"], cfn["fmi2GetReal"], cfn["fmi2DoStep"]
        ny, nu = len(self._y), len(self._u)
        y_vr, x_vr, u_vr, pu_vr, y, u = (self._y_vr, self._x_vr, self._u_vr, self._pu_vr,
                                         self._y, self._u)
        stop, stop_vr, stop_buf = self.wiring.stop, self._stop_vr, self._stop_buf
        get_stop = pfn[{"Real": "fmi2GetReal", "Integer": "fmi2GetInteger",
                        "Boolean": "fmi2GetBoolean"}.get(self._stop_type, "fmi2GetReal")]
        record = rec.on
        n_steps = int(math.ceil(t_end / h - 1e-9))
        check = stop.check_every if stop is not None else 1
        k = 0
        for k in range(n_steps + 1):
            t = rec.t = k * h
            if jacobi and k > 0:
                st = (get_real_c(cc, u_vr, nu, u) | get_real_p(pc, y_vr, ny, y)
                      | set_real_c(cc, x_vr, ny, y))
            else:
                st = (get_real_p(pc, y_vr, ny, y) | set_real_c(cc, x_vr, ny, y)
                      | get_real_c(cc, u_vr, nu, u))
            st |= set_real_p(pc, pu_vr, nu, u)
            if st > 1:
                raise FMUError(f"status {st} while exchanging values")
            if record:
                rec.sample(t, y, u, get_real_p, pc)
            # A plant that freezes once its stop condition holds need not be read every
            # step (Stop.check_every); every step when recording, so that the trajectory
            # ends at the stop.
            if stop_vr is not None and (record or k % check == 0 or k == n_steps):
                get_stop(pc, stop_vr, 1, stop_buf)
                if stop.holds(stop_buf[0]):
                    return k, True
            if k == n_steps:
                break
            dt = min(h, t_end - t)
            if step_p(pc, t, dt, fmi2True) > 1 or step_c(cc, t, dt, fmi2True) > 1:
                raise FMUError("doStep failed")
        return k, False

    def _final_outputs(self) -> dict:
        """Every plant output, by name (Reals as float, Integers and Booleans as int)."""
        fmu, final = self.plant.fmu, {}
        for kind, get in (("Real", fmu.getReal), ("Integer", fmu.getInteger),
                          ("Boolean", fmu.getBoolean)):
            vs = self._plant_out[kind]
            if vs:
                vals = get([v.valueReference for v in vs])
                conv = float if kind == "Real" else int
                final.update((v.name, conv(x)) for v, x in zip(vs, vals))
        return final


class _Recording:
    """The trajectories of one run of a :class:`ClosedLoop` (empty unless ``on``)."""

    def __init__(self, loop: ClosedLoop, on: bool):
        self.on, self.t = on, 0.0
        self.names = [n for n in loop.record if not n.startswith("ctrl.")] if on else []
        self.vr = (ctypes.c_uint * len(self.names))(*[loop.plant.vr(n) for n in self.names])
        self.buf = (ctypes.c_double * len(self.names))()
        self.ny, self.nu = len(loop._y), len(loop._u)
        self.times, self.rows_y, self.rows_u, self.rows_rec = [], [], [], []

    def sample(self, t, y, u, get_real, component) -> None:
        self.times.append(t)
        self.rows_y.append(tuple(y))
        self.rows_u.append(tuple(u))
        if self.names:
            get_real(component, self.vr, len(self.names), self.buf)
            self.rows_rec.append(tuple(self.buf))

    def outputs(self, w: Wiring) -> dict:
        """The recorded signals by name (connected plant outputs, ``ctrl.<u>``, extras)."""
        if not self.on:
            return {}
        out = {}
        arr_y = np.array(self.rows_y).reshape(len(self.times), self.ny)
        arr_u = np.array(self.rows_u).reshape(len(self.times), self.nu)
        for i, (a, _) in enumerate(w.to_controller):
            out[a] = arr_y[:, i]
        for i, (a, _) in enumerate(w.to_plant):
            out["ctrl." + a] = arr_u[:, i]
        if self.names:
            arr = np.array(self.rows_rec)
            for i, n in enumerate(self.names):
                out[n] = arr[:, i]
        return out
