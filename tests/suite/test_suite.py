"""The benchmark suite's references against their own oracles (benchmarks/suite/): fast checks
only -- no synthesis run.

* lq: the Van Loan discretisation against a quadrature of the cost over one step, the Riccati
  solution against its equation and against the closed loop's summed cost, the finite horizon
  against the infinite one (the tail), and the optimal gain flown through the FMUs (plant and
  the generic controller) against x0' P x0;
* cartpole: the basic law is the stored LQR law, it saves the starts up to 40 deg and lets the
  pole fall from 55 and 60 deg; the stored programs replayed through the plant FMU;
* parking: the polar law of Aicardi et al. parks every start through the Unicycle FMU;
* reentry-second: the stored bound replayed through the Reentry FMU;
* every problem of the suite loads.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

SUITE = Path(__file__).resolve().parents[2] / "benchmarks" / "suite"
sys.path.insert(0, str(SUITE))

import cartpole_reference as CP  # noqa: E402
import plant_flights as F  # noqa: E402
import references as R  # noqa: E402
import riccati as RIC  # noqa: E402
import suite  # noqa: E402


@pytest.fixture(scope="module")
def built():
    """The suite's plant FMUs, built by pythonfmu into benchmarks/suite/build/ (as the runner
    does; ~0.1 s each when missing)."""
    return F.build_plants()


def load(name, fmu_dir):
    return suite.load(name, fmu_dir, build=False)


# -- every problem loads ---------------------------------------------------------------------
@pytest.mark.parametrize("name", suite.ORDER)
def test_every_problem_of_the_suite_loads(built, fmu_dir, name):
    from descent_fmus.synthesis.methods.registry import method_names
    p = load(name, fmu_dir)
    methods = method_names(p)
    assert "network-operator" in methods and any(m.startswith("cma-") for m in methods)
    assert suite.SPECS[name].flights >= 1000


# -- lq --------------------------------------------------------------------------------------
def lq_setup(fmu_dir):
    p = load("lq", fmu_dir)
    with F.PlantFlyer(F.BUILD / "LQPlant.fmu") as fl:
        params = fl.defaults()
    return p, params


def test_van_loan_matches_a_quadrature_of_one_step():
    from scipy.integrate import solve_ivp
    A = np.array([[0.0, 1.0], [1.0, -0.5]])
    B = np.array([[0.0], [1.0]])
    Q, Rm, h = np.diag([1.0, 0.1]), np.array([[0.1]]), 0.1
    Ad, Bd, Qd, Nd, Rd = RIC.van_loan(A, B, Q, Rm, h)
    rng = np.random.default_rng(0)
    for _ in range(3):
        x0, u = rng.normal(size=2), rng.normal()

        def f(t, z):
            x = z[:2]
            return np.r_[A @ x + B[:, 0] * u, x @ Q @ x + Rm[0, 0] * u * u]
        z = solve_ivp(f, (0, h), np.r_[x0, 0.0], rtol=1e-12, atol=1e-14).y[:, -1]
        assert np.allclose(z[:2], Ad @ x0 + Bd[:, 0] * u, rtol=1e-10, atol=1e-12)
        step_cost = x0 @ Qd @ x0 + 2 * x0 @ Nd[:, 0] * u + Rd[0, 0] * u * u
        assert step_cost == pytest.approx(z[2], rel=1e-9)


def test_lq_riccati_solution_is_the_optimum(built, fmu_dir):
    from scipy.linalg import solve_continuous_are
    p, params = lq_setup(fmu_dir)
    A, B, Q, Rm = RIC.lq_matrices(params)
    d = RIC.sampled_lqr(A, B, Q, Rm, p.wiring.step)
    Ad, Bd, Qd, Nd, Rd, P, K = (d[k] for k in ("Ad", "Bd", "Qd", "Nd", "Rd", "P", "K"))
    # the discrete Riccati equation with the cross term holds
    G = Rd + Bd.T @ P @ Bd
    H = Bd.T @ P @ Ad + Nd.T
    assert np.allclose(Qd + Ad.T @ P @ Ad - H.T @ np.linalg.solve(G, H), P, atol=1e-12)
    # P is the summed step cost of the closed loop under u = -K x
    x = np.array([0.3, -0.8])
    J, z = 0.0, x.copy()
    for _ in range(2000):
        u = -K @ z
        J += z @ Qd @ z + 2 * z @ Nd @ u + u @ Rd @ u
        z = Ad @ z + Bd @ u
    assert J == pytest.approx(x @ P @ x, rel=1e-10)
    # any other gain costs more; the continuous LQR is close, not equal (the hold costs)
    for dK in ([0.05, 0.0], [0.0, -0.05], [-0.2, 0.1]):
        assert (x @ RIC.law_cost_matrix(d, K + np.array([dK])) @ x) > x @ P @ x
    Pc = solve_continuous_are(A, B, Q, Rm)
    assert np.allclose(P, Pc, rtol=0.05) and not np.allclose(P, Pc, rtol=1e-4)


def test_lq_reference_flown_through_the_fmus(built, fmu_dir):
    p, params = lq_setup(fmu_dir)
    ref = RIC.lq_reference(p, params)
    # the horizon is the infinite-horizon cost: the finite-horizon optimum agrees to 1e-9
    assert ref["finite_horizon_mean"] == pytest.approx(ref["mean"], rel=1e-9)
    assert ref["finite_horizon_mean"] <= ref["mean"] * (1 + 1e-12)
    # the optimal gain, a law of the generic controller FMU, through the closed loop
    K = ref["K"]
    law = p.basic().with_q([-K[0], -K[1], 0.0])
    (cost,), cv = F.objective_of(p, law, fmu_dir)
    assert cost == pytest.approx(ref["mean"], rel=1e-7)
    # the basic law is half of it, and costs what its Lyapunov equation says
    assert p.basic().q[:2] == pytest.approx([-K[0] / 2, -K[1] / 2], rel=1e-6)
    (basic,), _ = F.objective_of(p, p.basic(), fmu_dir)
    assert basic == pytest.approx(ref["basic_law_mean"], rel=1e-6)
    assert basic / ref["mean"] > 1.3
    # the bounds never bind: the optimal law's largest |u| over the starts
    X0 = np.array([[s["x10"], s["x20"]] for s in p.initial_states])
    assert np.max(np.abs(X0 @ np.array(K))) < 0.5 * p.basic().bounds[0][1]


# -- cartpole --------------------------------------------------------------------------------
def test_cartpole_basic_law_is_the_lqr_law_and_saves_half_the_starts(built, fmu_dir):
    p = load("cartpole", fmu_dir)
    stored = R.stored("cartpole")
    with F.PlantFlyer(F.BUILD / "CartPole.fmu") as fl:
        params = fl.defaults()
    K = CP.cartpole_lqr(params, p.wiring.step)["K"]
    assert K == pytest.approx(stored["lqr"]["K"], rel=1e-9)
    gains = np.array(p.basic().q[:4]) * np.array(p.basic().input_scale)
    assert gains == pytest.approx(-np.array(K), rel=1e-6)
    finals = F.fly_law(p, p.basic(), fmu_dir)
    bound = p.constraints[0].bound
    for s, f in zip(p.initial_states, finals):
        saved = f["tilt_max"] <= bound
        assert saved == (abs(s["theta0"]) < math.radians(50)), (s, f["tilt_max"])


def test_cartpole_programs_replay_through_the_fmu(built):
    stored = R.stored("cartpole")
    h, T = stored["step"], stored["stop_time"]
    with F.PlantFlyer(F.BUILD / "CartPole.fmu") as fl:
        for prog in stored["programs"]:
            u = np.asarray(prog["u"])[:, None]
            out = fl.fly(prog["start"], u, ["F"], h, T)
            assert out["J"] == pytest.approx(prog["J"], rel=1e-6)
            assert out["tilt_max"] < math.radians(80)
            assert np.max(np.abs(u)) <= 30.0


# -- parking ---------------------------------------------------------------------------------
def test_polar_law_parks_every_start(built, fmu_dir):
    p = load("parking", fmu_dir)
    ref = R.parking_reference(p, fmu_dir)
    assert len(ref["per_start"]) == len(p.initial_states) == 8
    for row in ref["per_start"]:
        assert row["distance"] < 1e-6 and row["heading"] < 1e-6, row
    # the basic (linear, Cartesian) law parks only the two starts already on the x axis with
    # heading 0 (straight ahead, straight back)
    finals = F.fly_law(p, p.basic(), fmu_dir)
    parked = [s for s, f in zip(p.initial_states, finals) if f["rho"] + abs(f["theta"]) < 1e-2]
    assert parked == [s for s in p.initial_states if s["y0"] == 0.0 and s["theta0"] == 0.0]


def test_polar_law_is_defined_at_the_target():
    law = R.aicardi_law()
    assert law({"rho": 0.0, "alpha": 0.0, "phi": 0.0}) == (0.0, 0.0)
    v, w = law({"rho": 1.0, "alpha": 1e-15, "phi": 0.5})
    assert math.isfinite(v) and math.isfinite(w)


# -- reentry-second --------------------------------------------------------------------------
def test_reentry_second_bound_replays_through_the_fmu(fmu_dir):
    from descent_fmus.models.reentry import SECOND_SCENARIO
    from descent_fmus.synthesis.systems.reentry.bound import Program, replay_program
    d = R.stored("reentry-second")
    prog = Program(np.asarray(d["bound"]["u"]), d["bound"]["t_seg"])
    out = replay_program(prog, fmu_dir, SECOND_SCENARIO)
    assert out["status"] == 1
    assert out["load_max"] == pytest.approx(d["J1"], rel=1e-9)
    assert abs(out["L"] - SECOND_SCENARIO.Lf) <= d["miss_tol"] * (1 + 1e-6)
    assert d["J1"] <= d["zero_miss"]["J1"]
    p = load("reentry-second", fmu_dir)
    assert p.initial_states[0]["V0"] == SECOND_SCENARIO.V0
    assert p.initial_states[0]["beta0"] == pytest.approx(SECOND_SCENARIO.beta0, abs=1e-15)
