"""The on-board linear-programme solver of the native re-planner (``c/lp.h``), callable from Python.

The native ``GuidedNetworkOperatorController`` solves the re-planner's linear programmes with a
small dense simplex method written in C (``c/lp.h``: the dual simplex tableau, one row per
variable), where the pythonfmu controller calls SciPy's HiGHS.  :func:`linprog_c` runs the same
C code on a problem stated as :func:`scipy.optimize.linprog` takes it, so the two can be
compared (the tests) and timed (``benchmarks/reentry_robust_replan.py``).
"""
from __future__ import annotations

import ctypes
import threading

import numpy as np

__all__ = ["linprog_c", "LpResult", "STATUS"]

#: lp.h's status codes (0 like SciPy's: the optimum found).
STATUS = {0: "optimal", 1: "iteration limit", 2: "infeasible (or unbounded)", 4: "out of memory"}
_LOCK = threading.Lock()
_DLL: list = []


class LpResult:
    """``status`` (0: optimal, :data:`STATUS`), ``x`` and ``fun`` (None unless optimal)."""

    def __init__(self, status: int, x, fun):
        self.status, self.x, self.fun = status, x, fun
        self.message = STATUS.get(status, f"status {status}")

    def __repr__(self) -> str:
        return f"LpResult(status={self.status} ({self.message}), fun={self.fun})"


def _dll(compiler: str | None = None):
    with _LOCK:
        if not _DLL:
            from descent_fmus.synthesis.fmi.native.builders.build import cached_library
            from descent_fmus.synthesis.systems.reentry.native.controllers import C_DIR
            dll = ctypes.CDLL(str(cached_library("onboard-lp", [C_DIR / "lp_export.c"],
                                                 [C_DIR / "lp.h"], compiler)))
            arr = np.ctypeslib.ndpointer(np.float64, flags="C_CONTIGUOUS")
            i = ctypes.c_int
            dll.descent_lp_solve.restype = i
            dll.descent_lp_solve.argtypes = [i, arr, i, arr, arr, i, arr, arr, arr, arr, arr,
                                             ctypes.POINTER(ctypes.c_double)]
            _DLL.append(dll)
        return _DLL[0]


def _matrix(a, n: int, what: str) -> np.ndarray:
    m = np.zeros((0, n)) if a is None else np.array(a, dtype=float, ndmin=2)
    if m.size == 0:
        return np.zeros((0, n))
    if m.ndim != 2 or m.shape[1] != n:
        raise ValueError(f"{what} must have {n} columns, got shape {m.shape}")
    return np.ascontiguousarray(m)


def linprog_c(c, A_ub=None, b_ub=None, A_eq=None, b_eq=None, bounds=(0.0, None),
              compiler: str | None = None) -> LpResult:
    """Minimise ``c @ x`` subject to ``A_ub @ x <= b_ub``, ``A_eq @ x == b_eq`` and the
    ``bounds`` (one ``(lo, hi)`` pair for all variables or one per variable, None for none) --
    the arguments of :func:`scipy.optimize.linprog` -- with the native re-planner's solver.

    Raises
    ------
    ValueError
        Shapes that do not fit, or non-finite data.
    """
    c = np.ascontiguousarray(c, dtype=float).ravel()
    n = len(c)
    a_ub, a_eq = _matrix(A_ub, n, "A_ub"), _matrix(A_eq, n, "A_eq")
    b_ub = np.ascontiguousarray(np.zeros(0) if b_ub is None else b_ub, dtype=float).ravel()
    b_eq = np.ascontiguousarray(np.zeros(0) if b_eq is None else b_eq, dtype=float).ravel()
    if len(b_ub) != len(a_ub) or len(b_eq) != len(a_eq):
        raise ValueError(f"b_ub has {len(b_ub)} entries for {len(a_ub)} rows of A_ub, b_eq "
                         f"{len(b_eq)} for {len(a_eq)} rows of A_eq")
    pairs = [bounds] * n if len(bounds) == 2 and not isinstance(bounds[0], (tuple, list)) \
        else list(bounds)
    if len(pairs) != n:
        raise ValueError(f"bounds: {len(pairs)} pairs for {n} variables")
    lo = np.array([-np.inf if p[0] is None else p[0] for p in pairs], dtype=float)
    hi = np.array([np.inf if p[1] is None else p[1] for p in pairs], dtype=float)
    for name, v in (("c", c), ("A_ub", a_ub), ("b_ub", b_ub), ("A_eq", a_eq), ("b_eq", b_eq)):
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name} has non-finite entries")
    if np.any(np.isnan(lo)) or np.any(np.isnan(hi)) or np.any(lo == np.inf) \
            or np.any(hi == -np.inf):
        raise ValueError("bounds must be numbers or None, lower < inf, upper > -inf")
    x, value = np.zeros(n), ctypes.c_double(0.0)
    status = _dll(compiler).descent_lp_solve(
        n, c, len(a_ub), a_ub.ravel() if len(a_ub) else np.zeros(1), b_ub if len(b_ub)
        else np.zeros(1), len(a_eq), a_eq.ravel() if len(a_eq) else np.zeros(1),
        b_eq if len(b_eq) else np.zeros(1), lo, hi, x, ctypes.byref(value))
    return LpResult(status, x if status == 0 else None, value.value if status == 0 else None)
