"""Synthesis problems from TOML files, for plant FMUs the package does not register.

Oracles: the registered ``reentry`` problem (a problem file describing it must give the same
Pareto set for the same seed), fmpy's own simulation of the exported closed-loop FMU, and the
plant's physics (a hopper that reaches the ground has h <= 0).
"""
from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from descent_fmus.synthesis.problems.files import ProblemFileError, load_problem_file
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.run.loop import run_synthesis

ROOT = Path(__file__).resolve().parents[2]
TUTORIAL = ROOT / "docs" / "tutorials"
SMALL = dict(population=16, generations=3, crossovers=6, lchr=4, epoch=2)


def _edit(src: Path, dst: Path, old: str, new: str) -> Path:
    text = src.read_text()
    assert old in text, old
    dst.write_text(text.replace(old, new, 1))
    return dst


@pytest.mark.slow            # a synthesis through the hopper FMU (~30 s)
def test_tutorial_problem_runs_through_the_fmus(hopper_dir, fmu_dir, tmp_path):
    from fmpy import simulate_fmu
    problem = load_problem_file(hopper_dir / "hopper.toml", fmu_dir=fmu_dir)
    assert problem.objective_names == ("v_touchdown", "fuel")
    assert len(problem.initial_states) == 6                     # samples = 6 (LHS box)
    out = tmp_path / "run"
    s = run_synthesis(problem.tuned(**SMALL, seed=1), out, fmu_dir, progress=False)
    assert s["failures"] == 0 and s["pareto_size"] >= 1
    rows = list(csv.DictReader(open(out / "pareto.csv")))
    best = min(float(r["v_touchdown"]) for r in rows)
    # the basic law (hover + PD) never touches down from some starts (penalty 100 m/s); the
    # synthesis finds laws that land every start: a worst touchdown speed below 5 m/s
    assert s["basic_law"]["v_touchdown"] > 50.0 and best < 5.0
    assert "best_law_q_at_range_edge" not in s["structure"]     # +-64 holds the gains
    # the exported closed loop runs in fmpy on its own and lands (h reaches 0 and freezes)
    law0 = out / "laws" / "0"
    res = simulate_fmu(str(law0 / "hopperClosedLoop.fmu"), stop_time=30.0,
                       start_values={"h0": 10.0, "v0": -1.0}, output=["h", "v"])
    assert res["h"][-1] <= 0.0 and abs(res["v"][-1]) < 5.0


@pytest.mark.slow            # a synthesis through the hopper FMU (~50 s)
def test_a_too_narrow_parameter_range_is_reported(hopper_dir, fmu_dir, tmp_path):
    # the basic law (gains -1.5, -0.5 on h/10 and v) lies inside q_range [-2, 2), but the laws
    # that touch down softly need larger gains (the cma-linear baseline of the suite ends near
    # -12 and -3.9): the basis' CMA-ES runs into the range's edge, and the run says which
    # parameters sit there (within 1e-3 of the range's width, the report's rule)
    # the plant with its native twin beside it (the C flights: the pythonfmu route of a problem
    # file is flown by the build-plant and expression tests)
    shutil.copy(hopper_dir / "Hopper.fmu", tmp_path / "Hopper.fmu")
    shutil.copytree(hopper_dir / "native", tmp_path / "native")
    f = _edit(hopper_dir / "hopper.toml", tmp_path / "narrow.toml", "q_range = [-64.0, 64.0]",
              "q_range = [-2.0, 2.0]")
    # (no sweep: with it, a problem file's default, this run's best law is one of the tuned
    # basic law's one-operation neighbours, whose parameters do not sit at the range's edge;
    # the scenario here is the linear law pushed against it)
    problem = load_problem_file(f, fmu_dir=fmu_dir).tuned(**SMALL, seed=1, refine_basis=60,
                                                           refine_basis_patience=0,
                                                           refine_sweep=0)
    s = run_synthesis(problem, tmp_path / "run", fmu_dir, progress=False, export=False,
                      reference=False)
    st = s["structure"]
    assert st["q_range"] == [-2.0, 2.0] and st["best_law_q_at_range_edge"]
    best = min(s["pareto"], key=lambda r: r["v_touchdown"])
    q = json.loads((tmp_path / "run" / "pareto.json").read_text())[best["k"]]["law"]["q"]
    for i in st["best_law_q_at_range_edge"]:
        assert min(abs(q[i - 1] + 2.0), abs(q[i - 1] - 2.0)) <= 4e-3
    from types import SimpleNamespace

    from descent_fmus.synthesis.cli.synthesize import _summary_lines
    args = SimpleNamespace(method="network-operator", out=tmp_path / "run", no_export=True)
    assert any("edge of the parameters' range [-2, 2)" in line
               for line in _summary_lines(problem, args, s))


def test_reentry_as_a_file_gives_the_registered_pareto_set(fmu_dir, tmp_path):
    # Oracle: the registered Python problem `reentry`; the file states its whole recipe (the
    # budget, the GA, the CMA-ES refinement of the basis and of the best laws with its target
    # J1 subject to miss < 1 km, the basis rule): same seed => the same Pareto set
    registered = get_problem("reentry")
    file_problem = load_problem_file(ROOT / "synthesis/systems/reentry/reentry.toml",
                                     fmu_dir=fmu_dir)
    assert (file_problem.budget, file_problem.ga, file_problem.refine, file_problem.target,
            file_problem.q_bits) == (registered.budget, registered.ga, registered.refine,
                                     registered.target, registered.q_bits)
    small = dict(SMALL, seed=2, generations=8, refine_evals=30, refine_basis=40, flights=400)
    key = lambda r: (r["J1"], r["J2"], r["formula"])  # noqa: E731
    runs = [run_synthesis(p.tuned(**small), tmp_path / n, fmu_dir, progress=False,
                          export=False, reference=False)
            for n, p in (("a", registered), ("b", file_problem))]
    assert runs[0]["simulated"] > 100              # the refinement ran (40 + 30 per epoch)
    assert [key(r) for r in runs[0]["pareto"]] == [key(r) for r in runs[1]["pareto"]]
    assert runs[0]["basic_law"] == runs[1]["basic_law"]
    # the file's polynomial baseline is the registered one: the same CMA-ES run
    base = [run_synthesis(p.tuned(flights=20, seed=3), tmp_path / f"c{n}", fmu_dir,
                          method="cma-polynomial", progress=False, export=False,
                          reference=False)
            for n, p in (("a", registered), ("b", file_problem))]
    assert [key(r) for r in base[0]["pareto"]] == [key(r) for r in base[1]["pareto"]]


BAD = [
    # (old text, new text, expected words of the message)
    ('fmu = "Hopper.fmu"', 'fmu = "Missing.fmu"', ["plant.fmu", "not found"]),
    ('{ output = "v" }', '{ output = "F_max" }', ["controller.inputs[2].output",
                                                  "not an output"]),
    ('input = "throttle"', 'input = "thrust"', ["controller.outputs[1].input",
                                                "not an input"]),
    ("min = 0.0, max = 1.0", "min = 1.0, max = 0.0", ["controller.outputs[1]", "min = 1.0 > max"]),
    ("h0 = [8.0, 12.0]", "h00 = [8.0, 12.0]", ["initial_states.box.h00", "no parameter"]),
    ('flight = "abs(final(v))"', 'flight = "abs(final(vv))"', ["objectives[1].flight", "vv"]),
    ('flight = "abs(final(v))"', 'flight = "__import__(\'os\').system(\'ls\')"',
     ["objectives[1].flight", "allowed functions"]),
    ('flight = "abs(final(v))"', 'flight = "final(v).real"',
     ["objectives[1].flight", "not allowed"]),
    ("box = { h0 = [8.0, 12.0], v0 = [-2.0, 0.0] }\nsamples = 6\nsampler = \"lhs\"\nseed = 3",
     "states = []", ["initial_states.states", "empty"]),
    ("step = 0.1", "step = -0.1", ["simulation.step", "> 0"]),
    ("over_states = \"max\"", "over_states = \"worst\"", ["objectives[1].over_states"]),
    ("[ga]", "[ga]\npopulation_size = 3", ["ga.population_size", "unknown key"]),
    # the Gray code decodes through int64/float64: at most 48 bits per parameter
    ("[ga]", "[ga]\nq_bits = [30, 19]", ["ga.q_bits", "1 to 48"]),
    # every "not an output" error lists the outputs (the hopper's, sorted)
    ('stop = { output = "h"', 'stop = { output = "hh"',
     ["simulation.stop.output", "its outputs: ", "fuel, h, m, status, t_end, v"]),
    # a missing table says what to write: its keys and a one-line example
    ("[basic_law]" + " " * 29 + "# throttle = 0.324 - 1.5 h/10 - 0.5 v (hover + PD)\n"
     "gains = [ [ -1.5, -0.5 ] ]\nbias = [ 0.324 ]\nsize = 14\n", "",
     ["basic_law: missing; add a [basic_law] table with gains, bias, size",
      "e.g. [basic_law] gains = [[-1.5, -0.5]]"]),
]


@pytest.mark.parametrize("old,new,words", BAD, ids=[b[2][0] for b in BAD])
def test_bad_problem_files_are_one_line_errors(hopper_dir, fmu_dir, tmp_path, old, new, words):
    shutil.copy(hopper_dir / "Hopper.fmu", tmp_path / "Hopper.fmu")
    bad = _edit(hopper_dir / "hopper.toml", tmp_path / "bad.toml", old, new)
    with pytest.raises(ProblemFileError) as exc:
        load_problem_file(bad, fmu_dir=fmu_dir)
    msg = str(exc.value)
    assert "\n" not in msg and str(bad) in msg
    for w in words:
        assert w in msg, msg
    # the command line: exit 2, one line naming the file, nothing written
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main", "synthesize",
                        "--problem", str(bad), "--out", str(out), "--fmus", str(fmu_dir)],
                       capture_output=True, text=True)
    assert r.returncode == 2 and str(bad) in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


def _rewrite_md(src: Path, dst: Path, old: str, new: str) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                assert old in text
                data = text.replace(old, new, 1).encode()
            zout.writestr(item, data)
    return dst


@pytest.mark.parametrize("old,new,words", [
    ('fmiVersion="2.0"', 'fmiVersion="1.0"', ["FMI 1.0", "needs FMI 2.0"]),
    ("<CoSimulation", "<ModelExchange", ["not a co-simulation FMU"]),
], ids=["fmi1", "model-exchange"])
def test_wrong_kind_of_fmu(hopper_dir, fmu_dir, tmp_path, old, new, words):
    _rewrite_md(hopper_dir / "Hopper.fmu", tmp_path / "Hopper.fmu", old, new)
    shutil.copy(hopper_dir / "hopper.toml", tmp_path / "hopper.toml")
    with pytest.raises(ProblemFileError) as exc:
        load_problem_file(tmp_path / "hopper.toml", fmu_dir=fmu_dir)
    assert "plant.fmu" in str(exc.value)
    for w in words:
        assert w in str(exc.value), str(exc.value)


def test_not_toml(tmp_path):
    bad = tmp_path / "x.toml"
    bad.write_text("[problem\nname = 1")
    with pytest.raises(ProblemFileError, match="not valid TOML"):
        load_problem_file(bad)


def test_a_relative_fmu_folder_names_the_same_controller(hopper_dir, fmu_dir, monkeypatch):
    # --fmus as typed on a command line, relative to the working directory: the generic
    # controller is found once, not under the folder twice (fmus/fmus/...)
    monkeypatch.chdir(Path(fmu_dir).resolve().parent)
    rel = Path(Path(fmu_dir).resolve().name)
    problem = load_problem_file(hopper_dir / "hopper.toml", fmu_dir=rel)
    ctrl = problem.fmu_paths(rel)[1]
    assert ctrl.is_file() and ctrl == (Path(fmu_dir) / "NetworkOperatorController.fmu").resolve()
