"""benchmarks/suite/epochs.py: the epoch log of a run folder read from its checkpoint, the
learning curve's value at flight marks, and a folder that is not a run (exit 2)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

SUITE = Path(__file__).resolve().parents[2] / "benchmarks" / "suite"
sys.path.insert(0, str(SUITE))

import epochs  # noqa: E402


def _row(gen, best, children, accepted, islands=0):
    return {"gen": gen, "evals": 100 * gen, "best": best, "forms": 5, "share_best": 0.5,
            "dist": 1.0, "children": children, "accepted": accepted, "restarts": islands,
            "islands": islands}


def test_epochs_reads_the_log_and_the_curve(tmp_path, capsys):
    log = [_row(10, 0.5, 40, 10), _row(20, 0.25, 40, 20, 1)]
    (tmp_path / "checkpoint.json").write_text(json.dumps(
        {"method": {"stats": {"epochs": log, "restarts": 1}},
         "curve": [[100, 1.0], [500, 0.5], [900, 0.25]]}))
    r = epochs.read(tmp_path)
    assert r["epochs"] == log and r["stats"] == {"restarts": 1}
    # the best value after at most N flights (the curve's points, hand read)
    assert [epochs.value_at(r["curve"], n) for n in (50, 100, 899, 900, 5000)] == \
        [None, 1.0, 0.5, 0.25, 0.25]
    epochs.main([str(tmp_path), "--marks", "500"])
    out = capsys.readouterr().out
    assert "900 flights, best 0.25; at 500: 0.5" in out
    assert " 25.0 " in out and " 50.0 " in out           # accepted / children per epoch, %


def test_a_folder_without_a_run_is_one_line_and_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        epochs.main([str(tmp_path)])
    assert e.value.code == 2
    assert capsys.readouterr().err.count("\n") == 1
