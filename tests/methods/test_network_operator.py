"""The network operator: evaluation, the FMU against the in-process type, bad matrices."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from descent_fmus.models.controllers.law_interpreter import MatrixError
from descent_fmus.models.controllers.network_operator import L_MAX, PAPER_Q
from descent_fmus.models.controllers.operation_table import BIG, UNARY, BINARY
from descent_fmus.synthesis.fmi.slave import FMUError, load_slave
from descent_fmus.synthesis.methods.law import LawFileError, NetworkOperator
from descent_fmus.synthesis.methods.law_fmu import CapacityError
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law, paper_law


def random_law(rng: np.random.Generator, L: int, nx: int = 2, nq: int = 2) -> NetworkOperator:
    """A random valid law: every non-source node gets a binary op and 1-3 incoming arcs."""
    psi = np.zeros((L, L), dtype=int)
    ns = nx + nq
    for j in range(ns, L):
        psi[j, j] = rng.integers(1, len(BINARY))
        for i in rng.choice(j, size=min(j, int(rng.integers(1, 4))), replace=False):
            psi[i, j] = rng.integers(1, len(UNARY))
    return NetworkOperator(psi, nx=nx, q=list(rng.uniform(-4, 4, nq)))


def test_basic_law_is_the_linear_law():
    # Diveev & Shmalko eqs. (24)-(25): u = clip(q1 y1 + q2 y2, -0.2, 0.2)
    law = paper_basic_law()
    q1, q2 = PAPER_Q
    for y in [(0.01, -0.02), (0.3, 0.1), (-1.0, 0.0)]:
        expect = min(max(q1 * y[0] + q2 * y[1], -0.2), 0.2)
        assert law(y)[0] == pytest.approx(expect, rel=1e-15, abs=1e-17)


def test_paper_law_matches_its_printed_formula():
    # the paper's printed law: z = z15 - y1, z15 = z14 + rho4(z9) + rho8(y1), ... (printed expression)
    law = paper_law()
    q1, q2 = PAPER_Q
    r4 = lambda z: math.copysign(math.sqrt(abs(z)), z) if z != 0 else 0.0  # noqa: E731
    r8 = lambda z: (1 - math.exp(-z)) / (1 + math.exp(-z))                  # noqa: E731
    for y1, y2 in [(0.02, -0.05), (-0.1, 0.3), (0.5, 0.5)]:
        z9 = (-q2 + y2) * (q1 * y1)
        z10 = z9 + r8(y2)
        z13 = -z10 + r4(z10)
        z14 = z13 + (1.0 if y2 >= 0 else 0.0)
        z15 = z14 + r4(z9) + r8(y1)
        assert law.raw((y1, y2))[0] == pytest.approx(z15 - y1, rel=1e-12)
    assert law.size == 16


def test_operations_are_overflow_safe():
    huge = [0.0, 1e-300, -1e-300, 1e300, -1e300, math.inf, -math.inf, math.nan, 7.0, -7.0]
    for k in range(1, len(UNARY)):
        for b in range(1, len(BINARY)):
            psi = np.zeros((4, 4), dtype=int)
            psi[0, 2] = k
            psi[2, 2] = b
            psi[1, 2] = 1
            psi[2, 3] = k
            psi[3, 3] = b
            law = NetworkOperator(psi, nx=2, q=[], bounds=[(-BIG, BIG)])
            for a in huge:
                for c in (a, 1.0, -1e200):
                    out = law.raw((a, c))[0]
                    assert math.isfinite(out) and abs(out) <= BIG, (k, b, a, c, out)


def test_fmu_equals_in_process_evaluation(fmu_dir):
    rng = np.random.default_rng(2026)
    fmu = load_slave(fmu_dir / "NetworkOperatorController.fmu", "no")
    md = fmu.model
    vr = {v.name: v.valueReference for v in md.modelVariables}
    try:
        checked = 0
        for trial in range(25):
            L = int(rng.integers(6, L_MAX + 1))
            law = random_law(rng, L)
            fmu.reset()
            sv = law.start_values()
            ints = {k: v for k, v in sv.items() if isinstance(v, int)}
            reals = {k: v for k, v in sv.items() if not isinstance(v, int)}
            fmu.setInteger([vr[k] for k in ints], list(ints.values()))
            fmu.setReal([vr[k] for k in reals], list(reals.values()))
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            for x in list(rng.normal(0, 3, (8, 2))) + [np.array([0.0, 0.0]),
                                                      np.array([1e12, -1e12])]:
                fmu.setReal([vr["x[1]"], vr["x[2]"]], list(map(float, x)))
                u = fmu.getReal([vr["u[1]"]])[0]
                assert math.isfinite(u)
                # same code path (models.controllers.network_operator): equal to rounding
                assert u == pytest.approx(law(list(x))[0], rel=1e-12, abs=1e-15)
                checked += 1
        assert checked == 25 * 10
    finally:
        fmu.terminate()
        fmu.freeInstance()


def test_json_round_trip(tmp_path):
    law = paper_law()
    path = law.save(tmp_path / "law.json")
    back = NetworkOperator.load(path)
    assert np.array_equal(back.psi, law.psi) and back.q == law.q
    assert back((0.1, -0.2)) == law((0.1, -0.2))
    assert "y1" in law.formula() and "heaviside(y2)" in law.formula()


def test_formula_of_basic_law():
    assert paper_basic_law().formula(4) == "((y1*2.259)+(y2*1.953))"
    # scaled and offset inputs print as the node holds them: scale * (x - offset), the sign
    # of a negative offset folded ("+0.25", not "--0.25")
    law = NetworkOperator.linear([[1.0, 1.0]], input_names=["y1", "y2"],
                                 input_scale=[100.0, 10.0], input_offset=[0.19, -0.25])
    f = law.formula(4)
    assert "100*(y1-0.19)" in f and "10*(y2+0.25)" in f and "--" not in f


# -- bad input ----------------------------------------------------------------------------
def test_not_upper_triangular():
    psi = np.zeros((5, 5), dtype=int)
    psi[4, 4] = 1
    psi[0, 4] = 1
    psi[3, 1] = 2
    with pytest.raises(MatrixError, match=r"not upper-triangular: psi\[4,2\]"):
        NetworkOperator(psi, nx=2, q=[0.0])


def test_unknown_operations():
    psi = np.zeros((5, 5), dtype=int)
    psi[4, 4] = 1
    psi[0, 4] = 99
    with pytest.raises(MatrixError, match="unknown unary operation 99 on arc 1->5"):
        NetworkOperator(psi, nx=2, q=[0.0])
    psi[0, 4] = 1
    psi[4, 4] = 42
    with pytest.raises(MatrixError, match="unknown binary operation 42 at node 5"):
        NetworkOperator(psi, nx=2, q=[0.0])


def test_not_square_and_arcs_into_sources():
    with pytest.raises(MatrixError, match="square"):
        NetworkOperator(np.zeros((3, 4)), nx=1, q=[])
    psi = np.zeros((4, 4), dtype=int)
    psi[0, 1] = 1
    with pytest.raises(MatrixError, match="ends in source node 2"):
        NetworkOperator(psi, nx=2, q=[])


def test_law_larger_than_the_fmu():
    psi = np.zeros((L_MAX + 8, L_MAX + 8), dtype=int)
    psi[-1, -1] = 1
    psi[0, -1] = 1
    law = NetworkOperator(psi, nx=2, q=[1.0])
    with pytest.raises(CapacityError, match=f"{L_MAX + 8} nodes.*at most {L_MAX}"):
        law.start_values()


def test_non_finite_parameter():
    with pytest.raises(MatrixError, match="q2 must be finite"):
        paper_basic_law(q=(1.0, math.inf))


def test_malformed_law_file(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text("{not json")
    with pytest.raises(LawFileError, match="not valid JSON"):
        NetworkOperator.load(p)
    p.write_text(json.dumps({"psi": [[0, 1], [0, 0]], "q": []}))
    with pytest.raises(LawFileError, match="missing the field 'nx'"):
        NetworkOperator.load(p)


def test_fmu_rejects_a_bad_matrix_with_its_reason(fmu_dir):
    from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
    from descent_fmus.synthesis.systems.reentry.wiring import WIRING
    loop = ClosedLoop(WIRING, fmu_dir / "Reentry.fmu", fmu_dir / "NetworkOperatorController.fmu")
    try:
        with pytest.raises(FMUError, match="unknown unary operation 77 on arc 1->5"):
            loop.run(controller_values={"psi[1,5]": 77})
        with pytest.raises(FMUError, match="V0 must be > 0"):
            loop.run(plant_values={"V0": -5.0})
        with pytest.raises(ValueError, match="beta0 must be finite"):
            loop.run(plant_values={"beta0": math.nan})
        # the loop is still usable after the errors
        assert loop.run().stopped
    finally:
        loop.close()
