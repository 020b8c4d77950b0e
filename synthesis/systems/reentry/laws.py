"""S1 reentry: the paper's laws as network-operator matrices (the basic law and the law the
paper found), with the reentry control bounds.

References
----------
Diveev & Shmalko (reentry paper): basic law eqs. (24)-(25); the found 16-node law and its
printed formula.
"""
from __future__ import annotations

import numpy as np

from descent_fmus.models.controllers.network_operator import BASIC_LAW_PSI, PAPER_Q
from descent_fmus.models.reentry import U_BOUNDS
from descent_fmus.synthesis.methods.law import NetworkOperator

__all__ = ["PAPER_LAW_PSI", "paper_basic_law", "paper_law", "reentry_law"]


def _paper_law_psi():
    """The paper's printed 16-node law (Diveev & Shmalko), rebuilt from its printed formula.

    The printed matrix is OCR-damaged (a row with 15 entries, diagonal entries lost), so it is
    rebuilt from the printed expression, which is complete:
    z5 = q1*y1, z6 = -q2 + y2, z7 = z6*z5, z8 = z7, z9 = z8, z10 = z9 + rho8(y2), z11 = z10,
    z12 = -z10, z13 = z12 + rho4(z11), z14 = z13 + rho9(y2), z15 = z14 + rho4(z9) + rho8(y1),
    z16 = z15 - y1; nodes 1 y1, 2 y2, 3 q1, 4 q2.
    """
    psi = [[0] * 16 for _ in range(16)]
    binary = {5: 2, 6: 1, 7: 2, 8: 1, 9: 1, 10: 1, 11: 1, 12: 1, 13: 1, 14: 1, 15: 1, 16: 1}
    for node, op in binary.items():
        psi[node - 1][node - 1] = op
    arcs = [(1, 5, 1), (3, 5, 1), (2, 6, 1), (4, 6, 3), (6, 7, 1), (5, 7, 1), (7, 8, 1),
            (8, 9, 1), (9, 10, 1), (2, 10, 8), (10, 11, 1), (10, 12, 3), (12, 13, 1),
            (11, 13, 4), (13, 14, 1), (2, 14, 9), (14, 15, 1), (9, 15, 4), (1, 15, 8),
            (15, 16, 1), (1, 16, 3)]
    for i, j, op in arcs:
        psi[i - 1][j - 1] = op
    return psi


PAPER_LAW_PSI = _paper_law_psi()


def reentry_law(psi, q, outputs=None, nx: int = 2, **kw) -> NetworkOperator:
    """A law of the reentry inputs (y1, y2 unless ``input_names`` is given) with the control
    bounds of the Reentry plant, ``u`` in [-0.2, 0.2]."""
    kw.setdefault("input_names", ["y1", "y2", "y3", "c"][:nx])
    return NetworkOperator(psi, nx=nx, q=list(q), outputs=outputs, bounds=[U_BOUNDS], **kw)


def paper_basic_law(q=PAPER_Q, size: int = 16) -> NetworkOperator:
    """The paper's basic law ``u = clip(q1 y1 + q2 y2, -0.2, 0.2)`` (Diveev & Shmalko, eqs.
    24-25).

    ``size`` pads the matrix with unused nodes (room for the GA's variations); the output is
    node 7.
    """
    n0 = len(BASIC_LAW_PSI)
    psi = np.zeros((max(size, n0), max(size, n0)), dtype=int)
    psi[:n0, :n0] = BASIC_LAW_PSI
    return reentry_law(psi, q, outputs=[n0])


def paper_law() -> NetworkOperator:
    """The paper's found 16-node law with q1 = 2.259375, q2 = 1.953125 (Diveev & Shmalko)."""
    return reentry_law(np.array(PAPER_LAW_PSI), PAPER_Q)
