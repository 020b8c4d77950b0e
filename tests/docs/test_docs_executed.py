"""The docs are executed: the README's commands (its first lines and the tour) and every command
block of docs/tutorials/*.md run as written in a scratch copy of the repository
(tests/docs/docs_run.py; the few substitutions are listed there with their reasons), and the figures
the text marks (``<!-- check: KEY -->``) are compared with what those commands printed or wrote.

Oracle: the commands themselves -- a seeded, deterministic run; a quoted figure must be the
measured value rounded to the digits it shows (tolerance half a unit of its last digit).
Durations (``<!-- time: KEY -->``) are never asserted (the tests time nothing: benchmarks/ does);
their key must name a phase the run reports, and the measured values are printed.

The README's main job runs once per session (about a minute on 2 quiet cores) in a fresh cache
folder, so that the tour's ``reentry bound`` shows that it reads the bound the job cached.
"""
from __future__ import annotations

import csv
import json
import math
import os
import re
import tomllib
import zipfile
from pathlib import Path

import pytest

from docs_run import (ROOT, SUBSTITUTED, command_lines, left_behind, parts, quoted_figures,
                      run_env, run_page, scratch_copy)

README = ROOT / "README.md"
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("*.md"))
MAIN_JOB = ".venv/bin/descent-fmus synthesize reentry --out runs/reentry"
BOUND = ".venv/bin/descent-fmus reentry bound"


@pytest.fixture(scope="session")
def scratch(tmp_path_factory, fmu_dir):
    """A scratch copy of the checkout and the environment its commands run in."""
    base = tmp_path_factory.mktemp("docs-executed")
    where = scratch_copy(base / "repo", fmu_dir)
    return where, run_env(base / "cache")


@pytest.fixture(scope="session")
def readme_run(scratch):
    where, env = scratch
    return where, run_page(README, where, env), env["DESCENT_FMUS_CACHE"]


@pytest.fixture(scope="session")
def tutorial_runs(scratch):
    where, env = scratch
    return where, {page.name: run_page(page, where, env) for page in TUTORIALS}


def _failures(results) -> list:
    return [f"{r.command}\n  exit {r.returncode}: {r.stderr.strip()[-1500:]}"
            for r in results.values() if r.returncode != 0]


def test_every_substitution_still_names_a_documented_command():
    documented = {p for page in [README, *TUTORIALS] for line in command_lines(page)
                  for p in parts(line)}
    missing = [c for c in SUBSTITUTED if c not in documented]
    assert not missing, f"substitutions for commands no page gives any more: {missing}"
    assert MAIN_JOB in documented and BOUND in documented


def test_figure_markers_parse(tmp_path):
    # the marker grammar of docs_run.quoted_figures on made-up text: value, digits, unit
    page = tmp_path / "markers.md"
    page.write_text("J1 = 8.2705<!-- check: a --> and **1.00016<!-- check: b --> ×**; "
                    "20 000 flights<!-- check: c -->, −0.17 mm/s<!-- check: d -->, "
                    "48 s<!-- time: wall -->\n")
    got = [(f.kind, f.key, f.value, f.decimals, f.unit) for f in quoted_figures(page)]
    assert got == [("check", "a", 8.2705, 4, ""), ("check", "b", 1.00016, 5, ""),
                   ("check", "c", 20000.0, 0, "flights"), ("check", "d", -0.17, 2, "mm/s"),
                   ("time", "wall", 48.0, 0, "s")]


# ---- the README -------------------------------------------------------------------------------

def _readme_measured(where: Path, results) -> tuple[dict, dict]:
    """{check key: value} and {time key: seconds} of the README's runs."""
    s = json.loads((where / "runs" / "reentry" / "summary.json").read_text())
    best = s["best_miss_below_1km"]
    checks = {"reentry.flights": s["simulated"], "reentry.best_J1": best["J1"],
              "reentry.ratio": s["ratio_to_bound"], "reentry.bound_1km": s["bound_J1"],
              "reentry.bound_zero": s["bound_J1_zero_miss"],
              "reentry.basic_J1": s["basic_law"]["J1"],
              "reentry.basic_miss_km": s["basic_law"]["J2"] / 1000}
    t = s["timings"]
    times = {"reentry.wall": results[MAIN_JOB].seconds, "reentry.seconds": s["seconds"],
             "reentry.search": t["search"],
             "reentry.export": t["export"], "reentry.report": t["report"],
             "reentry.checkpoints": t["checkpoints"],
             "reentry.bound": t["reference"]}
    return checks, times


def _print_durations(capsys, figures, times) -> None:
    """The quoted durations beside this run's (printed, never asserted: see the docstring)."""
    with capsys.disabled():
        print("\n" + "\n".join(f"  {page.name}:{f.line} quotes {f.text} {f.unit} for {f.key}; "
                               f"this run: {times[f.key]:.1f} s" for page, f in figures
                               if f.kind == "time"))


@pytest.mark.slow
def test_readme_commands_run_as_written(readme_run):
    where, results, _ = readme_run
    assert MAIN_JOB in results and BOUND in results
    assert not _failures(results), "\n".join(_failures(results))


@pytest.mark.slow
def test_readme_figures_are_what_the_commands_print(readme_run, capsys):
    where, results, _ = readme_run
    checks, times = _readme_measured(where, results)
    figures = [(page, f) for page in (README, ROOT / "docs" / "index.md")
               for f in quoted_figures(page)]
    assert {f.key for _, f in figures if f.kind == "check"} >= {"reentry.best_J1",
                                                                 "reentry.ratio"}
    unknown = [f.key for _, f in figures if f.key not in (checks if f.kind == "check" else times)]
    assert not unknown, f"markers no run measures: {unknown}"
    wrong = [f"{page.name}:{f.line}: {f.text} {f.unit} ({f.key}) but the run gives "
             f"{checks[f.key]:.6g}" for page, f in figures
             if f.kind == "check" and not f.matches(checks[f.key])]
    assert not wrong, "\n".join(wrong)
    _print_durations(capsys, figures, times)


@pytest.mark.slow
def test_reentry_bound_reads_the_bound_the_main_job_cached(readme_run):
    # oracle: the main job's summary.json (its report computed the bounds and cached them)
    where, results, cache = readme_run
    s = json.loads((where / "runs" / "reentry" / "summary.json").read_text())
    out = results[BOUND].stdout
    zero = float(re.search(r"bound at zero miss: J1 = ([\d.]+)", out)[1])
    tol = float(re.search(r"bound at miss <= 1 km: J1 = ([\d.]+)", out)[1])
    assert abs(zero - s["bound_J1_zero_miss"]) <= 5e-5 and abs(tol - s["bound_J1"]) <= 5e-5, out
    assert "ratio uses the bound at miss <= 1 km" in out
    assert f"cached in {cache}{os.sep}bound-" in out, out       # the session's fresh cache


@pytest.mark.slow
def test_the_readme_leaves_nothing_outside_runs(readme_run):
    where, _, _ = readme_run
    assert not left_behind(where), left_behind(where)


# ---- the tutorials ----------------------------------------------------------------------------

@pytest.mark.slow
def test_tutorial_commands_run_as_written(tutorial_runs):
    where, runs = tutorial_runs
    for page, results in runs.items():
        assert results, f"{page}: no command block"
        assert not _failures(results), page + ":\n" + "\n".join(_failures(results))


@pytest.mark.slow
def test_tutorial_closed_loop_carries_the_native_twin(tutorial_runs):
    # the page says the exported closed loop carries the hopper's native twin, no Python: the
    # archive the tutorial's export-law wrote holds the twin's binary and no pythonfmu binary
    where, _ = tutorial_runs
    with zipfile.ZipFile(where / "runs" / "hopper" / "law0" / "hopperClosedLoop.fmu") as z:
        names = z.namelist()
    assert "resources/Hopper/binaries/linux64/Hopper.so" in names
    assert not [n for n in names if "pythonfmu" in n or n.endswith(".py")]


def test_tutorial_problem_file_block_is_the_file():
    # oracle: docs/tutorials/hopper.toml itself; the page shows it "after its comment header"
    text = (ROOT / "docs" / "tutorials" / "own_plant.md").read_text()
    block = re.search(r"```toml\n(.*?)```", text, re.S)[1]
    lines = (ROOT / "docs" / "tutorials" / "hopper.toml").read_text().splitlines(keepends=True)
    body = "".join(lines[next(i for i, ln in enumerate(lines) if not ln.startswith("#")):])
    assert block.strip() == body.strip()
    assert tomllib.loads(block)["problem"]["name"] == "hopper"


def _numbers_close(shown: str, actual: str) -> bool:
    """Two CSV rows alike: text cells equal, numeric cells within 1e-6 relative (the same
    seeded run; the last digits may differ between machines' libm)."""
    a, b = next(csv.reader([shown])), next(csv.reader([actual]))
    if len(a) != len(b):
        return False
    for x, y in zip(a, b):
        try:
            if not math.isclose(float(x), float(y), rel_tol=1e-6, abs_tol=1e-12):
                return False
        except ValueError:
            if x != y:
                return False
    return True


@pytest.mark.slow
def test_tutorial_front_and_flight_are_what_the_run_wrote(tutorial_runs, capsys):
    where, runs = tutorial_runs
    page = ROOT / "docs" / "tutorials" / "own_plant.md"
    shown = re.search(r"<!-- output: (\S+) -->\n```\w*\n(.*?)```", page.read_text(), re.S)
    rows = (where / shown[1]).read_text().splitlines()
    by_k = {r.split(",", 1)[0]: r for r in rows}
    for line in shown[2].splitlines():
        if line.strip() != "...":
            wrote = by_k.get(line.split(",", 1)[0], "")
            assert _numbers_close(line, wrote), \
                f"{shown[1]}: the page shows\n{line}\nthe run wrote\n{wrote}"
    checks = _tutorial_measured(where)
    times = {"hopper.wall": next(r.seconds for c, r in runs[page.name].items()
                                 if " synthesize " in c),
             "hopper.seconds": json.loads((where / "runs" / "hopper" / "summary.json")
                                          .read_text())["seconds"]}
    figures = quoted_figures(page)
    unknown = [f.key for f in figures if f.key not in (checks if f.kind == "check" else times)]
    assert not unknown, f"markers no run measures: {unknown}"
    wrong = [f"own_plant.md:{f.line}: {f.text} {f.unit} ({f.key}) but the run gives "
             f"{checks[f.key]:.6g}" for f in figures
             if f.kind == "check" and not f.matches(checks[f.key])]
    assert not wrong, "\n".join(wrong)
    _print_durations(capsys, [(page, f) for f in figures], times)


def _tutorial_measured(where: Path) -> dict:
    run = where / "runs" / "hopper"
    s = json.loads((run / "summary.json").read_text())
    rows = list(csv.DictReader(open(run / "pareto.csv")))
    with open(where / "runs" / "hopper" / "hop.csv") as fh:
        flight = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(fh)]
    land = next(r for r in flight if r["h"] <= 0.0)
    return {"hopper.flights": s["simulated"], "hopper.pareto": s["pareto_size"],
            "hopper.new_form": s["structure"]["pareto_laws_with_new_form"],
            "hopper.best_v_mm": float(rows[0]["v_touchdown"]) * 1000,
            "hopper.best_fuel": float(rows[0]["fuel"]),
            "hopper.basic_v": s["basic_law"]["v_touchdown"],
            "hopper.t_land": land["time"], "hopper.v_land_mm": land["v"] * 1000,
            "hopper.fuel_used": flight[0]["m"] - land["m"],
            "hopper.stop_time": flight[-1]["time"],
            "hopper.file_flights": _file_flights(where / "docs" / "tutorials" / "hopper.toml")}


def _file_flights(path: Path) -> int:
    """The flight budget a problem file runs with: its own, else the package's default."""
    from descent_fmus.synthesis.problems.contract import Budget
    budget = tomllib.loads(path.read_text()).get("budget", {})
    return budget.get("flights", Budget().flights)


# ---- reentry bound: one name for each bound, read from the synthesis' cache -------------------

def test_reentry_bound_prints_both_bounds_from_the_cache(tmp_path, monkeypatch, capsys):
    # oracle: two programs planted in the cache folder under the synthesis' key, with J1 values
    # no optimisation gives (1.25, 1.5): the command must print exactly those, not compute
    from descent_fmus.synthesis.cli.main import main
    from descent_fmus.synthesis.systems.reentry.bound import Program
    from descent_fmus.synthesis.systems.reentry.reports import (BOUND_FILES, BOUND_NAMES,
                                                                _bound_key)
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path))
    folder = tmp_path / f"bound-{_bound_key()}"
    folder.mkdir()
    for name, j1, miss in zip(BOUND_FILES, (1.5, 1.25), (0.0, 999.0)):
        Program([0.1, -0.1], 1.0, J1=j1, miss=miss, t_land=200.0, info={}).save(folder / name)
    assert main(["reentry", "bound"]) == 0
    text = capsys.readouterr().out
    assert f"{BOUND_NAMES[0]}: J1 = 1.5000" in text and f"{BOUND_NAMES[1]}: J1 = 1.2500" in text
    assert f"ratio uses the {BOUND_NAMES[1]}" in text and str(folder) in text
    assert main(["reentry", "bound", "--json", "--out", str(tmp_path / "p.json")]) == 0
    d = json.loads(capsys.readouterr().out)
    assert (d["bound_at_zero_miss"]["J1"], d["bound_at_miss_1km"]["J1"]) == (1.5, 1.25)
    assert d["report_ratio_uses"] == "bound_at_miss_1km"
    assert Program.load(tmp_path / "p.json").J1 == 1.5        # --out: the zero-miss program


def test_the_run_report_names_the_bound_its_ratio_uses():
    # oracle: the summary fields a run writes (made up here); the printed lines use the names
    from descent_fmus.synthesis.systems.reentry.reports import BOUND_NAMES, ReentryReport
    lines = "\n".join(ReentryReport().lines({"bound_J1": 8.2691, "bound_J1_zero_miss": 8.2895,
                                             "ratio_to_bound": 1.00016}))
    assert f"{BOUND_NAMES[1]}: J1 = 8.2691 (the ratio's reference)" in lines
    assert f"{BOUND_NAMES[0]}: J1 = 8.2895" in lines
    assert f"1.00016 x the {BOUND_NAMES[1]}" in lines
