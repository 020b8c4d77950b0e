"""Program tables as native FMUs against the pythonfmu program controllers they replace.

Oracles: the pythonfmu ProgramController (S4 gimbal-rate programs, the S1 open-loop program)
and LandingProgram (S3) FMUs; the native table player gives bitwise equal outputs and closed-loop
flights (the same plant FMU, the same master)."""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop

from descent_fmus.synthesis.fmi.slave import load_slave
from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
from descent_fmus.synthesis.fmi.native.builders.table_fmu import (build_program_fmu, build_step_program_fmu,
                                                     hold_program_fmu, landing_program_fmu,
                                                     program_of_start_values)

from test_native_law import start

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (CI installs gcc)")


@pytest.mark.parametrize("sample_period", [0.0, 0.75])
def test_program_outputs_equal_the_program_controller(fmu_dir, tmp_path, sample_period):
    # uneven communication steps across nodes, before and after t_end: u and du bitwise equal
    rng = np.random.default_rng(1)
    controls = rng.normal(0.0, 0.01, (41, 6)).tolist()
    from descent_fmus.models.controllers.program_table import program_values
    values = program_values(40.0, controls)
    native = load_slave(build_program_fmu(tmp_path / "P.fmu", 40.0, controls), "native")
    generic = load_slave(fmu_dir / "ProgramController.fmu", "generic")
    steps = rng.uniform(0.05, 1.7, 60)
    names = [f"u[{j}]" for j in range(1, 7)] + [f"du[{j}]" for j in range(1, 7)]
    try:
        runs = []
        for fmu, sv in ((generic, values), (native, {})):
            vr = start(fmu, dict(sv, sample_period=sample_period))
            t, seq = 0.0, []
            for h in steps:
                seq.append(fmu.getReal([vr[n] for n in names]))
                fmu.doStep(t, float(h))
                t += float(h)
            runs.append(seq)
    finally:
        for fmu in (native, generic):
            fmu.terminate()
            fmu.freeInstance()
    assert t > 40.0
    assert runs[0] == runs[1]


def test_s4_reorientation_through_the_native_program(fmu_dir, tmp_path):
    # the stored rigid program of TelescopeClosedLoop: same plant, same master, the native
    # player instead of the ProgramController -> the same final attitude, bitwise
    from descent_fmus.synthesis.systems.telescope.wiring import WIRING, rigid_program
    values = rigid_program()
    t_end, controls = program_of_start_values(values)
    native = build_program_fmu(tmp_path / "RigidProgram.fmu", t_end, controls, "RigidProgram",
                               unit="rad/s")
    finals = []
    for ctrl, sv in ((fmu_dir / "ProgramController.fmu", values), (native, {})):
        with ClosedLoop(WIRING, fmu_dir / "Telescope.fmu", ctrl) as loop:
            finals.append(loop.run(controller_values=sv).final)
    assert finals[0] == finals[1]
    assert finals[1]["lam_norm"] == pytest.approx(1.0, abs=1e-9)


def test_s1_open_loop_program(fmu_dir, tmp_path):
    # a piecewise-constant program of the reentry (120 segments of 2.5 s) as a native step
    # program in closed loop with the Reentry FMU, against the blind replay of the same program
    # (bound.replay_program sets u[k] at every segment start): the same J1 and landing point
    # to 1e-12 (the mean over a segment is u[k] to the last bit or one rounding of the times)
    from descent_fmus.models.reentry import T_PLUS
    from descent_fmus.synthesis.fmi.closed_loop import STATUS_STOP, Wiring
    from descent_fmus.synthesis.systems.reentry.bound import Program, replay_program
    prog = Program(0.2 * np.sin(np.linspace(0.0, 6.0, 120)), 2.5)
    native = hold_program_fmu(tmp_path / "ReentryProgram.fmu", prog.t_seg, prog.u,
                              output="u")
    w = Wiring(name="ReentryProgram", plant="Reentry", controller="ReentryProgram",
               to_controller=(), to_plant=(("u", "u"),), step=prog.t_seg, stop_time=T_PLUS,
               stop=STATUS_STOP)
    with ClosedLoop(w, fmu_dir / "Reentry.fmu", native) as loop:
        got = loop.run().final
    want = replay_program(prog, fmu_dir)
    assert got["status"] == want["status"] == 1
    for name in ("load_max", "L", "t_end"):
        assert got[name] == pytest.approx(want[name], rel=1e-12)


def test_s3_landing_program(fmu_dir, tmp_path):
    # the S3 optimum as a step table (0, umax, 0) averaged over the coming step: the same
    # touchdown as the LandingProgram FMU (which averages the same way)
    from descent_fmus.synthesis.systems.lunar_landing.problems import (PROGRAM_WIRING, STEP,
                                                                       program_defaults)
    d = program_defaults()
    native = landing_program_fmu(tmp_path / "Landing.fmu", d["t_switch"], d["t_off"],
                                 d["umax"], STEP)
    finals = []
    for ctrl, sv in ((fmu_dir / "LandingProgram.fmu", d), (native, {})):
        with ClosedLoop(PROGRAM_WIRING, fmu_dir / "LunarLander.fmu", ctrl) as loop:
            finals.append(loop.run(controller_values=sv).final)
    assert finals[0] == finals[1]
    assert finals[1]["status"] == 1


def test_bad_tables(tmp_path):
    with pytest.raises(ValueError, match=">= 2 nodes"):
        build_program_fmu(tmp_path / "x.fmu", 10.0, [[1.0]])
    with pytest.raises(ValueError, match="finite values"):
        build_program_fmu(tmp_path / "x.fmu", 10.0, [[1.0], [float("nan")]])
    with pytest.raises(ValueError, match="non-decreasing"):
        build_step_program_fmu(tmp_path / "x.fmu", [0.0, 2.0, 1.0], [[0.0], [1.0], [0.0]])
    assert not (tmp_path / "x.fmu").exists()
    # an invalid start value is an fmi2Error naming it
    log = []
    fmu = load_slave(build_program_fmu(tmp_path / "P.fmu", 10.0, [[0.0], [1.0]]), "p", log)
    try:
        with pytest.raises(Exception):
            start(fmu, {"t_end": -1.0})
        assert "parameter t_end must be > 0, got -1.0" in log[-1]    # the Python words
        with pytest.raises(Exception):
            start(fmu, {"n_nodes": 3})
        assert "n_nodes must be in 2..2, got 3" in log[-1]
    finally:
        fmu.freeInstance()
