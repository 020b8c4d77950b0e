"""The :class:`NetworkOperator` type: a control law as matrix + parameters, validated.

Evaluation uses the one implementation in :mod:`models.controllers.law_interpreter`, which is
also what the ``NetworkOperatorController`` FMU runs, so a law evaluated here and the same law
loaded into the FMU give identical outputs; the start values that load it there are made by
:mod:`synthesis.methods.law_fmu`.

References
----------
A.I. Diveev, E.Yu. Shmalko (reentry paper); A.I. Diveev, E.A. Sofronova, Vestnik RUDN 2007 no. 4.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from descent_fmus.models.controllers.law_interpreter import (MatrixError, compile_law, evaluate,
                                                                evaluate_points)
from descent_fmus.models.controllers.network_operator import L_MAX
from descent_fmus.models.controllers.operation_table import (BIG, BINARY_NAMES, BINARY_OPS,
                                                             UNARY_NAMES)
from descent_fmus.synthesis.methods.law_fmu import start_array, start_values

__all__ = ["NetworkOperator", "MatrixError", "LawFileError", "MAX_NODES", "MAX_LAW_FILE_BYTES"]

#: Most nodes of a law's matrix (the controller FMU holds L_MAX; in-process laws may be larger,
#: up to this documented maximum: the evaluation is quadratic in the nodes).
MAX_NODES = 1024
#: Largest law file [bytes].
MAX_LAW_FILE_BYTES = 4 * 1_048_576


class LawFileError(ValueError):
    """A law file is not valid JSON or does not describe a valid network operator."""


@dataclass
class NetworkOperator:
    """A network-operator law ``u = clip(phi(x, q), u_min, u_max)``.

    Parameters
    ----------
    psi : array-like of int, shape (L, L)
        Upper-triangular matrix: binary operations on the diagonal, unary operations on arcs.
    nx : int
        Number of inputs (source nodes ``1..nx``).
    q : sequence of float
        Parameters (source nodes ``nx+1..nx+len(q)``).
    outputs : sequence of int, optional
        1-based output nodes (default: the last node).
    bounds : sequence of (float, float), optional
        Output bounds per output (default: none, i.e. the node clamp ``(-BIG, BIG)``).
    input_names : sequence of str, optional
        Names of the inputs for :meth:`formula` (default ``x1, x2, ...``).
    input_scale, input_offset : sequence of float, optional
        Source node k holds ``input_scale[k] (x[k] - input_offset[k])`` (default 1 and 0).

    Raises
    ------
    MatrixError
        Malformed matrix (not square, not upper-triangular, unknown operation, arcs into
        sources), output nodes out of range, or non-finite parameters/bounds.
    """

    psi: np.ndarray
    nx: int
    q: list
    outputs: list = field(default=None)
    bounds: list = field(default=None)
    input_names: list = field(default=None)
    input_scale: list = field(default=None)
    input_offset: list = field(default=None)

    def __post_init__(self):
        try:
            psi = np.asarray(self.psi)
        except Exception as exc:  # ragged lists
            raise MatrixError(f"matrix is not a rectangular array: {exc}") from None
        if psi.ndim != 2 or psi.shape[0] != psi.shape[1]:
            raise MatrixError(f"matrix must be square (L x L), got shape {psi.shape}")
        if psi.shape[0] > MAX_NODES:
            raise MatrixError(f"the matrix has {psi.shape[0]} nodes; the documented maximum is "
                              f"{MAX_NODES}")
        if isinstance(self.nx, bool) or not isinstance(self.nx, (int, np.integer)) \
                or not 0 <= self.nx <= psi.shape[0]:
            raise MatrixError(f"nx must be an integer in 0..{psi.shape[0]} (the inputs are "
                              f"source nodes of the matrix), got {self.nx!r}")
        self.nx = int(self.nx)
        if len(self.q) > psi.shape[0] or (self.outputs is not None
                                          and len(self.outputs) > psi.shape[0]):
            raise MatrixError(f"more parameters or outputs than the matrix's "
                              f"{psi.shape[0]} nodes")
        integer = psi.dtype.kind in "iu"            # finite integers already
        if psi.size and not integer and not np.all(np.isfinite(psi.astype(float))):
            raise MatrixError("matrix has non-finite entries")
        if psi.size and not ((integer or np.all(psi == np.round(psi)))
                             and np.all(np.abs(psi) < 2 ** 31)):
            raise MatrixError("matrix entries must be integers (operation numbers)")
        self.psi = psi.astype(int)
        L = self.psi.shape[0]
        self.q = [float(v) for v in self.q]
        for k, v in enumerate(self.q):
            if not math.isfinite(v):
                raise MatrixError(f"parameter q{k + 1} must be finite, got {v}")
        if self.outputs is None:
            self.outputs = [L]
        self.outputs = [int(o) for o in self.outputs]
        if self.bounds is None:
            self.bounds = [(-BIG, BIG)] * len(self.outputs)
        self.bounds = [(float(lo), float(hi)) for lo, hi in self.bounds]
        if len(self.bounds) != len(self.outputs):
            raise MatrixError(f"{len(self.outputs)} outputs but {len(self.bounds)} bounds")
        for k, (lo, hi) in enumerate(self.bounds):
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                raise MatrixError(f"bounds of output {k + 1} must be finite with lo <= hi, "
                                  f"got ({lo}, {hi})")
        if self.input_names is None:
            self.input_names = [f"x{k + 1}" for k in range(self.nx)]
        self.input_scale = [1.0] * self.nx if self.input_scale is None else \
            [float(v) for v in self.input_scale]
        self.input_offset = [0.0] * self.nx if self.input_offset is None else \
            [float(v) for v in self.input_offset]
        for what, vals in (("input_scale", self.input_scale), ("input_offset", self.input_offset)):
            if len(vals) != self.nx or not all(math.isfinite(v) for v in vals):
                raise MatrixError(f"{what} must hold {self.nx} finite values, got {vals}")
        self._compile()

    def _compile(self):
        self._program = compile_law(self.psi, self.nx, len(self.q), self.outputs)
        self._scaled = any(s != 1.0 for s in self.input_scale) or \
            any(o != 0.0 for o in self.input_offset)

    # the compiled program holds the operations (functions): rebuilt after unpickling
    def __getstate__(self):
        d = dict(self.__dict__)
        d.pop("_program", None)
        return d

    def __setstate__(self, d):
        self.__dict__.update(d)
        try:
            self._compile()
        except MatrixError:   # a law edited after validation: the FMU will reject it, per law
            self._program = None

    # -- constructors ---------------------------------------------------------------------
    @classmethod
    def linear(cls, gains, bias=None, bounds=None, size: int | None = None,
               input_names=None, input_scale=None, input_offset=None,
               spare_constants: int = 0, free_nodes: int = 0) -> "NetworkOperator":
        """The linear feedback ``u_k = clip(sum_i gains[k][i] x_i + bias[k])`` as a matrix.

        Nodes: the inputs, then the parameters (the gains row by row, then the biases, then
        ``spare_constants`` unused constants at 0), then for each output the products
        ``q x_i`` (binary *), ``free_nodes`` free nodes (no arcs in or out), their sum with
        the bias (binary +) and a chain of identity nodes (+) to the output node: spare nodes
        on which the GA's variations build structure (the unused constants and free nodes
        are room for weighted arcs: :func:`synthesis.methods.structures.with_room`).
        ``size`` (default: 4 spare nodes per output) is the total node count; the spare
        nodes are shared out evenly.
        """
        gains = [[float(g) for g in row] for row in gains]
        nu = len(gains)
        nx = len(gains[0]) if nu else 0
        if nu < 1 or nx < 1 or any(len(r) != nx for r in gains):
            raise MatrixError(f"gains must be a non-empty matrix (one row of input gains per "
                              f"output), got {gains}")
        bias = [0.0] * nu if bias is None else [float(b) for b in bias]
        if len(bias) != nu:
            raise MatrixError(f"{nu} outputs but {len(bias)} biases")
        q = [g for row in gains for g in row] + bias + [0.0] * int(spare_constants)
        ns = nx + len(q)
        core = ns + nu * (nx + 1 + int(free_nodes))
        size = core + 4 * nu if size is None else int(size)
        spare = (size - core) // nu
        if spare < 0:
            raise MatrixError(f"a linear law with {nx} inputs and {nu} outputs needs at least "
                              f"{core} nodes, got size = {size}")
        psi = np.zeros((size, size), dtype=int)
        node, outputs = ns, []
        for k in range(nu):
            prods = []
            for i in range(nx):
                psi[node, node] = 2                          # product q_ki * x_i
                psi[i, node] = 1
                psi[nx + k * nx + i, node] = 1
                prods.append(node)
                node += 1
            node += int(free_nodes)                          # free: room for weighted arcs
            psi[node, node] = 1                              # sum of the products + bias
            for j in prods:
                psi[j, node] = 1
            psi[nx + nu * nx + k, node] = 1
            last = node
            node += 1
            # the last output takes what the even share leaves over
            for _ in range(spare if k < nu - 1 else size - node):
                psi[node, node] = 1
                psi[last, node] = 1
                last = node
                node += 1
            outputs.append(last + 1)
        return cls(psi, nx=nx, q=q, outputs=outputs, bounds=bounds, input_names=input_names,
                   input_scale=input_scale, input_offset=input_offset)

    # -- evaluation -----------------------------------------------------------------------
    @property
    def size(self) -> int:
        return self.psi.shape[0]

    def raw(self, x) -> list:
        """Output node values before clipping (inputs in the plant's units, scaled here)."""
        x = list(x)
        if self._scaled:
            x = [s * (v - o) for v, s, o in zip(x, self.input_scale, self.input_offset)]
        return evaluate(self._program, x + self.q)

    def raw_points(self, points) -> list:
        """:meth:`raw` at each of ``points`` (the same values bit for bit, one pass over the
        law's arcs for all of them)."""
        xs = [list(x) for x in points]
        if self._scaled:
            xs = [[s * (v - o) for v, s, o in zip(x, self.input_scale, self.input_offset)]
                  for x in xs]
        return evaluate_points(self._program, [x + self.q for x in xs])

    def __call__(self, x) -> list:
        """The control: output node values clipped to their bounds (what the FMU outputs)."""
        return [lo if v < lo else (hi if v > hi else v)
                for v, (lo, hi) in zip(self.raw(x), self.bounds)]

    # -- FMU interface (synthesis.methods.law_fmu) ------------------------------------------
    def start_array(self) -> tuple:
        """:func:`synthesis.methods.law_fmu.start_array` of this law."""
        return start_array(self)

    def start_values(self) -> dict:
        """:func:`synthesis.methods.law_fmu.start_values` of this law."""
        return start_values(self)

    # -- persistence ----------------------------------------------------------------------
    def to_dict(self, formula: bool = True) -> dict:
        """The law as JSON-able data (``formula``: with its readable expression)."""
        d = {"psi": self.psi.tolist(), "nx": self.nx, "q": self.q, "outputs": self.outputs,
             "bounds": [list(b) for b in self.bounds], "input_names": self.input_names}
        if self._scaled:
            d["input_scale"], d["input_offset"] = self.input_scale, self.input_offset
        if formula:
            d["formula"] = self.formula()
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "NetworkOperator":
        try:
            return cls(np.array(d["psi"]), nx=int(d["nx"]), q=d["q"], outputs=d.get("outputs"),
                       bounds=d.get("bounds"), input_names=d.get("input_names"),
                       input_scale=d.get("input_scale"), input_offset=d.get("input_offset"))
        except KeyError as exc:
            raise LawFileError(f"law is missing the field {exc.args[0]!r}") from None
        except MatrixError as exc:
            raise LawFileError(str(exc)) from None
        except (TypeError, ValueError) as exc:
            raise LawFileError(f"malformed law: {exc}") from None

    def save(self, path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1))
        return path

    @classmethod
    def load(cls, path) -> "NetworkOperator":
        size = Path(path).stat().st_size
        if size > MAX_LAW_FILE_BYTES:
            raise LawFileError(f"{path} has {size} bytes; a law file holds at most "
                               f"{MAX_LAW_FILE_BYTES}")
        try:
            d = json.loads(Path(path).read_text())
        except json.JSONDecodeError as exc:
            raise LawFileError(f"{path} is not valid JSON: {exc}") from None
        if not isinstance(d, dict):
            raise LawFileError(f"{path} must hold a JSON object")
        return cls.from_dict(d)

    def with_q(self, q) -> "NetworkOperator":
        q = list(q)
        if len(q) != len(self.q):
            raise MatrixError(f"the law has {len(self.q)} parameters, got {len(q)}")
        return NetworkOperator(self.psi.copy(), self.nx, q, list(self.outputs), list(self.bounds),
                               list(self.input_names), list(self.input_scale),
                               list(self.input_offset))

    def with_structure(self, psi, q) -> "NetworkOperator":
        """This law's inputs, outputs, bounds and input scaling with another matrix and
        parameters (what a structure search varies).

        [choice] An integer matrix of this law's kind skips the constructor's checks of what
        this law already passed (its inputs, outputs, bounds, scaling): only the matrix
        (compiled, through the interpreter's cache of programs) and the parameters are checked
        -- the search builds thousands of laws a second; the same law as the constructor's.
        Anything else goes through the constructor (its messages)."""
        if not (isinstance(psi, np.ndarray) and psi.ndim == 2 and psi.dtype.kind in "iu"
                and psi.shape[0] == psi.shape[1] and psi.shape[0] <= MAX_NODES
                and self.nx <= psi.shape[0] and len(q) <= psi.shape[0]
                and len(self.outputs) <= psi.shape[0]):
            return NetworkOperator(psi, self.nx, q, self.outputs, self.bounds,
                                   self.input_names, self.input_scale, self.input_offset)
        q, psi = [float(v) for v in q], psi.astype(int)
        program = None
        if all(map(math.isfinite, q)):
            try:
                program = compile_law(psi, self.nx, len(q), self.outputs)
            except MatrixError:
                pass
        if program is None:           # the constructor names the fault
            return NetworkOperator(psi, self.nx, q, self.outputs, self.bounds,
                                   self.input_names, self.input_scale, self.input_offset)
        law = object.__new__(NetworkOperator)
        law.psi, law.nx, law.q = psi, self.nx, q
        law.outputs, law.bounds = list(self.outputs), list(self.bounds)
        law.input_names = list(self.input_names)
        law.input_scale, law.input_offset = list(self.input_scale), list(self.input_offset)
        law._program = program
        law._scaled = self._scaled           # the same scaling as this law
        return law

    @classmethod
    def stack(cls, laws) -> "NetworkOperator":
        """One law with the outputs of several laws of the same inputs: their matrices side by
        side (the inputs shared, the parameters one after the other, then each law's nodes),
        each output with its law's bounds.  Every law keeps its value."""
        laws = list(laws)
        first = laws[0]
        for law in laws[1:]:
            if law.nx != first.nx or law.input_scale != first.input_scale \
                    or law.input_offset != first.input_offset:
                raise MatrixError("stacked laws must read the same inputs with the same scaling")
        nx = first.nx
        nq = [len(law.q) for law in laws]
        inner = [law.size - nx - n for law, n in zip(laws, nq)]
        size = nx + sum(nq) + sum(inner)
        psi = np.zeros((size, size), dtype=int)
        outputs, bounds = [], []
        q_at, node_at = nx, nx + sum(nq)
        for law, n, m in zip(laws, nq, inner):
            index = list(range(nx)) + list(range(q_at, q_at + n)) + \
                list(range(node_at, node_at + m))
            psi[np.ix_(index, index)] = law.psi
            outputs += [index[o - 1] + 1 for o in law.outputs]
            bounds += list(law.bounds)
            q_at, node_at = q_at + n, node_at + m
        return cls(psi, nx, [v for law in laws for v in law.q], outputs, bounds,
                   list(first.input_names), list(first.input_scale), list(first.input_offset))

    def with_inputs(self, names, scales=None, offsets=None) -> "NetworkOperator":
        """This law reading more inputs: ``names`` extend :attr:`input_names` (they must start
        with them); the new inputs become source nodes no arc leaves yet (a structural
        variation may connect them), with their ``scales`` / ``offsets`` (default 1 and 0).
        The law's value is unchanged.  Identity nodes after the output, and an output node
        that is an identity of one node, are dropped to stay within the controller's
        :data:`L_MAX` nodes.

        Raises
        ------
        MatrixError
            ``names`` do not extend the inputs, the law has several outputs, or no node can be
            freed for the new inputs.
        """
        names = list(names)
        add = len(names) - self.nx
        if add < 0 or names[:self.nx] != list(self.input_names):
            raise MatrixError(f"the new inputs {names} must extend the law's inputs "
                              f"{list(self.input_names)}")
        if len(self.outputs) != 1:
            raise MatrixError("only a law with one output can take more inputs")
        psi, out = self.psi.copy(), self.outputs[0] - 1
        while psi.shape[0] + add > L_MAX:
            if out < psi.shape[0] - 1:                   # nodes after the output: unused
                psi = psi[:-1, :-1]
                continue
            src = np.flatnonzero(psi[:out, out])
            if len(src) != 1 or psi[src[0], out] != 1 or psi[out, out] not in (1, 2):
                raise MatrixError(f"the law needs {add} free nodes for the new inputs and its "
                                  f"output node is not an identity node that can be dropped")
            psi, out = psi[:-1, :-1], int(src[0])        # an identity node: its source is out
        n, nx = psi.shape[0], self.nx
        keep = [k if k < nx else k + add for k in range(n)]
        new = np.zeros((n + add, n + add), dtype=int)
        new[np.ix_(keep, keep)] = psi
        scale = list(self.input_scale) + list(scales if scales is not None else [1.0] * add)
        offset = list(self.input_offset) + list(offsets if offsets is not None else [0.0] * add)
        return NetworkOperator(new, len(names), list(self.q), [keep[out] + 1],
                               bounds=list(self.bounds), input_names=names, input_scale=scale,
                               input_offset=offset)

    # -- readable form --------------------------------------------------------------------
    def readable(self, digits: int = 6):
        """The law made readable by SymPy -- constants folded, simplified, common
        sub-expressions named (:class:`synthesis.methods.law_formula.Readable`: ``text``,
        ``latex``, ``exact``).  Computed once per law content (cached)."""
        from descent_fmus.synthesis.methods.law_formula import readable_cached
        return readable_cached(self, digits)

    def formula(self, digits: int = 6) -> str:
        """A readable expression of the (first) output, e.g. ``(q1*y1)+(q2*y2)``."""
        L, ns = self.size, self.nx + len(self.q)
        expr = [None] * L
        for k in range(self.nx):
            name, scale, off = self.input_names[k], self.input_scale[k], self.input_offset[k]
            if off != 0.0:
                name = f"({name}{-off:+.{digits}g})"
            expr[k] = name if scale == 1.0 else f"{scale:.{digits}g}*{name}"
        for k in range(len(self.q)):
            expr[self.nx + k] = f"{self.q[k]:.{digits}g}"
        terms = [[] for _ in range(L)]
        for i in range(L):
            for j in range(i + 1, L):
                if self.psi[i, j] and self.psi[j, j]:
                    terms[j].append(UNARY_NAMES[self.psi[i, j]].format(expr[i] or "0"))
            if i + 1 < L:
                j = i + 1
                if j >= ns:
                    b = self.psi[j, j]
                    if b and terms[j]:
                        one = len(terms[j]) == 1 and BINARY_OPS[b].first == "b"
                        expr[j] = terms[j][0] if one else \
                            (BINARY_NAMES[b].join(terms[j]) if b in (1, 2) else
                             f"{BINARY_NAMES[b]}(" + ", ".join(terms[j]) + ")")
                        if len(terms[j]) > 1:
                            expr[j] = f"({expr[j]})"
                    else:
                        expr[j] = None
        outs = [expr[o - 1] or "0" for o in self.outputs]
        return outs[0] if len(outs) == 1 else "; ".join(outs)

