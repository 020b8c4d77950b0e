"""Law structures of fixed form, built from any problem's inputs and outputs: a linear law, a
full polynomial, a small tanh network -- all as network-operator matrices, so that they are
start values of the same generic controller FMU as every other law.

They are the fixed structures of the CMA-ES baselines (``synthesize --method cma-NAME``,
:mod:`synthesis.methods.policy_search`) and can serve as a problem's basic solution.
"""
from __future__ import annotations

import numpy as np

from descent_fmus.synthesis.methods.law import NetworkOperator

__all__ = ["monomials", "polynomial_law", "tanh_network_law", "with_room", "ROOM_FREE_NODES"]


def monomials(nx: int, degree: int) -> list:
    """Exponent tuples of every monomial of total degree 1..``degree`` in ``nx`` inputs, by
    degree (x1, x2, x1^2, x1 x2, x2^2, ...)."""
    out = []

    def rec(prefix, left, k):
        if k == nx:
            if sum(prefix) and sum(prefix) == d:
                out.append(tuple(prefix))
            return
        for e in range(left, -1, -1):
            rec(prefix + [e], left - e, k + 1)

    for d in range(1, degree + 1):
        rec([], d, 0)
    return out


#: unary operations that raise a value to the power 1, 2, 3 (identity, z^2, z^3)
_POWER_OP = {1: 1, 2: 2, 3: 14}


def _finish(psi, nx, q, out_node, size, template: NetworkOperator):
    """Pad with identity nodes to ``size`` (spare nodes for structural variations) and build
    the law with the template's inputs, bounds and scaling."""
    node = out_node
    n = psi.shape[0]
    full = np.zeros((size, size), dtype=int)
    full[:n, :n] = psi
    for j in range(n, size):
        full[j, j] = 1
        full[node, j] = 1
        node = j
    return NetworkOperator(full, nx=nx, q=list(q), outputs=[node + 1],
                           bounds=[template.bounds[0]], input_names=list(template.input_names),
                           input_scale=list(template.input_scale),
                           input_offset=list(template.input_offset))


def polynomial_law(template: NetworkOperator, degree: int = 3, coefficients=None,
                   size: int | None = None) -> NetworkOperator:
    """u = clip(c0 + sum_m c_m x^m): a full polynomial of ``degree`` in the template's inputs.

    Nodes: the inputs, the coefficients (c0 first, then one per monomial in :func:`monomials`
    order), one product node per monomial (c_m times the powers of its inputs: arcs with the
    unary operations z, z^2, z^3) and their sum (with c0) as the output; identity nodes up to
    ``size``.  Inputs, bounds and input scaling are the template's (the basic law of a problem).
    """
    nx = template.nx
    mons = monomials(nx, degree)
    if max(max(m) for m in mons) > 3:
        raise ValueError("powers above 3 have no unary operation; use degree <= 3")
    nq = 1 + len(mons)
    core = nx + nq + len(mons) + 1
    size = core if size is None else int(size)
    if size < core:
        raise ValueError(f"a degree-{degree} polynomial in {nx} inputs needs {core} nodes")
    q = np.zeros(nq) if coefficients is None else np.asarray(coefficients, float)
    psi = np.zeros((core, core), dtype=int)
    total = core - 1
    psi[total, total] = 1
    psi[nx, total] = 1                                   # c0
    for k, m in enumerate(mons):
        node = nx + nq + k
        psi[node, node] = 2
        psi[nx + 1 + k, node] = 1                        # c_m
        for i, e in enumerate(m):
            if e:
                psi[i, node] = _POWER_OP[e]
        psi[node, total] = 1
    return _finish(psi, nx, q, total, size, template)


def tanh_network_law(template: NetworkOperator, hidden: int = 3, weights=None,
                     size: int | None = None, seed: int = 0) -> NetworkOperator:
    """u = clip(c + sum_i v_i tanh((w_i . x + b_i) / 2)): one hidden layer of ``hidden`` units.

    Parameters q (in this order): per unit ``w_i1..w_inx, b_i``, then ``v_1..v_hidden``, then
    ``c``.  Nodes per unit: one product w_ij x_j per input, their sum with b_i, the product of
    v_i and the unit's output (unary operation 8, (1 - e^-z)/(1 + e^-z) = tanh(z/2)); then the
    output sum.  Default weights: small seeded random numbers (a random start, as usual for
    networks).
    """
    nx = template.nx
    nq = hidden * (nx + 1) + hidden + 1
    core = nx + nq + hidden * (nx + 2) + 1
    size = core if size is None else int(size)
    if size < core:
        raise ValueError(f"a {nx}-{hidden}-1 tanh network needs {core} nodes")
    if weights is None:
        rng = np.random.default_rng(seed)
        weights = np.concatenate([rng.normal(0.0, 0.5, hidden * (nx + 1)),
                                  rng.normal(0.0, 0.1, hidden), [0.0]])
    q = np.asarray(weights, float)
    if len(q) != nq:
        raise ValueError(f"a {nx}-{hidden}-1 network has {nq} parameters, got {len(q)}")
    psi = np.zeros((core, core), dtype=int)
    total = core - 1
    psi[total, total] = 1
    psi[nx + nq - 1, total] = 1                           # c
    node = nx + nq
    for i in range(hidden):
        w0 = nx + i * (nx + 1)
        prods = []
        for j in range(nx):
            psi[node, node] = 2
            psi[j, node] = 1
            psi[w0 + j, node] = 1
            prods.append(node)
            node += 1
        s = node
        psi[s, s] = 1
        for pnode in prods:
            psi[pnode, s] = 1
        psi[w0 + nx, s] = 1                               # b_i
        node += 1
        psi[node, node] = 2
        psi[s, node] = 8                                  # tanh(z/2)
        psi[nx + hidden * (nx + 1) + i, node] = 1         # v_i
        psi[node, total] = 1
        node += 1
    return _finish(psi, nx, q, total, size, template)


# -- room for weighted arcs in a linear basic law ---------------------------------------------
#: [choice] free nodes per output a linear basic law gets for weighted arcs (between its
#: products and its sum): one weighted arc per node, and the switching forms measured need
#: one or two (docs/methods/network_operator.md, "Weighted arcs")
ROOM_FREE_NODES = 2


def with_room(law: NetworkOperator, free_nodes: int = ROOM_FREE_NODES) -> NetworkOperator:
    """A linear law in the layout of :meth:`NetworkOperator.linear` (``[basic_law] gains``)
    rewritten with room for weighted arcs (``ga.weighted_arcs``): as many unused constants
    (at 0) as inputs and ``free_nodes`` free nodes per output between its products and its
    sum, taken from its chain of identity nodes, so the node count stays ``law.size``.  The
    same function (the spare parts are read by nothing).  Any other law -- and a linear one
    whose nodes or the controller's parameters leave no room -- is returned as it is: a law
    is recognised as linear when :meth:`NetworkOperator.linear` rebuilds its matrix exactly
    from its parameters."""
    from descent_fmus.models.controllers.network_operator import NQ_MAX
    nx, nu = law.nx, len(law.outputs)
    m = nu * nx + nu
    if nx < 1 or len(law.q) != m:
        return law
    gains = [law.q[k * nx:(k + 1) * nx] for k in range(nu)]
    common = dict(bounds=law.bounds, input_names=law.input_names,
                  input_scale=law.input_scale, input_offset=law.input_offset)
    try:
        plain = NetworkOperator.linear(gains, law.q[nu * nx:], size=law.size, **common)
    except ValueError:                     # MatrixError: too few nodes for the layout
        return law
    if not np.array_equal(plain.psi, law.psi) or plain.outputs != law.outputs:
        return law
    spare = min(nx, NQ_MAX - m)
    chain = law.size - (nx + m + nu * (nx + 1))
    free = min(int(free_nodes), (chain - spare) // nu)
    if spare < 1 or free < 1:
        return law
    return NetworkOperator.linear(gains, law.q[nu * nx:], size=law.size, spare_constants=spare,
                                  free_nodes=free, **common)


# -- the default baselines of any problem ---------------------------------------------------------
def _single_output(basic: NetworkOperator, k: int) -> NetworkOperator:
    """The basic law's inputs and scaling with its output ``k`` alone (a template)."""
    return NetworkOperator(basic.psi, basic.nx, basic.q, [basic.outputs[k]], [basic.bounds[k]],
                           list(basic.input_names), list(basic.input_scale),
                           list(basic.input_offset))


def _fits(law: NetworkOperator) -> bool:
    from descent_fmus.models.controllers.network_operator import L_MAX, NQ_MAX
    return law.size <= L_MAX and len(law.q) <= NQ_MAX


def probe_inputs(law: NetworkOperator, n: int = 256, seed: int = 0,
                 spread: float = 1.0) -> np.ndarray:
    """``n`` seeded input points (plant units) where the law's scaled inputs lie in
    [-spread, spread]: by default the region its input scaling says it acts on."""
    z = np.random.default_rng(seed).uniform(-spread, spread, (n, law.nx))
    return np.asarray(law.input_offset) + z / np.asarray(law.input_scale)


def fit_parameters(law: NetworkOperator, target: NetworkOperator, free=None,
                   points=None) -> NetworkOperator:
    """``law`` with its parameters ``free`` (default all) chosen by least squares so that its
    unclipped outputs match ``target``'s on probe points (:func:`probe_inputs` of ``target``).
    ``law``'s outputs must be linear in the free parameters and vanish with them (a polynomial,
    a linear law, a network's output layer): each column of the fit is the law with one free
    parameter set to 1."""
    points = probe_inputs(target) if points is None else points
    free = list(range(len(law.q))) if free is None else list(free)
    base = np.array(law.q, float)
    base[free] = 0.0
    want = np.array([target.raw(x) for x in points], float).ravel()
    cols = []
    for i in free:
        q = base.copy()
        q[i] = 1.0
        trial = law.with_q(list(q))
        cols.append(np.array([trial.raw(x) for x in points], float).ravel())
    fixed = law.with_q(list(base))
    rest = np.array([fixed.raw(x) for x in points], float).ravel()
    ok = np.isfinite(want) & np.all(np.isfinite(cols), axis=0) & np.isfinite(rest)
    if not ok.any():
        return law
    sol, *_ = np.linalg.lstsq(np.array(cols).T[ok], (want - rest)[ok], rcond=None)
    q = base.copy()
    q[free] = sol
    return law.with_q(list(q))


def default_baselines(basic: NetworkOperator, seed: int = 0) -> dict:
    """The fixed structures of the CMA-ES baselines of any problem, built from its basic law's
    inputs, outputs, bounds and input scaling, each started at the least-squares fit of the
    basic law (``synthesize --method cma-NAME``):

    * ``linear`` -- u_k = sum_i g_ki x_i + b_k;
    * ``polynomial`` -- a full polynomial per output, of the highest degree <= 3 the generic
      controller holds (its 32 nodes, 16 parameters); left out if only degree 1 fits;
    * ``tanh`` -- a one-hidden-layer tanh network per output, of the most hidden units the
      controller holds (seeded random first layer, its output layer fitted).
    """
    outs = range(len(basic.outputs))
    nx, nu = basic.nx, len(basic.outputs)
    out = {}
    linear = NetworkOperator.linear([[0.0] * nx] * nu, size=nx + nu * (nx + 1) + nu * (nx + 1),
                                    bounds=basic.bounds, input_names=basic.input_names,
                                    input_scale=basic.input_scale,
                                    input_offset=basic.input_offset)
    if _fits(linear):
        out["linear"] = fit_parameters(linear, basic)
    for degree in (3, 2):
        try:
            law = NetworkOperator.stack([polynomial_law(_single_output(basic, k), degree)
                                         for k in outs])
        except ValueError:
            continue
        if _fits(law):
            out["polynomial"] = fit_parameters(law, basic)
            break
    for hidden in range(8, 0, -1):
        laws = [tanh_network_law(_single_output(basic, k), hidden, seed=seed + k) for k in outs]
        law = NetworkOperator.stack(laws)
        if _fits(law):
            per = len(laws[0].q)
            readout = [k * per + j for k in outs for j in range(per - hidden - 1, per)]
            out["tanh"] = fit_parameters(law, basic, readout)
            break
    return out
