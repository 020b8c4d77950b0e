"""The network operator: evaluation of a control law stored as an upper-triangular integer matrix.

A mathematical expression is a directed acyclic graph on nodes ``1..L`` stored as ``Psi`` (L x L):
the diagonal ``psi[i][i]`` is the number of the *binary* operation at node ``i``; an off-diagonal
``psi[i][j]`` (``i < j``) the number of the *unary* operation on the arc ``i -> j``; 0 = nothing.
Source nodes ``1..nx`` hold the inputs, nodes ``nx+1..nx+nq`` the parameters q.

Evaluation (Diveev & Sofronova 2007): a non-source node starts at the unit element of its
binary operation; for ``i = 1..L-1`` and every ``j > i`` with ``psi[i][j] != 0`` and
``psi[j][j] != 0``: ``z_j <- chi_{psi_jj}(z_j, rho_{psi_ij}(z_i))``.  The outputs are the values of
the output nodes (the last node by default).  ``atan2`` has no unit element: its "unit" is NaN
(no value yet) and its first incoming arc sets the node, later arcs fold ``a <- atan2(a, b)``;
a node without incoming arcs holds ``finite(unit)`` (0 for atan2, the unit for the others).

Every operation is overflow-safe: values are clamped to ``[-BIG, BIG]`` (BIG = 1e8, the authors'
"infinity") after every operation, and a NaN becomes 0, so the law never returns NaN or inf.

This module is the one implementation of the operations and of the evaluation; it serves the
:class:`NetworkOperatorController` FMU and ``synthesis.methods.law.NetworkOperator``.

References
----------
A.I. Diveev, E.Yu. Shmalko (reentry paper), section "Синтез"; A.I. Diveev, E.A. Sofronova, "The network operator
method in control problems", Vestnik RUDN, 2007, no. 4.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from pythonfmu import Fmi2Causality, Fmi2Variability, Integer

from descent_fmus.models.fmu_support import ParameterError, SlaveBase

__all__ = ["BIG", "UNARY", "BINARY", "UNIT", "UNARY_NAMES", "BINARY_NAMES", "compile_law",
           "evaluate", "NetworkOperatorController", "L_MAX", "NX_MAX", "NQ_MAX", "NU_MAX",
           "MatrixError", "Operation", "UNARY_OPS", "BINARY_OPS", "CONSTANTS", "HELPERS",
           "FUNCTIONS", "python_function", "finite", "DESCRIPTIONS", "operation_numbers",
           "OperationNameError"]

#: The authors' "infinity": every node value is clamped to [-BIG, BIG].
BIG = 1e8
_EPS5 = 1e-7     # epsilon of rho5 (Diveev & Shmalko)
_EPS = 1e-8      # epsilon of the wider operation set
_LN_BIG = math.log(BIG)

# Capacity of the generic controller FMU (fixed at build time; room for the paper's 16-node
# law plus synthesis headroom: L = 16-32 nodes, 2-9 parameters).
L_MAX = 32
NX_MAX = 8
NQ_MAX = 16
NU_MAX = 4


class MatrixError(ValueError):
    """A network-operator matrix or its node map is malformed."""


# -- the operations: one table, rendered to Python here and to C by synthesis.fmi.native ----------
#
# Every operation is ONE expression in a small language -- Python's expression syntax limited
# to the operand names (z; a, b), float literals, the named constants of CONSTANTS, + - * /,
# comparisons, ``x if c else y`` and the functions of FUNCTIONS -- so that the Python
# evaluation below and the C code of a native law FMU are the same IEEE operations in the same
# order: the two give bitwise equal results (both call the platform's C math library).

#: Named constants of the operation language (values as Python computes them).
CONSTANTS = {"BIG": BIG, "EPS5": _EPS5, "EPS": _EPS, "LN_BIG": _LN_BIG,
             "LOG_EPS": math.log(_EPS), "PI": math.pi, "TWO_PI": 2.0 * math.pi}
#: Helper functions of the operation language, themselves expressions: name -> (operands,
#: expr).  ``finite`` is the clamp after every operation (written inline in :func:`evaluate`),
#: ``clip`` the output bounds, ``scale`` the input scaling.
HELPERS = {
    "sgn": ("z", "1.0 if z >= 0.0 else -1.0"),           # the authors' sign: 1 for z >= 0
    "gexp": ("z", "BIG if z > LN_BIG else exp(z)"),       # e^z, guarded
    "finite": ("v", "BIG if v > BIG else (-BIG if v < -BIG else (v if v == v else 0.0))"),
    "clip": ("v, lo, hi", "lo if v < lo else (hi if v > hi else v)"),
    "scale": ("v, s, o", "s * (v - o)"),
}
#: Functions of the C math library the language may call (Python: ``math`` and ``abs``/``max``;
#: ``max(x, y)`` is Python's builtin: y if y > x else x).  Each gives the same double in Python
#: and C: ``math.atan2`` is libm's atan2 (CPython answers y = 0 and infinities itself, as C99
#: Annex F does), ``math.remainder`` is CPython's own but IEEE's remainder is exact.  Not
#: ``math.hypot``: CPython's differs from libm's (hypot is written with ``sqrt``).
FUNCTIONS = ("abs", "max", "sqrt", "exp", "log", "tanh", "cos", "sin", "atan", "cbrt", "atan2",
             "remainder")


@dataclass(frozen=True)
class Operation:
    """One operation of the network operator.

    Attributes
    ----------
    number : int
        Its number in the matrix (the reentry paper's numbering, then the wider set).
    name : str
        Short name (readable formulas, C function names).
    expr : str
        The guarded operation in the operation language: operand ``z`` (unary) or ``a, b``
        (binary: ``a`` the node's value so far, ``b`` the arc's).
    text : str
        Template of :meth:`NetworkOperator.formula` (unary: ``{}`` is the operand).
    unit : float or None
        Binary operations: the node's initial value (the unit element).
    sym : str
        The operation without its guards in SymPy's syntax (operands as in ``expr``) when it is
        plain algebra or a SymPy function (readable formulas simplify through it); empty: the
        operation stays a named function ``name(...)`` in readable formulas.
    latex : str
        LaTeX of a named function, ``#`` standing for the operand (default
        ``\\operatorname{name}(#)``).
    first : str
        Binary operations: the node's value after its first incoming arc ``b`` (the fold from
        the unit, ``chi(unit, b)``, without guards) in SymPy's syntax: ``b`` for all but hypot.
    """

    number: int
    name: str
    expr: str
    text: str = ""
    unit: float | None = None
    sym: str = ""
    latex: str = ""
    first: str = "b"


_UNARY_OPS = (
    Operation(1, "id", "z", "{}", sym="z"),
    Operation(2, "sq", "z * z", "({})^2", sym="z**2"),
    Operation(3, "neg", "-z", "-({})", sym="-z"),
    Operation(4, "ssqrt", "sgn(z) * sqrt(abs(z))", "sqrt~({})"),
    Operation(5, "inv", "1.0 / z if abs(z) > EPS5 else sgn(z) / EPS5", "inv({})"),
    Operation(6, "exp", "gexp(z)", "exp({})", latex=r"e^{#}"),
    Operation(7, "lnabs", "log(abs(z)) if abs(z) > EPS else LOG_EPS", "ln|{}|",
              latex=r"\ln\left|#\right|"),
    Operation(8, "sig2", "tanh(0.5 * z)", "sig2({})", sym="tanh(z/2)"),  # (1-e^-z)/(1+e^-z)
    Operation(9, "heaviside", "1.0 if z >= 0.0 else 0.0", "heaviside({})",
              latex=r"\theta\left(#\right)"),
    Operation(10, "sgn", "sgn(z)", "sgn({})", latex=r"\operatorname{sgn}\left(#\right)"),
    Operation(11, "cos", "cos(z)", "cos({})", sym="cos(z)"),
    Operation(12, "sin", "sin(z)", "sin({})", sym="sin(z)"),
    Operation(13, "atan", "atan(z)", "atan({})", sym="atan(z)"),
    Operation(14, "cube", "z * z * z", "({})^3", sym="z**3"),
    Operation(15, "cbrt", "cbrt(z)", "cbrt({})", latex=r"\sqrt[3]{#}"),
    Operation(16, "clip1", "1.0 if z > 1.0 else (-1.0 if z < -1.0 else z)", "clip1({})"),
    Operation(17, "sgnlog", "sgn(z) * log(abs(z) + 1.0)", "sgnlog({})"),
    Operation(18, "sgnexp1", "sgn(z) * (gexp(abs(z)) - 1.0)", "sgnexp1({})"),
    Operation(19, "sgnexpm", "sgn(z) * exp(-abs(z))", "sgnexpm({})"),
    Operation(20, "half", "0.5 * z", "({})/2", sym="z/2"),
    Operation(21, "twice", "2.0 * z", "2*({})", sym="2*z"),
    Operation(22, "sat", "sgn(z) * (1.0 - exp(-abs(z)))", "sat({})"),
    Operation(23, "cubic", "z - z * z * z", "cubic({})", sym="z - z**3"),
    Operation(24, "logistic", "0.5 * (1.0 + tanh(0.5 * z))", "logistic({})",
              sym="(1 + tanh(z/2))/2"),
    Operation(25, "pos", "1.0 if z > 0.0 else 0.0", "pos({})"),
    Operation(26, "dead", "sgn(z) if abs(z) >= 0.01 else 0.0", "dead({})"),
    Operation(27, "circ", "sgn(z) * (1.0 - sqrt(1.0 - z * z)) if abs(z) < 1.0 else sgn(z)",
              "circ({})"),
    Operation(28, "gauss", "z * (1.0 - exp(-z * z))", "gauss({})", sym="z*(1 - exp(-z**2))"),
    # the angle z wrapped to (-pi, pi]: IEEE remainder is exact, so the same double in C
    Operation(29, "wrap", "PI if remainder(z, TWO_PI) == -PI else remainder(z, TWO_PI)",
              "wrap({})", latex=r"\operatorname{wrap}\left(#\right)"),
)
#: Binary operations (unit elements: -inf/+inf of max/min are -BIG/+BIG).
_BINARY_OPS = (
    Operation(1, "add", "a + b", "+", 0.0, sym="a + b"),
    Operation(2, "mul", "a * b", "*", 1.0, sym="a*b"),
    Operation(3, "max", "a if a >= b else b", "max", -BIG, latex=r"\max\left(#\right)"),
    Operation(4, "min", "a if a <= b else b", "min", BIG, latex=r"\min\left(#\right)"),
    Operation(5, "or", "a + b - a * b", "or", 0.0, sym="a + b - a*b"),
    Operation(6, "norm", "sgn(a + b) * sqrt(a * a + b * b)", "norm", 0.0),
    Operation(7, "sabs", "sgn(a + b) * (abs(a) + abs(b))", "sabs", 0.0),
    Operation(8, "smax", "sgn(a + b) * max(abs(a), abs(b))", "smax", 0.0),
    # [choice] atan2 has no unit: NaN (no value yet), the first arc sets the node, later arcs
    # fold a <- atan2(a, b) (docs/methods/network_operator.md)
    Operation(9, "atan2", "b if a != a else atan2(a, b)", "atan2", math.nan),
    # node values are clamped to 1e8 and arcs stay below 1e24: a*a + b*b cannot overflow
    Operation(10, "hypot", "sqrt(a * a + b * b)", "hypot", 0.0, first="Abs(b)"),
)
#: Unary operations rho_k and binary operations chi_k by number (index 0 unused).
UNARY_OPS = (None,) + _UNARY_OPS
BINARY_OPS = (None,) + _BINARY_OPS


def _python_namespace() -> dict:
    ns = {"__builtins__": {}, "abs": abs, "max": max}
    ns.update((f, getattr(math, f)) for f in FUNCTIONS if f not in ("abs", "max"))
    ns.update(CONSTANTS)
    for name, (arg, expr) in HELPERS.items():
        ns[name] = eval(f"lambda {arg}: {expr}", ns)      # noqa: S307 (the table above)
    return ns


_NS = _python_namespace()
_sgn = _NS["sgn"]
_exp = _NS["gexp"]


def python_function(op: Operation, binary: bool = False):
    """The Python function of an operation (its expression compiled once)."""
    return eval(f"lambda {'a, b' if binary else 'z'}: {op.expr}", _NS)  # noqa: S307


#: Unary operations rho_k by number (index 0 unused).
UNARY = [None] + [python_function(op) for op in _UNARY_OPS]
UNARY_NAMES = [None] + [op.text for op in _UNARY_OPS]
#: Binary operations chi_k (index 0 unused): 1 +, 2 *, 3 max, 4 min, then the wider set.
BINARY = [None] + [python_function(op, binary=True) for op in _BINARY_OPS]
BINARY_NAMES = [None] + [op.text for op in _BINARY_OPS]
#: Unit elements of the binary operations (-inf/+inf of max/min are -BIG/+BIG; atan2: NaN).
UNIT = [None] + [op.unit for op in _BINARY_OPS]
#: A value as the law holds it: NaN -> 0, clamped to [-BIG, BIG].
finite = _NS["finite"]


class OperationNameError(ValueError):
    """An operation named or numbered outside the tables."""


def operation_numbers(items, binary: bool = False) -> tuple:
    """The operation numbers of ``items`` -- numbers or names (``"atan2"``, ``"wrap"``; the
    ``name`` of :class:`Operation`) -- of the unary (or binary) table, in their order.

    Raises
    ------
    OperationNameError
        An unknown name or number (the message lists the valid ones), or an empty list.
    """
    ops = _BINARY_OPS if binary else _UNARY_OPS
    kind = "binary" if binary else "unary"
    by_name = {op.name: op.number for op in ops}
    if isinstance(items, (str, int)):
        items = [items]
    out = []
    for v in items:
        if isinstance(v, str) and v.strip().isdigit():
            v = int(v)
        if isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= len(ops):
            out.append(v)
        elif isinstance(v, str) and v.strip() in by_name:
            out.append(by_name[v.strip()])
        else:
            raise OperationNameError(f"unknown {kind} operation {v!r}; valid: "
                                     + ", ".join(f"{op.number} {op.name}" for op in ops))
    if not out:
        raise OperationNameError(f"give at least one {kind} operation")
    return tuple(out)


def compile_law(psi, nx: int, nq: int, outputs):
    """Check a matrix and turn it into an arc program for :func:`evaluate`.

    Parameters
    ----------
    psi : sequence of sequences of int
        Square upper-triangular matrix (L x L).
    nx, nq : int
        Number of input and parameter source nodes (nodes ``1..nx`` and ``nx+1..nx+nq``).
    outputs : sequence of int
        1-based node numbers whose values are the outputs.

    Returns
    -------
    tuple
        ``(L, init, arcs, outputs0)``: node count, initial node values for non-source nodes
        (``None`` for sources), the arc list ``(i, j, rho, chi)`` in evaluation order (0-based) and
        the 0-based output nodes.

    Raises
    ------
    MatrixError
        Not square, not upper-triangular, unknown operation number, an arc into a source node,
        an operation on a source node, or an output node out of range.
    """
    L = len(psi)
    rows = [list(r) for r in psi]
    for i, r in enumerate(rows):
        if len(r) != L:
            raise MatrixError(f"matrix is not square: row {i + 1} has {len(r)} entries, "
                              f"expected {L}")
    ns = nx + nq
    if nx < 0 or nq < 0 or ns > L:
        raise MatrixError(f"{nx} inputs + {nq} parameters do not fit in a {L}-node matrix")
    init = [None] * L
    for i in range(L):
        for j in range(L):
            v = rows[i][j]
            if v != int(v):
                raise MatrixError(f"psi[{i + 1},{j + 1}] = {v!r} is not an integer")
            v = int(v)
            if j < i and v != 0:
                raise MatrixError(f"matrix is not upper-triangular: psi[{i + 1},{j + 1}] = {v} "
                                  f"below the diagonal")
            if i == j:
                if not 0 <= v < len(BINARY):
                    raise MatrixError(f"unknown binary operation {v} at node {i + 1} "
                                      f"(psi[{i + 1},{i + 1}]); valid: 1..{len(BINARY) - 1}")
                if i < ns and v != 0:
                    raise MatrixError(f"node {i + 1} is a source node (input or parameter) and "
                                      f"cannot carry binary operation {v}")
            elif j > i and v != 0:
                if not 0 < v < len(UNARY):
                    raise MatrixError(f"unknown unary operation {v} on arc {i + 1}->{j + 1} "
                                      f"(psi[{i + 1},{j + 1}]); valid: 1..{len(UNARY) - 1}")
                if j < ns:
                    raise MatrixError(f"arc {i + 1}->{j + 1} ends in source node {j + 1}")
    arcs = [(i, j, UNARY[int(rows[i][j])], BINARY[int(rows[j][j])])
            for i in range(L) for j in range(i + 1, L) if rows[i][j] and rows[j][j]]
    fed = {j for _, j, _, _ in arcs}
    for j in range(ns, L):          # the unit; finite(unit) (atan2: 0) on a node without arcs
        b = int(rows[j][j])
        init[j] = (UNIT[b] if j in fed else finite(UNIT[b])) if b else 0.0
    outs = []
    for k, o in enumerate(outputs):
        if not 1 <= int(o) <= L:
            raise MatrixError(f"output {k + 1} names node {o}, outside 1..{L}")
        outs.append(int(o) - 1)
    return L, init, arcs, outs


def evaluate(program, sources):
    """Values of the output nodes of a compiled law for source values ``sources`` (x then q)."""
    L, init, arcs, outs = program
    z = list(init)
    for k, v in enumerate(sources):
        z[k] = finite(v)
    for i, j, rho, chi in arcs:
        try:
            v = chi(z[j], rho(z[i]))
        except (OverflowError, ValueError, ZeroDivisionError):  # never met: the operands are
            v = BIG                                               # finite, the guards hold
        # finite(v), written inline (the hot loop of every closed-loop step)
        z[j] = BIG if v > BIG else (-BIG if v < -BIG else (v if v == v else 0.0))
    return [z[o] for o in outs]


#: The paper's basic law u = q1 y1 + q2 y2 (Diveev & Shmalko, eq. 25) on 7 nodes:
#: 1 y1, 2 y2, 3 q1, 4 q2, 5 = q1*y1, 6 = q2*y2, 7 = 5 + 6.
BASIC_LAW_PSI = [
    [0, 0, 0, 0, 1, 0, 0],
    [0, 0, 0, 0, 0, 1, 0],
    [0, 0, 0, 0, 1, 0, 0],
    [0, 0, 0, 0, 0, 1, 0],
    [0, 0, 0, 0, 2, 0, 1],
    [0, 0, 0, 0, 0, 2, 1],
    [0, 0, 0, 0, 0, 0, 1],
]
#: The paper's parameters of its chosen law (Diveev & Shmalko).
PAPER_Q = (2.259375, 1.953125)


#: Descriptions (unit in brackets) of the controller's variables; the native law FMUs of
#: synthesis.fmi.native declare the same names with the same descriptions, so one swaps in for the
#: other.
DESCRIPTIONS = {
    "x": "controller input [1]",
    "u": "control output, clipped to [u_min, u_max] [1]",
    "q": "law parameter q [1]",
    "u_min": "lower output bound [1]",
    "u_max": "upper output bound [1]",
    "x_scale": "input scale: node k holds x_scale[k] (x[k] - x_offset[k]) [1]",
    "x_offset": "input offset (in the input's unit) [1]",
}

_PSI_IJ = [(i, j) for i in range(L_MAX) for j in range(i, L_MAX)]
_PSI_NAMES = [f"psi[{i + 1},{j + 1}]" for i, j in _PSI_IJ]


class NetworkOperatorController(SlaveBase):
    """Generic network-operator controller FMU: ``u[k] = clip(z[out[k]], u_min[k], u_max[k])``.

    Interface (sizes fixed at build time): inputs ``x[1..NX_MAX]``; outputs ``u[1..NU_MAX]``;
    Integer parameters ``psi[i,j]`` (``i <= j``, upper triangle of an ``L_MAX``-node matrix),
    ``nx``, ``nq`` (source node counts), ``nu`` (outputs in use), ``out[k]`` (node of output k);
    Real parameters ``q[1..NQ_MAX]``, ``u_min[k]``, ``u_max[k]`` and the input scaling
    ``x_scale[k]``, ``x_offset[k]`` (source node k holds ``x_scale[k] (x[k] - x_offset[k])``;
    default 1 and 0).  Defaults: the paper's basic law ``u = clip(q1 y1 + q2 y2, -0.2, 0.2)``
    with q1 = 2.259375, q2 = 1.953125.

    The outputs are computed lazily from the current inputs when read (a static law has direct
    feed-through), so a master reading ``u`` right after setting ``x`` gets ``phi(x)``.
    """

    description = "Network-operator control law (Diveev & Sofronova): generic, " \
                  "parameterised by its matrix psi and parameters q"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.psi = [[0] * L_MAX for _ in range(L_MAX)]
        for i, row in enumerate(BASIC_LAW_PSI):
            self.psi[i][:len(row)] = row
        self.x = [0.0] * NX_MAX
        self.q = [0.0] * NQ_MAX
        self.q[:2] = PAPER_Q
        self.u_lo = [-0.2] * NU_MAX
        self.u_hi = [0.2] * NU_MAX
        self.x_scale = [1.0] * NX_MAX
        self.x_offset = [0.0] * NX_MAX
        self.out = [len(BASIC_LAW_PSI)] + [0] * (NU_MAX - 1)
        self._u = [0.0] * NU_MAX
        self._dirty = True
        self.int_parameter("nx", 2, "number of input source nodes (nodes 1..nx) [1]")
        self.int_parameter("nq", 2, "number of parameter source nodes (nodes nx+1..nx+nq) [1]")
        self.int_parameter("nu", 1, "number of outputs in use [1]")
        self.real_array("x", self.x, Fmi2Causality.input, DESCRIPTIONS["x"],
                        setter_hook=self._touch)
        for k in range(NU_MAX):
            self.output(f"u[{k + 1}]", DESCRIPTIONS["u"],
                        getter=lambda k=k: self._outputs()[k])
        self.real_array("q", self.q, Fmi2Causality.parameter, DESCRIPTIONS["q"])
        self.real_array("u_min", self.u_lo, Fmi2Causality.parameter, DESCRIPTIONS["u_min"])
        self.real_array("u_max", self.u_hi, Fmi2Causality.parameter, DESCRIPTIONS["u_max"])
        self.real_array("x_scale", self.x_scale, Fmi2Causality.parameter,
                        DESCRIPTIONS["x_scale"])
        self.real_array("x_offset", self.x_offset, Fmi2Causality.parameter,
                        DESCRIPTIONS["x_offset"])
        for k in range(NU_MAX):
            self.int_parameter(f"out[{k + 1}]", 0, "node whose value is output k (0 = unused) [1]",
                               lambda k=k: self.out[k],
                               lambda v, k=k: self.out.__setitem__(k, int(v)))
        psi = self.psi
        self.var_block(Integer, _PSI_NAMES,
                       lambda k: lambda i=_PSI_IJ[k][0], j=_PSI_IJ[k][1]: psi[i][j],
                       lambda k: lambda v, i=_PSI_IJ[k][0], j=_PSI_IJ[k][1]:
                       psi[i].__setitem__(j, int(v)),
                       causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                       description="binary operation (i = j) or unary operation on arc i->j [1]")
        self.apply_resource_defaults()
        self.check_parameters()
        self.prepare()

    def _touch(self):
        self._dirty = True

    def check_parameters(self) -> None:
        if not 0 <= self.nx <= NX_MAX:
            raise ParameterError(f"nx = {self.nx} outside 0..{NX_MAX}")
        if not 0 <= self.nq <= NQ_MAX:
            raise ParameterError(f"nq = {self.nq} outside 0..{NQ_MAX}")
        if not 1 <= self.nu <= NU_MAX:
            raise ParameterError(f"nu = {self.nu} outside 1..{NU_MAX}")
        for k in range(self.nu):
            lo, hi = self.u_lo[k], self.u_hi[k]
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                raise ParameterError(f"u_min[{k + 1}] = {lo}, u_max[{k + 1}] = {hi}: need "
                                     f"finite bounds with u_min <= u_max")
        for k in range(self.nq):
            if not math.isfinite(self.q[k]):
                raise ParameterError(f"parameter q[{k + 1}] must be finite, got {self.q[k]}")
        for k in range(self.nx):
            if not (math.isfinite(self.x_scale[k]) and math.isfinite(self.x_offset[k])):
                raise ParameterError(f"x_scale[{k + 1}] = {self.x_scale[k]}, x_offset[{k + 1}] "
                                     f"= {self.x_offset[k]}: need finite values")
        try:
            self._program = compile_law(self.psi, self.nx, self.nq, self.out[:self.nu])
        except MatrixError as exc:
            raise ParameterError(str(exc)) from None

    def prepare(self) -> None:
        self._dirty = True
        n = self.nx
        self._scaling = None
        if any(s != 1.0 for s in self.x_scale[:n]) or any(o != 0.0 for o in self.x_offset[:n]):
            self._scaling = list(zip(self.x_scale[:n], self.x_offset[:n]))

    def law(self, x) -> list:
        """The clipped outputs of the law for the inputs ``x`` (``nx`` values, unscaled)."""
        x = list(x)
        if self._scaling is not None:
            x = [s * (v - o) for v, (s, o) in zip(x, self._scaling)]
        z = evaluate(self._program, x + self.q[:self.nq])
        return [lo if v < lo else (hi if v > hi else v)
                for v, lo, hi in zip(z, self.u_lo, self.u_hi)]

    def _outputs(self):
        if self._dirty:
            u = self.law(self.x[:self.nx])
            self._u[:len(u)] = u
            self._dirty = False
        return self._u

    def do_step(self, current_time: float, step_size: float) -> bool:
        self._dirty = True
        return True
