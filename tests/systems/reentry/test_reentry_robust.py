"""S1 robust guidance: the oracle bound, the held-out study, the robust problems (racing, the
container path, statistics), the exported closed loop with the estimator, bad input.

Oracles: independent DOP853 integrations of the S1 equations (oracle bound); the Python master
(:class:`synthesis.fmi.closed_loop.ClosedLoop`) for the container path and for fmpy's ``simulate_fmu`` of
the exported closed loop; the issue's rules for the sets (disjoint, seeded).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from fmpy import extract, instantiate_fmu, read_model_description, simulate_fmu
from scipy.integrate import solve_ivp

from descent_fmus.models.controllers.reentry_prediction import predict_range
from descent_fmus.models.reentry import T_PLUS, ReentryParams, initial_state
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.fmi.container_loop import ContainerLoop
from descent_fmus.synthesis.systems.reentry.guidance import (DEFAULT_LAW_FILE, default_law,
                                                             reads_estimate)
from descent_fmus.synthesis.systems.reentry.laws import sensed_basic_law
from descent_fmus.synthesis.systems.reentry.objectives import J1_LIMIT, objectives
from descent_fmus.synthesis.systems.reentry.problems import set_problems
from descent_fmus.synthesis.systems.reentry.sample_set import (MISS_CAP, RACE_OFFSET,
                                                               SYNTHESIS_SAMPLES, statistic,
                                                               synthesis_set)
from descent_fmus.synthesis.systems.reentry.wiring import WIRING, plant_values
from descent_fmus.synthesis.systems.reentry.oracle import oracle_bound
from descent_fmus.synthesis.systems.reentry.robust_study import (fly_law, held_out_samples,
                                                                  robust_study, table_lines)

P0 = ReentryParams()


def _range_dop853(p: ReentryParams, u: float) -> float:
    mu = p.g0 * p.Rz ** 2
    kd = p.S * p.rho0 / p.m

    def f(t, x):
        r = math.hypot(x[0], x[2])
        d = (1 + u) * kd * math.hypot(x[1], x[3]) * math.exp(-p.lam * (r - p.Rz))
        return [x[1], -mu * x[0] / r ** 3 - d * x[1], x[3], -mu * x[2] / r ** 3 - d * x[3]]

    def landing(t, x):
        return math.hypot(x[0], x[2]) - p.Rz - p.hf
    landing.terminal, landing.direction = True, -1
    sol = solve_ivp(f, (0, 300), initial_state(p), method="DOP853", events=landing,
                    rtol=1e-11, atol=1e-6)
    xe = sol.y_events[0][0]
    return p.Rz * math.atan2(xe[0], xe[2])


@pytest.mark.parametrize("k", [0, 1, 2])
def test_oracle_bound_against_an_independent_integration(k):
    p = held_out_samples(3, seed=11)[k]
    b = oracle_bound(p)
    lo, hi = _range_dop853(p, 0.2), _range_dop853(p, -0.2)
    # the plant's RK4 (0.5 s) lands within 1 mm of DOP853 (models/README.md); 1 m here
    assert b.L_min == pytest.approx(lo, abs=1.0) and b.L_max == pytest.approx(hi, abs=1.0)
    expected = 0.0 if lo <= p.Lf <= hi else min(abs(p.Lf - lo), abs(p.Lf - hi))
    assert b.miss == pytest.approx(expected, abs=1.0) and b.exact == (expected == 0.0)


def test_npc_prediction_against_an_independent_integration():
    # the NPC's on-board prediction (RK4, 2 s steps, landing located in the step) from the entry
    # state with u = 0.1 and a drag factor 8 % above nominal, against DOP853 to h = hf
    p = P0.with_(rho0=P0.rho0 * 1.08)
    kd = p.S * p.rho0 / p.m
    assert predict_range(initial_state(P0), 0.1, kd, P0, dt=2.0) == \
        pytest.approx(_range_dop853(p, 0.1), abs=50.0)


def test_held_out_set_is_seeded_and_disjoint_from_the_synthesis_set():
    held = held_out_samples(200, seed=7)
    assert held == held_out_samples(200, seed=7)
    synth = synthesis_set()
    assert len(synth) == SYNTHESIS_SAMPLES and synth[0] == P0           # nominal first
    keys = {(p.rho0, p.m, p.V0, p.beta0) for p in synth}
    assert not any((p.rho0, p.m, p.V0, p.beta0) in keys for p in held)
    assert P0 not in held
    for p in held:                                        # inside the dispersion box
        assert abs(p.rho0 / P0.rho0 - 1) <= 0.15 + 1e-12 and abs(p.V0 - P0.V0) <= 50 + 1e-9


def test_bad_input_is_a_one_line_error(capsys):
    from descent_fmus.synthesis.cli.main import main
    with pytest.raises(ValueError, match="unknown statistic 'p99'; choose from"):
        statistic("p99")
    with pytest.raises(ValueError, match="unknown statistic"):
        set_problems(statistic_name="worst-ish")
    with pytest.raises(ValueError, match="samples must be >= 1"):
        held_out_samples(0)
    with pytest.raises(ValueError, match="samples must be >= 1"):
        synthesis_set(0)
    for argv in (["--samples", "0"], ["--noise", "-0.1"], ["--scenario", "third"]):
        with pytest.raises(SystemExit) as exc:
            main(["reentry", "robustness"] + argv)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1, err


def test_racing_stops_a_law_that_misses_the_nominal_flight(fmu_dir):
    problem = next(p for p in set_problems() if p.name == "reentry-sensed")
    with ClosedLoop(problem.wiring, fmu_dir / "Reentry.fmu",
                    fmu_dir / "SensedNetworkOperatorController.fmu") as loop:
        bad = NetworkOperator.linear([[0.0, 0.0, 0.0]], bias=[0.2])     # u = +0.2: 35 km short
        bad.input_names = ["y1", "y2", "y3"]
        results = problem.runner.flights(loop, problem, bad)
        assert len(results) == 1                              # raced out after the nominal
        outcome = problem.evaluate(results)
        f, extras = outcome.f, outcome.extras
        assert f[1] >= 2 * RACE_OFFSET and extras["raced_out"]
        good = problem.runner.flights(loop, problem, problem.basic())
        assert len(good) == SYNTHESIS_SAMPLES                   # flew the whole set
        g = problem.evaluate(good).f
        assert g[1] < RACE_OFFSET                               # ranked before any raced-out law
        miss = [min(objectives(r.final, P0)["J2"], MISS_CAP) for r in good]
        assert g[1] == pytest.approx(float(np.mean(miss)), rel=1e-12)   # the default: mean


def test_container_path_flies_the_same_flight_as_the_python_master(fmu_dir):
    law = sensed_basic_law(2)
    p = P0.with_(rho0=1.3, V0=7530.0)
    with ClosedLoop(WIRING, fmu_dir / "Reentry.fmu",
                    fmu_dir / "NetworkOperatorController.fmu") as loop:
        a = loop.run(plant_values(p), law.start_values()).final
    with ContainerLoop(WIRING, fmu_dir / "Reentry.fmu",
                       fmu_dir / "NetworkOperatorController.fmu") as cl:
        for _ in range(2):                                      # reset between runs
            b = cl.run(plant_values(p), law.start_values()).final
            assert b["status"] == a["status"] == 1
            for k in ("L", "load_max", "t_end", "aero_load_max"):
                assert b[k] == pytest.approx(a[k], rel=1e-12)
        nominal = cl.run(plant_values(P0), law.start_values()).final
        assert nominal["L"] != pytest.approx(a["L"], rel=1e-6)   # the parameters were applied


def test_committed_robust_law_lands_the_nominal_flight(fmu_dir):
    # the law the built ReentrySensedClosedLoop.fmu carries (docs/make_reentry_robust_figures.py
    # picks it: nominal flight within 1 km, median J1 over the set below 9.0 -- the issue's
    # targets for the nominal flight and the load)
    assert DEFAULT_LAW_FILE.exists()
    law = default_law()
    assert reads_estimate(law)
    (row,) = fly_law(law, [P0], fmu_dir)
    assert row["landed"] and row["J2"] < 1000.0 and row["J1"] < J1_LIMIT


def test_exported_closed_loop_with_the_estimator_reproduces_the_pareto_row(fmu_dir, tmp_path):
    # the robust law as users get it (controller FMU with the estimator and the law as
    # defaults, closed-loop container, SSP), flown by fmpy simulate from every point of the
    # synthesis set: the objectives equal the evaluator's row
    from descent_fmus.synthesis.fmi.law_files import export_law_files
    problem = next(p for p in set_problems() if p.name == "reentry-sensed")
    law = default_law()
    out = export_law_files(law, tmp_path / "law", law_fmu="native", fmu_dir=fmu_dir,
                           problem=problem, closed_loop=True)
    assert out["law_fmu"] == "python" and out["ssp"].endswith(".ssp")
    with ClosedLoop(problem.wiring, fmu_dir / "Reentry.fmu",
                    fmu_dir / "SensedNetworkOperatorController.fmu") as loop:
        outcome = problem.evaluate(problem.runner.flights(loop, problem, law))
    f, extras = outcome.f, outcome.extras
    assert extras["flights"] == SYNTHESIS_SAMPLES

    class Final:
        def __init__(self, row, start):
            self.final, self.start = row, start

    finals = []
    unzipped = extract(out["closed_loop_fmu"], str(tmp_path / "cl"))
    fmu = instantiate_fmu(unzipped, read_model_description(unzipped))   # once, reset per run
    for k, s in enumerate(problem.initial_states):
        if k:
            fmu.reset()
        res = simulate_fmu(unzipped, start_values=s, step_size=T_PLUS, output_interval=T_PLUS,
                           fmu_instance=fmu, terminate=False,
                           output=["L", "h", "load_max", "aero_load_max", "status", "t_end"])
        finals.append(Final({k: res[-1][k] for k in res.dtype.names}, s))
    fmu.freeInstance()
    g, _ = problem.objectives(finals)
    assert g == pytest.approx(f, rel=1e-12)


def test_study_reports_every_option_and_the_oracle(fmu_dir):
    study = robust_study({}, 4, 5, fmu_dir, scenarios=("default", "second"))
    assert study["disjoint"]
    for name in ("default", "second"):
        sc = study["scenarios"][name]
        assert set(sc["stats"]) == {"basic law (paper q)", "NPC guidance", "oracle bound"}
        assert sc["stats"]["NPC guidance"]["miss_nominal"] < 100.0     # lands the nominal flight
        # more drag at any time shortens the flight, so u = +-0.2 throughout bound the range:
        # no guidance misses less than the oracle (1 m: the plant's integration error)
        for rows in sc["results"].values():
            for r, bound in zip(rows, sc["oracle"]):
                assert r["J2"] >= bound - 1.0
    text = "\n".join(table_lines(study))
    assert "disjoint" in text and "NPC guidance" in text
    json.dumps(study)                                            # JSON-able as --json emits
