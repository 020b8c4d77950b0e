"""S1 fixed-structure CMA-ES baselines (``synthesize reentry --method cma-*``) through the FMUs.

Oracles: the paper's basic law flown directly (its J1 = 8.820 true peak, 5068 m miss), fmpy's
own ``simulate_fmu`` of the exported closed-loop FMU, and an uninterrupted run (resume).
"""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from fmpy import simulate_fmu

from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.methods.registry import method_names
from descent_fmus.synthesis.run.loop import run_synthesis
from descent_fmus.synthesis.systems.reentry.flight import fly, load_loop
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law

REENTRY = get_problem("reentry-window")
TINY = dict(population=8, generations=0, crossovers=2, lchr=2, epoch=2)


def test_baselines_are_laws_of_the_generic_controller(fmu_dir):
    assert method_names(REENTRY) == ["network-operator", "cma-basic", "cma-polynomial", "cma-tanh",
                                     "gp"]
    structures = REENTRY.baselines()
    with load_loop(fmu_dir) as loop:
        flights = {n: fly(law, loop=loop).objectives for n, law in structures.items()}
        paper = fly(paper_basic_law(), loop=loop).objectives
        own = fly(REENTRY.basic(), loop=loop).objectives
    # the basic-law and polynomial baselines start at the paper's basic law (the polynomial's
    # linear coefficients are q1/10, q2/2 on the inputs 10 y1, 2 y2): the same flight
    for name in ("basic", "polynomial"):
        assert flights[name]["J1"] == pytest.approx(paper["J1"], rel=1e-9)
        assert flights[name]["J2"] == pytest.approx(paper["J2"], rel=1e-6)
    assert paper["J1"] == pytest.approx(8.820, abs=1e-3)
    # the GA's basic solution is the polynomial's structure on 32 nodes (spare nodes) in the
    # window inputs 100 (y1 - 0.19), 10 (y2 + 0.25), at the paper's basic law: the same flight
    # (the same function: q1 y1 + q2 y2 = -0.059 + (q1/100) w1 + (q2/10) w2, closed form)
    basic = REENTRY.basic()
    poly = structures["polynomial"]
    assert basic.size == 32 and np.array_equal(basic.psi[:poly.size - 1, :poly.size - 1],
                                               poly.psi[:poly.size - 1, :poly.size - 1])
    assert basic.input_offset == [0.19, -0.25] and basic.input_scale == [100.0, 10.0]
    assert basic.q[0] == pytest.approx(2.259375 * 0.19 - 1.953125 * 0.25, rel=1e-15)
    assert own["J1"] == pytest.approx(paper["J1"], rel=1e-9)
    assert own["J2"] == pytest.approx(paper["J2"], rel=1e-6)


def test_baseline_run_exports_laws_that_replay_under_fmpy(fmu_dir, tmp_path):
    s = run_synthesis(REENTRY.tuned(**TINY, seed=1, flights=20), tmp_path / "poly", fmu_dir,
                      progress=False, reference=False, method="cma-polynomial")
    assert s["method"] == "cma-polynomial" and s["evaluations"] >= 20 and s["failures"] == 0
    rows = json.loads((tmp_path / "poly" / "pareto.json").read_text())
    assert rows and all(r["law"]["formula"] == NetworkOperator.from_dict(r["law"]).formula()
                        for r in rows)
    r = rows[0]
    res = simulate_fmu(r["closed_loop_fmu"], output=["L", "load_max", "status"])
    assert res[-1]["status"] == 1
    assert res[-1]["load_max"] == pytest.approx(r["J1"], rel=1e-12)
    assert abs(res[-1]["L"] - REENTRY.initial_states[0]["Lf"]) == pytest.approx(r["J2"],
                                                                                   abs=1e-6)


def test_baseline_run_resumes_to_the_uninterrupted_result(fmu_dir, tmp_path):
    problem = REENTRY.tuned(**TINY, seed=4, flights=40)
    a = run_synthesis(problem, tmp_path / "a", fmu_dir, progress=False, export=False,
                      reference=False, method="cma-tanh")
    cut = run_synthesis(problem, tmp_path / "b", fmu_dir, progress=False, export=False,
                        reference=False, method="cma-tanh", stop_after=2)
    assert cut["interrupted"]
    b = run_synthesis(problem, tmp_path / "b", fmu_dir, progress=False, export=False,
                      reference=False, method="cma-tanh", resume=True)
    key = lambda r: (r["J1"], r["J2"], r["formula"])  # noqa: E731
    assert [key(r) for r in a["pareto"]] == [key(r) for r in b["pareto"]]
    assert [list(c) for c in a["curve"]] == [list(c) for c in b["curve"]]


def test_unknown_method_is_a_one_line_error(fmu_dir, tmp_path):
    r = subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main", "synthesize",
                        "reentry", "--method", "cma-nope", "--out", str(tmp_path / "x"),
                        "--fmus", str(fmu_dir)], capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "unknown method 'cma-nope'" in r.stderr
    assert "cma-polynomial" in r.stderr and not (tmp_path / "x").exists()
