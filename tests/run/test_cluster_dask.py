"""Scale-out without a shared filesystem: a real Dask scheduler and workers started with the
``dask`` command line in their own working and temporary directories.

The workers get the FMUs only as bytes from the client (synthesis.run.cluster.FmuShipment); the
client's FMU folder is renamed away while the run goes on.  Oracles: the same run evaluated in
this process (same seed => the same Pareto set, to the last digit), and the FMU's own error
message for a setup in which every candidate fails.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from descent_fmus.synthesis.run.evaluation import Evaluator
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.methods.registry import make_method

ROOT = Path(__file__).resolve().parents[2]
REENTRY = get_problem("reentry")
# the reentry problem as a problem file, a small budget (the variational GA alone)
PROBLEM_FILE = ROOT / "synthesis/systems/reentry/reentry.toml"
SMALL = ["--population", "16", "--generations", "6", "--crossovers", "6", "--lchr", "4",
         "--epoch", "3", "--seed", "5", "--refine-basis", "0", "--refine-evals", "0",
         "--flights", "0", "--basis-rule", "compromise", "--input-scaling", "given",
         "--equivalence-probes", "0", "--quiet", "--no-export",
         "--no-reference", "--json"]
FMUS = ("Reentry.fmu", "NetworkOperatorController.fmu")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class DaskCLI:
    """A scheduler and workers started with the ``dask`` CLI, away from the client's folders."""

    def __init__(self, base: Path):
        self.dask = shutil.which("dask", path=os.path.dirname(sys.executable))
        self.base = base
        self.port = _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.procs = {}
        (base / "tmp").mkdir(parents=True)
        # the package is installed: the workers need nothing else (no PYTHONPATH, no FMUs)
        self.env = {k: v for k, v in os.environ.items()
                    if k not in ("PYTHONPATH", "DESCENT_FMUS_DIR")}
        self.env["TMPDIR"] = str(base / "tmp")
        self._start("scheduler", [self.dask, "scheduler", "--host", "127.0.0.1", "--port",
                                  str(self.port), "--no-dashboard"])

    def _start(self, name, cmd):
        self.procs[name] = subprocess.Popen(cmd, cwd=self.base, env=self.env,
                                            stdout=subprocess.DEVNULL,
                                            stderr=subprocess.DEVNULL)

    def add_worker(self, name: str) -> None:
        self._start(name, [self.dask, "worker", self.address, "--nthreads", "1", "--nworkers",
                           "1", "--no-dashboard", "--name", name, "--local-directory",
                           str(self.base / f"local-{name}")])

    def workers(self) -> dict:
        """{worker name: address} as the scheduler sees them."""
        from distributed import Client
        try:
            with Client(self.address, timeout="2s") as c:
                return {w["name"]: a for a, w in c.scheduler_info()["workers"].items()}
        except OSError:
            return {}

    def wait_for(self, names, timeout=60.0) -> dict:
        deadline = time.time() + timeout
        while time.time() < deadline:
            have = self.workers()
            if set(names) <= set(have):
                return have
            time.sleep(0.3)
        raise AssertionError(f"dask workers {names} did not start")

    def kill(self, name: str) -> None:
        p = self.procs.pop(name)
        p.kill()
        p.wait()

    def close(self) -> None:
        for p in reversed(list(self.procs.values())):
            p.terminate()
        for p in self.procs.values():
            try:
                p.wait(3)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


@pytest.fixture
def cluster(tmp_path):
    if shutil.which("dask", path=os.path.dirname(sys.executable)) is None:
        pytest.skip("dask CLI not installed")
    c = DaskCLI(tmp_path / "remote")
    for name in ("w0", "w1"):
        c.add_worker(name)
    c.wait_for(["w0", "w1"])
    yield c
    c.close()


def _copy_fmus(fmu_dir: Path, d: Path, native: bool) -> Path:
    (d / "native").mkdir(parents=True)
    for f in FMUS:
        shutil.copy(fmu_dir / f, d / f)
        if native and (fmu_dir / "native" / f).is_file():
            shutil.copy(fmu_dir / "native" / f, d / "native" / f)
    return d


@pytest.fixture
def client_fmus(tmp_path, fmu_dir):
    """A copy of the pythonfmu FMUs only the client sees (renamed away by the tests): the
    pythonfmu path, whose flights are slow enough to lose a worker in the middle of a batch."""
    return _copy_fmus(fmu_dir, tmp_path / "client_fmus", native=False)


@pytest.fixture
def client_fmus_native(tmp_path, fmu_dir):
    """The same with the native twins beside them where they are built (the evaluator's
    default path)."""
    return _copy_fmus(fmu_dir, tmp_path / "client_fmus_native", native=True)


def _native(d: Path) -> bool:
    return all((d / "native" / f).is_file() for f in FMUS)


def _worker_paths(client) -> dict:
    """{worker address: the closed-loop paths its flyers took}."""
    def paths(dask_worker):
        return sorted({fl.loop.path for p in dask_worker.plugins.values()
                       for fl in getattr(p, "flyers", {}).values() if fl.loop is not None})
    return client.run(paths)


def _cli(*args, **kw):
    return subprocess.Popen([sys.executable, "-m", "descent_fmus.synthesis.cli.main",
                             *map(str, args)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, **kw)


def test_synthesis_needs_no_shared_folder(cluster, client_fmus_native, fmu_dir, tmp_path):
    client_fmus = client_fmus_native
    out = tmp_path / "dask_run"
    run = _cli("synthesize", "--problem", PROBLEM_FILE, *SMALL, "--scheduler", cluster.address,
               "--fmus", str(client_fmus), "--out", str(out))
    deadline = time.time() + 120
    while not (out / "checkpoint.json").exists() and time.time() < deadline:
        time.sleep(0.05)
    assert run.poll() is None, "the run ended before the FMU folder could be moved"
    client_fmus.rename(tmp_path / "gone")          # nothing path-based reaches the workers
    stdout, stderr = run.communicate(timeout=300)
    assert run.returncode == 0, stderr
    summary = json.loads(stdout)
    assert summary["failures"] == 0 and summary["generations"] == 6
    native = _native(fmu_dir)
    assert summary["flight_path"] == ("native-c" if native else "master")
    local = _cli("synthesize", "--problem", PROBLEM_FILE, *SMALL, "--workers", "1",
                 "--fmus", str(fmu_dir),
                 "--out", str(tmp_path / "local_run"))
    assert local.wait(300) == 0, local.stderr.read()
    # same seed, same FMUs => the same Pareto set, to the last digit
    assert (out / "pareto.csv").read_text() == (tmp_path / "local_run" / "pareto.csv").read_text()
    # each worker holds the FMUs once, in a folder named by their hash, in its own local
    # directory, with the native twins beside them as on the client
    shipped = sorted(str(p.relative_to(p.parents[1 if p.parent.name == "native" else 0]))
                     for p in (cluster.base / "local-w0").rglob("*.fmu"))
    assert shipped == sorted(FMUS + (tuple(f"native/{f}" for f in FMUS) if native else ()))


def test_worker_loss_mid_batch_and_a_joining_worker(cluster, client_fmus, fmu_dir):
    from distributed import get_task_stream
    laws = [c.law for c in make_method("network-operator",
                                       REENTRY.tuned(population=64, seed=3)).ask()]
    more = [c.law for c in make_method("network-operator",
                                       REENTRY.tuned(population=64, seed=4)).ask()]
    with Evaluator(REENTRY, fmu_dir) as local:
        F_ref = local.evaluate(laws).F
        F_more_ref = local.evaluate(more).F
    with Evaluator(REENTRY, client_fmus, scheduler=cluster.address) as ev:
        client_fmus.rename(client_fmus.with_name("gone"))
        ev.evaluate(laws[:4])                         # both workers have loaded the FMUs
        assert ev.path == "master"
        assert list(_worker_paths(ev.client).values()) == [["master"], ["master"]]
        killed = []
        timer = threading.Timer(0.4, lambda: (cluster.kill("w1"), killed.append(time.time())))
        timer.start()
        F = ev.evaluate(laws).F
        done = time.time()
        timer.join()
        assert killed and killed[0] < done, "the worker died after the batch"
        assert ev.failures == 0                       # its tasks ran again on w0
        np.testing.assert_array_equal(F, F_ref)
        cluster.add_worker("w2")                      # joins mid-run, gets the FMUs itself
        addresses = cluster.wait_for(["w0", "w2"])
        with get_task_stream(client=ev.client) as ts:
            F_more = ev.evaluate(more).F
        ran_on = {t["worker"] for t in ts.data}
        assert addresses["w2"] in ran_on
        assert ev.failures == 0
        np.testing.assert_array_equal(F_more, F_more_ref)


def test_workers_fly_the_native_twins(cluster, client_fmus_native, fmu_dir):
    # the workers take the path the client would: the native twins shipped beside the
    # pythonfmu FMUs; the same numbers as this process's own flights, bit for bit
    if not _native(fmu_dir):
        pytest.skip("the native FMUs are not built (no C compiler)")
    laws = [c.law for c in make_method("network-operator",
                                       REENTRY.tuned(population=32, seed=6)).ask()]
    with Evaluator(REENTRY, fmu_dir) as local:
        assert local.path == "native-c"
        F_ref = local.evaluate(laws).F
    with Evaluator(REENTRY, client_fmus_native, scheduler=cluster.address) as ev:
        client_fmus_native.rename(client_fmus_native.with_name("gone"))
        assert ev.path == "native-c"
        F = ev.evaluate(laws).F
        # (a worker given no task has loaded nothing)
        assert set(tuple(v) for v in _worker_paths(ev.client).values() if v) \
            == {("native-c",)}
    np.testing.assert_array_equal(F, F_ref)


def test_every_candidate_failing_stops_the_run(cluster, client_fmus, tmp_path):
    # a broken setup (here: an invalid plant parameter in every initial state) is no
    # candidate's fault: exit 2 with the FMU's own message, nothing penalised into a result
    toml = PROBLEM_FILE.read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(toml.replace("states = [ {} ]", "states = [ { m = -5.0 } ]"))
    assert "m = -5.0" in bad.read_text()
    out = tmp_path / "bad_run"
    run = _cli("synthesize", "--problem", str(bad), *SMALL, "--scheduler", cluster.address,
               "--fmus", str(client_fmus), "--out", str(out))
    stdout, stderr = run.communicate(timeout=300)
    assert run.returncode == 2, stderr
    assert re.search(r"(\d+) of \1 evaluations failed", stderr), stderr
    assert "parameter m must be > 0, got -5.0" in stderr
    assert "Traceback" not in stderr
    # no generation finished: nothing to resume, the folder is free for the same command
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("n, workers, flight, overhead", [
    (256, 2, 0.044, 0.009), (1024, 16, 0.044, 0.009), (128, 4, 0.2, 0.002), (40, 8, 0.01, 0.02)])
def test_chunk_size_minimises_the_batch_time(n, workers, flight, overhead):
    # the batch-time model of chunk_size, minimised by brute force over every chunk size:
    # T(k) = n c / W + ceil(n / k) o / W + k c / 2; the closed form lands within one law of it
    from descent_fmus.synthesis.run.evaluation import chunk_size

    def T(k):
        return n * flight / workers + -(-n // k) * overhead / workers + k * flight / 2
    best = min(range(1, -(-n // workers) + 1), key=T)
    k = chunk_size(n, workers, flight, overhead)
    assert abs(k - best) <= 1 and T(k) <= 1.05 * T(best)
    # a scheduler that needs 5 ms per task keeps 64 workers of 10 ms laws busy only with >= 32
    assert chunk_size(4096, 64, 0.01, 0.001, dispatch=0.005) == 32
