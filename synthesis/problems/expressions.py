"""Objective expressions of problem files, parsed safely (a whitelist of Python's syntax tree).

An expression combines numbers, the arithmetic operators ``+ - * / **``, comparisons (1.0 when
true, 0.0 when false), conditionals ``a if condition else b``, the scalar functions ``abs sqrt exp log sin cos tanh min max`` and the
flight's signals through the reductions

* ``final(x)``, ``initial(x)`` -- the value of signal ``x`` at the end / start of the flight;
* ``max(x)``, ``min(x)`` -- its maximum / minimum over the communication points;
* ``integral(x)`` -- its integral over time (trapezoidal rule on the communication points);
* ``mean(x)`` -- ``integral(x)`` divided by the flight's duration;

where ``x`` names a plant output (or ``u1``, ``u2``, ... for the law's outputs).  The names
``tf`` (the time the flight ended) and ``stopped`` (1 if the stop condition ended it, else 0)
and the constant ``pi`` are also known.  Nothing is ever passed to ``eval``: the tree is checked
node by node when the file is read, and evaluated by :meth:`Expression.evaluate`.
A value that cannot be computed (log of 0, overflow) is NaN, which the evaluator turns into the
problem's penalty.
"""
from __future__ import annotations

import ast
import math
import operator

import numpy as np

__all__ = ["Expression", "ExpressionError", "SIGNAL_FUNCTIONS", "SCALAR_FUNCTIONS"]


class ExpressionError(ValueError):
    """An expression uses a construct or a name that is not allowed."""


SIGNAL_FUNCTIONS = ("final", "initial", "max", "min", "integral", "mean")
SCALAR_FUNCTIONS = {"abs": abs, "sqrt": math.sqrt, "exp": math.exp, "log": math.log,
                    "sin": math.sin, "cos": math.cos, "tanh": math.tanh, "min": min, "max": max}
CONSTANTS = {"pi": math.pi}
SPECIAL = ("tf", "stopped")
_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}
_COMPARE = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt,
            ast.GtE: operator.ge, ast.Eq: operator.eq, ast.NotEq: operator.ne}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}


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
        Syntax error, a construct outside the whitelist, an unknown name or function.

    Attributes
    ----------
    reductions : set of (str, str)
        ``(function, signal)`` pairs the expression needs.
    """

    def __init__(self, source: str, signals):
        self.source = source
        self._signals = set(signals)
        try:
            tree = ast.parse(source.strip(), mode="eval")
        except SyntaxError as exc:
            raise ExpressionError(f"syntax error in {source!r}: {exc.msg}") from None
        self.reductions = set()
        self._check(tree.body)
        self._tree = tree.body

    # -- checking (once, when the file is read) ------------------------------------------------
    def _check(self, node) -> None:
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise ExpressionError(f"only numbers are allowed as constants, got "
                                      f"{node.value!r} in {self.source!r}")
        elif isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            self._check(node.left)
            self._check(node.right)
        elif isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            self._check(node.operand)
        elif isinstance(node, ast.Compare) and all(type(o) in _COMPARE for o in node.ops):
            self._check(node.left)
            for c in node.comparators:
                self._check(c)
        elif isinstance(node, ast.IfExp):
            for part in (node.test, node.body, node.orelse):
                self._check(part)
        elif isinstance(node, ast.Name):
            if node.id in self._signals and node.id not in CONSTANTS and \
                    node.id not in SPECIAL:
                raise ExpressionError(f"signal {node.id!r} must be reduced to a number: write "
                                      f"final({node.id}), max({node.id}), integral({node.id}), "
                                      f"... in {self.source!r}")
            if node.id not in CONSTANTS and node.id not in SPECIAL:
                raise ExpressionError(f"unknown name {node.id!r} in {self.source!r}")
        elif isinstance(node, ast.Call):
            self._check_call(node)
        else:
            raise ExpressionError(f"construct not allowed in an objective: "
                                  f"{type(node).__name__} in {self.source!r}")

    def _check_call(self, node: ast.Call) -> None:
        if not isinstance(node.func, ast.Name) or node.keywords:
            raise ExpressionError(f"only calls of the allowed functions by name, without "
                                  f"keywords, in {self.source!r}")
        name = node.func.id
        if self._is_reduction(node):
            self.reductions.add((name, node.args[0].id))
            return
        if name in SIGNAL_FUNCTIONS and name not in SCALAR_FUNCTIONS:
            arg = node.args[0] if len(node.args) == 1 else None
            what = (f"unknown signal {arg.id!r} (known: {', '.join(sorted(self._signals))})"
                    if isinstance(arg, ast.Name) else "one signal name")
            raise ExpressionError(f"{name}() takes {what} in {self.source!r}")
        if name not in SCALAR_FUNCTIONS:
            raise ExpressionError(f"unknown function {name!r} in {self.source!r}; allowed: "
                                  f"{', '.join(sorted(set(SIGNAL_FUNCTIONS) | set(SCALAR_FUNCTIONS)))}")
        if not node.args:
            raise ExpressionError(f"{name}() needs an argument in {self.source!r}")
        for a in node.args:
            self._check(a)

    def _is_reduction(self, node: ast.Call) -> bool:
        return (node.func.id in SIGNAL_FUNCTIONS and len(node.args) == 1
                and isinstance(node.args[0], ast.Name) and node.args[0].id in self._signals)

    # -- evaluation ---------------------------------------------------------------------------------
    def evaluate(self, values: dict, special: dict) -> float:
        """The value for reductions ``values[(function, signal)]`` and ``special`` names."""
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
        if self._is_reduction(node):
            return values[(node.func.id, node.args[0].id)]
        return SCALAR_FUNCTIONS[node.func.id](*(self._eval(a, values, special)
                                               for a in node.args))

    # pickling: keep the source only (the tree is rebuilt)
    def __getstate__(self):
        return {"source": self.source, "signals": sorted(self._signals)}

    def __setstate__(self, state):
        self.__init__(state["source"], state["signals"])


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
