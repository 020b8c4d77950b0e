"""Native law FMUs (C, no Python in the host) against the pythonfmu controller they replace.

Oracles: the pythonfmu NetworkOperatorController FMU loaded with the same law (bitwise equal
outputs: both evaluate the one operation table with the platform's C math library), the
evaluator's closed-loop numbers (the Pareto rows of a synthesis), the recorded numbers of the
committed lunar-descent law (tests/reference/lunar_descent_law.meta.json), and a C host written
here that loads the FMU through the FMI 2.0 API alone.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.ssp.ssd import read_ssd
from fmpy.validation import validate_fmu

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop

from descent_fmus.synthesis.fmi.slave import load_slave
from descent_fmus.synthesis.run.evaluation import Evaluator
from descent_fmus.synthesis.fmi.law_files import export_law_files
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
from descent_fmus.synthesis.fmi.native.builders.law_fmu import build_law_fmu, write_law_fmu
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law, paper_law

from fmi_calls import bits, start
from law_samples import DESCENT_LAW, REENTRY_LAW, every_operation_law

#: extreme inputs: zeros of both signs, the largest and smallest doubles, inf, NaN, the clamp
EXTREMES = [0.0, -0.0, 1e300, -1e300, math.inf, -math.inf, math.nan, 1e-300, -1e-300,
            5e-324, 1.7976931348623157e308, 1e8, -1e8, 1e-7, -1e-7, 1.0, -1.0, 0.01, 18.5]

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (CI installs gcc)")


def inputs(rng, nx: int, n: int) -> list:
    """``n`` random input vectors over many scales, then the extremes (for 2 inputs: every
    pair of them)."""
    scales = rng.choice([1e-3, 0.3, 3.0, 100.0, 1e6], size=(n, 1))
    xs = [list(map(float, row)) for row in rng.normal(0.0, 1.0, (n, nx)) * scales]
    if nx == 2:
        xs += [[a, b] for a in EXTREMES for b in EXTREMES]
    else:
        xs += [[a] * nx for a in EXTREMES] + [list(map(float, rng.choice(EXTREMES, nx)))
                                              for _ in range(400)]
    return xs


def outputs_of(fmu, vr, law, xs) -> list:
    xi = [vr[f"x[{k + 1}]"] for k in range(law.nx)]
    ui = [vr[f"u[{k + 1}]"] for k in range(len(law.outputs))]
    out = []
    for x in xs:
        fmu.setReal(xi, x)
        out.append(fmu.getReal(ui))
    return out


@pytest.fixture(scope="module")
def generic(fmu_dir):
    fmu = load_slave(fmu_dir / "NetworkOperatorController.fmu", "generic")
    yield fmu
    fmu.terminate()
    fmu.freeInstance()


def laws():
    rng = np.random.default_rng(13)
    return [("reentry", NetworkOperator.load(REENTRY_LAW)),
            ("lunar-descent", NetworkOperator.load(DESCENT_LAW)),
            ("paper", paper_law())] + \
        [(f"every-op-{k}", every_operation_law(rng)) for k in range(3)]


@pytest.mark.parametrize("name,law", laws(), ids=[n for n, _ in laws()])
def test_native_equals_pythonfmu_controller(name, law, generic, tmp_path):
    # >= 2000 inputs per law (> 10 000 over the six laws), extremes included: every output of
    # the compiled law FMU and of the interpreter law FMU (the law as its start values, no
    # compile) bitwise equal to the pythonfmu controller's, and finite; both pass fmpy validate
    compiled = build_law_fmu(law, tmp_path / "Law.fmu", "Law")
    interpreted = write_law_fmu(law, tmp_path / "Interpreted.fmu", "Interpreted")
    rng = np.random.default_rng(len(name))
    xs = inputs(rng, law.nx, 1700)
    assert len(xs) >= 2000
    want = outputs_of(generic, start(generic, law.start_values()), law, xs)
    for path in (compiled, interpreted):
        assert validate_fmu(str(path)) == []
        assert path.stat().st_size <= 200 * 1024
        native = load_slave(path, "native")
        try:      # start() resets the instance first: the reset keeps the law's start values
            got = outputs_of(native, start(native, {}), law, xs)
        finally:
            native.terminate()
            native.freeInstance()
        for x, a, b in zip(xs, want, got):
            assert [bits(v) for v in a] == [bits(v) for v in b], (path.name, x, a, b)
            assert all(math.isfinite(v) for v in b)


def test_parameters_are_tunable_and_checked(tmp_path):
    # q is tunable (set between steps: the next output uses it); an invalid start value is
    # an fmi2Error with the parameter named (the same rules as the pythonfmu controller)
    law = paper_basic_law()
    log = []
    fmu = load_slave(build_law_fmu(law, tmp_path / "Basic.fmu", "Basic"), "basic", log)
    try:
        vr = start(fmu, {})
        fmu.setReal([vr["x[1]"], vr["x[2]"]], [0.01, -0.02])
        assert fmu.getReal([vr["u[1]"]])[0] == law([0.01, -0.02])[0]
        fmu.doStep(0.0, 1.0)
        fmu.setReal([vr["q[1]"]], [5.0])
        assert fmu.getReal([vr["u[1]"]])[0] == law.with_q([5.0, law.q[1]])([0.01, -0.02])[0]
        with pytest.raises(Exception):
            fmu.setReal([vr["u_min[1]"]], [0.0])       # fixed after initialisation
        assert "fixed parameter" in log[-1]
        with pytest.raises(Exception):
            start(fmu, {"u_min[1]": 1.0})              # u_min > u_max
        assert "u_min[1] = 1, u_max[1] = 0.2: need finite bounds" in log[-1]
        with pytest.raises(Exception):
            start(fmu, {"q[2]": math.inf})
        assert "parameter q[2] must be finite" in log[-1]
        start(fmu, {})                                  # usable again after the errors
        fmu.setReal([vr["x[1]"], vr["x[2]"]], [1.0, 1.0])
        assert fmu.getReal([vr["u[1]"]])[0] == 0.2
    finally:
        fmu.freeInstance()


def test_sampled_like_the_pythonfmu_controller(generic, tmp_path):
    # sample_period = 3 s stepped at 1 s: outputs held (inputs ignored) between samples, as
    # the pythonfmu controller does (models/fmu_support.py)
    law = NetworkOperator.load(REENTRY_LAW)
    native = load_slave(build_law_fmu(law, tmp_path / "S.fmu", "S"), "native")
    rng = np.random.default_rng(4)
    try:
        res = []
        for fmu, values in ((generic, law.start_values()), (native, {})):
            vr = start(fmu, dict(values, sample_period=3.0))
            seq = []
            for k in range(12):
                fmu.setReal([vr["x[1]"], vr["x[2]"]], list(rng.normal(0, 0.05, 2)))
                seq.append(fmu.getReal([vr["u[1]"]])[0])
                fmu.doStep(float(k), 1.0)
            res.append(seq)
            rng = np.random.default_rng(4)
    finally:
        native.freeInstance()
    assert res[0] == res[1]
    assert len(set(res[1])) < len(res[1])      # held values repeat


@pytest.fixture(scope="module")
def reentry_export(fmu_dir, tmp_path_factory):
    law = NetworkOperator.load(REENTRY_LAW)
    out = tmp_path_factory.mktemp("reentry_law")
    return law, export_law_files(law, out, law_fmu="native", fmu_dir=fmu_dir,
                                 problem=get_problem("reentry"), closed_loop=True,
                                 identifier="ReentryLaw")


def test_closed_loop_reproduces_the_pareto_row(reentry_export, fmu_dir):
    # the Pareto row of a law is what the evaluator computes; the exported closed loop (the
    # plant's native twin + the native law) under fmpy simulate gives the same J1 and miss
    # (1e-9), and so does the Python master with the pythonfmu plant and the native law
    law, files = reentry_export
    problem = get_problem("reentry")
    with Evaluator(problem, fmu_dir) as ev:
        (j1, j2), = ev.evaluate([law]).F
    res = simulate_fmu(files["closed_loop_fmu"], output=["L", "load_max", "status"])[-1]
    assert res["status"] == 1
    assert res["load_max"] == pytest.approx(j1, rel=1e-9)
    assert abs(res["L"] - 1_400_000.0) == pytest.approx(j2, rel=1e-9)
    with ClosedLoop(problem.wiring, fmu_dir / "Reentry.fmu", files["controller_fmu"]) as loop:
        f = problem.evaluate([loop.run(s) for s in problem.initial_states]).f
    assert f == (j1, j2)
    # the SSP of the same loop (schema-checked) holds the native law, not the generic controller
    ssd = read_ssd(files["ssp"], validate=True)
    assert [e.source for e in ssd.system.elements] == ["resources/Reentry.fmu",
                                                       "resources/ReentryLaw.fmu"]


def test_two_output_law_reproduces_its_recorded_numbers(fmu_dir, tmp_path):
    # tests/reference/lunar_descent_law.meta.json records J1, J2 of the committed S5 law over
    # its initial states (two outputs, scaled inputs); the native law flown by the Python
    # master with the pythonfmu plant reproduces them (1e-9)
    law = NetworkOperator.load(DESCENT_LAW)
    meta = json.loads(DESCENT_LAW.with_suffix(".meta.json").read_text())
    problem = get_problem("lunar-descent")
    path = build_law_fmu(law, tmp_path / "DescentLaw.fmu", "DescentLaw")
    plant = problem.fmu_paths(fmu_dir)[0]
    with ClosedLoop(problem.wiring, plant, path, record=problem.record) as loop:
        results = [loop.run(s, record=bool(problem.record)) for s in problem.initial_states]
    (j1, j2) = problem.evaluate(results).f
    assert (j1, j2) == pytest.approx((meta["J1"], meta["J2"]), rel=1e-9)


def test_closed_loop_carries_the_plants_native_twin(reentry_export, fmu_dir, tmp_path):
    # a plant with a native twin (fmus/native/Reentry.fmu) goes into the exported closed loop as
    # that twin: no pythonfmu binary and no Python source in the container; without the twin
    # (a folder holding only the pythonfmu plant) the pythonfmu plant goes in
    law, files = reentry_export
    assert files["closed_loop_plant"] == "native"
    with zipfile.ZipFile(files["closed_loop_fmu"]) as z:
        names = z.namelist()
    assert "resources/Reentry/binaries/linux64/Reentry.so" in names
    assert not [n for n in names if "pythonfmu" in n or n.endswith(".py")]
    alone = tmp_path / "fmus"
    alone.mkdir()
    shutil.copy(fmu_dir / "Reentry.fmu", alone / "Reentry.fmu")
    out = export_law_files(law, tmp_path / "law", law_fmu="native", fmu_dir=alone,
                           problem=get_problem("reentry"), closed_loop=True)
    assert out["closed_loop_plant"] == "pythonfmu"
    with zipfile.ZipFile(out["closed_loop_fmu"]) as z:
        assert "resources/Reentry/binaries/linux64/Reentry.pythonfmu.so" in z.namelist()


def test_no_python_in_the_binary(reentry_export):
    _, files = reentry_export
    with zipfile.ZipFile(files["controller_fmu"]) as z:
        names = z.namelist()
        so = [n for n in names if n.startswith("binaries/")]
        assert so == ["binaries/linux64/ReentryLaw.so"]
        assert not any(n.endswith(".py") for n in names)
        data = z.read(so[0])
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm (binutils) not installed")
    lib = Path(files["controller_fmu"]).with_suffix(".so")
    lib.write_bytes(data)
    dyn = subprocess.run([nm, "-D", str(lib)], capture_output=True, text=True, check=True).stdout
    symbols = [line.split()[-1] for line in dyn.splitlines() if line.strip()]
    assert not [s for s in symbols if s.startswith(("Py", "_Py")) or "python" in s.lower()]
    needed = subprocess.run(["ldd", str(lib)], capture_output=True, text=True).stdout
    assert "python" not in needed.lower()
    exported = {s for line in dyn.splitlines() if " T " in line for s in [line.split()[-1]]}
    assert "fmi2DoStep" in exported and all(s.startswith("fmi2") for s in exported)


def _host(tmp_path, libs=()) -> Path:
    exe = tmp_path / "fmi2_host"
    subprocess.run([find_compiler(), "-std=c99", "-O1", "-o", str(exe),
                    str(Path(__file__).parent / "fmi2_host.c"), "-ldl", *libs], check=True)
    return exe


def _run_host(exe, fmu: Path, workdir: Path, law, xs) -> list:
    with zipfile.ZipFile(fmu) as z:
        z.extractall(workdir)
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    ins = ",".join(str(vr[f"x[{k + 1}]"]) for k in range(law.nx))
    outs = ",".join(str(vr[f"u[{k + 1}]"]) for k in range(len(law.outputs)))
    env = {k: v for k, v in os.environ.items()
           if k not in ("LD_PRELOAD", "PYTHONHOME", "PYTHONPATH")}
    env["PATH"] = "/usr/bin:/bin"
    lib = workdir / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    text = "\n".join(" ".join(float.hex(v) if math.isfinite(v) else repr(v) for v in x)
                     for x in xs) + "\n"
    # the resources folder: an interpreter law FMU reads its law's start values there
    res = subprocess.run([str(exe), str(lib), md.guid, ins, outs,
                          (workdir / "resources").as_uri()], input=text,
                         capture_output=True, text=True, env=env, check=True)
    return [[float.fromhex(t) for t in line.split()] for line in res.stdout.splitlines()]


def test_a_c_host_runs_it_without_python(reentry_export, tmp_path):
    # a host written in C (fmi2_host.c beside this file), LD_PRELOAD/PYTHONHOME/PYTHONPATH unset:
    # the outputs equal the law evaluated in Python, bitwise
    law, files = reentry_export
    xs = inputs(np.random.default_rng(8), 2, 500)
    got = _run_host(_host(tmp_path), Path(files["controller_fmu"]), tmp_path / "fmu", law, xs)
    assert len(got) == len(xs)
    for x, u in zip(xs, got):
        assert bits(u[0]) == bits(law(x)[0]), x


def test_sources_rebuild_the_fmu(reentry_export, tmp_path):
    # the FMU alone is enough: compile the files its model description lists (sources/), with
    # no descent-fmus code, and get the same outputs (bitwise) through the same C host
    law, files = reentry_export
    fmu = Path(files["controller_fmu"])
    work = tmp_path / "unzipped"
    with zipfile.ZipFile(fmu) as z:
        z.extractall(work)
    md = read_model_description(str(fmu))
    sources = md.buildConfigurations[0].sourceFileSets[0].sourceFiles
    # the interpreter's C (the law is its start values, in resources/start_values.txt)
    assert set(sources) == {"fmi2_cs.c", "no_model.c", "no_interp.c"}
    lib = work / "binaries" / "linux64" / "ReentryLaw.so"
    lib.unlink()
    subprocess.run([find_compiler(), "-shared", "-fPIC", "-O2", "-I", str(work / "sources"),
                    *[str(work / "sources" / f) for f in sources], "-o", str(lib), "-lm"],
                   check=True)
    rebuilt = tmp_path / "Rebuilt.fmu"
    with zipfile.ZipFile(rebuilt, "w") as z:
        for p in sorted(work.rglob("*")):
            if p.is_file():
                z.write(p, p.relative_to(work).as_posix())
    xs = inputs(np.random.default_rng(9), 2, 300)
    exe = _host(tmp_path)
    a = _run_host(exe, fmu, tmp_path / "a", law, xs)
    b = _run_host(exe, rebuilt, tmp_path / "b", law, xs)
    assert [[bits(v) for v in r] for r in a] == [[bits(v) for v in r] for r in b]
    assert [bits(r[0]) for r in b] == [bits(law(x)[0]) for x in xs]     # the law, not another


@pytest.mark.skipif(shutil.which("cmake") is None, reason="fmpy compile needs cmake")
def test_fmpy_compile_rebuilds_it(reentry_export, tmp_path):
    # another tool's build of the shipped sources (fmpy compile: CMake + the <SourceFiles>).
    # fmpy's CMake project does not link the math library: that binary takes exp, tanh, ...
    # from the host process (a Python host has them), so this C host links -lm itself
    law, files = reentry_export
    fmu = tmp_path / "ReentryLaw.fmu"
    shutil.copy(files["controller_fmu"], fmu)
    subprocess.run([sys.executable, "-m", "fmpy", "compile", str(fmu)], check=True,
                   capture_output=True)
    xs = inputs(np.random.default_rng(10), 2, 200)
    got = _run_host(_host(tmp_path, ["-Wl,--no-as-needed", "-lm"]), fmu, tmp_path / "fmu", law,
                    xs)
    for x, u in zip(xs, got):
        assert bits(u[0]) == bits(law(x)[0]), x


def test_fmu_rejects_calls_out_of_order(tmp_path):
    log = []
    fmu = load_slave(build_law_fmu(paper_basic_law(), tmp_path / "B.fmu", "B"), "b",
                     log)
    try:
        with pytest.raises(Exception):
            fmu.doStep(0.0, 1.0)                 # before initialisation
        assert "before fmi2ExitInitializationMode" in log[-1]
        with pytest.raises(Exception):
            fmu.setReal([999], [1.0])
        assert "no Real variable has value reference 999" in log[-1]
    finally:
        fmu.freeInstance()


# -- the interpreter law FMU (the law as start values, no compile) ---------------------------
def test_interpreter_law_flies_as_the_compiled_one(reentry_export, fmu_dir, tmp_path):
    # the S1 closed loop (Python master, pythonfmu plant) with the exported law FMU (the
    # interpreter with the law's start values) and with the law FMU compiled from law.c: the
    # same trajectory to the bit, every recorded signal at every step
    law, files = reentry_export
    problem = get_problem("reentry")
    compiled = build_law_fmu(law, tmp_path / "Compiled.fmu", "Compiled")
    runs = []
    for ctrl in (files["controller_fmu"], compiled):
        with ClosedLoop(problem.wiring, fmu_dir / "Reentry.fmu", ctrl) as loop:
            runs.append([loop.run(s, record=True) for s in problem.initial_states])
    for a, b in zip(*runs):
        assert a.final == b.final and np.array_equal(a.time, b.time)
        assert a.outputs.keys() == b.outputs.keys()
        for key in a.outputs:              # bitwise: the same doubles, NaN nowhere
            assert a.outputs[key].tobytes() == b.outputs[key].tobytes(), key
    assert len(runs[0][0].time) > 100 and any(k.startswith("ctrl.") for k in runs[0][0].outputs)


@pytest.mark.parametrize("text", ["3 abc\n", "99999 1.0\n", "1 0.5\n"],
                         ids=["no-number", "no-variable", "an-output"])
def test_bad_start_values_resource_fails_instantiation(tmp_path, text):
    # a malformed resources/start_values.txt (no value, no such variable, an output): the
    # instantiation fails with one logged line naming the file and the line
    law = NetworkOperator.load(REENTRY_LAW)
    path = write_law_fmu(law, tmp_path / "Law.fmu", "Law")
    md = read_model_description(str(path))
    u1 = next(v.valueReference for v in md.modelVariables if v.name == "u[1]")
    text = text.replace("1 0.5", f"{u1} 0.5")
    bad = tmp_path / "Bad.fmu"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(bad, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "resources/start_values.txt":
                data = data + text.encode()
            dst.writestr(item, data)
    log = []
    with pytest.raises(Exception):
        load_slave(bad, "bad", log)
    assert len(log) == 1 and "resources/start_values.txt line" in log[0], log


def test_a_law_beyond_the_interpreter_is_compiled(tmp_path):
    # 36 nodes (the interpreter holds 32): the export compiles the law's C instead, and that
    # FMU gives the law's outputs bitwise (oracle: the law evaluated in Python)
    L = 36
    psi = np.zeros((L, L), dtype=int)
    for j in range(3, L):
        psi[j, j], psi[j - 1, j] = 1, 1          # a chain of sums: node j = node j-1
    psi[0, 3], psi[2, 3] = 1, 2                  # node 4 = x1 + q1 ** 2 (rho 2: square)
    law = NetworkOperator(psi, nx=2, q=[0.5], outputs=[L], bounds=[(-1.0, 1.0)])
    files = export_law_files(law, tmp_path / "big", law_fmu="native", identifier="Big")
    with zipfile.ZipFile(files["controller_fmu"]) as z:
        assert "sources/law.c" in z.namelist()
        assert "resources/start_values.txt" not in z.namelist()
    xs = [[0.1, 0.2], [-0.3, 5.0], [1e300, -1.0], [0.0, -0.0]]
    fmu = load_slave(files["controller_fmu"], "big")
    try:
        got = outputs_of(fmu, start(fmu, {}), law, xs)
    finally:
        fmu.freeInstance()
    assert [bits(u[0]) for u in got] == [bits(law(x)[0]) for x in xs]


def test_the_interpreter_fmus_cache_key_follows_the_operation_table(monkeypatch, tmp_path):
    # a stale cache must not survive a new operation: the interpreter FMU kept in the cache
    # folder is keyed by its generated no_operations.h too (the table rendered to C).  Oracle:
    # the same call with the table's text changed names another file; unchanged, the same one.
    from descent_fmus.synthesis.fmi.native.builders import controllers, law_fmu
    monkeypatch.setattr(law_fmu, "_INTERPRETERS", {})
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path))
    built = []              # the key alone is under test: the compile is replaced by a write
    monkeypatch.setattr(controllers, "build_network_operator_controller",
                        lambda dest, cc: built.append(Path(dest).write_bytes(b"fmu")))
    (tmp_path / "law_interpreter").mkdir()
    first = law_fmu.interpreter_fmu()
    law_fmu._INTERPRETERS.clear()
    assert law_fmu.interpreter_fmu() == first
    law_fmu._INTERPRETERS.clear()
    table = law_fmu.interpreter_operations_h()
    monkeypatch.setattr(law_fmu, "interpreter_operations_h", lambda: table + "/* one more */")
    assert law_fmu.interpreter_fmu() != first
    assert len(built) == 2          # built once per key, found the second time
