"""The one run loop of every synthesis method.

:class:`RunLoop` drives any :class:`~synthesis.methods.base.Method`: ask, evaluate, tell, offer
the evaluated candidates to the run's :class:`~synthesis.methods.pareto.ParetoArchive`, and at
every boundary of the method (between generations) hand over a checkpoint and check the budget
(flights, wall time, the method's own end).  It knows nothing of FMUs: the evaluation is a
function.

:func:`run_synthesis` is the loop for a synthesis problem: ``descent-fmus synthesize NAME
--out DIR`` (or ``--problem FILE.toml``) drives it.  It builds the method from the registry
(:mod:`synthesis.methods.registry`), the FMU evaluator (:mod:`synthesis.run.evaluation`) on the
chosen backend, the run folder (:mod:`synthesis.run.folder`: ``run.json``, ``checkpoint.json``,
``--resume``), shows progress, and writes the results (:mod:`synthesis.run.report`).  Signals,
systematic failures and full disks end it cleanly (:mod:`synthesis.run.guard`).
"""
from __future__ import annotations

import importlib
import threading
import time
from pathlib import Path
from typing import Callable

import numpy as np

from descent_fmus.synthesis.methods.base import Candidate, Method
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.pareto import ParetoArchive
from descent_fmus.synthesis.methods.registry import (NETWORK_OPERATOR, cma_target, entry_of,
                                                     make_method, method_names)
from descent_fmus.synthesis.problems.contract import SynthesisProblem
from descent_fmus.synthesis.run.evaluation import Evaluator
from descent_fmus.synthesis.run.folder import (RunDirError, RunFolder, recipe_defaults, run_spec,
                                               write_json)
from descent_fmus.synthesis.run.guard import guarded
from descent_fmus.synthesis.run.progress import Console
from descent_fmus.synthesis.run.report import write_results
from descent_fmus.synthesis.run.resources import check_memory

__all__ = ["RunLoop", "run_synthesis", "RunDirError", "NETWORK_OPERATOR", "method_names",
           "archive_state", "load_archive"]


#: Why a run ended (``summary.json``'s ``ended_by``) and how the summary says it.
END_REASONS = {"flights": "the flight budget ({limit}) was spent",
               "seconds": "the wall-time budget ({limit}) ran out",
               "generations": "the generation limit ({limit}) was reached",
               "signal": "a signal stopped it"}


class RunLoop:
    """Ask, evaluate, tell, archive -- until the budget is spent (see the module docstring).

    Parameters
    ----------
    method : Method
    evaluate : callable
        ``evaluate(laws) -> Evaluation`` (``F``, ``cv``, ``extras``, ``flown``): the laws of
        the method's candidates (e.g. :meth:`synthesis.run.evaluation.Evaluator.evaluate`).
    archive : ParetoArchive, optional
    flights : int
        Flight budget (laws flown, counted by ``Evaluation.flown``); 0 = none.
    seconds : float
        Wall-clock budget; 0 = none.
    flights_done : int
        Flights spent before this loop (a resumed run).
    on_boundary : callable, optional
        ``on_boundary(loop)`` at every boundary of the method (checkpoint, progress).
    stop_after : int, optional
        Stop after this many more generations and report an interruption (tests).
    on_phase : callable, optional
        ``on_phase(text)`` whenever the method's :attr:`~synthesis.methods.base.Method.phase`
        changes.
    """

    def __init__(self, method: Method, evaluate: Callable, archive: ParetoArchive | None = None,
                 flights: int = 0, seconds: float = 0.0, flights_done: int = 0,
                 on_boundary: Callable | None = None, stop_after: int | None = None,
                 on_phase: Callable | None = None):
        self.method, self.evaluate = method, evaluate
        self.archive = archive if archive is not None else ParetoArchive()
        self.flights_budget, self.seconds = flights, seconds
        self.flights = flights_done
        self.on_boundary = on_boundary
        self.stop_after = stop_after
        self.on_phase, self._phase = on_phase, None
        self.interrupted = False
        self.ended_by: str | None = None
        self._t0 = time.monotonic()
        self._gen0 = method.generation

    def spent(self) -> bool:
        """Whether a budget is used up (checked only at the method's boundaries); which one
        goes to :attr:`ended_by` (:data:`END_REASONS`)."""
        if self.flights_budget and self.flights >= self.flights_budget:
            self.ended_by = "flights"
        elif self.seconds and time.monotonic() - self._t0 >= self.seconds:
            self.ended_by = "seconds"
        elif self.method.finished():
            self.ended_by = getattr(self.method, "end_reason", "generations")
        return self.ended_by is not None

    def end_fields(self, generations: int | None = None) -> dict:
        """The summary's account of why the run ended: ``ended_by`` (a key of
        :data:`END_REASONS`), the sentence saying it and the flights left of the budget."""
        why = self.ended_by or "signal"
        limit = {"flights": f"{self.flights_budget} flights",
                 "seconds": f"{self.seconds:g} s",
                 "generations": f"{generations} generations"}.get(why, "")
        left = max(self.flights_budget - self.flights, 0) if self.flights_budget else None
        text = END_REASONS.get(why, why).format(limit=limit)
        if left:
            text += f", {left} of the {self.flights_budget} flights left"
        return {"ended_by": why, "ended_because": text, "flights_left": left}

    def step(self) -> None:
        """One ask / evaluate / tell, the candidates offered to the archive."""
        if self.on_phase is not None and self.method.phase != self._phase:
            self._phase = self.method.phase
            self.on_phase(self._phase)
        cands: list[Candidate] = self.method.ask()
        ev = self.evaluate([c.law for c in cands])
        self.flights += ev.flown
        self.method.tell(ev.F, ev.cv)
        self.archive.add_many(cands, ev.F, ev.cv)

    def run(self) -> "RunLoop":
        """Step until a budget is spent (or ``stop_after`` generations: :attr:`interrupted`)."""
        m = self.method
        while not (m.at_boundary() and self.spent()):
            self.step()
            if not m.at_boundary():
                continue
            if self.on_boundary is not None:
                self.on_boundary(self)
            if self.stop_after is not None and m.generation - self._gen0 >= self.stop_after:
                self.interrupted = True
                break
        return self


# -- checkpoints ------------------------------------------------------------------------------------
#: A checkpoint is written at the run's first boundary, at the method's boundaries once its
#: generation or phase has changed and at least CHECKPOINT_MIN_SECONDS have passed since the
#: last one, and at any boundary after CHECKPOINT_MAX_SECONDS (long refinements); a stop loses at
#: most that much work.  (Before: at every boundary -- some 1 600 writes of up to 1.2 MB in a
#: default S1 run, 15 % of its time.)
CHECKPOINT_MIN_SECONDS, CHECKPOINT_MAX_SECONDS = 1.0, 10.0


def _law_state(law) -> dict:
    """A law as a checkpoint keeps it: the matrix by its non-zero entries."""
    d = law.to_dict(formula=False)
    psi = np.asarray(d.pop("psi"))
    d["size"] = int(psi.shape[0])
    d["arcs"] = [[int(i), int(j), int(psi[i, j])] for i, j in zip(*np.nonzero(psi))]
    return d


def _law_from_state(d: dict) -> NetworkOperator:
    d = dict(d)
    psi = np.zeros((d.pop("size"),) * 2, dtype=int)
    for i, j, op in d.pop("arcs"):
        psi[i, j] = op
    return NetworkOperator.from_dict(dict(d, psi=psi))


def archive_state(archive: ParetoArchive, known: dict | None = None) -> list:
    """The archive as a checkpoint keeps it; ``known``: the laws' states of the last call
    (``id(law) -> (law, state)``, the law held so that its id stays its own), updated to the
    archive's laws.  [choice] A checkpoint re-encoded every archived law's matrix (a third of
    its time): a law is never changed once made, so its state is made once."""
    if known is None:
        known = {}
    states = {}
    for c, _, _ in archive.items:
        got = known.get(id(c.law))
        states[id(c.law)] = got if got is not None and got[0] is c.law \
            else (c.law, _law_state(c.law))
    known.clear()
    known.update(states)
    return [{"law": states[id(c.law)][1], "info": dict(c.info), "f": f.tolist(), "cv": cv}
            for c, f, cv in archive.items]


def load_archive(state: list, cap: int = 200) -> ParetoArchive:
    archive = ParetoArchive(cap)
    archive.items = [(Candidate(_law_from_state(a["law"]), a.get("info", {})),
                      np.array(a["f"], float), float(a.get("cv", 0.0))) for a in state]
    return archive


class _Checkpoints:
    """When and what a run saves (see :data:`CHECKPOINT_MIN_SECONDS`)."""

    def __init__(self, folder: RunFolder, evaluator, curve: list):
        self.folder, self.evaluator, self.curve = folder, evaluator, curve
        self.t, self.mark = None, None
        self.written, self.seconds = 0, 0.0
        self.states: dict = {}          # the archived laws' states (archive_state)

    def due(self, loop: RunLoop) -> bool:
        if self.t is None:
            return True
        age = time.monotonic() - self.t
        mark = (loop.method.generation, loop.method.phase)
        return (age >= CHECKPOINT_MIN_SECONDS and mark != self.mark) \
            or age >= CHECKPOINT_MAX_SECONDS

    def save(self, loop: RunLoop) -> None:
        t0 = time.perf_counter()
        self.folder.save({"generation": loop.method.generation,
                          "method": loop.method.state(),
                          "archive": archive_state(loop.archive, self.states),
                          "curve": self.curve,
                          "simulated": loop.flights}, *self.evaluator.take_new())
        self.t, self.mark = time.monotonic(), (loop.method.generation, loop.method.phase)
        self.written += 1
        self.seconds += time.perf_counter() - t0


# -- a synthesis run ------------------------------------------------------------------------------
def _import_ahead(*modules) -> None:
    """Import ``modules`` in a background thread.

    [choice] pycma (with the part of SciPy it loads) took about 2 s of the main process at the
    first CMA-ES search, after the initial population; imported at the run's start it loads
    while this process waits for the workers' first flights.  Started only once the local
    workers are forked (:class:`~synthesis.run.backends.ProcessPool` starts them at once), so
    that no worker inherits a half-imported module's lock.  A failure leaves the import to its
    first use (which then raises as before).  Only for the methods that use CMA-ES."""
    def load():
        for name in modules:
            try:
                importlib.import_module(name)
            except Exception:
                pass
    threading.Thread(target=load, name="descent-fmus-import-ahead", daemon=True).start()


def _announce_path(problem, evaluator, announce) -> None:
    """The path the flights take, and where it is not native although it could be, why."""
    announce(f"flying on the {evaluator.path} path ({evaluator.workers} "
             f"{'worker' if evaluator.workers == 1 else 'workers'})")
    if evaluator.path in ("master", "container") and problem.runner.native is not False:
        from descent_fmus.synthesis.fmi.native_loop import missing_twins
        note = missing_twins(problem.wiring, *evaluator.fmus)
        if note:
            announce(note)


def _curve_point(problem, loop: RunLoop) -> tuple | None:
    """(flights, the target's best objective so far) for the learning curve (the target:
    the problem's, else its first objective)."""
    t = cma_target(problem)
    if not len(loop.archive):
        return None
    k = t.best(loop.archive.F, loop.archive.cv)
    return None if k is None else (loop.flights, float(loop.archive.F[k][t.objective]))


@guarded        # signals, systematic failures, full disks: synthesis/run/guard.py
def run_synthesis(problem: SynthesisProblem, out: Path, fmu_dir: Path,
                  method: str = NETWORK_OPERATOR, workers: int = 1,
                  scheduler: str | None = None, resume: bool = False, progress: bool = True,
                  export=True, stop_after: int | None = None, reference: bool = True) -> dict:
    """Run (or resume) a synthesis of ``problem`` with its recipe; the summary (also written to
    ``out/summary.json``).

    Parameters
    ----------
    problem : SynthesisProblem
        With the recipe of this run (:meth:`~synthesis.problems.contract.SynthesisProblem.tuned`).
    out : path-like
        Run folder (must be empty or absent, or hold this run with ``resume``).
    fmu_dir : path-like
        Folder of the built FMUs.
    method : str
        A method of :func:`method_names` (``network-operator``, ``cma-<structure>``, ...).
    workers, scheduler :
        Local worker processes, or the address of a Dask scheduler.
    export : bool or LawExport
        What to write per Pareto law: True = everything (law files, law FMU, closed-loop FMU and
        SSP), False = nothing, or a :class:`~synthesis.fmi.law_files.LawExport`.
    reference : bool
        Let the problem's report compute an expensive reference (e.g. the reentry bound).
    """
    entry = entry_of(method, problem)
    if entry.needs_flights and problem.budget.flights < 1:
        raise ValueError(f"method {method} needs a flight budget (flights >= 1)")
    check_memory(problem, max(workers, 1))          # before anything is written or allocated
    out = Path(out)
    folder = RunFolder(out)
    st = folder.open(run_spec(problem, method), resume, recipe_defaults(problem)) or {}
    console = Console(problem.name, progress)
    try:
        return _run(problem, out, fmu_dir, method, workers, scheduler, export, stop_after,
                    reference, folder, st, console)
    finally:
        console.close()


def _run(problem, out, fmu_dir, method, workers, scheduler, export, stop_after, reference,
         folder: RunFolder, st: dict, console) -> dict:
    """:func:`run_synthesis` once its folder is open (``st``: the checkpoint resumed)."""
    announce = console.say
    problem, search, scaling, t_scaling = _method(problem, method, fmu_dir, folder, announce)
    archive = load_archive(st["archive"]) if st else ParetoArchive()
    if st:
        search.load_state(st["method"])
    curve, sim0 = list(st.get("curve", [])), st.get("simulated", 0)
    if scheduler:
        announce("starting a Dask LocalCluster" if scheduler == "local"
                 else f"connecting to the Dask scheduler at {scheduler}")
    elif workers > 1:
        announce(f"starting {workers} workers")
    evaluator = Evaluator(problem, fmu_dir, workers=workers, scheduler=scheduler,
                          fail_loudly=True)
    refine = getattr(search, "refine_cfg", None)
    if method.startswith("cma-") or (refine is not None and refine.active):
        _import_ahead("cma")                 # after the workers' fork (see the function)
    _announce_path(problem, evaluator, announce)
    if st:
        evaluator.restore(folder.flown(sim0), folder.behaviour(st.get("behaviour_bytes", 0)),
                          folder.journaled())
    evaluator.journal = folder.journal       # a stop loses only the chunk in flight
    checkpoints = _Checkpoints(folder, evaluator, curve)
    bar = console.bar(problem, f"synthesize {problem.name}" if method == NETWORK_OPERATOR
                      else f"{method} {problem.name}", problem.budget.flights,
                      problem.budget.generations, sim0, search.generation)
    evaluator.on_chunk = bar.advance if bar is not None else None
    t0 = time.perf_counter()
    loop = RunLoop(search, evaluator.evaluate, archive,
                   flights=problem.budget.flights, seconds=problem.budget.seconds,
                   flights_done=sim0, stop_after=stop_after, on_phase=announce,
                   on_boundary=_on_boundary(problem, curve, checkpoints, bar, evaluator, t0))
    try:
        loop.run()
    finally:
        console.end_bar()
    t_search = time.perf_counter() - t0
    checkpoints.save(loop)             # the search is done: a resume goes straight to the report
    evaluator.journal = evaluator.on_chunk = None
    if loop.interrupted:
        evaluator.close()
        return {"interrupted": True, "generation": search.generation,
                "evaluations": search.evaluations}
    timings: dict = {}
    summary = write_results(problem, loop.archive, evaluator, out, fmu_dir, export, reference,
                            announce, timings)
    timings.update(scaling=t_scaling, search=t_search - checkpoints.seconds,
                   checkpoints=checkpoints.seconds)
    summary["timings"] = timings
    summary.update(_run_fields(loop, evaluator, time.perf_counter() - t0, method, out, curve,
                               checkpoints.written))
    if scaling is not None:
        refreshed = getattr(getattr(search, "rescale", None), "refreshes", [])
        summary["input_scaling"] = dict(scaling, refreshed=refreshed)
    evaluator.close()
    write_json(out / "summary.json", summary)
    return summary


def _method(problem, method: str, fmu_dir, folder: RunFolder, announce) -> tuple:
    """``(problem, the method built for it, what auto scaling derived, its seconds)``: with
    ``input_scaling = "auto"`` the problem's basic law in derived coordinates, and the GA's
    refresh of them after the basis refinement."""
    t0 = time.perf_counter()
    scaling = None
    if problem.input_scaling == "auto":
        announce("deriving the input scaling from the basic law's flights")
        problem, scaling = _auto_scaled(problem, fmu_dir, folder)
    search = make_method(method, problem)
    if scaling is not None and hasattr(search, "rescale"):
        from descent_fmus.synthesis.run.scaling import Rescaler
        search.rescale = Rescaler(problem, *problem.fmu_paths(fmu_dir), problem.q_bits[2:])
    return problem, search, scaling, time.perf_counter() - t0


def _auto_scaled(problem, fmu_dir, folder: RunFolder) -> tuple:
    """The problem with its basic law in coordinates derived from its flights (the same each
    time: a resumed run derives them again), its Gray code widened if the rewritten
    parameters need it; what was derived is written to ``scaling.json``."""
    from descent_fmus.synthesis.run.scaling import auto_scaling
    problem, info = auto_scaling(problem, *problem.fmu_paths(fmu_dir))
    q = problem.basic().q
    ib, fb, lo, hi = problem.q_bits
    need = max([abs(v) for v in q] + [1.0])
    if need >= min(-lo, hi):
        # a symmetric range of the next power of two, the same number of bits in all
        k = max(int(np.ceil(np.log2(need))) + 1, 1)
        ib, fb = k + 1, max(ib + fb - (k + 1), 0)
        problem = problem.with_(q_bits=(ib, fb, -float(2 ** k), float(2 ** k)))
        info["q_bits"] = list(problem.q_bits)
    write_json(folder.path / "scaling.json", info)
    return problem, info


def _on_boundary(problem, curve: list, checkpoints: _Checkpoints, bar, evaluator, t0):
    """What the run does at every boundary of its method: the learning curve, a checkpoint
    when one is due, the progress bar."""
    def boundary(loop: RunLoop) -> None:
        point = _curve_point(problem, loop)
        if point is not None:
            curve.append(point)
        if checkpoints.due(loop):
            checkpoints.save(loop)
        if bar is not None:
            bar.update(loop, evaluator.simulated / max(time.perf_counter() - t0, 1e-9))
    return boundary


def _run_fields(loop: RunLoop, evaluator, elapsed: float, method: str, out, curve,
                checkpoints: int) -> dict:
    """The summary's fields about the run itself: counts, rates, failures, the curve."""
    m = loop.method
    return {**loop.end_fields(getattr(m, "generations", None)),
            "method": method, "seconds": elapsed, "simulated": evaluator.simulated,
            "flights": loop.flights, "failures": evaluator.failures,
            "first_failure": evaluator.first_error,
            "evaluations_per_second": evaluator.simulated / max(elapsed, 1e-9),
            "flight_seconds": {"waited": evaluator.fly_seconds,
                               "own": evaluator.flights_cpu / max(evaluator.workers, 1)},
            "flight_path": evaluator.path,
            "out": str(out), "evaluations": m.evaluations, "generations": m.generation,
            "curve": curve, "checkpoints": checkpoints,
            **({"restarts": m.restarts} if hasattr(m, "restarts") else {})}
