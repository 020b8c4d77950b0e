"""S5 command line: ``descent-fmus lunar-descent report`` (--json, --plot only when asked, user
errors as one line with exit code 2), ``synthesize lunar-descent`` with the problem's budget,
``info lunar-descent``, and an import of the system package that does no work."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law
from descent_fmus.synthesis.systems.lunar_descent.problems import LUNAR_DESCENT_RECIPE

ROOT = Path(__file__).resolve().parents[3]
REFERENCE_LAW = ROOT / "tests" / "reference" / "lunar_descent_law.json"


def _cli(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main", *args], cwd=cwd,
                          capture_output=True, text=True)


def _report(fmu_dir, *args, cwd=ROOT):
    return _cli("lunar-descent", "report", "--fmus", str(fmu_dir), *args, cwd=cwd)


def test_report_json_writes_no_file(fmu_dir, tmp_path):
    r = _report(fmu_dir, "--law", str(REFERENCE_LAW), "--samples", "8", "--json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["laws"]["synthesised"]["dispersion"]["n"] == 8
    # 211.48 m: the basic law's J1 (models/README.md, S5 basic law; also the evaluator test)
    assert out["laws"]["baseline"]["J1"] == pytest.approx(211.48, abs=0.01)
    assert np.isfinite(out["laws"]["synthesised"]["initial_set"]["fuel_max"])
    assert "plot" not in out and list(tmp_path.iterdir()) == []     # no --plot, no file


def test_report_plot_only_when_asked(fmu_dir, tmp_path):
    png = tmp_path / "report.png"
    r = _report(fmu_dir, "--law", str(REFERENCE_LAW), "--samples", "2", "--plot", str(png),
                cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert png.is_file() and [p.name for p in tmp_path.iterdir()] == ["report.png"]
    assert "synthesised" in r.stdout and "dispersion (2 samples, seed 7)" in r.stdout


def test_report_user_errors_are_one_line(fmu_dir, tmp_path):
    paper_basic_law().save(tmp_path / "one_output.json")
    for args, words in [(("--law", str(tmp_path / "one_output.json"), "--samples", "0"),
                         "4 inputs and drives 2 outputs"),
                        (("--law", str(tmp_path / "missing.json")), "cannot read law"),
                        (("--law", str(REFERENCE_LAW), "--samples", "-1"), "--samples must be"),
                        (("--law", str(REFERENCE_LAW), "--samples", "0", "--fmus",
                          str(tmp_path)), "FMU not found")]:
        r = _report(fmu_dir, *args)
        assert r.returncode == 2 and words in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_synthesize_cli_takes_the_problem_budget(fmu_dir, tmp_path):
    # options not given on the command line come from the problem's Budget (no CMA-ES on the
    # basic law here: the recipe's six searches of 8 000 laws are the run's first minutes)
    out = tmp_path / "run"
    r = _cli("synthesize", "lunar-descent", "--population", "6", "--generations", "0",
             "--refine-basis", "0", "--workers", "1", "--no-export", "--json", "--fmus",
             str(fmu_dir), "--out", str(out))
    assert r.returncode == 0, r.stderr
    run = json.loads((out / "run.json").read_text())
    ga = LUNAR_DESCENT_RECIPE["ga"]
    assert run["ga"]["population"] == 6 and run["seed"] == LUNAR_DESCENT_RECIPE["budget"].seed
    assert {k: run["ga"][k] for k in ("crossovers", "lchr", "epoch")} == \
        {k: getattr(ga, k) for k in ("crossovers", "lchr", "epoch")}
    assert json.loads(r.stdout)["laws_all_in_box"] >= 1     # the basic law reaches the box


def test_info_lists_the_parameters_with_units():
    r = _cli("info", "lunar-descent", "--json")
    assert r.returncode == 0, r.stderr
    fmus = {f["fmu"]: f for f in json.loads(r.stdout)["fmus"]}
    params = {p["name"]: p for p in fmus["LunarDescent"]["parameters"]}
    assert params["P0"]["unit"] == "kgf" and params["g0"]["unit"] == "m/s2"
    assert json.loads(r.stdout)["closed_loops"] == ["LunarDescentClosedLoop"]


def test_importing_the_system_does_no_work():
    # no solver, no plotting, no flights imported; no data file of the checkout read
    code = f"""
import sys
opened = []
sys.addaudithook(lambda ev, a: opened.append(str(a[0])) if ev == "open" else None)
import descent_fmus.synthesis.systems.lunar_descent as s
bad = [m for m in ("scipy.integrate", "matplotlib",
                   "descent_fmus.synthesis.systems.lunar_descent.study") if m in sys.modules]
bad += [f for f in opened if f.startswith({str(ROOT)!r}) and not f.endswith((".py", ".pyc"))]
assert not bad, bad
assert callable(s.SYSTEM.problems)
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
