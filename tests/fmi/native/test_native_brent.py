"""brent.h, the native root search, against the Python it reproduces, bit for bit.

Oracles: scipy.optimize.brentq(f, a, b, xtol, rtol, maxiter, disp=False) -- its root, the
number of calls of f, the errors it raises -- for br_brentq; the Python
descent_fmus.models.controllers.reentry_prediction.solve_control -- (u, miss(u), evaluations), the
errors it raises, the calls of miss made -- for br_solve_control.

Both sides call the same Python function (C through a ctypes callback, reset between the two
runs), so a case compares the root searches alone: every double is compared by its bits (NaN and
the sign of zero included), every count with ==.  A Python exception inside f is the callback's
nonzero return (a failing model evaluation in the FMU).
"""
from __future__ import annotations

import ctypes
import math
import os
import random
import shutil
import struct
import subprocess
from pathlib import Path

import pytest
from scipy.optimize import brentq

from descent_fmus.models.controllers.reentry_prediction import solve_control
from descent_fmus.models.reentry import U_BOUNDS

HEADER_DIR = (Path(__file__).resolve().parents[3] / "synthesis" / "fmi" / "native" / "c"
              / "runtime")
FLAGS = ["-O2", "-ffp-contract=off", "-std=c99", "-Wall", "-Wextra", "-Werror"]
EPS = 2.0 ** -52
RTOL = 4.0 * EPS                                   # SciPy's default and smallest rtol
NAN, INF = float("nan"), float("inf")

BR_SIGN, BR_ARGS, BR_NAN, BR_ZERODIV = -100, -101, -102, -103

CALLBACK = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_double, ctypes.c_void_p,
                            ctypes.POINTER(ctypes.c_double))

WRAPPER = r"""
#include "brent.h"
#include "brent.h"      /* twice: the include guard */
#include <stddef.h>

int t_brentq(br_fn f, double a, double b, double xtol, double rtol, int maxiter,
             double *root, int *calls)
{
    return br_brentq(f, NULL, a, b, xtol, rtol, maxiter, root, calls);
}

int t_solve_control(br_fn miss, double u0, double tol, int max_iter, double lo, double hi,
                    double *u, double *miss_u, int *evaluations)
{
    return br_solve_control(miss, NULL, u0, tol, max_iter, lo, hi, u, miss_u, evaluations);
}

void t_constants(int *codes, double *rtol)
{
    codes[0] = BR_SIGN; codes[1] = BR_ARGS; codes[2] = BR_NAN; codes[3] = BR_ZERODIV;
    *rtol = BR_RTOL;
}
"""


def compiler() -> str | None:
    cc = os.environ.get("CC")
    return shutil.which(cc) if cc else shutil.which("gcc")


def fb(x: float) -> str:
    """A double as its repr and its bits: equal strings, the same double (NaN, -0.0 too)."""
    return f"{x!r}/{struct.pack('<d', x).hex()}"


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    """brent.h behind two exported wrappers, built with the project's flags and -Werror."""
    cc = compiler()
    if cc is None:
        pytest.skip("no C compiler (CI installs gcc)")
    d = tmp_path_factory.mktemp("brent")
    (d / "t_brent.c").write_text(WRAPPER)
    so = d / "t_brent.so"
    r = subprocess.run([cc, "-shared", "-fPIC", *FLAGS, "-I", str(HEADER_DIR),
                        str(d / "t_brent.c"), "-o", str(so), "-lm"], capture_output=True, text=True)
    assert r.returncode == 0 and not r.stderr, r.stderr           # warning-free
    dll = ctypes.CDLL(str(so))
    dll.t_brentq.restype = ctypes.c_int
    dll.t_brentq.argtypes = [CALLBACK, ctypes.c_double, ctypes.c_double, ctypes.c_double,
                             ctypes.c_double, ctypes.c_int, ctypes.POINTER(ctypes.c_double),
                             ctypes.POINTER(ctypes.c_int)]
    dll.t_solve_control.restype = ctypes.c_int
    dll.t_solve_control.argtypes = [CALLBACK, ctypes.c_double, ctypes.c_double, ctypes.c_int,
                                    ctypes.c_double, ctypes.c_double,
                                    ctypes.POINTER(ctypes.c_double),
                                    ctypes.POINTER(ctypes.c_double),
                                    ctypes.POINTER(ctypes.c_int)]
    return dll


# ------------------------------------------------------------------------------------------
# the function under search, run by both sides


class Fail(Exception):
    """f failed (the C callback returns the code)."""

    def __init__(self, code: int):
        super().__init__(code)
        self.code = code


class Probe:
    """f(x) as a float, its calls counted; failing with ``code`` at call ``fail_at``; a Python
    arithmetic error inside f (math.exp overflow, ...) fails with code 5."""

    def __init__(self, f, fail_at: int | None = None, code: int = 7):
        self.f, self.fail_at, self.code = f, fail_at, code
        self.bug = None
        self.cb = CALLBACK(self._callback)
        self.reset()

    def reset(self):
        self.n = 0
        if hasattr(self.f, "reset"):
            self.f.reset()

    def __call__(self, x):
        self.n += 1
        if self.n == self.fail_at:
            raise Fail(self.code)
        try:
            return float(self.f(x))
        except ArithmeticError:
            raise Fail(5) from None

    def _callback(self, x, ctx, out):
        try:
            out[0] = self(x)
        except Fail as e:
            return e.code
        except BaseException as e:                 # a bug of the test: reported, not hidden
            self.bug = e
            return 99
        return 0


def value_error_code(e: ValueError) -> int:
    msg = str(e)
    if "different signs" in msg:
        return BR_SIGN
    if "is NaN" in msg:
        return BR_NAN
    if "too small" in msg or "must be >= 0" in msg:
        return BR_ARGS
    raise e


def scipy_outcome(p: Probe, a, b, xtol, rtol, maxiter):
    """Oracle: scipy.optimize.brentq (full_output only adds the flag: the same C path)."""
    p.reset()
    try:
        x, r = brentq(p, a, b, xtol=xtol, rtol=rtol, maxiter=maxiter, disp=False,
                      full_output=True)
    except ValueError as e:
        return ("err", value_error_code(e), p.n), None
    except Fail as e:
        return ("err", e.code, p.n), None
    assert r.function_calls == p.n
    return ("ok", fb(x), p.n), r.converged


def c_brentq(lib, p: Probe, a, b, xtol, rtol, maxiter):
    p.reset()
    root, calls = ctypes.c_double(12345.0), ctypes.c_int(-1)
    rc = lib.t_brentq(p.cb, a, b, xtol, rtol, maxiter, ctypes.byref(root), ctypes.byref(calls))
    if p.bug is not None:
        raise p.bug
    assert calls.value == p.n                      # *calls: the calls of f made
    return ("ok", fb(root.value), calls.value) if rc == 0 else ("err", rc, calls.value)


def python_solve(p: Probe, u0, tol, max_iter, bounds):
    """Oracle: the Python solve_control."""
    p.reset()
    try:
        u, fu, n = solve_control(p, u0, tol, max_iter, bounds)
    except ValueError as e:
        return ("err", value_error_code(e), p.n)
    except ZeroDivisionError:
        return ("err", BR_ZERODIV, p.n)
    except Fail as e:
        return ("err", e.code, p.n)
    assert n == p.n                                 # evaluations: the calls of miss
    return ("ok", fb(u), fb(fu), n)


def c_solve(lib, p: Probe, u0, tol, max_iter, bounds):
    p.reset()
    u, fu, n = ctypes.c_double(12345.0), ctypes.c_double(12345.0), ctypes.c_int(-1)
    rc = lib.t_solve_control(p.cb, u0, tol, max_iter, bounds[0], bounds[1], ctypes.byref(u),
                             ctypes.byref(fu), ctypes.byref(n))
    if p.bug is not None:
        raise p.bug
    assert n.value == p.n
    return ("ok", fb(u.value), fb(fu.value), n.value) if rc == 0 else ("err", rc, n.value)


def check_brentq(lib, f, a, b, xtol, rtol, maxiter, fail_at=None, code=7):
    """C == SciPy on one case; returns SciPy's outcome and its converged flag."""
    p = Probe(f, fail_at, code)
    want, converged = scipy_outcome(p, a, b, xtol, rtol, maxiter)
    got = c_brentq(lib, p, a, b, xtol, rtol, maxiter)
    assert got == want, (a, b, xtol, rtol, maxiter, fail_at)
    return want, converged


def check_solve(lib, f, u0, tol, max_iter, bounds=U_BOUNDS, fail_at=None, code=7):
    """C == the Python solve_control on one case; returns the outcome."""
    p = Probe(f, fail_at, code)
    want = python_solve(p, u0, tol, max_iter, bounds)
    got = c_solve(lib, p, u0, tol, max_iter, bounds)
    assert got == want, (u0, tol, max_iter, bounds, fail_at)
    return want


# ------------------------------------------------------------------------------------------
# seeded random functions


class Replay:
    """f's values from a list, in call order, whatever x (restarted with each run)."""

    def __init__(self, values):
        self.values = values
        self.i = 0

    def reset(self):
        self.i = 0

    def __call__(self, x):
        v = self.values[self.i % len(self.values)]
        self.i += 1
        return v


def poly(roots, c):
    def f(x):
        y = c
        for r in roots:
            y *= x - r
        return y
    return f


def random_function(rng: random.Random):
    """(family, f, natural bracket): monotone and non-monotone shapes."""
    kind = rng.choice(["poly", "poly", "exp", "tanh", "step", "jump", "sin", "double_root",
                       "flat", "kink", "rational"])
    r = rng.uniform(-2.0, 2.0)
    if kind == "poly":
        roots = [rng.uniform(-3.0, 3.0) for _ in range(rng.randint(1, 5))]
        return kind, poly(roots, rng.choice([-1, 1]) * 10.0 ** rng.uniform(-3, 3)), (-3.5, 3.5)
    if kind == "exp":
        s, c = rng.choice([-1, 1]) * rng.uniform(0.1, 5.0), rng.uniform(0.1, 10.0)
        return kind, (lambda x: math.exp(s * x) - c), (-4.0, 4.0)
    if kind == "tanh":
        a, s = rng.uniform(0.5, 50.0), rng.uniform(0.1, 30.0)
        b = rng.uniform(-0.9, 0.9) * a
        return kind, (lambda x: a * math.tanh(s * (x - r)) + b), (-3.0, 3.0)
    if kind == "step":                             # no root: a sign change at r
        return kind, (lambda x: 1.0 if x > r else -1.0), (-3.0, 3.0)
    if kind == "jump":                             # a root and a jump beside it
        j = rng.uniform(0.1, 3.0)
        return kind, (lambda x: (x - r) + (j if x > r + 0.1 else 0.0)), (-3.0, 3.0)
    if kind == "sin":                              # many roots, non-monotone
        k, c, d = rng.uniform(0.5, 8.0), rng.uniform(-0.5, 0.5), rng.uniform(-0.8, 0.8)
        return kind, (lambda x: math.sin(k * x) + c * x + d), (-4.0, 4.0)
    if kind == "double_root":                      # touches zero at r, crosses at q
        q, e = rng.uniform(-2.0, 2.0), rng.choice([0.0, 1e-12, -1e-9])
        return kind, (lambda x: (x - r) * (x - r) * (x - q) + e), (-3.0, 3.0)
    if kind == "flat":                             # zero on [r - w, r + w]
        w = rng.uniform(0.0, 1.0)
        return kind, (lambda x: max(x - r - w, 0.0) + min(x - r + w, 0.0)), (-3.0, 3.0)
    if kind == "kink":                             # very different slopes on both sides
        s = 10.0 ** rng.uniform(-6, 6)
        return kind, (lambda x: (x - r) * (s if x > r else 1.0)), (-3.0, 3.0)
    # rational: a pole outside [-3, 3], steep near it
    p = rng.choice([-1, 1]) * rng.uniform(3.01, 4.0)
    return kind, (lambda x: 1.0 / (x - p) - 1.0 / (r - p)), (-3.0, 3.0)


XTOLS = [2e-12, 2e-12, 1e-8, 1e-4, 0.1, 5e-324, 1e-300, 1e-15]
RTOLS = [RTOL, RTOL, RTOL, 1e-10, 1e-3, 0.1]
MAXITERS = [100, 100, 100, 50, 10, 5, 3, 2, 1, 0]


def random_bracket(rng, lo, hi):
    a, b = rng.uniform(lo, hi), rng.uniform(lo, hi)
    return (a, b) if rng.random() < 0.5 else (b, a)      # either order


def sign_changing_bracket(rng, f, lo, hi):
    """A random bracket, of a sign change three times in four (when one is found soon)."""
    a, b = random_bracket(rng, lo, hi)
    if rng.random() < 0.25:
        return a, b
    for _ in range(30):
        try:
            if (f(a) < 0.0) != (f(b) < 0.0):
                break
        except ArithmeticError:
            pass
        a, b = random_bracket(rng, lo, hi)
    return a, b


def test_brentq_random_functions(lib):
    # Oracle: SciPy's brentq -- root bits and calls of f, or the same error, on 10000 seeded
    # random (function, bracket in either order, xtol, rtol, maxiter)
    rng = random.Random(20240611)
    seen = {"converged": 0, "exhausted": 0, "sign": 0, "nan": 0, "fail": 0}
    kinds = set()
    for _ in range(10000):
        kind, f, (lo, hi) = random_function(rng)
        kinds.add(kind)
        a, b = sign_changing_bracket(rng, f, lo, hi)
        want, converged = check_brentq(lib, f, a, b, rng.choice(XTOLS), rng.choice(RTOLS),
                                       rng.choice(MAXITERS))
        if want[0] == "ok":
            seen["converged" if converged else "exhausted"] += 1
        else:
            seen["sign" if want[1] == BR_SIGN else "nan" if want[1] == BR_NAN else "fail"] += 1
    assert len(kinds) == 10
    assert seen["converged"] > 3200 and seen["exhausted"] > 800 and seen["sign"] > 800, seen


def test_brentq_roots_at_the_ends_and_flat_zeros(lib):
    # Oracle: SciPy's brentq -- f(a) == 0 or f(b) == 0 returns that end after both calls (even
    # -0.0, even with the other end of the same sign); f == 0 throughout returns a
    rng = random.Random(7)
    for _ in range(200):
        a, b = random_bracket(rng, -5.0, 5.0)
        s = rng.uniform(-3.0, 3.0)
        for f in (lambda x: s * (x - a), lambda x: s * (x - b), lambda x: (x - a) * (x - b),
                  lambda x: 0.0, lambda x: -0.0, lambda x: s * (x - a) * (x - a) + 0.0 * x):
            want, _ = check_brentq(lib, f, a, b, 2e-12, RTOL, 100)
            assert want[0] == "ok" and want[2] == 2
    # a root at an end reached inside the loop (fcur == 0): a linear f and an exact secant
    for a, b in ((-1.0, 3.0), (3.0, -1.0), (0.0, 4.0), (-2.0, 2.0)):
        check_brentq(lib, lambda x: x - 1.0, a, b, 2e-12, RTOL, 100)


def test_brentq_maxiter_exhausted_and_tiny_xtol(lib):
    # Oracle: SciPy's brentq -- the current estimate after maxiter iterations (disp=False: no
    # error), for every maxiter up to convergence; xtol down to the smallest subnormal
    rng = random.Random(11)
    for _ in range(60):
        kind, f, (lo, hi) = random_function(rng)
        a, b = random_bracket(rng, lo, hi)
        xtol = rng.choice([5e-324, 1e-300, 2e-12])
        want, converged = check_brentq(lib, f, a, b, xtol, RTOL, 200)
        if want[0] != "ok":
            continue
        for maxiter in range(0, want[2] - 1):       # the iterations before the last
            check_brentq(lib, f, a, b, xtol, RTOL, maxiter)
    # roots at and near zero: the absolute tolerance is all there is
    for r in (0.0, 5e-324, -1e-310, 1e-300, 1e-20):
        for xtol in (5e-324, 1e-320, 1e-300, 2e-12):
            check_brentq(lib, lambda x: x - r, -1.0, 2.0, xtol, RTOL, 2000)
            check_brentq(lib, lambda x: math.tanh(1e3 * (r - x)), 1.0, -0.5, xtol, RTOL, 2000)
    # subnormal roots and tolerances of an odd number of units: delta = (xtol + rtol |x|) / 2
    # rounds there, (xtol / 2 + rtol |x| / 2 would not give the same steps)
    check_brentq(lib, lambda x: math.tanh(37.879381673234214 * (2.08e-322 - x)),
                 -1.2245341010238853, 2.2997001141201427, 1.5e-323, RTOL, 3000)
    tiny = 5e-324
    for _ in range(300):
        r, s = tiny * rng.randint(-50, 50), 10.0 ** rng.uniform(-3, 3)
        f = rng.choice([lambda x: s * (x - r), lambda x: math.tanh(s * (r - x)),
                        lambda x: (x - r) * (1.0 + x * x), lambda x: 1.0 if x > r else -1.0])
        a, b = random_bracket(rng, -2.0, 3.0)
        check_brentq(lib, f, a, b, tiny * rng.choice([1, 3, 5, 7, 9, 11, 101, 1001]), RTOL, 3000)


def test_brentq_same_sign_and_bad_arguments(lib):
    # Oracle: SciPy's brentq -- ValueError for f(a), f(b) of one sign bit (after both calls);
    # ValueError for xtol <= 0, rtol < 4 eps, maxiter < 0 (before any call); a NaN tolerance
    # passes SciPy's checks and runs
    f = lambda x: x * x - 1.0                      # noqa: E731
    for a, b in ((-0.5, 0.5), (2.0, 3.0), (-3.0, -2.0), (3.0, 2.0)):
        assert check_brentq(lib, f, a, b, 2e-12, RTOL, 100)[0] == ("err", BR_SIGN, 2)
    # the sign bits: 1e-320 and -1e-320 are of opposite signs
    assert check_brentq(lib, lambda x: x, -1e-320, 1e-320, 5e-324, RTOL, 100)[0][0] == "ok"
    below = RTOL * (1.0 - EPS / 2)                 # the double just below 4 eps
    for xtol, rtol, maxiter in ((0.0, RTOL, 100), (-0.0, RTOL, 100), (-1e-3, RTOL, 100),
                                (-INF, RTOL, 100), (1e-3, below, 100), (1e-3, 0.0, 100),
                                (1e-3, -1.0, 100), (1e-3, RTOL, -1), (0.0, 0.0, -5)):
        assert check_brentq(lib, f, 0.0, 3.0, xtol, rtol, maxiter)[0] == ("err", BR_ARGS, 0)
    assert check_brentq(lib, f, 0.0, 3.0, 1e-3, RTOL, 0)[0][0] == "ok"
    # NaN and infinite tolerances and ends: whatever SciPy does (a NaN step, a NaN f raising)
    for xtol, rtol in ((NAN, RTOL), (1e-3, NAN), (INF, RTOL), (1e-3, INF)):
        for g in (f, lambda x: 1.0 if x > 1.0 else -1.0, math.atan):
            check_brentq(lib, g, 0.0, 3.0, xtol, rtol, 30)
            check_brentq(lib, g, -2.0, 3.0, xtol, rtol, 30)
    # a bracket of -0.0 and +0.0 (f tells them apart): sbis = -0.0, a NaN step of its sign
    for xtol in (NAN, 5e-324, 1e-3):
        for a, b in ((-0.0, 0.0), (0.0, -0.0)):
            check_brentq(lib, lambda x: math.copysign(1.0, x), a, b, xtol, RTOL, 3)
    for a, b in ((-INF, 3.0), (0.0, INF), (-INF, INF), (NAN, 3.0), (0.0, NAN)):
        for g in (math.atan, lambda x: 1.0 if x > 1.0 else -1.0, lambda x: x - 1.0):
            check_brentq(lib, g, a, b, 2e-12, RTOL, 60)


def test_brentq_nan_values_and_failing_callback(lib):
    # Oracle: SciPy's brentq -- a NaN value of f raises ValueError at that call (counted); a
    # failure of f (Python raises) ends the search at that call: the same code, the same count
    assert check_brentq(lib, lambda x: NAN, 0.0, 1.0, 2e-12, RTOL, 100)[0] == ("err", BR_NAN, 1)
    nan_above = lambda x: NAN if x > 0.7 else x - 0.5      # noqa: E731
    assert check_brentq(lib, nan_above, 0.0, 1.0, 2e-12, RTOL, 100)[0] == ("err", BR_NAN, 2)
    nan_inside = lambda x: NAN if 0.3 < x < 0.45 else x - 0.4  # noqa: E731
    assert check_brentq(lib, nan_inside, 0.0, 1.0, 2e-12, RTOL, 100)[0][1] == BR_NAN
    rng = random.Random(3)
    for _ in range(150):
        kind, f, (lo, hi) = random_function(rng)
        a, b = random_bracket(rng, lo, hi)
        want, _ = check_brentq(lib, f, a, b, 1e-10, RTOL, 100)
        for k in range(1, want[2] + 1):
            code = rng.choice([1, 3, 17, -5, 1000])
            assert check_brentq(lib, f, a, b, 1e-10, RTOL, 100, fail_at=k,
                                code=code)[0] == ("err", code, k)


# ------------------------------------------------------------------------------------------
# solve_control


def random_miss(rng: random.Random):
    """A miss in metres of u (decreasing, or not), root r (inside U_BOUNDS or not)."""
    r = rng.uniform(-0.25, 0.25)
    k = 10.0 ** rng.uniform(2, 6)
    kind = rng.choice(["linear", "cubic", "tanh", "exp", "wavy", "step"])
    if kind == "linear":
        return lambda u: k * (r - u)
    if kind == "cubic":
        c = rng.uniform(0.0, 50.0)
        return lambda u: k * ((r - u) + c * (r - u) * (r - u) * (r - u))
    if kind == "tanh":
        s = rng.uniform(1.0, 100.0)
        return lambda u: k * math.tanh(s * (r - u))
    if kind == "exp":
        s = rng.uniform(0.5, 20.0)
        return lambda u: k * (math.exp(-s * u) - math.exp(-s * r))
    if kind == "wavy":                             # non-monotone
        w = rng.uniform(10.0, 80.0)
        return lambda u: k * ((r - u) + 0.02 * math.sin(w * u))
    return lambda u: k * (1.0 if u < r else -1.0)


def test_solve_control_random_misses(lib):
    # Oracle: the Python solve_control -- (u, miss(u), evaluations) bitwise, or the same error
    # with the same calls of miss, on 10000 seeded random misses, guesses, tolerances, bounds
    rng = random.Random(99)
    seen = {"guess": 0, "bound": 0, "brent": 0, "err": 0}
    for _ in range(10000):
        miss = random_miss(rng)
        u0 = rng.choice([0.0, rng.uniform(-0.25, 0.25), rng.uniform(-0.2, 0.2)])
        tol = rng.choice([20.0, 1.0, 1e-3, 1e-9, 10.0 ** rng.uniform(-6, 4)])
        max_iter = rng.choice([20, 20, 50, 5, 2, 1, 0])
        bounds = rng.choice([U_BOUNDS, U_BOUNDS, (-0.5, 0.1), (0.05, 0.3), (0.2, -0.2)])
        want = check_solve(lib, miss, u0, tol, max_iter, bounds)
        if want[0] == "err":
            seen["err"] += 1
        else:
            seen["guess" if want[3] == 1 else "bound" if want[3] == 2 else "brent"] += 1
    assert seen["brent"] > 4000 and seen["bound"] > 800 and seen["guess"] > 80, seen


def test_solve_control_edges(lib):
    # Oracle: the Python solve_control -- the guess clipped as min(max(u0, lo), hi) (a NaN
    # guess stays NaN, -0.0 stays -0.0), tolerances 0, negative, NaN, infinite (ValueError of
    # brentq), the slope's ZeroDivisionError, NaN misses (brentq's ValueError only inside it)
    lin = lambda u: 1e5 * (0.05 - u)               # noqa: E731
    for u0 in (NAN, -0.0, 0.0, 0.2, -0.2, 0.7, -0.7, INF, -INF, 5e-324):
        for tol in (1.0, 0.0, -1.0, NAN, INF, 1e-300):
            for max_iter in (20, 0, -1):
                for bounds in (U_BOUNDS, (0.2, -0.2), (0.0, 0.0), (-INF, INF), (NAN, 0.2)):
                    check_solve(lib, lin, u0, tol, max_iter, bounds)
    # max_iter < 0 reaches brentq only when the guess and the bound bracket the root
    assert check_solve(lib, lin, 0.0, 1.0, -1)[:2] == ("err", BR_ARGS)
    assert check_solve(lib, lin, 0.0, 0.0, 20)[:2] == ("err", BR_ARGS)
    # ZeroDivisionError: end == u0 (-0.0 clipped at lo = +0.0) and slope == 0 (infinite bound)
    sign = lambda u: math.copysign(1.0, u)         # noqa: E731
    assert check_solve(lib, sign, -0.0, 0.5, 20, (0.0, 1.0)) == ("err", BR_ZERODIV, 2)
    assert check_solve(lib, lambda u: -math.tanh(u), -1.0, 0.1, 20,
                       (-INF, INF)) == ("err", BR_ZERODIV, 2)
    # an infinite slope (fe - f0 overflows): xtol = 0, brentq's ValueError
    huge = lambda u: -1.7e308 if u > 0.0 else 1.7e308      # noqa: E731
    assert check_solve(lib, huge, -0.1, 1.0, 20) == ("err", BR_ARGS, 2)
    # NaN misses: at the guess (then the bound; inside brentq it raises), at the bound, inside
    for miss in (lambda u: NAN, lambda u: NAN if u == -0.2 else lin(u),
                 lambda u: NAN if u == 0.2 else -lin(u), lambda u: NAN if u == 0.1 else lin(u),
                 lambda u: NAN if 0.03 < u < 0.06 else lin(u)):
        for u0 in (0.1, 0.0, -0.2, 0.2):
            check_solve(lib, miss, u0, 1.0, 20)
    # a miss that changes between calls (a stateful model): the same values on both sides
    for seq in ([5.0, -5.0, 5.0, -5.0], [5.0, -5.0, 5.0, 5.0], [5.0, -5.0, -5.0, 5.0, 2.0],
                [-3.0, 4.0, 0.0, 1.0], [5.0, 5.0], [0.5], [5.0, -5.0, NAN]):
        for u0 in (0.0, 0.2, -0.2):
            check_solve(lib, Replay(seq), u0, 1.0, 20)


def test_solve_control_failing_miss(lib):
    # Oracle: the Python solve_control -- a miss that raises at its k-th call, for every k up to
    # the calls it makes: the same code, evaluations counting the failed call
    rng = random.Random(5)
    for _ in range(200):
        miss = random_miss(rng)
        u0, tol = rng.uniform(-0.2, 0.2), rng.choice([1.0, 1e-3])
        want = check_solve(lib, miss, u0, tol, 20)
        n = want[3] if want[0] == "ok" else want[2]
        for k in range(1, n + 1):
            code = rng.choice([1, 2, 42, -7])
            assert check_solve(lib, miss, u0, tol, 20, fail_at=k, code=code) == ("err", code, k)


def test_header_constants(lib):
    # Oracle: SciPy's smallest rtol, 4 * np.finfo(float).eps; the codes documented here
    import numpy as np
    codes, rtol = (ctypes.c_int * 4)(), ctypes.c_double()
    lib.t_constants(codes, ctypes.byref(rtol))
    assert list(codes) == [BR_SIGN, BR_ARGS, BR_NAN, BR_ZERODIV]
    assert rtol.value == RTOL == 4 * np.finfo(float).eps


# ------------------------------------------------------------------------------------------
# properties (Hypothesis)

try:
    from hypothesis import given, settings, strategies as st
except ImportError:                                    # optional: the test extra installs it
    given = None

if given is None:
    def test_properties_need_hypothesis():
        pytest.skip("hypothesis is not installed")
else:
    finite = st.floats(-1e6, 1e6, allow_nan=False)
    anything = st.floats()                             # NaN and infinities included

    @settings(max_examples=500, deadline=None)
    @given(coef=st.lists(st.floats(-100.0, 100.0), min_size=1, max_size=5), a=finite, b=finite,
           xtol=st.one_of(st.sampled_from([2e-12, 5e-324, 1e-300]), st.floats(0.0, 10.0),
                          anything),
           rtol=st.one_of(st.just(RTOL), st.floats(0.0, 1.0), anything),
           maxiter=st.integers(-2, 120))
    def test_brentq_property(lib, coef, a, b, xtol, rtol, maxiter):
        # Oracle: SciPy's brentq -- any polynomial (Horner), any bracket and tolerances, NaN too
        def f(x):
            y = 0.0
            for c in coef:
                y = y * x + c
            return y
        check_brentq(lib, f, a, b, xtol, rtol, maxiter)

    @settings(max_examples=500, deadline=None)
    @given(r=st.floats(-1.0, 1.0), k=st.floats(1e-3, 1e7), c=st.floats(-10.0, 100.0),
           u0=st.one_of(st.floats(-1.0, 1.0), anything),
           tol=st.one_of(st.floats(1e-9, 1e3), anything), max_iter=st.integers(-1, 40),
           bounds=st.one_of(st.just(U_BOUNDS),
                            st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0))))
    def test_solve_control_property(lib, r, k, c, u0, tol, max_iter, bounds):
        # Oracle: the Python solve_control -- cubic misses around a root r, any guess, tolerance
        # and bounds (NaN, infinities, reversed bounds included)
        check_solve(lib, lambda u: k * ((r - u) + c * (r - u) * (r - u) * (r - u)), u0, tol,
                    max_iter, bounds)
