"""The closed loop of native (C) FMUs run in C: one call per flight.

When the native twins of a wiring's plant and controller exist in ``<fmu dir>/native/``
(``build_fmus.py`` builds them; same variable names, defaults and behaviour as the pythonfmu
FMUs), a flight runs entirely in C: the two native FMUs inside fmpy's container FMU, whose one
``doStep`` over the horizon steps them on the wiring's communication grid (the master algorithm
of :mod:`synthesis.fmi.closed_loop`, so the same numbers as the Python master).

:class:`NativeContainerLoop` is the :class:`~synthesis.fmi.container_loop.ContainerLoop` of those
FMUs with the Python side of a flight cut to what changes per candidate: the FMI functions of the
container's library are called directly, and the start values of a run are compared with the
components' declared ones as arrays (a law's start values have the same names every time), so
only those that differ are set -- one ``fmi2SetReal`` and one ``fmi2SetInteger`` per flight.  The
runner hands a law's start values over as :class:`~synthesis.fmi.start_values.StartValues`
(names and one array, from ``NetworkOperator.start_array``: 15 us a law where a dict takes 46 us
and its reading as an array 22 us more per flight).

:func:`native_fmus` says whether a wiring's native twins exist (:func:`missing_twins`: why not).
"""
from __future__ import annotations

import ctypes
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoopResult, Wiring

from descent_fmus.synthesis.fmi.slave import FMUError
from descent_fmus.synthesis.fmi.container_loop import ContainerLoop
from descent_fmus.synthesis.fmi.start_values import StartValues

__all__ = ["NativeContainerLoop", "Layouts", "native_fmus", "twin_of", "missing_twins",
           "NATIVE_DIR"]

#: The folder of the native FMUs inside the FMU folder.
NATIVE_DIR = "native"

_c_void_p, _c_size_t, _c_int, _c_double = (ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int,
                                           ctypes.c_double)
_SET_REAL = ctypes.CFUNCTYPE(_c_int, _c_void_p, ctypes.POINTER(ctypes.c_uint), _c_size_t,
                             ctypes.POINTER(_c_double))
_SET_INT = ctypes.CFUNCTYPE(_c_int, _c_void_p, ctypes.POINTER(ctypes.c_uint), _c_size_t,
                            ctypes.POINTER(_c_int))


def native_fmus(wiring: Wiring, plant_fmu, controller_fmu) -> tuple[Path, Path] | None:
    """The native twins ``(plant, controller)`` of the wiring's generic FMUs, or None.

    The twins are ``<dir>/native/<identifier>.fmu`` beside the given FMUs, which must be the
    wiring's own (``<dir>/<identifier>.fmu``): a problem flying another FMU (an exported
    controller with other defaults, a user's plant) has no twin."""
    out = [twin_of(plant_fmu, wiring.plant), twin_of(controller_fmu, wiring.controller)]
    return None if None in out else (out[0], out[1])


def twin_of(fmu, identifier: str) -> Path | None:
    """The native twin ``<dir>/native/<identifier>.fmu`` of the FMU ``<dir>/<identifier>.fmu``,
    or None (no twin, or ``fmu`` is not named after ``identifier``)."""
    fmu = Path(fmu)
    twin = fmu.parent / NATIVE_DIR / f"{identifier}.fmu"
    return twin if fmu.stem == identifier and twin.is_file() else None


def missing_twins(wiring: Wiring, plant_fmu, controller_fmu) -> str | None:
    """Why a wiring's flights run on its pythonfmu FMUs: the native twins :func:`native_fmus`
    looks for and does not find, in one line (None when both exist)."""
    missing = []
    for path, ident in ((Path(plant_fmu), wiring.plant), (Path(controller_fmu),
                                                           wiring.controller)):
        twin = path.parent / NATIVE_DIR / f"{ident}.fmu"
        if path.stem != ident:
            missing.append(f"{path.name} is not named after its model identifier {ident}")
        elif not twin.is_file():
            missing.append(f"no {NATIVE_DIR}/{ident}.fmu beside {path.name}")
    if not missing:
        return None
    return ("flying the pythonfmu FMUs: " + "; ".join(missing) + " (descent-fmus build-plant "
            "PLANT.py builds a plant's twin, python build_fmus.py the package's)")


class _Layout:
    """How the start values of one component reach an FMU: for a fixed sequence of names, the
    value references, types and declared start values as arrays, and the buffers the FMI calls
    read (made once).  ``lookup(name)`` gives ``(model variable or None, declared start or
    None)``; ``where`` names the FMU in errors."""

    def __init__(self, names: tuple, lookup, where: str):
        self.names = names
        kinds, vrs, starts = [], [], []
        for name in names:
            v, start = lookup(name)
            if v is None:
                raise KeyError(f"{where} has no parameter {name!r}")
            if v.type not in ("Real", "Integer", "Enumeration"):
                raise TypeError(f"cannot set {v.type} variable {name}")
            kinds.append(v.type == "Real")
            vrs.append(v.valueReference)
            starts.append(math.nan if start is None else float(start))
        n = len(names)
        self.is_real, self.vr = np.array(kinds, dtype=bool), np.array(vrs, dtype=np.uint32)
        self.start = np.array(starts)
        self.bufs = ((ctypes.c_uint * n)(), (ctypes.c_double * n)(), (ctypes.c_uint * n)(),
                     (ctypes.c_int * n)())
        self.views = tuple(np.frombuffer(b, dtype=t) for b, t in zip(
            self.bufs, (np.uint32, np.float64, np.uint32, np.int32)))

    def fill(self, v: np.ndarray) -> tuple:
        """Put the values ``v`` (in the order of the names) that differ from the declared start
        values (a NaN start: always) into the buffers: ``(number of Reals, of Integers)``."""
        d = np.flatnonzero(v != self.start)
        real = self.is_real[d]
        rd, idd = d[real], d[~real]
        rvr_v, rval_v, ivr_v, ival_v = self.views
        if len(rd):
            values = v[rd]
            if not np.isfinite(values).all():
                raise self._not_finite(rd[np.flatnonzero(~np.isfinite(values))[0]], v)
            rvr_v[:len(rd)] = self.vr[rd]
            rval_v[:len(rd)] = values
        if len(idd):
            ivr_v[:len(idd)] = self.vr[idd]
            ival_v[:len(idd)] = v[idd]
        return len(rd), len(idd)

    def _not_finite(self, k: int, v: np.ndarray) -> ValueError:
        return ValueError(f"value of {self.names[k]} must be finite, got {v[k]!r}")

    def fill_many(self, V: np.ndarray) -> tuple:
        """:meth:`fill` of every row of ``V`` (one flight's values a row) at once, packed as a
        batch of flights takes them (``dm_fly_many``): ``(arrays, errors)``, ``arrays`` the
        Reals and Integers per row (C longs), then the Reals' value references and values and
        the Integers' (the rows' entries one after the other, each row's in :meth:`fill`'s
        order), ``errors`` ``{row: ValueError}`` for the rows :meth:`fill` would refuse."""
        rows, cols = np.nonzero(V != self.start)          # row by row, as flatnonzero per row
        real = self.is_real[cols]
        values = V[rows, cols]
        errors = {}
        bad = real & ~np.isfinite(values)
        for r in np.unique(rows[bad]).tolist():
            errors[r] = self._not_finite(int(cols[bad & (rows == r)][0]), V[r])
        n, c_long = len(V), np.dtype(ctypes.c_long)
        arrays = (np.bincount(rows[real], minlength=n).astype(c_long),
                  np.ascontiguousarray(self.vr[cols[real]]), np.ascontiguousarray(values[real]),
                  np.bincount(rows[~real], minlength=n).astype(c_long),
                  np.ascontiguousarray(self.vr[cols[~real]]),
                  values[~real].astype(np.int32))
        return arrays, errors


class Layouts:
    """The :class:`_Layout` of each ``(role, names)`` met so far (a law's names: the same tuple
    every time, found at once); ``lookup(role)`` gives a role's name lookup."""

    def __init__(self, lookup, where: str):
        self._lookup, self._where, self._known = lookup, where, {}

    def get(self, role: str, values):
        """``(layout, value array)`` of a component's start values (a mapping:
        :class:`~synthesis.fmi.start_values.StartValues` or a dict); None for no values."""
        if not values:
            return None
        sv = StartValues.of(values)
        names, v = sv.names, sv.values
        key = (role, names)
        lay = self._known.get(key)
        if lay is None:
            if len(self._known) > 64:            # names of ad-hoc calls: keep a few only
                self._known.clear()
            lay = self._known[key] = _Layout(names, self._lookup(role), self._where)
        return lay, v


class NativeContainerLoop(ContainerLoop):
    """The closed loop of a plant and a controller (the native twins, or any FMI 2.0 FMUs) as
    one fmpy container FMU run by direct calls; same ``run`` as
    :class:`~synthesis.fmi.container_loop.ContainerLoop` (final outputs, no recording)."""

    path = "native-container"

    def __init__(self, wiring: Wiring, plant_fmu, controller_fmu):
        super().__init__(wiring, plant_fmu, controller_fmu)
        dll, self._c = self.fmu.dll, self.fmu.component
        self._fn = {name: getattr(dll, name) for name in (
            "fmi2Reset", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
            "fmi2ExitInitializationMode", "fmi2DoStep", "fmi2GetReal", "fmi2GetInteger",
            "fmi2GetBoolean")}
        self._set_real = _SET_REAL(("fmi2SetReal", dll))
        self._set_int = _SET_INT(("fmi2SetInteger", dll))
        self._layouts = Layouts(self._lookup, wiring.name)
        self._out = {}
        for kind, ctype in (("Real", ctypes.c_double), ("Integer", ctypes.c_int),
                            ("Boolean", ctypes.c_int)):
            vrs = self._out_vr[kind]
            self._out[kind] = ((ctypes.c_uint * len(vrs))(*vrs), len(vrs),
                               (ctype * len(vrs))(), self._out_names[kind])

    def _lookup(self, role: str):
        """A role's name -> (container variable, declared start) lookup."""
        def lookup(name):
            cname = self._names.get((role, name), name)
            return self._vars.get(cname), self._starts.get(cname)
        return lookup

    def _set_values(self, role: str, values) -> int:
        """Set a component's start values (a mapping): one fmi2SetReal, one fmi2SetInteger."""
        got = self._layouts.get(role, values)
        if got is None:
            return 0
        lay, v = got
        nr, ni = lay.fill(v)
        rvr, rval, ivr, ival = lay.bufs
        status = self._set_real(self._c, rvr, nr, rval) if nr else 0
        if ni:
            status |= self._set_int(self._c, ivr, ni, ival)
        return status

    def run(self, plant_values: Mapping | None = None, controller_values: Mapping | None = None,
            stop_time: float | None = None, record: bool = False, **_) -> ClosedLoopResult:
        """One flight from t = 0 to the stop time in one ``doStep``; the final plant outputs."""
        if record:
            raise ValueError("the container path records no trajectory; use ClosedLoop")
        t_end = self.wiring.stop_time if stop_time is None else float(stop_time)
        fn, c = self._fn, self._c
        del self.log[:]
        if self._used and fn["fmi2Reset"](c) > 1:
            self._fail("fmi2Reset")
        self._used = True
        if (self._set_values("plant", plant_values)
                | self._set_values("controller", controller_values)) > 1:
            self._fail("setting the start values")
        if (fn["fmi2SetupExperiment"](c, 0, 0.0, 0.0, 1, t_end) > 1
                or fn["fmi2EnterInitializationMode"](c) > 1
                or fn["fmi2ExitInitializationMode"](c) > 1):
            self._fail("initialisation")
        if fn["fmi2DoStep"](c, 0.0, t_end, 1) > 1:
            self._fail("doStep")
        final = {}
        for kind, getter, conv in (("Real", "fmi2GetReal", float),
                                   ("Integer", "fmi2GetInteger", int),
                                   ("Boolean", "fmi2GetBoolean", int)):
            vrs, n, buf, names = self._out[kind]
            if n:
                if fn[getter](c, vrs, n, buf) > 1:
                    self._fail("reading the outputs")
                final.update(zip(names, buf) if kind == "Real" else zip(names, map(conv, buf)))
        stop = self.wiring.stop
        stopped = bool(stop is not None and stop.output in final and stop.holds(final[stop.output]))
        return ClosedLoopResult(time=np.zeros(0), outputs={}, final=final, stopped=stopped,
                                steps=int(math.ceil(t_end / self.wiring.step - 1e-9)),
                                t_final=t_end, start=dict(plant_values or {}))

    def _fail(self, what: str):
        said = "; ".join(m.strip() for m in self.log if m.strip())
        raise FMUError(f"{self.wiring.name} ({self.path}): {what} failed"
                       + (f": {said}" if said else ""))
