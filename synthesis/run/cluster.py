"""The Dask side of the evaluator: FMUs shipped to the workers, nothing path-based.

A Dask worker may run on another host, in a container or under a batch system: it has the
installed ``descent-fmus`` package and nothing of the client's disk.  The client therefore reads
the two FMU files once (and their native twins, ``native/<identifier>.fmu``, where they are
built) and registers a :class:`FmuShipment` worker plugin carrying their bytes; the scheduler
hands the plugin to every worker, present and joining later, and each worker writes the files
once into its own local directory (``worker.local_directory``), in a folder named by the hash of
their contents, laid out as on the client (so a worker flies the native path where the client
would).  A task names the shipment only.

Worker loss costs nothing: the scheduler re-runs a lost task elsewhere (the evaluator also retries
a failed chunk once).  A joining worker receives the plugin when it registers and then takes
tasks like the others (work stealing moves queued tasks to it).

Each worker flies the laws with one :class:`~synthesis.run.flights.LawFlyer` per problem, which
the plugin keeps (:meth:`FmuShipment.flyer`): the FMUs are loaded once per worker, not per task.

This module imports ``distributed``; :mod:`synthesis.run.backends` imports it only when a
scheduler is used.
"""
from __future__ import annotations

import hashlib
import os
import uuid
from dataclasses import dataclass
from pathlib import Path

from distributed import Client, get_worker
from distributed.diagnostics.plugin import WorkerPlugin

from descent_fmus.synthesis.paths import FMUNotFoundError, require_fmu

__all__ = ["FmuFile", "FmuShipment", "start_local_cluster", "fly_shipped", "CACHE_DIR"]

#: Folder inside a worker's local directory holding shipped FMUs
#: (``<hash of the shipment>/<file name>``, ``.../native/<file name>``).
CACHE_DIR = "descent-fmus-fmus"


@dataclass(frozen=True)
class FmuFile:
    """One FMU file as bytes, named by its path in the shipment (``Reentry.fmu``,
    ``native/Reentry.fmu``) and the SHA-256 of its content."""

    name: str
    digest: str
    data: bytes

    @classmethod
    def read(cls, path, name: str | None = None) -> "FmuFile":
        path = require_fmu(path)
        data = path.read_bytes()
        return cls(name or path.name, hashlib.sha256(data).hexdigest(), data)


def materialise(f: FmuFile, folder) -> Path:
    """Write ``f`` as ``folder/f.name`` once (atomically; a file of that size is kept: the
    folder is named by the hash of the whole shipment)."""
    path = Path(folder) / f.name
    if path.is_file() and path.stat().st_size == len(f.data):
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(f.data)
    os.replace(tmp, path)
    return path


class FmuShipment(WorkerPlugin):
    """Worker plugin writing a run's FMU files into each worker's local directory.

    ``files`` are the problem's plant and controller, then any other files of the shipment
    (their native twins, named ``native/<file name>``).  One plugin per evaluator (the run
    unregisters it when it ends, so that a long-lived scheduler does not collect them); the
    files are kept in a folder named by the hash of their contents, so a worker that already
    has them (another run, a resumed run) writes nothing.
    """

    def __init__(self, files):
        self.files = tuple(files)
        names = [f.name for f in self.files]
        if len(set(names)) != len(names):
            raise ValueError(f"a shipment names each file once, got {names}")
        digest = hashlib.sha256("".join(f"{f.name}:{f.digest};" for f in self.files)
                                .encode()).hexdigest()
        self.digest = digest
        self.name = f"descent-fmus-{digest[:16]}-{uuid.uuid4().hex[:8]}"

    def setup(self, worker):
        folder = Path(worker.local_directory) / CACHE_DIR / self.digest
        written = [materialise(f, folder) for f in self.files]
        self.paths = tuple(str(p) for p in written[:2])
        self.flyers = {}

    def teardown(self, worker):
        for flyer in self.flyers.values():
            flyer.close()
        self.flyers = {}

    def flyer(self, problem):
        """This worker's flyer of ``problem`` with the shipped FMUs (loaded on first use)."""
        from descent_fmus.synthesis.run.flights import LawFlyer
        key = (problem.name, problem.source)
        if key not in self.flyers:
            for path in self.paths:
                if not Path(path).is_file():
                    raise FMUNotFoundError(f"FMU {Path(path).name} was not shipped to this "
                                           f"Dask worker")
            self.flyers[key] = LawFlyer(problem, *self.paths)
        return self.flyers[key]


def fly_shipped(problem, plugin_name: str, laws):
    """Dask task: fly ``laws`` with the FMUs the plugin ``plugin_name`` shipped to this worker;
    ``(results, compute seconds)`` (per-law failures are results)."""
    return get_worker().plugins[plugin_name].flyer(problem).fly_timed(laws)


def start_local_cluster(workers: int):
    """A Dask LocalCluster of ``workers`` single-threaded worker processes and its client.

    Dask's worker processes watch a pipe to the process that started them and exit at once when
    it dies (``distributed.process.AsyncProcess``), so they never outlive the run.
    """
    from distributed import LocalCluster
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    try:
        return cluster, Client(cluster, set_as_default=False)
    except BaseException:
        cluster.close()
        raise
