"""Closed-loop evaluation of network-operator laws through the FMUs only.

A candidate law becomes start values of the generic ``NetworkOperatorController`` FMU; the plant
FMU and the controller FMU fly in closed loop (synthesis.cosim) once per initial state of the
problem; the problem's objective function turns the plants' final outputs into the objective
vector.  The evaluator knows nothing of the plant's Python: it is built from FMU paths and a
:class:`SynthesisProblem` (wiring, start values, objective function).

Backends: in-process (``workers=1``), a local process pool (each worker loads its FMUs once),
or a Dask distributed cluster (``scheduler="tcp://host:port"``).  Identical candidates are not
simulated twice (cache).  A failing candidate (an FMU error, a worker that dies) is retried once,
then given the problem's penalty -- never a crash, never a NaN.
"""
from __future__ import annotations

import math
import os
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from pathlib import Path

import numpy as np

from descent_fmus.synthesis.cosim import ClosedLoop
from descent_fmus.synthesis.paths import require_fmu
from descent_fmus.synthesis.methods.network_operator import NetworkOperator
from descent_fmus.synthesis.problem import SynthesisProblem

__all__ = ["Evaluator", "SchedulerError", "evaluate_on"]


class SchedulerError(ConnectionError):
    """The Dask scheduler cannot be reached."""


# -- one evaluation (runs wherever the FMUs are loaded) ------------------------------------------
def evaluate_on(loop: ClosedLoop, problem: SynthesisProblem, law):
    """Fly one law over every initial state; ``(f, extras)`` or raise on an FMU failure."""
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
        _LOOPS[key] = ClosedLoop(problem.wiring, plant, controller, record=problem.record)
    return _LOOPS[key]


def evaluate_chunk(problem: SynthesisProblem, plant: str, controller: str, laws):
    """Evaluate laws in this process; a failure is reported per candidate as ``(None, ...)``."""
    loop = _worker_loop(problem, plant, controller)
    out = []
    for law in laws:
        try:
            out.append(evaluate_on(loop, problem, law))
        except Exception as exc:  # an FMU error costs this candidate only
            out.append((None, {"error": f"{type(exc).__name__}: {exc}"}))
    return out


def _init_worker(problem, plant, controller):
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    _worker_loop(problem, plant, controller)


class Evaluator:
    """Objective vectors of candidate laws, through the FMUs.

    Parameters
    ----------
    problem : SynthesisProblem
    fmu_dir : path-like
        Folder holding the FMUs the problem names (files given by absolute path in the problem
        are used as they are).
    workers : int
        1 = in this process; >1 = a local process pool of that size.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:port``); overrides ``workers``.
    """

    def __init__(self, problem, fmu_dir, workers: int = 1, scheduler: str | None = None,
                 connect_timeout: float = 10.0):
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
        self._pool = None
        self._client = None
        if scheduler:
            self._client = self._connect(scheduler, connect_timeout)
        elif workers > 1:
            self._pool = self._new_pool()

    # -- backends -------------------------------------------------------------------------
    def _connect(self, address, timeout):
        try:
            from distributed import Client
        except ImportError:
            raise SchedulerError("the Dask backend needs 'distributed': pip install "
                                 "'dask[distributed]'") from None
        try:
            return Client(address, timeout=f"{timeout}s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise SchedulerError(f"cannot reach the Dask scheduler at {address}: {exc}") \
                from None

    def _new_pool(self):
        return ProcessPoolExecutor(max_workers=self.workers, initializer=_init_worker,
                                   initargs=(self.problem,) + self.fmus)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None
        if self._client is not None:
            self._client.close()
            self._client = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _chunks(self, items, n):
        k = max(1, math.ceil(len(items) / n))
        return [items[i:i + k] for i in range(0, len(items), k)]

    def _run_batch(self, payloads) -> list:
        """Results (f or None, extras) for laws on the configured backend."""
        if not payloads:
            return []
        if self._client is not None:
            chunks = self._chunks(payloads, 4 * max(1, len(self._client.nthreads())))
            n = len(chunks)
            futures = self._client.map(evaluate_chunk, [self.problem] * n,
                                       [self.fmus[0]] * n, [self.fmus[1]] * n, chunks,
                                       pure=False)
            out = []
            for fut, chunk in zip(futures, chunks):
                try:
                    out.extend(fut.result())
                except Exception as exc:  # a worker died (KilledWorker) or similar
                    out.extend([(None, {"error": f"{type(exc).__name__}: {exc}"})] * len(chunk))
            return out
        if self._pool is not None:
            chunks = self._chunks(payloads, 4 * self.workers)
            try:
                futures = [self._pool.submit(evaluate_chunk, self.problem, *self.fmus, c)
                           for c in chunks]
                out = []
                for fut, chunk in zip(futures, chunks):
                    try:
                        out.extend(fut.result())
                    except BrokenProcessPool:
                        raise
                    except Exception as exc:
                        out.extend([(None, {"error": str(exc)})] * len(chunk))
                return out
            except BrokenProcessPool as exc:
                # a worker died: start a fresh pool; the batch's candidates are retried
                self._pool.shutdown(cancel_futures=True)
                self._pool = self._new_pool()
                return [(None, {"error": f"worker died: {exc}"})] * len(payloads)
        return evaluate_chunk(self.problem, *self.fmus, payloads)

    # -- public ---------------------------------------------------------------------------
    @staticmethod
    def key(law: NetworkOperator):
        return (law.psi.tobytes(), law.psi.shape[0], tuple(law.q), tuple(law.outputs),
                tuple(map(tuple, law.bounds)), tuple(law.input_scale), tuple(law.input_offset))

    def evaluate(self, laws) -> tuple[np.ndarray, list]:
        """Objective matrix (one row per law) and the list of extras dicts."""
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
            for (k, _), (f, extras) in zip(todo, results):
                if f is None:   # ... then penalised
                    self.failures += 1
                    f = tuple(self.problem.penalty)
                    extras = dict(extras, failed=True)
                self.cache[k] = (f, extras)
            self.simulated += len(todo)
        F = np.array([self.cache[k][0] for k in keys], float).reshape(len(laws), -1)
        return F, [self.cache[k][1] for k in keys]
