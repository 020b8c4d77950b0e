"""How a problem flies a candidate law: which closed-loop path, which flights.

A problem's :class:`Runner` holds its choice of closed-loop path -- the native twins where
built (``native`` None), always (True) or never (False); the container FMU where no twins fly
(``container``) -- and :meth:`Runner.load` opens that loop through the one factory,
:func:`synthesis.fmi.loop.open_loop` (the paths: ``"native-c"``, ``"native-container"``,
``"container"``, ``"master"``, ``"native-master"``; the loaded loop's ``path`` names it).

:meth:`Runner.flights` flies a law from every initial state of its problem, or fewer with
**racing** (``race``): the initial states are flown in stages; after each stage the problem's
``proceed(flights so far)`` decides whether the law flies the rest.  A law that is bad on the
first flights (e.g. the nominal one) does not fly the whole set; the problem's objective
function receives the shorter list and must rank such a law behind every fully flown one.

Everything here pickles (worker processes, Dask): module-level callables only.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from descent_fmus.synthesis.fmi.closed_loop import Wiring
from descent_fmus.synthesis.fmi.loop import Loop, choose_path, open_loop
from descent_fmus.synthesis.fmi.start_values import StartValues

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
    """A problem's choice of closed-loop path and flights (see the module docstring):
    ``native`` None (default) takes the native path where the twins are built, True requires
    it, False never takes it."""

    container: bool = False
    race: Race | None = None
    native: bool | None = None

    def choose(self, wiring: Wiring, plant_fmu, controller_fmu, record=(), initial=()) -> tuple:
        """``(path, (plant FMU, controller FMU))``: the path :meth:`load` takes, in one word,
        and the FMUs it flies (:func:`synthesis.fmi.loop.choose_path`)."""
        return choose_path(wiring, plant_fmu, controller_fmu, self.native, self.container,
                           record, initial)

    def load(self, wiring: Wiring, plant_fmu, controller_fmu, record=(), initial=()) -> Loop:
        """The loop the flights use, loaded once per process (recording needs the master;
        ``initial``, outputs read at t = 0 only, the C master or a recording); its ``path``
        names it."""
        return open_loop(wiring, plant_fmu, controller_fmu, native=self.native,
                         container=self.container, record=record, initial=initial)

    def flights(self, loop: Loop, problem, law) -> list:
        """The flights of ``law`` (all initial states, or fewer if a race stopped it); each
        result carries its start values (``result.start``)."""
        sv = _law_values(problem, law)
        record = records(loop, problem)
        states = problem.initial_states
        stops = set(self.race.sizes) if self.race is not None else set()
        results = []
        for s in states:
            results.append(loop.run(plant_values=s, controller_values=sv, record=record))
            n = len(results)
            if n in stops and n < len(states) and not self.race.proceed(results):
                break
        return results

    def batches(self, loop: Loop, problem) -> bool:
        """Whether :meth:`batch_flights` flies ``problem``'s laws on ``loop`` (a loop with
        ``run_many``, no racing, no recording): one C call a batch, the GIL released in it."""
        return hasattr(loop, "run_many") and self.race is None and not records(loop, problem)

    def batch_flights(self, loop: Loop, problem, laws) -> list | None:
        """:meth:`flights` of each of ``laws`` in one call of the loop's ``run_many`` (the C
        master's batch): per law its flights, or the exception :meth:`flights` would raise (the
        first failing flight's, in the order of the initial states).  None where a batch does
        not apply: racing, recording, or a loop without ``run_many``."""
        if not self.batches(loop, problem):
            return None
        run_many = loop.run_many
        states = problem.initial_states
        out, flights = [], []
        for law in laws:
            try:
                sv = _law_values(problem, law)
            except Exception as exc:        # as flights() would raise it
                out.append(exc)
                continue
            out.append(len(flights))
            flights.extend((s, sv) for s in states)
        results = run_many(flights)
        m = len(states)
        for i, k in enumerate(out):
            if not isinstance(k, int):
                continue
            mine = results[k:k + m]
            out[i] = next((r for r in mine if isinstance(r, BaseException)), mine)
        return out


def records(loop: Loop, problem) -> bool:
    """Whether ``problem``'s flights on ``loop`` record: it names signals to record, or
    outputs at t = 0 (``initial``) that the loop does not read there itself."""
    return bool(problem.record) or not set(problem.initial) <= set(getattr(loop, "initial", ()))


def _law_values(problem, law) -> StartValues:
    """The law's start values and the problem's controller mode, in the one form."""
    return StartValues.of_law(law).merged(problem.controller_values)
