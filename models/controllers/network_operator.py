"""The generic network-operator controller FMU: any law's matrix and parameters as FMU variables.

:class:`NetworkOperatorController` carries any network-operator law up to its capacity
(:data:`L_MAX` nodes, :data:`NX_MAX` inputs, :data:`NQ_MAX` parameters, :data:`NU_MAX` outputs)
as Integer and Real parameters; it checks and compiles the matrix with
:func:`models.controllers.law_interpreter.compile_law` and evaluates it every step with
:func:`~models.controllers.law_interpreter.evaluate` (the operations:
:mod:`models.controllers.operation_table`).  Its default is the reentry paper's basic law
(:data:`BASIC_LAW_PSI`, :data:`PAPER_Q`).

References
----------
A.I. Diveev, E.Yu. Shmalko (reentry paper), section "Синтез"; A.I. Diveev, E.A. Sofronova, "The network operator
method in control problems", Vestnik RUDN, 2007, no. 4.
"""
from __future__ import annotations

import math

from pythonfmu import Fmi2Causality, Fmi2Variability, Integer

from descent_fmus.models.controllers.law_interpreter import MatrixError, compile_law, evaluate
from descent_fmus.models.fmu_support import ParameterError, SlaveBase

__all__ = ["NetworkOperatorController", "L_MAX", "NX_MAX", "NQ_MAX", "NU_MAX", "DESCRIPTIONS",
           "BASIC_LAW_PSI", "PAPER_Q"]

# Capacity of the generic controller FMU (fixed at build time; room for the paper's 16-node
# law plus synthesis headroom: L = 16-32 nodes, 2-9 parameters).
L_MAX = 32
NX_MAX = 8
NQ_MAX = 16
NU_MAX = 4


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
