"""One way to open a closed loop: every path through ``synthesis.fmi.loop.open_loop``.

Oracles: the package's and the benchmarks' source (read as syntax trees: no module but the
factory constructs a closed-loop class), and the Python master on the pythonfmu FMUs (the
definition of the master algorithm): every path flies the same law from the same state to the
same final outputs, bit for bit (tolerance 0).
"""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from descent_fmus.synthesis.fmi.loop import PATHS, Loop, choose_path, open_loop
from descent_fmus.synthesis.fmi.native_loop import native_fmus
from descent_fmus.synthesis.fmi.start_values import StartValues

ROOT = Path(__file__).resolve().parents[2]
#: the five closed-loop classes (ContainerLoop's subclass NativeContainerLoop included)
LOOP_CLASSES = {"ClosedLoop", "ContainerLoop", "NativeContainerLoop", "CMasterLoop"}
FACTORY = ROOT / "synthesis" / "fmi" / "loop.py"


def loop_constructions(root: Path = ROOT) -> list:
    """``file:line Class(...)`` for every call of a closed-loop class outside the factory, in
    ``root``'s synthesis/ and benchmarks/ (a subclass's ``super().__init__`` is none)."""
    found = []
    for folder in ("synthesis", "benchmarks"):
        for path in sorted((root / folder).rglob("*.py")):
            if path == FACTORY:
                continue
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Call):
                    f = node.func
                    name = f.id if isinstance(f, ast.Name) else \
                        f.attr if isinstance(f, ast.Attribute) else None
                    if name in LOOP_CLASSES:
                        found.append(f"{path.relative_to(root)}:{node.lineno} {name}(...)")
    return found


def test_no_closed_loop_is_built_outside_the_factory():
    assert loop_constructions() == []


def test_the_grep_finds_a_construction(tmp_path):
    # the check above can fail: a module that builds a loop itself is found, a subclass is not
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / "benchmarks" / "probe.py").write_text(
        "from x import ClosedLoop, fmi\nclass Mine(ClosedLoop):\n    pass\n"
        "loop = ClosedLoop(1, 2, 3)\nother = fmi.CMasterLoop(1, 2, 3)\n")
    assert loop_constructions(tmp_path) == ["benchmarks/probe.py:4 ClosedLoop(...)",
                                            "benchmarks/probe.py:5 CMasterLoop(...)"]


def test_start_values_are_one_mapping():
    # a dict and its StartValues read the same; merged pairs follow, the last one wins
    d = {"nx": 3, "q[1]": 0.25}
    sv = StartValues.of(d)
    assert dict(sv) == {"nx": 3.0, "q[1]": 0.25} and sv.items() == [("nx", 3.0), ("q[1]", 0.25)]
    assert StartValues.of(sv) is sv and len(StartValues.of(None)) == 0
    m = sv.merged((("replan", 1), ("q[1]", 0.5)))
    assert m.names == ("nx", "q[1]", "replan", "q[1]") and m["q[1]"] == 0.5
    with pytest.raises(ValueError, match="2 names"):
        StartValues(("a", "b"), np.zeros(3))


def test_every_path_is_a_loop_and_flies_the_same_flight(fmu_dir):
    # the S1 problem's basic law from its first initial state, on each of the five paths:
    # the same final outputs as the Python master on the pythonfmu FMUs, bit for bit
    from descent_fmus.synthesis.registry import get_problem
    problem = get_problem("reentry")
    plant, ctrl = problem.fmu_paths(fmu_dir)
    twins = native_fmus(problem.wiring, plant, ctrl)
    if twins is None:
        pytest.skip("the native twins are not built (python build_fmus.py)")
    law, state = problem.basic(), problem.initial_states[0]
    sv = StartValues.of_law(law)
    finals = {}
    for path in PATHS:
        fmus = twins if path.startswith("native") else (plant, ctrl)
        with open_loop(problem.wiring, *fmus, path) as loop:
            assert isinstance(loop, Loop) and loop.path == path
            finals[path] = loop.run(plant_values=state, controller_values=sv).final
    want = {k: np.float64(v).tobytes() for k, v in finals["master"].items()}
    for path, final in finals.items():
        assert {k: np.float64(v).tobytes() for k, v in final.items()} == want, path
    assert choose_path(problem.wiring, plant, ctrl, native=False)[0] == "master"
    with pytest.raises(ValueError, match="unknown closed-loop path"):
        open_loop(problem.wiring, plant, ctrl, "jacobi")
