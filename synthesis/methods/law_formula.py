"""Readable network-operator laws: the matrix as a SymPy expression, folded, simplified, CSE'd.

A law found by the GA is a graph full of constant sub-expressions (``sig2(3.82373)``,
``inv(2.27075)``) and of repeated branches; printed as the network operator stores it, it is a
nest of a thousand characters.  :func:`readable` turns the graph into SymPy expressions:

* every operation of the one operation table (:mod:`models.controllers.operation_table`) that
  is plain algebra or a SymPy function enters through its ``sym`` form (so ``z**2``, ``tanh(z/2)``,
  ``+`` and ``*`` simplify), every other one as a named function (``inv``, ``sgn``,
  ``heaviside``, ``max``, ...);
* constant folding: a named function of a number evaluates to the number the guarded Python
  operation gives (exactly the law's value), SymPy folds the rest;
* simplification: SymPy's canonical forms (like terms and powers collected), then
  :func:`sympy.factor_terms`, kept only when it shortens the expression;
* common sub-expressions (:func:`sympy.cse`) become ``t1 = ...`` lines shared by the outputs.

The readable form is the law where no node value reaches the network operator's clamp
(|z| < 1e8): the clamps after every operation are not written.  Printed to ``digits``
significant digits for reading (``text``, ``latex``) and to full precision (``exact``, which
re-evaluates to the law).

Named functions (text names; ``sgn(0) = 1``): ``inv`` 1/z (|z| > 1e-7), ``exp`` e^z capped at
1e8, ``lnabs`` ln|z| (|z| > 1e-8), ``ssqrt`` sgn(z) sqrt|z|, ``heaviside`` [z >= 0], ``cbrt``
real cube root, ``clip1`` clip to [-1, 1], ``wrap`` the angle wrapped to (-pi, pi],
``max``/``min``/``norm``/``sabs``/``smax``/``atan2``/``hypot`` the binary operations 3, 4, 6-10
(``atan2(y, x)``: named rather than SymPy's, whose numbers fold into exact expressions of pi);
the table's ``expr`` of each is its definition (:func:`legend`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

from descent_fmus.models.controllers.operation_table import (BINARY_OPS, UNARY_OPS, finite,
                                                             python_function)

__all__ = ["Readable", "readable", "readable_cached", "sympy_functions", "legend"]


@lru_cache(maxsize=None)
def sympy_functions() -> dict:
    """``{name: SymPy function class}`` of the named (non-algebraic) operations."""
    import sympy

    out = {}

    def make(op, binary):
        fn = python_function(op, binary)
        n = 2 if binary else 1
        latex = op.latex or (r"\operatorname{%s}\left(#\right)" % op.name)

        def eval_(cls, *args):
            if all(a.is_Number and a.is_real for a in args):   # constant folding, exactly
                return sympy.Float(fn(*(float(a) for a in args)))
            if binary and op.unit == 0.0 and args[0] == 0:     # the unit: chi(0, b) = first(b)
                return _first(op)(args[1])
            if op.name in _EVEN and any(isinstance(a, sympy.Abs) for a in args):
                return cls(*(a.args[0] if isinstance(a, sympy.Abs) else a for a in args))
            return None

        def _latex(self, printer, exp=None):
            text = latex.replace("#", ", ".join(printer._print(a) for a in self.args))
            return f"\\left({text}\\right)^{{{exp}}}" if exp else text

        return type(op.name, (sympy.Function,), {"nargs": n, "eval": classmethod(eval_),
                                                 "_latex": _latex})

    for op in UNARY_OPS[1:]:
        if not op.sym:
            out[op.name] = make(op, False)
    for op in BINARY_OPS[1:]:
        if not op.sym:
            out[op.name] = make(op, True)
    return out


#: named binary operations that depend on their operands' magnitudes only: hypot(|a|, b) =
#: hypot(a, b) (a node's first arc gives hypot(0, b) = |b|)
_EVEN = ("hypot",)


@lru_cache(maxsize=None)
def _first(op):
    """The node's value after its first arc as a function of the arc's SymPy expression."""
    import sympy
    if op.first == "b":
        return lambda e: e
    b = sympy.Symbol("b")
    f = sympy.sympify(op.first, locals={"b": b})
    return lambda e: f.xreplace({b: e})


def legend() -> dict:
    """``{name: guarded definition}`` of the named functions readable laws may contain."""
    return {op.name: op.expr for op in list(UNARY_OPS[1:]) + list(BINARY_OPS[1:])
            if not op.sym}


@lru_cache(maxsize=None)
def _sym_ops():
    import sympy
    z, a, b = sympy.symbols("z a b")
    funcs = sympy_functions()
    unary = [None]
    for op in UNARY_OPS[1:]:
        if op.sym:
            e = sympy.sympify(op.sym, locals={"z": z})
            unary.append(lambda arg, e=e: e.xreplace({z: arg}))
        else:
            unary.append(funcs[op.name])
    binary = [None]
    for op in BINARY_OPS[1:]:
        if op.sym:
            e = sympy.sympify(op.sym, locals={"a": a, "b": b})
            binary.append(lambda x, y, e=e: e.xreplace({a: x, b: y}))
        else:
            binary.append(funcs[op.name])
    return unary, binary


@dataclass
class Readable:
    """A law in readable form.

    Attributes
    ----------
    outputs : list
        SymPy expressions of the raw outputs (before the output bounds), simplified.
    replacements : list of (Symbol, expr)
        Common sub-expressions ``t1 = ...`` used in ``reduced``.
    reduced : list
        The outputs in terms of the ``t`` symbols.
    symbols : list
        The input symbols (the law's input names).
    bounds : list of (float, float)
    text, latex, exact : str
        The law to ``digits`` significant digits as text and LaTeX, and to full precision.
    """

    outputs: list
    replacements: list
    reduced: list
    symbols: list
    bounds: list
    text: str = ""
    latex: str = ""
    exact: str = ""
    functions: dict = field(default_factory=dict)
    _numeric: object = field(default=None, repr=False, compare=False)

    def _lines(self, printer, name, clip) -> list:
        import sympy
        out = [f"{printer.doprint(s)} = {printer.doprint(e)}" for s, e in self.replacements]
        n = len(self.reduced)
        for k, (e, (lo, hi)) in enumerate(zip(self.reduced, self.bounds)):
            args = (printer.doprint(e), printer.doprint(sympy.Float(lo)),
                    printer.doprint(sympy.Float(hi)))
            out.append(f"{name(k, n)} = {clip(*args)}")
        return out

    def lines(self, digits: int | None = 6) -> list:
        """``t1 = ...``, ..., ``u = clip(..., lo, hi)`` as text (``digits`` significant digits,
        None: full precision)."""
        from sympy.printing.str import StrPrinter

        class Printer(StrPrinter):
            def _print_Float(self, expr):
                v = float(expr)
                return repr(v) if digits is None else f"{v:.{digits}g}"

        return self._lines(Printer({"order": "none"}),
                           lambda k, n: "u" if n == 1 else f"u{k + 1}",
                           lambda e, lo, hi: f"clip({e}, {lo}, {hi})")

    def latex_lines(self, digits: int = 6) -> list:
        """The same lines in LaTeX."""
        from sympy.printing.latex import LatexPrinter

        class Printer(LatexPrinter):
            def _print_Float(self, expr):
                text = f"{float(expr):.{digits}g}"
                if "e" in text:
                    m, e = text.split("e")
                    return f"{m} \\cdot 10^{{{int(e)}}}"
                return text

        return self._lines(Printer({"order": "none"}),
                           lambda k, n: "u" if n == 1 else f"u_{{{k + 1}}}",
                           lambda e, lo, hi: f"\\operatorname{{clip}}\\left({e}, {lo}, "
                                             f"{hi}\\right)")

    def to_dict(self) -> dict:
        return {"text": self.text, "latex": self.latex, "exact": self.exact,
                "functions": self.functions}

    def evaluate(self, x) -> list:
        """The raw outputs at inputs ``x`` (floats), through the simplified expressions (in
        floating point; the named functions are the guarded Python operations)."""
        if self._numeric is None:
            import sympy
            self._numeric = sympy.lambdify(self.symbols, self.outputs,
                                           modules=[_numeric_functions(), "math"])
        return [float(v) for v in self._numeric(*x)]


@lru_cache(maxsize=None)
def _numeric_functions() -> dict:
    import math
    funcs = {op.name: python_function(op) for op in UNARY_OPS[1:] if not op.sym}
    funcs.update({op.name: python_function(op, True) for op in BINARY_OPS[1:] if not op.sym})
    funcs.update({"tanh": math.tanh, "exp": funcs["exp"]})
    return funcs


def _shorter(a, b):
    from sympy import count_ops
    return b if count_ops(b) < count_ops(a) else a


def readable(law, digits: int = 6) -> Readable:
    """The readable form of a :class:`~synthesis.methods.law.NetworkOperator`."""
    import sympy

    unary, binary = _sym_ops()
    psi = law.psi
    L, nx, nq = law.size, law.nx, len(law.q)
    ns = nx + nq
    symbols = [sympy.Symbol(name) for name in law.input_names]
    z = [None] * L
    for k in range(nx):
        s, o = law.input_scale[k], law.input_offset[k]
        z[k] = sympy.Float(s) * (symbols[k] - sympy.Float(o)) if (s, o) != (1.0, 0.0) \
            else symbols[k]
    for k in range(nq):
        z[nx + k] = sympy.Float(law.q[k])
    for j in range(ns, L):
        b = int(psi[j, j])
        terms = [unary[int(psi[i, j])](z[i]) for i in range(j) if psi[i, j]] if b else []
        if not terms:
            z[j] = sympy.Float(finite(BINARY_OPS[b].unit)) if b else sympy.Float(0.0)
            continue
        acc = _first(BINARY_OPS[b])(terms[0])   # chi(unit, r): r for all but hypot (|r|)
        for t in terms[1:]:
            acc = binary[b](acc, t)
        z[j] = acc
    outputs = []
    for o in law.outputs:
        e = z[o - 1]
        outputs.append(_shorter(e, sympy.factor_terms(e)))
    replacements, reduced = sympy.cse(outputs, symbols=sympy.numbered_symbols("t", start=1),
                                      order="none")
    r = Readable(outputs, replacements, reduced, symbols, list(law.bounds),
                 functions={k: v for k, v in legend().items()
                            if any(e.atoms(sympy_functions()[k]) for e in outputs)})
    r.text = "; ".join(r.lines(digits))
    r.exact = "; ".join(r.lines(None))
    r.latex = r" \\ ".join(r.latex_lines(digits))
    return r


_CACHE: dict = {}


def readable_cached(law, digits: int = 6) -> Readable:
    """:func:`readable`, computed once per law content and digits (a run prints each Pareto law
    in pareto.csv, law.json and the C files)."""
    key = (law.psi.tobytes(), law.psi.shape, tuple(law.q), tuple(law.outputs),
           tuple(map(tuple, law.bounds)), tuple(law.input_names), tuple(law.input_scale),
           tuple(law.input_offset), digits)
    if key not in _CACHE:
        if len(_CACHE) > 4096:
            _CACHE.clear()
        _CACHE[key] = readable(law, digits)
    return _CACHE[key]
