"""The stepping loops at trace time: ``advance_to`` and ``propagate_linear_input`` recorded as
calls of the C runtime, their function arguments traced into C callbacks.

At trace time :func:`traced_advance_to` stands in for :func:`models.integrators.advance_to` (and
:func:`traced_propagate` for :func:`models.rk4_input.propagate_linear_input`) in the model
modules.  It traces the right-hand side, the event function and ``on_step`` -- whatever
functions or closures the plant passes -- each into a C function (:class:`Unit`), records one
call of the hand-written loop (``pc_advance_to``, ``c/plant_runtime.c``, which mirrors the
Python loop operation for operation) and returns traced results: the state, the time, and the
outcome as a decision with one path per outcome (``ok``, ``event``, ``diverged``), so that the
plant's own code after the loop is traced on each.

A callback that writes the plant's attributes (``on_step`` keeping loads) writes the plant's
slots (:class:`SlotView`): the caller's pending attribute values are stored before the call and
read back after it.  A callback commits its writes only when no operation raised; that is
Python's behaviour as long as nothing that may raise follows the first write, which is checked.
"""
from __future__ import annotations

from descent_fmus.synthesis.fmi.native.tracer.plant_codegen import Scope, literal, render_function
from descent_fmus.synthesis.fmi.native.tracer.plant_trace import (MAY_RAISE, Sym, TraceError, Tracer,
                                                           active, explore, operand, _STACK)

__all__ = ["Unit", "SlotLayout", "SlotView", "traced_advance_to", "traced_propagate",
           "proxy_class", "current_unit", "using_unit", "CALL_RENDERERS"]

_UNITS: list = []


class Unit:
    """The C functions of one plant (deduplicated by their text)."""

    def __init__(self, prefix: str):
        self.prefix = prefix
        self.functions: list = []          # (name, text, static)
        self._names: dict = {}
        self._count: dict = {}

    def add(self, stem: str, render, static: bool = True) -> str:
        """``render(name) -> text``; the same text under one name."""
        probe = render("@NAME@")
        if probe in self._names:
            return self._names[probe]
        self._count[stem] = self._count.get(stem, 0) + 1
        name = f"{self.prefix}_{stem}{self._count[stem]}"
        self._names[probe] = name
        self.functions.append((name, render(name), static))
        return name


def current_unit() -> Unit:
    if not _UNITS:
        raise TraceError("no plant unit is being generated")
    return _UNITS[-1]


class using_unit:
    """Context: the unit the callbacks traced inside go to."""

    def __init__(self, unit: Unit):
        self.unit = unit

    def __enter__(self):
        _UNITS.append(self.unit)
        return self.unit

    def __exit__(self, *exc):
        _UNITS.pop()


_PROXIES: dict = {}


def proxy_class(cls):
    """``cls`` with attribute writes marked in the trace (for the commit check)."""
    if cls not in _PROXIES:
        def __setattr__(self, name, value):
            if _STACK:
                active().mark("set", name)
            object.__setattr__(self, name, value)
        _PROXIES[cls] = type(cls.__name__, (cls,), {"__setattr__": __setattr__,
                                                    "__module__": cls.__module__})
    return _PROXIES[cls]


class SlotLayout:
    """The plant's slots ``S``: the integrator's numeric attributes (``attrs``: name ->
    (first index, length or None for a number)), then values computed once at the start and
    kept (``hidden``: (owner, id) -> index)."""

    def __init__(self):
        self.attrs: dict = {}
        self.hidden: dict = {}
        self.size = 0

    def add_attr(self, name: str, n):
        if name not in self.attrs:
            self.attrs[name] = (self.size, n)
            self.size += 1 if n is None else n

    def add_hidden(self, sym: Sym):
        key = (sym.owner, sym.id)
        if key not in self.hidden:
            self.hidden[key] = self.size
            self.size += 1

    def persisted(self) -> dict:
        return {key: f"S[{k}]" for key, k in self.hidden.items()}


class SlotView:
    """The slot attributes of ``obj`` as values read from ``S`` by ``tracer``."""

    def __init__(self, obj, layout: SlotLayout, tracer: Tracer):
        self.obj, self.layout, self.tracer = obj, layout, tracer
        self.loaded: dict = {}

    def load(self):
        for name, (start, n) in self.layout.attrs.items():
            v = (self.tracer.load("S", start) if n is None
                 else tuple(self.tracer.load("S", start + j) for j in range(n)))
            object.__setattr__(self.obj, name, v)
            self.loaded[name] = v

    def changed(self) -> list:
        """``(slot index, value)`` of the attributes written since :meth:`load`."""
        out = []
        for name, (start, n) in self.layout.attrs.items():
            cur, old = getattr(self.obj, name), self.loaded[name]
            if n is None:
                if cur is not old:
                    out.append((start, _number(cur, name)))
                continue
            if not isinstance(cur, tuple) or len(cur) != n:
                raise TraceError(f"attribute {name} changed its shape ({n} values)")
            out += [(start + j, _number(c, name)) for j, (c, o) in enumerate(zip(cur, old))
                    if c is not o]
        return out

    def flush(self):
        for k, v in self.changed():
            self.tracer.store("S", k, v)
        self.load()


def _number(v, name):
    if isinstance(v, Sym) or (isinstance(v, (int, float)) and not isinstance(v, complex)):
        return v
    raise TraceError(f"attribute {name} = {v!r} is not a number")


# -- callbacks -------------------------------------------------------------------------------
_SIGNATURES = {
    "f": ("int @NAME@(const double *x, const double *a, const double *ctx, double *dx)",
          ("x", "a", "ctx", "dx")),
    "event": ("int @NAME@(const double *x, const double *ctx, double *g)", ("x", "ctx", "g")),
    "on_step": ("int @NAME@(const double *x, const double *k1, const double *ctx, double *S)",
                ("x", "k1", "ctx", "S")),
}


def _check_commit(tree, name):
    """No operation that may raise after the first attribute write (see the module docstring)."""
    def walk(node, written):
        for ev in node.events:
            if ev[0] == "mark" and ev[1] == "set":
                written = True
            elif written and ev[0] == "op" and ev[2] in MAY_RAISE:
                raise TraceError(f"{name}: an operation that may raise ({ev[2]}) follows an "
                                 f"attribute write; compute before writing")
        for child in node.children.values():
            walk(child, written)
    walk(tree, False)


def _trace_callback(kind: str, fn, n: int, m: int = 0, star: bool = True, view_of=None):
    """Trace ``fn`` as the callback ``kind``; returns (C name, ctx operands)."""
    tracer = Tracer(f"{kind} {getattr(fn, '__qualname__', fn)}")

    def body():
        x = tuple(tracer.load("x", j) for j in range(n))
        if kind == "f":
            a = [tracer.load("a", j) for j in range(m)]
            out = fn(x, *a) if star else fn(x, tuple(a))
            if not isinstance(out, tuple) or len(out) != n:
                raise TraceError(f"{tracer.name}: returns {len(out)} values for {n} states")
            return list(out)
        if kind == "event":
            return fn(x)
        view = SlotView(view_of[0], view_of[1], tracer)
        saved = {name: getattr(view.obj, name) for name in view.layout.attrs}
        view.load()
        try:
            fn(x, tuple(tracer.load("k1", j) for j in range(n)))
            return view.changed()
        finally:
            for name, v in saved.items():
                object.__setattr__(view.obj, name, v)

    tree = explore(tracer, body)
    if kind == "on_step":
        _check_commit(tree, tracer.name)
    scope = Scope(tracer, spaces={"x": "x", "a": "a", "k1": "k1", "S": "S"})
    signature, params = _SIGNATURES[kind]

    def leaf(value, scope, ind):
        if kind == "f":
            lines = [f"{ind}dx[{j}] = {scope.value(operand(v))};" for j, v in enumerate(value)]
        elif kind == "event":
            lines = [f"{ind}*g = {scope.value(operand(value))};"]
        else:
            lines = [f"{ind}S[{k}] = {scope.value(operand(v))};" for k, v in value]
        return lines + [f"{ind}return PC_OK;"]

    text = render_function("static " + signature, tree, scope, leaf, params)
    name = current_unit().add(kind, lambda nm: text.replace("@NAME@", nm))
    return name, list(scope.ctx)


def _slot_view():
    return active().hooks.get("slots")


def traced_advance_to(f, x, t0, t_end, dt, args, event=None, on_step=None, tol=1e-9):
    """Stand-in for ``models.integrators.advance_to`` (see the module docstring)."""
    tr = active()
    n, args = len(x), tuple(args)
    view = _slot_view()
    if view is not None:
        view.flush()
    f_name, f_ctx = _trace_callback("f", f, n, len(args))
    spec = {"n": n, "x": [operand(v) for v in x], "t0": operand(t0), "t_end": operand(t_end),
            "dt": operand(dt), "args": [operand(v) for v in args], "tol": float(tol),
            "f": f_name, "f_ctx": f_ctx, "event": None, "event_ctx": [], "on_step": None,
            "on_step_ctx": []}
    if event is not None:
        spec["event"], spec["event_ctx"] = _trace_callback("event", event, n)
    if on_step is not None:
        if view is None:
            raise TraceError("on_step without the plant's slots")
        spec["on_step"], spec["on_step_ctx"] = _trace_callback(
            "on_step", on_step, n, view_of=(view.obj, view.layout))
    outs = tr.call("advance_to", spec, n + 2, kinds={n + 1: "b"})
    if view is not None:                # on_step may have written the slots: read them again
        tr.versions["S"] = tr.versions.get("S", 0) + 1
        view.load()
    outcome = tr.decide(outs[n + 1], (0, 1, 2))
    from descent_fmus.models.integrators import DIVERGED, EVENT, OK
    return tuple(outs[:n]), outs[n], (OK, EVENT, DIVERGED)[outcome]


def traced_propagate(f, x, span, u0, du, n, out=None):
    """Stand-in for ``models.rk4_input.propagate_linear_input``: ``x`` after ``n`` RK4 steps
    with the input linear over ``span``; an exception where the C loop reports one."""
    if out is not None:
        raise TraceError("propagate_linear_input(out=...) is not traced")
    tr = active()
    nx, u0, du = len(x), tuple(u0), tuple(du)
    f_name, f_ctx = _trace_callback("f", f, nx, len(u0), star=False)
    spec = {"n": nx, "x": [operand(v) for v in x], "span": operand(span),
            "u0": [operand(v) for v in u0], "du": [operand(v) for v in du],
            "steps": operand(n), "f": f_name, "f_ctx": f_ctx}
    outs = tr.call("propagate", spec, nx + 1, kinds={nx: "b"})
    if tr.decide(outs[nx], (0, 1)) == 1:
        raise ArithmeticError("the traced propagation raised")
    return tuple(outs[:nx])


# -- the calls in C --------------------------------------------------------------------------
def _arrays(spec, keys, c, scope, ind, lines, const=True) -> dict:
    names = {}
    for key in keys:
        vals = spec[key]
        if not vals:
            names[key] = "NULL"
            continue
        names[key] = f"{c}_{key}"
        lines.append(f"{ind}{'const ' if const else ''}double {c}_{key}[{len(vals)}] = "
                     f"{{{', '.join(scope.value(o) for o in vals)}}};")
    return names


def _results(outs, c, n, used, me, ind, last) -> list:
    lines = [f"{ind}const double v{outs[j]} = {c}_x[{j}];" for j in range(n)
             if (me, outs[j]) in used]
    for i, expr, ctype in last:
        if (me, outs[i]) in used:
            lines.append(f"{ind}const {ctype} v{outs[i]} = {expr};")
    return lines


def _render_advance_to(ev, scope, ind, used) -> list:
    _, _, spec, outs = ev
    c, n, lines = scope.fresh("c"), spec["n"], []
    arr = _arrays(spec, ["x"], c, scope, ind, lines, const=False)
    arr.update(_arrays(spec, ["args", "f_ctx", "event_ctx", "on_step_ctx"], c, scope, ind, lines))
    slots = scope.spaces.get("S", "NULL") if spec["on_step"] else "NULL"
    lines += [f"{ind}const pc_system {c}_sys = {{{n}, {spec['f']}, {arr['f_ctx']}, "
              f"{arr['args']}, {spec['event'] or 'NULL'}, {arr['event_ctx']}, "
              f"{literal(spec['tol'])}, {spec['on_step'] or 'NULL'}, {arr['on_step_ctx']}, "
              f"{slots}}};",
              f"{ind}double {c}_t;",
              f"{ind}const int {c}_out = pc_advance_to(&{c}_sys, {c}_x, "
              f"{scope.value(spec['t0'])}, {scope.value(spec['t_end'])}, "
              f"{scope.value(spec['dt'])}, &{c}_t);",
              f"{ind}if ({c}_out == PC_OUT_ERROR)", f"{ind}    return PC_ERROR;"]
    return lines + _results(outs, c, n, used, id(scope.tracer), ind,
                            [(n, f"{c}_t", "double"), (n + 1, f"{c}_out", "int")])


def _render_propagate(ev, scope, ind, used) -> list:
    _, _, spec, outs = ev
    c, n, lines = scope.fresh("c"), spec["n"], []
    arr = _arrays(spec, ["x"], c, scope, ind, lines, const=False)
    arr.update(_arrays(spec, ["u0", "du", "f_ctx"], c, scope, ind, lines))
    lines.append(f"{ind}const int {c}_out = pc_propagate_linear({spec['f']}, {arr['f_ctx']}, "
                 f"{n}, {c}_x, {scope.value(spec['span'])}, {arr['u0']}, {arr['du']}, "
                 f"{len(spec['u0'])}, {scope.value(spec['steps'])});")
    return lines + _results(outs, c, n, used, id(scope.tracer), ind,
                            [(n, f"{c}_out", "int")])


def _render_linalg(ev, scope, ind, used) -> list:
    _, _, spec, outs = ev
    c, lines = scope.fresh("c"), []
    arr = _arrays(spec, ["args"], c, scope, ind, lines)
    lines += [f"{ind}double {c}_out[{len(outs)}];",
              f"{ind}if ({spec['fn']}({arr['args']}, {c}_out))",
              f"{ind}    err = 1;                    /* numpy.linalg.LinAlgError */"]
    return lines + [f"{ind}const double v{o} = {c}_out[{k}];" for k, o in enumerate(outs)
                    if (id(scope.tracer), o) in used]


#: how the calls recorded by the stand-ins are written (Scope.call_renderers)
CALL_RENDERERS = {"advance_to": _render_advance_to, "propagate": _render_propagate,
                  "linalg": _render_linalg}
