"""Closed-loop evaluation of candidate laws through the FMUs only: the evaluation rules.

A candidate law becomes start values of the generic ``NetworkOperatorController`` FMU; the plant
FMU and the controller FMU fly in closed loop once per initial state of the problem; the problem
turns the flights into objectives and a constraint violation
(:meth:`~synthesis.problems.contract.SynthesisProblem.evaluate`).  The evaluator knows nothing of
the plant's Python: it is built from FMU paths and a problem.  Where the laws fly is a backend's
business (:mod:`synthesis.run.backends`: in-process, local processes, Dask); the rules are here:

* identical candidates are not flown twice (a cache of the last :data:`CACHE_SIZE` laws' outcomes;
  with ``equivalence_probes`` > 0 (the recipe's GA setting) a law whose unclipped outputs equal
  those of a law flown before on that many fixed input points -- the same function written
  differently, as the GA's variations often make -- takes that law's outcome without a flight,
  as machine-learning-control toolboxes do;
  a law flown before is never counted as a new flight again, so a flight budget counts distinct
  laws, and a resumed run, which starts with an empty cache, counts and judges exactly as an
  uninterrupted one: the fingerprints of the flown laws and the outcomes by behaviour are part
  of the run's checkpoint);
* a failing candidate (an FMU error, a worker that dies) is retried once, then given the
  problem's penalty -- never a crash, never a NaN;
* with a :attr:`~Evaluator.journal` (a synthesis run's folder) a batch of new laws is flown in
  chunks of about :data:`CHUNK_SECONDS`, each chunk's outcomes handed to the journal as they
  come: a run stopped in the middle of a long batch (a CMA-ES generation of thousands of laws
  after IPOP restarts, six basis searches at once) loses only the chunk in flight, and its
  resume takes the journaled outcomes (:meth:`~Evaluator.restore`) instead of flying those
  laws again -- counted, cached and judged exactly as the flights they stand for;
* a failure that hits a whole batch is no candidate's fault (a broken FMU, a wrong wiring,
  workers that cannot load the FMUs): with ``fail_loudly`` the evaluator raises
  :class:`SystematicFailure` with the first error instead of penalising.
"""
from __future__ import annotations

import hashlib
import struct
import time
import weakref
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.paths import require_fmu
from descent_fmus.synthesis.problems.contract import SynthesisProblem
from descent_fmus.synthesis.run.backends import (Backend, SchedulerError, chunk_size,
                                                 flight_path, make_backend)
from descent_fmus.synthesis.run.probes import native_prober
from descent_fmus.synthesis.run.signals import check_stop

__all__ = ["Evaluator", "Evaluation", "SchedulerError", "SystematicFailure", "chunk_size",
           "law_key", "CACHE_SIZE"]

#: Outcomes kept in the evaluator's cache (the most recently used; a few hundred bytes each).
CACHE_SIZE = 100_000
#: [choice] With a journal, a batch is flown in chunks of about this many seconds (at the rate
#: measured on the batches before): what a stop loses, against a wait for the slowest worker
#: per chunk (negligible at seconds per chunk).
CHUNK_SECONDS = 2.0


class SystematicFailure(RuntimeError):
    """(Nearly) every candidate of a batch failed: the setup is broken, not the candidates."""

    def __init__(self, failed: int, total: int, first_error: str):
        super().__init__(f"{failed} of {total} evaluations failed -- a broken setup, not bad "
                         f"candidates; the first error: {first_error}")
        self.failed, self.total, self.first_error = failed, total, first_error


@dataclass
class Evaluation:
    """Objective rows ``F`` (n x m), total constraint violations ``cv`` (n,), reported values
    per law, and how many laws of the batch were flown for the first time in the run."""

    F: np.ndarray
    cv: np.ndarray
    extras: list
    flown: int


#: [choice] The fingerprint's hash state after the matrix, per matrix (its bytes): hashing a
#: 32 x 32 matrix (8 kB) was most of a fingerprint's cost, and a CMA-ES generation's laws share
#: their matrix; the state is copied, so the digest is the one hashed from scratch.
KEY_PREFIXES = 4096
_PREFIXES: dict = {}


def _matrix_hash(psi: np.ndarray):
    """The fingerprint's hash object after the matrix's shape and entries (a copy)."""
    key = (psi.shape, psi.dtype.str, psi.tobytes())
    h = _PREFIXES.get(key)
    if h is None:
        h = hashlib.blake2b(digest_size=16)
        h.update(struct.pack("<2q", *psi.shape))
        h.update(psi.astype("<i8").tobytes())
        if len(_PREFIXES) >= KEY_PREFIXES:
            _PREFIXES.clear()
        _PREFIXES[key] = h
    return h.copy()


def law_key(law) -> bytes:
    """A 16-byte fingerprint of what makes two laws the same candidate (their flights are
    identical): the matrix, the parameters, the outputs and bounds, the input scaling."""
    psi = law.psi
    h = _matrix_hash(psi) if isinstance(psi, np.ndarray) else _matrix_hash(np.asarray(psi))
    for part in (law.q, law.outputs, [v for b in law.bounds for v in b], law.input_scale,
                 law.input_offset):
        h.update(struct.pack(f"<q{len(part)}d", len(part), *map(float, part)))
    return h.digest()


def _probes(problem):
    """The fixed input points of the equivalence test (None: off)."""
    n = getattr(problem.ga, "equivalence_probes", 0)
    if not n:
        return None
    from descent_fmus.synthesis.methods.structures import probe_inputs
    basic = problem.basic()       # half where the inputs' scaling says the law acts, half wider
    return np.vstack([probe_inputs(basic, n - n // 2, seed=12345),
                      probe_inputs(basic, n // 2, seed=54321, spread=4.0)])


def _behaviour_key(law, points, prober=None) -> bytes | None:
    """The law's unclipped outputs on ``points``, to 12 significant digits, hashed (None when
    the law cannot be evaluated here: the FMU will say why); ``prober``: the native route
    (:mod:`synthesis.run.probes`, the same values)."""
    values = prober.values(law, points) if prober is not None else None
    if values is None:
        try:
            values = [v for row in law.raw_points(points) for v in row]
        except Exception:
            return None
    # one format call for all values: the text of ",".join(f"{v:.12g}" for v in values)
    text = ("%.12g," * len(values) % tuple(values))[:-1]
    return hashlib.blake2b(text.encode(), digest_size=16).digest()


class Evaluator:
    """Objective rows of candidate laws, through the FMUs (see the module docstring).

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
    fail_loudly : bool
        Raise :class:`SystematicFailure` when more than half of the first judged batch fails,
        or every candidate of a later one (batches of at least :attr:`JUDGED_BATCH` new
        candidates; smaller ones are penalised as usual).  A synthesis run sets it.
    backend : Backend, optional
        A backend built elsewhere (then ``workers`` and ``scheduler`` are not used).
    """

    #: Smallest batch of new candidates whose failures are judged systematic.
    JUDGED_BATCH = 4
    _open = weakref.WeakSet()

    @classmethod
    def open_evaluators(cls) -> list:
        """Evaluators not closed yet (a run stops their workers when it ends early)."""
        return list(cls._open)

    def __init__(self, problem: SynthesisProblem, fmu_dir, workers: int = 1,
                 scheduler: str | None = None, connect_timeout: float = 10.0,
                 fail_loudly: bool = False, backend: Backend | None = None):
        self.problem = problem
        self.fmu_dir = str(Path(fmu_dir).resolve())
        self.fmus = tuple(str(require_fmu(f).resolve()) for f in problem.fmu_paths(fmu_dir))
        self.backend = backend or make_backend(problem, self.fmus, workers, scheduler,
                                               connect_timeout)
        #: the closed-loop path the flights take, in one word (``native-c``: the native twins
        #: of the FMUs under the C master, one call per flight)
        self.path = flight_path(problem, self.fmus)
        self.cache: OrderedDict = OrderedDict()     # fingerprint -> Outcome, recent last
        self.behaviour: OrderedDict = OrderedDict()  # behaviour key -> Outcome of its first flight
        self.new_behaviour: list = []               # (key, Outcome) not yet in a checkpoint
        self.equivalent = 0                          # laws not flown: equivalent to one flown
        self._probes = _probes(problem)
        self._prober = native_prober(problem, self.fmus) \
            if self._probes is not None and self.path.startswith("native") else None
        self.flown: set = set()                     # fingerprints of every law flown in the run
        self.new_flown: list = []                   # ... of those not yet in a checkpoint
        self.simulated = 0
        self.failures = 0
        self.first_error: str | None = None
        self.fail_loudly = fail_loudly
        self._judged = 0
        #: ``journal([(fingerprint, Outcome), ...])``, called after every chunk of new flights
        #: (None: batches are flown whole, nothing journaled); a synthesis run's folder
        self.journal = None
        #: ``on_chunk(n)`` after every journaled chunk of ``n`` flights (the run's progress)
        self.on_chunk = None
        self._journaled: dict = {}                  # fingerprint -> Outcome a stopped run flew
        self._rate = 0.0                            # laws per second of the last chunk
        #: wall seconds this process spent waiting for flights (inside the backend), and the
        #: flights' own compute seconds (the workers' measured time per law, summed)
        self.fly_seconds = 0.0
        self.flights_cpu = 0.0
        Evaluator._open.add(self)

    @property
    def workers(self) -> int:
        return self.backend.workers

    @property
    def client(self):
        """The Dask client of the Dask backend (None otherwise)."""
        return getattr(self.backend, "client", None)

    def close(self, wait: bool = True) -> None:
        """Release the backend.  ``wait=False`` (a stop on a signal, an error): local workers
        are ended at once instead of finishing their tasks."""
        Evaluator._open.discard(self)
        self.backend.close(wait)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        self.close(wait=exc_type is None)

    def evaluate(self, laws) -> Evaluation:
        """The :class:`Evaluation` of ``laws`` (one row per law, duplicates included).

        A failed candidate gets the problem's penalty (``extras["failed"]``, counted in
        :attr:`failures`); with :attr:`fail_loudly` a systematic failure raises
        :class:`SystematicFailure` instead (nothing of that batch is cached or counted).
        """
        check_stop()
        keys = [law_key(law) for law in laws]
        todo = list({k: law for k, law in zip(keys, laws) if k not in self.cache}.items())
        todo = self._known_behaviour(todo)
        first = 0
        if todo:
            results = self._fly(todo)
            retry = [i for i, (o, _) in enumerate(results) if o is None]
            if retry:   # retried once (a dead worker or a transient FMU error) ...
                for i, r in zip(retry, self._backend_fly([todo[i][1] for i in retry])):
                    results[i] = r
            self._judge([err for o, err in results if o is None], len(todo))
            for (k, _, b), (outcome, err) in zip(todo, results):
                if outcome is None:   # ... then penalised
                    self.failures += 1
                    self.first_error = self.first_error or err
                    outcome = self.problem.failed({"error": err or "unknown error"})
                self.cache[k] = outcome
                self._remember_behaviour(b, outcome)
                if k not in self.flown:
                    self.flown.add(k)
                    self.new_flown.append(k)
                    first += 1
            self.simulated += len(todo)
        rows = []
        for k in keys:
            self.cache.move_to_end(k)
            rows.append(self.cache[k])
        while len(self.cache) > CACHE_SIZE:
            self.cache.popitem(last=False)
        F = np.array([o.f for o in rows], float).reshape(len(laws),
                                                         len(self.problem.objective_names))
        return Evaluation(F, np.array([o.cv for o in rows], float), [o.extras for o in rows],
                          first)

    def _fly(self, todo: list) -> list:
        """The backend's results for the laws of ``todo`` (see :attr:`journal`): the outcomes
        a stopped run journaled, the rest flown in chunks, each chunk journaled."""
        if self.journal is None:
            return self._backend_fly([law for _, law, _ in todo])
        results: list = [None] * len(todo)
        rest = []
        for i, (k, _, _) in enumerate(todo):
            known = self._journaled.pop(k, None)
            if known is not None:
                results[i] = (known, None)
            else:
                rest.append(i)
        while rest:
            n = max(4 * self.workers, int(CHUNK_SECONDS * self._rate)) if self._rate else \
                4 * self.workers
            part, rest = rest[:n], rest[n:]
            t0 = time.perf_counter()
            got = self._backend_fly([todo[i][1] for i in part])
            self._rate = len(part) / max(time.perf_counter() - t0, 1e-9)
            for i, r in zip(part, got):
                results[i] = r
            self.journal([(todo[i][0], r[0]) for i, r in zip(part, got) if r[0] is not None])
            if self.on_chunk is not None:
                self.on_chunk(len(part))
        return results

    def _backend_fly(self, laws) -> list:
        """The backend's results for ``laws``, timed (:attr:`fly_seconds`,
        :attr:`flights_cpu`)."""
        t0 = time.perf_counter()
        out = self.backend.fly(laws)
        wall = time.perf_counter() - t0
        self.fly_seconds += wall
        self.flights_cpu += wall if self.backend.kind == "in-process" else \
            len(laws) * self.backend.flight_seconds
        return out

    def _known_behaviour(self, todo: list) -> list:
        """``todo`` without the laws equivalent to a law flown before (they take its outcome);
        the behaviour keys of the laws to fly come back with them."""
        if self._probes is None:
            return [(k, law, None) for k, law in todo]
        out = []
        for k, law in todo:
            b = _behaviour_key(law, self._probes, self._prober)
            known = self.behaviour.get(b) if b is not None else None
            if known is not None:
                self.cache[k] = known
                self.equivalent += 1
                continue
            out.append((k, law, b))
        return out

    def _remember_behaviour(self, b: bytes | None, outcome) -> None:
        """The first outcome flown with behaviour ``b`` (the last :data:`CACHE_SIZE` kept)."""
        if b is None or b in self.behaviour:
            return
        self.behaviour[b] = outcome
        self.new_behaviour.append((b, outcome))
        while len(self.behaviour) > CACHE_SIZE:
            self.behaviour.popitem(last=False)

    def restore(self, fingerprints, behaviour=(), journaled=()) -> None:
        """What a resumed run had flown before its checkpoint: the laws' fingerprints (not new
        flights again) and the outcomes by behaviour (``(key, Outcome)`` in flight order); and
        what it flew after it, ``(fingerprint, Outcome)`` from the journal: taken instead of
        flying those laws again (see :attr:`journal`)."""
        self.flown.update(fingerprints)
        for b, outcome in behaviour:
            self._remember_behaviour(b, outcome)
        self.new_behaviour = []
        self._journaled.update(journaled)

    def take_new(self) -> tuple[list, list]:
        """``(fingerprints, (behaviour key, Outcome) pairs)`` flown since the last call (for the
        run's checkpoint)."""
        out = (self.new_flown, self.new_behaviour)
        self.new_flown, self.new_behaviour = [], []
        return out

    def _judge(self, errors: list, batch: int) -> None:
        """Raise :class:`SystematicFailure` if this batch's failures are the setup's fault."""
        if self.fail_loudly and batch >= self.JUDGED_BATCH:
            limit = 0.5 if self._judged == 0 else 1.0
            self._judged += 1
            if errors and (len(errors) == batch or len(errors) > limit * batch):
                raise SystematicFailure(len(errors), batch, errors[0] or "unknown error")
