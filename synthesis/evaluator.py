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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from synthesis.cosim import ClosedLoop, Wiring
from synthesis.network_operator import NetworkOperator

__all__ = ["SynthesisProblem", "Evaluator", "SchedulerError", "PROBLEMS", "register_problem",
           "get_problem"]


class SchedulerError(ConnectionError):
    """The Dask scheduler cannot be reached."""


@dataclass(frozen=True)
class SynthesisProblem:
    """What the GA synthesises and how a law is judged -- everything the evaluator needs.

    Attributes
    ----------
    name : str
        Registry name (``descent-fmus synthesize NAME``).
    wiring : Wiring
        Plant/controller wiring (also names the two FMU files).
    initial_states : tuple of dict
        Plant start values, one dict per initial state (objectives summed over them).
    objectives : callable
        ``objectives(finals) -> (f, extras)``: ``finals`` the list of plant final-output dicts,
        ``f`` the objective tuple, ``extras`` a dict of reported values (JSON-able).
    objective_names : tuple of str
    penalty : tuple of float
        Objectives of a failed evaluation.
    basic_law : callable
        ``basic_law() -> NetworkOperator``, the GA's first basic solution.
    unary, binary : tuple of int
        Operations the variations may use.
    q_bits : tuple
        (int_bits, frac_bits, lo, hi) of the Gray coding of the parameters.
    """

    name: str
    wiring: Wiring
    initial_states: tuple
    objectives: object
    objective_names: tuple
    penalty: tuple
    basic_law: object
    unary: tuple = (1, 3, 4, 5, 8, 9, 10, 14, 15)
    binary: tuple = (1, 2)
    q_bits: tuple = (4, 12, 0.0, 16.0)
    description: str = ""
    defaults: dict = field(default_factory=dict)

    @property
    def plant_fmu(self) -> str:
        return f"{self.wiring.plant}.fmu"

    @property
    def controller_fmu(self) -> str:
        return f"{self.wiring.controller}.fmu"


#: Registered synthesis problems by name (filled by synthesis.scenarios modules).
PROBLEMS: dict[str, SynthesisProblem] = {}


def register_problem(problem: SynthesisProblem) -> None:
    PROBLEMS[problem.name] = problem


def get_problem(name: str) -> SynthesisProblem:
    from synthesis import scenarios
    scenarios.load_all()
    try:
        return PROBLEMS[name]
    except KeyError:
        raise KeyError(f"unknown synthesis problem {name!r}; known: "
                       f"{', '.join(sorted(PROBLEMS)) or 'none'}") from None


# -- one evaluation (runs wherever the FMUs are loaded) ------------------------------------------
def _payload(law: NetworkOperator):
    return (law.psi.tolist(), law.nx, list(law.q), list(law.outputs),
            [list(b) for b in law.bounds])


def _law(payload) -> NetworkOperator:
    psi, nx, q, outs, bounds = payload
    return NetworkOperator(np.array(psi), nx, q, outs, bounds)


def evaluate_on(loop: ClosedLoop, problem: SynthesisProblem, payload):
    """Fly one law over every initial state; ``(f, extras)`` or raise on an FMU failure."""
    sv = _law(payload).start_values()
    finals = [loop.run(plant_values=s, controller_values=sv).final
              for s in problem.initial_states]
    f, extras = problem.objectives(finals)
    f = tuple(float(v) for v in f)
    if not all(math.isfinite(v) for v in f):
        return tuple(problem.penalty), dict(extras, failed="non-finite objectives")
    return f, extras


# worker-process state: one closed loop per (problem, fmu_dir), loaded once
_LOOPS: dict = {}


def _worker_loop(problem_name: str, fmu_dir: str):
    key = (problem_name, fmu_dir)
    if key not in _LOOPS:
        problem = get_problem(problem_name)
        d = Path(fmu_dir)
        _LOOPS[key] = (problem, ClosedLoop(problem.wiring, d / problem.plant_fmu,
                                           d / problem.controller_fmu))
    return _LOOPS[key]


def evaluate_chunk(problem_name: str, fmu_dir: str, payloads):
    """Evaluate payloads in this process; a failure is reported per candidate as None."""
    problem, loop = _worker_loop(problem_name, fmu_dir)
    out = []
    for p in payloads:
        try:
            out.append(evaluate_on(loop, problem, p))
        except Exception as exc:  # an FMU error costs this candidate only
            out.append((None, {"error": f"{type(exc).__name__}: {exc}"}))
    return out


def _init_worker(problem_name, fmu_dir):
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    _worker_loop(problem_name, fmu_dir)


class Evaluator:
    """Objective vectors of candidate laws, through the FMUs.

    Parameters
    ----------
    problem : SynthesisProblem or str
    fmu_dir : path-like
        Folder holding the plant and controller FMUs.
    workers : int
        1 = in this process; >1 = a local process pool of that size.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:port``); overrides ``workers``.
    """

    def __init__(self, problem, fmu_dir, workers: int = 1, scheduler: str | None = None,
                 connect_timeout: float = 10.0):
        self.problem = get_problem(problem) if isinstance(problem, str) else problem
        self.fmu_dir = str(Path(fmu_dir).resolve())
        for f in (self.problem.plant_fmu, self.problem.controller_fmu):
            if not (Path(self.fmu_dir) / f).is_file():
                from synthesis.cosim import FMUNotFoundError
                raise FMUNotFoundError(f"FMU not found: {Path(self.fmu_dir) / f} -- build the "
                                       f"FMUs first with 'python build_fmus.py'")
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
                                   initargs=(self.problem.name, self.fmu_dir))

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
        """Results (f or None, extras) for payloads on the configured backend."""
        if not payloads:
            return []
        if self._client is not None:
            chunks = self._chunks(payloads, 4 * max(1, len(self._client.nthreads())))
            futures = self._client.map(evaluate_chunk, [self.problem.name] * len(chunks),
                                       [self.fmu_dir] * len(chunks), chunks, pure=False)
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
                futures = [self._pool.submit(evaluate_chunk, self.problem.name, self.fmu_dir, c)
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
        return evaluate_chunk(self.problem.name, self.fmu_dir, payloads)

    # -- public ---------------------------------------------------------------------------
    @staticmethod
    def key(law: NetworkOperator):
        return (law.psi.tobytes(), law.psi.shape[0], tuple(law.q), tuple(law.outputs))

    def evaluate(self, laws) -> tuple[np.ndarray, list]:
        """Objective matrix (one row per law) and the list of extras dicts."""
        keys = [self.key(law) for law in laws]
        todo, seen = [], set()
        for k, law in zip(keys, laws):
            if k not in self.cache and k not in seen:
                seen.add(k)
                todo.append((k, law))
        if todo:
            results = self._run_batch([_payload(law) for _, law in todo])
            retry = [i for i, (f, _) in enumerate(results) if f is None]
            if retry:   # retried once (a dead worker or a transient FMU error) ...
                again = self._run_batch([_payload(todo[i][1]) for i in retry])
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
