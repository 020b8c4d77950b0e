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
from descent_fmus.synthesis.fmi.native.tracer.plant_calls import (CALL_RENDERERS, SlotLayout, SlotView,
                                                           Unit, proxy_class, traced_advance_to,
                                                           traced_propagate, using_unit)
from descent_fmus.synthesis.fmi.native.tracer.plant_codegen import Scope, render_function
from descent_fmus.synthesis.fmi.native.tracer.plant_numpy import TRACED_NUMPY
from descent_fmus.synthesis.fmi.native.tracer.plant_shims import own_modules, patched
from descent_fmus.synthesis.fmi.native.tracer.plant_trace import (Source, Sym, TraceError, Tracer,
                                                           check_python, explore, operand)

__all__ = ["Interface", "trace_plant", "PlantCode", "interface_of"]

#: names swapped into the model modules besides math/float/sum (plant_shims.patched)
_INTERCEPTORS = {"advance_to": traced_advance_to, "propagate_linear_input": traced_propagate,
                 "np": TRACED_NUMPY}


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


def _syms(obj, owner, found: list, seen: set, pos=()) -> None:
    """``(position, value)`` of the traced values of ``owner`` reachable from ``obj`` (objects,
    containers, closures), in a fixed order; a position names the way there."""
    if isinstance(obj, Sym):
        if obj.owner is owner:
            found.append((pos, obj))
        return
    if isinstance(obj, (str, bytes, int, float, type(None), type, types.ModuleType)) \
            or id(obj) in seen:
        return
    seen.add(id(obj))
    if isinstance(obj, (tuple, list)):
        items = enumerate(obj)
    elif isinstance(obj, dict):
        items = obj.items()
    elif isinstance(obj, np.ndarray):
        items = enumerate(obj.flat if obj.dtype == object else ())
    elif isinstance(obj, types.FunctionType):
        items = [(f"cell{k}", c.cell_contents) for k, c in enumerate(obj.__closure__ or ())
                 if _cell_full(c)]
        items += [(f"default{k}", v) for k, v in enumerate(obj.__defaults__ or ())]
    elif isinstance(obj, types.MethodType):
        items = (("self", obj.__self__), ("func", obj.__func__))
    elif hasattr(obj, "__dict__"):
        items = vars(obj).items()
    else:
        items = ()
    for key, item in items:
        _syms(item, owner, found, seen, pos + (key,))


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
        self.R, self.I, self.TH = Source("r"), Source("iv", "i"), Source("th")
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
        """Slots from the integrators the start paths built (see :class:`SlotLayout`): their
        numeric attributes, then every other value computed at the start that they keep, by its
        position (the paths build the same objects, their values may differ in identity)."""
        self.integrator, self.instance_state, self.attr = results[0]
        self._hidden = {}
        layout = None
        for ig, changed, _ in results:
            for name, v in vars(ig).items():
                shape = _slot_shape(v)
                if shape is not False:
                    self.layout.add_attr(name, shape)
            found: list = []
            seen: set = set()
            _syms({k: v for k, v in vars(ig).items() if k not in self.layout.attrs}, tracer,
                  found, seen, ("integrator",))
            _syms(changed, tracer, found, seen, ("fmu",))
            if layout is not None and [p for p, _ in found] != layout:
                raise TraceError(f"{self.prefix}: the start paths keep different objects")
            layout = [p for p, _ in found]
            self._hidden[id(ig)] = found
        for pos, sym in self._hidden[id(self.integrator)]:
            self.layout.add_hidden(sym)
        # each position's slot: that of the template's value there
        self._slot_of = [self.layout.hidden[(sym.owner, sym.id)]
                         for _, sym in self._hidden[id(self.integrator)]]

    def _start_writes(self, tracer, ig, changed) -> list:
        writes = []
        for name, (start, n) in self.layout.attrs.items():
            if name not in vars(ig):
                raise TraceError(f"{self.prefix}: a start path leaves {name} unset")
            v = getattr(ig, name)
            writes += [(start, v)] if n is None else [(start + j, e) for j, e in enumerate(v)]
        written = set()
        for k, (_, sym) in zip(self._slot_of, self._hidden[id(ig)]):
            if k not in written:
                writes.append((k, sym))
                written.add(k)
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
        with patched(_INTERCEPTORS, own_modules(self.cls)), using_unit(self.unit):
            self._bind(self.inst)
            self.trace_check()
            self.trace_start()
            self.trace_inputs()
            self.trace_advance()
            self.trace_outputs()
        return self


#: the phase functions' signatures (name -> (signature, arguments))
PHASES = {"check": ("int @NAME@(const double *r, const int *iv, char *msg)", "r, iv, msg"),
          "start": ("int @NAME@(const double *r, const int *iv, double *S, char *msg)",
                    "r, iv, S, msg"),
          "inputs": ("int @NAME@(const double *r, const int *iv, const double *th, "
                     "double *call)", "r, iv, th, call"),
          "advance": ("int @NAME@(const double *r, const int *iv, double *S, "
                      "const double *call)", "r, iv, S, call"),
          "outputs": ("int @NAME@(double *r, int *iv, const double *S)", "r, iv, S")}


def dispatch_functions(cls, prefix: str, name: str, variants: dict) -> list:
    """``(name, text)`` of the plant's phase functions that dispatch on the structural Integer
    parameter ``name`` to the traced ``variants`` (value -> PlantCode).  The check is traced
    with the parameter as an Integer: the class's own checks of it, then -- where Python needs
    its value -- the variant's check."""
    code = PlantCode(cls, prefix)
    space, k = code.iface.index[name]

    def switch(phase, ind):
        lines = [f"{ind}switch (iv[{k}]) {{"]
        lines += [f"{ind}case {v}:\n{ind}    return {c.prefix}_{phase}({PHASES[phase][1]});"
                  for v, c in variants.items()]
        return lines + [f"{ind}}}", f"{ind}return PC_ERROR;"]

    out = []
    with patched(_INTERCEPTORS, own_modules(cls)), using_unit(code.unit):
        code._bind(code.inst)
        tracer = Tracer(f"{prefix} check")
        tracer.hooks["dispatch"] = True
        tree = explore(tracer, lambda: code.inst.check_parameters())
        text = render_function(PHASES["check"][0].replace("@NAME@", f"{prefix}_check"), tree,
                               code._scope(tracer, {}, False),
                               lambda value, scope, ind: switch("check", ind), ("r", "iv", "msg"))
        out.append((f"{prefix}_check", text))
    for phase in ("start", "inputs", "advance", "outputs"):
        head = PHASES[phase][0].replace("@NAME@", f"{prefix}_{phase}")
        out.append((f"{prefix}_{phase}", "\n".join([head, "{"] + switch(phase, "    ") + ["}"])
                    + "\n"))
    return out


def _writes_leaf(space: str):
    def leaf(value, scope, ind):
        return [f"{ind}{space}[{k}] = {scope.value(operand(v))};" for k, v in value] + \
            [f"{ind}return PC_OK;"]
    return leaf


def trace_plant(cls, prefix: str, structural: dict | None = None) -> PlantCode:
    """Trace the pythonfmu plant class ``cls`` (see the module docstring)."""
    return PlantCode(cls, prefix, structural).trace_all()
