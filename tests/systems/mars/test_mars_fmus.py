"""S2 Mars capsule: the plant FMUs and the Bellman controller FMU, each driven alone.

Oracles: the law's formulas (Lyubimov & Kurkina, eqs. 14-17) written out independently,
independent scipy.integrate.solve_ivp (DOP853) runs of the same right-hand sides, the status
convention of the plants (models/integrators.py).
"""
from __future__ import annotations

import math
import random

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from descent_fmus.models.controllers import mars_bellman as mb
from descent_fmus.models.integrators import LEFT_DOMAIN, REACHED, RUNNING
from descent_fmus.models.mars import MarsParams, rhs
from descent_fmus.models.mars_6dof import initial_state6, rhs6
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.fmi.slave import FMUError, load_slave
from descent_fmus.synthesis.systems.mars.wiring import WIRING

from test_mars_model import random_law_inputs

P = MarsParams()


class Slave:
    """One FMU driven directly through fmpy (no master): set, init, step, get by name."""

    def __init__(self, path, values=None):
        self.log = []
        self.fmu = load_slave(path, "test", self.log)
        md = self.fmu.model
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

    def status(self) -> int:
        return self.fmu.getInteger([self.vars["status"].valueReference])[0]

    def step(self, t, h):
        self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def _ivp(f, x0, u, args, t_end, h_end, t_eval):
    ev = lambda t, x: x[2] - h_end  # noqa: E731
    ev.terminal, ev.direction = True, -1
    return solve_ivp(lambda t, x: f(tuple(x), u, *args), (0.0, t_end), list(x0), method="DOP853",
                     rtol=1e-11, atol=1e-12, events=ev, t_eval=t_eval, dense_output=True)


# -- the controller ------------------------------------------------------------------------------
def test_controller_fmu_equals_formula_on_random_inputs(fmu_dir):
    # oracle: control() (same function: equal to rounding) and eq. (17) with the consistent
    # root of eq. (14) written out here
    rng = random.Random(11)
    for formula in (mb.CONSISTENT, mb.PAPER):
        b, c, th1, umax = 0.5, 20.0, -0.7, 0.05
        s = Slave(fmu_dir / "MarsBellmanController.fmu",
                  {"b": b, "c": c, "theta1": th1, "u_max": umax, "formula": formula})
        try:
            acted = 0
            for _ in range(300):
                x = random_law_inputs(rng)
                if formula == mb.PAPER and rng.random() < 0.5:
                    x = x[:3] + (-abs(x[3]) * 50.0, x[4])   # make the paper's guards pass
                s.set(dict(zip(("alpha", "theta", "omega", "omega_dot", "omega_a"), x)))
                u, A = s.get("u", "A")
                u_ref, A_ref = mb.control(*x, b, c, th1, umax, formula)
                assert u == pytest.approx(u_ref, rel=1e-15, abs=1e-300)
                assert A == pytest.approx(A_ref, rel=1e-15, abs=1e-300)
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
def test_plant_fmu_matches_solve_ivp(fmu_dir):
    # oracle: an independent solve_ivp (DOP853, rtol 1e-11) run of the same right-hand side
    u = 0.004          # constant control: exercises the cos(theta + theta1) term
    s = Slave(fmu_dir / "MarsCapsule.fmu", {"u": u})
    try:
        times, rows = [], []
        h = 0.5
        for k in range(1, 1400):
            s.step((k - 1) * h, h)
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
    # oracle: an independent solve_ivp (DOP853, rtol 1e-11) run of the same right-hand side
    u = 0.004
    T = 120.0          # ~40 precession periods; keeps the reference solve short
    s = Slave(fmu_dir / "MarsCapsule6DOF.fmu", {"u": u})
    try:
        h = 0.5
        got = []
        for k in range(1, int(T / h) + 1):
            s.step((k - 1) * h, h)
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


@pytest.mark.parametrize("plant", ["MarsCapsule", "MarsCapsule6DOF"])
def test_plant_fmu_status_reached_at_h_end(fmu_dir, plant):
    # oracle: the status convention -- 0 and t_end = -1 while flying; REACHED with t_end inside
    # the step where h = h_end (the descent takes 660.5 s), then frozen
    s = Slave(fmu_dir / f"{plant}.fmu")
    try:
        h = 10.0
        k = 0
        while s.status() == RUNNING:
            assert s.get("t_end")[0] == -1.0 and k < 150
            s.step(k * h, h)
            k += 1
        assert s.status() == REACHED
        t_end, alt = s.get("t_end", "h")
        assert (k - 1) * h < t_end <= k * h and t_end == pytest.approx(660.5, abs=0.1)
        assert alt == pytest.approx(P.h_end, abs=1e-3)
        s.step(k * h, h)
        assert s.status() == REACHED and list(s.get("t_end", "h")) == [t_end, alt]
    finally:
        s.close()


def test_plant_fmu_status_left_domain(fmu_dir):
    # oracle: the status convention. An absurd atmosphere overflows the first sub-step (as
    # in-process, test_mars_model.py): LEFT_DOMAIN, t_end = 0
    s = Slave(fmu_dir / "MarsCapsule.fmu", {"rho0": 1e6, "Hs": 1e6})
    try:
        s.step(0.0, 1.0)
        assert s.status() == LEFT_DOMAIN and s.get("t_end")[0] == 0.0
    finally:
        s.close()


# -- bad input ---------------------------------------------------------------------------------
@pytest.mark.parametrize("values, words", [
    ({"Ix": -270.0}, "Ix"), ({"I": -1.0}, "parameter I must be > 0"),
    ({"omega_x": 0.0}, "omega_x"), ({"mz_alpha": 0.1}, "mz_alpha"),
    ({"Ix": 1000.0}, "Ix <= Iy + Iz")])
def test_bad_plant_parameters_fail_at_initialisation(fmu_dir, values, words):
    with ClosedLoop(WIRING, fmu_dir / "MarsCapsule.fmu",
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
    with ClosedLoop(WIRING, fmu_dir / "MarsCapsule.fmu",
                    fmu_dir / "MarsBellmanController.fmu") as loop:
        with pytest.raises(FMUError, match=words):
            loop.run(None, values)
