"""The network operator: evaluation of a control law stored as an upper-triangular integer matrix.

A mathematical expression is a directed acyclic graph on nodes ``1..L`` stored as ``Psi`` (L x L):
the diagonal ``psi[i][i]`` is the number of the *binary* operation at node ``i``; an off-diagonal
``psi[i][j]`` (``i < j``) the number of the *unary* operation on the arc ``i -> j``; 0 = nothing.
Source nodes ``1..nx`` hold the inputs, nodes ``nx+1..nx+nq`` the parameters q.

Evaluation (Diveev & Sofronova 2007): a non-source node starts at the unit element of its
binary operation; for ``i = 1..L-1`` and every ``j > i`` with ``psi[i][j] != 0`` and
``psi[j][j] != 0``: ``z_j <- chi_{psi_jj}(z_j, rho_{psi_ij}(z_i))``.  The outputs are the values of
the output nodes (the last node by default).

Every operation is overflow-safe: values are clamped to ``[-BIG, BIG]`` (BIG = 1e8, the authors'
"infinity") after every operation, and a NaN becomes 0, so the law never returns NaN or inf.

This module is the one implementation of the operations and of the evaluation; it serves the
:class:`NetworkOperatorController` FMU and ``synthesis.methods.network_operator.NetworkOperator``.

References
----------
A.I. Diveev, E.Yu. Shmalko (reentry paper), section "Синтез"; A.I. Diveev, E.A. Sofronova, "The network operator
method in control problems", Vestnik RUDN, 2007, no. 4.
"""
from __future__ import annotations

import math

from pythonfmu import Fmi2Causality, Fmi2Variability, Integer

from descent_fmus.models.fmu_support import ParameterError, SlaveBase

__all__ = ["BIG", "UNARY", "BINARY", "UNIT", "UNARY_NAMES", "BINARY_NAMES", "compile_law",
           "evaluate", "NetworkOperatorController", "L_MAX", "NX_MAX", "NQ_MAX", "NU_MAX",
           "MatrixError"]

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


def _sgn(z):           # the seed's sign: 1 for z >= 0, else -1 (rho10)
    return 1.0 if z >= 0.0 else -1.0


def _exp(z):
    return BIG if z > _LN_BIG else math.exp(z)


def _r5(z):
    return 1.0 / z if abs(z) > _EPS5 else _sgn(z) / _EPS5


def _r7(z):
    a = abs(z)
    return math.log(a) if a > _EPS else math.log(_EPS)


def _r18(z):
    return _sgn(z) * (_exp(abs(z)) - 1.0)


def _r27(z):
    a = abs(z)
    return _sgn(z) * (1.0 - math.sqrt(1.0 - z * z)) if a < 1.0 else _sgn(z)


#: Unary operations rho_k, numbered as in the seed (index 0 unused).
UNARY = [
    None,
    lambda z: z,                                      # 1  identity
    lambda z: z * z,                                  # 2  z^2
    lambda z: -z,                                     # 3  -z
    lambda z: _sgn(z) * math.sqrt(abs(z)),            # 4  sgn(z) sqrt|z|
    _r5,                                              # 5  1/z, guarded
    _exp,                                             # 6  e^z
    _r7,                                              # 7  ln|z|
    lambda z: math.tanh(0.5 * z),                     # 8  (1-e^-z)/(1+e^-z)
    lambda z: 1.0 if z >= 0.0 else 0.0,               # 9  Heaviside
    _sgn,                                             # 10 sign
    math.cos,                                         # 11 cos
    math.sin,                                         # 12 sin
    math.atan,                                        # 13 atan
    lambda z: z * z * z,                              # 14 z^3
    math.cbrt,                                        # 15 cube root
    lambda z: 1.0 if z > 1.0 else (-1.0 if z < -1.0 else z),   # 16 clip to [-1, 1]
    lambda z: _sgn(z) * math.log(abs(z) + 1.0),       # 17 sgn(z) ln(|z|+1)
    _r18,                                             # 18 sgn(z)(e^|z| - 1)
    lambda z: _sgn(z) * math.exp(-abs(z)),            # 19 sgn(z) e^-|z|
    lambda z: 0.5 * z,                                # 20 z/2
    lambda z: 2.0 * z,                                # 21 2z
    lambda z: _sgn(z) * (1.0 - math.exp(-abs(z))),    # 22 sgn(z)(1 - e^-|z|)
    lambda z: z - z * z * z,                          # 23 z - z^3
    lambda z: 0.5 * (1.0 + math.tanh(0.5 * z)),       # 24 logistic 1/(1+e^-z)
    lambda z: 1.0 if z > 0.0 else 0.0,                # 25 [z > 0]
    lambda z: _sgn(z) if abs(z) >= 0.01 else 0.0,     # 26 dead zone
    _r27,                                             # 27 sgn(z)(1 - sqrt(1 - z^2))
    lambda z: z * (1.0 - math.exp(-z * z)),           # 28 z(1 - e^-z^2)
]

UNARY_NAMES = [None, "{}", "({})^2", "-({})", "sqrt~({})", "inv({})", "exp({})", "ln|{}|",
               "sig2({})", "heaviside({})", "sgn({})", "cos({})", "sin({})", "atan({})",
               "({})^3", "cbrt({})", "clip1({})", "sgnlog({})", "sgnexp1({})", "sgnexpm({})",
               "({})/2", "2*({})", "sat({})", "cubic({})", "logistic({})", "pos({})",
               "dead({})", "circ({})", "gauss({})"]

#: Binary operations chi_k (index 0 unused): 1 +, 2 *, 3 max, 4 min, then the wider set.
BINARY = [
    None,
    lambda a, b: a + b,                                                   # 1
    lambda a, b: a * b,                                                   # 2
    lambda a, b: a if a >= b else b,                                      # 3 max
    lambda a, b: a if a <= b else b,                                      # 4 min
    lambda a, b: a + b - a * b,                                           # 5
    lambda a, b: _sgn(a + b) * math.sqrt(a * a + b * b),                  # 6
    lambda a, b: _sgn(a + b) * (abs(a) + abs(b)),                         # 7
    lambda a, b: _sgn(a + b) * max(abs(a), abs(b)),                       # 8
]
BINARY_NAMES = [None, "+", "*", "max", "min", "or", "norm", "sabs", "smax"]
#: Unit elements of the binary operations (-inf/+inf of max/min are -BIG/+BIG).
UNIT = [None, 0.0, 1.0, -BIG, BIG, 0.0, 0.0, 0.0, 0.0]


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
    for j in range(ns, L):
        b = int(rows[j][j])
        init[j] = UNIT[b] if b else 0.0
    arcs = [(i, j, UNARY[int(rows[i][j])], BINARY[int(rows[j][j])])
            for i in range(L) for j in range(i + 1, L) if rows[i][j] and rows[j][j]]
    outs = []
    for k, o in enumerate(outputs):
        if not 1 <= int(o) <= L:
            raise MatrixError(f"output {k + 1} names node {o}, outside 1..{L}")
        outs.append(int(o) - 1)
    return L, init, arcs, outs


def _finite(v):
    if v != v:
        return 0.0
    return BIG if v > BIG else (-BIG if v < -BIG else v)


def evaluate(program, sources):
    """Values of the output nodes of a compiled law for source values ``sources`` (x then q)."""
    L, init, arcs, outs = program
    z = list(init)
    for k, v in enumerate(sources):
        z[k] = _finite(v)
    for i, j, rho, chi in arcs:
        try:
            v = chi(z[j], rho(z[i]))
        except (OverflowError, ValueError, ZeroDivisionError):
            v = BIG
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
        self.real_array("x", self.x, Fmi2Causality.input, "controller input [1]",
                        setter_hook=self._touch)
        for k in range(NU_MAX):
            self.output(f"u[{k + 1}]", "control output, clipped to [u_min, u_max] [1]",
                        getter=lambda k=k: self._outputs()[k])
        self.real_array("q", self.q, Fmi2Causality.parameter, "law parameter q [1]")
        self.real_array("u_min", self.u_lo, Fmi2Causality.parameter, "lower output bound [1]")
        self.real_array("u_max", self.u_hi, Fmi2Causality.parameter, "upper output bound [1]")
        self.real_array("x_scale", self.x_scale, Fmi2Causality.parameter,
                        "input scale: node k holds x_scale[k] (x[k] - x_offset[k]) [1]")
        self.real_array("x_offset", self.x_offset, Fmi2Causality.parameter,
                        "input offset (in the input's unit) [1]")
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

    def _outputs(self):
        if self._dirty:
            x = self.x[:self.nx]
            if self._scaling is not None:
                x = [s * (v - o) for v, (s, o) in zip(x, self._scaling)]
            z = evaluate(self._program, x + self.q[:self.nq])
            for k, v in enumerate(z):
                lo, hi = self.u_lo[k], self.u_hi[k]
                self._u[k] = lo if v < lo else (hi if v > hi else v)
            self._dirty = False
        return self._u

    def do_step(self, current_time: float, step_size: float) -> bool:
        self._dirty = True
        return True
