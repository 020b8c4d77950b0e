"""The Dask backend: a real scheduler and two workers on loopback, started by the test.

Oracle: the in-process evaluator on the same FMUs (identical numbers); a worker killed before
the batch costs time, not results.
"""
from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from descent_fmus.synthesis.run.evaluation import Evaluator
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law

ROOT = Path(__file__).resolve().parents[2]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def cluster(tmp_path):
    dask = shutil.which("dask", path=os.path.dirname(sys.executable)) or shutil.which("dask")
    if dask is None:
        pytest.skip("dask CLI not installed")
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], cwd=tmp_path, env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    for k in range(2):
        procs.append(subprocess.Popen([dask, "worker", addr, "--nthreads", "1", "--nworkers",
                                       "1", "--no-dashboard", "--name", f"w{k}"],
                                      cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL))
    from distributed import Client
    deadline = time.time() + 60
    while True:
        try:
            with Client(addr, timeout="2s") as c:
                if len(c.scheduler_info()["workers"]) == 2:
                    break
        except OSError:
            pass
        if time.time() > deadline:
            for p in procs:
                p.kill()
            pytest.fail("dask cluster did not start")
        time.sleep(0.3)
    yield addr, procs
    for p in reversed(procs):
        p.terminate()
    for p in procs:
        try:
            p.wait(10)
        except subprocess.TimeoutExpired:
            p.kill()


def test_dask_cluster_equals_local(cluster, fmu_dir):
    addr, procs = cluster
    rng = np.random.default_rng(8)
    laws = [paper_basic_law(q=rng.uniform(0, 8, 2)) for _ in range(12)]
    with Evaluator(get_problem("reentry"), fmu_dir) as local:
        F_local = local.evaluate(laws).F
    with Evaluator(get_problem("reentry"), fmu_dir, scheduler=addr) as remote:
        F_dask = remote.evaluate(laws).F
        assert remote.failures == 0
        # one worker dies: the scheduler hands its share to the other; nothing is lost
        procs[1].kill()
        procs[1].wait()
        more = [paper_basic_law(q=rng.uniform(0, 8, 2)) for _ in range(6)]
        F_more = remote.evaluate(more).F
        assert remote.failures == 0
    assert np.array_equal(F_local, F_dask)
    with Evaluator(get_problem("reentry"), fmu_dir) as local:
        assert np.array_equal(local.evaluate(more).F, F_more)
