"""S2 Mars capsule: plant FMUs, the Bellman controller FMU, the closed loop, the CLI.

Oracles: the law's formulas (seed 001, eqs. 14, 15-17; SPEC S2), the closed form of the
uncontrolled averaged equation (alpha ~ omega_a^(-1/2)), independent solve_ivp runs of the
same right-hand sides, and the in-process simulation of the same equations.
"""
from __future__ import annotations

import json
import math
import random

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from descent_fmus.models.controllers import mars_bellman as mb
from descent_fmus.models.fmu_support import ParameterError
from descent_fmus.models.mars import OUTPUTS, MarsParams, rhs, simulate
from descent_fmus.models.mars_6dof import OUTPUTS6, flight, initial_state6, rhs6
from descent_fmus.synthesis.cosim import ClosedLoop, FMUError, load_slave
from descent_fmus.synthesis.systems.mars.flight import fly, open_loop
from descent_fmus.synthesis.scenarios import mars as spec

P = MarsParams()


# -- helpers -------------------------------------------------------------------------------------
class Slave:
    """One FMU driven directly through fmpy (no master): set, init, step, get by name."""

    def __init__(self, path, values=None):
        self.log = []
        self.fmu = load_slave(path, "test", self.log)
        md = self.fmu._descent_md
        self.vars = {v.name: v for v in md.modelVariables}
        self.set(values or {})
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def set(self, values):
        for name, value in values.items():
            v = self.vars[name]
            if v.type == "Integer":
                self.fmu.setInteger([v.valueReference], [int(value)])
            else:
                self.fmu.setReal([v.valueReference], [float(value)])

    def get(self, *names):
        return self.fmu.getReal([self.vars[n].valueReference for n in names])

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def _ivp(f, x0, u, args, t_end, h_end, t_eval):
    ev = lambda t, x: x[2] - h_end  # noqa: E731
    ev.terminal, ev.direction = True, -1
    return solve_ivp(lambda t, x: f(tuple(x), u, *args), (0.0, t_end), list(x0), method="DOP853",
                     rtol=1e-11, atol=1e-12, events=ev, t_eval=t_eval, dense_output=True)


# -- the law ---------------------------------------------------------------------------------------
def _random_state(rng):
    wa = rng.uniform(0.2, 4.0)
    w = rng.uniform(0.0, wa)
    return (rng.uniform(0.0, 0.5), rng.uniform(-10.0, 10.0), w, rng.uniform(-0.5, 0.5), wa)


def test_consistent_root_solves_eq14_to_rounding():
    # SPEC S2: A is the positive root of b - A w wd/wa^2 - A^2/(8 c wa^2) = 0 (seed 001, eq. 14).
    rng = random.Random(7)
    for _ in range(2000):
        _, _, w, wd, wa = _random_state(rng)
        wd *= 10.0 ** rng.uniform(-3, 2)           # also omega omega_dot >> sqrt(b / c)
        b, c = 10.0 ** rng.uniform(-3, 2), 10.0 ** rng.uniform(-2, 3)
        A = mb.consistent_gain(w, wd, wa, b, c)
        assert A > 0.0
        # residual relative to the size of the terms (rounding: a few ulp)
        scale = b + abs(A * w * wd) / wa ** 2 + A * A / (8 * c * wa ** 2)
        assert abs(mb.bellman_residual(A, w, wd, wa, b, c)) <= 1e-13 * scale


def test_paper_root_does_not_solve_eq14_and_guards():
    b, c, wa, w = 1.0, 100.0, 2.0, 1.0
    # guards of eq. (16): omega_dot >= 0 -> no control; D < 0 -> no control
    assert mb.paper_gain(w, 0.0, wa, b, c) == 0.0
    assert mb.paper_gain(w, 0.3, wa, b, c) == 0.0
    wd = -0.01       # D = (w wd / wa^2)^2 - b / (4 c wa^2) = 6.25e-6 - 6.25e-4 < 0
    assert mb.paper_gain(w, wd, wa, b, c) == 0.0
    assert mb.control(0.1, 0.0, w, wd, wa, b, c, 0.0, 1.0, mb.PAPER) == (0.0, 0.0)
    # where the guards pass, A is the printed formula (15): A_1 = 8 c wa^2 (-x + sqrt(D))
    wd = -1.0        # x = -0.25, D = 0.0625 - 6.25e-4 > 0
    x = w * wd / wa ** 2
    D = x * x - b / (4 * c * wa ** 2)
    A = mb.paper_gain(w, wd, wa, b, c)
    assert A == pytest.approx(8 * c * wa ** 2 * (-x + math.sqrt(D)), rel=1e-14)
    # ... which does not solve eq. (14) (SPEC S2: a sign and a factor are off)
    assert abs(mb.bellman_residual(A, w, wd, wa, b, c)) > 0.1 * b
    u, _ = mb.control(0.1, 0.0, w, wd, wa, b, c, 0.0, 1e9, mb.PAPER)
    assert u == pytest.approx(A * 0.1 / (2 * c * wa), rel=1e-14)


def test_controller_fmu_equals_formula_on_random_inputs(fmu_dir):
    rng = random.Random(11)
    for formula in (mb.CONSISTENT, mb.PAPER):
        b, c, th1, umax = 0.5, 20.0, -0.7, 0.05
        s = Slave(fmu_dir / "MarsBellmanController.fmu",
                  {"b": b, "c": c, "theta1": th1, "u_max": umax, "formula": formula})
        try:
            acted = 0
            for _ in range(300):
                x = _random_state(rng)
                if formula == mb.PAPER and rng.random() < 0.5:
                    x = x[:3] + (-abs(x[3]) * 50.0, x[4])   # make the paper's guards pass
                s.set(dict(zip(("alpha", "theta", "omega", "omega_dot", "omega_a"), x)))
                u, A = s.get("u", "A")
                u_ref, A_ref = mb.control(*x, b, c, th1, umax, formula)
                # same function in the FMU: equal to rounding
                assert u == pytest.approx(u_ref, rel=1e-15, abs=1e-300)
                assert A == pytest.approx(A_ref, rel=1e-15, abs=1e-300)
                # and the formula of eq. (17), written out here independently
                if formula == mb.CONSISTENT:
                    al, th, w, wd, wa = x
                    A_ind = 4 * c * wa ** 2 * (-w * wd / wa ** 2 + math.sqrt(
                        (w * wd) ** 2 / wa ** 4 + b / (2 * c * wa ** 2)))
                    u_ind = min(umax, max(-umax, A_ind * al * math.cos(th + th1) / (2 * c * wa)))
                    assert A == pytest.approx(A_ind, rel=1e-9)
                    assert u == pytest.approx(u_ind, rel=1e-9, abs=1e-15)
                acted += u != 0.0
            assert acted > 50
        finally:
            s.close()


# -- the plants --------------------------------------------------------------------------------
def test_uncontrolled_alpha_follows_closed_form():
    # u = 0: dalpha/alpha = -w dw / (2 wa^2) = -d(wa^2) / (4 wa^2)  =>  alpha wa^(1/2) = const
    fl, rec = simulate(P, None)
    wa0, wa1 = rec["omega_a"][0], rec["omega_a"][-1]
    assert fl.outputs()[0] == pytest.approx(P.alpha0 * math.sqrt(wa0 / wa1), rel=1e-7)


def test_plant_fmu_matches_solve_ivp(fmu_dir):
    u = 0.004          # constant control: exercises the cos(theta + theta1) term
    s = Slave(fmu_dir / "MarsCapsule.fmu", {"u": u})
    try:
        times, rows = [], []
        h = 0.5
        for k in range(1, 1400):
            s.fmu.doStep(currentCommunicationPoint=(k - 1) * h, communicationStepSize=h)
            times.append(k * h)
            rows.append(s.get("V", "gamma", "h", "s", "alpha", "theta"))
            if s.get("t_end")[0] >= 0:
                t_end_fmu = s.get("t_end")[0]
                break
    finally:
        s.close()
    sol = _ivp(rhs, (P.V0, P.gamma0, P.h0, 0.0, P.alpha0, P.theta0), u, P.constants(), 1500.0,
               P.h_end, None)
    # event time: RK4 (dt = 0.1 s sub-steps of the 0.5 s step) vs DOP853 at rtol 1e-11
    assert t_end_fmu == pytest.approx(sol.t_events[0][0], abs=1e-4)
    ref = sol.sol(np.array(times[:-1])).T
    got = np.array(rows[:-1])
    scale = np.array([P.V0, 1.0, P.h0, 1e6, P.alpha0, 100.0])
    assert np.max(np.abs(got - ref) / scale) < 1e-6


def test_6dof_plant_fmu_matches_solve_ivp(fmu_dir):
    u = 0.004
    T = 120.0          # ~40 precession periods; keeps the reference solve short
    s = Slave(fmu_dir / "MarsCapsule6DOF.fmu", {"u": u})
    try:
        h = 0.5
        got = []
        for k in range(1, int(T / h) + 1):
            s.fmu.doStep(currentCommunicationPoint=(k - 1) * h, communicationStepSize=h)
            if k % 20 == 0:
                got.append(s.get("alpha", "theta", "wy", "wz", "h"))
    finally:
        s.close()
    t_eval = np.arange(1, len(got) + 1) * 10.0
    sol = _ivp(rhs6, initial_state6(P), u, P.constants(), T + 1e-9, P.h_end, t_eval)
    # RK4 with dt = 0.02 s (0.1 rad of the fastest body-axis rotation per step): its phase
    # error grows to ~3e-6 rad/s in the body rates (|w| ~ 0.4 rad/s) over 120 s and falls 16x
    # per halving of dt (measured: 3.8e-5, 2.8e-6, 1.7e-7 for dt = 0.04, 0.02, 0.01 s), i.e. it
    # is the integrator's truncation error; the reference is DOP853 at rtol 1e-11
    err = np.zeros(4)
    for row, x in zip(got, sol.y.T):
        a = math.atan2(math.hypot(x[5], x[6]), x[4])
        err = np.maximum(err, np.abs([row[0] - a, row[2] - x[8], row[3] - x[9],
                                      (row[4] - x[2]) / P.h0]))
    assert err[0] < 1e-7 and err[1] < 5e-6 and err[2] < 5e-6 and err[3] < 1e-9


# -- closed loop, acceptance -------------------------------------------------------------------
@pytest.fixture(scope="module")
def runs(fmu_dir):
    with open_loop(fmu_dir) as loop:
        yield {"law": fly(loop, "law"),
               "none": fly(loop, "none", controller_values={"u_max": 0.0}),
               "paper": fly(loop, "paper", controller_values={"formula": mb.PAPER}),
               "half_step": fly(loop, "half", step=spec.STEP / 2, record=False)}


def test_acceptance_alpha_end_through_fmus(runs):
    law, none = runs["law"], runs["none"]
    assert law.result.stopped and none.result.stopped
    assert law.result.final["h"] == pytest.approx(P.h_end, abs=1e-3)
    # SPEC S2 acceptance: alpha_end < 0.01 rad with the law, >= 5x larger without it
    assert law.alpha_end < 0.01
    assert none.alpha_end >= 5 * law.alpha_end
    # the uncontrolled run is the closed form alpha0 (wa0 / wa_end)^(1/2)
    wa = none.result["omega_a"]
    assert none.alpha_end == pytest.approx(P.alpha0 * math.sqrt(wa[0] / wa[-1]), rel=1e-6)


def test_paper_formula_rarely_acts_on_the_scenario(runs):
    # SPEC S2: with the printed root's guards the discriminant is negative on the scenario
    assert runs["paper"].alpha_end == pytest.approx(runs["none"].alpha_end, rel=1e-12)
    assert np.all(runs["paper"].result["ctrl.u"] == 0.0)


def test_fmu_closed_loop_equals_in_process(runs):
    law = runs["law"]
    ctl = lambda y: mb.control(*y[:5], mb.B, mb.C, P.theta1, mb.U_MAX)[0]  # noqa: E731
    fl, _ = simulate(P, ctl, step=spec.STEP, record=False)
    assert law.alpha_end == pytest.approx(fl.outputs()[0], rel=1e-9)
    assert law.result.final["t_end"] == pytest.approx(fl.t_end, abs=1e-9)


def test_communication_step_effect_is_small(runs):
    # held control over a step: halving the step changes alpha_end by ~1 % (measured 0.9 %)
    assert runs["half_step"].alpha_end == pytest.approx(runs["law"].alpha_end, rel=0.03)


def test_container_fmu_runs_the_same_loop(fmu_dir, runs):
    from fmpy import simulate_fmu
    res = simulate_fmu(str(fmu_dir / "MarsClosedLoop.fmu"), stop_time=700.0,
                       output=["alpha", "done"])
    assert res["done"][-1] == 1
    assert res["alpha"][-1] == pytest.approx(runs["law"].alpha_end, rel=1e-9)


# -- the averaging against the rigid body ------------------------------------------------------
@pytest.fixture(scope="module")
def six_dof(fmu_dir):
    out = {}
    for key, wiring in (("mode1", spec.WIRING_6DOF), ("instant", spec.WIRING_6DOF_INSTANT)):
        with ClosedLoop(wiring, fmu_dir / "MarsCapsule6DOF.fmu",
                        fmu_dir / "MarsBellmanController.fmu",
                        record=("alpha", "alpha_m1", "alpha_m2", "omega_a")) as loop:
            out[key] = loop.run(record=True)
            if key == "mode1":
                out["none"] = loop.run(controller_values={"u_max": 0.0}, record=True)
    return out


def test_6dof_uncontrolled_agrees_with_averaged(six_dof, runs):
    # no control: the omega_1 amplitude of the rigid body follows the averaged alpha (and its
    # closed form) to 0.5 % over the whole descent (measured 0.35 %)
    r6, ra = six_dof["none"], runs["none"].result
    a_avg = np.interp(r6.time, ra.time, ra["alpha"])
    assert np.max(np.abs(r6["alpha_m1"] / a_avg - 1.0)) < 5e-3
    assert r6.final["alpha"] == pytest.approx(runs["none"].alpha_end, rel=5e-3)


def test_6dof_controlled_mode1_follows_averaged_and_meets_target(six_dof, runs):
    r6, ra = six_dof["mode1"], runs["law"].result
    a_avg = np.interp(r6.time, ra.time, ra["alpha"])
    big = a_avg > 1e-3
    # while the omega_1 mode dominates, amplitude within 10 % of the averaged model
    assert np.max(np.abs(r6["alpha_m1"][big] / a_avg[big] - 1.0)) < 0.1
    # the total angle ends at the omega_2 residue the saturated control excited (~1.4e-3 rad)
    assert r6.final["alpha"] < 0.01
    assert r6.final["alpha_m2"] > 10 * r6.final["alpha_m1"]


def test_6dof_instantaneous_feedback_breaks_down(six_dof):
    # documented breakdown: fed the instantaneous angles, the law tracks the omega_2 mode once
    # it exceeds the omega_1 mode, and it destabilises it (models/README.md)
    r = six_dof["instant"]
    assert r.final["alpha"] > 0.1
    assert r.final["alpha_m2"] > 10 * r.final["alpha_m1"]


# -- bad input ---------------------------------------------------------------------------------
@pytest.mark.parametrize("values, words", [
    ({"Ix": -270.0}, "Ix"), ({"I": -1.0}, "I (moment of inertia)"),
    ({"omega_x": 0.0}, "omega_x"), ({"mz_alpha": 0.1}, "mz_alpha"),
    ({"Ix": 1000.0}, "Ix <= Iy + Iz")])
def test_bad_plant_parameters_fail_at_initialisation(fmu_dir, values, words):
    with ClosedLoop(spec.WIRING, fmu_dir / "MarsCapsule.fmu",
                    fmu_dir / "MarsBellmanController.fmu") as loop:
        with pytest.raises(FMUError, match="exitInitializationMode") as err:
            loop.run(values)
        assert words in str(err.value)
        # the loaded FMUs are still usable after the error
        assert loop.run().final["alpha"] < 0.01


@pytest.mark.parametrize("values, words", [
    ({"c": 0.0}, "parameter c"), ({"c": -1.0}, "parameter c"), ({"b": 0.0}, "parameter b"),
    ({"b": -2.0}, "parameter b"), ({"u_max": -1.0}, "u_max"), ({"formula": 3}, "formula")])
def test_bad_controller_parameters_fail_at_initialisation(fmu_dir, values, words):
    with ClosedLoop(spec.WIRING, fmu_dir / "MarsCapsule.fmu",
                    fmu_dir / "MarsBellmanController.fmu") as loop:
        with pytest.raises(FMUError, match=words):
            loop.run(None, values)


def test_in_process_parameter_errors():
    with pytest.raises(ParameterError, match="omega_x"):
        MarsParams(omega_x=0.0).validate()
    with pytest.raises(ParameterError, match="Ix"):
        flight(MarsParams(Ix=-1.0))


# -- CLI ---------------------------------------------------------------------------------------
def test_cli_json(fmu_dir, capsys):
    from descent_fmus.synthesis.cli import main
    assert main(["mars", "--json", "--fmus", str(fmu_dir)]) == 0
    out = json.loads(capsys.readouterr().out)
    none, law = out["runs"]
    assert law["alpha_end"] < 0.01 and none["alpha_end"] >= 5 * law["alpha_end"]
    assert main(["mars", "--no-control", "--json", "--fmus", str(fmu_dir)]) == 0
    assert len(json.loads(capsys.readouterr().out)["runs"]) == 1


def test_cli_missing_fmus(tmp_path, capsys):
    from descent_fmus.synthesis.cli import main
    assert main(["mars", "--fmus", str(tmp_path)]) == 2
    assert "build_fmus.py" in capsys.readouterr().err


def test_outputs_tables_are_consistent():
    assert OUTPUTS6[:len(OUTPUTS)] == OUTPUTS
