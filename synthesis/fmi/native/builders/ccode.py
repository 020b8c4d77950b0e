"""The network operator's operation table rendered to C, and a law as a C straight-line program.

The operations live in ONE table (:mod:`descent_fmus.models.controllers.operation_table`): each
is an expression of a small language (Python's expression syntax: operands, float literals,
named constants, ``+ - * /``, comparisons, ``x if c else y``, a few math functions).  Python
compiles the expressions into the functions it evaluates; :func:`render` turns the same syntax
trees into C, operation for operation and in the same order, so a compiled law computes the same
IEEE doubles as the Python controller (both call the platform's C math library for ``exp``,
``log``, ``tanh``, ...).  Compile without value-changing optimisations (no ``-ffast-math``; the
native build adds ``-ffp-contract=off`` so that no multiply-add is fused).

:func:`law_c` writes a law as ``law.h`` / ``law.c``: a plain C function (no FMI) holding the
law's graph as a straight-line program -- one statement per arc, the same guards as Python --
usable in flight software on its own and the core of the native law FMU.
"""
from __future__ import annotations

import ast
import re
from functools import lru_cache

from descent_fmus.models.controllers.law_interpreter import MatrixError
from descent_fmus.models.controllers.operation_table import (BINARY_OPS, CONSTANTS, FUNCTIONS,
                                                             HELPERS, UNARY_OPS, finite)

__all__ = ["render", "operations_c", "law_c", "c_double", "c_identifier", "OperationError",
           "interpreter_operations_h"]

#: C names of the language's functions (the helpers are the static ``no_<name>`` functions).
C_FUNCTIONS = {"abs": "fabs", "max": "no_max", "sqrt": "sqrt", "exp": "exp", "log": "log",
               "tanh": "tanh", "cos": "cos", "sin": "sin", "atan": "atan", "cbrt": "cbrt",
               "atan2": "atan2", "remainder": "remainder"}
_C_OPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Gt: ">", ast.GtE: ">=",
          ast.Lt: "<", ast.LtE: "<=", ast.Eq: "==", ast.NotEq: "!="}


class OperationError(ValueError):
    """An operation expression outside the operation language (or an unknown operation)."""


def c_double(v: float) -> str:
    """A C double literal that reads back as exactly ``v`` (Python's shortest round-trip repr)."""
    v = float(v)
    if v != v or v in (float("inf"), float("-inf")):
        raise OperationError(f"no C literal for the non-finite value {v!r}")
    text = repr(v)
    return text if any(ch in text for ch in ".en") else text + ".0"


def c_identifier(name: str) -> str:
    """``name`` as a C identifier (letters, digits and ``_``; not starting with a digit)."""
    out = re.sub(r"[^A-Za-z0-9_]", "_", name)
    if not out or out[0].isdigit():
        out = "_" + out
    return out


def render(expr: str, operands=("z",)) -> str:
    """C expression of one expression of the operation language.

    Raises
    ------
    OperationError
        A construct, name or function outside the language.
    """
    try:
        tree = ast.parse(expr, mode="eval")
    except SyntaxError as exc:
        raise OperationError(f"operation {expr!r} is not an expression: {exc.msg}") from None

    def r(node) -> str:
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                and not isinstance(node.value, bool):
            return c_double(node.value)
        if isinstance(node, ast.Name):
            if node.id in operands:
                return node.id
            if node.id in CONSTANTS:
                return f"NO_{node.id}"
            raise OperationError(f"unknown name {node.id!r} in operation {expr!r}")
        if isinstance(node, ast.BinOp) and type(node.op) in _C_OPS:
            return f"({r(node.left)} {_C_OPS[type(node.op)]} {r(node.right)})"
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            return f"(-{r(node.operand)})"
        if isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in _C_OPS:
            return f"({r(node.left)} {_C_OPS[type(node.ops[0])]} {r(node.comparators[0])})"
        if isinstance(node, ast.IfExp):
            return f"({r(node.test)} ? {r(node.body)} : {r(node.orelse)})"
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and not node.keywords:
            name = node.func.id
            if name in HELPERS:
                cname = f"no_{name}"
            elif name in FUNCTIONS:
                cname = C_FUNCTIONS[name]
            else:
                raise OperationError(f"unknown function {name!r} in operation {expr!r}")
            return f"{cname}({', '.join(r(a) for a in node.args)})"
        raise OperationError(f"{ast.dump(node)[:60]} is outside the operation language "
                             f"(operation {expr!r})")

    return r(tree.body)


@lru_cache(maxsize=None)
def _calls(expr: str) -> frozenset:
    return frozenset({n.func.id for n in ast.walk(ast.parse(expr, mode="eval"))
            if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)})


def _helper_closure(exprs) -> list:
    """Helpers the expressions use, dependencies first."""
    order, seen = [], set()

    def visit(name):
        if name in seen:
            return
        seen.add(name)
        for dep in sorted(_calls(HELPERS[name][1]) & set(HELPERS)):
            visit(dep)
        order.append(name)

    for e in exprs:
        for name in sorted(_calls(e) & set(HELPERS)):
            visit(name)
    return order


def operations_c(unary=(), binary=(), helpers=("finite", "clip", "scale")) -> str:
    """C definitions (static functions) of the given operations and of what they need.

    Unary operation k becomes ``rho<k>(z)``, binary operation k ``chi<k>(a, b)``, a helper
    ``no_<name>(...)``; the named constants become ``NO_<NAME>`` macros.  Made once per set of
    operations in a process (every Pareto law's ``law.c`` asks for a few such sets).
    """
    return _operations_c(tuple(sorted(set(unary))), tuple(sorted(set(binary))), tuple(helpers))


@lru_cache(maxsize=256)
def _operations_c(unary: tuple, binary: tuple, helpers: tuple) -> str:
    ops = []
    for k in sorted(set(unary)):
        if not (0 < k < len(UNARY_OPS)):
            raise OperationError(f"unknown unary operation {k}")
        ops.append((f"rho{k}", "z", UNARY_OPS[k]))
    for k in sorted(set(binary)):
        if not (0 < k < len(BINARY_OPS)):
            raise OperationError(f"unknown binary operation {k}")
        ops.append((f"chi{k}", "a, b", BINARY_OPS[k]))
    exprs = [op.expr for _, _, op in ops] + [HELPERS[h][1] for h in helpers]
    closure = _helper_closure(exprs)
    closure += [h for h in helpers if h not in closure]
    lines = [f"#define NO_{name} " + (f"({c_double(v)})" if v < 0 else c_double(v))
             for name, v in CONSTANTS.items()]
    if "max" in set().union(*(_calls(e) for e in exprs + [HELPERS[h][1] for h in closure])):
        lines.append("static double no_max(double a, double b) { return b > a ? b : a; }  "
                     "/* Python's max(a, b) */")
    for name in closure:
        args, expr = HELPERS[name]
        names = [a.strip() for a in args.split(",")]
        params = ", ".join(f"double {a}" for a in names)
        lines.append(f"static double no_{name}({params})\n{{\n    return {render(expr, names)};"
                     f"\n}}")
    for cname, args, op in ops:
        names = [a.strip() for a in args.split(",")]
        params = ", ".join(f"double {a}" for a in names)
        lines.append(f"/* {op.number} {op.name}: {op.expr} */\n"
                     f"static double {cname}({params})\n{{\n    return {render(op.expr, names)};"
                     f"\n}}")
    return "\n".join(lines) + "\n"


def interpreter_operations_h() -> str:
    """``no_operations.h`` of the native matrix interpreter (``c/no_interp.c``): every operation
    of the table as a static function (:func:`operations_c`), the unit elements ``NO_UNIT[k]``
    of the binary operations, their counts and ``no_arc(NO_ARC_CODE(rho, chi), a, z)`` -- one
    arc, ``finite(chi(a, rho(z)))``, dispatched by one ``switch`` on the pair into which the
    compiler inlines both operations (measured: 1.5x faster than a switch per operation)."""
    nu, nb = len(UNARY_OPS) - 1, len(BINARY_OPS) - 1
    units = ", ".join(["0.0"] + [_c_unit(BINARY_OPS[k].unit) for k in range(1, nb + 1)])
    cases = "".join(f"    case NO_ARC_CODE({r}, {c}): return no_finite(chi{c}(a, rho{r}(z)));\n"
                    for r in range(1, nu + 1) for c in range(1, nb + 1))
    return ("/* no_operations.h -- the network operator's operation table rendered to C (generated "
            "by descent-fmus\n * from models/controllers/operation_table.py; regenerate rather "
            "than edit). */\n#ifndef DESCENT_NO_OPERATIONS_H\n#define DESCENT_NO_OPERATIONS_H\n\n"
            "#include <math.h>\n\n"
            # static inline: a file that includes it for the helpers only is not warned of
            # the operations it does not use
            + operations_c(range(1, nu + 1), range(1, nb + 1)).replace(
                "static double ", "static inline double ") + "\n"
            f"#define NO_N_UNARY {nu}\n#define NO_N_BINARY {nb}\n"
            f"static const double NO_UNIT[NO_N_BINARY + 1] = {{{units}}};\n\n"
            "/* one arc: the unary operation rho on z, then the binary operation chi of the node's "
            "value a\n   and that, clamped */\n"
            "#define NO_ARC_CODE(rho, chi) ((rho) * (NO_N_BINARY + 1) + (chi))\n"
            "static inline double no_arc(int code, double a, double z)\n{\n    switch (code) {\n"
            + cases + "    default: return 0.0;\n    }\n}\n\n#endif\n")


def _sets_first(b: int) -> bool:
    """The node's first arc sets it (atan2, whose unit is NaN: chi(NaN, b) = b)."""
    return BINARY_OPS[b].unit != BINARY_OPS[b].unit


def _c_unit(v: float) -> str:
    """C of a unit element: ``NAN`` (C99) for atan2's "no value yet"."""
    return "NAN" if v != v else c_double(v)


def _reachable(psi, ns: int, outputs) -> set:
    """0-based nodes whose values reach an output node."""
    need = {o - 1 for o in outputs}
    for j in range(len(psi) - 1, -1, -1):
        if j in need and j >= ns and psi[j][j]:
            need.update(i for i in range(j) if psi[i][j])
    return need


def law_c(law, prefix: str = "law", header: str = "law.h", about=()) -> tuple[str, str]:
    """``(law.h, law.c)``: the law as a C function, its graph as a straight-line program.

    ``<prefix>_eval(x, q, x_scale, x_offset, u_min, u_max, u)`` computes
    ``u[k] = clip(z[out_k], u_min[k], u_max[k])`` with source nodes ``x_scale[k] (x[k] -
    x_offset[k])`` and ``q``, every node value through the same guarded operations and the same
    clamp as :func:`models.controllers.law_interpreter.evaluate`; ``<prefix>(x, u)`` does it
    with the law's own parameters (``<PREFIX>_Q`` ...).  Only nodes that reach an output are
    computed (the others cannot change it).  ``about``: lines of the files' opening comment
    (e.g. the readable formula).
    """
    psi = [[int(v) for v in row] for row in law.psi.tolist()]
    nx, nq = law.nx, len(law.q)
    _check_matrix(psi, nx + nq)
    p, P = c_identifier(prefix), c_identifier(prefix).upper()
    need = _reachable(psi, nx + nq, law.outputs)
    comment = _opening_comment(law, about)
    return (_header_text(comment, p, P, nx, nq, len(law.outputs)),
            _source_text(law, psi, need, comment, header, p, P))


def _check_matrix(psi, ns: int) -> None:
    """Raise :class:`MatrixError` for an operation number outside the tables on a computed
    node (``ns`` source nodes): a law built without validation is refused in Python, with the
    node or arc, rather than as C that does not compile."""
    for j in range(ns, len(psi)):
        if not 0 <= psi[j][j] < len(BINARY_OPS):
            raise MatrixError(f"unknown binary operation {psi[j][j]} at node {j + 1}")
        for i in range(j):
            if psi[i][j] and psi[j][j] and not 0 < psi[i][j] < len(UNARY_OPS):
                raise MatrixError(f"unknown unary operation {psi[i][j]} on arc {i + 1}->{j + 1}")


def _straight_line(law, psi, need: set) -> list:
    """The statements of ``<prefix>_eval``: the needed source nodes, every needed node as its
    binary operation's unit folded with one statement per incoming arc (Python's order and
    guards), then the clipped outputs."""
    nx, nq = law.nx, len(law.q)
    ns = nx + nq
    body = []
    for k in range(nx):
        if k in need:
            body.append(f"    const double z{k + 1} = no_finite(no_scale(x[{k}], x_scale[{k}], "
                        f"x_offset[{k}]));  /* {law.input_names[k]} */")
    for k in range(nq):
        if nx + k in need:
            body.append(f"    const double z{nx + k + 1} = no_finite(q[{k}]);  /* q{k + 1} */")
    for j in range(ns, len(psi)):
        if j not in need:
            continue
        b = psi[j][j]
        arcs = [i for i in range(j) if psi[i][j]] if b else []
        if not arcs:
            unit = finite(BINARY_OPS[b].unit) if b else 0.0
            body.append(f"    const double z{j + 1} = {c_double(unit)};  /* node {j + 1}: "
                        f"no arc */")
            continue
        if _sets_first(b):                                # atan2: the first arc sets the node
            i = arcs.pop(0)                               # (chi(NaN, b) = b), no NaN in law.c
            body.append(f"    double z{j + 1} = no_finite(rho{psi[i][j]}(z{i + 1}));  /* node "
                        f"{j + 1}: {BINARY_OPS[b].name}; {UNARY_OPS[psi[i][j]].name} on "
                        f"{i + 1}->{j + 1} */")
        else:
            body.append(f"    double z{j + 1} = {c_double(BINARY_OPS[b].unit)};  /* node "
                        f"{j + 1}: {BINARY_OPS[b].name} */")
        for i in arcs:
            body.append(f"    z{j + 1} = no_finite(chi{b}(z{j + 1}, rho{psi[i][j]}(z{i + 1})));"
                        f"  /* {UNARY_OPS[psi[i][j]].name} on {i + 1}->{j + 1} */")
    for k, o in enumerate(law.outputs):
        body.append(f"    u[{k}] = no_clip(z{o}, u_min[{k}], u_max[{k}]);")
    return body


def _opening_comment(law, about) -> str:
    """The files' opening C comment: the ``about`` lines (default the law's formula), the
    inputs, and a warning that the files are generated."""
    lines = list(about) or [f"u = {law.formula(6)}"]
    lines += [f"inputs x = ({', '.join(law.input_names)}); outputs clipped to their bounds",
              "Generated by descent-fmus from the law's matrix; regenerate rather than edit."]
    return "/* Network-operator law.\n" + "".join(
        f" * {line.replace('*/', '* /')}\n" for line in lines) + " */\n"


def _header_text(comment: str, p: str, P: str, nx: int, nq: int, nu: int) -> str:
    """``law.h``: the sizes, the law's own values and the two functions' prototypes."""
    guard = f"DESCENT_LAW_{P}_H"
    return (comment + f"#ifndef {guard}\n#define {guard}\n\n"
            f"#define {P}_NX {nx}  /* inputs x */\n#define {P}_NQ {nq}  /* parameters q */\n"
            f"#define {P}_NU {nu}  /* outputs u */\n\n"
            f"/* the law's own values */\n"
            f"extern const double {P}_Q[], {P}_X_SCALE[], {P}_X_OFFSET[], {P}_U_MIN[], "
            f"{P}_U_MAX[];\n\n"
            f"/* u[k] = clip(z[out_k], u_min[k], u_max[k]); source node k = x_scale[k] (x[k] - "
            f"x_offset[k]), then q.\n   Never NaN or inf, whatever x holds. */\n"
            f"void {p}_eval(const double *x, const double *q, const double *x_scale, "
            f"const double *x_offset,\n"
            f"    const double *u_min, const double *u_max, double *u);\n\n"
            f"/* the same with the law's own values */\n"
            f"void {p}(const double *x, double *u);\n\n#endif\n")


def _source_text(law, psi, need: set, comment: str, header: str, p: str, P: str) -> str:
    """``law.c``: the operations the needed nodes use, the law's own values, ``<prefix>_eval``
    (the straight-line program) and ``<prefix>``."""
    nx, nq = law.nx, len(law.q)
    ns = nx + nq
    unary = {psi[i][j] for j in need if j >= ns and psi[j][j] for i in range(j) if psi[i][j]}
    # the binary operations of nodes that fold an arc (atan2's first arc only sets its node)
    binary = {psi[j][j] for j in need if j >= ns and psi[j][j]
              and sum(1 for i in range(j) if psi[i][j]) > _sets_first(psi[j][j])}

    def arr(vals):
        return "{" + ", ".join(c_double(v) for v in vals) + "}" if vals else "{0.0}"

    # arguments no needed node reads: cast to void so that the C compiler does not warn
    unused = [name for name, used in (("x", any(k in need for k in range(nx))),
                                      ("q", any(nx + k in need for k in range(nq))),
                                      ("x_scale", any(k in need for k in range(nx))),
                                      ("x_offset", any(k in need for k in range(nx))))
              if not used]
    return (comment + "#include <math.h>\n\n" + f'#include "{header}"\n\n'
            + operations_c(unary, binary) + "\n"
            f"const double {P}_Q[] = {arr(law.q)};\n"
            f"const double {P}_X_SCALE[] = {arr(law.input_scale)};\n"
            f"const double {P}_X_OFFSET[] = {arr(law.input_offset)};\n"
            f"const double {P}_U_MIN[] = {arr([lo for lo, _ in law.bounds])};\n"
            f"const double {P}_U_MAX[] = {arr([hi for _, hi in law.bounds])};\n\n"
            f"void {p}_eval(const double *x, const double *q, const double *x_scale, "
            f"const double *x_offset,\n"
            f"    const double *u_min, const double *u_max, double *u)\n{{\n"
            + "".join(f"    (void){name};\n" for name in unused)
            + "\n".join(_straight_line(law, psi, need)) + "\n}\n\n"
            f"void {p}(const double *x, double *u)\n{{\n"
            f"    {p}_eval(x, {P}_Q, {P}_X_SCALE, {P}_X_OFFSET, {P}_U_MIN, {P}_U_MAX, u);\n}}\n")
