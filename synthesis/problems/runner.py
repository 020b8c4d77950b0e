"""How a problem flies a candidate law: which closed-loop path, which flights.

By default every law flies from every initial state of its problem through
:class:`synthesis.fmi.closed_loop.ClosedLoop` (the fmpy master stepping two FMUs).  A problem's
:class:`Runner` may choose instead

* the **container path** (``container=True``): the closed loop as one fmpy container FMU,
  loaded once per process, reset per flight, one ``doStep`` over the whole horizon
  (:class:`synthesis.fmi.container_loop.ContainerLoop`);
* **racing** (``race``): the initial states are flown in stages; after each stage the problem's
  ``proceed(flights so far)`` decides whether the law flies the rest.  A law that is bad on the
  first flights (e.g. the nominal one) does not fly the whole set; the problem's objective
  function receives the shorter list and must rank such a law behind every fully flown one.

Everything here pickles (worker processes, Dask): module-level callables only.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop, Wiring

__all__ = ["Runner", "Race"]


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
    """A problem's choice of closed-loop path and flights (see the module docstring)."""

    container: bool = False
    race: Race | None = None

    def load(self, wiring: Wiring, plant_fmu, controller_fmu, record=()):
        """The loop the flights use, loaded once per process (recording needs the master)."""
        if self.container and not record:
            from descent_fmus.synthesis.fmi.container_loop import ContainerLoop
            return ContainerLoop(wiring, plant_fmu, controller_fmu)
        return ClosedLoop(wiring, plant_fmu, controller_fmu, record=record)

    def flights(self, loop, problem, law) -> list:
        """The flights of ``law`` (all initial states, or fewer if a race stopped it); each
        result carries its start values (``result.start``)."""
        sv = law.start_values()
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
