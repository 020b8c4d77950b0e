"""Objective expressions of problem files, parsed safely (a whitelist of Python's syntax tree).

An expression combines numbers, the arithmetic operators ``+ - * / **``, comparisons (1.0 when
true, 0.0 when false), conditionals ``a if condition else b``, the scalar functions
``abs sqrt exp log sin cos tanh`` (one argument) and ``min max`` (two or more arguments), and
the flight's signals through the reductions

* ``final(e)``, ``initial(e)`` -- the value of ``e`` at the end / start of the flight;
* ``max(e)``, ``min(e)`` -- its maximum / minimum over the communication points;
* ``integral(e)`` -- its integral over time (trapezoidal rule on the communication points);
* ``mean(e)`` -- ``integral(e)`` divided by the flight's duration;

where ``e`` is an expression of signals: plant outputs (or ``u1``, ``u2``, ... for the law's
outputs), numbers, ``tf``, ``stopped``, ``pi``, the same operators, comparisons and conditionals,
and the same functions, evaluated pointwise at every communication point (NumPy: ``min(a, b)``
and ``max(a, b)`` are ``np.minimum`` / ``np.maximum``, ``a if c else b`` is ``np.where``).
``max`` and ``min`` with ONE argument reduce it (``max(abs(x))``); with two or more they are the
larger / smaller of their arguments (``max(final(h), 0)``, or pointwise inside a reduction).
``final`` of plant outputs reads the plant's final outputs (so it needs no recording); a
reduction inside a reduction is an error.  The names ``tf`` (the time the flight ended) and
``stopped`` (1 if the stop condition ended it, else 0) and the constant ``pi`` are also known.
Nothing is ever passed to ``eval``: the tree is checked node by node when the file is read
(names, functions, argument counts), and evaluated by :meth:`Expression.evaluate` from the values
of its reductions (:meth:`Expression.reduce`, :meth:`Expression.at_point`).  A value that cannot
be computed (log of 0, a division by 0, an overflow -- at any point inside a reduction) is NaN,
which the evaluator turns into the problem's penalty; no floating-point warning is emitted.
"""
from __future__ import annotations

import ast
import functools
import math
import operator
from dataclasses import dataclass

import numpy as np

__all__ = ["Expression", "ExpressionError", "Reduction", "SIGNAL_FUNCTIONS", "SCALAR_FUNCTIONS",
           "POINTWISE_FUNCTIONS", "reduce_signal"]


class ExpressionError(ValueError):
    """An expression uses a construct or a name that is not allowed."""


#: The reductions of a signal expression over a flight.
SIGNAL_FUNCTIONS = ("final", "initial", "max", "min", "integral", "mean")
#: Functions of numbers (outside reductions): ``math``'s and Python's own.
SCALAR_FUNCTIONS = {"abs": abs, "sqrt": math.sqrt, "exp": math.exp, "log": math.log,
                    "sin": math.sin, "cos": math.cos, "tanh": math.tanh, "min": min, "max": max}
#: The same functions at every point of a flight (inside reductions).
POINTWISE_FUNCTIONS = {"abs": np.abs, "sqrt": np.sqrt, "exp": np.exp, "log": np.log,
                       "sin": np.sin, "cos": np.cos, "tanh": np.tanh,
                       "min": lambda *a: functools.reduce(np.minimum, a),
                       "max": lambda *a: functools.reduce(np.maximum, a)}
_VARIADIC = ("min", "max")
CONSTANTS = {"pi": math.pi}
SPECIAL = ("tf", "stopped")
_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}
_BINARY_NP = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply,
              ast.Div: np.divide, ast.Pow: np.power}
_COMPARE = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt,
            ast.GtE: operator.ge, ast.Eq: operator.eq, ast.NotEq: operator.ne}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}


@dataclass(frozen=True)
class Reduction:
    """One reduction of an expression: ``function(argument)``.

    Attributes
    ----------
    function : str
        One of :data:`SIGNAL_FUNCTIONS`.
    argument : str
        Its argument, as text (normalised by ``ast.unparse``).
    signals : tuple of str
        The signals the argument names, sorted.
    """

    function: str
    argument: str
    signals: tuple

    def __str__(self) -> str:
        return f"{self.function}({self.argument})"


class Expression:
    """A parsed objective expression.

    Parameters
    ----------
    source : str
        The expression text.
    signals : iterable of str
        The signal names it may use inside reductions.

    Raises
    ------
    ExpressionError
        Syntax error, a construct outside the whitelist, an unknown name or function, a wrong
        number of arguments, a signal outside a reduction, a reduction inside a reduction.

    Attributes
    ----------
    terms : tuple of Reduction
        The reductions, in the order of the text (:meth:`evaluate` takes one value for each).
    reductions : set of (str, str)
        ``(function, signal)`` for every signal named inside every reduction.
    """

    def __init__(self, source: str, signals):
        self.source = source
        self._signals = frozenset(signals)
        try:
            tree = ast.parse(source.strip(), mode="eval")
        except SyntaxError as exc:
            raise ExpressionError(f"syntax error in {source!r}: {exc.msg}") from None
        except (RecursionError, MemoryError):
            raise ExpressionError(f"expression nested too deeply ({len(source)} "
                                  f"characters)") from None
        self._terms, self._args, self._index = [], [], {}
        try:
            self._check(tree.body, None)
        except RecursionError:
            raise ExpressionError(f"expression nested too deeply ({len(source)} "
                                  f"characters)") from None
        self._tree = tree.body
        self.terms = tuple(self._terms)
        self.reductions = {(r.function, s) for r in self.terms for s in r.signals}

    def _error(self, message: str) -> ExpressionError:
        return ExpressionError(f"{message} in {self.source!r}")

    # -- checking (once, when the file is read) ------------------------------------------------
    def _check(self, node, inside) -> None:
        """Check ``node``; ``inside`` is the reduction it is the argument of (None: outside)."""
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise self._error(f"only numbers are allowed as constants, got {node.value!r}")
        elif isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            self._check(node.left, inside)
            self._check(node.right, inside)
        elif isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            self._check(node.operand, inside)
        elif isinstance(node, ast.Compare) and all(type(o) in _COMPARE for o in node.ops):
            for part in (node.left, *node.comparators):
                self._check(part, inside)
        elif isinstance(node, ast.IfExp):
            for part in (node.test, node.body, node.orelse):
                self._check(part, inside)
        elif isinstance(node, ast.Name):
            self._check_name(node.id, inside)
        elif isinstance(node, ast.Call):
            self._check_call(node, inside)
        else:
            raise self._error(f"construct not allowed in an objective: {type(node).__name__}")

    def _check_name(self, name: str, inside) -> None:
        if inside is not None and name in self._signals:    # inside a reduction signals first
            self._found.add(name)
        elif name in CONSTANTS or name in SPECIAL:
            pass
        elif name in self._signals:
            raise self._error(f"signal {name!r} must be reduced to a number: write final({name}), "
                              f"max({name}), integral({name}), ...")
        elif inside is not None:
            raise self._error(f"unknown signal {name!r} in {inside}() (known: "
                              f"{', '.join(sorted(self._signals))})")
        else:
            raise self._error(f"unknown name {name!r}")

    def _check_call(self, node: ast.Call, inside) -> None:
        if not isinstance(node.func, ast.Name) or node.keywords:
            raise self._error("only calls of the allowed functions by name, without keywords,")
        name, n = node.func.id, len(node.args)
        if name in SIGNAL_FUNCTIONS and (name not in _VARIADIC or n == 1):
            if inside is not None:
                raise self._error(f"{name}() inside {inside}(): a reduction inside a reduction; "
                                  f"reduce an expression of signals once, e.g. "
                                  f"{inside}(abs(x)), and combine reductions outside them")
            if n != 1:
                raise self._error(f"{name}() takes one argument (an expression of the flight's "
                                  f"signals), got {n}")
            self._check_reduction(node)
            return
        if name not in SCALAR_FUNCTIONS:
            raise self._error(f"unknown function {name!r}; allowed: "
                              f"{', '.join(sorted(set(SIGNAL_FUNCTIONS) | set(SCALAR_FUNCTIONS)))}")
        if name in _VARIADIC and n < 2:
            raise self._error(f"{name}() takes one argument (its {name}imum over the flight) "
                              f"or two or more (the {'larger' if name == 'max' else 'smaller'})")
        if name not in _VARIADIC and n != 1:
            raise self._error(f"{name}() takes one argument, got {n}")
        for a in node.args:
            self._check(a, inside)

    def _check_reduction(self, node: ast.Call) -> None:
        name, arg = node.func.id, node.args[0]
        self._found = set()
        self._check(arg, name)
        if not self._found:
            extra = (f"; the {'larger' if name == 'max' else 'smaller'} of numbers takes two "
                     f"or more arguments" if name in _VARIADIC else "")
            raise self._error(f"{name}() reduces an expression of the flight's signals; "
                              f"{ast.unparse(arg)!r} names none (signals: "
                              f"{', '.join(sorted(self._signals))}){extra}")
        self._index[id(node)] = len(self._terms)
        self._terms.append(Reduction(name, ast.unparse(arg), tuple(sorted(self._found))))
        self._args.append(arg)

    # -- evaluation ---------------------------------------------------------------------------------
    def evaluate(self, values, special: dict) -> float:
        """The value, given one value per reduction of :attr:`terms` (in their order) and the
        ``special`` names; NaN if it cannot be computed."""
        try:
            v = float(self._eval(self._tree, values, special))
        except (ArithmeticError, ValueError):
            return math.nan
        return v

    def _eval(self, node, values, special):
        if isinstance(node, ast.Constant):
            return float(node.value)        # float arithmetic: 10**10**10 overflows, never hangs
        if isinstance(node, ast.BinOp):
            return _BINARY[type(node.op)](self._eval(node.left, values, special),
                                          self._eval(node.right, values, special))
        if isinstance(node, ast.UnaryOp):
            return _UNARY[type(node.op)](self._eval(node.operand, values, special))
        if isinstance(node, ast.Compare):
            left = self._eval(node.left, values, special)
            for op, c in zip(node.ops, node.comparators):
                right = self._eval(c, values, special)
                if not _COMPARE[type(op)](left, right):
                    return 0.0
                left = right
            return 1.0
        if isinstance(node, ast.IfExp):
            test = self._eval(node.test, values, special)
            return self._eval(node.body if test else node.orelse, values, special)
        if isinstance(node, ast.Name):
            return CONSTANTS[node.id] if node.id in CONSTANTS else special[node.id]
        if id(node) in self._index:
            return values[self._index[id(node)]]
        return SCALAR_FUNCTIONS[node.func.id](*(self._eval(a, values, special)
                                               for a in node.args))

    def reduce(self, k: int, t: np.ndarray, signals: dict, special: dict) -> float:
        """Reduction ``terms[k]`` over a recorded flight: its argument at every time ``t``
        (``signals``: an array per signal it names) reduced as :func:`reduce_signal` does;
        NaN if it cannot be computed.  ``initial`` reads the first point only."""
        fn = self._terms[k].function
        if fn == "initial":
            signals = {s: x[:1] for s, x in signals.items()}
            t = t[:1]
        with np.errstate(all="ignore"):
            try:
                x = np.asarray(self._points(self._args[k], signals, special), dtype=float)
                if x.ndim == 0:
                    x = np.full(np.shape(t), x)
                if x.shape != np.shape(t):
                    return math.nan
                return reduce_signal(fn, t, x, math.nan if len(x) == 0 else float(x[-1]))
            except (ArithmeticError, ValueError):
                return math.nan

    def at_point(self, k: int, signals: dict, special: dict) -> float:
        """Reduction ``terms[k]``'s argument at one point (``signals``: a number per signal it
        names; a ``final`` from the plant's final outputs); NaN if it cannot be computed."""
        with np.errstate(all="ignore"):
            try:
                return float(self._points(self._args[k], signals, special))
            except (ArithmeticError, ValueError):
                return math.nan

    def _points(self, node, env, special):
        """``node`` at every point: NumPy over the arrays (or numbers) of ``env``; a value
        that is infinite after an operation (log of 0, overflow) is NaN."""
        if isinstance(node, ast.Constant):
            return float(node.value)
        if isinstance(node, ast.Name):
            if node.id in env:
                return env[node.id]
            return CONSTANTS[node.id] if node.id in CONSTANTS else special[node.id]
        if isinstance(node, ast.BinOp):
            return _finite(_BINARY_NP[type(node.op)](self._points(node.left, env, special),
                                                     self._points(node.right, env, special)))
        if isinstance(node, ast.UnaryOp):
            v = self._points(node.operand, env, special)
            return np.negative(v) if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.Compare):
            left, out = self._points(node.left, env, special), True
            for op, c in zip(node.ops, node.comparators):
                right = self._points(c, env, special)
                out = np.logical_and(out, _COMPARE[type(op)](left, right))
                left = right
            return np.asarray(out, dtype=float)
        if isinstance(node, ast.IfExp):
            return np.where(self._points(node.test, env, special),
                            self._points(node.body, env, special),
                            self._points(node.orelse, env, special))
        return _finite(POINTWISE_FUNCTIONS[node.func.id](
            *(self._points(a, env, special) for a in node.args)))

    # pickling: keep the source only (the tree is rebuilt)
    def __getstate__(self):
        return {"source": self.source, "signals": sorted(self._signals)}

    def __setstate__(self, state):
        self.__init__(state["source"], state["signals"])


def _finite(x):
    """``x`` with its infinities made NaN (a value that could not be computed)."""
    x = np.asarray(x, dtype=float)
    return np.where(np.isinf(x), math.nan, x)


def reduce_signal(function: str, t: np.ndarray, x: np.ndarray, final: float) -> float:
    """One reduction of a recorded signal ``x(t)`` (``final`` from the plant's final outputs)."""
    if function == "final":
        return final
    if len(x) == 0:
        return math.nan
    if function == "initial":
        return float(x[0])
    if function == "max":
        return float(np.max(x))
    if function == "min":
        return float(np.min(x))
    integral = float(0.5 * np.sum((x[1:] + x[:-1]) * np.diff(t))) if len(x) > 1 else 0.0
    if function == "integral":
        return integral
    span = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    return integral / span if span > 0 else float(x[0])
