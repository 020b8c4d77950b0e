"""Where laws are flown: in this process, in a local process pool, or on a Dask cluster -- one
interface (:class:`Backend`), chosen by :func:`make_backend`.

A backend takes a batch of laws and returns, per law, what a
:class:`~synthesis.run.flights.LawFlyer` gave (an Outcome, or None and the error text); it
knows no method and no evaluation rule (caching, retries and penalties are
:mod:`synthesis.run.evaluation`'s).  Batches are cut into chunks sized by the measured cost of a
law (:func:`chunk_size`).

Local pool workers exit within seconds of the parent's death, whatever ends it
(:func:`synthesis.run.signals.watch_parent`); each worker reports its process id when it starts,
so that :meth:`ProcessPool.close` can end them at once without reading the pool's private state.
The parent's waits honour a requested stop (:func:`synthesis.run.signals.check_stop`).
"""
from __future__ import annotations

import abc
import math
import multiprocessing
import os
import signal
import time
from concurrent.futures import FIRST_EXCEPTION, ProcessPoolExecutor
from concurrent.futures import wait as wait_futures
from pathlib import Path
from concurrent.futures.process import BrokenProcessPool

from descent_fmus.synthesis.run.flights import LawFlyer
from descent_fmus.synthesis.run.signals import check_stop, critical, watch_parent

__all__ = ["Backend", "InProcess", "ProcessPool", "DaskCluster", "make_backend", "chunk_size",
           "SchedulerError", "TASK_OVERHEAD", "TASK_DISPATCH", "FIRST_GUESS_FLIGHT",
           "SMALL_BATCH", "HERE_THREADS"]


class SchedulerError(ConnectionError):
    """The Dask scheduler cannot be reached (or has no workers)."""


#: Scheduling cost per task [s] of each backend (dispatch, argument transfer, result return:
#: the wall time of a task that does no work, one worker) and the Dask scheduler's dispatch
#: time per task (no-op tasks on several workers), measured by ``python benchmarks/cluster.py``;
#: with the measured cost of a flight they choose the chunk size (:func:`chunk_size`).  Values of
#: a shared, loaded 2-core machine (the upper end: larger chunks are the safe side).
TASK_OVERHEAD = {"pool": 0.0037, "dask": 0.0094}
TASK_DISPATCH = {"pool": 0.0, "dask": 0.009}
#: [choice] A local pool flies a batch of at most this many laws in the parent process (the
#: same flyer on the same FMUs): a round trip to the workers costs more than the flights.
SMALL_BATCH = 16
#: [choice] A small batch flown in the parent goes in this many threads: 2, its second half by
#: a second C master in a helper thread (:meth:`LawFlyer.split
#: <synthesis.run.flights.LawFlyer.split>`; the start values packed once, each half one C call
#: with the GIL released); where the flights do not go through the C master's batch, one
#: thread.  While the parent flies a CMA-ES generation the workers wait, so their cores are
#: idle (docs/methods/run_loop.md, speed13).
HERE_THREADS = 2
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


class Backend(abc.ABC):
    """Flies batches of laws of one problem (see the module docstring)."""

    kind = "in-process"
    workers = 1

    def __init__(self, problem, fmus: tuple):
        self.problem, self.fmus = problem, tuple(str(f) for f in fmus)
        self.flight_seconds = FIRST_GUESS_FLIGHT      # measured compute time per law [s]

    @abc.abstractmethod
    def fly(self, laws) -> list:
        """Per law ``(Outcome or None, error text or None)``, same order."""

    def close(self, wait: bool = True) -> None:
        """Release the workers; ``wait=False`` (a stop, an error): end them at once."""

    def _chunks(self, items, workers: int):
        k = chunk_size(len(items), workers, self.flight_seconds, TASK_OVERHEAD[self.kind],
                       TASK_DISPATCH[self.kind])
        return [items[i:i + k] for i in range(0, len(items), k)]

    def _measured(self, chunks, timings) -> None:
        n = sum(len(c) for c, t in zip(chunks, timings) if t is not None)
        if n:
            self.flight_seconds = sum(t for t in timings if t is not None) / n

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
                out.extend([(None, f"{type(exc).__name__}: {exc}")] * len(chunk))
                timings.append(None)
        self._measured(chunks, timings)
        return out


class InProcess(Backend):
    """Laws flown in this process; a requested stop ends a batch between two laws."""

    def __init__(self, problem, fmus):
        super().__init__(problem, fmus)
        self.flyer = LawFlyer(problem, *self.fmus)

    def fly(self, laws) -> list:
        return self.flyer.fly_all(laws, stoppable=True)

    def close(self, wait: bool = True) -> None:
        self.flyer.close()


# -- local process pool ---------------------------------------------------------------------------
#: This worker process's flyer (set by the pool's initialiser; one per process).
_WORKER_FLYER: LawFlyer | None = None


def _remove_worker_files() -> None:
    if _WORKER_FLYER is not None:
        _WORKER_FLYER.remove_files()


def _init_worker(problem, plant, controller, parent_pid, pids) -> None:
    global _WORKER_FLYER
    import multiprocessing.util
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    pids.put(os.getpid())
    watch_parent(parent_pid, cleanup=_remove_worker_files)
    # a worker leaves through os._exit (no atexit): its files go in multiprocessing's finaliser
    multiprocessing.util.Finalize(None, _remove_worker_files, exitpriority=10)
    _WORKER_FLYER = LawFlyer(problem, plant, controller)   # a load failure fails every law


def _fly_in_worker(laws) -> tuple:
    return _WORKER_FLYER.fly_timed(laws)


class ProcessPool(Backend):
    """A local pool of ``workers`` processes, each loading the FMUs once."""

    kind = "pool"

    def __init__(self, problem, fmus, workers: int):
        super().__init__(problem, fmus)
        self.workers = workers
        self._ctx = multiprocessing.get_context()
        self._pids = self._ctx.SimpleQueue()
        self._known: set = set()
        self._here: LawFlyer | None = None          # flies small batches
        self.small_batch = SMALL_BATCH                # (0: every batch goes to the workers)
        self.here_threads = HERE_THREADS              # (1: in this thread alone)
        self._pool = self._new_pool()
        # [choice] the workers start now (forked at the first task), loading their FMUs while
        # this process prepares the search, not when the first batch waits for them
        self._pool.submit(int)

    def _new_pool(self):
        return ProcessPoolExecutor(max_workers=self.workers, mp_context=self._ctx,
                                   initializer=_init_worker,
                                   initargs=(self.problem,) + self.fmus
                                   + (os.getpid(), self._pids))

    def worker_pids(self) -> set:
        """Process ids of the workers started so far (each reports its own)."""
        while not self._pids.empty():
            self._known.add(self._pids.get())
        return set(self._known)

    def fly(self, laws) -> list:
        if len(laws) <= self.small_batch:
            return self._fly_here(laws)
        chunks = self._chunks(laws, self.workers)
        try:
            futures = [self._pool.submit(_fly_in_worker, c) for c in chunks]
            self._wait(futures)
            return self._collect(futures, chunks, fatal=BrokenProcessPool)
        except BrokenProcessPool as exc:
            return self._broken(exc, len(laws))

    def _wait(self, futures) -> None:
        """Until every task is done (or a worker died), honouring a requested stop."""
        pending = set(futures)
        while pending:
            _, pending = wait_futures(pending, timeout=0.25, return_when=FIRST_EXCEPTION)
            check_stop()
            if any(f.done() and isinstance(f.exception(), BrokenProcessPool) for f in futures):
                break

    def _broken(self, exc, n: int) -> list:
        """A worker died: start a fresh pool; the batch's laws are retried by the evaluator."""
        self._end_pool(wait=False)
        self._pool = self._new_pool()
        return [(None, f"worker died: {exc}")] * n

    def _fly_here(self, laws) -> list:
        """A small batch flown in this process: the workers' code on the same FMUs, so the
        same outcomes, without a round trip to them (:data:`SMALL_BATCH`), in
        :data:`HERE_THREADS` threads."""
        if self._here is None:
            self._here = LawFlyer(self.problem, *self.fmus)
            if self.here_threads > 1:
                self._here.split()
        out, seconds = self._here.fly_timed(laws)
        self.flight_seconds = seconds / max(len(laws), 1)
        return out

    def _end_pool(self, wait: bool) -> None:
        pool, self._pool = self._pool, None
        if pool is None:
            return
        if wait:
            pool.shutdown(wait=True, cancel_futures=True)
            return
        pids = self.worker_pids()
        for pid in pids:           # SIGTERM: a worker removes its extracted FMUs and exits
            _signal(pid, signal.SIGTERM)
        deadline = time.monotonic() + 1.0          # a worker leaves at once on SIGTERM
        while time.monotonic() < deadline and any(_alive(p) for p in pids):
            time.sleep(0.02)
        for pid in pids:
            if _alive(pid):
                _signal(pid, signal.SIGKILL)
        pool.shutdown(wait=False, cancel_futures=True)      # its thread reaps the processes
        self._known.clear()

    def close(self, wait: bool = True) -> None:
        self._end_pool(wait)
        flyer, self._here = self._here, None
        if flyer is not None:
            flyer.close()


def _signal(pid: int, sig) -> None:
    try:
        os.kill(pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def _alive(pid: int) -> bool:
    """Whether process ``pid`` still runs (a zombie, awaiting its reaping, does not)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rpartition(")")[2].split()[0] not in ("Z", "X")
    except FileNotFoundError:
        return False
    except OSError:                   # no /proc: ask the kernel whether the pid exists
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True


# -- Dask -----------------------------------------------------------------------------------------
class DaskCluster(Backend):
    """A Dask cluster: a scheduler address (``tcp://host:port``) or ``"local"`` (a LocalCluster
    of ``workers`` processes).  The FMU files are read here and shipped to the workers
    (:mod:`synthesis.run.cluster`)."""

    kind = "dask"

    def __init__(self, problem, fmus, address: str, workers: int = 1,
                 connect_timeout: float = 10.0):
        super().__init__(problem, fmus)
        try:
            from distributed import Client
        except ImportError:
            raise SchedulerError("the Dask backend needs 'distributed': pip install "
                                 "'dask[distributed]'") from None
        from descent_fmus.synthesis.run.cluster import FmuFile, FmuShipment, start_local_cluster
        self.workers = workers
        self.cluster = None
        self.plugin = FmuShipment(_shipment(problem, self.fmus, FmuFile.read))
        if address == "local":
            self.cluster, self.client = start_local_cluster(workers)
        else:
            try:
                self.client = Client(address, timeout=f"{connect_timeout}s",
                                     set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise SchedulerError(f"cannot reach the Dask scheduler at {address}: {exc}") \
                    from None
        try:
            self.client.register_plugin(self.plugin)
        except BaseException:
            self.close()
            raise

    def fly(self, laws) -> list:
        from descent_fmus.synthesis.run.cluster import fly_shipped
        client = self.client
        if not client.nthreads():
            try:
                client.wait_for_workers(1, timeout=60)
            except TimeoutError:
                raise SchedulerError(f"the Dask cluster at {client.scheduler.address} has no "
                                     f"workers (waited 60 s)") from None
        chunks = self._chunks(laws, len(client.nthreads()))
        n = len(chunks)
        futures = client.map(fly_shipped, [self.problem] * n, [self.plugin.name] * n, chunks,
                             pure=False)
        try:
            while not all(f.done() for f in futures):
                check_stop()
                time.sleep(0.01)
            return self._collect(futures, chunks)
        finally:
            client.cancel([f for f in futures if not f.done()])

    def close(self, wait: bool = True) -> None:
        client, self.client = getattr(self, "client", None), None
        if client is not None:
            try:
                if self.cluster is None:
                    client.unregister_worker_plugin(self.plugin.name)
            except Exception:
                pass
            client.close()
        cluster, self.cluster = self.cluster, None
        if cluster is not None:
            cluster.close()


def flight_path(problem, fmus) -> str:
    """The closed-loop path the problem's runner takes with these FMUs, in one word
    (``native-c``, ``native-container``, ``native-master``, ``container``, ``master``)."""
    return problem.runner.choose(problem.wiring, *fmus, record=problem.record,
                                 initial=problem.initial)[0]


def _shipment(problem, fmus, read) -> list:
    """The files a Dask worker needs: the plant and the controller, and their native twins
    (``native/<identifier>.fmu``) where the runner flies them, so that the workers take the
    path the client would."""
    files = [read(f) for f in fmus]
    if flight_path(problem, fmus).startswith("native"):
        from descent_fmus.synthesis.fmi.native_loop import NATIVE_DIR, native_fmus
        files += [read(t, f"{NATIVE_DIR}/{Path(t).name}")
                  for t in native_fmus(problem.wiring, *fmus)]
    return files


def make_backend(problem, fmus, workers: int = 1, scheduler: str | None = None,
                 connect_timeout: float = 10.0) -> Backend:
    """The backend for ``workers`` local processes (1 = this process) or a Dask ``scheduler``
    (an address, or ``"local"`` for a LocalCluster of ``workers`` processes)."""
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if scheduler:
        return DaskCluster(problem, fmus, scheduler, workers, connect_timeout)
    if workers > 1:
        return ProcessPool(problem, fmus, workers)
    return InProcess(problem, fmus)

