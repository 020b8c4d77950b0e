"""A synthesis run (problem `reentry`): the evaluator's numbers come from the FMUs; runs resume;
bad input.  Oracles: plain closed-loop flights (synthesis.systems.reentry.flight) and fmpy's own
simulation of the exported closed-loop FMUs."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu

from descent_fmus.synthesis.run.evaluation import Evaluator, SchedulerError
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.registry import UnknownProblemError, get_problem
from descent_fmus.synthesis.run.loop import RunDirError, run_synthesis
from descent_fmus.synthesis.systems.reentry.flight import fly
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law, paper_law

ROOT = Path(__file__).resolve().parents[2]
SMALL = dict(population=16, crossovers=6, lchr=4, epoch=3, elite_trim=2)
REENTRY = get_problem("reentry")


def test_evaluator_equals_an_fmpy_run(fmu_dir):
    # the evaluator is built from FMU paths alone; its objectives equal a plain closed-loop run
    laws = [paper_basic_law(), paper_law(),
            get_problem("reentry").basic()]
    with Evaluator(REENTRY, fmu_dir) as ev:
        ev_ = ev.evaluate(laws + laws)               # duplicates are not simulated twice
        F = ev_.F
        assert ev.simulated == 3 and ev_.flown == 3
    for law, f in zip(laws, F):
        o = fly(law, fmu_dir=fmu_dir).objectives
        assert f[0] == o["J1"] and f[1] == o["J2"]


def test_fmu_error_costs_one_candidate(fmu_dir):
    bad = paper_basic_law()
    bad.psi[0, 4] = 99            # bypasses validation: the FMU itself must reject it
    good = paper_basic_law()
    with Evaluator(REENTRY, fmu_dir) as ev:
        res = ev.evaluate([bad, good])
        F, extras = res.F, res.extras
        assert ev.failures == 1
    prob = get_problem("reentry")
    assert tuple(F[0]) == prob.penalty and extras[0]["failed"] is True
    assert "unknown unary operation 99" in extras[0]["error"]
    assert F[1][0] == pytest.approx(fly(good, fmu_dir=fmu_dir).objectives["J1"], rel=1e-15)


def test_local_pool_equals_in_process(fmu_dir):
    rng = np.random.default_rng(3)
    laws = [paper_basic_law(q=rng.uniform(0, 8, 2)) for _ in range(6)]
    with Evaluator(REENTRY, fmu_dir) as ev1, Evaluator(REENTRY, fmu_dir, workers=2) as ev2, \
            Evaluator(REENTRY, fmu_dir, workers=2) as ev3:
        ev2.backend.small_batch = 0                   # these 6 laws go to the workers
        assert np.array_equal(ev1.evaluate(laws).F, ev2.evaluate(laws).F)
        assert ev2.backend.worker_pids() and ev2.backend._here is None
        # a small batch is flown in the parent (SMALL_BATCH) by its own flyer: the same
        # outcomes (the workers are forked when the pool starts, so they exist either way)
        assert np.array_equal(ev1.evaluate(laws).F, ev3.evaluate(laws).F)
        assert ev3.backend._here is not None


def test_small_batch_in_two_threads_equals_one_thread(fmu_dir):
    # a small batch flown in the parent goes in two threads (HERE_THREADS = 2: the second half
    # of the packed flights by a second C master in a helper thread, the GIL released in
    # each C call); oracle: the same laws flown one by one in one thread
    # (InProcess) -- every outcome bit for bit, in order, a failing law (the FMU rejects its
    # operation) in each half included, the flights after it flown; and the parent's
    # one-thread path
    from descent_fmus.synthesis.run.backends import HERE_THREADS
    rng = np.random.default_rng(7)
    laws = [paper_basic_law(q=rng.uniform(0, 8, 2)) for _ in range(7)]
    for k in (1, 5):                                  # one in each half (3 + 4 flights)
        laws[k].psi[0, 4] = 99                        # bypasses validation: the FMU rejects it
    with Evaluator(REENTRY, fmu_dir) as ev1:
        one = [ev1.backend.flyer.fly(law) for law in laws]
    with Evaluator(REENTRY, fmu_dir, workers=2) as ev2, \
            Evaluator(REENTRY, fmu_dir, workers=2) as ev3:
        assert ev2.backend.here_threads == HERE_THREADS == 2
        assert len(laws) <= ev2.backend.small_batch
        two = ev2.backend.fly(laws)
        loop = ev2.backend._here.loop
        assert loop._twin is not None and loop.twin_flights == 4    # the twin flew its half
        ev3.backend.here_threads = 1                  # the one-thread path of the parent
        assert ev3.backend.fly(laws) == two
        assert ev3.backend._here.loop._twin is None
    for k in (1, 5):
        assert two[k][0] is None and "unknown unary operation 99" in two[k][1]
    assert all(two[k][0] is not None for k in (0, 2, 3, 4, 6))
    assert repr(one) == repr(two)                     # floats' repr: exact to the bit
    assert loop._twin is None and not Path(loop._tmp).exists()      # closed with its loop


def test_a_second_master_that_cannot_open_leaves_one_thread(fmu_dir, monkeypatch):
    # the split's second C master fails to load (here: the FMUs' extraction raises, as a full
    # disk would): split() says so, its folder goes, and the parent flies its small batches in
    # one thread with the same outcomes (oracle: an evaluator whose split worked)
    from descent_fmus.synthesis.fmi.c_master_loop import CMasterLoop
    from descent_fmus.synthesis.fmi.slave import FMUError
    rng = np.random.default_rng(3)
    laws = [paper_basic_law(q=rng.uniform(0, 8, 2)) for _ in range(5)]
    with Evaluator(REENTRY, fmu_dir, workers=2) as ev1:
        want = ev1.backend.fly(laws)
        assert ev1.backend._here.loop._twin is not None
    opened = CMasterLoop._master

    def refuse(self, folder):
        if folder.endswith("twin"):
            os.makedirs(folder, exist_ok=True)      # a half-extracted folder is left behind
            raise FMUError("no room to extract the FMUs")
        return opened(self, folder)

    monkeypatch.setattr(CMasterLoop, "_master", refuse)
    with Evaluator(REENTRY, fmu_dir, workers=2) as ev2:
        got = ev2.backend.fly(laws)
        loop = ev2.backend._here.loop
        assert loop._twin is None and loop._helper is None
        assert not Path(loop._tmp, "twin").exists()
        assert loop.split() is False and loop.twin_seconds == 0.0 == loop.twin_flights
    assert repr(got) == repr(want)                    # floats' repr: exact to the bit


def test_local_worker_death_costs_no_candidate(fmu_dir):
    # a worker process of the local pool dies between batches: the batch fails with a broken
    # pool, a fresh pool is started and the candidates are retried -- same numbers, no penalty
    rng = np.random.default_rng(5)
    laws = [paper_basic_law(q=rng.uniform(0, 8, 2)) for _ in range(6)]
    with Evaluator(REENTRY, fmu_dir) as ev1:
        F_ref = ev1.evaluate(laws).F
    with Evaluator(REENTRY, fmu_dir, workers=2) as ev:
        ev.backend.small_batch = 0                # small batches to the workers too
        ev.evaluate([paper_basic_law()])          # start the workers
        pids = ev.backend.worker_pids()
        assert pids
        for pid in pids:
            os.kill(pid, signal.SIGKILL)
        time.sleep(0.5)
        F = ev.evaluate(laws).F
        assert ev.backend.worker_pids() - pids            # the broken pool was replaced
        assert ev.failures == 0
    assert np.array_equal(F, F_ref)


def _run(out, fmu_dir, generations=6, seed=11, **kw):
    kw.setdefault("reference", False)
    problem = REENTRY.tuned(**SMALL, generations=generations, seed=seed, refine_evals=0,
                            refine_basis=0, flights=0, basis_rule="compromise")
    return run_synthesis(problem, out, fmu_dir, progress=False, **kw)


def test_interrupted_run_resumes_to_the_same_result(fmu_dir, tmp_path):
    full = _run(tmp_path / "full", fmu_dir, export=False)
    part = _run(tmp_path / "part", fmu_dir, export=False, stop_after=2)
    assert part["interrupted"]
    ck = json.loads((tmp_path / "part" / "checkpoint.json").read_text())
    assert ck["generation"] == 2
    done = _run(tmp_path / "part", fmu_dir, export=False, resume=True)
    assert (tmp_path / "full" / "pareto.csv").read_text() == \
        (tmp_path / "part" / "pareto.csv").read_text()
    assert done["generations"] == full["generations"] == 6
    # a run folder whose logs are shorter than its checkpoint says is refused in one line
    # (nothing resumed from a half): the flown fingerprints, then the outcomes by behaviour
    for name in ("behaviour.jsonl", "flown.bin"):
        log = tmp_path / "part" / name
        assert log.stat().st_size > 0, name
        log.write_bytes(log.read_bytes()[:-3])
        with pytest.raises(RunDirError, match=f"{name}.*run folder was altered"):
            _run(tmp_path / "part", fmu_dir, export=False, resume=True)


@pytest.mark.parametrize("budget", [("--generations", "60"),
                                    ("--generations", "1000", "--flights", "1500")],
                         ids=["generations", "flights"])
@pytest.mark.slow            # two CLI runs per case (~15 s)
def test_killed_cli_run_resumes(fmu_dir, tmp_path, budget):
    # a real SIGKILL in the middle of a CLI run (checkpoints at most a second apart, at
    # generation and phase boundaries): resume finishes with the same Pareto set as an
    # uninterrupted run of the same seed, whether the budget counts generations or flights.
    # The budgets are a few seconds of search (small batches fly in the main process: ten
    # generations took under 3 s, and a run of them could end between two checkpoints a second
    # apart before the kill arrived)
    args = [sys.executable, "-m", "descent_fmus.synthesis.cli.main", "synthesize", "reentry",
            "--population", "16", *budget, "--crossovers", "6", "--lchr", "4", "--epoch", "3",
            "--seed", "4", "--workers", "1", "--quiet", "--no-export", "--no-reference",
            "--refine-evals", "20", "--refine-basis", "0", "--fmus", str(fmu_dir)]
    ref = subprocess.run(args + ["--out", str(tmp_path / "ref")], cwd=ROOT,
                         capture_output=True, text=True)
    assert ref.returncode == 0, ref.stderr[-4000:]
    out = tmp_path / "killed"
    proc = subprocess.Popen(args + ["--out", str(out)], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    gen = -1
    while time.time() < deadline and proc.poll() is None:
        try:
            gen = json.loads((out / "checkpoint.json").read_text())["generation"]
        except (OSError, ValueError, KeyError):
            gen = -1
        if gen >= 3:
            break
        time.sleep(0.02)
    assert proc.poll() is None, "the run finished before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not (out / "pareto.csv").exists()
    res = subprocess.run(args + ["--out", str(out), "--resume", "--json"], cwd=ROOT,
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    ref_summary = json.loads((tmp_path / "ref" / "summary.json").read_text())
    done = json.loads(res.stdout)
    assert done["generations"] == ref_summary["generations"]
    assert done["flights"] == ref_summary["flights"]
    if budget[0:2] == ("--generations", "60"):
        assert done["generations"] == 60
    else:                                           # the flight budget ended the run
        assert done["flights"] >= 1500 and done["generations"] < 1000
    assert (out / "pareto.csv").read_text() == (tmp_path / "ref" / "pareto.csv").read_text()


def test_exported_law_reproduces_its_pareto_row(fmu_dir, tmp_path):
    # the GA's numbers come from the FMUs: an exported law's closed-loop FMU, run by fmpy
    # simulate, reproduces the J1 and miss of its row in pareto.csv
    assert REENTRY.input_scaling == "auto"
    s = _run(tmp_path / "run", fmu_dir, generations=3)
    scaling = json.loads((tmp_path / "run" / "scaling.json").read_text())
    # derived from the paper's basic law (written in 10 y1, 2 y2): where it acts unsaturated
    # on the default entry, y1 > 0 and y2 < 0 (the flight's deviations from the line), with
    # finite positive scales
    assert REENTRY.basic().input_offset == [0.0, 0.0]
    assert scaling["offset"][0] > 0.0 > scaling["offset"][1]
    assert all(0 < v < 1e4 for v in scaling["scale"])
    assert s["input_scaling"]["offset"] == scaling["offset"]
    rows = s["pareto"]
    assert rows and (tmp_path / "run" / "pareto.png").stat().st_size > 1000
    for r in rows[:3]:
        res = simulate_fmu(r["closed_loop_fmu"], output=["L", "load_max", "status"])
        last = res[-1]
        assert last["load_max"] == pytest.approx(r["J1"], rel=1e-12)
        if last["status"] == 1:
            assert abs(last["L"] - 1_400_000.0) == pytest.approx(r["J2"], rel=1e-9, abs=1e-6)
        law = NetworkOperator.load(Path(r["closed_loop_fmu"]).parent / "law.json")
        assert law.formula(6) == r["formula"]
        # S1 derives its input coordinates from the basic law's flights: the run records them,
        # and the law file (so the exported FMU, which reproduced the row above) carries them
        assert list(law.input_offset) == pytest.approx(scaling["offset"], rel=0, abs=0)
        assert list(law.input_scale) == pytest.approx(scaling["scale"], rel=0, abs=0)


def test_bad_input(fmu_dir, tmp_path):
    with pytest.raises(UnknownProblemError, match="unknown synthesis problem 'mars-orbit'"):
        get_problem("mars-orbit")
    with pytest.raises(SchedulerError, match="cannot reach the Dask scheduler"):
        Evaluator(REENTRY, fmu_dir, scheduler="tcp://127.0.0.1:9", connect_timeout=1.0)
    d = tmp_path / "other"
    d.mkdir()
    (d / "notes.txt").write_text("keep me")
    with pytest.raises(RunDirError, match="not empty"):
        _run(d, fmu_dir, generations=1)
    assert (d / "notes.txt").read_text() == "keep me"
    _run(tmp_path / "a", fmu_dir, generations=1, export=False)
    with pytest.raises(RunDirError, match="already holds a run"):
        _run(tmp_path / "a", fmu_dir, generations=1)
    with pytest.raises(RunDirError, match="different run"):
        _run(tmp_path / "a", fmu_dir, generations=2, seed=12, resume=True)
    with pytest.raises(RunDirError, match="no run to resume"):
        _run(tmp_path / "nothing", fmu_dir, resume=True)


def test_cli_messages(fmu_dir, tmp_path):
    def cli(*a):
        return subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main", *a], cwd=ROOT,
                              capture_output=True, text=True)
    r = cli("synthesize", "nowhere", "--out", str(tmp_path / "x"))
    assert r.returncode == 2 and "unknown synthesis problem 'nowhere'" in r.stderr
    bad = tmp_path / "bad.json"
    bad.write_text('{"psi": [[0, 1], [0, 0]], "nx": 1, "q": [], "outputs": [5]}')
    r = cli("reentry", "fly", "--law", str(bad), "--fmus", str(fmu_dir))
    assert r.returncode == 2 and "output 1 names node 5, outside 1..2" in r.stderr
    r = cli("reentry", "fly", "--fmus", str(tmp_path / "nowhere"))
    assert r.returncode == 2 and "FMU not found" in r.stderr and "build_fmus.py" in r.stderr
    assert "Traceback" not in r.stderr
    r = cli("reentry", "fly", "--fmus", str(fmu_dir), "--plot", str(tmp_path / "no" / "x.png"))
    assert r.returncode == 2 and "No such file or directory" in r.stderr
    r = cli("synthesize", "reentry", "--scheduler", "tcp://127.0.0.1:9", "--out",
            str(tmp_path / "y"), "--fmus", str(fmu_dir), "--generations", "1")
    assert r.returncode == 2 and "cannot reach the Dask scheduler" in r.stderr
