"""A stop is a stop wherever it lands, and loses only the flights in progress.

Oracles: the uninterrupted run of the same seed (same Pareto set, byte for byte), the count of
laws the backend flew (an interrupted run plus its resume fly exactly the laws of one run:
nothing flown before the stop is flown again), and the signal semantics of
``synthesis.run.signals`` (a stop raised in the program's own code, never inside an FMU's).
"""
from __future__ import annotations

import io
import os
import signal
import sys
import time

import pytest

from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.run import backends, evaluation
from descent_fmus.synthesis.run.loop import run_synthesis
from descent_fmus.synthesis.run.signals import RECHECK_SECONDS, RunInterrupted, graceful_signals

# a small S1 whose basic solution's CMA-ES asks 24 laws a generation, flown 4 at a time
SMALL = dict(population=16, crossovers=4, lchr=4, epoch=2, generations=2, seed=3,
             refine_basis=72, refine_evals=24, refine_popsize=24, flights=160)


_FLY = backends.InProcess.fly


class _Counted:
    """InProcess.fly counting the laws it flies; raises a stop before the ``stop_at``-th."""

    def __init__(self, monkeypatch, stop_at=None):
        self.flown, self.stop_at = 0, stop_at
        real = _FLY

        def fly(backend, laws):
            if self.stop_at is not None and self.flown + len(laws) > self.stop_at:
                raise RunInterrupted(signal.SIGTERM)
            self.flown += len(laws)
            return real(backend, laws)
        monkeypatch.setattr(backends.InProcess, "fly", fly)


def _run(problem, out, fmu_dir, resume=False):
    return run_synthesis(problem, out, fmu_dir, workers=1, progress=False, export=False,
                         reference=False, resume=resume)


@pytest.mark.slow            # three small runs: ~10 s, 25 s on a busy machine
def test_a_stop_inside_a_cma_generation_loses_only_the_chunk_in_flight(fmu_dir, tmp_path,
                                                                      monkeypatch):
    monkeypatch.setattr(evaluation, "CHUNK_SECONDS", 0.0)       # chunks of 4 laws
    problem = get_problem("reentry").tuned(**SMALL)
    ref = _Counted(monkeypatch)
    whole = _run(problem, tmp_path / "ref", fmu_dir)
    # stopped in the middle of the basis CMA-ES's second generation (16 laws of the initial
    # population, 24 of the first generation, 8 of the second)
    cut = _Counted(monkeypatch, stop_at=16 + 24 + 8)
    with pytest.raises(RunInterrupted):
        _run(problem, tmp_path / "run", fmu_dir)
    assert 16 + 24 < cut.flown <= 48 and (tmp_path / "run" / "journal.jsonl").exists()
    rest = _Counted(monkeypatch)
    done = _run(problem, tmp_path / "run", fmu_dir, resume=True)
    assert (tmp_path / "run" / "pareto.csv").read_bytes() == \
        (tmp_path / "ref" / "pareto.csv").read_bytes()
    assert done["flights"] == whole["flights"]
    # nothing flown before the stop was flown again
    assert cut.flown + rest.flown == ref.flown
    assert not (tmp_path / "run" / "journal.jsonl").exists()    # the last checkpoint covers it


def test_a_signal_inside_an_fmus_python_code_is_raised_after_the_call():
    # a signal that lands while a pythonfmu slave's method runs (Python code reached through
    # an FMI call) must not raise there: it is raised once the method has returned
    from pythonfmu.fmi2slave import Fmi2Slave

    class Slave(Fmi2Slave):
        def do_step(self, t, dt):
            os.kill(os.getpid(), signal.SIGTERM)
            t0 = time.monotonic()
            try:
                while time.monotonic() - t0 < 10 * RECHECK_SECONDS:
                    pass                        # Python code: the handler runs in here
            except BaseException as exc:        # what pythonfmu would report as an FMU error
                self.raised = exc
            return True

    slave = object.__new__(Slave)                # no FMU instance needed: only the frames
    slave.raised = None
    with graceful_signals():
        with pytest.raises(RunInterrupted) as stop:
            assert slave.do_step(0.0, 1.0)
            t0 = time.monotonic()
            while time.monotonic() - t0 < 1.0:     # the program's own code: raised here
                pass
    assert slave.raised is None and stop.value.signum == signal.SIGTERM
    assert time.monotonic() - t0 < 0.5


def test_a_signal_in_the_programs_own_code_is_raised_at_once():
    t0 = time.monotonic()
    with graceful_signals():
        with pytest.raises(RunInterrupted):
            os.kill(os.getpid(), signal.SIGINT)
            while time.monotonic() - t0 < 1.0:
                pass
    assert time.monotonic() - t0 < 0.1


def test_the_resume_hint_repeats_the_program_as_launched(monkeypatch, tmp_path):
    from descent_fmus.synthesis.cli.main import launched_as
    script = tmp_path / "bin" / "descent-fmus"
    script.parent.mkdir()
    script.write_text("#!/bin/sh\n")
    script.chmod(0o755)
    args = ["synthesize", "reentry", "--out", "runs/x"]
    monkeypatch.setattr(sys, "argv", [str(script), *args])
    monkeypatch.setattr(sys, "orig_argv", ["/usr/bin/python3", str(script), *args])
    monkeypatch.setenv("PATH", str(tmp_path / "elsewhere"))
    assert launched_as() == str(script)                 # typed as a path: the same path
    monkeypatch.setenv("PATH", str(script.parent))
    assert launched_as() == "descent-fmus"              # found on the PATH: its name
    monkeypatch.setattr(sys, "argv", ["/site/descent_fmus/synthesis/cli/main.py", *args])
    monkeypatch.setattr(sys, "orig_argv", [".venv/bin/python", "-m",
                                           "descent_fmus.synthesis.cli.main", *args])
    assert launched_as() == ".venv/bin/python -m descent_fmus.synthesis.cli.main"


class _Terminal(io.StringIO):
    def isatty(self):
        return True


@pytest.mark.parametrize("stream", [io.StringIO, _Terminal], ids=["log file", "terminal"])
def test_a_waiting_phase_shows_its_clock(stream, monkeypatch):
    # oracle: the documented output of synthesis.run.progress -- plain lines only in a log, a
    # status line rewritten in place on a terminal, within a second of the phase's start
    from descent_fmus.synthesis.run import progress
    monkeypatch.setattr(progress, "PLAIN_SECONDS", 0.3)
    out = stream()
    console = progress.Console("reentry", stream=out)
    console.say("computing the problem's reference")
    time.sleep(1.0)
    # a bar's clock runs between its updates too (workers starting, a long batch)
    console.bar(None, "synthesize reentry", 100, 10, 0, 0)
    time.sleep(1.0)
    assert "0/100" in out.getvalue()
    console.close()
    text = out.getvalue()
    assert text.startswith("descent-fmus synthesize reentry: computing the problem's reference\n")
    if stream is _Terminal:
        assert "\rdescent-fmus synthesize reentry: computing the problem's reference ... " in text
    else:
        assert "\r" not in text and "\x1b" not in text
        assert "descent-fmus synthesize reentry: still computing the problem's reference (" \
            in text
    quiet = io.StringIO()
    progress.Console("reentry", enabled=False, stream=quiet).say("anything")
    assert quiet.getvalue() == ""


def test_the_journal_skips_a_line_a_stop_cut_short(tmp_path):
    # oracle: what was written -- two whole lines read back exactly, the cut one dropped
    from descent_fmus.synthesis.problems.contract import Outcome
    from descent_fmus.synthesis.run.folder import JOURNAL, RunFolder
    folder = RunFolder(tmp_path)
    a, b = Outcome((0.1, 2.5), 0.0, {"landed": True}), Outcome((1e300, -3.0), 0.25, {})
    folder.journal([(b"\x01" * 16, a), (b"\x02" * 16, b)])
    with open(tmp_path / JOURNAL, "a") as fh:
        fh.write('{"k": "0303030303030303030303030303030303", "f": [0.')     # cut short
    got = folder.journaled()
    assert [k for k, _ in got] == [b"\x01" * 16, b"\x02" * 16]
    assert [(o.f, o.cv, o.extras) for _, o in got] == [(a.f, a.cv, a.extras),
                                                       (b.f, b.cv, b.extras)]
