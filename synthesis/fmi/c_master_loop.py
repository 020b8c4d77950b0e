"""The closed loop of two native FMUs stepped by a small C master: one call per flight.

The master (``synthesis/fmi/native/c/master/master.c``) is the Python master's algorithm
(:class:`synthesis.fmi.closed_loop.ClosedLoop`) written in C, call for call: reset, start values,
initialisation, then the Gauss-Seidel exchange and the two ``doStep`` calls on the grid
``t_k = k h``, ending at the wiring's stop condition.  The same FMUs give the same numbers bit for
bit as the Python master and as fmpy's container FMU (whose frozen plant ends where the stop
condition held), at the cost of the FMUs' own work: no Python and no container between two
steps.

The master is a shared library compiled here once per machine (:func:`master_library`: kept
in :func:`synthesis.paths.cache_dir`, keyed by the compiler and the source), loaded once per
process.  :class:`CMasterLoop` extracts the two FMUs, loads their binaries through it and flies
with one ``dm_fly`` call: a flight sets only the start values that differ from the FMUs'
declared ones (a law's come as :class:`~synthesis.fmi.start_values.StartValues`: names, array).
:meth:`CMasterLoop.run_many` flies a batch of flights with one ``dm_fly_many`` call (the same
``dm_fly`` per flight, in C): the start values packed as arrays for the whole batch, the final
outputs read from arrays.
"""
from __future__ import annotations

import ctypes
import math
from collections.abc import Mapping
import os
import shutil
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoopResult, Wiring
from descent_fmus.synthesis.fmi.description.declared import declared_starts
from descent_fmus.synthesis.fmi.native_loop import Layouts
from descent_fmus.synthesis.fmi.slave import FMUError, not_an_output

__all__ = ["CMasterLoop", "master_library", "MasterUnavailable",
           "STOP_TYPES", "STOP_OPS"]

_SOURCES = ("master.c", "master.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")
#: The stop condition as ``dm_wire`` takes it: the output's type and the operator, coded.
STOP_TYPES = {"Real": 1, "Integer": 2, "Boolean": 3}
STOP_OPS = {"!=": 0, "<=": 1, ">=": 2}
_LOCK = threading.Lock()
_LOADED: dict = {}


class MasterUnavailable(RuntimeError):
    """The C master cannot be built here (no compiler, or the build failed)."""


class _Values(ctypes.Structure):
    _fields_ = [("nr", ctypes.c_size_t), ("rvr", ctypes.c_void_p), ("rval", ctypes.c_void_p),
                ("ni", ctypes.c_size_t), ("ivr", ctypes.c_void_p), ("ival", ctypes.c_void_p)]


class _BatchValues(ctypes.Structure):
    _fields_ = [("nr", ctypes.c_void_p), ("rvr", ctypes.c_void_p), ("rval", ctypes.c_void_p),
                ("ni", ctypes.c_void_p), ("ivr", ctypes.c_void_p), ("ival", ctypes.c_void_p)]


class _Outputs(ctypes.Structure):
    _fields_ = [("nr", ctypes.c_size_t), ("ni", ctypes.c_size_t), ("nb", ctypes.c_size_t),
                ("rvr", ctypes.c_void_p), ("ivr", ctypes.c_void_p), ("bvr", ctypes.c_void_p),
                ("rval", ctypes.c_void_p), ("ival", ctypes.c_void_p), ("bval", ctypes.c_void_p),
                ("n0", ctypes.c_size_t), ("vr0", ctypes.c_void_p), ("val0", ctypes.c_void_p)]


def master_library(compiler: str | None = None) -> Path:
    """The compiled C master (built on first use, then found in the cache).

    Raises
    ------
    MasterUnavailable
        No C compiler, or it failed on the master's source (the message says which).
    """
    from descent_fmus.synthesis.fmi.native.builders.build import (CompilerNotFoundError,
                                                         NativeBuildError, cached_library,
                                                         find_compiler)
    cc = compiler or find_compiler()
    if cc is None:
        raise MasterUnavailable("no C compiler found to build the C master (install gcc, or "
                                "set CC)")
    try:
        return cached_library("master", ["master.c"], _SOURCES[1:], cc, libraries=("m", "dl"))
    except (CompilerNotFoundError, NativeBuildError) as exc:
        raise MasterUnavailable(f"cannot build the C master: {exc}") from None


def _dll(path: Path):
    """The master library, loaded once per process, with its functions' signatures."""
    with _LOCK:
        dll = _LOADED.get(path)
        if dll is None:
            dll = ctypes.CDLL(str(path))
            p, s, d, i, u, l_ = (ctypes.c_void_p, ctypes.c_char_p, ctypes.c_double,
                                 ctypes.c_int, ctypes.c_uint, ctypes.c_long)
            dll.dm_open.restype, dll.dm_open.argtypes = p, [s] * 6
            dll.dm_message.restype, dll.dm_message.argtypes = s, [p]
            dll.dm_close.restype, dll.dm_close.argtypes = None, [p]
            dll.dm_wire.restype = i
            dll.dm_wire.argtypes = [p, ctypes.c_size_t, p, p, ctypes.c_size_t, p, p, d, i, u, i,
                                    d, l_]
            dll.dm_fly.restype = i
            dll.dm_fly.argtypes = [p, d, p, p, p, ctypes.POINTER(l_), ctypes.POINTER(i)]
            dll.dm_fly_many.restype = l_
            dll.dm_fly_many.argtypes = [p, l_, l_, d, p, p, p, p, p]
            _LOADED[path] = dll
        return dll


def _uint_array(values):
    return (ctypes.c_uint * max(len(values), 1))(*values)


class _Fmu:
    """One extracted FMU: its model description, variables, declared starts and binary."""

    def __init__(self, path, role: str, tmp: str):
        from fmpy import extract, read_model_description

        from descent_fmus.synthesis.fmi.native.builders.build import platform_folder
        self.md = read_model_description(str(path))
        if self.md.coSimulation is None:
            raise FMUError(f"{path}: not a co-simulation FMU")
        self.dir = extract(str(path), unzipdir=os.path.join(tmp, role))
        folder, suffix = platform_folder()
        self.binary = Path(self.dir, "binaries", folder,
                           self.md.coSimulation.modelIdentifier + suffix)
        if not self.binary.is_file():
            raise FMUError(f"{path}: no binary for {folder} ({self.binary.name})")
        self.resources = Path(self.dir, "resources").as_uri()
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.starts = declared_starts(self.md)

    def var(self, name: str):
        try:
            return self.vars[name]
        except KeyError:
            raise KeyError(f"{self.md.modelName} has no variable {name!r}") from None


class CMasterLoop:
    """A plant and a controller FMU (native, FMI 2.0 co-simulation) in closed loop under the C
    master; same ``run`` as :class:`~synthesis.fmi.closed_loop.ClosedLoop` for final outputs
    (no recording, the wiring's step, Gauss-Seidel).  ``initial``: plant Real outputs also
    read at t = 0, after the first exchange of values, where a recording takes its first
    sample (each result's ``initial``; what an objective's ``initial(...)`` reads without a
    recording).

    Raises
    ------
    MasterUnavailable
        No C master on this machine (the runner then takes fmpy's container).
    FMUError
        An FMU that cannot be extracted, loaded or instantiated.
    """

    #: The closed-loop path, in one word (what a run reports).
    path = "native-c"

    def __init__(self, wiring: Wiring, plant_fmu, controller_fmu, initial=()):
        self._dll = _dll(master_library())
        self.wiring, self._m, self.initial = wiring, None, tuple(initial)
        self._files = (plant_fmu, controller_fmu)
        self._twin = None             # a second master: flies a batch's second half (split)
        self._helper = None
        #: seconds the twin flew beside this thread, less this thread's waits for it (at
        #: least 0 a batch: a helper that starts late can wait longer than it flew), summed
        #: over every split batch: with a batch's wall time, its flights' compute time
        self.twin_seconds = 0.0
        self.twin_flights = 0         #: flights the twin was given (split batches' halves)
        self._tmp = tempfile.mkdtemp(prefix="descent_c_master_")
        try:
            self._open(wiring)
        except BaseException:
            self.close()
            raise

    def _master(self, folder: str) -> tuple:
        """``(plant, controller, master)``: the two FMUs extracted into ``folder`` and loaded
        by a new C master (its own instances)."""
        plant_fmu, controller_fmu = self._files
        p, c = _Fmu(plant_fmu, "plant", folder), _Fmu(controller_fmu, "controller", folder)
        m = self._dll.dm_open(str(p.binary).encode(), p.md.guid.encode(),
                              p.resources.encode(), str(c.binary).encode(),
                              c.md.guid.encode(), c.resources.encode())
        if not m:
            raise MemoryError("the C master could not allocate its state")
        return p, c, m

    def _open(self, wiring: Wiring) -> None:
        p, c, self._m = self._master(self._tmp)
        self._fmus = {"plant": p, "controller": c}
        self._check(f"{wiring.name} (native-c): loading the FMUs")
        self._wire(wiring, p, c, self._m)
        self._layouts = Layouts(self._lookup, wiring.name)
        self._none = _Values()
        outs = {t: [v for v in p.md.modelVariables if v.causality == "output" and v.type == t]
                for t in ("Real", "Integer", "Boolean")}
        self._out_names = {t: [v.name for v in vs] for t, vs in outs.items()}
        vr = {t: _uint_array([v.valueReference for v in vs]) for t, vs in outs.items()}
        self._out_buf = {"Real": (ctypes.c_double * max(len(outs["Real"]), 1))(),
                         "Integer": (ctypes.c_int * max(len(outs["Integer"]), 1))(),
                         "Boolean": (ctypes.c_int * max(len(outs["Boolean"]), 1))()}
        a = ctypes.addressof
        first = [p.var(name) for name in self.initial]
        for v in first:
            if v.causality != "output" or v.type != "Real":
                raise KeyError(f"{p.md.modelName}: {v.name!r} is not a Real output (read at t = 0)")
        vr["initial"] = _uint_array([v.valueReference for v in first])
        self._first_buf = (ctypes.c_double * max(len(self.initial), 1))()
        self._keep = vr
        self._outputs = _Outputs(len(outs["Real"]), len(outs["Integer"]), len(outs["Boolean"]),
                                 a(vr["Real"]), a(vr["Integer"]), a(vr["Boolean"]),
                                 a(self._out_buf["Real"]), a(self._out_buf["Integer"]),
                                 a(self._out_buf["Boolean"]), len(self.initial),
                                 a(vr["initial"]), a(self._first_buf))
        self._steps, self._stopped = ctypes.c_long(), ctypes.c_int()

    def _wire(self, w: Wiring, p: _Fmu, c: _Fmu, m) -> None:
        y = _uint_array([p.var(a).valueReference for a, _ in w.to_controller])
        x = _uint_array([c.var(b).valueReference for _, b in w.to_controller])
        u = _uint_array([c.var(a).valueReference for a, _ in w.to_plant])
        pu = _uint_array([p.var(b).valueReference for _, b in w.to_plant])
        stop_type, stop_vr, stop_op, stop_value, check = 0, 0, 0, 0.0, 1
        if w.stop is not None:
            sv = p.var(w.stop.output)
            if sv.causality != "output":
                raise KeyError(not_an_output(p.md, w.stop.output))
            stop_type, stop_vr = STOP_TYPES.get(sv.type, 1), sv.valueReference
            stop_op, stop_value, check = STOP_OPS[w.stop.op], w.stop.value, w.stop.check_every
        if self._dll.dm_wire(m, len(w.to_controller), y, x, len(w.to_plant), u, pu,
                             w.step, stop_type, stop_vr, stop_op, stop_value, check):
            self._check(f"{w.name} (native-c): wiring", m)

    def _lookup(self, role: str):
        fmu = self._fmus[role]
        return lambda name: (fmu.vars.get(name), fmu.starts.get(name))

    def _said(self, m=None) -> str:
        """The message of master ``m`` (default this loop's) about its last failed call."""
        return (self._dll.dm_message(self._m if m is None else m) or b"").decode(
            errors="replace")

    def _failure(self, what: str, m=None) -> FMUError:
        """The error of the call that just failed, with the message of master ``m`` (default
        this loop's) if it has one."""
        said = self._said(m)
        return FMUError(f"{what} failed: {said}" if said else f"{what} failed")

    def _check(self, what: str, m=None) -> None:
        said = self._said(m)
        if said:
            raise FMUError(f"{what} failed: {said}")

    def _stop_time(self, stop_time) -> float:
        """The flight's end time (the wiring's by default), checked, on an open loop."""
        t_end = self.wiring.stop_time if stop_time is None else float(stop_time)
        if not (t_end > 0 and math.isfinite(t_end)):
            raise ValueError(f"need a finite stop time > 0, got {t_end}")
        if self._m is None:
            raise FMUError(f"{self.wiring.name} (native-c): the loop is closed")
        return t_end

    def _result(self, final: dict, stopped, steps: int, t_end: float, plant_values, first=()):
        return ClosedLoopResult(time=np.zeros(0), outputs={}, final=final,
                                stopped=bool(stopped), steps=steps,
                                t_final=min(steps * self.wiring.step, t_end),
                                start=dict(plant_values or {}),
                                initial=dict(zip(self.initial, first)))

    def _values(self, role: str, values):
        """The ``_Values`` of a component's start values for this flight (kept on the layout,
        which holds the buffers it points to)."""
        got = self._layouts.get(role, values)
        if got is None:
            return self._none
        lay, v = got
        st = getattr(lay, "c_values", None)
        if st is None:
            rvr, rval, ivr, ival = (ctypes.addressof(b) for b in lay.bufs)
            st = lay.c_values = _Values(0, rvr, rval, 0, ivr, ival)
        st.nr, st.ni = lay.fill(v)
        return st

    def run(self, plant_values: Mapping | None = None, controller_values: Mapping | None = None,
            stop_time: float | None = None, step: float | None = None, record: bool = False,
            scheme: str = "gauss-seidel") -> ClosedLoopResult:
        """One flight from t = 0; the final plant outputs.  The start values: mappings
        (:class:`~synthesis.fmi.start_values.StartValues` or dicts)."""
        w = self.wiring
        if record:
            raise ValueError("the C master records no trajectory; use ClosedLoop")
        if scheme != "gauss-seidel" or (step is not None and float(step) != w.step):
            raise ValueError("the C master steps on the wiring's grid, Gauss-Seidel only; use "
                             "ClosedLoop for another step or scheme")
        t_end = self._stop_time(stop_time)
        pv = self._values("plant", plant_values)
        cv = self._values("controller", controller_values)
        if self._dll.dm_fly(self._m, t_end, ctypes.byref(pv), ctypes.byref(cv),
                            ctypes.byref(self._outputs), ctypes.byref(self._steps),
                            ctypes.byref(self._stopped)):
            raise self._failure(f"{w.name} (native-c): the flight")
        final = dict(zip(self._out_names["Real"], self._out_buf["Real"]))
        for kind in ("Integer", "Boolean"):
            final.update(zip(self._out_names[kind], map(int, self._out_buf[kind])))
        return self._result(final, self._stopped.value, self._steps.value, t_end, plant_values,
                            list(self._first_buf))

    def run_many(self, flights, stop_time: float | None = None) -> list:
        """Flights ``[(plant values, controller values), ...]`` from t = 0 in one
        ``dm_fly_many`` call: per flight the :class:`ClosedLoopResult` :meth:`run` gives, or the
        exception it would raise (a failed flight does not stop the others)."""
        t_end = self._stop_time(stop_time)
        out: list = [None] * len(flights)
        packed = [self._pack(role, [f[k] for f in flights])
                  for k, role in enumerate(("plant", "controller"))]
        if any(p is None for p in packed):        # values by other names: one flight a call
            return [self._run_one(p, c, t_end) for p, c in flights]
        errors = {**packed[0][1], **packed[1][1]}
        if errors:                                # refused values: the rest flies without them
            good = [k for k in range(len(flights)) if k not in errors]
            for k, r in zip(good, self.run_many([flights[k] for k in good], t_end)):
                out[k] = r
            for k, exc in errors.items():
                out[k] = exc
            return out
        return self._fly_packed(flights, packed[0][0], packed[1][0], t_end)

    def _run_one(self, plant_values, controller_values, t_end):
        try:
            return self.run(plant_values, controller_values, stop_time=t_end)
        except Exception as exc:        # as a flight of run() would raise it
            return exc

    def _pack(self, role: str, values: list):
        """``(arrays, errors)`` of one component's start values over a batch
        (:meth:`~synthesis.fmi.native_loop._Layout.fill_many`; no values: zero counts), or None
        when the flights name different values."""
        n = len(values)
        if not any(values):
            zero = np.zeros(n, dtype=np.dtype(ctypes.c_long))
            return (zero, np.zeros(1, np.uint32), np.zeros(1), zero, np.zeros(1, np.uint32),
                    np.zeros(1, np.int32)), {}
        seen: dict = {}
        rows = []
        for v in values:
            got = seen.get(id(v))
            if got is None:
                try:
                    got = seen[id(v)] = self._layouts.get(role, v) if v else None
                except (KeyError, TypeError):     # each flight says so (run_one)
                    return None
            if got is None:
                return None
            rows.append(got)
        lay = rows[0][0]
        if any(r[0] is not lay for r in rows):
            return None
        return lay.fill_many(np.stack([r[1] for r in rows]))

    def split(self) -> bool:
        """Fly every batch of two or more flights in two threads from now on: the first half
        here, the second by a second C master (the FMUs extracted again and loaded by it: the
        masters' instances share no state) in a helper thread, each half one ``dm_fly_many``
        call with the GIL released; the start values are packed and the results read once,
        here.  A flight depends on its start values only, so every result is the one a single
        thread gives.  False (one thread goes on) when the second master cannot be opened."""
        if self._twin is not None:
            return True
        if self._m is None:
            return False
        from concurrent.futures import ThreadPoolExecutor
        m = None
        try:
            p, c, m = self._master(os.path.join(self._tmp, "twin"))
            self._check(f"{self.wiring.name} (native-c): loading the FMUs again", m)
            self._wire(self.wiring, p, c, m)
        except (FMUError, KeyError, OSError, MemoryError):
            if m:
                self._dll.dm_close(m)
            shutil.rmtree(os.path.join(self._tmp, "twin"), ignore_errors=True)
            return False
        self._twin = m
        self._helper = ThreadPoolExecutor(1, thread_name_prefix="descent-c-master")
        return True

    def _fly_range(self, m, lo: int, hi: int, args) -> dict:
        """Flights ``lo .. hi - 1`` of a packed batch on master ``m`` (this loop's or its
        twin's): ``dm_fly_many``, again after each failed flight from the next one; the
        failed flights' errors by index."""
        failed, k = {}, lo
        while k < hi:
            k = self._dll.dm_fly_many(m, k, hi, *args)
            if k < hi:
                failed[k] = self._failure(f"{self.wiring.name} (native-c): the flight", m)
                k += 1
        return failed

    def _fly_packed(self, flights, plant, ctrl, t_end: float) -> list:
        """The flights of a packed batch (no refused values): one ``dm_fly_many`` call, again
        after each failed flight from the next one; split in two threads after
        :meth:`split`."""
        n, a = len(flights), ctypes.addressof
        o = self._outputs
        bufs = {"Real": np.zeros((n, max(o.nr, 1))), "Integer": np.zeros((n, max(o.ni, 1)),
                                                                          np.int32),
                "Boolean": np.zeros((n, max(o.nb, 1)), np.int32)}
        steps = np.zeros(n, dtype=np.dtype(ctypes.c_long))
        stopped = np.zeros(n, dtype=np.int32)
        first = np.zeros((n, max(o.n0, 1)))
        outs = _Outputs(o.nr, o.ni, o.nb, o.rvr, o.ivr, o.bvr, bufs["Real"].ctypes.data,
                        bufs["Integer"].ctypes.data, bufs["Boolean"].ctypes.data, o.n0, o.vr0,
                        first.ctypes.data)
        pv, cv = (_BatchValues(*(x.ctypes.data for x in arrays)) for arrays in (plant, ctrl))
        args = (t_end, a(pv), a(cv), a(outs), steps.ctypes.data, stopped.ctypes.data)
        half = n // 2 if self._twin is not None and n > 1 else n
        theirs, failed_theirs = None, {}
        if half < n:        # the rows written are disjoint; the packed values are only read
            theirs = self._helper.submit(self._timed_range, self._twin, half, n, args)
            self.twin_flights += n - half
        try:
            failed = self._fly_range(self._m, 0, half, args)
        finally:
            if theirs is not None:          # never leaves with the twin's flight running
                t_mine = time.perf_counter()
                failed_theirs, seconds = theirs.result()
                self.twin_seconds += max(0.0, seconds - (time.perf_counter() - t_mine))
        failed.update(failed_theirs)
        names = self._out_names
        ints = [(t, names[t], bufs[t].tolist()) for t in ("Integer", "Boolean") if names[t]]
        reals, steps_l, stopped_l = bufs["Real"].tolist(), steps.tolist(), stopped.tolist()
        firsts = first.tolist() if o.n0 else [()] * n     # none asked for: nothing to read
        out = []
        for i, (pvals, _) in enumerate(flights):
            if i in failed:
                out.append(failed[i])
                continue
            final = dict(zip(names["Real"], reals[i]))
            for _, nm, rows in ints:
                final.update(zip(nm, rows[i]))
            out.append(self._result(final, stopped_l[i], steps_l[i], t_end, pvals, firsts[i]))
        return out

    def _timed_range(self, m, lo: int, hi: int, args) -> tuple:
        t0 = time.perf_counter()
        failed = self._fly_range(m, lo, hi, args)
        return failed, time.perf_counter() - t0

    def close(self) -> None:
        helper, self._helper = self._helper, None
        if helper is not None:
            helper.shutdown(wait=True)
        twin, self._twin = self._twin, None
        if twin:
            self._dll.dm_close(twin)
        m, self._m = self._m, None
        if m:
            self._dll.dm_close(m)
        self.remove_files()

    def remove_files(self) -> None:
        """Delete the extracted FMUs (files only: no FMU call)."""
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
