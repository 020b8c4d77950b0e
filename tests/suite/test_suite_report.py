"""The suite's table of every method at fixed budgets and its learning-curve figure
(benchmarks/suite/suite_table.py, suite_report.py) on tiny stored runs written here: no synthesis.

The oracle is the hand computation written beside each assertion: GP and CMA-ES (they do not
read their budget) give their value at N flights off any run flown that far, the network
operator (it reads it) only from a run of that budget; the median over the seeds that have a
value; the ratio NO / GP of the medians, above the reference of the excesses over it.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

SUITE = Path(__file__).resolve().parents[2] / "benchmarks" / "suite"
sys.path.insert(0, str(SUITE))

import suite_report  # noqa: E402
import suite_table  # noqa: E402

NAME = "mintime-di"


def _store(out: Path, method: str, seed: int, budget: int, flights: int, curve) -> None:
    d = suite_table.run_dir(out, NAME, method, seed)
    d.mkdir(parents=True)
    (d / "run.json").write_text(json.dumps({"budget": {"flights": budget, "seed": seed}}))
    (d / "summary.json").write_text(json.dumps({"flights": flights, "curve": curve}))


@pytest.fixture()
def stored(tmp_path):
    """Run folders A (GP 20 000 flights on seeds 1-2, 5 000 on seed 3; the network operator at
    5 000 on seeds 1-2; CMA-ES at 4 000 on seed 1) and B (the network operator at 20 000,
    seeds 1-2; cma-tanh and the network operator stopped at 6 000 flights, seed 3), and the
    part of :func:`suite_table.tabulate`'s table they need."""
    a, b = tmp_path / "a", tmp_path / "b"
    _store(a, "gp", 1, 20000, 20005, [[100, 4.0], [3000, 3.0], [12000, 2.5]])
    _store(a, "gp", 2, 20000, 20010, [[200, 5.0], [6000, 2.8]])
    _store(a, "gp", 3, 5000, 5050, [[150, 3.5], [4000, 3.2]])
    _store(a, "network-operator", 1, 5000, 5003, [[1000, 3.0], [5003, 2.4]])
    _store(a, "network-operator", 2, 5000, 5001, [[900, 2.6]])
    _store(a, "cma-linear", 1, 4000, 4002, [[100, 4.5]])
    _store(b, "network-operator", 1, 20000, 20004, [[1000, 3.0], [19000, 2.1]])
    _store(b, "network-operator", 2, 20000, 20004, [[1000, 2.0]])
    # stopped before their ends: a checkpoint, no summary
    for method, curve in (("cma-tanh", [[100, 4.1], [5500, 3.9]]),
                          ("network-operator", [[100, 1.0]])):
        d = suite_table.run_dir(b, NAME, method, 3)
        d.mkdir(parents=True)
        (d / "run.json").write_text(json.dumps({"budget": {"flights": 5000, "seed": 3}}))
        (d / "checkpoint.json").write_text(json.dumps({"simulated": 6000, "curve": curve}))
    table = {NAME: {"reference": 2.0, "plot": "excess", "goal_ratio": 1.05, "rows": [],
                    "methods": ["network-operator", "nop-lchr0", "gp", "cma-linear",
                                "cma-tanh"]}}
    return table, [a, b]


def test_every_method_at_fixed_budgets(stored):
    table, dirs = stored
    t = suite_table.at_budgets(table, dirs, [1, 2, 3], [5000, 20000])[NAME]
    rows = {r["method"]: r for r in t["rows"]}
    assert list(rows) == ["network-operator", "gp", "cma-linear", "cma-tanh"]  # no nop-lchr0
    # GP: at 5 000 the curves give 3.0, 5.0, 3.2 (median 3.2); at 20 000 seed 3 (5 050
    # flights) has none: the median of 2.5 and 2.8
    assert rows["gp"]["values"] == {5000: [3.0, 5.0, 3.2], 20000: [2.5, 2.8, None]}
    assert rows["gp"]["median"] == {5000: 3.2, 20000: pytest.approx(2.65, abs=1e-12)}
    # the network operator: at 5 000 the 5 000-flight runs' ends (2.4, 2.6), not B's
    # 20 000-flight runs' curves at 5 000 (3.0, 2.0); at 20 000 B's runs (2.1, 2.0); seed 3
    # stopped (a checkpoint of 6 000 flights, no summary): it reads its budget, so nothing
    assert rows["network-operator"]["values"] == {5000: [2.4, 2.6, None],
                                                  20000: [2.1, 2.0, None]}
    assert rows["network-operator"]["median"][5000] == pytest.approx(2.5, abs=1e-12)
    # CMA-ES flew 4 002 flights: no value at either budget; the stopped cma-tanh run's
    # checkpoint (6 000 flights) gives its curve's 4.1 at 5 000
    assert rows["cma-linear"]["values"] == {5000: [None] * 3, 20000: [None] * 3}
    assert rows["cma-tanh"]["values"] == {5000: [None, None, 4.1], 20000: [None] * 3}
    # NO / GP as the goal reads it on a minimum-time problem: the excesses over 2.0,
    # 0.5 / 1.2 and 0.05 / 0.65; the raw values beside it: 2.5 / 3.2 and 2.05 / 2.65
    assert t["no_over_gp_of"] == "excess over the reference"
    assert t["no_over_gp"][5000] == pytest.approx(0.5 / 1.2, rel=1e-12)
    assert t["no_over_gp"][20000] == pytest.approx(0.05 / 0.65, rel=1e-9)
    assert t["values_no_over_gp"][5000] == pytest.approx(0.78125, rel=1e-12)
    assert t["values_no_over_gp"][20000] == pytest.approx(2.05 / 2.65, rel=1e-12)
    # the figure's curves are each seed's longest run: B's for the network operator's
    # seeds 1-2, the stopped run's checkpoint for seed 3
    assert rows["network-operator"]["ends"] == {1: 20004, 2: 20004, 3: 6000}


def test_median_curve_of_the_seeds():
    curves = {1: [[100, 4.0], [3000, 3.0], [12000, 2.5]], 2: [[200, 5.0], [6000, 2.8]],
              3: [[150, 3.5], [4000, 3.2]]}
    # up to the shortest run (5 050 flights); at 100 two seeds have no value yet (median inf,
    # left out); at 150: 4, inf, 3.5 -> 4; at 200: 4, 5, 3.5 -> 4 (no step); at 3 000:
    # 3, 5, 3.5 -> 3.5; at 4 000: 3, 5, 3.2 -> 3.2; held to the end
    assert suite_table.median_curve(curves, {1: 20005, 2: 20010, 3: 5050}) == \
        [[150, 4.0], [3000, 3.5], [4000, 3.2], [5050, 3.2]]
    assert suite_table.median_curve({}, {}) == []


def test_figure_and_printed_table_of_the_stored_runs(stored, tmp_path, capsys):
    table, dirs = stored
    at = suite_table.at_budgets(table, dirs, [1, 2, 3], [5000, 20000])
    path = tmp_path / "fig" / "suite-baselines-tuning.png"
    drawn = suite_report.plot(at, path, "tuning")
    assert path.is_file() and path.stat().st_size > 10_000
    # every method drawn; GP's median as in test_median_curve_of_the_seeds
    assert set(drawn[NAME]) == {"network-operator", "gp", "cma-linear", "cma-tanh"}
    assert drawn[NAME]["gp"] == [[150, 4.0], [3000, 3.5], [4000, 3.2], [5050, 3.2]]
    # the network operator's three seeds (B's runs, the checkpoint), up to 6 000 flights:
    # at 100 the median of inf, inf, 1.0 is inf (left out); at 1 000 of 3.0, 2.0, 1.0: 2.0
    assert drawn[NAME]["network-operator"] == [[1000, 2.0], [6000, 2.0]]
    suite_report.print_budgets(at, [1, 2, 3])
    out = capsys.readouterr().out
    assert "gp                 5000: 3.2 (3, 5, 3.2); 20000: 2.65 (2.5, 2.8, -)" in out
    assert ("network operator / GP (excess over the reference): 5000: 0.417; "
            "20000: 0.0769") in out
    assert "reference): 5000: 0.781; 20000: 0.774" in out      # the raw ratio, labelled


# made-up medians of three problems (closed-form ratios): a minimum-time problem whose
# optimum is 2.0, one whose NO equals its reference, and a parking problem (reference 0)
@pytest.mark.parametrize("ref, plot, no, gp, expected, of, raw", [
    # (2.22 - 2) / (2.56 - 2) = 0.22 / 0.56 = 0.392857...: the goal "<= 0.5 x GP" met,
    # where the raw ratio 2.22 / 2.56 = 0.867 could never come under 0.5
    (2.0, "excess", 2.22, 2.56, 0.22 / 0.56, "excess over the reference", 2.22 / 2.56),
    (2.0, "excess", 2.0, 2.5, 0.0, "excess over the reference", 0.8),
    # a reference of 0 (parking): excess and value are the same number, read as the value
    (0.0, "value", 0.03, 0.6, 0.05, "value", None),
])
def test_no_over_gp_reads_the_excess_above_a_reference(ref, plot, no, gp, expected, of, raw):
    r = suite_table.no_over_gp({5000: no}, {5000: gp}, ref, plot, [5000])
    assert r["no_over_gp"][5000] == pytest.approx(expected, rel=1e-12, abs=1e-15)
    assert r["no_over_gp_of"] == of
    if raw is None:
        assert "values_no_over_gp" not in r
    else:
        assert r["values_no_over_gp"][5000] == pytest.approx(raw, rel=1e-12)


def test_no_over_gp_without_a_gp_value_is_none():
    # GP has no median at 20 000 (no run flown that far), or its excess is 0: no ratio
    r = suite_table.no_over_gp({5000: 2.4, 20000: 2.2}, {5000: 2.0}, 2.0, "excess",
                               [5000, 20000])
    assert r["no_over_gp"] == {5000: None, 20000: None}
