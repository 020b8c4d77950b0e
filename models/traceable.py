"""Branches written so that the native-plant generator traces them as one C conditional.

The native plant FMUs are C generated from these models by running their own functions on
traced values (``synthesis/fmi/native/tracer/plant_trace.py``).  A plain ``if`` on a value is traced
too -- one C ``if`` per path -- but everything after it is then written once per path; where
that would multiply, a model writes the branch with these helpers instead.  On plain numbers
they are exactly the Python expressions they name (the same operations, the same result, the
same laziness), so a model's numbers do not change.

This module needs nothing but the standard library.
"""
from __future__ import annotations

__all__ = ["where", "clip", "minimum", "maximum", "first_smallest"]


def where(cond, if_true, if_false):
    """``if_true if cond else if_false``.

    A branch given as a zero-argument callable is evaluated only when it is taken (as Python's
    conditional expression evaluates only its branch); a traced ``cond`` makes it a C
    conditional whose two branches are each computed on their side only.
    """
    select = getattr(cond, "__where__", None)
    if select is not None:
        return select(if_true, if_false)
    branch = if_true if cond else if_false
    return branch() if callable(branch) else branch


def clip(x, lo, hi):
    """``min(max(x, lo), hi)``, with its rules for equal values and NaN (NaN stays NaN)."""
    m = where(lo > x, lo, x)
    return where(hi < m, hi, m)


def minimum(first, *rest):
    """``min(first, *rest)`` with its rules: a later value replaces the current one only if it
    is smaller (so the first of equal values, and a NaN only where ``min`` keeps it)."""
    m = first
    for v in rest:
        m = where(v < m, v, m)
    return m


def maximum(first, *rest):
    """``max(first, *rest)`` with its rules (a later value replaces the current one only if it
    is larger)."""
    m = first
    for v in rest:
        m = where(v > m, v, m)
    return m


def first_smallest(pairs):
    """``min(pairs, key=lambda p: p[1])``: the first of the pairs ``(label, value)`` whose value
    is the smallest."""
    best = pairs[0]
    for p in pairs[1:]:
        best = where(p[1] < best[1], p, best)
    return best
