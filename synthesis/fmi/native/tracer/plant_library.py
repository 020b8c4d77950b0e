"""A plant's model functions as plain C functions with stable names, for other C code.

The phase functions of a native plant (:mod:`.plant_phases`) work on the FMU's value arrays;
C code of its own -- an on-board predictor, a C master, the native twin of a guidance
controller -- also wants the model's functions themselves: the right-hand side, the altitude,
the loads.  :func:`export_functions` traces the functions a :class:`PlantSpec` lists (any
function of ``models/``, run on traced values under the same stand-ins as the plant) into
``int <prefix>_<name>(<arguments>, double *out)``: a vector argument is ``const double *``,
a number ``double``, a ``Params`` dataclass ``const double *`` of its fields in their order;
the result (a number or a tuple) is written to ``out``.  The function returns ``PC_OK`` or
``PC_ERROR`` where Python raises.
"""
from __future__ import annotations

import dataclasses
import importlib
import inspect

from descent_fmus.synthesis.fmi.native.tracer.plant_codegen import Scope, render_function
from descent_fmus.synthesis.fmi.native.tracer.plant_shims import patched
from descent_fmus.synthesis.fmi.native.tracer.plant_trace import (TraceError, Tracer, explore,
                                                           operand)

__all__ = ["export_functions", "params_macros", "resolve"]


def resolve(path: str):
    """``"module:qualname"`` under ``descent_fmus.models`` -> the function."""
    module, qualname = path.split(":")
    obj = importlib.import_module(f"descent_fmus.models.{module}")
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


def _argument(tracer, name: str, kind):
    """The traced argument ``name`` of ``kind`` (1: a number, n > 1: n values, a Params class)
    and its C declaration."""
    if kind == 1:
        return tracer.load(name, None), f"double {name}"
    if isinstance(kind, int):
        return tuple(tracer.load(name, j) for j in range(kind)), f"const double *{name}"
    values = {f.name: tracer.load(name, j) for j, f in enumerate(dataclasses.fields(kind))}
    return kind(**values), f"const double *{name}"


def _export(prefix: str, name: str, path: str, kinds: dict) -> str:
    fn = resolve(path)
    names = list(inspect.signature(fn).parameters)
    if names != list(kinds):
        raise TraceError(f"{path}: arguments {names}, declared {list(kinds)}")
    module = path.split(":")[0]
    kinds = {k: resolve(f"{module}:{v}") if isinstance(v, str) else v for k, v in kinds.items()}
    tracer = Tracer(f"{prefix}_{name}")
    decls = []

    def body():
        args = []
        decls.clear()
        for arg, kind in kinds.items():
            value, decl = _argument(tracer, arg, kind)
            args.append(value)
            decls.append(decl)
        out = fn(*args)
        return list(out) if isinstance(out, tuple) else [out]

    with patched():
        tree = explore(tracer, body)
    scope = Scope(tracer, spaces={k: k for k in kinds}, allow_ctx=False)

    def leaf(value, scope, ind):
        return [f"{ind}out[{k}] = {scope.value(operand(v))};" for k, v in enumerate(value)] + \
            [f"{ind}return PC_OK;"]

    signature = f"int {prefix}_{name}({', '.join(decls)}, double *out)"
    return render_function(signature, tree, scope, leaf, list(kinds) + ["out"])


def export_functions(prefix: str, exports: dict) -> list:
    """``(name, text)`` of the exported functions ``exports`` (C name -> ("module:qualname",
    {argument: kind})); a kind given as a name is that Params class of the module."""
    return [(f"{prefix}_{name}", _export(prefix, name, path, kinds))
            for name, (path, kinds) in exports.items()]


def params_macros(prefix: str, exports: dict) -> list:
    """``#define <PREFIX>_P_<field> k``: the order of the fields of every Params argument."""
    lines, done = [], set()
    for path, kinds in exports.values():
        module = path.split(":")[0]
        for kind in kinds.values():
            if isinstance(kind, str) and kind not in done:
                done.add(kind)
                lines.append(f"/* {kind} as an array: its fields in this order */")
                lines += [f"#define {prefix.upper()}_P_{f.name} {k}" for k, f in
                          enumerate(dataclasses.fields(resolve(f"{module}:{kind}")))]
    return lines
