"""S4 telescope through the FMUs: program replay, closed-loop container FMUs, status outputs.

Sources: the in-process direct-method solution (same RK4 sub-steps: the FMU replay must agree
to rounding), the target of Voronov (2009), Example 1-2, closed forms (first integrals), the
status convention of models/integrators.py.
"""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.models.controllers.program_table import program_values
from descent_fmus.models.integrators import LEFT_DOMAIN, RUNNING
from descent_fmus.models.telescope_dynamics import T_DEFAULT, TARGET_LAM, TARGET_W
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.fmi.slave import FMUError
from descent_fmus.synthesis.systems.telescope.reorientation import reorient, replay
from descent_fmus.synthesis.systems.telescope.wiring import FLEXIBLE_WIRING, WIRING

TARGET = np.array(TARGET_LAM + TARGET_W)
NAMES = ("lam0", "lam1", "lam2", "lam3", "w1", "w2", "w3")


@pytest.fixture(scope="module")
def solutions():
    """The in-process solutions by model ("rigid", "flexible")."""
    return {model: reorient(flexible=model == "flexible") for model in ("rigid", "flexible")}


def test_fmu_replay_hits_the_target(solutions, fmu_dir):
    # oracle: the in-process solution -- the same control through ProgramController + plant
    # FMUs by fmpy reaches the target within the solver's tolerance
    for model, tol in (("rigid", 1e-7), ("flexible", 1e-8)):
        rep = replay(solutions[model], fmu_dir)
        assert rep["replay_error_vs_target"] < tol
        assert rep["replay_error_vs_solver"] < 1e-12      # same RK4 sub-steps, first-order hold
        assert rep["replay_status"] == RUNNING            # no terminal condition: runs to T


def test_fmu_replay_with_a_coarser_communication_step(solutions, fmu_dir):
    # oracle: the target; step = grid spacing (1 s): still one segment per step, the plant's
    # sub-steps unchanged
    rep = replay(solutions["rigid"], fmu_dir, step=1.0)
    assert rep["replay_error_vs_target"] < 1e-6


def test_closed_loop_container_fmu_flies_the_reorientation(fmu_dir):
    from fmpy import simulate_fmu
    for name, tol in (("TelescopeClosedLoop", 1e-6), ("FlexibleTelescopeClosedLoop", 1e-6)):
        res = simulate_fmu(str(fmu_dir / f"{name}.fmu"))
        end = np.array([res[n][-1] for n in NAMES])
        assert res["time"][-1] == pytest.approx(T_DEFAULT)
        # oracle: the target of the stored program (Voronov 2009, Examples 1-2)
        assert np.max(np.abs(end - TARGET)) < tol
        # closed form: the inertial angular momentum is a first integral
        K = np.stack([res["K1"], res["K2"], res["K3"]], -1)
        assert np.max(np.abs(K - K[0])) < 1e-7 * np.linalg.norm(K[0])
        # status convention: running up to the stop time, t_end -1
        assert np.all(res["status"] == RUNNING) and np.all(res["t_end"] == -1.0)


def test_plant_status_becomes_left_domain_when_it_diverges(fmu_dir):
    # absurd gimbal rates (1e300 rad/s) make the state non-finite: the plant freezes at the last
    # finite state with status LEFT_DOMAIN and the closed loop stops on it
    controls = [[0.0] * 6] + [[1e300] * 6] * 40
    with ClosedLoop(WIRING, fmu_dir / "Telescope.fmu", fmu_dir / "ProgramController.fmu") as cl:
        out = cl.run(controller_values=program_values(T_DEFAULT, controls))
    assert out.stopped and out.final["status"] == LEFT_DOMAIN
    assert 0.0 <= out.final["t_end"] < T_DEFAULT
    # closed form: the frozen state is the last finite one, |lambda| = 1
    assert out.final["lam_norm"] == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("values, message", [
    ({"lam_init[1]": 0.5}, "unit quaternion"),
    ({"h": -1.0}, "parameter h must be > 0"),
    ({"I12": 50.0}, "symmetric"),
    ({"rotor_ref[1]": 0.0, "rotor_ref[2]": 0.0}, "rotor_ref"),
])
def test_fmu_rejects_invalid_parameters_with_a_message(fmu_dir, values, message):
    with ClosedLoop(WIRING, fmu_dir / "Telescope.fmu", fmu_dir / "ProgramController.fmu") as cl:
        with pytest.raises(FMUError, match=message):
            cl.run(plant_values=values, stop_time=1.0)


def test_flexible_fmu_rejects_panels_outweighing_the_body(fmu_dir):
    with ClosedLoop(FLEXIBLE_WIRING, fmu_dir / "FlexibleTelescope.fmu",
                    fmu_dir / "ProgramController.fmu") as cl:
        with pytest.raises(FMUError, match="coupling too strong"):
            cl.run(plant_values={"coupling[1]": 200.0}, stop_time=1.0)


@pytest.mark.parametrize("values, message", [
    ({"n_gyros": 7}, "n_gyros must be in 1..6"),
    ({"n_gyros": 0}, "n_gyros must be in 1..6"),
    ({"gimbal_axes[4]": 0.0, "gimbal_axes[5]": 0.0, "gimbal_axes[6]": 0.0}, "gimbal axis 2"),
])
def test_fmu_rejects_a_bad_gyro_cluster(fmu_dir, values, message):
    with ClosedLoop(WIRING, fmu_dir / "Telescope.fmu", fmu_dir / "ProgramController.fmu") as cl:
        with pytest.raises(FMUError, match=message):
            cl.run(plant_values=values, stop_time=1.0)


def test_program_controller_rejects_node_times_out_of_order(fmu_dir):
    values = program_values(2.0, [[0.0] * 6] * 3, times=[0.0, 1.0, 2.0])
    values["t_node[3]"] = 0.5
    with ClosedLoop(WIRING, fmu_dir / "Telescope.fmu", fmu_dir / "ProgramController.fmu") as cl:
        with pytest.raises(FMUError, match="increasing"):
            cl.run(controller_values=values, stop_time=1.0)
