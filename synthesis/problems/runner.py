"""How a problem flies a candidate law: which closed-loop path, which flights.

By default every law flies from every initial state of its problem through
:class:`synthesis.fmi.closed_loop.ClosedLoop` (the fmpy master stepping two FMUs).  A problem's
:class:`Runner` chooses instead

* the **native path**, whenever the native (C) twins of the wiring's plant and controller are
  built (``<fmu dir>/native/<identifier>.fmu``, ``build_fmus.py``): both stepped by the C
  master, one call per flight, no Python in the flight
  (:class:`synthesis.fmi.c_master_loop.CMasterLoop`; where the master cannot be compiled, both
  inside fmpy's container FMU, :class:`synthesis.fmi.native_loop.NativeContainerLoop`); the
  same numbers as the pythonfmu path.  ``native=False`` never takes it, ``native=True``
  requires it (an error if the twins are missing; with a recording, the Python master on the
  twins);
* the **container path** (``container=True``): the closed loop as one fmpy container FMU,
  loaded once per process, reset per flight, one ``doStep`` over the whole horizon
  (:class:`synthesis.fmi.container_loop.ContainerLoop`);
* **racing** (``race``): the initial states are flown in stages; after each stage the problem's
  ``proceed(flights so far)`` decides whether the law flies the rest.  A law that is bad on the
  first flights (e.g. the nominal one) does not fly the whole set; the problem's objective
  function receives the shorter list and must rank such a law behind every fully flown one.

The loaded loop says which path it is in one word, its ``path``: ``"native-c"``,
``"native-container"``, ``"container"``, ``"master"`` (``"native-master"``: the Python master
on the twins).

Everything here pickles (worker processes, Dask): module-level callables only.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop, Wiring
from descent_fmus.synthesis.fmi.native_loop import native_fmus
from descent_fmus.synthesis.paths import FMUNotFoundError

__all__ = ["Runner", "Race"]


def _native_loop() -> str:
    """``"native-c"`` where the C master is built (or can be, once), else
    ``"native-container"`` (and a warning saying why, once per process)."""
    from descent_fmus.synthesis.fmi.c_master_loop import MasterUnavailable, master_library
    try:
        master_library()
        return "native-c"
    except MasterUnavailable as exc:
        if not _WARNED:
            _WARNED.append(1)
            warnings.warn(f"{exc}; the native flights run in fmpy's container FMU instead",
                          RuntimeWarning, stacklevel=3)
        return "native-container"


_WARNED: list = []


@dataclass(frozen=True)
class Race:
    """Fly the initial states in stages: after the first ``sizes[i]`` flights,
    ``proceed(flights)`` (a module-level function of the ClosedLoopResults so far) says whether
    the law flies on."""

    sizes: tuple
    proceed: Callable

    def __post_init__(self):
        if any(int(s) < 1 for s in self.sizes):
            raise ValueError(f"race stage sizes must be >= 1, got {self.sizes}")


@dataclass(frozen=True)
class Runner:
    """A problem's choice of closed-loop path and flights (see the module docstring):
    ``native`` None (default) takes the native path where the twins are built, True requires
    it, False never takes it."""

    container: bool = False
    race: Race | None = None
    native: bool | None = None

    def choose(self, wiring: Wiring, plant_fmu, controller_fmu, record=()) -> tuple:
        """``(path, (plant FMU, controller FMU))``: the path :meth:`load` takes, in one word,
        and the FMUs it flies (the native twins on a native path)."""
        twins = native_fmus(wiring, plant_fmu, controller_fmu) \
            if self.native is not False else None
        if self.native and twins is None:
            raise FMUNotFoundError(
                f"the native path needs the native FMUs {wiring.plant}.fmu and "
                f"{wiring.controller}.fmu in the folder native/ beside {plant_fmu} (python "
                f"build_fmus.py builds them where a C compiler exists)")
        if twins is not None:
            return ("native-master" if record else _native_loop()), twins
        return ("container" if self.container and not record else "master"), \
            (plant_fmu, controller_fmu)

    def load(self, wiring: Wiring, plant_fmu, controller_fmu, record=()):
        """The loop the flights use, loaded once per process (recording needs the master); its
        ``path`` names it."""
        path, fmus = self.choose(wiring, plant_fmu, controller_fmu, record)
        if path == "native-c":
            from descent_fmus.synthesis.fmi.c_master_loop import CMasterLoop
            return CMasterLoop(wiring, *fmus)
        if path == "native-container":
            from descent_fmus.synthesis.fmi.native_loop import NativeContainerLoop
            return NativeContainerLoop(wiring, *fmus)
        if path == "container":
            from descent_fmus.synthesis.fmi.container_loop import ContainerLoop
            return ContainerLoop(wiring, *fmus)
        loop = ClosedLoop(wiring, *fmus, record=record)
        loop.path = path
        return loop

    def flights(self, loop, problem, law) -> list:
        """The flights of ``law`` (all initial states, or fewer if a race stopped it); each
        result carries its start values (``result.start``)."""
        # the native loop reads a law's start values as one array (the same names and values)
        sv = law.start_array() if getattr(loop, "takes_arrays", False) \
            and hasattr(law, "start_array") else law.start_values()
        if problem.controller_values:       # the problem's controller mode over the law's values
            names, values = zip(*problem.controller_values)
            if isinstance(sv, tuple):
                sv = (sv[0] + names, np.concatenate([sv[1], np.asarray(values, float)]))
            else:
                sv = {**sv, **dict(problem.controller_values)}
        record = bool(problem.record)
        states = problem.initial_states
        stops = set(self.race.sizes) if self.race is not None else set()
        results = []
        for s in states:
            results.append(loop.run(plant_values=s, controller_values=sv, record=record))
            n = len(results)
            if n in stops and n < len(states) and not self.race.proceed(results):
                break
        return results
