"""Tracing the plant models into programs of IEEE operations with branches, for C.

A traced value (:class:`Sym`) stands for a double (or a truth value) that the C code computes.
Every operation on it -- ``+ - * / **``, unary ``-``, ``abs``, comparisons, and the math functions
of :mod:`.plant_shims` that stand in for the module's ``math`` at trace time -- is recorded in
Python's evaluation order, operand for operand, with no simplification: the C code performs the
same operations in the same order and so computes the same doubles.

Where the model branches on a traced value (an ``if``, ``and``/``or``, ``min``/``max`` of traced
values, ``x if c else y``, a ``ParameterError`` raised on a bad value), :func:`explore` runs the
function once per path (every ``bool()`` of a traced value is a decision; the decisions of a run
are forced from a prefix and the untried alternatives queued) and joins the runs into a tree:
shared operations, then a decision and one subtree per choice.  The C code is that tree -- an
``if`` per decision -- so every path does exactly what Python does on it, including the lazy
evaluation of the branch not taken.  ``models.traceable.where`` flattens a branch into a C
conditional expression where a tree would grow too large.

Identical operations on the same operands inside one path are recorded once (they give the same
double), and a decision on a condition already decided in the path is not asked again.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field

from descent_fmus.models.params import ParameterError

__all__ = ["Sym", "Source", "Tracer", "Node", "TraceError", "StructuralValue", "explore",
           "active", "operand", "is_sym", "evaluate", "MAX_PATHS", "MAX_DECISIONS"]

#: Paths one traced function may have (a model with more should flatten a branch with
#: ``models.traceable.where``).
MAX_PATHS = 4096

#: Decisions one path may take (more: a loop on a traced value, which never ends when traced).
MAX_DECISIONS = 2000

#: Operations that may raise in Python (ArithmeticError or ValueError) -- the C code flags them.
MAY_RAISE = {"div", "pow", "fmod", "sqrt", "exp", "log", "log1p", "sin", "cos", "tan", "asin",
             "acos", "atan", "tanh", "ceil", "floor"}


_PY = {"add": lambda a, b: a + b, "sub": lambda a, b: a - b, "mul": lambda a, b: a * b,
       "div": lambda a, b: a / b, "pow": lambda a, b: a ** b, "neg": lambda a: -a,
       "lt": lambda a, b: a < b, "le": lambda a, b: a <= b, "gt": lambda a, b: a > b,
       "ge": lambda a, b: a >= b, "eq": lambda a, b: a == b, "ne": lambda a, b: a != b,
       "select": lambda c, a, b: a if c else b}


def evaluate(name: str, args):
    """The operation on plain numbers, as Python computes it."""
    if name in _PY:
        return _PY[name](*args)
    return getattr(math, name)(*args)


class TraceError(RuntimeError):
    """Model code the tracer cannot follow (an unsupported operation, too many paths, ...)."""


class StructuralValue(TraceError):
    """A structural parameter's value is needed (as an integer) where the dispatching function
    is traced: the path goes on in the variant traced for that value."""


_STACK: list = []


def active() -> "Tracer":
    """The tracer recording now."""
    if not _STACK:
        raise TraceError("a traced value was used outside a trace")
    return _STACK[-1]


def is_sym(v) -> bool:
    return isinstance(v, Sym)


def operand(v):
    """The recorded form of an operand: ``("s", owner, id)`` for a traced value, ``("c", x)`` for
    a number (ints and bools become the double Python would use)."""
    if isinstance(v, Sym):
        return ("s", v.owner, v.id)
    if isinstance(v, (float, int)):
        return ("c", float(v))
    if type(v).__module__ == "numpy" and hasattr(v, "item"):
        return ("c", float(v.item()))
    raise TraceError(f"cannot trace an operation on {type(v).__name__} {v!r}")


class Source:
    """A family of values the generated code reads from outside a trace (parameters, inputs,
    the step's time): ``Source("r").sym(12)`` renders as ``r[12]``."""

    def __init__(self, name: str, kind: str = "f"):
        self.name = name
        self.kind = kind
        self._syms: dict = {}

    def sym(self, index, kind: str | None = None) -> "Sym":
        if index not in self._syms:
            self._syms[index] = Sym(self, index, kind or self.kind)
        return self._syms[index]

    def __repr__(self):
        return f"Source({self.name})"


class Sym:
    """A traced double (kind ``"f"``) or truth value (kind ``"b"``)."""

    __slots__ = ("owner", "id", "kind", "finite")

    def __init__(self, owner, id_, kind: str = "f", finite: bool = False):
        self.owner = owner
        self.id = id_
        self.kind = kind
        self.finite = finite      # known to be finite (isfinite() of it is True, no decision)

    __hash__ = object.__hash__

    # -- arithmetic, in Python's order: a op b records (op, a, b) ------------------------------
    def __add__(self, o): return _bin("add", self, o)
    def __radd__(self, o): return _bin("add", o, self)
    def __sub__(self, o): return _bin("sub", self, o)
    def __rsub__(self, o): return _bin("sub", o, self)
    def __mul__(self, o): return _bin("mul", self, o)
    def __rmul__(self, o): return _bin("mul", o, self)
    def __truediv__(self, o): return _bin("div", self, o)
    def __rtruediv__(self, o): return _bin("div", o, self)
    def __pow__(self, o): return _bin("pow", self, o)
    def __rpow__(self, o): return _bin("pow", o, self)
    def __neg__(self): return active().op("neg", self)
    def __pos__(self): return self
    def __abs__(self): return active().op("fabs", self)

    # -- comparisons give truth values ----------------------------------------------------------
    def __lt__(self, o): return _bin("lt", self, o, "b")
    def __le__(self, o): return _bin("le", self, o, "b")
    def __gt__(self, o): return _bin("gt", self, o, "b")
    def __ge__(self, o): return _bin("ge", self, o, "b")

    def __eq__(self, o):
        if not isinstance(o, (Sym, float, int)):
            return NotImplemented
        return active().op("eq", self, o, kind="b")

    def __ne__(self, o):
        if not isinstance(o, (Sym, float, int)):
            return NotImplemented
        return active().op("ne", self, o, kind="b")

    def __bool__(self):
        tr = active()
        cond = self if self.kind == "b" else tr.op("ne", self, 0.0, kind="b")
        return tr.decide(cond, (True, False)) is True

    # -- conversions: only what keeps the value a double ---------------------------------------
    def __float__(self):
        raise TraceError("float() of a traced value outside a traced module (a math function "
                         "imported by name, 'from math import sin'? write math.sin)")

    def __int__(self):
        if _STACK and _STACK[-1].hooks.get("dispatch"):
            raise StructuralValue()
        raise TraceError("int() of a traced value: an integer that shapes the model must be a "
                         "structural parameter")

    __index__ = __int__

    def __round__(self, n=None):
        raise TraceError("round() of a traced value is not traced")

    def __floordiv__(self, o):
        raise TraceError("// of a traced value is not traced")

    def __mod__(self, o):
        raise TraceError("% of a traced value is not traced (math.fmod is)")

    __rfloordiv__, __rmod__ = __floordiv__, __mod__

    # -- formatting inside messages (ParameterError): a placeholder the C code fills in --------
    def __format__(self, spec):
        return active().placeholder(self, spec)

    def __repr__(self):
        if _STACK:
            return active().placeholder(self, "r")
        return f"<Sym {self.owner!r}:{self.id}>"

    __str__ = __repr__

    # -- models.traceable.where: a conditional whose branches are traced lazily ------------------
    def __where__(self, if_true, if_false):
        return active().where(self, if_true, if_false)


def _bin(name, a, b, kind="f"):
    """``a <name> b`` recorded; an array operand is NumPy's to handle (element by element)."""
    if type(a).__name__ == "ndarray" or type(b).__name__ == "ndarray":
        return NotImplemented
    return active().op(name, a, b, kind=kind)


@dataclass
class Node:
    """A node of a traced function's tree: ``events`` (operations, stores, calls), then either a
    decision on ``cond`` with one child per option or, at a leaf, ``result``."""

    events: list = field(default_factory=list)
    cond: tuple | None = None
    skey: tuple | None = None         # the condition's expression (Tracer.skey)
    options: tuple = ()
    children: dict = field(default_factory=dict)
    result: tuple | None = None       # ("return", value) | ("raise", message, holes) | ("error",)

    def leaves(self):
        if self.cond is None:
            yield self
        for child in self.children.values():
            yield from child.leaves()

    def conditions(self, ok) -> dict:
        """The conditions (structural key -> value) every path to a leaf with ``ok(result)``
        has decided the same way: what holds wherever such a leaf is reached."""
        found = []

        def walk(node, path):
            if node.cond is None:
                if ok(node.result):
                    found.append(dict(path))
                return
            for index, child in node.children.items():
                walk(child, path + [(node.skey, node.options[index])])
        walk(self, [])
        if not found:
            return {}
        common = found[0]
        for other in found[1:]:
            common = {k: v for k, v in common.items() if other.get(k, not v) == v}
        return common


class Tracer:
    """Records one traced function (all its paths, :func:`explore`)."""

    def __init__(self, name: str, assumed: dict | None = None):
        self.name = name
        #: conditions known to hold wherever the function runs (structural key -> value, e.g.
        #: the parameter check passed): decided without a branch
        self.assumed = dict(assumed or {})
        self.hooks = {}                  # e.g. "slots": the plant's SlotView
        self._begin(())

    # -- one run -------------------------------------------------------------------------------
    def _begin(self, forced):
        self.forced = forced
        self.choices: list = []          # (index chosen, number of options) per decision
        self.events: list = []
        self.memo: dict = {}             # CSE: key -> Sym
        self.decided: dict = {}          # cond key -> option value
        self.holes: list = []            # message placeholders: (operand, spec)
        self.next_id = 0
        self.versions: dict = {}         # load space -> store count (loads after a store differ)
        self.path: list = []             # (events index, decision) for the tree
        self.skeys: dict = {}            # id -> structural key (the expression, for assumptions)

    def new(self, kind="f", finite=False) -> Sym:
        s = Sym(self, self.next_id, kind, finite)
        self.next_id += 1
        return s

    def op(self, name, *args, kind="f"):
        ops = tuple(operand(a) for a in args)
        if all(o[0] == "c" for o in ops):
            return evaluate(name, [o[1] for o in ops])
        key = (name,) + ops
        hit = self.memo.get(key)
        if hit is not None:
            return hit
        s = self.new(kind)
        self.events.append(("op", s.id, name, ops, kind))
        self.memo[key] = s
        self.skeys[s.id] = (name,) + tuple(self.skey(o) for o in ops)
        return s

    def skey(self, op) -> tuple:
        """The expression of an operand over sources and constants (equal in two traces for the
        same computation): ids of this trace replaced by their expressions."""
        if op[0] == "c":
            return op
        _, owner, id_ = op
        if owner is self:
            return self.skeys.get(id_, ("?", id_))
        return ("src", owner.name, id_) if isinstance(owner, Source) else ("x", id(owner), id_)

    def load(self, space: str, index, kind="f", finite=False) -> Sym:
        """The value ``space[index]`` (``S``, ``x``, ``a``, ``in``, ...) as read now."""
        key = ("load", space, index, self.versions.get(space, 0))
        hit = self.memo.get(key)
        if hit is not None:
            return hit
        s = self.new(kind, finite)
        self.events.append(("load", s.id, space, index, kind))
        self.memo[key] = s
        return s

    def store(self, space: str, index, value) -> None:
        self.events.append(("store", space, index, operand(value)))
        self.versions[space] = self.versions.get(space, 0) + 1

    def mark(self, what: str, detail=None) -> None:
        """A marker in the event list (e.g. an attribute written), not rendered."""
        self.events.append(("mark", what, detail))

    def call(self, name: str, spec: dict, n_out: int, kinds=None, key=None) -> list:
        """A call of the C runtime (``advance_to``, ...): ``n_out`` results; ``key``: the
        call's expression, if the results are a function of its arguments alone."""
        outs = [self.new((kinds or {}).get(k, "f")) for k in range(n_out)]
        self.events.append(("call", name, spec, [s.id for s in outs]))
        if key is not None:
            for k, s in enumerate(outs):
                self.skeys[s.id] = ("call", key, k)
        return outs

    def decide(self, cond, options: tuple):
        """The option the current path takes at this decision on ``cond`` (a truth value or a
        small integer, e.g. an outcome)."""
        key = operand(cond)
        if key in self.decided:
            return self.decided[key]
        skey = self.skey(key)
        if skey in self.assumed:
            return self.assumed[skey]
        k = len(self.choices)
        if k >= MAX_DECISIONS:
            raise TraceError(f"{self.name}: more than {MAX_DECISIONS} decisions on one path: a "
                             f"loop whose end depends on a traced value (loop a fixed number "
                             f"of times, or step with advance_to)")
        index = self.forced[k] if k < len(self.forced) else 0
        self.choices.append((index, len(options)))
        self.path.append((len(self.events), key, options, index, skey))
        self.decided[key] = options[index]
        return options[index]

    def where(self, cond, if_true, if_false):
        """``models.traceable.where`` on a traced condition: a C conditional whose two branches
        are traced apart (each computes only on its own side, as Python's lazy branch does)."""
        cond = cond if cond.kind == "b" else self.op("ne", cond, 0.0, kind="b")
        a_events, a = self._branch(if_true)
        b_events, b = self._branch(if_false)
        if isinstance(a, tuple) != isinstance(b, tuple) or \
                (isinstance(a, tuple) and len(a) != len(b)):
            raise TraceError(f"{self.name}: where() branches of different shapes")
        a_vals, b_vals = (list(a), list(b)) if isinstance(a, tuple) else ([a], [b])
        outs = [self.new() for _ in a_vals]
        self.events.append(("where", [s.id for s in outs], operand(cond),
                            a_events, [operand(v) for v in a_vals],
                            b_events, [operand(v) for v in b_vals]))
        return tuple(outs) if isinstance(a, tuple) else outs[0]

    def _branch(self, fn):
        saved = (self.events, dict(self.memo), dict(self.decided), dict(self.versions),
                 len(self.path))
        self.events = []
        try:
            value = fn() if callable(fn) else fn
        finally:
            events = self.events
            self.events, self.memo, self.decided, self.versions, n_path = saved
        if len(self.path) != n_path:
            raise TraceError(f"{self.name}: a branch of where() decides on a traced value; "
                             f"use where() inside it too")
        return events, value

    def placeholder(self, sym, spec) -> str:
        self.holes.append((operand(sym), spec))
        return f"\x00{len(self.holes) - 1}\x00"


def _run(tracer: Tracer, fn, forced):
    tracer._begin(forced)
    _STACK.append(tracer)
    try:
        result = ("return", fn())
    except StructuralValue:
        result = ("dispatch",)
    except ParameterError as exc:
        result = ("raise", str(exc), list(tracer.holes))
    except (ArithmeticError, ValueError):
        result = ("error",)
    finally:
        _STACK.pop()
    return result


def _insert(root: Node, tracer: Tracer, result) -> None:
    node, start = root, 0
    for at, key, options, index, skey in tracer.path:
        seg = tracer.events[start:at]
        if node.cond is None and not node.children:
            node.events, node.cond, node.options, node.skey = seg, key, options, skey
        elif not _same(node.events, seg) or node.cond != key:
            raise TraceError(f"{tracer.name}: the traced function is not deterministic (a path "
                             f"replayed differently)")
        node = node.children.setdefault(index, Node())
        start = at
    seg = tracer.events[start:]
    if node.result is None and node.cond is None:
        node.events, node.result = seg, result
    elif not _same(node.events, seg):
        raise TraceError(f"{tracer.name}: a path replayed differently")


def _same(a, b) -> bool:
    """Event lists equal (NaN constants compare equal to themselves here)."""
    return a == b or repr(a) == repr(b)


def explore(tracer: Tracer, fn, limit: int = MAX_PATHS) -> Node:
    """Run ``fn()`` under ``tracer`` once per path; the tree of its paths.

    A leaf's ``result`` is ``("return", value)`` (``value`` as ``fn`` returned it, traced values
    inside), ``("raise", message, holes)`` for a :class:`ParameterError` (its message with
    placeholders for traced values, :meth:`Tracer.placeholder`) or ``("error",)`` for the
    ArithmeticError/ValueError Python would raise on that path with plain numbers.
    """
    root = Node()
    pending, runs = [()], 0
    while pending:
        forced = pending.pop()
        result = _run(tracer, fn, forced)
        runs += 1
        if runs > limit:
            raise TraceError(f"{tracer.name}: more than {limit} paths; flatten a branch with "
                             f"models.traceable.where")
        for k in range(len(tracer.choices) - 1, len(forced) - 1, -1):
            _, n = tracer.choices[k]
            prefix = tuple(i for i, _ in tracer.choices[:k])
            pending.extend(prefix + (alt,) for alt in range(n - 1, 0, -1))
        _insert(root, tracer, result)
    return root


#: The CPython whose float arithmetic the C runtime reproduces: math.hypot (its own algorithm,
#: whose subnormal branch changed in 3.12) and sum() of floats (in order; 3.12 compensates).
PYTHON = (3, 11)


def check_python() -> None:
    """Raise :class:`TraceError` unless this is the CPython the C runtime reproduces."""
    if sys.version_info[:2] != PYTHON:
        raise TraceError(f"the native plants reproduce CPython {PYTHON[0]}.{PYTHON[1]}'s "
                         f"math.hypot and sum(); this is {sys.version_info[0]}."
                         f"{sys.version_info[1]}")
