"""Room for weighted arcs in a ``[basic_law] gains`` law (``ga.weighted_arcs > 0``): the suite's
linear basic laws get unused constants and free nodes, fly as before through the FMUs, and a
weighted arc on them applies and starts neutral (docs/methods/network_operator.md, "Weighted
arcs").  Oracles: the law without room flown through the same evaluator (the spare parts are
inert), the file's law itself (off = bit for bit)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

SUITE = Path(__file__).resolve().parents[2] / "benchmarks" / "suite"
sys.path.insert(0, str(SUITE))

import plant_flights as F  # noqa: E402
import suite  # noqa: E402

from descent_fmus.synthesis.methods.registry import make_method  # noqa: E402


@pytest.fixture(scope="module")
def di(fmu_dir):
    F.build_plants(names=("DoubleIntegrator",))
    return suite.load("mintime-di", fmu_dir, build=False)


def test_off_is_the_files_law_bit_for_bit(di):
    off, law = di.tuned(weighted_arcs=0.0).basic(), di.basic_law
    assert np.array_equal(off.psi, law.psi) and off.q == law.q and off.outputs == law.outputs
    ga = make_method("network-operator", di)
    assert ga.params.n == 3 and np.array_equal(ga.psi0, law.psi)


def test_the_roomy_law_and_a_neutral_weighted_arc_fly_as_the_gains_law(di, fmu_dir):
    on = di.tuned(weighted_arcs=0.25)
    roomy = on.basic()
    assert roomy.size == di.basic_law.size == 24 and len(roomy.q) == 5
    ga = make_method("network-operator", on)
    assert ga.params.n == 5 and ga.structure.n_params == 5
    psi = ga.structure.apply(roomy.psi, [(4, 8, 11, 30)])     # x2's product through ssq
    assert not np.array_equal(psi, roomy.psi)
    plain = F.objective_of(di, di.basic_law, fmu_dir)
    # oracle: the law without room through the same evaluator (mean time, worst excess, cv)
    for law in (roomy, roomy.with_structure(psi, roomy.q)):
        got = F.objective_of(on, law, fmu_dir)
        assert np.allclose(got[0], plain[0], rtol=1e-12, atol=0) and got[1] == plain[1]
    # the weight grown from 0 changes the flight (the test can fail)
    grown = F.objective_of(on, roomy.with_structure(psi, [-1.0, -1.5, 0.0, 0.5, 0.0]), fmu_dir)
    assert abs(grown[0][0] - plain[0][0]) > 1e-3
