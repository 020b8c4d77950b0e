"""``pareto.png`` drawn in a forked process while the laws are exported
(synthesis/run/report.py ``_draw_aside``).

Oracle: the same figure drawn in this process by ``plot_front`` (the route without an export):
the forked drawing must give the same PNG bytes, and a drawing process that fails must leave
the figure drawn here instead.
"""
from __future__ import annotations

import os
from types import SimpleNamespace

import pytest

from descent_fmus.synthesis.run import report

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")

PROBLEM = SimpleNamespace(name="toy", objective_names=["J1", "miss"], penalty=[1e6, 1e6],
                          labels=["J1", "miss (km)"])
ROWS = [{"J1": 1.0 + 0.1 * k, "miss": 2.0 / (1 + k)} for k in range(6)]
SUMMARY = {"basic_law": {"J1": 2.0, "miss": 3.0}}


def test_the_forked_figure_is_the_same_png(tmp_path):
    report.plot_front(PROBLEM, ROWS, SUMMARY, tmp_path / "here.png")
    report._draw_aside(PROBLEM, ROWS, SUMMARY, tmp_path / "aside.png")(True)
    here = (tmp_path / "here.png").read_bytes()
    assert len(here) > 1000
    assert (tmp_path / "aside.png").read_bytes() == here


def test_a_failed_drawing_process_is_drawn_here(tmp_path, monkeypatch):
    parent, real = os.getpid(), report.plot_front

    def plot(*args):                    # fails in the forked process only
        if os.getpid() != parent:
            raise RuntimeError("no display")
        real(*args)
    monkeypatch.setattr(report, "plot_front", plot)
    report._draw_aside(PROBLEM, ROWS, SUMMARY, tmp_path / "aside.png")(True)
    real(PROBLEM, ROWS, SUMMARY, tmp_path / "here.png")
    assert (tmp_path / "aside.png").read_bytes() == (tmp_path / "here.png").read_bytes()


def test_a_failed_export_ends_the_drawing(tmp_path, monkeypatch):
    parent = os.getpid()

    def plot(problem, rows, summary, path):
        if os.getpid() == parent:
            raise AssertionError("drawn here although the export failed")
        import time
        time.sleep(30)
        path.write_bytes(b"late")
    monkeypatch.setattr(report, "plot_front", plot)
    import time
    t0 = time.monotonic()
    report._draw_aside(PROBLEM, ROWS, SUMMARY, tmp_path / "aside.png")(False)
    assert time.monotonic() - t0 < 20.0          # ended, not waited for (it sleeps 30 s)
    assert not (tmp_path / "aside.png").exists()
