"""A law in the generic controller FMU: the start values that load a
:class:`~synthesis.methods.law.NetworkOperator` into the ``NetworkOperatorController`` FMU
(as a name -> value dict, or as one names tuple and one float64 array), and the FMU's capacity
check.
"""
from __future__ import annotations

import numpy as np

from descent_fmus.models.controllers.law_interpreter import MatrixError
from descent_fmus.models.controllers.network_operator import L_MAX, NQ_MAX, NU_MAX, NX_MAX

__all__ = ["CapacityError", "start_array", "start_values"]

#: Names of the generic controller FMU's variables a law sets (start_values).
_FMU_NAMES = {
    "upper": np.triu_indices(L_MAX),
    "psi": [f"psi[{i + 1},{j + 1}]" for i, j in zip(*np.triu_indices(L_MAX))],
    "q": [f"q[{k + 1}]" for k in range(NQ_MAX)],
    "bounds": [(f"u_min[{k + 1}]", f"u_max[{k + 1}]", f"out[{k + 1}]") for k in range(NU_MAX)],
    "scaling": [(f"x_scale[{k + 1}]", f"x_offset[{k + 1}]") for k in range(NX_MAX)],
}
#: every name in the order of start_values, and where each block is (start_array)
_FMU_NAMES["all"] = ("nx", "nq", "nu", *_FMU_NAMES["psi"], *_FMU_NAMES["q"],
                     *(n for t in _FMU_NAMES["bounds"] for n in t),
                     *(n for t in _FMU_NAMES["scaling"] for n in t))
_FMU_NAMES["at"] = {key: slice(a, a + n) for key, a, n in (
    ("psi", 3, len(_FMU_NAMES["psi"])), ("q", 3 + len(_FMU_NAMES["psi"]), NQ_MAX),
    ("bounds", 3 + len(_FMU_NAMES["psi"]) + NQ_MAX, 3 * NU_MAX),
    ("scaling", 3 + len(_FMU_NAMES["psi"]) + NQ_MAX + 3 * NU_MAX, 2 * NX_MAX))}
_FMU_NAMES["template"] = np.zeros(len(_FMU_NAMES["all"]))
_FMU_NAMES["template"][_FMU_NAMES["at"]["scaling"].start::2] = 1.0
#: per matrix size L: (where in start_array's values, which entries of the L x L matrix
#: raveled) of the upper triangle's entries that lie in the matrix, in the FMU's order
_PSI_PLACES: dict = {}


def _psi_places(size: int) -> tuple:
    """``(places in the values array, flat indices in a size x size matrix)`` of the upper
    triangle of :data:`L_MAX` restricted to the matrix (made once per size: start_array sets
    these entries only, the template holds the zeros of the rest)."""
    got = _PSI_PLACES.get(size)
    if got is None:
        i, j = _FMU_NAMES["upper"]
        inside = (i < size) & (j < size)
        got = _PSI_PLACES[size] = (np.flatnonzero(inside) + _FMU_NAMES["at"]["psi"].start,
                                   i[inside] * size + j[inside])
    return got


class CapacityError(MatrixError):
    """The law is larger than the generic controller FMU holds (sizes fixed at build time)."""


def _check_capacity(law) -> None:
    for what, n, cap in (("nodes", law.size, L_MAX), ("inputs", law.nx, NX_MAX),
                         ("parameters", len(law.q), NQ_MAX),
                         ("outputs", len(law.outputs), NU_MAX)):
        if n > cap:
            raise CapacityError(f"the law has {n} {what}; the NetworkOperatorController "
                                f"FMU holds at most {cap} (sizes are fixed at build time)")


def start_array(law) -> tuple:
    """:func:`start_values` as ``(names, values)``: the same names in the same order (one
    tuple per process) and their values as one float64 array (the integers exactly), made in
    a few microseconds -- for the native closed loop, which compares them with the FMU's
    declared start values as arrays.

    Raises
    ------
    CapacityError
        If the law has more nodes, inputs, parameters or outputs than the FMU holds.
    """
    _check_capacity(law)
    names, at = _FMU_NAMES, _FMU_NAMES["at"]
    v = names["template"].copy()          # zeros; bounds (0, 0, 0), scaling (1, 0) unused
    v[0], v[1], v[2] = law.nx, len(law.q), len(law.outputs)
    dest, src = _psi_places(law.size)
    # the integers as floats exactly (|psi| < 2**31); the rest of the triangle: the template's 0
    v[dest] = law.psi.ravel()[src].astype(float)
    q0 = at["q"].start
    v[q0:q0 + len(law.q)] = law.q
    b = at["bounds"].start
    for (lo, hi), o in zip(law.bounds, law.outputs):
        v[b], v[b + 1], v[b + 2] = lo, hi, o
        b += 3
    s = at["scaling"].start
    for scale, offset in zip(law.input_scale, law.input_offset):
        v[s], v[s + 1] = scale, offset
        s += 2
    return names["all"], v


def start_values(law) -> dict:
    """Start values that load ``law`` into the generic NetworkOperatorController FMU.

    Raises
    ------
    CapacityError
        If the law has more nodes, inputs, parameters or outputs than the FMU holds.
    """
    _check_capacity(law)
    L = law.size
    # once per candidate on the evaluation's hot path: the names are made once per process
    # and the matrix is read as one array (the upper triangle, row by row: psi[1,1],
    # psi[1,2], ..., the order of the controller's variables)
    names = _FMU_NAMES
    vals = {"nx": law.nx, "nq": len(law.q), "nu": len(law.outputs)}
    full = np.zeros((L_MAX, L_MAX), dtype=np.int64)
    full[:L, :L] = law.psi
    vals.update(zip(names["psi"], full[names["upper"]].tolist()))
    vals.update(zip(names["q"], law.q + [0.0] * (NQ_MAX - len(law.q))))
    for k, (lo_name, hi_name, out_name) in enumerate(names["bounds"]):
        lo, hi = law.bounds[k] if k < len(law.outputs) else (0.0, 0.0)
        vals[lo_name], vals[hi_name] = lo, hi
        vals[out_name] = law.outputs[k] if k < len(law.outputs) else 0
    for k, (scale_name, offset_name) in enumerate(names["scaling"]):
        vals[scale_name] = law.input_scale[k] if k < law.nx else 1.0
        vals[offset_name] = law.input_offset[k] if k < law.nx else 0.0
    return vals
