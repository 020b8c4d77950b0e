"""The parking problem's polar law in the network operator's operation set, from the Cartesian
basic law of benchmarks/suite/parking.toml (docs/methods/network_operator.md, "Why the
parking law stalls"): how many variations away it is and what the forms on the way fly."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

SUITE = Path(__file__).resolve().parents[2] / "benchmarks" / "suite"
sys.path.insert(0, str(SUITE))

import mintime as M  # noqa: E402

from descent_fmus.synthesis.methods.encoding import StructureCodec  # noqa: E402
from descent_fmus.synthesis.methods.ga_config import FILE_BINARY, FILE_UNARY  # noqa: E402
from descent_fmus.synthesis.methods.law import NetworkOperator  # noqa: E402

ARC = M._plant_module("unicycle").arc
#: parking.toml's starts (x0, y0, theta0)
STARTS = [(-2.0, 0.0, 0.0), (-2.0, 0.0, 3.141592653590), (0.0, 1.5, 0.0), (0.0, -1.5, 0.0),
          (2.0, 0.0, 0.0), (-1.5, 1.5, -1.570796326795), (1.5, -1.5, 1.570796326795),
          (0.0, 2.0, 1.570796326795)]
#: parking.toml's basic law (v = -0.5 x, omega = -y - theta; 32 nodes: inputs 0-2, the 8
#: parameters 3-10, v's products 11-13, sum 14, spares 15-20; omega's 21-31)
BASIC = NetworkOperator.linear([[-0.5, 0.0, 0.0], [0.0, -1.0, -1.0]], [0.0, 0.0],
                               bounds=[(-1.0, 1.0), (-3.0, 3.0)], size=32)
#: (kind, i, j, op): node 11 hypot over x, y (and q3 -> 0): rho; node 25 atan2(-y, node 24)
#: with node 24 = q6 x (q6 = -1): phi; node 26 phi - theta, its arc to 27 wrapped: alpha;
#: alpha twice more (arcs 26 -> 28, 26 -> 29 wrapped) and phi (25 -> 30) on omega's chain
POLAR_PATH = [(1, 0, 11, 10), (2, 1, 11, 1), (1, 0, 25, 9), (2, 1, 25, 3), (2, 2, 26, 3),
              (0, 26, 27, 29), (2, 26, 28, 29), (2, 26, 29, 29), (2, 25, 30, 1)]
#: the polar form's constants: every gain 0 but q6 = -1 (node 24 = -x)
Q = [0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0]


def park(law) -> float:
    """parking.toml's objective: mean final distance + |heading| over the starts, 12 s of
    0.1 s steps flown on the plant's exact arcs (the plant file's own step), v in [-1, 1],
    omega in [-3, 3]."""
    out = []
    for s in STARTS:
        x = s
        for _ in range(120):
            v, w = law(x)
            x = ARC(x, min(1.0, max(-1.0, v)), min(3.0, max(-3.0, w)), 0.1)
        out.append(math.hypot(x[0], x[1]) + abs(x[2]))
    return float(np.mean(out))


def _form(variations) -> NetworkOperator:
    codec = StructureCodec(32, 11, unary=FILE_UNARY, binary=FILE_BINARY)
    return NetworkOperator(codec.apply(BASIC.psi, variations), nx=3, q=Q,
                           outputs=BASIC.outputs, bounds=BASIC.bounds)


def test_the_polar_law_is_nine_variations_from_the_cartesian_basic_law():
    # every variation uses the problem file's default operations (hypot, atan2, neg, wrap)
    assert all(op in (FILE_BINARY if kind == 1 else FILE_UNARY)
               for kind, _, _, op in POLAR_PATH)
    law = _form(POLAR_PATH)
    assert int(np.sum(law.psi != BASIC.psi)) == 9
    # the matrix is the polar law v = rho, omega = 3 alpha + phi: the oracle flies that law
    # written with math.hypot, atan2 and the plant's wrap, the same starts, to 1e-12
    def polar(x):
        rho = math.hypot(x[0], x[1])
        phi = math.atan2(-x[1], -x[0])
        return rho, 3.0 * math.remainder(phi - x[2], 2.0 * math.pi) + phi
    ref = park(polar)
    assert ref < 1e-3                                    # 4.5e-4: parks every start
    assert math.isclose(park(lambda x: law(list(x))), ref, rel_tol=1e-9, abs_tol=1e-12)


def test_no_form_on_the_way_is_better_than_the_basic_law_until_the_last_variations():
    # the forms after 0..9 variations of the path, with the polar constants: only the ninth
    # parks; after 6-8 variations (omega = alpha + phi, 2 alpha + phi, ...) the heading stays
    # off (> 1), the forms after 2-5 are worse than the basic matrix with the same constants
    # (3.24): no improving path one variation at a time (docs/methods/network_operator.md)
    values = [park(lambda x, f=_form(POLAR_PATH[:n]): f(list(x))) for n in range(10)]
    assert math.isclose(values[0], 3.2411, abs_tol=1e-3)
    assert all(v > values[0] for v in values[2:6])
    assert min(values[:8]) > 1.0 and values[8] > 1.0
    assert values[9] < 1e-3


@pytest.mark.slow         # 200 CMA-ES flights of 8 starts in Python: ~10-20 s
def test_the_polar_form_with_inherited_constants_loses_to_its_parents_until_tuned():
    # a child that reaches the form flies its parents' constants: the basic law's (2.32 with
    # the basic matrix) give 12.1; CMA-ES (the package's refinement library, seed 1, sigma
    # 0.5) from them is below the basic law after 200 evaluations (0.67; 0.013 after 1 000)
    import cma
    law = _form(POLAR_PATH)

    def value(q):
        f = NetworkOperator(law.psi, nx=3, q=list(q), outputs=law.outputs, bounds=law.bounds)
        return park(lambda x: f(list(x)))
    inherited = list(BASIC.q)
    assert math.isclose(park(lambda x: BASIC(list(x))), 2.3245, abs_tol=1e-3)
    assert value(inherited) > 12.0
    es = cma.CMAEvolutionStrategy(inherited, 0.5, {"seed": 1, "maxfevals": 200, "verbose": -9})
    es.optimize(value)
    assert es.result.fbest < 0.7
