"""The C master (synthesis/fmi/native/c/master/master.c): the evaluator's native path.

Oracle: the Python master (``ClosedLoop``) on the same native FMUs -- the master algorithm's
definition -- and fmpy's container FMU: the same FMI calls in the same order, so every final plant
output, the steps taken and the stop flag must agree bit for bit (tolerance 0).
"""
from __future__ import annotations

import math
import shutil

import numpy as np
import pytest

from descent_fmus.synthesis.fmi.c_master_loop import CMasterLoop, MasterUnavailable, master_library
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.fmi.slave import FMUError
from descent_fmus.synthesis.fmi.native_loop import NativeContainerLoop, native_fmus
from descent_fmus.synthesis.fmi.start_values import StartValues

pytestmark = pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None,
                                reason="needs a C compiler")


def _twins_or_skip(problem, fmu_dir):
    twins = native_fmus(problem.wiring, *problem.fmu_paths(fmu_dir))
    if twins is None:
        pytest.skip(f"native twins of {problem.wiring.name} not built")
    return twins


def _same(a, b):
    # bitwise: NaN only equal to NaN, -0.0 distinct from 0.0
    assert a.keys() == b.keys()
    for k in a:
        x, y = a[k], b[k]
        assert np.float64(x).tobytes() == np.float64(y).tobytes(), (k, x, y)


@pytest.mark.parametrize("name", ["reentry", "reentry-robust", "reentry-sensed",
                                  "reentry-guided", "lunar-descent"])
def test_c_master_equals_the_python_master_and_the_container(name, fmu_dir):
    # every registered problem with native twins: its basic law from its first three initial
    # states, and a second round on the same loop (after the resets)
    from descent_fmus.synthesis.registry import get_problem
    problem = get_problem(name)
    twins = _twins_or_skip(problem, fmu_dir)
    law = problem.basic()
    states = problem.initial_states[:3]
    with ClosedLoop(problem.wiring, *twins) as py:
        want = [py.run(s, law.start_values()) for s in states]
    with NativeContainerLoop(problem.wiring, *twins) as box:
        boxed = [box.run(s, StartValues.of_law(law)).final for s in states]
    with CMasterLoop(problem.wiring, *twins) as cm:
        for _ in range(2):
            for s, w, b in zip(states, want, boxed):
                got = cm.run(s, StartValues.of_law(law))
                _same(got.final, w.final)
                _same(got.final, b)
                assert (got.steps, got.stopped, got.t_final) == (w.steps, w.stopped, w.t_final)
            # the law's start values as a dict give the same flight
            _same(cm.run(states[0], law.start_values()).final, want[0].final)


def test_c_master_runs_every_native_closed_loop(fmu_dir):
    # the registered closed loops whose components are native (telescopes, S5, S1 ...), each
    # with its own controller defaults, at their default start values
    from descent_fmus.synthesis.registry import closed_loop_specs
    flown = 0
    for spec in closed_loop_specs():
        w, d = spec.wiring, fmu_dir / "native"
        ctrl = d / (f"{w.name}Controller.fmu" if spec.controller_defaults is not None
                    else f"{w.controller}.fmu")
        plant = d / f"{w.plant}.fmu"
        if not (plant.is_file() and ctrl.is_file()):
            continue
        with ClosedLoop(w, plant, ctrl) as py, CMasterLoop(w, plant, ctrl) as cm:
            want, got = py.run(), cm.run()
        _same(got.final, want.final)
        assert (got.steps, got.stopped) == (want.steps, want.stopped), w.name
        flown += 1
    assert flown >= 5


def test_no_compiler_falls_back_to_the_container(fmu_dir, monkeypatch, tmp_path):
    # no master built and no compiler: the runner says so once and takes fmpy's container
    from descent_fmus.synthesis.fmi import loop as loop_mod
    from descent_fmus.synthesis.problems import runner as runner_mod
    from descent_fmus.synthesis.registry import get_problem
    problem = get_problem("reentry")
    fmus = problem.fmu_paths(fmu_dir)
    _twins_or_skip(problem, fmu_dir)
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", "no-such-compiler-here")
    monkeypatch.setattr(loop_mod, "_WARNED", [])
    with pytest.raises(MasterUnavailable, match="no C compiler"):
        master_library()
    with pytest.warns(RuntimeWarning, match="container"):
        assert runner_mod.Runner().choose(problem.wiring, *fmus)[0] == "native-container"
    loop = runner_mod.Runner().load(problem.wiring, *fmus)
    try:
        assert loop.path == "native-container"
    finally:
        loop.close()
    # outputs wanted at t = 0 only: the container cannot read them there, so the master on the
    # twins records them (the flights then record: runner.records)
    r = runner_mod.Runner()
    assert r.choose(problem.wiring, *fmus, initial=("h",))[0] == "native-master"
    loop = r.load(problem.wiring, *fmus, initial=("h",))
    try:
        assert loop.path == "native-master" and "h" in loop.record
        assert runner_mod.records(loop, problem.with_(initial=("h",)))
    finally:
        loop.close()


def test_bad_input_and_failing_flights(fmu_dir, tmp_path):
    from descent_fmus.synthesis.registry import get_problem
    problem = get_problem("reentry-guided")
    twins = _twins_or_skip(problem, fmu_dir)
    law = problem.basic()
    state = problem.initial_states[0]
    with CMasterLoop(problem.wiring, *twins) as cm:
        with pytest.raises(KeyError, match="no_such_parameter"):
            cm.run(state, {"no_such_parameter": 1.0})
        names, values = law.start_array()
        bad = values.copy()
        k = next(i for i, n in enumerate(names) if n.startswith("q["))
        bad[k] = math.nan
        with pytest.raises(ValueError, match="must be finite"):
            cm.run(state, StartValues(names, bad))
        with pytest.raises(ValueError, match="records no trajectory"):
            cm.run(state, StartValues.of_law(law), record=True)
        with pytest.raises(ValueError, match="Gauss-Seidel"):
            cm.run(state, StartValues.of_law(law), scheme="jacobi")
        # the twin refuses a parameter at initialisation: the flight fails with its words,
        # and the loop flies on afterwards
        with pytest.raises(FMUError, match="dt_pred"):
            cm.run(state, {**law.start_values(), "replan": 1, "dt_pred": 1e-4})
        with ClosedLoop(problem.wiring, *twins) as py:
            _same(cm.run(state, StartValues.of_law(law)).final,
                  py.run(state, law.start_values()).final)
    with pytest.raises(FMUError, match="no binary"):
        broken = tmp_path / "Empty.fmu"
        import zipfile
        with zipfile.ZipFile(twins[0]) as src, zipfile.ZipFile(broken, "w") as dst:
            for item in src.infolist():
                if not item.filename.startswith("binaries/"):
                    dst.writestr(item, src.read(item.filename))
        CMasterLoop(problem.wiring, broken, twins[1])


def test_a_batch_flies_as_its_flights_one_by_one_failures_in_the_middle(fmu_dir):
    # Oracle: run() of each flight on the same loop (dm_fly per flight) -- run_many's one
    # dm_fly_many call must give the same final outputs bit for bit, the same steps and stop
    # flags, and for a failing flight the same exception (type and text) as run(), without
    # disturbing the flights after it: a value the twin refuses at initialisation (its dt_pred
    # check: a failure inside dm_fly_many) and a non-finite parameter (refused before the
    # call), both in the middle of the batch
    from descent_fmus.synthesis.registry import get_problem
    problem = get_problem("reentry-guided")
    twins = _twins_or_skip(problem, fmu_dir)
    law = problem.basic()
    names, values = law.start_array()
    names = names + ("replan", "dt_pred")
    values = np.concatenate([values, [1.0, 2.0]])
    k = next(i for i, n in enumerate(names) if n.startswith("q["))
    rng = np.random.default_rng(3)
    ctrl = []
    for _ in range(7):
        v = values.copy()
        v[k] *= 1.0 + 0.2 * rng.standard_normal()
        ctrl.append(v)
    ctrl[2][-1] = 1e-4                    # refused by the twin
    ctrl[4][k] = math.nan                 # refused by the loop
    states = problem.initial_states[:2]
    flights = [(s, StartValues(names, c)) for c in ctrl for s in states]
    with CMasterLoop(problem.wiring, *twins) as cm:
        want = []
        for s, c in flights:
            try:
                want.append(cm.run(s, c))
            except (FMUError, ValueError) as exc:
                want.append(exc)
        got = cm.run_many(flights)
        # values by other names than the batch's first (a dict): one call a flight, same results
        mixed = cm.run_many(flights[:2] + [(states[0], law.start_values())])
        alone = cm.run(states[0], law.start_values())
    assert len(got) == len(flights)
    failed = []
    for i, (w, g) in enumerate(zip(want, got)):
        if isinstance(w, Exception):
            assert type(g) is type(w) and str(g) == str(w)
            failed.append(i)
            continue
        _same(g.final, w.final)
        assert (g.steps, g.stopped, g.t_final, g.start) == (w.steps, w.stopped, w.t_final,
                                                              w.start)
    assert failed == [4, 5, 8, 9]
    assert isinstance(got[4], FMUError) and "dt_pred" in str(got[4])
    assert isinstance(got[8], ValueError) and "must be finite" in str(got[8])
    _same(mixed[0].final, want[0].final)
    _same(mixed[2].final, alone.final)


def test_outputs_at_t0_are_a_recordings_first_sample(fmu_dir):
    # Oracle: the Python master's recording on the same native FMUs -- its first sample is
    # taken at t = 0 after the first exchange of values; the C master's ``initial`` outputs
    # (read there without a recording, an objective's initial(...)) must equal it bit for bit,
    # by run() and by run_many(), over several initial states; the final outputs are unchanged
    from descent_fmus.synthesis.registry import get_problem
    problem = get_problem("reentry")
    twins = _twins_or_skip(problem, fmu_dir)
    law = problem.basic()
    states = problem.initial_states[:3]
    names = ("h", "load", "aero_load")
    with ClosedLoop(problem.wiring, *twins, record=list(names)) as py:
        want = [py.run(s, law.start_values(), record=True) for s in states]
    with CMasterLoop(problem.wiring, *twins, initial=names) as cm, \
            CMasterLoop(problem.wiring, *twins) as plain:
        one = [cm.run(s, StartValues.of_law(law)) for s in states]
        many = cm.run_many([(s, StartValues.of_law(law)) for s in states])
        bare = plain.run(states[0], StartValues.of_law(law))
    for w, a, b in zip(want, one, many):
        first = {n: float(w.outputs[n][0]) for n in names}
        assert first["h"] != w.final["h"]       # a start, not an end
        _same(a.initial, first)
        _same(b.initial, first)
        _same(a.final, w.final)
    assert bare.initial == {} and bare.final == one[0].final
    with pytest.raises(KeyError, match="no variable 'nope'"):
        CMasterLoop(problem.wiring, *twins, initial=("nope",))
    parameter = next(iter(states[0]))              # a start value, not an output
    with pytest.raises(KeyError, match=f"{parameter!r} is not a Real output"):
        CMasterLoop(problem.wiring, *twins, initial=(parameter,))
