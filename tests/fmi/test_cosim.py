"""Closed-loop co-simulation through the FMUs: step size, container FMU, SSP, second tool."""
from __future__ import annotations

import zipfile

import pytest
from fmpy import simulate_fmu
from fmpy.ssp.ssd import read_ssd
from fmpy.validation import validate_fmu

from descent_fmus.models.reentry import ReentryParams, downrange, simulate
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.paths import FMUNotFoundError
from descent_fmus.synthesis.systems.reentry import wiring as spec
from descent_fmus.synthesis.systems.reentry.flight import fly, load_loop
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law, paper_law


@pytest.fixture(scope="module")
def loop(fmu_dir):
    lp = load_loop(fmu_dir)
    yield lp
    lp.close()


@pytest.mark.parametrize("law", [paper_basic_law(), paper_law()],
                         ids=["basic", "paper"])
def test_halving_the_communication_step_changes_j1_by_less_than_half_a_percent(loop, law):
    # the chosen communication step (reentry problems.STEP) is converged: halving it moves J1
    # by less than 0.5 % (independent check: the same law at half the step)
    a = fly(law, loop=loop).objectives
    b = fly(law, loop=loop, step=spec.STEP / 2).objectives
    assert a["landed"] and b["landed"]
    assert abs(a["J1"] - b["J1"]) / b["J1"] < 0.005


def test_closed_loop_equals_in_process_loop(loop):
    # the same law flown in-process (models.reentry.simulate, same integrator, same ZOH
    # master) must give the same numbers as the FMU co-simulation, to rounding
    law = paper_basic_law()
    p = ReentryParams()
    from descent_fmus.models.reentry import deviations
    fi = simulate(p, lambda t, x: law(deviations(x, p))[0], step=spec.STEP)
    f = fly(law, loop=loop)
    assert f.objectives["J1"] == pytest.approx(fi.load_max, rel=1e-12)
    assert f.objectives["L_final"] == pytest.approx(downrange(fi.x, p.Rz), rel=1e-12)


def test_reset_between_runs_gives_identical_results(loop):
    law = paper_law()
    a = fly(law, loop=loop).objectives
    fly(paper_basic_law(q=(9.0, 0.1)), loop=loop)
    b = fly(law, loop=loop).objectives
    assert a == b


def test_recorded_trajectory(loop):
    f = fly(paper_basic_law(), loop=loop, record=True)
    r = f.result
    assert r.stopped and r.time[-1] == pytest.approx(r.steps * spec.STEP)
    assert r["h"][0] == pytest.approx(100_000.0) and r["h"][-1] == pytest.approx(10_000.0)
    assert (abs(r["ctrl.u[1]"]) <= 0.2 + 1e-15).all()


def test_container_fmu_reproduces_the_python_master(fmu_dir, loop):
    # fmpy simulate of fmus/ReentryClosedLoop.fmu (fmpy's native container master) and our
    # Python master run the same Gauss-Seidel scheme: identical landing numbers
    res = simulate_fmu(str(fmu_dir / "ReentryClosedLoop.fmu"), output=["L", "load_max", "status",
                                                                        "t_end", "u"])
    last = res[-1]
    f = fly(paper_basic_law(), loop=loop).objectives
    assert last["status"] == 1                         # REACHED: h = hf
    assert last["t_end"] == pytest.approx(f["t_land"], rel=1e-12)
    assert last["L"] == pytest.approx(f["L_final"], rel=1e-12)
    assert last["load_max"] == pytest.approx(f["J1"], rel=1e-12)


def test_container_parameters(fmu_dir, loop):
    res = simulate_fmu(str(fmu_dir / "ReentryClosedLoop.fmu"), output=["L", "load_max"],
                       start_values={"V0": 7550.0, "q[1]": 3.0})
    f = fly(paper_basic_law(q=(3.0, 1.953125)),
            params=ReentryParams(V0=7550.0), loop=loop).objectives
    assert res[-1]["L"] == pytest.approx(f["L_final"], rel=1e-12)


@pytest.mark.slow            # fmpy validate of every FMU (~15 s)
def test_every_fmu_validates(fmu_dir):
    fmus = sorted(fmu_dir.glob("*.fmu"))
    assert len(fmus) >= 3
    for path in fmus:
        assert validate_fmu(str(path)) == [], path.name


def test_ssp_is_valid_and_describes_the_loop(fmu_dir):
    ssd = read_ssd(str(fmu_dir / "ReentryClosedLoop.ssp"), validate=True)
    conns = {(c.startElement, c.startConnector, c.endElement, c.endConnector)
             for c in ssd.system.connections}
    assert ("plant", "y1", "controller", "x[1]") in conns
    assert ("controller", "u[1]", "plant", "u") in conns


def test_missing_fmu_is_a_clear_error(tmp_path):
    with pytest.raises(FMUNotFoundError, match="build_fmus.py"):
        ClosedLoop(spec.WIRING, tmp_path / "Reentry.fmu", tmp_path / "NoSuch.fmu")


# -- errors: the FMU's message and the FMI status of an invalid parameter -----------------------
PLANTS = ("Reentry", "MarsCapsule", "MarsCapsule6DOF", "LunarLander", "Telescope",
          "FlexibleTelescope", "LunarDescent")


@pytest.mark.parametrize("plant", PLANTS)
def test_invalid_parameter_is_reported_with_its_name(fmu_dir, plant):
    # every plant checks its RK4 sub-step dt > 0 at exitInitializationMode; the message naming
    # the parameter reaches a host that instantiates with loggingOn (fmpy simulate
    # --debug-logging).  FMI 2.0: a rejected value is fmi2Error (3), after which the instance
    # may be reset -- pythonfmu 0.7 alone says fmi2Fatal (4); the build's status wrapper (where
    # a C compiler exists) turns it into fmi2Error
    from fmpy.fmi1 import FMICallException

    from descent_fmus.synthesis.fmi.slave import load_slave
    with zipfile.ZipFile(fmu_dir / f"{plant}.fmu") as z:
        wrapped = f"binaries/linux64/{plant}.pythonfmu.so" in z.namelist()
    log: list = []
    fmu = load_slave(fmu_dir / f"{plant}.fmu", "plant", log)
    try:
        vr = next(v.valueReference for v in fmu.model.modelVariables if v.name == "dt")
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal([vr], [-1.0])
        with pytest.raises(FMICallException) as err:
            fmu.exitInitializationMode()
        assert err.value.status == (3 if wrapped else 4)
        assert any("parameter dt must be > 0, got -1.0" in m for m in log), log
        if wrapped:
            # after fmi2Error the instance resets and initialises with its default dt
            fmu.reset()
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            fmu.terminate()
    finally:
        fmu.freeInstance()


def test_the_build_wraps_pythonfmu_binaries_where_a_compiler_exists(fmu_dir):
    # CI installs gcc: every pythonfmu FMU then reports user errors as fmi2Error
    from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
    if find_compiler() is None:
        pytest.skip("no C compiler: the FMUs keep pythonfmu's own binary")
    for plant in PLANTS:
        with zipfile.ZipFile(fmu_dir / f"{plant}.fmu") as z:
            assert f"binaries/linux64/{plant}.pythonfmu.so" in z.namelist(), plant


@pytest.mark.parametrize("loop", ["ReentryClosedLoop", "MarsClosedLoop",
                                  "LunarLanderFeedbackClosedLoop", "LunarDescentClosedLoop"])
def test_container_reports_an_invalid_parameter_as_fmi2error(fmu_dir, loop):
    # fmpy's container returns fmi2Error (3) when a component rejects a value (here the
    # controller's sample period, exposed by every feedback loop)
    from fmpy.fmi1 import FMICallException
    with pytest.raises(FMICallException) as err:
        simulate_fmu(str(fmu_dir / f"{loop}.fmu"), start_values={"sample_period": -1.0},
                     stop_time=1.0)
    assert err.value.status == 3


# -- fine output: any output interval, the controller at its own sample period -----------------
def test_fine_output_keeps_the_controller_period(fmu_dir, loop):
    # the closed-loop FMU at output interval 0.1 s (fmpy's container refused it): the plant is
    # stepped every 0.1 s, the law still acts once per second
    coarse = fmu_dir / "ReentryClosedLoop.fmu"
    res = simulate_fmu(str(coarse), output_interval=0.1, output=["L", "load_max", "u", "status"])
    t, u = res["time"], res["u"]
    assert t[1] - t[0] == pytest.approx(0.1, abs=1e-12)
    # the law acts once per second (spec.STEP): u changes only at whole seconds
    changes = t[1:][u[1:] != u[:-1]]
    assert len(changes) > 50 and all(abs(c - round(c)) < 1e-9 for c in changes)
    # the same scheme in our master (plant stepped at 0.1 s, controller sample_period 1 s)
    law = paper_basic_law()
    r = loop.run(controller_values=dict(law.start_values(), sample_period=spec.STEP),
                 step=0.1, record=True)
    assert res[-1]["L"] == pytest.approx(r.final["L"], rel=1e-12)
    assert res[-1]["load_max"] == pytest.approx(r.final["load_max"], rel=1e-12)
    # ... and the control is the coarse one: the landing moves by the plant's integration
    # error only (RK4 sub-step 0.1 s instead of 0.5 s: < 1 m of 1395 km), not by the 159 m a
    # controller acting every 0.1 s would cause
    base = simulate_fmu(str(coarse), output=["L"])
    assert abs(res[-1]["L"] - base[-1]["L"]) < 1.0
    r10 = loop.run(controller_values=law.start_values(), step=0.1)
    assert abs(r10.final["L"] - base[-1]["L"]) > 50.0


def test_sample_period_equal_to_the_step_changes_nothing(loop):
    # a controller sampled at the communication step acts at every step: bit-identical flights
    law = paper_law()
    a = loop.run(controller_values=law.start_values())
    b = loop.run(controller_values=dict(law.start_values(), sample_period=spec.STEP))
    c = loop.run(controller_values=dict(law.start_values(), sample_period=spec.STEP),
                 step=spec.STEP / 2)       # the plant's sub-step is 0.5 s either way
    assert a.final == b.final == c.final
