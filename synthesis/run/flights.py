"""Flying laws where the FMUs are loaded: one :class:`LawFlyer` per process (or per Dask worker),
whatever backend sends it the laws.

A flyer loads its problem's closed loop once (the path the problem's runner chooses), flies a
law over the problem's initial states and returns its :class:`~synthesis.problems.contract.Outcome`;
an FMU error costs that law only (reported as its error text, never raised).  Loaded FMUs are
freed, and their extracted folders removed, when the flyer closes -- at the latest at
interpreter exit, while Python is still whole (a pythonfmu instance holds Python objects; left
to the interpreter's teardown they would be released in no defined order).
"""
from __future__ import annotations

import atexit
import time
import weakref

from descent_fmus.synthesis.problems.contract import SynthesisProblem
from descent_fmus.synthesis.run.signals import check_stop, critical

__all__ = ["LawFlyer", "Flown", "BATCH_LAWS"]

#: [choice] Laws handed to the C master at once: one call for a CMA-ES generation, and a signal
#: waits at most for one call (~0.1 s): a requested stop in the run's own process, a worker's
#: SIGTERM handler (Python runs it only between two C calls).
BATCH_LAWS = 128

#: What flying one law gives: its Outcome, or None and the error text.
Flown = tuple


class LawFlyer:
    """A problem's closed loop, loaded once, flying laws (see the module docstring).

    Parameters
    ----------
    problem : SynthesisProblem
    plant, controller : str
        FMU files.
    """

    _alive: "weakref.WeakSet[LawFlyer]" = weakref.WeakSet()

    def __init__(self, problem: SynthesisProblem, plant: str, controller: str):
        self.problem = problem
        self.fmus = (plant, controller)
        self.loop = None
        self.error = None
        if not LawFlyer._alive:
            atexit.register(LawFlyer.close_all)
        LawFlyer._alive.add(self)
        try:
            with critical():        # instantiating a pythonfmu FMU runs its Python code
                self.loop = problem.load(plant, controller)
        except Exception as exc:   # FMUs that do not load: every law fails with that error
            self.error = _text(exc)

    def fly(self, law) -> Flown:
        """``(Outcome, None)``, or ``(None, error text)`` if an FMU call failed."""
        if self.loop is None:
            return None, self.error
        try:
            with critical():        # a stop waits for the flight's FMU calls
                return self.problem.fly(self.loop, law), None
        except Exception as exc:  # an FMU error costs this law only
            return None, _text(exc)

    def fly_all(self, laws, stoppable: bool = False) -> list:
        """:meth:`fly` of each law -- where the loop flies batches (the C master), in one call
        per :data:`BATCH_LAWS` laws, the same outcomes; with ``stoppable`` a requested stop
        (:func:`synthesis.run.signals.check_stop`) ends the batch between two laws (two
        batches)."""
        out = []
        i = 0
        while i < len(laws):
            if stoppable:
                check_stop()
            part = laws[i:i + BATCH_LAWS]
            got = self._fly_batch(part)
            if got is None:
                got, part = [self.fly(laws[i])], laws[i:i + 1]
            out.extend(got)
            i += len(part)
        return out

    def _fly_batch(self, laws) -> list | None:
        """:meth:`fly` of each law through the runner's batch (None: no batch here)."""
        if self.loop is None or not hasattr(self.loop, "run_many"):
            return None
        problem, out = self.problem, []
        with critical():            # a split batch: held until both halves are back
            flown = problem.runner.batch_flights(self.loop, problem, laws)
            if flown is None:
                return None
            for flights in flown:
                if isinstance(flights, BaseException):
                    out.append((None, _text(flights)))
                    continue
                try:
                    out.append((problem.evaluate(flights), None))
                except Exception as exc:  # as fly(): this law only
                    out.append((None, _text(exc)))
        return out

    def batches(self) -> bool:
        """Whether this flyer flies its laws in batches of the C master (one C call a batch,
        the GIL released in it)."""
        return self.loop is not None and self.problem.runner.batches(self.loop, self.problem)

    def split(self) -> bool:
        """Fly each batch in two threads from now on, where the loop can
        (:meth:`CMasterLoop.split <synthesis.fmi.c_master_loop.CMasterLoop.split>`: the C
        master's batches); whether it does."""
        return self.batches() and self.loop.split()

    def fly_timed(self, laws) -> tuple:
        """``(results, seconds)``: the chunk's results and its compute time (the backends'
        measure of the cost of a law): the wall time, and after :meth:`split` what the second
        thread flew beside this one."""
        t0 = time.perf_counter()
        beside = getattr(self.loop, "twin_seconds", 0.0)
        out = self.fly_all(laws)
        beside = getattr(self.loop, "twin_seconds", 0.0) - beside
        return out, time.perf_counter() - t0 + beside

    def remove_files(self) -> None:
        """Delete the extracted FMU folders (files only: no FMU call; safe in a signal
        handler)."""
        if self.loop is not None:
            self.loop.remove_files()

    def close(self) -> None:
        loop, self.loop = self.loop, None
        LawFlyer._alive.discard(self)
        if loop is not None:
            try:
                loop.close()
            except Exception:       # an FMU that cannot be freed: its folder still goes
                loop.remove_files()

    @classmethod
    def close_all(cls) -> None:
        for flyer in list(cls._alive):
            flyer.close()


def _text(exc: BaseException) -> str:
    """A failed law's error text, as every path of :class:`LawFlyer` records it."""
    return f"{type(exc).__name__}: {exc}"
