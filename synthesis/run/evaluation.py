"""Closed-loop evaluation of network-operator laws through the FMUs only.

A candidate law becomes start values of the generic ``NetworkOperatorController`` FMU; the plant
FMU and the controller FMU fly in closed loop (synthesis.fmi.closed_loop) once per initial state of the
problem; the problem's objective function turns the plants' final outputs into the objective
vector.  The evaluator knows nothing of the plant's Python: it is built from FMU paths and a
:class:`SynthesisProblem` (wiring, start values, objective function).

Backends: in-process (``workers=1``), a local process pool (each worker loads its FMUs once),
or a Dask distributed cluster (``scheduler="tcp://host:port"``, or ``"local"`` for a Dask
LocalCluster of ``workers`` processes).  The Dask workers need only the installed package: the
FMU files travel to them as bytes, once per run (:mod:`synthesis.run.cluster`).

Identical candidates are not simulated twice (cache).  A failing candidate (an FMU error, a
worker that dies) is retried once, then given the problem's penalty -- never a crash, never a
NaN.  A failure that hits a whole batch is no candidate's fault (a broken FMU, a wrong wiring,
workers that cannot load the FMUs): with ``fail_loudly`` the evaluator raises
:class:`SystematicFailure` with the first error instead of penalising (see :meth:`evaluate`).

Local pool workers exit within seconds of the parent's death, whatever ends it
(:func:`synthesis.run.signals.watch_parent`); the waits of the parent honour a requested stop
(:func:`synthesis.run.signals.check_stop`).
"""
from __future__ import annotations

import math
import os
import shutil
import time
import weakref
from concurrent.futures import FIRST_EXCEPTION, ProcessPoolExecutor
from concurrent.futures import wait as wait_futures
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.run.signals import check_stop, watch_parent
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.paths import require_fmu
from descent_fmus.synthesis.problems.contract import SynthesisProblem

__all__ = ["Evaluator", "SchedulerError", "SystematicFailure", "evaluate_on", "chunk_size",
           "TASK_OVERHEAD", "TASK_DISPATCH"]


class SchedulerError(ConnectionError):
    """The Dask scheduler cannot be reached (or has no workers)."""


class SystematicFailure(RuntimeError):
    """(Nearly) every candidate of a batch failed: the setup is broken, not the candidates."""

    def __init__(self, failed: int, total: int, first_error: str):
        super().__init__(f"{failed} of {total} evaluations failed -- a broken setup, not bad "
                         f"candidates; the first error: {first_error}")
        self.failed, self.total, self.first_error = failed, total, first_error


#: Scheduling cost per task [s] of each backend (dispatch, argument transfer, result return:
#: the wall time of a task that does no work, one worker) and the Dask scheduler's dispatch
#: time per task (no-op tasks on several workers), measured by ``python benchmarks/cluster.py``;
#: with the measured cost of a flight they choose the chunk size (:func:`chunk_size`).  Values of
#: a shared, loaded 2-core machine (the upper end: larger chunks are the safe side).
TASK_OVERHEAD = {"pool": 0.0037, "dask": 0.0094}
TASK_DISPATCH = {"pool": 0.0, "dask": 0.009}
#: Cost of one law's flights [s] assumed until the first batch has measured it.
FIRST_GUESS_FLIGHT = 0.02


def chunk_size(n: int, workers: int, flight: float, overhead: float,
               dispatch: float = 0.0) -> int:
    """Laws per task for ``n`` laws on ``workers`` workers.

    A batch takes about ``n c / W`` (work) ``+ (n / k) o / W`` (one overhead ``o`` per task of
    ``k`` laws) ``+ k c / 2`` (the last tasks finish unevenly); the sum is smallest at
    ``k = sqrt(2 n o / (W c))``.  A scheduler that needs ``dispatch`` seconds per task keeps
    ``W`` workers busy only if ``k >= W dispatch / c``.  Clipped to ``1 .. ceil(n / W)``.
    """
    if n <= 0:
        return 1
    w = max(1, workers)
    c = max(flight, 1e-6)
    k = max(math.sqrt(2.0 * n * overhead / (w * c)), w * dispatch / c)
    return int(min(max(1, round(k)), math.ceil(n / w)))


# -- one evaluation (runs wherever the FMUs are loaded) ------------------------------------------
def evaluate_on(loop: ClosedLoop, problem: SynthesisProblem, law):
    """Fly one law over every initial state; ``(f, extras)`` or raise on an FMU failure.

    A problem with a ``runner`` (:mod:`synthesis.fmi.container_loop`) chooses its flights itself (racing).
    """
    if problem.runner is not None:
        results = problem.runner.flights(loop, problem, law)
    else:
        sv = law.start_values()
        record = bool(problem.record)
        results = [loop.run(plant_values=s, controller_values=sv, record=record)
                   for s in problem.initial_states]
    f, extras = problem.evaluate_flights(results)
    if not all(math.isfinite(v) for v in f):
        return tuple(problem.penalty), dict(extras, failed="non-finite objectives")
    return f, extras


# worker-process state: one closed loop per (problem, FMU files), loaded once
_LOOPS: dict = {}


def _worker_loop(problem: SynthesisProblem, plant: str, controller: str):
    key = (problem.name, problem.source, plant, controller)
    if key not in _LOOPS:
        if not _LOOPS:         # the process's FMUs are freed, their folders removed, at exit
            import atexit
            atexit.register(_free_loops)
        # a problem's runner may choose the closed-loop container FMU (synthesis.fmi.container_loop)
        load = problem.runner.load if problem.runner is not None else ClosedLoop
        _LOOPS[key] = load(problem.wiring, plant, controller, record=problem.record)
    return _LOOPS[key]


def _free_loops() -> None:
    """At interpreter exit: free the FMU instances while Python is still whole (a pythonfmu
    instance holds Python objects; left to the interpreter's teardown they are released in no
    defined order), then remove their folders."""
    for loop in list(_LOOPS.values()):
        try:
            loop.close()
        except Exception:       # an FMU that cannot be freed: its folder still goes
            pass
    remove_extracted()
    _LOOPS.clear()


def remove_extracted() -> None:
    """Delete the folders the loaded FMUs were extracted to (files only: no FMU call)."""
    for loop in _LOOPS.values():
        for comp in (loop.plant, loop.ctrl):
            shutil.rmtree(comp.fmu._descent_unzipdir, ignore_errors=True)


def evaluate_chunk(problem: SynthesisProblem, plant: str, controller: str, laws):
    """Evaluate laws in this process; a failure is reported per candidate as ``(None, ...)``.

    In the process that runs the synthesis (``workers=1``) a requested stop ends the chunk
    between two candidates (:func:`synthesis.run.signals.check_stop`).
    """
    try:
        loop = _worker_loop(problem, plant, controller)
    except Exception as exc:   # FMUs that do not load: every candidate fails with that error
        return [(None, {"error": f"{type(exc).__name__}: {exc}"})] * len(laws)
    out = []
    for law in laws:
        check_stop()
        try:
            out.append(evaluate_on(loop, problem, law))
        except Exception as exc:  # an FMU error costs this candidate only
            out.append((None, {"error": f"{type(exc).__name__}: {exc}"}))
    return out


def evaluate_shipped(problem, plant_ref, controller_ref, laws):
    """Dask task: evaluate ``laws`` with the FMUs shipped to this worker
    (:class:`synthesis.run.cluster.FmuShipment`); per-candidate failures are results.

    Returns ``(results, seconds)``: the per-law results and the compute time of the chunk on the
    worker (the evaluator's measure of the per-flight cost).
    """
    from descent_fmus.synthesis.run.cluster import shipped_path
    t0 = time.perf_counter()
    out = evaluate_chunk(problem, str(shipped_path(plant_ref)), str(shipped_path(controller_ref)),
                         laws)
    return out, time.perf_counter() - t0


def _timed_chunk(problem, plant, controller, laws):
    t0 = time.perf_counter()
    out = evaluate_chunk(problem, plant, controller, laws)
    return out, time.perf_counter() - t0


def _init_worker(problem, plant, controller, parent_pid):
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import multiprocessing.util
    watch_parent(parent_pid, cleanup=remove_extracted)
    multiprocessing.util.Finalize(None, remove_extracted, exitpriority=10)
    try:
        _worker_loop(problem, plant, controller)
    except Exception:
        pass           # evaluate_chunk reports the error for every candidate


class Evaluator:
    """Objective vectors of candidate laws, through the FMUs.

    Parameters
    ----------
    problem : SynthesisProblem
    fmu_dir : path-like
        Folder holding the FMUs the problem names (files given by absolute path in the problem
        are used as they are).
    workers : int
        1 = in this process; >1 = a local process pool of that size (also the size of the
        LocalCluster of ``scheduler="local"``).
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:port``), or ``"local"``; overrides the pool.
        The FMU files are read here, when the evaluator is created, and shipped to the workers.
    fail_loudly : bool
        Raise :class:`SystematicFailure` when more than half of the first judged batch fails,
        or every candidate of a later one (batches of at least :attr:`JUDGED_BATCH` new
        candidates; smaller ones are penalised as usual).  A synthesis run sets it.
    """

    #: Smallest batch of new candidates whose failures are judged systematic.
    JUDGED_BATCH = 4
    _open = weakref.WeakSet()

    @classmethod
    def open_evaluators(cls) -> list:
        """Evaluators not closed yet (a run stops their workers when it ends early)."""
        return list(cls._open)

    def __init__(self, problem, fmu_dir, workers: int = 1, scheduler: str | None = None,
                 connect_timeout: float = 10.0, fail_loudly: bool = False):
        self.problem = problem
        self.fmu_dir = str(Path(fmu_dir).resolve())
        self.fmus = tuple(str(require_fmu(f).resolve()) for f in problem.fmu_paths(fmu_dir))
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.workers = workers
        self.scheduler = scheduler
        self.cache: dict = {}
        self.simulated = 0
        self.failures = 0
        self.first_error: str | None = None
        self.flight_seconds = FIRST_GUESS_FLIGHT     # measured compute time per law [s]
        self.fail_loudly = fail_loudly
        self._judged = 0
        self._pool = None
        self._client = None
        self._cluster = None
        self._refs = None
        self._plugin = None
        Evaluator._open.add(self)
        if scheduler:
            from descent_fmus.synthesis.run.cluster import FmuFile, FmuShipment
            files = [FmuFile.read(f) for f in self.fmus]
            self._refs = tuple(f.ref for f in files)
            self._connect(scheduler, connect_timeout)
            self._plugin = FmuShipment(files)
            try:
                self._client.register_plugin(self._plugin)
            except BaseException:
                self.close()
                raise
        elif workers > 1:
            self._pool = self._new_pool()

    # -- backends -------------------------------------------------------------------------
    def _connect(self, address, timeout):
        try:
            from distributed import Client
        except ImportError:
            raise SchedulerError("the Dask backend needs 'distributed': pip install "
                                 "'dask[distributed]'") from None
        if address == "local":
            from descent_fmus.synthesis.run.cluster import start_local_cluster
            self._cluster, self._client = start_local_cluster(self.workers)
            return
        try:
            self._client = Client(address, timeout=f"{timeout}s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise SchedulerError(f"cannot reach the Dask scheduler at {address}: {exc}") \
                from None

    def _new_pool(self):
        return ProcessPoolExecutor(max_workers=self.workers, initializer=_init_worker,
                                   initargs=(self.problem,) + self.fmus + (os.getpid(),))

    def _stop_pool(self, wait: bool) -> None:
        """Shut the pool down; without ``wait`` its processes are terminated and reaped now."""
        pool, self._pool = self._pool, None
        if pool is None:
            return
        procs = list((pool._processes or {}).values())
        if wait:
            pool.shutdown(wait=True, cancel_futures=True)
            return
        for p in procs:              # SIGTERM: a worker removes its extracted FMUs and exits
            try:
                p.terminate()
            except (OSError, ValueError):
                pass
        deadline = time.monotonic() + 5.0
        for p in procs:
            try:
                p.join(max(0.0, deadline - time.monotonic()))
                if p.is_alive():
                    p.kill()
                    p.join(1.0)
            except (OSError, ValueError, AssertionError):
                pass
        pool.shutdown(wait=False, cancel_futures=True)

    def close(self, wait: bool = True) -> None:
        """Release the backend.  ``wait=False`` (a stop on a signal, an error): local workers
        are terminated at once instead of finishing their tasks."""
        self._stop_pool(wait)
        client, self._client = self._client, None
        if client is not None:
            try:
                if self._plugin is not None and self._cluster is None:
                    client.unregister_worker_plugin(self._plugin.name)
            except Exception:
                pass
            client.close()
        cluster, self._cluster = self._cluster, None
        if cluster is not None:
            cluster.close()
        Evaluator._open.discard(self)

    @property
    def client(self):
        """The Dask client of the Dask backend (None otherwise)."""
        return self._client

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        self.close(wait=exc_type is None)

    def _chunks(self, items, workers, backend):
        k = chunk_size(len(items), workers, self.flight_seconds, TASK_OVERHEAD[backend],
                       TASK_DISPATCH[backend])
        return [items[i:i + k] for i in range(0, len(items), k)]

    def _measured(self, chunks, timings) -> None:
        n = sum(len(c) for c, t in zip(chunks, timings) if t is not None)
        if n:
            self.flight_seconds = sum(t for t in timings if t is not None) / n

    def _dask_batch(self, payloads) -> list:
        client = self._client
        if not client.nthreads():
            try:
                client.wait_for_workers(1, timeout=60)
            except TimeoutError:
                raise SchedulerError(f"the Dask cluster at {client.scheduler.address} has no "
                                     f"workers (waited 60 s)") from None
        chunks = self._chunks(payloads, len(client.nthreads()), "dask")
        n = len(chunks)
        futures = client.map(evaluate_shipped, [self.problem] * n, [self._refs[0]] * n,
                             [self._refs[1]] * n, chunks, pure=False)
        try:
            while not all(f.done() for f in futures):
                check_stop()
                time.sleep(0.01)
            return self._collect(futures, chunks)
        finally:
            client.cancel([f for f in futures if not f.done()])

    def _collect(self, futures, chunks, fatal=()) -> list:
        """Per-law results of finished chunk tasks; a failed task (a worker that died, a
        KilledWorker) fails its laws, except the ``fatal`` exceptions, which propagate."""
        out, timings = [], []
        for fut, chunk in zip(futures, chunks):
            try:
                res, seconds = fut.result()
                out.extend(res)
                timings.append(seconds)
            except fatal:
                raise
            except Exception as exc:
                out.extend([(None, {"error": f"{type(exc).__name__}: {exc}"})] * len(chunk))
                timings.append(None)
        self._measured(chunks, timings)
        return out

    def _pool_batch(self, payloads) -> list:
        chunks = self._chunks(payloads, self.workers, "pool")
        try:
            futures = [self._pool.submit(_timed_chunk, self.problem, *self.fmus, c)
                       for c in chunks]
            pending = set(futures)
            while pending:
                _, pending = wait_futures(pending, timeout=0.25, return_when=FIRST_EXCEPTION)
                check_stop()
                if any(f.done() and isinstance(f.exception(), BrokenProcessPool)
                       for f in futures):
                    break
            return self._collect(futures, chunks, fatal=BrokenProcessPool)
        except BrokenProcessPool as exc:
            # a worker died: start a fresh pool; the batch's candidates are retried
            self._stop_pool(wait=False)
            self._pool = self._new_pool()
            return [(None, {"error": f"worker died: {exc}"})] * len(payloads)

    def _run_batch(self, payloads) -> list:
        """Results (f or None, extras) for laws on the configured backend."""
        if not payloads:
            return []
        if self._client is not None:
            return self._dask_batch(payloads)
        if self._pool is not None:
            return self._pool_batch(payloads)
        return evaluate_chunk(self.problem, *self.fmus, payloads)

    # -- public ---------------------------------------------------------------------------
    @staticmethod
    def key(law: NetworkOperator):
        return (law.psi.tobytes(), law.psi.shape[0], tuple(law.q), tuple(law.outputs),
                tuple(map(tuple, law.bounds)), tuple(law.input_scale), tuple(law.input_offset))

    def evaluate(self, laws) -> tuple[np.ndarray, list]:
        """Objective matrix (one row per law) and the list of extras dicts.

        A failed candidate gets the problem's penalty (``extras["failed"]``, counted in
        :attr:`failures`); with :attr:`fail_loudly` a systematic failure raises
        :class:`SystematicFailure` instead (nothing of that batch is cached or counted).
        """
        check_stop()
        keys = [self.key(law) for law in laws]
        todo, seen = [], set()
        for k, law in zip(keys, laws):
            if k not in self.cache and k not in seen:
                seen.add(k)
                todo.append((k, law))
        if todo:
            results = self._run_batch([law for _, law in todo])
            retry = [i for i, (f, _) in enumerate(results) if f is None]
            if retry:   # retried once (a dead worker or a transient FMU error) ...
                again = self._run_batch([todo[i][1] for i in retry])
                for i, r in zip(retry, again):
                    results[i] = r
            failed = [extras for f, extras in results if f is None]
            if self.fail_loudly and len(todo) >= self.JUDGED_BATCH:
                limit = 0.5 if self._judged == 0 else 1.0
                self._judged += 1
                if failed and (len(failed) == len(todo) or len(failed) > limit * len(todo)):
                    raise SystematicFailure(len(failed), len(todo),
                                            failed[0].get("error", "unknown error"))
            for (k, _), (f, extras) in zip(todo, results):
                if f is None:   # ... then penalised
                    self.failures += 1
                    if self.first_error is None:
                        self.first_error = extras.get("error")
                    f = tuple(self.problem.penalty)
                    extras = dict(extras, failed=True)
                self.cache[k] = (f, extras)
            self.simulated += len(todo)
        F = np.array([self.cache[k][0] for k in keys], float).reshape(
            len(laws), len(self.problem.objective_names))
        return F, [self.cache[k][1] for k in keys]
