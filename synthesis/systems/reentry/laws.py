"""S1 reentry: the laws -- the paper's laws as network-operator matrices (the basic law and the
law the paper found) with the reentry control bounds, and the basic solutions and baseline
structures of the synthesis problems with their input scalings.

* the paper's laws: :func:`paper_basic_law`, :func:`paper_law`, :func:`paper_basic_law_16`;
* nominal problems: :func:`synthesis_basic_law` (window inputs :data:`WINDOW_CENTRE`,
  :data:`WINDOW_HALF`), :func:`robust_basic_law`, :func:`baseline_structures`
  (:data:`INPUT_SCALE`);
* sensed problems: :func:`sensed_basic_law`, :func:`sensed_baselines`,
  :func:`sensed_y12_baselines` (:data:`SENSED_INPUT_SCALE`);
* guided problem: :func:`as_guided` (:data:`GUIDED_INPUTS`); its basic solution, the committed
  nominal law made guided, is loaded in :mod:`.guidance`.

References
----------
Diveev & Shmalko (reentry paper): basic law eqs. (24)-(25); the found 16-node law and its
printed formula.
"""
from __future__ import annotations

import numpy as np

from descent_fmus.models.controllers.network_operator import BASIC_LAW_PSI, PAPER_Q
from descent_fmus.models.reentry import U_BOUNDS
from descent_fmus.synthesis.methods.law import NetworkOperator

__all__ = ["PAPER_LAW_PSI", "paper_basic_law", "paper_law", "reentry_law", "paper_basic_law_16",
           "INPUT_SCALE", "WINDOW_CENTRE", "WINDOW_HALF", "synthesis_basic_law",
           "robust_basic_law", "baseline_structures", "SENSED_INPUT_SCALE", "sensed_basic_law",
           "sensed_baselines", "sensed_y12_baselines", "GUIDED_INPUTS", "as_guided"]


def _paper_law_psi():
    """The paper's printed 16-node law (Diveev & Shmalko), rebuilt from its printed formula.

    The printed matrix is OCR-damaged (a row with 15 entries, diagonal entries lost), so it is
    rebuilt from the printed expression, which is complete:
    z5 = q1*y1, z6 = -q2 + y2, z7 = z6*z5, z8 = z7, z9 = z8, z10 = z9 + rho8(y2), z11 = z10,
    z12 = -z10, z13 = z12 + rho4(z11), z14 = z13 + rho9(y2), z15 = z14 + rho4(z9) + rho8(y1),
    z16 = z15 - y1; nodes 1 y1, 2 y2, 3 q1, 4 q2.
    """
    psi = [[0] * 16 for _ in range(16)]
    binary = {5: 2, 6: 1, 7: 2, 8: 1, 9: 1, 10: 1, 11: 1, 12: 1, 13: 1, 14: 1, 15: 1, 16: 1}
    for node, op in binary.items():
        psi[node - 1][node - 1] = op
    arcs = [(1, 5, 1), (3, 5, 1), (2, 6, 1), (4, 6, 3), (6, 7, 1), (5, 7, 1), (7, 8, 1),
            (8, 9, 1), (9, 10, 1), (2, 10, 8), (10, 11, 1), (10, 12, 3), (12, 13, 1),
            (11, 13, 4), (13, 14, 1), (2, 14, 9), (14, 15, 1), (9, 15, 4), (1, 15, 8),
            (15, 16, 1), (1, 16, 3)]
    for i, j, op in arcs:
        psi[i - 1][j - 1] = op
    return psi


PAPER_LAW_PSI = _paper_law_psi()


def reentry_law(psi, q, outputs=None, nx: int = 2, **kw) -> NetworkOperator:
    """A law of the reentry inputs (y1, y2 unless ``input_names`` is given) with the control
    bounds of the Reentry plant, ``u`` in [-0.2, 0.2]."""
    kw.setdefault("input_names", ["y1", "y2", "y3", "c"][:nx])
    return NetworkOperator(psi, nx=nx, q=list(q), outputs=outputs, bounds=[U_BOUNDS], **kw)


def paper_basic_law(q=PAPER_Q, size: int = 16) -> NetworkOperator:
    """The paper's basic law ``u = clip(q1 y1 + q2 y2, -0.2, 0.2)`` (Diveev & Shmalko, eqs.
    24-25).

    ``size`` pads the matrix with unused nodes (room for the GA's variations); the output is
    node 7.
    """
    n0 = len(BASIC_LAW_PSI)
    psi = np.zeros((max(size, n0), max(size, n0)), dtype=int)
    psi[:n0, :n0] = BASIC_LAW_PSI
    return reentry_law(psi, q, outputs=[n0])


def paper_law() -> NetworkOperator:
    """The paper's found 16-node law with q1 = 2.259375, q2 = 1.953125 (Diveev & Shmalko)."""
    return reentry_law(np.array(PAPER_LAW_PSI), PAPER_Q)


def paper_basic_law_16() -> NetworkOperator:
    """The paper's basic law q1*y1 + q2*y2 on a 16-node matrix (the GA's basic solution before
    the richer polynomial one; kept as the ``cma-basic`` baseline structure).

    Nodes: 1 y1, 2 y2, 3-6 q1..q4 (q3, q4 unused until a variation connects them),
    7 = q1*y1, 8 = q2*y2, 9 = 7 + 8, then identity nodes 10..16 (+) carrying z9 to the output
    node 16.
    """
    L = 16
    psi = np.zeros((L, L), dtype=int)
    for a, b, op in [(1, 7, 1), (3, 7, 1), (2, 8, 1), (4, 8, 1), (7, 9, 1), (8, 9, 1)]:
        psi[a - 1, b - 1] = op
    psi[6, 6], psi[7, 7], psi[8, 8] = 2, 2, 1
    for k in range(9, L):
        psi[k - 1, k] = 1
        psi[k, k] = 1
    return reentry_law(psi, list(PAPER_Q) + [1.0, 1.0], outputs=[L])


#: Input scaling of the baselines' laws [choice]: 10*y1 and 2*y2 are of order 1 along a flight
#: (y1 in [0, 0.2], y2 in [-1.1, -0.1] rad under the basic law).
INPUT_SCALE = (10.0, 2.0)
#: Input window of the GA's basic solution [choice] (models/README.md, "S1 synthesis"): its
#: inputs are w1 = (y1 - 0.19) / 0.01 and w2 = (y2 + 0.25) / 0.1, of order 1 where near-optimal
#: laws act (unclipped only between t ~ 125 s and 195 s, at y1 in [0.18, 0.20] near its
#: maximum and y2 in [-0.37, -0.15]).
WINDOW_CENTRE, WINDOW_HALF = (0.19, -0.25), (0.01, 0.1)


def _paper_template(scale, offset=(0.0, 0.0)) -> NetworkOperator:
    return reentry_law(paper_basic_law_16().psi, list(PAPER_Q) + [1.0, 1.0], [16],
                       input_scale=list(scale), input_offset=list(offset))


def _paper_cubic(template: NetworkOperator, size: int | None = None) -> NetworkOperator:
    """A cubic polynomial in the template's inputs s_i = k_i (y_i - o_i) at the paper's basic
    law q1 y1 + q2 y2 = (q1 o1 + q2 o2) + (q1 / k1) s1 + (q2 / k2) s2 (the rest 0)."""
    from descent_fmus.synthesis.methods.structures import polynomial_law
    (k1, k2), (o1, o2) = template.input_scale, template.input_offset
    q = [PAPER_Q[0] * o1 + PAPER_Q[1] * o2, PAPER_Q[0] / k1, PAPER_Q[1] / k2] + [0.0] * 7
    return polynomial_law(template, 3, q, size=size)


def synthesis_basic_law() -> NetworkOperator:
    """The GA's first basic solution [choice]: a cubic polynomial in the window inputs
    (w1, w2) = ((y1 - 0.19) / 0.01, (y2 + 0.25) / 0.1) on 32 nodes, at the paper's basic law.

    Nodes: 1-2 the inputs, 3-12 the coefficients (constant first), 13-21 one product node per
    monomial, 22 their sum, 23-32 identity nodes (spare nodes on which the variations build
    structure).  The method leaves the basic solution to the designer; a richer one than the
    paper's linear law gives the parameter search (CMA-ES) more to work with, and inputs of
    order 1 where the law acts give it coefficients of order 1 that act nearly independently.
    """
    return _paper_cubic(_paper_template([1.0 / h for h in WINDOW_HALF], WINDOW_CENTRE), size=32)


def robust_basic_law() -> NetworkOperator:
    """The robust variant's basic solution: the same cubic in the baselines' inputs
    (10 y1, 2 y2) on 32 nodes, at the paper's basic law (its Gray-coded bit flips search
    q in +-64, ``ROBUST_Q_BITS``)."""
    return _paper_cubic(_paper_template(INPUT_SCALE), size=32)


def baseline_structures() -> dict:
    """The fixed structures of the CMA-ES baselines (``synthesize reentry --method cma-NAME``):
    ``basic`` the paper's basic law (its two gains), ``polynomial`` the basic solution's cubic
    polynomial (10 coefficients) in the inputs (10 y1, 2 y2), ``tanh`` a 2-3-1 tanh network (13 weights, seeded
    random start)."""
    from descent_fmus.synthesis.methods.structures import tanh_network_law
    return {"basic": paper_basic_law(),
            "polynomial": _paper_cubic(_paper_template(INPUT_SCALE)),
            "tanh": tanh_network_law(_paper_template(INPUT_SCALE), 3, seed=0)}


#: Input scaling of the sensed laws [choice]: 10 y1, 2 y2 as the nominal problem, 5 y3
#: (y3 lies in [-0.21, 0.19] over the dispersion set).
SENSED_INPUT_SCALE = tuple(INPUT_SCALE) + (5.0,)


def _sensed_template(nx: int) -> NetworkOperator:
    psi = np.zeros((nx + 2, nx + 2), dtype=int)
    return reentry_law(psi, [0.0], [nx + 2], nx=nx, input_scale=list(SENSED_INPUT_SCALE[:nx]))


def _start_coefficients(nx: int, degree: int) -> list:
    """The paper's basic law (gains q1/10, q2/2 on the scaled inputs) and, with y3, the
    first-order compensation of the drag factor: u = -y3 (coefficient -1/5 on 5 y3)."""
    from descent_fmus.synthesis.methods.structures import monomials
    gains = {0: PAPER_Q[0] / SENSED_INPUT_SCALE[0], 1: PAPER_Q[1] / SENSED_INPUT_SCALE[1],
             2: -1.0 / SENSED_INPUT_SCALE[2]}
    q = [0.0]
    for m in monomials(nx, degree):
        q.append(gains[m.index(1)] if sum(m) == 1 else 0.0)
    return q


def sensed_basic_law(nx: int = 3) -> NetworkOperator:
    """The GA's first basic solution [choice]: a quadratic polynomial in the scaled inputs on 32
    nodes (a cubic in three inputs needs 20 parameters, more than the controller FMU holds), the
    paper's basic law plus u = -y3 as its start; identity nodes up to 32 for the variations.
    With ``nx = 2`` (y1, y2 only) the same construction without y3 (degree 3 fits)."""
    from descent_fmus.synthesis.methods.structures import polynomial_law
    degree = 2 if nx == 3 else 3
    return polynomial_law(_sensed_template(nx), degree, _start_coefficients(nx, degree), size=32)


def sensed_baselines() -> dict:
    """Fixed structures of the CMA-ES baseline (``--method cma-polynomial``): the basic
    solution's polynomial, only its coefficients tuned."""
    from descent_fmus.synthesis.methods.structures import polynomial_law
    return {"polynomial": polynomial_law(_sensed_template(3), 2, _start_coefficients(3, 2))}


def sensed_y12_baselines() -> dict:
    from descent_fmus.synthesis.methods.structures import polynomial_law
    return {"polynomial": polynomial_law(_sensed_template(2), 3, _start_coefficients(2, 3))}


#: Names and scales of the guided laws' inputs [choice]: y1, y2, y3 as the sensed laws, and
#: the correction c unscaled (|c| <= 0.4).
GUIDED_INPUTS = (("y1", INPUT_SCALE[0]), ("y2", INPUT_SCALE[1]),
                 ("y3", SENSED_INPUT_SCALE[2]), ("c", 1.0))


def as_guided(law: NetworkOperator) -> NetworkOperator:
    """``law`` with the inputs of a guided law (y1, y2, y3, c): a law of (y1, y2) or (y1, y2,
    y3) gets the missing inputs as unused source nodes (the controller adds c to its output
    all the same; a variation may connect them; :meth:`NetworkOperator.with_inputs`).  A law
    whose fourth input is c already (``guidance.reads_correction``) is returned as it is.

    Raises
    ------
    ValueError
        The law does not read y1, y2 (and y3) or has several outputs; or (a ``MatrixError``)
        no node can be freed for the new inputs.
    """
    names = list(law.input_names or [])
    if law.nx >= 4 and names[3:4] == ["c"]:
        return law
    want = [n for n, _ in GUIDED_INPUTS]
    if not 2 <= law.nx <= 3 or names != want[:law.nx] or len(law.outputs) != 1:
        raise ValueError(f"a guided law needs the inputs {', '.join(want[:3])} (the first two "
                         f"at least) and one output; got inputs {names}")
    return law.with_inputs(want, [v for _, v in GUIDED_INPUTS[law.nx:]])
