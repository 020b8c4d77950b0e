"""The network-operator law interpreter: a matrix checked and compiled to an arc program, evaluated.

A mathematical expression is a directed acyclic graph on nodes ``1..L`` stored as ``Psi`` (L x L):
the diagonal ``psi[i][i]`` is the number of the *binary* operation at node ``i``; an off-diagonal
``psi[i][j]`` (``i < j``) the number of the *unary* operation on the arc ``i -> j``; 0 = nothing.
Source nodes ``1..nx`` hold the inputs, nodes ``nx+1..nx+nq`` the parameters q.

Evaluation (Diveev & Sofronova 2007): a non-source node starts at the unit element of its
binary operation; for ``i = 1..L-1`` and every ``j > i`` with ``psi[i][j] != 0`` and
``psi[j][j] != 0``: ``z_j <- chi_{psi_jj}(z_j, rho_{psi_ij}(z_i))``.  The outputs are the values of
the output nodes (the last node by default).  ``atan2`` has no unit element: its "unit" is NaN
(no value yet) and its first incoming arc sets the node, later arcs fold ``a <- atan2(a, b)``;
a node without incoming arcs holds ``finite(unit)`` (0 for atan2, the unit for the others).
Every node value is clamped to ``[-BIG, BIG]`` and a NaN becomes 0, so the law never returns
NaN or inf.

This module is the one implementation of the evaluation (the operations are the table of
:mod:`models.controllers.operation_table`); it serves the :class:`NetworkOperatorController`
FMU (:mod:`models.controllers.network_operator`) and ``synthesis.methods.law.NetworkOperator``.

References
----------
A.I. Diveev, E.Yu. Shmalko (reentry paper), section "Синтез"; A.I. Diveev, E.A. Sofronova, "The network operator
method in control problems", Vestnik RUDN, 2007, no. 4.
"""
from __future__ import annotations

from descent_fmus.models.controllers.operation_table import BIG, BINARY, UNARY, UNIT, finite

__all__ = ["MatrixError", "compile_law", "evaluate", "evaluate_points"]


class MatrixError(ValueError):
    """A network-operator matrix or its node map is malformed."""


def compile_law(psi, nx: int, nq: int, outputs):
    """Check a matrix and turn it into an arc program for :func:`evaluate`.

    Parameters
    ----------
    psi : sequence of sequences of int
        Square upper-triangular matrix (L x L).
    nx, nq : int
        Number of input and parameter source nodes (nodes ``1..nx`` and ``nx+1..nx+nq``).
    outputs : sequence of int
        1-based node numbers whose values are the outputs.

    Returns
    -------
    tuple
        ``(L, init, arcs, outputs0)``: node count, initial node values for non-source nodes
        (``None`` for sources), the arc list ``(i, j, rho, chi)`` in evaluation order (0-based) and
        the 0-based output nodes.

    Raises
    ------
    MatrixError
        Not square, not upper-triangular, unknown operation number, an arc into a source node,
        an operation on a source node, or an output node out of range.
    """
    if hasattr(psi, "dtype") and psi.ndim == 2 and psi.dtype.kind in "iu":
        program = _compiled(psi, nx, nq, outputs)
        if program is not None:
            return program
        psi = psi.tolist()       # a malformed matrix: the checks below name the fault
    L = len(psi)
    rows = [list(r) for r in psi]
    for i, r in enumerate(rows):
        if len(r) != L:
            raise MatrixError(f"matrix is not square: row {i + 1} has {len(r)} entries, "
                              f"expected {L}")
    ns = nx + nq
    if nx < 0 or nq < 0 or ns > L:
        raise MatrixError(f"{nx} inputs + {nq} parameters do not fit in a {L}-node matrix")
    init = [None] * L
    for i in range(L):
        for j in range(L):
            v = rows[i][j]
            if v != int(v):
                raise MatrixError(f"psi[{i + 1},{j + 1}] = {v!r} is not an integer")
            v = int(v)
            if j < i and v != 0:
                raise MatrixError(f"matrix is not upper-triangular: psi[{i + 1},{j + 1}] = {v} "
                                  f"below the diagonal")
            if i == j:
                if not 0 <= v < len(BINARY):
                    raise MatrixError(f"unknown binary operation {v} at node {i + 1} "
                                      f"(psi[{i + 1},{i + 1}]); valid: 1..{len(BINARY) - 1}")
                if i < ns and v != 0:
                    raise MatrixError(f"node {i + 1} is a source node (input or parameter) and "
                                      f"cannot carry binary operation {v}")
            elif j > i and v != 0:
                if not 0 < v < len(UNARY):
                    raise MatrixError(f"unknown unary operation {v} on arc {i + 1}->{j + 1} "
                                      f"(psi[{i + 1},{j + 1}]); valid: 1..{len(UNARY) - 1}")
                if j < ns:
                    raise MatrixError(f"arc {i + 1}->{j + 1} ends in source node {j + 1}")
    arcs = [(i, j, UNARY[int(rows[i][j])], BINARY[int(rows[j][j])])
            for i in range(L) for j in range(i + 1, L) if rows[i][j] and rows[j][j]]
    fed = {j for _, j, _, _ in arcs}
    for j in range(ns, L):          # the unit; finite(unit) (atan2: 0) on a node without arcs
        b = int(rows[j][j])
        init[j] = (UNIT[b] if j in fed else finite(UNIT[b])) if b else 0.0
    outs = []
    for k, o in enumerate(outputs):
        if not 1 <= int(o) <= L:
            raise MatrixError(f"output {k + 1} names node {o}, outside 1..{L}")
        outs.append(int(o) - 1)
    return L, init, arcs, outs


#: [choice] Programs of the last integer matrices compiled, by their bytes and the sources and
#: outputs: the search compiles a structure once for all its parameter vectors (a CMA-ES
#: generation, the GA's children that share a form), where each law was compiled anew.
#: Programs are never modified (:func:`evaluate` copies ``init``), so laws share them.
PROGRAM_CACHE = 4096
_PROGRAMS: dict = {}


def _compiled(psi, nx: int, nq: int, outputs):
    """:func:`_compile_array` through :data:`PROGRAM_CACHE` (the programs of valid matrices
    only)."""
    key = (psi.shape, psi.dtype.str, psi.tobytes(), nx, nq, tuple(outputs))
    program = _PROGRAMS.get(key)
    if program is None:
        program = _compile_array(psi, nx, nq, outputs)
        if program is not None:
            if len(_PROGRAMS) >= PROGRAM_CACHE:
                del _PROGRAMS[next(iter(_PROGRAMS))]      # the oldest entry
            _PROGRAMS[key] = program
    return program


def _compile_array(psi, nx: int, nq: int, outputs):
    """:func:`compile_law` of an integer NumPy matrix, its checks made on the whole array at
    once (the search compiles thousands of laws a second); None when a check fails, so that
    :func:`compile_law`'s item-by-item checks name the fault.  The same program: the arcs in
    the same order (row by row), the same initial values and outputs."""
    L = psi.shape[0]
    ns = nx + nq
    if psi.shape[1] != L or nx < 0 or nq < 0 or ns > L:
        return None
    lower, ii, jj = _triangles(L)
    diag = psi.diagonal()
    up = psi[ii, jj]                                # above the diagonal, row by row
    if L and (psi[lower].any() or diag.min() < 0 or diag.max() >= len(BINARY)
              or diag[:ns].any() or up.min(initial=0) < 0 or up.max(initial=0) >= len(UNARY)
              or up[jj < ns].any()):
        return None
    outs = [int(o) - 1 for o in outputs]
    if any(not 0 <= o < L for o in outs):
        return None
    d = diag.tolist()
    on = (up != 0) & (diag[jj] != 0)
    fed = jj[on].tolist()
    arcs = [(i, j, UNARY[r], BINARY[d[j]])
            for i, j, r in zip(ii[on].tolist(), fed, up[on].tolist())]
    fed = set(fed)
    init = [None] * L
    for j in range(ns, L):          # the unit; finite(unit) (atan2: 0) on a node without arcs
        b = d[j]
        init[j] = (UNIT[b] if j in fed else finite(UNIT[b])) if b else 0.0
    return L, init, arcs, outs


_TRIANGLES: dict = {}


def _triangles(L: int):
    """The mask below the diagonal and the indices above it (row by row) of an L x L matrix."""
    t = _TRIANGLES.get(L)
    if t is None:
        import numpy as np
        ii, jj = np.triu_indices(L, 1)
        t = _TRIANGLES[L] = (np.tril(np.ones((L, L), bool), -1), ii, jj)
    return t


def evaluate(program, sources):
    """Values of the output nodes of a compiled law for source values ``sources`` (x then q)."""
    L, init, arcs, outs = program
    z = list(init)
    for k, v in enumerate(sources):
        z[k] = finite(v)
    for i, j, rho, chi in arcs:
        try:
            v = chi(z[j], rho(z[i]))
        except (OverflowError, ValueError, ZeroDivisionError):  # never met: the operands are
            v = BIG                                               # finite, the guards hold
        # finite(v), written inline (the hot loop of every closed-loop step)
        z[j] = BIG if v > BIG else (-BIG if v < -BIG else (v if v == v else 0.0))
    return [z[o] for o in outs]


def evaluate_points(program, points):
    """:func:`evaluate` at several source vectors at once: per point the same operations in
    the same order, so the same values bit for bit; the loop runs over the arcs once, each arc
    applied to every point (a law's equivalence key evaluates it on a few dozen points)."""
    L, init, arcs, outs = program
    n = len(points)
    cols = [[v] * n for v in init]
    for k in range(len(points[0]) if n else 0):
        cols[k] = [finite(p[k]) for p in points]
    for i, j, rho, chi in arcs:
        try:
            new = [chi(a, rho(b)) for a, b in zip(cols[j], cols[i])]
        except (OverflowError, ValueError, ZeroDivisionError):   # as in evaluate: never met
            new = [_guarded(chi, rho, a, b) for a, b in zip(cols[j], cols[i])]
        cols[j] = [BIG if v > BIG else (-BIG if v < -BIG else (v if v == v else 0.0))
                   for v in new]
    return [[cols[o][p] for o in outs] for p in range(n)]


def _guarded(chi, rho, a, b):
    try:
        return chi(a, rho(b))
    except (OverflowError, ValueError, ZeroDivisionError):
        return BIG
