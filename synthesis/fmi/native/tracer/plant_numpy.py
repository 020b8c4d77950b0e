"""What stands in for ``numpy`` in the model modules at trace time (the telescope plants).

Arrays of traced values are NumPy *object* arrays: their element-wise arithmetic, ``@`` and
``.dot`` run NumPy's object loops, which call the traced operators element by element -- so
those operations are traced as NumPy's object arithmetic performs them (in order, one product
and one sum at a time).  NumPy's float arrays compute the same element-wise operations
bitwise, but its matrix products go through BLAS (blocked, vectorised, fused multiply-adds)
and its ``linalg`` functions through LAPACK; those give results that differ from the C
code's in the last bits.  ``linalg.inv``, ``det`` and ``eigvalsh`` of a traced 3x3 matrix are
calls of the C runtime (``pc_inv3``, ``pc_det3``, ``pc_eigvalsh3``: partial-pivoting LU as
LAPACK's ``getrf``, and Jacobi rotations).  A plant that uses them is equal to its pythonfmu
FMU to a stated tolerance, not bitwise.
"""
from __future__ import annotations

import numpy as np

from descent_fmus.models.traceable import where
from descent_fmus.synthesis.fmi.native.tracer.plant_shims import TRACED_MATH
from descent_fmus.synthesis.fmi.native.tracer.plant_trace import Sym, TraceError, active, operand

__all__ = ["TRACED_NUMPY", "LINALG_CALLS"]

#: the C runtime's functions for NumPy's linalg: name -> (inputs, outputs)
LINALG_CALLS = {"pc_inv3": (9, 9), "pc_det3": (9, 1), "pc_eigvalsh3": (9, 3)}


def _has_sym(obj) -> bool:
    if isinstance(obj, Sym):
        return True
    if isinstance(obj, np.ndarray):
        return obj.dtype == object and any(isinstance(v, Sym) for v in obj.flat)
    if isinstance(obj, (list, tuple)):
        return any(_has_sym(v) for v in obj)
    return False


def _objects(obj) -> np.ndarray:
    """``obj`` (nested sequences, arrays) as an object array of its numbers and traced values."""
    if isinstance(obj, np.ndarray) and obj.dtype == object:
        return obj
    if isinstance(obj, np.ndarray):
        return obj.astype(object)
    out = np.empty(np.shape(np.array(obj, dtype=object)), dtype=object)
    flat = list(_flatten(obj))
    for k, v in enumerate(flat):
        out.flat[k] = float(v) if isinstance(v, (int, float, np.floating)) else v
    return out


def _flatten(obj):
    if isinstance(obj, (list, tuple, np.ndarray)):
        for v in obj:
            yield from _flatten(v)
    else:
        yield obj


def _map(fn, x):
    if isinstance(x, np.ndarray):
        out = np.empty(x.shape, dtype=object)
        for k, v in enumerate(x.flat):
            out.flat[k] = fn(v)
        return out
    return fn(x)


def _linalg_call(name: str, a) -> list:
    m = _objects(a)
    if m.shape != (3, 3):
        raise TraceError(f"numpy.linalg on a traced {m.shape} array: 3x3 only")
    n_in, n_out = LINALG_CALLS[name]
    tr = active()
    args = [operand(v) for v in m.flat]
    return tr.call("linalg", {"fn": name, "args": args}, n_out,
                   key=("linalg", name, tuple(tr.skey(o) for o in args)))


class _TracedLinalg:
    """``numpy.linalg`` with traced 3x3 matrices (see the module docstring)."""

    def __getattr__(self, name):
        return getattr(np.linalg, name)

    @staticmethod
    def inv(a):
        if not _has_sym(a):
            return np.linalg.inv(a)
        return np.array(_linalg_call("pc_inv3", a), dtype=object).reshape(3, 3)

    @staticmethod
    def det(a):
        return _linalg_call("pc_det3", a)[0] if _has_sym(a) else np.linalg.det(a)

    @staticmethod
    def eigvalsh(a):
        if not _has_sym(a):
            return np.linalg.eigvalsh(a)
        w = _linalg_call("pc_eigvalsh3", a)
        # ascending (NumPy's and pc_eigvalsh3's): a later one is never smaller -- sorting them
        # decides nothing
        tr = active()
        for i in range(3):
            for j in range(i + 1, 3):
                tr.decided[operand(w[j] < w[i])] = False
                tr.decided[operand(w[i] > w[j])] = False
        return np.array(w, dtype=object)

    @staticmethod
    def norm(x):
        if not _has_sym(x):
            return np.linalg.norm(x)
        v = _objects(x).ravel()
        return TRACED_MATH.sqrt(v.dot(v))          # NumPy: sqrt(x.dot(x)) for a vector


class _TracedNumpy:
    """``numpy`` with traced values (see the module docstring)."""

    linalg = _TracedLinalg()

    def __getattr__(self, name):
        return getattr(np, name)

    @staticmethod
    def array(obj, dtype=None, *args, **kwargs):
        return _objects(obj) if _has_sym(obj) else np.array(obj, dtype, *args, **kwargs)

    @staticmethod
    def asarray(obj, dtype=None, *args, **kwargs):
        return _objects(obj) if _has_sym(obj) else np.asarray(obj, dtype, *args, **kwargs)

    @staticmethod
    def cos(x):
        return _map(TRACED_MATH.cos, x) if _has_sym(x) else np.cos(x)

    @staticmethod
    def sin(x):
        return _map(TRACED_MATH.sin, x) if _has_sym(x) else np.sin(x)

    @staticmethod
    def sqrt(x):
        return _map(TRACED_MATH.sqrt, x) if _has_sym(x) else np.sqrt(x)

    @staticmethod
    def cross(a, b):
        if not (_has_sym(a) or _has_sym(b)):
            return np.cross(a, b)
        a, b = _objects(a).ravel(), _objects(b).ravel()
        return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                         a[0] * b[1] - a[1] * b[0]], dtype=object)

    @staticmethod
    def allclose(a, b, rtol=1e-05, atol=1e-08, equal_nan=False):
        if not (_has_sym(a) or _has_sym(b)):
            return np.allclose(a, b, rtol, atol, equal_nan)
        a, b = _objects(a).ravel(), _objects(b).ravel()
        # isclose: (|a - b| <= atol + rtol |b| and b finite) or a == b -- as one conditional per
        # element (where |a - b| <= ... holds, a == b adds nothing: a = b = +-inf fails it)
        return all(where(abs(x - y) <= atol + rtol * abs(y), lambda y=y: TRACED_MATH.isfinite(y),
                         lambda x=x, y=y: x == y) for x, y in zip(a, b))


#: the stand-in for ``numpy`` (``import numpy as np`` in the model modules)
TRACED_NUMPY = _TracedNumpy()
