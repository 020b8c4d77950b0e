"""Bounded inputs and prompt exits: every size a user can give has a documented maximum (one-line
error, exit 2, nothing written), and SIGTERM ends a run in every phase within 2 s -- its process
group empty, exit code 143, the checkpoint valid and the resume hint printed.

Oracles: the documented maxima themselves (the settings dataclasses, synthesis/problems/limits.py,
synthesis/run/resources.py), the process table (/proc: which processes of the run's group are
alive), and the checkpoint that a resume reads.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from processes import cli, wait_empty

from descent_fmus.synthesis.methods.refinement import RefineConfig
from descent_fmus.synthesis.methods.settings import settings_of
from descent_fmus.synthesis.methods.ga_config import GAConfig
from descent_fmus.synthesis.problems.contract import Budget
from descent_fmus.synthesis.problems.limits import MAX_STATES, MAX_STEPS
from descent_fmus.synthesis.run.resources import MAX_WORKERS

ROOT = Path(__file__).resolve().parents[2]
TUTORIAL = ROOT / "docs" / "tutorials"
pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="reads the process table from /proc")


# -- sizes over their documented maxima: one line, exit 2, nothing written --------------------
SETTINGS = [(cls, s) for cls in (Budget, GAConfig, RefineConfig) for s in settings_of(cls)
            if s.maximum is not None and s.type is int]


@pytest.mark.parametrize("info", [s for _, s in SETTINGS], ids=[s.name for _, s in SETTINGS])
def test_every_size_setting_has_a_maximum_on_the_command_line(info, fmu_dir, tmp_path):
    prefix = "refine-" if info in [s for c, s in SETTINGS if c is RefineConfig] else ""
    flag = "--" + prefix + info.name.replace("_", "-")
    out = tmp_path / "out"
    r = subprocess.run(cli("synthesize", "reentry", flag, info.maximum + 1, "--out", out,
                            "--fmus", fmu_dir), capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and flag in r.stderr
    assert f"<= {info.maximum}" in r.stderr and not out.exists()


def test_workers_have_a_maximum(fmu_dir, tmp_path):
    r = subprocess.run(cli("synthesize", "reentry", "--workers", MAX_WORKERS + 1, "--out",
                            tmp_path / "out", "--fmus", fmu_dir),
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2 and f"<= {MAX_WORKERS}" in r.stderr
    assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def hopper(hopper_dir):
    """The tutorial's plant and its problem file's text."""
    return hopper_dir, (hopper_dir / "hopper.toml").read_text()


FILE_SIZES = [
    # (old text, new text, the key the message names, the maximum it states)
    ("population = 48", "population = 100000000", "ga.population", "5000"),
    ("seed = 1\n", "seed = 1\ngenerations = 100000000\n", "budget.generations", "10000000"),
    ("crossovers = 12", "crossovers = 10000000", "ga.crossovers", "10000"),
    ("samples = 6", "samples = 1000000000", "initial_states.samples", str(MAX_STATES)),
    ("step = 0.1", "step = 1e-9", "simulation", str(MAX_STEPS)),
    ("size = 14", "size = 1000000000", "basic_law.size", "1..32"),
    ("seed = 1\n", "seed = 1\nflights = 100000000000\n", "budget.flights", "10000000"),
    ("[ga]", "[refine]\nlaws = 100000\n[ga]", "refine.laws", "64"),
    ("lchr = 6", "lchr = 100000", "ga.lchr", "256"),
]


@pytest.mark.parametrize("old,new,key,most", FILE_SIZES, ids=[f[2] for f in FILE_SIZES])
def test_every_size_in_a_problem_file_has_a_maximum(hopper, fmu_dir, tmp_path, old, new, key,
                                                    most):
    d, text = hopper
    assert old in text, old
    (tmp_path / "Hopper.fmu").write_bytes((d / "Hopper.fmu").read_bytes())
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(old, new, 1))
    out = tmp_path / "out"
    t0 = time.perf_counter()
    r = subprocess.run(cli("synthesize", "--problem", bad, "--out", out, "--fmus", fmu_dir),
                       capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert key in r.stderr and most in r.stderr, r.stderr
    assert not out.exists()
    assert time.perf_counter() - t0 < 30          # refused before anything was built


def test_a_run_larger_than_the_machine_is_refused_before_it_starts(fmu_dir):
    # sizes within their maxima can still add up: the memory estimate is checked against the
    # machine's available memory (here a machine of 64 MiB) before anything is allocated
    from descent_fmus.synthesis.registry import get_problem
    from descent_fmus.synthesis.run.resources import ResourceLimitError, check_memory
    problem = get_problem("reentry").tuned(population=5000)
    with pytest.raises(ResourceLimitError, match="more than the 0.1 GiB"):
        check_memory(problem, 1, available=64 * 2 ** 20)
    assert sum(check_memory(get_problem("reentry"), 2, available=2 ** 34).values()) < 2 ** 30


# -- SIGTERM in every phase ----------------------------------------------------------------------
def _phase_run(args, phase: str, tmp_path, seconds: float = 240, inside: float = 0.3):
    """Start a run, wait for the line announcing ``phase`` (stderr), SIGTERM it ``inside``
    seconds later; the time until its process group is empty, its exit code and what it
    printed."""
    proc = subprocess.Popen(cli("synthesize", *args), cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env=dict(os.environ, PYTHONUNBUFFERED="1"))
    seen = []
    deadline = time.time() + seconds
    for line in proc.stderr:
        seen.append(line)
        if phase in line or time.time() > deadline:
            break
    assert proc.poll() is None, "".join(seen)[-2000:]
    assert any(phase in line for line in seen), "".join(seen)[-2000:]
    time.sleep(inside)                                # well inside the phase
    t0 = time.monotonic()
    os.killpg(proc.pid, signal.SIGTERM)
    left = wait_empty(proc.pid, 10.0)
    gone = time.monotonic() - t0
    rest = proc.stderr.read()
    proc.wait(10)
    return gone, left, proc.returncode, "".join(seen) + rest


SMALL = ["--population", "16", "--crossovers", "4", "--lchr", "4", "--epoch", "2", "--seed", "3"]


@pytest.mark.parametrize("phase,extra", [
    ("flying the initial population", ["reentry-robust", "--population", "400", "--workers",
                                       "2"]),
    ("refining parameters by CMA-ES", ["reentry", *SMALL, "--refine-basis", "4000",
                                       "--workers", "1"]),
    ("computing the problem's reference", ["reentry", *SMALL, "--generations", "1",
                                           "--refine-basis", "0", "--refine-evals", "0",
                                           "--workers", "2"]),
    # six Pareto laws with their closed loops: an export of about 0.9 s on a quiet 2-core
    # machine (the signal comes 0.1 s into it; two laws took 0.4 s, too close to 0.3 s)
    ("exporting", ["reentry", "--population", "64", "--crossovers", "16", "--lchr", "4",
                   "--epoch", "2", "--seed", "3", "--generations", "3", "--refine-basis", "0",
                   "--refine-evals", "0", "--no-reference", "--export", "all",
                   "--law-fmu", "python", "--workers", "1"]),
    ("starting a Dask LocalCluster", ["reentry", *SMALL, "--generations", "2",
                                      "--scheduler", "local", "--workers", "2"]),
], ids=["population", "refinement", "reference", "export", "dask"])
def test_sigterm_ends_every_phase_within_2_s(phase, extra, fmu_dir, tmp_path):
    out = tmp_path / "run"
    gone, left, code, err = _phase_run([*extra, "--out", out, "--fmus", fmu_dir], phase,
                                       tmp_path, inside=0.1 if phase == "exporting" else 0.3)
    assert not left and gone <= 2.0, f"{left} alive {gone:.2f} s after SIGTERM"
    assert code == 143, err[-2000:]
    last = err.strip().splitlines()[-1]
    assert "interrupted by SIGTERM" in last
    ck = out / "checkpoint.json"
    if ck.exists():                           # valid, and the hint continues the run
        state = json.loads(ck.read_text())
        assert state["simulated"] >= 1 and "--resume" in last
    else:
        assert "nothing to resume" in last and not (out / "run.json").exists()
    assert not list(out.glob("*.tmp")) if out.exists() else True


def test_a_run_stopped_while_refining_resumes_to_the_uninterrupted_result(fmu_dir, tmp_path):
    args = ["reentry", *SMALL, "--generations", "3", "--refine-basis", "300", "--refine-evals",
            "40", "--flights", "500", "--workers", "1", "--no-reference", "--no-export",
            "--fmus", fmu_dir]
    ref = subprocess.run(cli("synthesize", *args, "--out", tmp_path / "ref", "--quiet"),
                         cwd=ROOT, capture_output=True, text=True)
    assert ref.returncode == 0, ref.stderr
    out = tmp_path / "run"
    _, left, code, err = _phase_run([*args, "--out", out], "refining parameters", tmp_path)
    assert code == 143 and not left
    done = subprocess.run(cli("synthesize", *args, "--out", out, "--resume", "--quiet"),
                          cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert (out / "pareto.csv").read_text() == (tmp_path / "ref" / "pareto.csv").read_text()


def test_a_stop_inside_an_import_still_ends_as_a_stop(monkeypatch, capsys):
    # A SIGTERM handled while a C extension initialises (seen: matplotlib's ft2font imported to
    # plot the front) comes out as that module's ImportError raised from RunInterrupted: the
    # program still ends as a stopped run, 128 + 15 and its one line, not as a crash (exit 1)
    import argparse
    import signal

    from descent_fmus.synthesis.cli import main as cli
    from descent_fmus.synthesis.run.signals import RunInterrupted

    def func(args):
        try:
            raise RunInterrupted(signal.SIGTERM, "writing the results")
        except RunInterrupted as exc:
            raise ImportError("initialization failed") from exc

    class Parser:
        def parse_args(self, argv):
            return argparse.Namespace(command="synthesize", func=func)
    monkeypatch.setattr(cli, "build_parser", lambda: Parser())
    assert cli.main([]) == 143
    assert "interrupted by SIGTERM: writing the results" in capsys.readouterr().err


def test_a_stop_inside_ctypes_argument_conversion_still_ends_as_a_stop(tmp_path):
    # A SIGTERM handled while ctypes converts a call's arguments (seen: numpy's from_param of
    # the equivalence prober's matrix, in a fresh-clone CI run) comes out as ctypes'
    # ArgumentError, which names the stop only in its text: the guarded run turns it back into
    # the stop (exit 143 on the command line), as the same stop raised anywhere else
    import ctypes

    from descent_fmus.synthesis.run import signals
    from descent_fmus.synthesis.run.guard import guarded
    from descent_fmus.synthesis.run.signals import RunInterrupted

    def run(problem, out, fmu_dir, resume=False):
        signals._requested.append(signal.SIGTERM)       # the handler's record of the stop
        raise ctypes.ArgumentError("argument 4: RunInterrupted: interrupted by SIGTERM")

    with pytest.raises(RunInterrupted) as info:
        guarded(run)(None, tmp_path / "run", None)
    assert info.value.exit_code == 143

    def broken(problem, out, fmu_dir, resume=False):   # no stop asked: ctypes' error stays
        raise ctypes.ArgumentError("argument 1: wrong type")
    with pytest.raises(ctypes.ArgumentError):
        guarded(broken)(None, tmp_path / "run2", None)


def test_a_stop_that_cut_an_import_short_says_where_the_run_stands(tmp_path):
    # A SIGTERM that lands inside a lazy import (seen in a fresh-clone CI run while the
    # reference was computed) comes out as an ImportError caused by the stop.  The guarded run
    # reports the stop itself, with where the checkpoint stands and that it can be resumed --
    # not the bare stop the command line would otherwise dig out of the ImportError
    import json

    from descent_fmus.synthesis.run.guard import guarded
    from descent_fmus.synthesis.run.signals import RunInterrupted

    out = tmp_path / "run"

    def run(problem, out, fmu_dir, resume=False):
        out.mkdir()
        (out / "checkpoint.json").write_text(json.dumps({"generation": 3, "simulated": 30}))
        try:
            raise RunInterrupted(signal.SIGTERM)
        except RunInterrupted as stop:
            raise ImportError("cannot import name 'minimize'") from stop

    with pytest.raises(RunInterrupted) as info:
        guarded(run)(None, out, None)
    assert info.value.resumable and "generation 3" in info.value.where
    assert info.value.exit_code == 143
