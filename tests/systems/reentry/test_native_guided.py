"""The native GuidedNetworkOperatorController (C, no Python) against its pythonfmu twin.

Oracle: the pythonfmu ``GuidedNetworkOperatorController`` of
``models/controllers/reentry_npc.py`` flown by the Python master -- its outputs at every
communication point and the plant's final outputs (bitwise equal: the native twin's arithmetic
is traced from the same Python functions, its loops -- the prediction's steps, Brent's method --
are SciPy's and the controller's in the same order), its error messages (the same words).
Tolerance: none -- every comparison of numbers is bitwise.
"""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop

from descent_fmus.synthesis.fmi.slave import load_slave
from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
from descent_fmus.synthesis.methods.law import NetworkOperator

from fmi_calls import bits, start

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (CI installs gcc)")

GUIDED_LAW = "synthesis/systems/reentry/guided_law.json"
#: the controller's inputs (fed from a recorded flight) and outputs (compared)
INPUTS = {"x[1]": "y1", "x[2]": "y2", "a_drag": "aero_load", "nav_x1": "x1", "nav_x2": "x2",
          "nav_x3": "x3", "nav_x4": "x4"}
OUTPUTS = ("u[1]", "correction", "predicted_miss", "drag_factor_log", "drag_factor",
           "scale_height_error", "drag_factor_sd")


@pytest.fixture(scope="module")
def guided_twin(native_twin):
    """The native guided controller, built from this checkout's C once per session
    (tests/conftest.py; its builder: build_guided_controller)."""
    return native_twin("GuidedNetworkOperatorController")


@pytest.fixture(scope="module")
def problem():
    from descent_fmus.synthesis.registry import get_problem
    return get_problem("reentry-guided")


def _law_values() -> list:
    """The committed guided law as flown (correction read at x[4], added with gain 1), with
    seeded accelerometer noise and bias, with a 20 g load gate, with the correction added but
    not read, read but not added, and with a non-optimal basic law of y1, y2 (y3, c unread)."""
    from descent_fmus.synthesis.systems.reentry.laws import synthesis_basic_law
    law = dict(NetworkOperator.load(GUIDED_LAW).start_values())
    basic = dict(synthesis_basic_law().start_values(), estimate_input=0, correction_input=0)
    return [law, dict(law, noise=0.05, bias=0.01, noise_seed=4), dict(law, correction_gate=20.0),
            dict(law, correction_input=0), dict(law, correction_gain=0.0), basic]


def _states(problem) -> list:
    """4 dispersed samples of the reentry-guided problem, one with the density scale height
    6 % off (the profile fit's slope acts)."""
    states = [dict(s) for s in problem.initial_states[:4]]
    states[3]["lam"] = 1.35e-4 * 1.06
    return states


def _flights(fmu_dir, ctrl, problem) -> list:
    """``[(values, state, flight)]``: the Python master flying the pythonfmu plant with the
    controller FMU ``ctrl``, 6 settings x 4 samples, recorded (h, load and the connected
    signals)."""
    with ClosedLoop(problem.wiring, fmu_dir / "Reentry.fmu", ctrl, record=("h", "load")) as loop:
        return [(v, s, loop.run(s, v, record=True)) for v in _law_values()
                for s in _states(problem)]


@pytest.fixture(scope="module")
def pythonfmu_flights(fmu_dir, problem) -> list:
    """:func:`_flights` of the pythonfmu guided controller, flown once for the two tests that
    compare the twin with them."""
    return _flights(fmu_dir, fmu_dir / "GuidedNetworkOperatorController.fmu", problem)


def test_guided_twin_flies_as_the_pythonfmu_controller(fmu_dir, guided_twin, problem,
                                                        pythonfmu_flights):
    # 6 settings x 4 samples, the Python master flying the plant with each controller: every
    # final plant output and the control at every communication point equal
    runs = [[f for _, _, f in pythonfmu_flights],
            [f for _, _, f in _flights(fmu_dir, guided_twin, problem)]]
    for want, got in zip(*runs):
        assert got.final == want.final
        for name in ("ctrl.u[1]", "h", "load"):
            assert [bits(v) for v in got[name]] == [bits(v) for v in want[name]], name
    assert {r.final["status"] for r in runs[0]} == {1}


def test_guided_twin_outputs_at_every_step(fmu_dir, guided_twin, pythonfmu_flights):
    # the controllers alone fed the same recorded flights (6 settings x 4 samples, flown with
    # the pythonfmu controller): u, the correction c, the predicted miss, y3, the factor, the
    # scale-height error and the fit's standard deviation, and the number of predictions,
    # equal at every communication point
    made = []
    try:
        for k, path in enumerate((fmu_dir / "GuidedNetworkOperatorController.fmu",
                                  guided_twin)):
            made.append(load_slave(path, f"g{k}", []))
        corrected = 0
        for values, s, flight in pythonfmu_flights:
            seqs = []
            for fmu in made:
                vr = start(fmu, values)
                seq = []
                for i in range(len(flight.time)):
                    fmu.setReal([vr[n] for n in INPUTS],
                                [float(flight[v][i]) for v in INPUTS.values()])
                    seq.append([bits(v) for v in fmu.getReal([vr[n] for n in OUTPUTS])]
                               + fmu.getInteger([vr["predictions"]]))
                    fmu.doStep(float(flight.time[i]), 1.0)
                seqs.append(seq)
            assert seqs[0] == seqs[1], (values, s)
            corrected += seqs[0][-1][-1] > 0
        assert corrected >= 16                   # predictions were made (not all idle)
    finally:
        for fmu in made:
            fmu.freeInstance()


def test_guided_twin_in_the_native_loop(fmu_dir, guided_twin, problem):
    # the evaluator's path (both twins in fmpy's container, one call per flight) against the
    # Python master with the pythonfmu FMUs: the final plant outputs of 8 samples equal
    from descent_fmus.synthesis.fmi.native_loop import NativeContainerLoop
    plant = fmu_dir / "native" / "Reentry.fmu"
    plant = plant if plant.is_file() else fmu_dir / "Reentry.fmu"
    law = _law_values()[0]
    states = problem.initial_states[:8]
    with ClosedLoop(problem.wiring, fmu_dir / "Reentry.fmu",
                    fmu_dir / "GuidedNetworkOperatorController.fmu") as master:
        want = [master.run(s, law).final for s in states]
    with NativeContainerLoop(problem.wiring, plant, guided_twin) as loop:
        got = [loop.run(s, law).final for s in states]
    assert got == want


#: bad parameters: both FMUs refuse them with the same message
BAD = [{"correction_input": 9}, {"correction_input": -1}, {"correction_input": 3},
       {"cycle": 0.0}, {"dt_pred": -1.0}, {"correction_max": 0.0}, {"replan_effort": -1.0},
       {"correction_gate": -2.0}, {"max_iter": 0}, {"scale_prior": -0.1}, {"nx": 9}]


def _loaded(paths, tag):
    """``[(fmu, log), ...]`` of the FMU files ``paths``, loaded."""
    out = []
    for k, path in enumerate(paths):
        log = []
        out.append((load_slave(path, f"{tag}{k}", log), log))
    return out


def _same_errors(made, cases) -> None:
    """Every start-value case of ``cases`` is refused by both FMUs of ``made`` with the same
    message; both usable again afterwards."""
    for case in cases:
        said = []
        for fmu, log in made:
            del log[:]
            with pytest.raises(Exception):
                start(fmu, case)
            said.append(log[0].split(": ", 1)[1])      # after "<model or instance>: "
        assert said[0] == said[1], case
    for fmu, _ in made:
        start(fmu, {})


def test_guided_twin_names_errors_as_the_python_controller(fmu_dir, guided_twin):
    made = _loaded((fmu_dir / "GuidedNetworkOperatorController.fmu", guided_twin), "g")
    try:
        _same_errors(made, BAD)
        for fmu, _ in made:                               # both take the re-planner
            start(fmu, {"replan": 1, "replan_iterations": 3})
    finally:
        for fmu, _ in made:
            fmu.freeInstance()


# -- the NPC baseline (ReentryNPC) ------------------------------------------------------------
@pytest.fixture(scope="module")
def npc_twin(native_twin):
    """The native NPC controller, built once per session (tests/conftest.py; its builder:
    build_npc_controller)."""
    return native_twin("ReentryNPC")


def test_npc_twin_flies_as_the_pythonfmu_controller(fmu_dir, npc_twin, problem):
    # 3 settings (default; accelerometer noise and bias; a 5 s cycle predicting with 1 s steps)
    # x 4 dispersed samples, one with the scale height 6 % off: every final plant output and
    # the control at every communication point equal, and the NPC's outputs at the end
    from descent_fmus.synthesis.systems.reentry.guidance import NPC_WIRING
    settings = [{}, {"noise": 0.05, "bias": 0.01, "noise_seed": 4},
                {"cycle": 5.0, "dt_pred": 1.0}]
    runs = []
    for ctrl in (fmu_dir / "ReentryNPC.fmu", npc_twin):
        with ClosedLoop(NPC_WIRING, fmu_dir / "Reentry.fmu", ctrl, record=("h", "load")) as loop:
            runs.append([loop.run(s, v, record=True) for v in settings
                         for s in _states(problem)])
    for want, got in zip(*runs):
        assert got.final == want.final
        for name in ("ctrl.u", "h", "load"):
            assert [bits(v) for v in got[name]] == [bits(v) for v in want[name]], name
    assert {r.final["status"] for r in runs[0]} == {1}
    # the NPC acts: a command other than 0 in every flight, re-solved cycle by cycle in some
    assert all(np.any(r["ctrl.u"] != 0.0) for r in runs[0])
    assert max(len(set(r["ctrl.u"])) for r in runs[0]) > 10


#: bad parameters of the NPC: both FMUs refuse them with the same message
BAD_NPC = [{"cycle": 0.0}, {"dt_pred": -1.0}, {"tol": 0.0}, {"max_iter": 0},
           {"accel_sigma": 0.0}, {"bias_prior": -1.0}, {"noise": -0.5}]


def test_npc_twin_names_errors_as_the_python_controller(fmu_dir, npc_twin):
    made = _loaded((fmu_dir / "ReentryNPC.fmu", npc_twin), "n")
    try:
        _same_errors(made, BAD_NPC)
    finally:
        for fmu, _ in made:
            fmu.freeInstance()


def test_the_re_planner_flies_the_native_twins(fmu_dir, problem):
    # the twin has the re-planner: every run takes the native path where the twins are built
    # (as build_fmus.py builds them)
    from descent_fmus.synthesis.problems.runner import Runner
    fmus = (fmu_dir / "Reentry.fmu", fmu_dir / "GuidedNetworkOperatorController.fmu")
    if not (fmu_dir / "native" / "GuidedNetworkOperatorController.fmu").is_file():
        pytest.skip("no native twins in the FMU folder")
    assert Runner().choose(problem.wiring, *fmus)[0] == "native-c"
