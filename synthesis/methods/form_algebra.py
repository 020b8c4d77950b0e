"""The algebra of a network operator's forms, apart from any search: which nodes feed given
ones, a form's skeleton (its formula with the constants abstracted: two matrices with one
skeleton are one form to the structure search), which constants a change of the matrix
touches, and a function-preserving choice of a new form's constants (a network morphism).
:mod:`synthesis.methods.form_search` uses them; docs/methods/network_operator.md records each
choice with its measurement.
"""
from __future__ import annotations

import numpy as np

from descent_fmus.models.controllers.operation_table import BINARY_OPS

__all__ = ["form_skeleton", "preserving_constants", "touched_constants", "upstream"]


def upstream(psi, nodes) -> np.ndarray:
    """Mask of the nodes of ``psi`` (upper triangular, arcs ``a -> b`` for ``a < b``) from
    which a path leads into one of ``nodes`` (those included)."""
    psi = np.asarray(psi)
    mark = np.zeros(len(psi), bool)
    mark[sorted(nodes)] = True
    for b in range(len(psi) - 1, 0, -1):
        if mark[b]:
            mark[:b] |= psi[:b, b] != 0
    return mark


#: unary operations that only scale their argument (identity, negation, halving, doubling):
#: a constant factor, which the skeleton absorbs
_SCALING = {1, 3, 20, 21}
#: binary operations whose operands commute and repeat idempotently in a skeleton (sum and
#: product: a repeated term or factor is the same term with another constant)
_LINEAR_FOLD = {1: "+", 2: "*"}
#: a skeleton's mark of a free scale (a product with a constant factor)
_SCALED = "c*"


def form_skeleton(psi, nx: int, nq: int, outputs) -> str:
    """The law's form with its constants abstracted: the expression of each output node of
    matrix ``psi`` (``nx`` inputs ``x0, x1, ..``, then ``nq`` constants; node ``j`` folds its
    binary operation ``psi[j, j]`` over ``rho(z_i)`` of its arcs ``i -> j``) in which every
    value that reads no input is one constant ``c``, a scaling operation (identity, negation,
    halving, doubling) is dropped, a product with a constant factor is ``c*`` its other
    factors (a free scale: ``sin(c*x0)`` is not ``sin(x0)``), and a sum or product is
    flattened, its terms sorted (a sum's taken once, without their free scales:
    ``x1 + c*x1 + c`` has the skeleton of ``c*x1 + c``, ``+[c,x1]``).  Two laws with one
    skeleton are one form with other constants; a changed operation on a path from an input
    changes it.  docs/methods/network_operator.md, "The one-operation neighbourhood of the
    tuned basic law, and forms by skeleton"."""
    psi = np.asarray(psi)
    L, ns = len(psi), nx + nq
    expr = [f"x{k}" for k in range(nx)] + ["c"] * (L - nx)
    folds = {}                          # a sum's or product's skeleton -> (sign, its terms)
    for j in range(ns, L):
        b = int(psi[j, j])
        terms = [expr[i] if expr[i] == "c" or int(psi[i, j]) in _SCALING
                 else f"u{int(psi[i, j])}({expr[i]})"
                 for i in range(j) if psi[i, j] and b]
        if not terms or all(t == "c" for t in terms):
            continue                        # reads no input: a constant
        if len(terms) == 1 or (b == 1 and len(set(terms)) == 1):
            one = b in _LINEAR_FOLD or BINARY_OPS[b].first == "b"
            expr[j] = terms[0] if one else f"b{b}({terms[0]})"    # one term: its value
            continue
        sym = _LINEAR_FOLD.get(b)
        if sym is None:
            expr[j] = f"b{b}(" + ",".join(terms) + ")"
            continue
        flat, scaled = [], False
        for t in terms:
            core = t[2:] if t.startswith(_SCALED) else t
            scaled |= core != t or t == "c"
            inner = folds.get(core)
            flat += list(inner[1]) if inner and inner[0] == sym else [core]
        if sym == "*":                      # the constant factors: one free scale
            uniq = sorted(t for t in flat if t != "c")     # x0 x0 is not x0
            core = uniq[0] if len(uniq) == 1 else "*[" + ",".join(uniq) + "]"
            expr[j] = _SCALED + core if scaled else core
        else:                               # a sum's terms without their scales
            uniq = sorted(set(flat))
            core = expr[j] = uniq[0] if len(uniq) == 1 else "+[" + ",".join(uniq) + "]"
        if len(uniq) > 1:
            folds[core] = (sym, tuple(uniq))
    return "; ".join(expr[o - 1] for o in outputs)


def touched_constants(psi0, psi, nx: int, m: int) -> list:
    """The constants (0-based indices into q; source nodes ``nx .. nx + m - 1``) that the
    change from matrix ``psi0`` to ``psi`` touches: for an arc ``i -> j`` given a new unary
    operation (or added) those upstream of ``i`` (what the new operation reads: its scale is
    theirs), for a new binary operation at node ``j`` or a removed arc those upstream of
    ``j``; when none is, those upstream of the changed entries' target nodes."""
    psi0, psi = np.asarray(psi0), np.asarray(psi)
    src, dst = set(), set()
    for i, j in zip(*np.nonzero(psi != psi0)):
        dst.add(int(j))
        src.add(int(j) if i == j or psi[i, j] == 0 else int(i))
    for nodes in (src, dst):
        if nodes:
            mark = upstream(psi, nodes)
            out = [k for k in range(m) if mark[nx + k]]
            if out:
                return out
    return []


def preserving_constants(parent, child, idx, points, lo=-np.inf, hi=np.inf) -> list:
    """A network morphism: ``child``'s constants ``idx`` (the others kept) chosen by least
    squares so that its clipped outputs match ``parent``'s at ``points`` (plant units); the
    child's own constants when the fit is no closer.  [choice] the clipped outputs (what is
    flown) are matched, not the raw ones: docs/methods/network_operator.md "Function-preserving
    starts"."""
    from scipy.optimize import least_squares
    points = np.asarray(points, float)
    bounds = np.asarray(parent.bounds, float)
    want = np.clip(np.asarray(parent.raw_points(points), float), bounds[:, 0], bounds[:, 1])
    q0 = np.array(child.q, float)

    def resid(z):
        q = q0.copy()
        q[idx] = z
        got = np.asarray(child.with_q(list(q)).raw_points(points), float)
        r = (np.clip(got, bounds[:, 0], bounds[:, 1]) - want).ravel()
        return np.where(np.isfinite(r), r, 1e3)

    start = np.clip(q0[idx], lo, hi)
    best = float(np.sum(resid(start) ** 2))
    for z0 in (start, np.where(start == 0.0, 1.0, start)):
        try:
            sol = least_squares(resid, z0, bounds=(lo, hi), max_nfev=40 * len(idx))
        except (ValueError, FloatingPointError):
            continue
        if 2 * sol.cost < best:
            best, start = 2 * sol.cost, sol.x
    q = q0.copy()
    q[idx] = start
    return list(q)
