"""The network operator's operations: one table of guarded expressions, compiled to Python here.

Every unary operation ``rho_k`` and binary operation ``chi_k`` of the network operator is one
:class:`Operation`, whose expression in a small operation language is compiled once into the
Python functions :data:`UNARY` and :data:`BINARY` (and rendered to C by the native builders of
``synthesis/fmi/native/builders/ccode.py``: the same IEEE operations in the same order).

Every operation is overflow-safe: values are clamped to ``[-BIG, BIG]`` (BIG = 1e8, the authors'
"infinity") after every operation (:func:`finite`), and a NaN becomes 0, so a law never returns
NaN or inf.  :func:`operation_numbers` reads operations given by number or name.

The matrix interpreter that applies them is :mod:`models.controllers.law_interpreter`; the
controller FMU is :mod:`models.controllers.network_operator`.

References
----------
A.I. Diveev, E.Yu. Shmalko (reentry paper), section "Синтез"; A.I. Diveev, E.A. Sofronova, "The network operator
method in control problems", Vestnik RUDN, 2007, no. 4.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["BIG", "UNARY", "BINARY", "UNIT", "UNARY_NAMES", "BINARY_NAMES", "Operation",
           "UNARY_OPS", "BINARY_OPS", "CONSTANTS", "HELPERS", "FUNCTIONS", "python_function",
           "finite", "operation_numbers", "OperationNameError"]

#: The authors' "infinity": every node value is clamped to [-BIG, BIG].
BIG = 1e8
_EPS5 = 1e-7     # epsilon of rho5 (Diveev & Shmalko)
_EPS = 1e-8      # epsilon of the wider operation set
_LN_BIG = math.log(BIG)


# -- the operations: one table, rendered to Python here and to C by synthesis.fmi.native --------
#
# Every operation is ONE expression in a small language -- Python's expression syntax limited
# to the operand names (z; a, b), float literals, the named constants of CONSTANTS, + - * /,
# comparisons, ``x if c else y`` and the functions of FUNCTIONS -- so that the Python
# functions below and the C code of a native law FMU are the same IEEE operations in the same
# order: the two give bitwise equal results (both call the platform's C math library).

#: Named constants of the operation language (values as Python computes them).
CONSTANTS = {"BIG": BIG, "EPS5": _EPS5, "EPS": _EPS, "LN_BIG": _LN_BIG,
             "LOG_EPS": math.log(_EPS), "PI": math.pi, "TWO_PI": 2.0 * math.pi}
#: Helper functions of the operation language, themselves expressions: name -> (operands,
#: expr).  ``finite`` is the clamp after every operation (written inline in
#: :func:`models.controllers.law_interpreter.evaluate`),
#: ``clip`` the output bounds, ``scale`` the input scaling.
HELPERS = {
    "sgn": ("z", "1.0 if z >= 0.0 else -1.0"),           # the authors' sign: 1 for z >= 0
    "gexp": ("z", "BIG if z > LN_BIG else exp(z)"),       # e^z, guarded
    "finite": ("v", "BIG if v > BIG else (-BIG if v < -BIG else (v if v == v else 0.0))"),
    "clip": ("v, lo, hi", "lo if v < lo else (hi if v > hi else v)"),
    "scale": ("v, s, o", "s * (v - o)"),
}
#: Functions of the C math library the language may call (Python: ``math`` and ``abs``/``max``;
#: ``max(x, y)`` is Python's builtin: y if y > x else x).  Each gives the same double in Python
#: and C: ``math.atan2`` is libm's atan2 (CPython answers y = 0 and infinities itself, as C99
#: Annex F does), ``math.remainder`` is CPython's own but IEEE's remainder is exact.  Not
#: ``math.hypot``: CPython's differs from libm's (hypot is written with ``sqrt``).
FUNCTIONS = ("abs", "max", "sqrt", "exp", "log", "tanh", "cos", "sin", "atan", "cbrt", "atan2",
             "remainder")


@dataclass(frozen=True)
class Operation:
    """One operation of the network operator.

    Attributes
    ----------
    number : int
        Its number in the matrix (the reentry paper's numbering, then the wider set).
    name : str
        Short name (readable formulas, C function names).
    expr : str
        The guarded operation in the operation language: operand ``z`` (unary) or ``a, b``
        (binary: ``a`` the node's value so far, ``b`` the arc's).
    text : str
        Template of :meth:`NetworkOperator.formula` (unary: ``{}`` is the operand).
    unit : float or None
        Binary operations: the node's initial value (the unit element).
    sym : str
        The operation without its guards in SymPy's syntax (operands as in ``expr``) when it is
        plain algebra or a SymPy function (readable formulas simplify through it); empty: the
        operation stays a named function ``name(...)`` in readable formulas.
    latex : str
        LaTeX of a named function, ``#`` standing for the operand (default
        ``\\operatorname{name}(#)``).
    first : str
        Binary operations: the node's value after its first incoming arc ``b`` (the fold from
        the unit, ``chi(unit, b)``, without guards) in SymPy's syntax: ``b`` for all but hypot.
    """

    number: int
    name: str
    expr: str
    text: str = ""
    unit: float | None = None
    sym: str = ""
    latex: str = ""
    first: str = "b"


_UNARY_OPS = (
    Operation(1, "id", "z", "{}", sym="z"),
    Operation(2, "sq", "z * z", "({})^2", sym="z**2"),
    Operation(3, "neg", "-z", "-({})", sym="-z"),
    Operation(4, "ssqrt", "sgn(z) * sqrt(abs(z))", "sqrt~({})"),
    Operation(5, "inv", "1.0 / z if abs(z) > EPS5 else sgn(z) / EPS5", "inv({})"),
    Operation(6, "exp", "gexp(z)", "exp({})", latex=r"e^{#}"),
    Operation(7, "lnabs", "log(abs(z)) if abs(z) > EPS else LOG_EPS", "ln|{}|",
              latex=r"\ln\left|#\right|"),
    Operation(8, "sig2", "tanh(0.5 * z)", "sig2({})", sym="tanh(z/2)"),  # (1-e^-z)/(1+e^-z)
    Operation(9, "heaviside", "1.0 if z >= 0.0 else 0.0", "heaviside({})",
              latex=r"\theta\left(#\right)"),
    Operation(10, "sgn", "sgn(z)", "sgn({})", latex=r"\operatorname{sgn}\left(#\right)"),
    Operation(11, "cos", "cos(z)", "cos({})", sym="cos(z)"),
    Operation(12, "sin", "sin(z)", "sin({})", sym="sin(z)"),
    Operation(13, "atan", "atan(z)", "atan({})", sym="atan(z)"),
    Operation(14, "cube", "z * z * z", "({})^3", sym="z**3"),
    Operation(15, "cbrt", "cbrt(z)", "cbrt({})", latex=r"\sqrt[3]{#}"),
    Operation(16, "clip1", "1.0 if z > 1.0 else (-1.0 if z < -1.0 else z)", "clip1({})"),
    Operation(17, "sgnlog", "sgn(z) * log(abs(z) + 1.0)", "sgnlog({})"),
    Operation(18, "sgnexp1", "sgn(z) * (gexp(abs(z)) - 1.0)", "sgnexp1({})"),
    Operation(19, "sgnexpm", "sgn(z) * exp(-abs(z))", "sgnexpm({})"),
    Operation(20, "half", "0.5 * z", "({})/2", sym="z/2"),
    Operation(21, "twice", "2.0 * z", "2*({})", sym="2*z"),
    Operation(22, "sat", "sgn(z) * (1.0 - exp(-abs(z)))", "sat({})"),
    Operation(23, "cubic", "z - z * z * z", "cubic({})", sym="z - z**3"),
    Operation(24, "logistic", "0.5 * (1.0 + tanh(0.5 * z))", "logistic({})",
              sym="(1 + tanh(z/2))/2"),
    Operation(25, "pos", "1.0 if z > 0.0 else 0.0", "pos({})"),
    Operation(26, "dead", "sgn(z) if abs(z) >= 0.01 else 0.0", "dead({})"),
    Operation(27, "circ", "sgn(z) * (1.0 - sqrt(1.0 - z * z)) if abs(z) < 1.0 else sgn(z)",
              "circ({})"),
    Operation(28, "gauss", "z * (1.0 - exp(-z * z))", "gauss({})", sym="z*(1 - exp(-z**2))"),
    # the angle z wrapped to (-pi, pi]: IEEE remainder is exact, so the same double in C
    Operation(29, "wrap", "PI if remainder(z, TWO_PI) == -PI else remainder(z, TWO_PI)",
              "wrap({})", latex=r"\operatorname{wrap}\left(#\right)"),
    # the signed square z|z|: the odd counterpart of sq and the inverse of ssqrt (quadratic
    # drag, orifice flow, the double integrator's switching curve x1 + x2|x2|/2); an overflow
    # to inf is clamped as cube's is -- [choice] docs/methods/network_operator.md "ssq"
    Operation(30, "ssq", "z * abs(z)", "ssq({})", sym="z*Abs(z)"),
)
#: Binary operations (unit elements: -inf/+inf of max/min are -BIG/+BIG).
_BINARY_OPS = (
    Operation(1, "add", "a + b", "+", 0.0, sym="a + b"),
    Operation(2, "mul", "a * b", "*", 1.0, sym="a*b"),
    Operation(3, "max", "a if a >= b else b", "max", -BIG, latex=r"\max\left(#\right)"),
    Operation(4, "min", "a if a <= b else b", "min", BIG, latex=r"\min\left(#\right)"),
    Operation(5, "or", "a + b - a * b", "or", 0.0, sym="a + b - a*b"),
    Operation(6, "norm", "sgn(a + b) * sqrt(a * a + b * b)", "norm", 0.0),
    Operation(7, "sabs", "sgn(a + b) * (abs(a) + abs(b))", "sabs", 0.0),
    Operation(8, "smax", "sgn(a + b) * max(abs(a), abs(b))", "smax", 0.0),
    # [choice] atan2 has no unit: NaN (no value yet), the first arc sets the node, later arcs
    # fold a <- atan2(a, b) (docs/methods/network_operator.md)
    Operation(9, "atan2", "b if a != a else atan2(a, b)", "atan2", math.nan),
    # node values are clamped to 1e8 and arcs stay below 1e24: a*a + b*b cannot overflow
    Operation(10, "hypot", "sqrt(a * a + b * b)", "hypot", 0.0, first="Abs(b)"),
)
#: Unary operations rho_k and binary operations chi_k by number (index 0 unused).
UNARY_OPS = (None,) + _UNARY_OPS
BINARY_OPS = (None,) + _BINARY_OPS


def _python_namespace() -> dict:
    ns = {"__builtins__": {}, "abs": abs, "max": max}
    ns.update((f, getattr(math, f)) for f in FUNCTIONS if f not in ("abs", "max"))
    ns.update(CONSTANTS)
    for name, (arg, expr) in HELPERS.items():
        ns[name] = eval(f"lambda {arg}: {expr}", ns)      # noqa: S307 (the table above)
    return ns


_NS = _python_namespace()
_sgn = _NS["sgn"]
_exp = _NS["gexp"]


def python_function(op: Operation, binary: bool = False):
    """The Python function of an operation (its expression compiled once)."""
    return eval(f"lambda {'a, b' if binary else 'z'}: {op.expr}", _NS)  # noqa: S307


#: Unary operations rho_k by number (index 0 unused).
UNARY = [None] + [python_function(op) for op in _UNARY_OPS]
UNARY_NAMES = [None] + [op.text for op in _UNARY_OPS]
#: Binary operations chi_k (index 0 unused): 1 +, 2 *, 3 max, 4 min, then the wider set.
BINARY = [None] + [python_function(op, binary=True) for op in _BINARY_OPS]
BINARY_NAMES = [None] + [op.text for op in _BINARY_OPS]
#: Unit elements of the binary operations (-inf/+inf of max/min are -BIG/+BIG; atan2: NaN).
UNIT = [None] + [op.unit for op in _BINARY_OPS]
#: A value as the law holds it: NaN -> 0, clamped to [-BIG, BIG].
finite = _NS["finite"]


class OperationNameError(ValueError):
    """An operation named or numbered outside the tables."""


def operation_numbers(items, binary: bool = False) -> tuple:
    """The operation numbers of ``items`` -- numbers or names (``"atan2"``, ``"wrap"``; the
    ``name`` of :class:`Operation`) -- of the unary (or binary) table, in their order.

    Raises
    ------
    OperationNameError
        An unknown name or number (the message lists the valid ones), or an empty list.
    """
    ops = _BINARY_OPS if binary else _UNARY_OPS
    kind = "binary" if binary else "unary"
    by_name = {op.name: op.number for op in ops}
    if isinstance(items, (str, int)):
        items = [items]
    out = []
    for v in items:
        if isinstance(v, str) and v.strip().isdigit():
            v = int(v)
        if isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= len(ops):
            out.append(v)
        elif isinstance(v, str) and v.strip() in by_name:
            out.append(by_name[v.strip()])
        else:
            raise OperationNameError(f"unknown {kind} operation {v!r}; valid: "
                                     + ", ".join(f"{op.number} {op.name}" for op in ops))
    if not out:
        raise OperationNameError(f"give at least one {kind} operation")
    return tuple(out)
