"""A plant FMU class traced into the C functions of its native FMU.

The pythonfmu class itself is instantiated here and its own methods run on traced values:

* **check** -- ``check_parameters()`` with every parameter a traced value: the C function returns
  the message of the ParameterError Python raises, formatted as Python formats it;
* **start** -- ``prepare()`` (the integrator built from the parameters, its initial state and
  its constants): the integrator's numeric attributes become the plant's slots ``S`` and every
  other value computed here that the plant keeps (closures, derived constants) a hidden slot;
* **inputs** -- ``do_step(t, h)`` up to the integrator's ``advance`` (the inputs as the FMU
  clips and replaces them): the arguments of that call;
* **advance** -- the integrator's ``advance`` with those arguments, on the slots; its stepping
  loop is a call of the C runtime (:mod:`.plant_calls`);
* **outputs** -- the FMU's ``_publish`` (if it has one) and the getters of its outputs.

Every pythonfmu plant's ``do_step`` is "inputs, one ``advance``, publish"; that is checked on
every path.  An FMU class with a structural Integer parameter (the telescope's ``n_gyros``)
is traced once per value of it.
"""
from __future__ import annotations

import types
from dataclasses import dataclass

import numpy as np

from descent_fmus.models.integrators import Integrator
from descent_fmus.synthesis.fmi.native.plant_calls import (CALL_RENDERERS, SlotLayout, SlotView,
                                                           Unit, proxy_class, traced_advance_to,
                                                           traced_propagate, using_unit)
from descent_fmus.synthesis.fmi.native.plant_codegen import Scope, render_function
from descent_fmus.synthesis.fmi.native.plant_shims import patched
from descent_fmus.synthesis.fmi.native.plant_trace import (Source, Sym, TraceError, Tracer,
                                                           check_python, explore, operand)

__all__ = ["Interface", "trace_plant", "PlantCode", "interface_of"]

_INTERCEPTORS = {"advance_to": traced_advance_to, "propagate_linear_input": traced_propagate}


@dataclass
class Interface:
    """The FMU's variables as the pythonfmu class declares them (value-reference order) and
    where the native FMU keeps each: ``index[name] = ("r" | "iv", k)``."""

    variables: list           # pythonfmu Fmi2 variables
    index: dict

    def of(self, causality: str):
        return [v for v in self.variables if v.causality.name == causality]


def interface_of(inst) -> Interface:
    inst.vars.materialise()
    variables = [inst.vars[vr] for vr in sorted(inst.vars)]
    index, nr, ni = {}, 0, 0
    for v in variables:
        kind = type(v).__name__
        if kind == "Real":
            index[v.name] = ("r", nr)
            nr += 1
    for v in variables:
        kind = type(v).__name__
        if kind == "Integer":
            index[v.name] = ("iv", ni)
            ni += 1
        elif kind != "Real":
            raise TraceError(f"variable {v.name}: {kind} variables are not supported natively")
    return Interface(variables, index)


class _Recorder:
    """Stands in for the integrator in ``do_step``: records the ``advance`` call."""

    def __init__(self):
        self.calls, self.published = [], 0

    def advance(self, *args):
        self.calls.append(args)

    def __getattr__(self, name):
        raise TraceError(f"do_step reads {name} of the integrator (only advance() is traced)")


def _integrator_attr(inst) -> str:
    names = [k for k, v in vars(inst).items() if isinstance(v, Integrator)]
    if len(names) != 1:
        raise TraceError(f"{type(inst).__name__}: need exactly one integrator attribute, found "
                         f"{names}")
    return names[0]


def _is_number(v) -> bool:
    return isinstance(v, (Sym, float, int)) and not isinstance(v, bool)


def _slot_shape(v):
    if _is_number(v):
        return None
    if isinstance(v, tuple) and v and all(_is_number(e) for e in v):
        return len(v)
    return False


def _syms(obj, owner, found: dict, seen: set) -> None:
    """Traced values of ``owner`` reachable from ``obj`` (objects, containers, closures)."""
    if isinstance(obj, Sym):
        if obj.owner is owner:
            found.setdefault(obj.id, obj)
        return
    if isinstance(obj, (str, bytes, int, float, type(None), type, types.ModuleType)) \
            or id(obj) in seen:
        return
    seen.add(id(obj))
    if isinstance(obj, (tuple, list, set, frozenset)):
        items = obj
    elif isinstance(obj, dict):
        items = obj.values()
    elif isinstance(obj, np.ndarray):
        items = obj.flat if obj.dtype == object else ()
    elif isinstance(obj, types.FunctionType):
        items = [c.cell_contents for c in (obj.__closure__ or ()) if _cell_full(c)]
        items += list(obj.__defaults__ or ())
    elif isinstance(obj, types.MethodType):
        items = (obj.__self__, obj.__func__)
    elif hasattr(obj, "__dict__"):
        items = vars(obj).values()
    else:
        items = ()
    for item in items:
        _syms(item, owner, found, seen)


def _cell_full(cell) -> bool:
    try:
        cell.cell_contents
    except ValueError:
        return False
    return True


class PlantCode:
    """The traced plant: its C unit, interface, slot layout and the start values."""

    def __init__(self, cls, prefix: str, structural: dict | None = None):
        check_python()
        self.cls, self.prefix = cls, prefix
        self.structural = dict(structural or {})
        self.unit = Unit(prefix)
        self.inst = cls(instance_name="native-trace")
        self.iface = interface_of(self.inst)
        self.R, self.I, self.TH = Source("r"), Source("iv"), Source("th")
        self.layout = SlotLayout()
        self.call_shapes = None
        self.integrator = None
        self.publish = hasattr(cls, "_publish")
        self.assumed: dict = {}

    # -- the traced FMU instance ---------------------------------------------------------------
    def _bind(self, inst) -> None:
        """Every parameter and input of ``inst`` a traced value (structural ones fixed)."""
        for v in self.iface.variables:
            if v.causality.name not in ("parameter", "input"):
                continue
            space, k = self.iface.index[v.name]
            if v.name in self.structural:
                v.setter(self.structural[v.name])
            elif space == "r":
                v.setter(self.R.sym(k))
            else:
                object.__setattr__(inst, v.name, self.I.sym(k))

    def _scope(self, tracer, spaces, persisted=True) -> Scope:
        scope = Scope(tracer, sources={self.R: "r", self.I: "iv", self.TH: "th"},
                      persisted=self.layout.persisted() if persisted else {},
                      spaces=spaces, allow_ctx=False)
        scope.call_renderers = CALL_RENDERERS
        return scope

    def _function(self, stem, signature, params, tree, scope, leaf) -> str:
        text = render_function(signature.replace("@NAME@", f"{self.prefix}_{stem}"), tree,
                               scope, leaf, params)
        self.unit.functions.append((f"{self.prefix}_{stem}", text, False))
        return f"{self.prefix}_{stem}"

    @property
    def call_size(self) -> int:
        """Values passed from the inputs phase to ``advance``."""
        return sum(1 if n is None else n for n in self.call_shapes or ())

    # -- phases --------------------------------------------------------------------------------
    def trace_check(self) -> str:
        tracer = Tracer(f"{self.prefix} check")
        tree = explore(tracer, lambda: self.inst.check_parameters())
        # every later phase runs only with parameters that passed the check (fmi2_cs.c prepares
        # after model_check, steps after a successful initialisation): its conditions hold there
        self.assumed = tree.conditions(lambda result: result[0] == "return")
        return self._function("check", "int @NAME@(const double *r, const int *iv, char *msg)",
                               ("r", "iv", "msg"), tree, self._scope(tracer, {}, False),
                               lambda value, scope, ind: [f"{ind}return PC_OK;"])

    def trace_start(self) -> str:
        tracer = Tracer(f"{self.prefix} start", self.assumed)
        inst = self.inst
        before = dict(vars(inst))

        def body():
            if self.publish:
                inst._publish = lambda: None
            try:
                inst.prepare()
            finally:
                vars(inst).pop("_publish", None)
            attr = _integrator_attr(inst)
            changed = {k: v for k, v in vars(inst).items()
                       if k != attr and (k not in before or before[k] is not v)}
            return getattr(inst, attr), changed, attr

        tree = explore(tracer, body)
        leaves = [n for n in tree.leaves() if n.result[0] == "return"]
        if not leaves:
            raise TraceError(f"{self.prefix}: prepare() fails on every path")
        self._layout(tracer, [n.result[1] for n in leaves])
        for node in leaves:
            node.result = ("return", self._start_writes(tracer, *node.result[1][:2]))
        return self._function("start", "int @NAME@(const double *r, const int *iv, double *S, "
                              "char *msg)", ("r", "iv", "S", "msg"), tree,
                              self._scope(tracer, {}, False), _writes_leaf("S"))

    def _layout(self, tracer, results) -> None:
        """Slots from the integrators the start paths built (see :class:`SlotLayout`)."""
        self.integrator, self.instance_state, self.attr = results[0]
        hidden = None
        for ig, changed, _ in results:
            for name, v in vars(ig).items():
                shape = _slot_shape(v)
                if shape is not False:
                    self.layout.add_attr(name, shape)
            found: dict = {}
            seen: set = set()
            _syms([v for k, v in vars(ig).items() if k not in self.layout.attrs], tracer,
                  found, seen)
            _syms(list(changed.values()), tracer, found, seen)
            if hidden is not None and set(found) != set(hidden):
                raise TraceError(f"{self.prefix}: the start paths keep different values")
            hidden = found
        for sym in sorted(hidden.values(), key=lambda s: s.id):
            self.layout.add_hidden(sym)

    def _start_writes(self, tracer, ig, changed) -> list:
        writes = []
        for name, (start, n) in self.layout.attrs.items():
            if name not in vars(ig):
                raise TraceError(f"{self.prefix}: a start path leaves {name} unset")
            v = getattr(ig, name)
            writes += [(start, v)] if n is None else [(start + j, e) for j, e in enumerate(v)]
        for (owner, id_), k in self.layout.hidden.items():
            writes.append((k, Sym(tracer, id_)))
        return writes

    def _proxy(self, tracer):
        """A fresh integrator like the start's, its slot attributes read from ``S``."""
        ig = object.__new__(proxy_class(type(self.integrator)))
        ig.__dict__.update(vars(self.integrator))
        view = SlotView(ig, self.layout, tracer)
        view.load()
        tracer.hooks["slots"] = view
        return ig

    def trace_inputs(self) -> str:
        tracer = Tracer(f"{self.prefix} inputs", self.assumed)
        inst = self.inst
        t, h = self.TH.sym(0), self.TH.sym(1)
        do_step = type(inst).do_step
        do_step = getattr(do_step, "__wrapped__", do_step)

        def body():
            rec = _Recorder()
            vars(inst)[self.attr] = rec
            if self.publish:
                inst._publish = lambda: rec.__dict__.update(published=rec.published + 1)
            try:
                do_step(inst, t, h)
            finally:
                vars(inst).pop("_publish", None)
            if len(rec.calls) != 1 or rec.published != (1 if self.publish else 0):
                raise TraceError(f"{self.prefix}: do_step is not 'inputs, advance, publish'")
            shapes = [len(a) if isinstance(a, tuple) else None for a in rec.calls[0]]
            if self.call_shapes not in (None, shapes):
                raise TraceError(f"{self.prefix}: advance() is called with other shapes")
            self.call_shapes = shapes
            flat = [e for a in rec.calls[0] for e in (a if isinstance(a, tuple) else (a,))]
            return list(enumerate(flat))

        tree = explore(tracer, body)
        return self._function("inputs", "int @NAME@(const double *r, const int *iv, "
                              "const double *th, double *call)", ("r", "iv", "th", "call"),
                              tree, self._scope(tracer, {}), _writes_leaf("call"))

    def trace_advance(self) -> str:
        tracer = Tracer(f"{self.prefix} advance", self.assumed)

        def body():
            ig = self._proxy(tracer)
            k, args = 0, []
            for n in self.call_shapes:
                if n is None:
                    args.append(tracer.load("call", k))
                    k += 1
                else:
                    args.append(tuple(tracer.load("call", k + j) for j in range(n)))
                    k += n
            ig.advance(*args)
            return tracer.hooks["slots"].changed()

        tree = explore(tracer, body)
        return self._function("advance", "int @NAME@(const double *r, const int *iv, double *S, "
                              "const double *call)", ("r", "iv", "S", "call"), tree,
                              self._scope(tracer, {"S": "S", "call": "call"}),
                              _writes_leaf("S"))

    def trace_outputs(self) -> str:
        tracer = Tracer(f"{self.prefix} outputs", self.assumed)
        inst, outputs = self.inst, self.iface.of("output")

        def body():
            ig = self._proxy(tracer)
            vars(inst).update(self.instance_state)
            vars(inst)[self.attr] = ig
            if self.publish:
                inst._publish()
            for v in outputs:                   # each output stored as soon as it is known
                tracer.store(*self.iface.index[v.name], v.getter())

        scope = self._scope(tracer, {"S": "S", "r": "r", "iv": "iv"})
        scope.casts = {"iv": "(int)"}
        tree = explore(tracer, body)
        return self._function("outputs", "int @NAME@(double *r, int *iv, const double *S)",
                              ("r", "iv", "S"), tree, scope,
                              lambda value, scope, ind: [f"{ind}return PC_OK;"])

    def trace_all(self) -> "PlantCode":
        with patched(_INTERCEPTORS), using_unit(self.unit):
            self._bind(self.inst)
            self.trace_check()
            self.trace_start()
            self.trace_inputs()
            self.trace_advance()
            self.trace_outputs()
        return self


def _writes_leaf(space: str):
    def leaf(value, scope, ind):
        return [f"{ind}{space}[{k}] = {scope.value(operand(v))};" for k, v in value] + \
            [f"{ind}return PC_OK;"]
    return leaf


def trace_plant(cls, prefix: str, structural: dict | None = None) -> PlantCode:
    """Trace the pythonfmu plant class ``cls`` (see the module docstring)."""
    return PlantCode(cls, prefix, structural).trace_all()
