"""What stands in for ``math`` (and ``float``, ``sum``) in the model modules at trace time.

:data:`TRACED_MATH` has the functions of :mod:`math` the models use; given a traced value they
record the operation (:meth:`Tracer.op`), given numbers they are :mod:`math`'s own.  Every other
attribute (``pi``, ``nan``, ``radians`` of a number, ...) is :mod:`math`'s.  :func:`patched`
swaps it in for the name ``math`` of every module of ``descent_fmus.models`` (and ``float`` for a
``float()`` that returns a traced value unchanged, ``sum`` for the summation order), plus the
interceptors of the stepping loops (:mod:`.plant_calls`), and restores them afterwards.

:data:`C_FUNCTIONS` says how each recorded operation is written in C: the C runtime
(``c/plant_runtime.h``) has a ``py_<name>`` function per math operation that computes what
CPython computes -- the C library's function (CPython calls the same one) and a flag set where
CPython raises (a domain or range error, division by zero) -- and ``py_hypot``, CPython's own
algorithm (not the C library's ``hypot``, which differs in the last bit in ~0.1 % of cases).
"""
from __future__ import annotations

import builtins
import math
import sys
import types
from contextlib import contextmanager

from descent_fmus.synthesis.fmi.native.tracer.plant_trace import (Sym, TraceError, active, evaluate,
                                                           is_sym)

__all__ = ["TRACED_MATH", "patched", "own_modules", "evaluate", "C_FUNCTIONS", "BINARY_C",
           "UNARY_MATH"]

#: math functions of one argument recorded as an operation (CPython: the C library's function,
#: an error where the result is NaN from a number or infinite from a finite number)
UNARY_MATH = ("sqrt", "exp", "log", "log1p", "sin", "cos", "tan", "asin", "acos", "atan", "tanh")
#: C form of the infix operations
BINARY_C = {"add": "+", "sub": "-", "mul": "*", "lt": "<", "le": "<=", "gt": ">", "ge": ">=",
            "eq": "==", "ne": "!="}
#: C function of the other operations (their error flag is the last argument where they have one)
C_FUNCTIONS = dict({f: f"py_{f}" for f in UNARY_MATH},
                   div="py_div", pow="py_pow", fmod="py_fmod", hypot="py_hypot", atan2="atan2",
                   fabs="fabs",
                   copysign="copysign", ceil="py_ceil", floor="py_floor", isfinite="isfinite",
                   isnan="isnan", isinf="isinf", to_double="(double)")

class _TracedMath:
    """``math`` with traced values: see the module docstring."""

    def __getattr__(self, name):
        return getattr(math, name)

    @staticmethod
    def _one(name, x):
        if is_sym(x):
            return active().op(name, x)
        return getattr(math, name)(x)


def _unary(name):
    def fn(self, x):
        return self._one(name, x)
    fn.__name__ = name
    return fn


for _name in UNARY_MATH + ("fabs", "ceil", "floor"):
    setattr(_TracedMath, _name, _unary(_name))


def _hypot(self, *args):
    if not any(is_sym(a) for a in args):
        return math.hypot(*args)
    if len(args) != 2:
        raise TraceError("math.hypot of traced values: two arguments only")
    return active().op("hypot", *args)


def _binary(name):
    def fn(self, a, b):
        if is_sym(a) or is_sym(b):
            return active().op(name, a, b)
        return getattr(math, name)(a, b)
    fn.__name__ = name
    return fn


def _predicate(name):
    def fn(self, x):
        if not is_sym(x):
            return getattr(math, name)(x)
        if name == "isfinite" and x.finite:
            return True
        if name in ("isnan", "isinf") and x.finite:
            return False
        return active().op(name, x, kind="b")
    fn.__name__ = name
    return fn


def _unsupported(name):
    def fn(self, *args):
        if any(is_sym(a) for a in args):
            raise TraceError(f"math.{name} of a traced value is not traced")
        return getattr(math, name)(*args)
    return fn


_TracedMath.hypot = _hypot
_TracedMath.atan2 = _binary("atan2")
_TracedMath.copysign = _binary("copysign")
_TracedMath.fmod = _binary("fmod")
for _name in ("isfinite", "isnan", "isinf"):
    setattr(_TracedMath, _name, _predicate(_name))
for _name in ("pow", "fsum", "prod", "dist", "remainder", "ldexp", "frexp", "modf",
              "trunc", "erf", "erfc", "gamma", "lgamma", "log2", "log10", "expm1", "sinh", "cosh",
              "asinh", "acosh", "atanh", "degrees", "radians"):
    setattr(_TracedMath, _name, _unsupported(_name))

#: the stand-in for ``math``
TRACED_MATH = _TracedMath()


def _traced_float(v=0.0):
    """``float()`` that keeps a traced double (in a traced module)."""
    if isinstance(v, Sym):
        if v.kind == "b":
            raise TraceError("float() of a traced truth value")
        return v if v.kind == "f" else active().op("to_double", v)   # an Integer variable
    return builtins.float(v)


def _traced_sum(values, start=0):
    """``sum()``: CPython 3.11 adds floats in order, from ``0 + first`` (3.12 compensates; the
    generator runs on 3.11 only, ``plant_trace.check_python``)."""
    return builtins.sum(values, start)


def own_modules(cls) -> list:
    """The modules outside the package that define the plant class ``cls`` or a base of it (a
    user's plant, ``descent-fmus build-plant``): traced as the package's models are."""
    out = []
    for c in cls.__mro__:
        m = sys.modules.get(c.__module__)
        if m is not None and m not in out and not m.__name__.startswith(
                ("descent_fmus.", "pythonfmu", "builtins")):
            out.append(m)
    return out


def _model_modules():
    return [m for name, m in sorted(sys.modules.items())
            if name.startswith("descent_fmus.models.") and m is not None]


@contextmanager
def patched(interceptors: dict | None = None, extra_modules=()):
    """Swap the traced ``math``/``float``/``sum`` (and ``interceptors``: name -> function, for
    the modules that have that name) into every loaded module of ``descent_fmus.models``."""
    names = {"math": TRACED_MATH, "float": _traced_float, "sum": _traced_sum}
    names.update(interceptors or {})
    saved, defaults = [], []
    for module in _model_modules() + list(extra_modules):
        d = module.__dict__
        for name, value in names.items():
            if name in ("float", "sum") or name in d:
                saved.append((d, name, d.get(name, _MISSING)))
                d[name] = value
        # math functions bound as default arguments (``cos=math.cos``, a fast local name)
        for fn in list(d.values()):
            if isinstance(fn, types.FunctionType) and fn.__defaults__ and \
                    any(_is_math(v) for v in fn.__defaults__):
                defaults.append((fn, fn.__defaults__))
                fn.__defaults__ = tuple(getattr(TRACED_MATH, v.__name__) if _is_math(v) else v
                                        for v in fn.__defaults__)
    try:
        yield
    finally:
        for fn, old in defaults:
            fn.__defaults__ = old
        for d, name, old in reversed(saved):
            if old is _MISSING:
                d.pop(name, None)
            else:
                d[name] = old


def _is_math(v) -> bool:
    return isinstance(v, types.BuiltinFunctionType) and getattr(math, v.__name__, None) is v


_MISSING = object()
