"""Native generic controllers (C, no Python in the host) against their pythonfmu twins.

Oracles: ``NetworkOperator.__call__`` (the Python evaluation of the one operation table) and the
pythonfmu controller FMUs of ``models/controllers/`` -- their outputs (bitwise equal: both
evaluate the same IEEE operations in the same order, with the platform's C math library), their
variables (names, start values, descriptions, units, causality, variability) and their error
messages (the same words); ``fmpy validate``; the dynamic symbols of the binaries (no ``Py*``).
Tolerance: none -- every comparison of numbers is bitwise (``struct.pack('<d')``).
"""
from __future__ import annotations

import math
import os
import shutil
import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from descent_fmus.models.controllers.operation_table import BINARY, UNARY
from descent_fmus.models.controllers.program_table import program_values
from descent_fmus.synthesis.fmi.slave import load_slave
from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.registry import native_controllers

from test_native_law import bits, every_operation_law, inputs, start

NATIVE_CONTROLLERS = native_controllers()

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (CI installs gcc)")


@pytest.fixture(scope="module")
def native(native_twin):
    """The native twins (name -> FMU path), built from this checkout's C once per session
    (tests/conftest.py)."""
    return {name: native_twin(name) for name in NATIVE_CONTROLLERS}


@pytest.fixture
def pair(native, fmu_dir):
    """``pair(name)``: (pythonfmu, native) instances of a controller with their logs."""
    made = []

    def load(name):
        out = []
        for tag, path in (("py", fmu_dir / f"{name}.fmu"), ("c", native[name])):
            log = []
            fmu = load_slave(path, tag, log)
            made.append(fmu)
            out.append((fmu, log))
        return out
    yield load
    for fmu in made:
        fmu.freeInstance()


def random_law(rng) -> NetworkOperator:
    """A random matrix within the controller's capacity: 10..32 nodes, 1..8 inputs, 0..16
    parameters, random operations on a quarter of the arcs, 1..4 outputs on any node (a source
    too), random bounds and input scaling."""
    L = int(rng.integers(10, 33))
    nx = int(rng.integers(1, 9))
    nq = int(rng.integers(0, min(16, L - nx - 1) + 1))
    psi = np.zeros((L, L), dtype=int)
    for j in range(nx + nq, L):
        psi[j, j] = rng.integers(0, len(BINARY))
        for i in range(j):
            if rng.random() < 0.25:
                psi[i, j] = rng.integers(1, len(UNARY))
    nu = int(rng.integers(1, 5))
    bounds = [(float(lo), float(lo + abs(w))) for lo, w in rng.normal(0, 10, (nu, 2))]
    return NetworkOperator(psi, nx=nx, q=list(rng.normal(0, 3, nq)),
                           outputs=[int(o) for o in rng.integers(1, L + 1, nu)], bounds=bounds,
                           input_scale=list(rng.normal(0, 2, nx)),
                           input_offset=list(rng.normal(0, 1, nx)))


def test_interpreter_equals_the_python_law(native):
    # 90 laws (random matrices, and laws on which every operation acts), each loaded by its
    # start values alone, >= 300 inputs each incl. +-0, +-1e300, +-inf, NaN, 5e-324, the clamp:
    # every output bitwise NetworkOperator.__call__'s, never NaN or inf
    rng = np.random.default_rng(2024)
    fmu = load_slave(native["NetworkOperatorController"], "interpreter")
    n = 0
    try:
        for k in range(90):
            law = every_operation_law(rng) if k % 3 == 0 else random_law(rng)
            vr = start(fmu, law.start_values())
            xi = [vr[f"x[{i + 1}]"] for i in range(law.nx)]
            ui = [vr[f"u[{i + 1}]"] for i in range(len(law.outputs))]
            for x in inputs(rng, law.nx, 120):
                fmu.setReal(xi, x)
                got, want = fmu.getReal(ui), law(x)
                assert [bits(v) for v in got] == [bits(v) for v in want], (k, x, got, want)
                assert all(math.isfinite(v) for v in got)
                n += 1
    finally:
        fmu.freeInstance()
    assert n > 30_000


def test_network_operator_twin_equals_the_pythonfmu_controller(pair):
    # the default law (no start value set), a sampled law stepped finer than its period, and a
    # law whose q is set after a reset: the same outputs, bitwise, at every communication point
    (py, _), (c, _) = pair("NetworkOperatorController")
    rng = np.random.default_rng(7)
    laws = [({}, 2), (dict(random_law(rng).start_values(), sample_period=0.75), None),
            (every_operation_law(rng).start_values(), None)]
    for values, nx in laws:
        runs = []
        for fmu in (py, c):
            vr = start(fmu, values)
            n_in = nx or values["nx"]
            xi = [vr[f"x[{i + 1}]"] for i in range(n_in)]
            ui = [vr[f"u[{i + 1}]"] for i in range(4)]
            seq, t, steps = [], 0.0, np.random.default_rng(1).uniform(0.1, 0.6, 80)
            xs = inputs(np.random.default_rng(2), n_in, 80)
            for x, h in zip(xs, steps):
                fmu.setReal(xi, x)
                seq.append([bits(v) for v in fmu.getReal(ui)])
                fmu.doStep(t, float(h))
                t += float(h)
            runs.append(seq)
        assert runs[0] == runs[1]


#: Bad start values of the NetworkOperatorController: each is refused at
#: exitInitializationMode with the words of the Python controller (operation numbers one past
#: the tables).
BAD_NO = [{"nx": 9}, {"nq": -1}, {"nu": 0}, {"u_min[1]": 1.0}, {"u_max[1]": math.inf},
          {"q[2]": math.nan}, {"x_scale[2]": -math.inf}, {"psi[7,7]": len(BINARY)},
          {"psi[7,7]": -2}, {"psi[3,3]": 1}, {"psi[1,3]": 1}, {"psi[1,9]": len(UNARY)},
          {"out[1]": 33}, {"nu": 2},
          {"sample_period": -1.0}, {"sample_period": math.inf},
          {"u_min[1]": 1e-05, "u_max[1]": 1e-06}]
#: ... and of the ProgramController
BAD_PROGRAM = [{"n_nodes": 1}, {"n_nodes": 300}, {"grid": 2}, {"t_end": -1.0},
               {"t_end": math.nan}, {"grid": 1}, {"grid": 1, "t_node[1]": 0.0,
                                                  "t_node[2]": math.inf},
               {"table[2,3]": math.inf}]


#: ... of the DragEstimator and the SensedNetworkOperatorController (the estimator's parameters:
#: their check is traced from the Python dataclass)
BAD_DRAG = [{"threshold": 0.0}, {"noise": -1.0}, {"bias": math.inf}, {"threshold": math.nan}]
BAD_SENSED = [{"nx": 9}, {"psi[7,7]": len(BINARY)}, {"noise": -0.5}, {"estimate_input": 9},
              {"estimate_input": -1}, {"threshold": -1.0}]


@pytest.mark.parametrize("name,cases", [("NetworkOperatorController", BAD_NO),
                                        ("ProgramController", BAD_PROGRAM),
                                        ("DragEstimator", BAD_DRAG),
                                        ("SensedNetworkOperatorController", BAD_SENSED)])
def test_errors_are_named_as_the_python_controller_names_them(pair, name, cases):
    (py, py_log), (c, c_log) = pair(name)
    for case in cases:
        said = []
        for fmu, log in ((py, py_log), (c, c_log)):
            del log[:]
            with pytest.raises(Exception):
                start(fmu, case)
            said.append(log[0].split(": ", 1)[1])      # after "<model or instance>: "
        assert said[0] == said[1], case
    for fmu in (py, c):
        start(fmu, {})                                   # usable again after the errors


def _variables(path) -> dict:
    md = read_model_description(str(path))
    return {v.name: (v.type, v.causality, v.variability, v.start and float(v.start),
                     v.description, v.unit) for v in md.modelVariables}


@pytest.mark.parametrize("name", sorted(NATIVE_CONTROLLERS))
def test_twin_has_the_pythonfmu_variables(native, fmu_dir, name):
    # names, types, causality, variability, start values, descriptions and units: the same
    # (value references differ: the native FMU numbers its Reals first); fmpy validate passes
    want, got = _variables(fmu_dir / f"{name}.fmu"), _variables(native[name])
    assert list(got) == [n for n in want if want[n][0] == "Real"] + \
        [n for n in want if want[n][0] == "Integer"]
    for n, (kind, causality, variability, s, description, unit) in want.items():
        g = got[n]
        assert g[:3] == (kind, causality, variability) and g[4:] == (description, unit), n
        assert g[3] == s or causality == "output", n
    assert validate_fmu(str(native[name])) == []


def test_program_twin_equals_the_program_controller(pair):
    # 12 random programs (2..257 nodes, 1..6 channels, uniform grid or node times, sampled or
    # not), 200 uneven steps across the nodes and past the end: u and du bitwise equal
    (py, _), (c, _) = pair("ProgramController")
    rng = np.random.default_rng(3)
    names = [f"u[{j}]" for j in range(1, 7)] + [f"du[{j}]" for j in range(1, 7)]
    for case in range(12):
        n, ch = int(rng.integers(2, 258)), int(rng.integers(1, 7))
        times = np.cumsum(rng.uniform(0.01, 2.0, n)) - 0.5 if case % 2 else None
        values = program_values(float(rng.uniform(1, 100)), rng.normal(0, 1, (n, ch)).tolist(),
                                times)
        values["sample_period"] = 0.75 if case % 3 == 0 else 0.0
        runs = []
        for fmu in (py, c):
            vr = start(fmu, values)
            t, seq = 0.0, []
            for h in np.random.default_rng(case).uniform(0.01, 3.0, 200):
                seq.append([bits(v) for v in fmu.getReal([vr[m] for m in names])])
                fmu.doStep(t, float(h))
                t += float(h)
            runs.append(seq)
        assert runs[0] == runs[1], case


@pytest.fixture(scope="module")
def s1_trajectory(fmu_dir):
    """A nominal S1 flight under the GA's basic solution: aero_load, x1..x4 and u at every
    communication point (the estimator's inputs)."""
    from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
    from descent_fmus.synthesis.registry import get_problem
    from descent_fmus.synthesis.systems.reentry.laws import synthesis_basic_law
    p = get_problem("reentry")
    with ClosedLoop(p.wiring, fmu_dir / "Reentry.fmu", fmu_dir / "NetworkOperatorController.fmu",
                    record=("x1", "x2", "x3", "x4", "aero_load")) as loop:
        r = loop.run(p.initial_states[0], synthesis_basic_law().start_values(), record=True)
    return np.column_stack([r["aero_load"], r["x1"], r["x2"], r["x3"], r["x4"], r["ctrl.u[1]"]])


#: Estimator settings: none, seeded accelerometer noise (the generator's draws), noise and bias,
#: a high threshold, a bias alone, sampled every 2 s stepped at 1 s
ESTIMATOR_CASES = [{}, {"noise": 0.05, "noise_seed": 3},
                   {"noise": 0.2, "bias": 0.01, "noise_seed": -7}, {"threshold": 0.5},
                   {"bias": -0.02}, {"sample_period": 2.0, "noise": 0.1, "noise_seed": 1}]


def test_drag_estimator_twin_equals_the_pythonfmu_estimator(pair, s1_trajectory):
    # the sensed drag and navigated state of a whole flight (every 50th drag sample off by
    # 30 %, the state frozen after landing), 6 settings: drag_factor_log and drag_factor
    # bitwise equal at every communication point
    (py, _), (c, _) = pair("DragEstimator")
    names = ["a_drag", "nav_x1", "nav_x2", "nav_x3", "nav_x4", "u"]
    for case in ESTIMATOR_CASES:
        runs = []
        for fmu in (py, c):
            vr = start(fmu, case)
            seq = []
            for i, row in enumerate(s1_trajectory):
                row = [float(v) for v in row]
                row[0] *= 1.3 if i % 50 == 7 else 1.0
                fmu.setReal([vr[n] for n in names], row)
                seq.append([bits(v) for v in fmu.getReal([vr["drag_factor_log"],
                                                           vr["drag_factor"]])])
                fmu.doStep(float(i), 1.0)
            runs.append(seq)
        assert runs[0] == runs[1], case
        assert len({tuple(r) for r in runs[1]}) > 10, case      # the estimate moves


def test_sensed_controller_twin_in_the_sensed_loop(fmu_dir, native, tmp_path):
    # the problem reentry-sensed's loop (the law reads y3 at x[3]): the committed sensed law and
    # the basic solution over 6 dispersed flights, with and without accelerometer noise, on
    # the native loop (native plant if built, native sensed controller) and through the
    # pythonfmu master: every final plant output bitwise equal
    from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
    from descent_fmus.synthesis.fmi.native_loop import NativeContainerLoop
    from descent_fmus.synthesis.registry import get_problem
    from descent_fmus.synthesis.systems.reentry.guidance import default_law
    from descent_fmus.synthesis.systems.reentry.laws import sensed_basic_law
    problem = get_problem("reentry-sensed")
    plant = fmu_dir / "native" / "Reentry.fmu"
    plant = plant if plant.is_file() else fmu_dir / "Reentry.fmu"
    states = problem.initial_states[:6]
    laws = [dict(default_law().start_values()), sensed_basic_law(3).start_values(),
            dict(default_law().start_values(), noise=0.1, noise_seed=5)]
    with ClosedLoop(problem.wiring, fmu_dir / "Reentry.fmu",
                    fmu_dir / "SensedNetworkOperatorController.fmu") as master:
        want = [[master.run(s, v).final for s in states] for v in laws]
    with NativeContainerLoop(problem.wiring, plant,
                             native["SensedNetworkOperatorController"]) as loop:
        got = [[loop.run(s, v).final for s in states] for v in laws]
    assert got == want
    assert {f["status"] for row in want for f in row} == {1}


@pytest.mark.parametrize("name", sorted(NATIVE_CONTROLLERS))
def test_no_python_in_the_binary(native, name, tmp_path):
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm (binutils) not installed")
    with zipfile.ZipFile(native[name]) as z:
        so = [n for n in z.namelist() if n.startswith("binaries/")]
        assert len(so) == 1 and not any(n.endswith(".py") for n in z.namelist())
        lib = tmp_path / "lib.so"
        lib.write_bytes(z.read(so[0]))
    dyn = subprocess.run([nm, "-D", str(lib)], capture_output=True, text=True, check=True).stdout
    symbols = [line.split()[-1] for line in dyn.splitlines() if line.strip()]
    assert not [s for s in symbols if s.startswith(("Py", "_Py")) or "python" in s.lower()]
    exported = {line.split()[-1] for line in dyn.splitlines() if " T " in line}
    assert "fmi2DoStep" in exported and all(s.startswith("fmi2") for s in exported)


# -- the closed loop of native FMUs: one call per flight -------------------------------------------
def s1_laws(n_random: int = 12) -> list:
    """S1 laws: the GA's basic solution, the paper's basic and published laws, the committed
    best law, and ``n_random`` structural variations of the basic solution (the GA's own
    variation operator, 8 variations each, q perturbed)."""
    from descent_fmus.synthesis.methods.encoding import StructureCodec
    from descent_fmus.synthesis.systems.reentry.laws import (paper_basic_law, paper_law,
                                                             synthesis_basic_law)
    from test_native_law import REENTRY_LAW
    basic = synthesis_basic_law()
    codec = StructureCodec(basic.size, basic.nx + len(basic.q))
    rng = np.random.default_rng(11)
    out = [basic, paper_basic_law(), paper_law(), NetworkOperator.load(REENTRY_LAW)]
    for _ in range(n_random):
        psi = codec.apply(basic.psi, [codec.random(rng) for _ in range(8)])
        out.append(basic.with_structure(psi, list(np.asarray(basic.q) *
                                                  rng.uniform(0.5, 1.5, len(basic.q)))))
    return out


@pytest.fixture(scope="module")
def twin_dir(fmu_dir, native, tmp_path_factory):
    """An FMU folder with the reentry problem's FMUs and their native twins in ``native/``: the
    built native plant if there is one (``fmus/native/Reentry.fmu``), else the pythonfmu plant
    standing in for it (the loop is then half native: the test is of the path, not of the
    plant)."""
    d = tmp_path_factory.mktemp("fmus")
    (d / "native").mkdir()
    for name in ("Reentry", "NetworkOperatorController"):
        shutil.copy(fmu_dir / f"{name}.fmu", d / f"{name}.fmu")
    plant = fmu_dir / "native" / "Reentry.fmu"
    shutil.copy(plant if plant.is_file() else fmu_dir / "Reentry.fmu", d / "native" / "Reentry.fmu")
    shutil.copy(native["NetworkOperatorController"], d / "native")
    return d


def test_start_array_is_start_values():
    # what the native loop reads (NetworkOperator.start_array) is what every other path sets
    # (start_values): the same names in the same order, the same values (integers exactly)
    rng = np.random.default_rng(5)
    for k in range(200):
        law = random_law(rng) if k % 2 else every_operation_law(rng)
        names, values = law.start_array()
        sv = law.start_values()
        assert names == tuple(sv) and values.tolist() == list(sv.values())


def test_runner_chooses_the_native_path_when_the_twins_exist(twin_dir, fmu_dir, tmp_path):
    from descent_fmus.synthesis.paths import FMUNotFoundError
    from descent_fmus.synthesis.problems.runner import Runner
    from descent_fmus.synthesis.systems.reentry.wiring import WIRING
    fmus = (twin_dir / "Reentry.fmu", twin_dir / "NetworkOperatorController.fmu")
    assert Runner().choose(WIRING, *fmus)[0] == "native-c"
    assert Runner().choose(WIRING, *fmus, record=("h",))[0] == "native-master"
    assert Runner(native=False).choose(WIRING, *fmus)[0] == "master"
    assert Runner(native=False, container=True).choose(WIRING, *fmus)[0] == "container"
    (tmp_path / "Reentry.fmu").write_bytes(b"")                  # no twins here
    none = (tmp_path / "Reentry.fmu", tmp_path / "NetworkOperatorController.fmu")
    assert Runner().choose(WIRING, *none)[0] == "master"
    with pytest.raises(FMUNotFoundError, match="native/"):
        Runner(native=True).choose(WIRING, *none)
    loop = Runner().load(WIRING, *fmus)
    try:
        assert loop.path == "native-c"
    finally:
        loop.close()


def test_native_loop_equals_the_pythonfmu_master(twin_dir, fmu_dir):
    # 16 S1 laws, nominal flight: every final plant output (status, load_max = J1, L at hf, ...)
    # of the native loop equals the Python master's with the pythonfmu FMUs, bitwise; a second
    # run of the same loop (after a reset) too
    from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
    from descent_fmus.synthesis.fmi.native_loop import NativeContainerLoop
    from descent_fmus.synthesis.registry import get_problem
    problem = get_problem("reentry")
    state = problem.initial_states[0]
    laws = s1_laws()
    with ClosedLoop(problem.wiring, fmu_dir / "Reentry.fmu",
                    fmu_dir / "NetworkOperatorController.fmu") as master:
        want = [master.run(state, law.start_values()).final for law in laws]
    with NativeContainerLoop(problem.wiring, twin_dir / "native" / "Reentry.fmu",
                             twin_dir / "native" / "NetworkOperatorController.fmu") as loop:
        for _ in range(2):
            got = [loop.run(state, law.start_values()).final for law in laws]
            assert got == want
    assert {f["status"] for f in want} >= {1}


def test_evaluator_native_path_gives_the_pythonfmu_objectives(twin_dir, fmu_dir):
    # the evaluator (in-process backend) on the native path and on the pythonfmu path: the same
    # objectives and constraint violations for 16 S1 laws, to the last bit
    from dataclasses import replace

    from descent_fmus.synthesis.registry import get_problem
    from descent_fmus.synthesis.run.evaluation import Evaluator
    problem = get_problem("reentry")
    laws = s1_laws()
    res = {}
    for native_path in (True, False):
        p = replace(problem, runner=replace(problem.runner, native=native_path))
        with Evaluator(p, twin_dir) as ev:
            assert ev.backend.flyer.loop.path == ("native-c" if native_path
                                                  else "master")
            e = ev.evaluate(laws)
            res[native_path] = (e.F.tolist(), list(e.cv))
    assert res[True] == res[False]


def test_native_closed_loop_fmu_and_ssp(twin_dir, fmu_dir, tmp_path):
    # the registered ReentryClosedLoop of the native twins: fmpy validate passes, fmpy simulate
    # at the loop's step ends where the pythonfmu closed loop ends (bitwise), and at output
    # intervals 0.25 s and 0.5 s (the controller keeps sampling every 1 s) within the plant's
    # integration error; the SSP holds the two native FMUs
    from fmpy import simulate_fmu
    from fmpy.ssp.ssd import read_ssd

    from descent_fmus.synthesis.fmi.native.builders.closed_loops import build_native_closed_loops
    from descent_fmus.synthesis.registry import get_system
    specs = [s for s in get_system("reentry").closed_loops
             if s.wiring.name == "ReentryClosedLoop"]
    built = build_native_closed_loops(specs, twin_dir / "native", NATIVE_CONTROLLERS,
                                      say=lambda _: None)
    loop = twin_dir / "native" / "ReentryClosedLoop.fmu"
    assert built == [loop] and validate_fmu(str(loop)) == []
    names = ["L", "load_max", "status", "t_end"]
    want = simulate_fmu(fmu_dir / "ReentryClosedLoop.fmu", output=names)[-1]
    got = simulate_fmu(loop, output=names)[-1]
    assert [bits(got[n]) for n in names] == [bits(want[n]) for n in names]
    for interval in (0.25, 0.5):
        res = simulate_fmu(loop, output=names, output_interval=interval)
        assert res["time"][1] == interval and res[-1]["status"] == 1
        assert res[-1]["load_max"] == pytest.approx(want["load_max"], rel=2e-3)
    ssd = read_ssd(str(twin_dir / "native" / "ReentryClosedLoop.ssp"), validate=True)
    assert [e.source for e in ssd.system.elements] == ["resources/Reentry.fmu",
                                                       "resources/NetworkOperatorController.fmu"]


def test_native_closed_loop_in_a_c_host(twin_dir, fmu_dir, tmp_path):
    # the native ReentryClosedLoop (fmpy's container FMU, C, of the two native twins) run by the
    # C host tests/fmi/native/fmi2_host.c with LD_PRELOAD, PYTHONHOME and PYTHONPATH unset: the
    # same final L and load_max as the pythonfmu FMUs under the Python master, bitwise
    from descent_fmus.synthesis.fmi.native.builders.closed_loops import build_native_closed_loops
    from descent_fmus.synthesis.registry import get_problem, get_system
    from test_native_law import _host
    if not (fmu_dir / "native" / "Reentry.fmu").is_file():
        pytest.skip("the native Reentry plant is not built (python build_fmus.py)")
    loop = twin_dir / "native" / "ReentryClosedLoop.fmu"
    if not loop.is_file():
        build_native_closed_loops([s for s in get_system("reentry").closed_loops
                                   if s.wiring.name == "ReentryClosedLoop"],
                                  twin_dir / "native", NATIVE_CONTROLLERS, say=lambda _: None)
    work = tmp_path / "loop"
    with zipfile.ZipFile(loop) as z:
        z.extractall(work)
    md = read_model_description(str(loop))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    env = {k: v for k, v in os.environ.items()
           if k not in ("LD_PRELOAD", "PYTHONHOME", "PYTHONPATH")}
    env["PATH"] = "/usr/bin:/bin"
    lib = work / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    res = subprocess.run([str(_host(tmp_path)), str(lib), md.guid, "",
                          f"{vr['L']},{vr['load_max']}", (work / "resources").as_uri()],
                         input="\n" * 301, capture_output=True, text=True, env=env, check=True)
    rows = [[float.fromhex(t) for t in line.split()] for line in res.stdout.splitlines()]
    problem = get_problem("reentry")
    from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
    with ClosedLoop(problem.wiring, fmu_dir / "Reentry.fmu",
                    fmu_dir / "NetworkOperatorController.fmu") as master:
        want = master.run(problem.initial_states[0]).final
    assert len(rows) == 301
    assert [bits(v) for v in rows[-1]] == [bits(want["L"]), bits(want["load_max"])]
