"""S5 descent from lunar orbit: plant against an independent solve_ivp and closed forms, the
registered synthesis problem through the unchanged evaluator, exported laws through fmpy
simulate, the committed synthesised law, bad input."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu
from scipy.integrate import solve_ivp

from descent_fmus.models.fmu_support import ParameterError
from descent_fmus.models.lunar_descent import (CRASHED, G_TILDE, IN_BOX, OUT_OF_DOMAIN, DescentParams,
                                  simulate)
from descent_fmus.synthesis.cosim import ClosedLoop, FMUError
from descent_fmus.synthesis.evaluator import Evaluator, get_problem
from descent_fmus.synthesis.methods.ga import GAConfig
from descent_fmus.synthesis.methods.network_operator import NetworkOperator
from descent_fmus.synthesis.systems.lunar_descent.problems import (INITIAL_SET, WIRING, fly_in_process,
                                               initial_states, objectives, per_state,
                                               synthesis_basic_law)
from descent_fmus.synthesis.synthesize import run_synthesis

ROOT = Path(__file__).resolve().parent.parent
REFERENCE_LAW = ROOT / "tests" / "reference" / "lunar_descent_law.json"


def _spec_rhs(t, x, tilt, p0=440.0, pud=319.0, g0=1.623, r0=1_738_400.0):
    # SPEC S5 / seed 004 eqs. (1)-(6), written out again here (independent of models/), with
    # the law u1 = theta + pi + tilt applied continuously, u2 = 0
    V, th, h, _, m = x
    u1 = th + math.pi + tilt
    W = 9.80665 * p0 / m
    g = g0 * (r0 / (r0 + h)) ** 2
    return [W * math.cos(u1 - th) - g * math.cos(th),
            (W * math.sin(u1 - th) + g * math.sin(th)) / V,
            V * math.cos(th), V * math.sin(th) / (r0 + h), -p0 / pud]


def test_plant_against_solve_ivp_and_spec_orientation_numbers():
    # SPEC S5 "for orientation": tilt 0.4 rad reaches 50 m/s at h ~ 8.8 km after ~443 s with
    # ~610 kg used; tilt 0.3 crashes at V ~ 750 m/s.
    x0 = [1690.0, math.pi / 2, 18_000.0, 0.0, 1400.0]
    ev = lambda t, x, tilt: x[0] - 50.0  # noqa: E731
    ev.terminal = True
    ref = solve_ivp(_spec_rhs, (0, 600), x0, args=(0.4,), method="DOP853", rtol=1e-11,
                    atol=1e-9, events=ev)
    t_ref, x_ref = ref.t_events[0][0], ref.y_events[0][0]
    p = DescentParams(V_lo=45.0, V_hi=50.0, h_lo=0.0, h_hi=1e5)   # box = "V reaches 50 m/s"
    fi = simulate(p, lambda t, x: (x[1] + math.pi + 0.4, 0.0), step=0.05, dt=0.05)
    assert fi.stop == IN_BOX
    assert fi.t == pytest.approx(t_ref, abs=0.05)                  # zero-order hold of 0.05 s
    assert fi.x[2] == pytest.approx(x_ref[2], abs=1.0)
    assert fi.x[4] == pytest.approx(x_ref[4], abs=0.1)
    assert (t_ref, x_ref[2], 1400 - x_ref[4]) == pytest.approx((443, 8800, 610), rel=0.01)
    crash = simulate(DescentParams(), lambda t, x: (x[1] + math.pi + 0.3, 0.0))
    assert crash.stop == CRASHED and abs(crash.x[2]) < 1e-6
    assert crash.x[0] == pytest.approx(750, rel=0.01)


def test_pure_braking_is_tsiolkovsky():
    # closed form: horizontal pure braking without gravity. W = g~ k P / m and
    # dm/dt = -k P / P_ud give dV = g~ P_ud dm / m, the rocket equation
    # V0 - V = g~ P_ud ln(m0/m) for any thrust factor k, and m = m0 - k P t / P_ud
    for k_P, u2 in ((1.0, 0.0), (1.03, 25.0)):
        p = DescentParams(g0=1e-12, k_P=k_P, P_ud=322.19)
        fi = simulate(p, lambda t, x: (1.5 * math.pi, u2), t_plus=200.0)
        m = 1400.0 - k_P * (440.0 + u2) * 200.0 / 322.19
        assert fi.x[4] == pytest.approx(m, rel=1e-12)
        assert fi.x[0] == pytest.approx(1690.0 - G_TILDE * 322.19 * math.log(1400.0 / m),
                                        rel=1e-10)
        assert fi.x[2] == pytest.approx(18_000.0, abs=1e-6)    # theta stays pi/2


def test_step_halving_and_integration_accuracy():
    law = synthesis_basic_law()
    for th, h0 in INITIAL_SET:
        a = fly_in_process(law, th, h0)                       # STEP = dt = 1 s
        b = fly_in_process(law, th, h0, step=0.5)             # halved communication step
        c = fly_in_process(law, th, h0, dt=0.25)              # 4x finer RK4 sub-step
        assert a.stop == b.stop == c.stop == IN_BOX
        assert abs(a.x[2] - b.x[2]) < 3.0 and abs(a.x[0] - b.x[0]) < 0.1
        assert abs(a.x[2] - c.x[2]) < 0.05 and abs(a.x[4] - c.x[4]) < 1e-3


def test_evaluator_runs_the_registered_problem_through_the_fmus(fmu_dir):
    prob = get_problem("lunar-descent")
    basic = prob.basic_law()
    laws = [basic, basic.with_q([3.4] + basic.q[1:])]
    with Evaluator("lunar-descent", fmu_dir) as ev:        # built from FMU paths alone
        F, extras = ev.evaluate(laws + laws)
        assert ev.simulated == 2
    for law, f, ex in zip(laws, F, extras):
        finals = []
        for th, h0 in INITIAL_SET:
            fi = fly_in_process(law, th, h0)             # same equations, in-process
            finals.append({"V": fi.x[0], "h": fi.x[2], "h_min": fi.h_min,
                           "fuel": 1400.0 - fi.x[4], "t_end": fi.t_end, "end": float(fi.stop)})
        (j1, j2), _ = objectives(finals)
        assert f == pytest.approx((j1, j2), rel=1e-9, abs=1e-9)
    # the basic (designer's linear) law already reaches the box from every initial state
    assert extras[0]["in_box"] == 5 and extras[0]["h_min"] > 1500.0
    assert F[0] == pytest.approx((211.48, 50.0), abs=0.01)


def test_exported_law_reproduces_its_pareto_row(fmu_dir, tmp_path):
    cfg = GAConfig(population=6, crossovers=2, lchr=2, epoch=2, elite_trim=1)
    s = run_synthesis("lunar-descent", tmp_path / "run", fmu_dir, cfg, 1, seed=3,
                      progress=False)
    row = s["pareto"][0]
    finals = []
    for th, h0 in INITIAL_SET:
        res = simulate_fmu(row["closed_loop_fmu"], start_values={"theta0": th, "h0": h0},
                           output=["V", "h", "h_min", "fuel", "t_end", "stop"])
        last = res[-1]
        finals.append({"V": last["V"], "h": last["h"], "h_min": last["h_min"],
                       "fuel": last["fuel"], "t_end": last["t_end"], "end": float(last["stop"])})
    (j1, j2), _ = objectives(finals)
    assert (j1, j2) == pytest.approx((row["J1"], row["J2"]), rel=1e-12, abs=1e-9)
    law = NetworkOperator.load(Path(row["closed_loop_fmu"]).parent / "law.json")
    assert law.formula(6) == row["formula"] and law.outputs == [26, 32]


def test_committed_synthesised_law(fmu_dir):
    # tests/reference/lunar_descent_law.json: Pareto law of `descent-fmus synthesize
    # lunar-descent` (default budget, seed 1; models/README.md): every initial state ends in
    # the box, never below the box floor, closer to the box centre in h than the basic law
    law = NetworkOperator.load(REFERENCE_LAW)
    meta = json.loads(REFERENCE_LAW.with_suffix(".meta.json").read_text())
    rows = []
    with ClosedLoop(WIRING, fmu_dir / "LunarDescent.fmu",
                    fmu_dir / "NetworkOperatorController.fmu") as loop:
        for s in initial_states():
            rows.append(per_state(loop.run(plant_values=s,
                                           controller_values=law.start_values()).final))
    assert all(r["in_box"] for r in rows) and min(r["h_min"] for r in rows) >= 1500.0
    j1, j2 = sum(r["j1"] for r in rows), sum(r["j2"] for r in rows)
    assert (j1, j2) == pytest.approx((meta["J1"], meta["J2"]), rel=1e-9)
    assert j1 < 0.5 * 211.48 and j2 <= 50.0 + 1e-9


def test_stall_and_bad_input(fmu_dir):
    stall = simulate(DescentParams(), lambda t, x: (x[1] + math.pi + 0.4, 0.0))
    assert stall.stop == OUT_OF_DOMAIN and stall.x[0] == pytest.approx(1.0, abs=1e-6)
    for kw, msg in [({"P_ud": -1.0}, "P_ud must be > 0"), ({"theta0": 4.0}, "theta0"),
                    ({"V_lo": 70.0}, "V_lo < V_hi"), ({"m0": math.nan}, "m0 must be finite"),
                    ({"V0": 50.0, "h0": 2000.0}, "inside the terminal box")]:
        with pytest.raises(ParameterError, match=msg):
            DescentParams(**kw).validate()
    with ClosedLoop(WIRING, fmu_dir / "LunarDescent.fmu",
                    fmu_dir / "NetworkOperatorController.fmu") as loop:
        with pytest.raises(FMUError, match="P_ud must be > 0"):
            loop.run(plant_values={"P_ud": -5.0})
        # the loop is still usable after the error
        assert loop.run(plant_values=initial_states()[0],
                        controller_values=synthesis_basic_law().start_values()).flag == IN_BOX


def test_report_cli(fmu_dir, tmp_path):
    def cli(*a):
        return subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli", "lunar-descent-report",
                               "--fmus", str(fmu_dir), *a], cwd=ROOT, capture_output=True,
                              text=True)
    r = cli("--law", str(REFERENCE_LAW), "--samples", "8", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["laws"]["synthesised"]["dispersion"]["n"] == 8
    assert out["laws"]["baseline"]["J1"] == pytest.approx(211.48, abs=0.01)
    NetworkOperator.basic_law().save(tmp_path / "one_output.json")
    r = cli("--law", str(tmp_path / "one_output.json"), "--samples", "0")
    assert r.returncode == 2 and "4 inputs and drives 2 outputs" in r.stderr
    r = cli("--law", str(tmp_path / "missing.json"))
    assert r.returncode == 2 and "cannot read law" in r.stderr
    assert np.isfinite(out["laws"]["synthesised"]["initial_set"]["fuel_max"])


def test_synthesize_cli_takes_the_problem_budget(fmu_dir, tmp_path):
    # options not given on the command line come from SynthesisProblem.defaults["ga"]
    from descent_fmus.synthesis.systems.lunar_descent.problems import GA_BUDGET
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli", "synthesize", "lunar-descent",
                        "--population", "6", "--generations", "0", "--workers", "1",
                        "--no-export", "--json", "--fmus", str(fmu_dir), "--out", str(out)],
                       cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    ga = json.loads((out / "run.json").read_text())["ga"]
    assert ga["population"] == 6
    assert {k: ga[k] for k in ("crossovers", "lchr", "epoch")} == \
        {k: GA_BUDGET[k] for k in ("crossovers", "lchr", "epoch")}
    assert json.loads(r.stdout)["laws_all_in_box"] >= 1     # the basic law reaches the box
