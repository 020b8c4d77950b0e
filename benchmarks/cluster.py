"""Benchmark: the Dask backend on workers started with the ``dask`` command line.

Measures, for the reentry problem (every candidate one closed-loop FMU flight):

* the cost of one law's flights on one core (in-process evaluator);
* the scheduling overhead per task: of the Dask scheduler (a task carrying the problem and a
  chunk of laws that does no work; round trip client -> scheduler -> worker -> client) and of a
  local process pool (the same);
* evaluations/s with 1, 2 and 4 worker processes started with ``dask worker`` (``--nworkers N
  --nthreads 1``) -- the FMUs shipped as bytes, no shared folder;
* the chunk size the evaluator chooses from these (``synthesis.run.evaluation.chunk_size``) and a
  projection of evaluations/s for N hosts.

    python benchmarks/cluster.py [--n 256] [--fmus DIR] [--cores-per-host 2] [--json]

On a 2-core machine, 4 worker processes share 2 cores: the rate cannot exceed the 2-worker rate
(the printed ceiling is 2 x the single-core rate).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from descent_fmus.synthesis.run.evaluation import Evaluator, chunk_size
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.methods.registry import make_method

PROBLEM = get_problem("reentry")


def laws(n: int, seed: int):
    return [c.law for c in make_method("network-operator",
                                       PROBLEM.tuned(population=n, seed=seed)).ask()]


def _noop(problem, chunk):          # a task with the evaluator's arguments and no work
    return [None] * len(chunk), 0.0


def flight_cost(fmus, batch) -> float:
    with Evaluator(PROBLEM, fmus) as ev:
        ev.evaluate(batch[:4])
        t0 = time.perf_counter()
        ev.evaluate(batch[4:])
        return (time.perf_counter() - t0) / (len(batch) - 4)


def dask_noop_wall(address, batch, tasks=400) -> float:
    """Wall time per no-op task: with one worker, what a task costs a worker (o); with
    several, the cluster's dispatch rate (its inverse bounds the tasks/s of the scheduler)."""
    from distributed import Client
    chunk = batch[:4]
    with Client(address, set_as_default=False) as c:
        c.gather(c.map(_noop, [PROBLEM] * 20, [chunk] * 20, pure=False))      # warm up
        t0 = time.perf_counter()
        c.gather(c.map(_noop, [PROBLEM] * tasks, [chunk] * tasks, pure=False))
        return (time.perf_counter() - t0) / tasks


def pool_overhead(batch, tasks=400) -> float:
    chunk = batch[:4]
    with ProcessPoolExecutor(1) as pool:
        list(pool.map(_noop, [PROBLEM] * 20, [chunk] * 20))
        t0 = time.perf_counter()
        list(pool.map(_noop, [PROBLEM] * tasks, [chunk] * tasks))
        return (time.perf_counter() - t0) / tasks


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Cluster:
    """``dask scheduler`` + ``dask worker --nworkers N`` in a scratch folder."""

    def __init__(self, workers: int):
        dask = shutil.which("dask", path=os.path.dirname(sys.executable)) or "dask"
        self.tmp = tempfile.mkdtemp(prefix="descent_bench_")
        self.address = f"tcp://127.0.0.1:{_port()}"
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        kw = dict(cwd=self.tmp, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port",
                                        self.address.rsplit(":", 1)[1], "--no-dashboard"], **kw)]
        self.procs.append(subprocess.Popen([dask, "worker", self.address, "--nworkers",
                                            str(workers), "--nthreads", "1", "--no-dashboard",
                                            "--local-directory", self.tmp], **kw))
        from distributed import Client
        deadline = time.time() + 120
        while time.time() < deadline:
            try:
                with Client(self.address, timeout="2s", set_as_default=False) as c:
                    if len(c.nthreads()) == workers:
                        return
            except OSError:
                pass
            time.sleep(0.3)
        self.close()
        raise RuntimeError("the dask cluster did not start")

    def close(self):
        for p in reversed(self.procs):
            p.terminate()
        for p in self.procs:
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                p.kill()
        shutil.rmtree(self.tmp, ignore_errors=True)


def dask_rate(address, fmus, batch, warm) -> float:
    with Evaluator(PROBLEM, fmus, scheduler=address) as ev:
        ev.evaluate(warm)                          # every worker loads the FMUs
        t0 = time.perf_counter()
        n0 = ev.simulated
        ev.evaluate(batch)
        return (ev.simulated - n0) / (time.perf_counter() - t0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=256, help="laws per measured batch")
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    ap.add_argument("--cores-per-host", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    batch, warm = laws(args.n, 11), laws(32, 12)
    c = flight_cost(args.fmus, laws(64, 13))
    out = {"flight_seconds": c, "pool_overhead_seconds": pool_overhead(batch), "rates": {}}
    for w in (1, 2, 4):
        cl = Cluster(w)
        try:
            out.setdefault("dask_noop_wall_seconds", {})[w] = dask_noop_wall(cl.address, batch)
            out["rates"][w] = dask_rate(cl.address, args.fmus, batch, warm)
        finally:
            cl.close()
    o = out["dask_overhead_seconds"] = out["dask_noop_wall_seconds"][1]
    o_s = out["dask_dispatch_seconds"] = min(out["dask_noop_wall_seconds"].values())
    out["chunk_size"] = {W: chunk_size(args.n, W, c, o, o_s) for W in (1, 2, 4, 8, 16, 32, 64)}
    # projection: each core runs one law per (c + o / k); the scheduler hands out at most one
    # task per o_s seconds (the fastest no-op dispatch measured here: a pessimistic bound on a
    # 2-core machine where the scheduler shares the cores with the workers).  Batches of 256
    # (this problem's population) and 1024 laws (the paper's population of 1000).
    proj = {}
    for hosts in (1, 2, 4, 8, 16, 32):
        W = hosts * args.cores_per_host
        row = {"workers": W}
        for n in (256, 1024):
            k = chunk_size(n, W, c, o, o_s)
            work, sched = W / (c + o / k), k / o_s
            row[n] = {"chunk": k, "evaluations_per_s": min(work, sched),
                      "scheduler_bound": work > sched}
        proj[hosts] = row
    out["projection"] = proj
    if args.json:
        print(json.dumps(out, indent=1))
        return
    print(f"reentry, batches of {args.n} distinct laws (FMU co-simulation per law)")
    print(f"  one law's flights on one core            c = {1e3 * c:7.2f} ms "
          f"({1 / c:5.1f} evaluations/s)")
    print(f"  Dask scheduling overhead per task        o = {1e3 * o:7.2f} ms "
          f"(no-op tasks; fastest dispatch {1e3 * o_s:.2f} ms/task)")
    print(f"  process-pool overhead per task               "
          f"{1e3 * out['pool_overhead_seconds']:7.2f} ms")
    for w, r in out["rates"].items():
        print(f"  dask CLI, {w} worker process(es): {r:7.1f} evaluations/s   "
              f"(x{r * c:4.2f} one core; ceiling on this machine "
              f"{min(w, os.cpu_count() or 1) / c:5.1f}/s)")
    print("  chunk size k = max(sqrt(2 n o / (W c)), W o_s / c) for n = %d: %s" % (
        args.n, ", ".join(f"W={W}: {k}" for W, k in out["chunk_size"].items())))
    print(f"  projection ({args.cores_per_host} cores per host, same per-flight cost), "
          f"batches of 256 | 1024 laws:")
    for hosts, p in proj.items():
        cols = [f"{p[n]['evaluations_per_s']:7.0f}/s (chunk {p[n]['chunk']:2d}"
                + (", scheduler-bound)" if p[n]["scheduler_bound"] else ")") for n in (256, 1024)]
        print(f"    {hosts:3d} hosts ({p['workers']:3d} workers): " + " | ".join(cols))

if __name__ == "__main__":
    main()
