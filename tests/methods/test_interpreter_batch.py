"""The search's fast routes through the law interpreter give what the item-by-item routes give,
bit for bit: ``compile_law`` of a NumPy matrix (checks on the whole array) against the same
matrix as lists (checks entry by entry), and ``evaluate_points`` / ``NetworkOperator.raw_points``
against ``evaluate`` / ``raw`` point by point (the oracle in both cases: the item-by-item path,
which the FMU runs)."""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.models.controllers.law_interpreter import (MatrixError, compile_law, evaluate,
                                                             evaluate_points)
from descent_fmus.models.controllers.operation_table import BINARY, UNARY
from descent_fmus.synthesis.methods.law import NetworkOperator

from tests.law_samples import every_operation_law


def _random_law(rng, L=24, nx=4, nq=5):
    psi = np.zeros((L, L), dtype=int)
    ns = nx + nq
    for j in range(ns, L):
        psi[j, j] = rng.integers(0, len(BINARY)) if rng.random() < 0.9 else 0
        for i in range(j):
            if rng.random() < 0.2:
                psi[i, j] = rng.integers(1, len(UNARY))
    return NetworkOperator(psi, nx=nx, q=list(rng.normal(0, 3, nq)),
                           outputs=[L, L - 1], input_scale=list(rng.uniform(0.5, 2, nx)),
                           input_offset=list(rng.normal(0, 1, nx)))


def test_array_compile_is_the_list_compile():
    rng = np.random.default_rng(4)
    laws = [every_operation_law(rng)] + [_random_law(rng) for _ in range(60)]
    for law in laws:
        fast = compile_law(law.psi, law.nx, len(law.q), law.outputs)
        slow = compile_law(law.psi.tolist(), law.nx, len(law.q), law.outputs)
        assert fast[0] == slow[0] and fast[3] == slow[3]
        assert fast[2] == slow[2]                     # same arcs, same order, same functions
        assert [repr(v) for v in fast[1]] == [repr(v) for v in slow[1]]   # nan (atan2) too


@pytest.mark.parametrize("bad, nx, nq, outputs", [
    ([[0, 1, 0], [0, 0, 1], [1, 0, 1]], 1, 0, [3]),        # below the diagonal
    ([[0, 1, 0], [0, 99, 0], [0, 0, 1]], 1, 0, [3]),       # unknown binary operation
    ([[0, 99, 0], [0, 1, 0], [0, 0, 1]], 1, 0, [3]),       # unknown unary operation
    ([[0, 1, 0], [0, 0, 1], [0, 0, 1]], 2, 0, [3]),        # arc into a source node
    ([[1, 1, 0], [0, 1, 0], [0, 0, 1]], 1, 0, [3]),        # operation on a source node
    ([[0, 1, 0], [0, 1, 0], [0, 0, 1]], 1, 0, [4]),        # output out of range
    ([[0, 1, 0], [0, 1, -1], [0, 0, 1]], 1, 0, [3]),       # negative operation number
])
def test_array_compile_names_the_same_fault(bad, nx, nq, outputs):
    with pytest.raises(MatrixError) as slow:
        compile_law(bad, nx, nq, outputs)
    with pytest.raises(MatrixError) as fast:
        compile_law(np.array(bad), nx, nq, outputs)
    assert str(fast.value) == str(slow.value)


def test_points_are_evaluated_as_one_by_one():
    rng = np.random.default_rng(7)
    laws = [every_operation_law(rng) for _ in range(5)] + [_random_law(rng) for _ in range(40)]
    for law in laws:
        pts = np.vstack([rng.normal(0, 1, (8, law.nx)), rng.normal(0, 1e4, (8, law.nx)),
                         np.zeros((1, law.nx))])
        got = law.raw_points(pts)
        want = [law.raw(x) for x in pts]
        assert [[float(v).hex() for v in r] for r in got] == \
            [[float(v).hex() for v in r] for r in want]                   # bit for bit
        assert [[type(v) for v in r] for r in got] == [[type(v) for v in r] for r in want]
    program = compile_law(np.array([[0, 6], [0, 1]]), 1, 0, [2])   # exp: overflow guarded
    assert evaluate_points(program, [[1e300], [-3.0]]) == [evaluate(program, [1e300]),
                                                           evaluate(program, [-3.0])]
    assert evaluate_points(program, []) == []
