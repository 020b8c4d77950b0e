"""Laws the tests of several folders share: the committed S1 and S5 laws and a random law on
which every operation of the network operator acts (the native interpreter's and the readable
formula's tests, ``tests/fmi/native/`` and ``tests/methods/``)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from descent_fmus.models.controllers.operation_table import BINARY, UNARY
from descent_fmus.synthesis.methods.law import NetworkOperator

REF = Path(__file__).resolve().parent / "reference"
REENTRY_LAW = REF / "reentry_best_law.json"
DESCENT_LAW = REF / "lunar_descent_law.json"


def every_operation_law(rng, L: int = 32, nx: int = 3, nq: int = 4) -> NetworkOperator:
    """A law on which every unary and every binary operation acts (random arcs, scaled inputs,
    two outputs with wide bounds so that the raw node values show)."""
    psi = np.zeros((L, L), dtype=int)
    ns = nx + nq
    unary = list(rng.permutation(np.arange(1, len(UNARY))))
    for j in range(ns, L):
        psi[j, j] = 1 + (j - ns) % (len(BINARY) - 1)
        for i in rng.choice(j, size=min(j, 3), replace=False):
            psi[i, j] = unary.pop() if unary else rng.integers(1, len(UNARY))
    return NetworkOperator(psi, nx=nx, q=list(rng.uniform(-4, 4, nq)), outputs=[L, L - 3],
                           bounds=[(-1e9, 1e9), (-0.2, 0.3)], input_scale=[2.0, 0.5, -1.0],
                           input_offset=[0.1, -3.0, 0.0])
