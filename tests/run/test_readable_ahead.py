"""The readable forms computed while the search runs (synthesis/run/readable_ahead.py).

Oracle: each law's readable form computed alone in this process (``law.readable().to_dict()``,
the report's own route); the watcher -- a forked process reading the run's checkpoint -- must
keep exactly those dictionaries in the cache folder, where the report then finds them without
computing anything.
"""
from __future__ import annotations

import os
import time

import numpy as np
import pytest

from descent_fmus.synthesis.fmi import law_files
from descent_fmus.synthesis.methods.base import Candidate
from descent_fmus.synthesis.methods.pareto import ParetoArchive
from descent_fmus.synthesis.run import readable_ahead
from descent_fmus.synthesis.run.folder import write_json
from descent_fmus.synthesis.cli.synthesize import _archive_laws
from descent_fmus.synthesis.run.loop import archive_state

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")


def _laws(n: int) -> list:
    from descent_fmus.synthesis.registry import get_problem
    base = get_problem("reentry").basic()
    out = []
    for k in range(n):
        d = base.to_dict(formula=False)
        d["q"] = [v * (1.0 + 0.5 * k) + 0.25 * k for v in d["q"]]
        out.append(type(base).from_dict(d))
    return out


def _checkpoint(path, laws) -> None:
    archive = ParetoArchive()
    archive.items = [(Candidate(law, {}), np.array([float(k), -float(k)]), 0.0)
                     for k, law in enumerate(laws)]
    write_json(path / "checkpoint.json", {"archive": archive_state(archive)}, indent=None)


def _wait_for(folder, n: int, seconds: float = 60.0) -> list:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        kept = sorted(folder.glob("*.json"))
        if len(kept) >= n:
            return kept
        time.sleep(0.1)
    return sorted(folder.glob("*.json"))


def test_the_watcher_keeps_each_new_checkpoints_forms(tmp_path, monkeypatch):
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(law_files, "_READABLE", {})
    monkeypatch.setattr(readable_ahead, "NICE", 0)     # not starved by a busy test machine
    run = tmp_path / "run"
    run.mkdir()
    laws = _laws(3)
    alone = [law.readable().to_dict() for law in laws]
    folder = law_files._readable_folder()
    process = readable_ahead.start(run, _archive_laws)
    try:
        assert process is not None and process.is_alive()
        _checkpoint(run, laws[:2])
        assert len(_wait_for(folder, 2)) == 2
        time.sleep(0.05)                               # a later checkpoint: one more law
        _checkpoint(run, laws)
        assert len(_wait_for(folder, 3)) == 3
    finally:
        readable_ahead.stop()
    assert not process.is_alive()

    def compute(law):
        raise AssertionError("computed although the watcher kept it")
    monkeypatch.setattr(law_files, "_compute_readable", compute)
    law_files.prefetch_readable(laws, processes=2)
    assert [law_files.law_document(law)["readable"] for law in laws] == alone
    assert not list(folder.glob(".*.tmp"))            # no half-written form left


def test_a_form_sympy_did_not_make_is_left_to_the_report(tmp_path, monkeypatch):
    # a form past the time limit in the low-priority watcher (a busy machine) must not stand
    # in for SymPy's: the report computes it as before (oracle: law.readable(), alone)
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(law_files, "_READABLE", {})
    monkeypatch.setattr(readable_ahead, "NICE", 0)
    laws = _laws(2)
    alone = [law.readable().to_dict() for law in laws]
    slow = law_files._law_key(laws[0])
    real = law_files._compute_readable

    def compute(law):                                  # what the watcher meets (forked copy)
        if law_files._law_key(law) == slow:
            return {"text": law.formula(6), "error": "ReadableTimeout: SymPy took over 3 s"}
        return real(law)
    monkeypatch.setattr(law_files, "_compute_readable", compute)
    folder = law_files._readable_folder()
    readable_ahead.start(tmp_path, _archive_laws)
    try:
        _checkpoint(tmp_path, laws)
        assert len(_wait_for(folder, 1)) == 1
        time.sleep(0.5)                                # time for a wrong second file
    finally:
        readable_ahead.stop()
    assert [p.stem for p in folder.glob("*.json")] == [law_files._law_key(laws[1])]
    monkeypatch.setattr(law_files, "_compute_readable", real)
    law_files.prefetch_readable(laws, processes=1)
    assert [law_files.law_document(law)["readable"] for law in laws] == alone


def test_stop_ends_a_watcher_with_nothing_to_do(tmp_path, monkeypatch):
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path / "cache"))
    process = readable_ahead.start(tmp_path, _archive_laws)   # no checkpoint appears
    assert process is not None
    t0 = time.monotonic()
    readable_ahead.stop()
    assert not process.is_alive()
    assert time.monotonic() - t0 < 2.0                # it leaves at once on the stop
    assert readable_ahead._RUNNING == []
