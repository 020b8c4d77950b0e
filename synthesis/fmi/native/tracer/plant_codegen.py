"""Rendering traced trees (:mod:`.plant_trace`) as C functions.

Every recorded operation becomes one statement ``const double v<id> = <expression>;`` in the
order it was recorded; a decision becomes an ``if``; a ``where`` an ``if`` that assigns its
result on both sides; a leaf what the caller asks for (:class:`Scope`, ``leaf``).  An operation
that may raise in Python sets ``err`` (the C runtime's ``py_*`` functions), and every leaf
returns ``PC_ERROR`` when ``err`` is set -- what Python's exception would have ended.  Values
the function does not compute itself are rendered by its :class:`Scope`: parameters and inputs
as the FMU's arrays, values of the start phase as the plant's slots, anything else as an entry
of the function's context array ``ctx`` that the caller fills.
"""
from __future__ import annotations

import math

from descent_fmus.synthesis.fmi.native.tracer.plant_shims import BINARY_C, C_FUNCTIONS
from descent_fmus.synthesis.fmi.native.tracer.plant_trace import (MAY_RAISE, Node, Source, Sym,
                                                            TraceError)

__all__ = ["Scope", "literal", "render_function", "c_string", "message_lines"]


def literal(v: float) -> str:
    """A C double literal equal to ``v`` (shortest round-trip digits)."""
    v = float(v)
    if math.isnan(v):
        return "NAN"
    if math.isinf(v):
        return "INFINITY" if v > 0 else "(-INFINITY)"
    text = repr(v)
    if not any(ch in text for ch in ".en"):
        text += ".0"
    return f"({text})" if text.startswith("-") else text


def c_string(text: str) -> str:
    """``text`` as a C string literal (UTF-8, escaped)."""
    out = []
    for b in text.encode("utf-8"):
        ch = chr(b)
        if ch in '"\\':
            out.append("\\" + ch)
        elif 32 <= b < 127:
            out.append(ch)
        else:
            out.append(f"\\{b:03o}")
    return '"' + "".join(out) + '"'


class Scope:
    """How a generated function names values: its own (``v<id>``), its sources (``sources``:
    Source -> C array name, e.g. the FMU's Reals ``r``), values persisted in slots
    (``persisted``: (owner, id) -> C expression), the rest through ``ctx[k]``."""

    def __init__(self, tracer, sources: dict | None = None, persisted: dict | None = None,
                 spaces: dict | None = None, allow_ctx: bool = True):
        self.tracer = tracer
        self.sources = sources or {}
        self.persisted = persisted or {}
        self.spaces = spaces or {}              # load space -> C array name
        self.allow_ctx = allow_ctx
        self.ctx: list = []                     # operands the caller provides, in ctx order
        self._ctx_index: dict = {}
        self.call_renderers: dict = {}          # call name -> fn(event, scope, indent) -> lines
        self.casts: dict = {}                   # store space -> C cast (e.g. "(int)")
        self.counter = 0

    def value(self, op) -> str:
        if op[0] == "c":
            return literal(op[1])
        _, owner, id_ = op
        if owner is self.tracer:
            return f"v{id_}"
        if isinstance(owner, Source) and owner in self.sources:
            return f"{self.sources[owner]}[{id_}]"
        if (owner, id_) in self.persisted:
            return self.persisted[(owner, id_)]
        if not self.allow_ctx:
            raise TraceError(f"{self.tracer.name}: a value from {owner!r} is not reachable here")
        key = (id(owner), id_)
        if key not in self._ctx_index:
            self._ctx_index[key] = len(self.ctx)
            self.ctx.append(op)
        return f"ctx[{self._ctx_index[key]}]"

    def fresh(self, stem: str) -> str:
        self.counter += 1
        return f"{stem}{self.counter}"


def _expr(name: str, ops: list, scope: Scope) -> str:
    a = [scope.value(o) for o in ops]
    if name in BINARY_C:
        return f"({a[0]} {BINARY_C[name]} {a[1]})"
    if name == "neg":
        return f"(-{a[0]})"
    if name == "select":
        return f"({a[0]} ? {a[1]} : {a[2]})"
    if name not in C_FUNCTIONS:
        raise TraceError(f"no C form of the operation {name}")
    fn = C_FUNCTIONS[name]
    if name in MAY_RAISE:
        return f"{fn}({', '.join(a)}, &err)"
    if name in ("isfinite", "isnan", "isinf"):
        return f"({fn}({a[0]}) != 0)"
    return f"{fn}({', '.join(a)})"


def _mark(obj, live: set) -> None:
    """Every value ``obj`` reads (operands, traced values, inside containers) is live."""
    if isinstance(obj, Sym):
        live.add((id(obj.owner), obj.id))
    elif isinstance(obj, tuple) and len(obj) == 3 and obj[0] == "s":
        live.add((id(obj[1]), obj[2]))
    elif isinstance(obj, (list, tuple)):
        for item in obj:
            _mark(item, live)
    elif isinstance(obj, dict):
        for item in obj.values():
            _mark(item, live)


def _live_events(events: list, live: set, me: int) -> None:
    """Backwards over ``events``: an operation is computed if its value is read later (``live``)
    or it may raise (Python would raise there); stores and calls always are."""
    for ev in reversed(events):
        kind = ev[0]
        if kind == "op":
            if ev[2] in MAY_RAISE or (me, ev[1]) in live:
                _mark(ev[3], live)
        elif kind in ("store", "call"):
            _mark(ev[1:], live)
        elif kind == "where":
            _, outs, cond, a_events, a_vals, b_events, b_vals = ev
            _mark(cond, live)
            for k, i in enumerate(outs):
                if (me, i) in live:
                    _mark(a_vals[k], live)
                    _mark(b_vals[k], live)
            _live_events(a_events, live, me)
            _live_events(b_events, live, me)


def _live(node: Node, me: int) -> set:
    """The values this node and the paths below it read (an id names one value per path)."""
    live: set = set()
    for child in node.children.values():
        live |= _live(child, me)
    _mark(node.cond, live)
    if node.result is not None:
        _mark(node.result, live)
    _live_events(node.events, live, me)
    return live


def _events(events: list, scope: Scope, used: set, ind: str) -> list:
    out = []
    me = id(scope.tracer)
    for ev in events:
        kind = ev[0]
        if kind == "op":
            _, id_, name, ops, k = ev
            expr = _expr(name, ops, scope)
            if (me, id_) in used:
                ctype = "int" if k == "b" else "double"
                out.append(f"{ind}const {ctype} v{id_} = {expr};")
            elif name in MAY_RAISE:
                out.append(f"{ind}(void){expr};")
        elif kind == "load":
            _, id_, space, index, k = ev
            if (me, id_) in used:
                ctype = "int" if k == "b" else "double"
                at = "" if index is None else f"[{index}]"         # None: a scalar argument
                out.append(f"{ind}const {ctype} v{id_} = {scope.spaces[space]}{at};")
        elif kind == "store":
            _, space, index, op = ev
            cast = scope.casts.get(space, "")
            out.append(f"{ind}{scope.spaces[space]}[{index}] = {cast}{scope.value(op)};")
        elif kind == "where":
            out += _where(ev, scope, used, ind)
        elif kind == "call":
            out += scope.call_renderers[ev[1]](ev, scope, ind, used)
        elif kind != "mark":
            raise TraceError(f"unknown event {kind}")
    return out


def _where(ev, scope: Scope, used: set, ind: str) -> list:
    _, outs, cond, a_events, a_vals, b_events, b_vals = ev
    me = id(scope.tracer)
    live = [k for k, i in enumerate(outs) if (me, i) in used]
    out = [f"{ind}double {', '.join(f'v{outs[k]}' for k in live)};"] if live else []
    out.append(f"{ind}if ({scope.value(cond)}) {{")
    out += _events(a_events, scope, used, ind + "    ")
    out += [f"{ind}    v{outs[k]} = {scope.value(a_vals[k])};" for k in live]
    out.append(f"{ind}}} else {{")
    out += _events(b_events, scope, used, ind + "    ")
    out += [f"{ind}    v{outs[k]} = {scope.value(b_vals[k])};" for k in live]
    out.append(f"{ind}}}")
    return out


def message_lines(message: str, holes: list, scope: Scope, ind: str) -> list:
    """Write a ParameterError's message into ``msg`` (its placeholders formatted as Python
    formats the traced values: ``repr``, ``str`` or a format spec)."""
    parts = message.split("\x00")
    fmt, args, lines = [], [], []
    for k, part in enumerate(parts):
        if k % 2 == 0:
            fmt.append(part.replace("%", "%%"))
            continue
        op, spec = holes[int(part)]
        if op[0] == "s" and isinstance(op[1], Source) and op[1].kind == "i":
            fmt.append("%d")                        # an Integer variable: str(int)
            args.append(f"(int){scope.value(op)}")
            continue
        buf = scope.fresh("text")
        lines.append(f"{ind}char {buf}[40];")
        lines.append(f"{ind}pc_format({buf}, sizeof {buf}, {scope.value(op)}, "
                     f"{c_string('' if spec in ('r', 's') else spec)});")
        fmt.append("%s")
        args.append(buf)
    lines.append(f"{ind}snprintf(msg, PC_MSG, {c_string(''.join(fmt))}"
                 + "".join(f", {a}" for a in args) + ");")
    lines.append(f"{ind}return PC_RAISE;")
    return lines


def _node(node: Node, scope: Scope, used: set, leaf, ind: str) -> list:
    used = _live(node, id(scope.tracer))
    out = _events(node.events, scope, used, ind)
    if node.cond is None:
        out.append(f"{ind}if (err)")
        out.append(f"{ind}    return PC_ERROR;")
        result = node.result
        if result[0] == "dispatch":
            out += leaf(result, scope, ind)
        elif result[0] == "error":
            out.append(f"{ind}return PC_ERROR;")
        elif result[0] == "raise":
            out += message_lines(result[1], result[2], scope, ind)
        else:
            out += leaf(result[1], scope, ind)
        return out
    cond = scope.value(node.cond)
    indexes = sorted(node.children)

    def test(value):
        return cond if value is True else f"!{cond}" if value is False else \
            f"{cond} == {value}"

    guards = [i for i in indexes if node.children[i].cond is None]
    if len(indexes) == 2 and guards:
        # a branch that ends here is a guard clause; the other goes on at this level
        g = guards[-1] if node.children[guards[-1]].result[0] != "return" else guards[0]
        other = indexes[1 - indexes.index(g)]
        out.append(f"{ind}if ({test(node.options[g])}) {{")
        out += _node(node.children[g], scope, used, leaf, ind + "    ")
        out.append(f"{ind}}}")
        return out + _node(node.children[other], scope, used, leaf, ind)
    for n, index in enumerate(indexes):
        if n and n == len(indexes) - 1:
            head = "} else {"
        else:
            head = f"{'} else ' if n else ''}if ({test(node.options[index])}) {{"
        out.append(ind + head)
        out += _node(node.children[index], scope, used, leaf, ind + "    ")
    out.append(f"{ind}}}")
    return out


def render_function(signature: str, tree: Node, scope: Scope, leaf, params=()) -> str:
    """The C function ``signature`` whose body is ``tree``; ``leaf(value, scope, indent)``
    gives the lines of a leaf that returns ``value`` (after ``err`` is checked); ``params``
    are the names of its parameters (cast to void in case a path reads none of them)."""
    body = _node(tree, scope, set(), leaf, "    ")
    head = [f"{signature}", "{", "    int err = 0;"]
    head += [f"    (void){p};" for p in params]
    return "\n".join(head + body + ["}"]) + "\n"
