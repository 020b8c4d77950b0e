"""Fixed-structure policy search: CMA-ES over the parameters q of one network-operator law.

A *baseline* is a law structure (a :class:`NetworkOperator` matrix: the basic law, a polynomial in
the controller inputs, a small tanh network -- :func:`polynomial_law`, :func:`tanh_network_law`)
plus its parameters q; :class:`PolicySearch` tunes q by CMA-ES (pycma, Hansen's covariance matrix
adaptation) with every candidate flown by the same evaluator as the network-operator synthesis,
so the laws it finds are start values of the same generic controller FMU and export like any
other law.  The same class refines the parameters of promising structures inside the
network-operator search (:mod:`synthesis.methods.ga`).

CMA-ES minimises one number; a two-objective problem gives it through a :class:`Target`:
objective ``objective`` subject to objective ``constraint`` <= ``limit`` (a violation costs
``weight`` per unit of relative excess), e.g. min max load subject to miss < 1 km.

Determinism: the sampling uses a :class:`numpy.random.Generator` owned by the search (pycma's
``randn`` option), and :meth:`PolicySearch.state` is the pickled optimiser with that generator,
so a restored search continues exactly as an uninterrupted one.

References
----------
N. Hansen, "The CMA Evolution Strategy: A Tutorial", arXiv:1604.00772; pycma (github.com/CMA-ES).
"""
from __future__ import annotations

import base64
import copy
import math
import pickle
from dataclasses import dataclass

import numpy as np

from descent_fmus.synthesis.methods.law import NetworkOperator

__all__ = ["Target", "CMA", "IPOP_SIGMA", "IPOP_STALL", "PolicySearch", "polynomial_law", "tanh_network_law", "monomials",
           "NormalSource"]


@dataclass(frozen=True)
class Target:
    """The single objective CMA-ES minimises: ``F[objective]`` subject to
    ``F[constraint] < limit`` (no constraint: ``constraint=None``).

    ``scalar(F) = F[objective] + weight * max(0, F[constraint] / limit - 1)``; ``feasible(F)``
    tells the rows that meet the constraint (what a report counts).
    """

    objective: int = 0
    constraint: int | None = None
    limit: float = math.inf
    weight: float = 10.0

    def feasible(self, F) -> np.ndarray:
        F = np.atleast_2d(np.asarray(F, float))
        if self.constraint is None:
            return np.ones(len(F), bool)
        return F[:, self.constraint] < self.limit

    def scalar(self, F) -> np.ndarray:
        F = np.atleast_2d(np.asarray(F, float))
        s = F[:, self.objective].copy()
        if self.constraint is not None and math.isfinite(self.limit):
            excess = F[:, self.constraint] / self.limit - 1.0
            s += self.weight * np.maximum(excess, 0.0)
        return s

    def best(self, F) -> int | None:
        """Index of the best feasible row (lowest objective), None if no row is feasible."""
        F = np.atleast_2d(np.asarray(F, float))
        ok = np.flatnonzero(self.feasible(F))
        return None if not len(ok) else int(ok[np.argmin(F[ok, self.objective])])


#: Default IPOP restart triggers of a search [choice]: step size below 1e-3 of the initial one,
#: or 60 generations without a better value.
IPOP_SIGMA, IPOP_STALL = 1e-3, 60


class NormalSource:
    """Picklable standard-normal sampler for pycma (``randn(*shape)``) on a seeded Generator."""

    def __init__(self, seed):
        self.rng = np.random.default_rng(seed)

    def __call__(self, *shape):
        return self.rng.standard_normal(shape)


class CMA:
    """CMA-ES (pycma) on a real vector ``x``, worked on ``x / scale``; seeded, checkpointable,
    with IPOP restarts (Auger & Hansen 2005).

    Parameters
    ----------
    x0 : sequence of float
        Start point.
    sigma : float
        Initial step size relative to ``scale``.
    seed : int
    scale : sequence of float, optional
        Per-coordinate scale (default ``max(|x0|, scale_floor)``, taken again at every
        restart from the restart point).
    popsize : int, optional
        Candidates per generation (default pycma's 4 + 3 ln n).
    bounds : (float, float), optional
        Bounds of every coordinate.
    x_map : callable, optional
        ``x_map(x) -> x`` applied to every candidate before it is returned (e.g. rounding to
        the grid of a Gray code, so that what is evaluated is exactly representable).
    restart_sigma, restart_stall : float, int, optional
        Restart once the step size fell below ``restart_sigma * sigma`` or the best value has
        not improved for ``restart_stall`` generations: a new search from the best point found,
        with the initial relative step size and twice the population (IPOP), seed
        ``seed + 1000 r`` at the r-th restart.  None: never.  With the default scale the
        restart's scale is ``max(|x|, scale_floor)`` at the restart point: the step stays
        relative to the parameters' size when they have grown far beyond the start's (a
        polynomial law's coefficients grow to thousands), so a restart explores around the
        point instead of polishing it with steps a thousandth of its size.
    """

    def __init__(self, x0, sigma: float = 0.3, seed: int = 1, scale=None,
                 popsize: int | None = None, bounds: tuple | None = None,
                 scale_floor: float = 0.1, x_map=None, restart_sigma: float | None = None,
                 restart_stall: int | None = None):
        x0 = np.asarray(x0, float)
        self.scale_floor, self.relative = float(scale_floor), scale is None
        self.scale = (np.maximum(np.abs(x0), scale_floor) if scale is None
                      else np.asarray(scale, float))
        self.bounds = bounds
        self.x_map = x_map
        self.sigma0, self.seed = float(sigma), int(seed)
        self.restart_sigma, self.restart_stall = restart_sigma, restart_stall
        self.restarts, self.best_value, self.best_x, self.stall = 0, math.inf, None, 0
        self.es = self._strategy(x0, self.seed, popsize)
        self._pending = None

    def _strategy(self, x0, seed, popsize):
        import cma
        opts = {"seed": int(seed) % (2 ** 31 - 1) + 1, "verbose": -9,
                "randn": NormalSource(seed), "tolx": 1e-14, "tolfun": 0, "tolfunhist": 0,
                "tolflatfitness": 10 ** 9, "tolstagnation": 10 ** 9, "maxiter": 10 ** 9}
        if popsize:
            opts["popsize"] = int(popsize)
        if self.bounds is not None:
            opts["bounds"] = [list(self.bounds[0] / self.scale), list(self.bounds[1] / self.scale)]
        return cma.CMAEvolutionStrategy(list(np.asarray(x0, float) / self.scale), self.sigma0,
                                        opts)

    @property
    def popsize(self) -> int:
        return self.es.popsize

    @property
    def sigma(self) -> float:
        return float(self.es.sigma)

    def x(self, z) -> np.ndarray:
        x = np.asarray(z, float) * self.scale
        if self.bounds is not None:
            x = np.clip(x, *self.bounds)
        return self.x_map(x) if self.x_map is not None else x

    def ask(self) -> list:
        """The candidates (vectors) of the next generation."""
        if self._pending is None:
            self._pending = self.es.ask()
        return [self.x(z) for z in self._pending]

    def tell(self, values) -> None:
        """Values to minimise of the candidates of the last :meth:`ask`, same order."""
        if self._pending is None:
            raise RuntimeError("tell() without a pending ask()")
        values = [float(v) for v in values]
        if len(values) != len(self._pending) or not all(map(math.isfinite, values)):
            raise ValueError(f"expected {len(self._pending)} finite values, got {values}")
        self.es.tell(self._pending, values)
        i = int(np.argmin(values))
        if values[i] < self.best_value:
            self.best_value, self.best_x, self.stall = values[i], \
                [float(v) for v in self.x(self._pending[i])], 0
        else:
            self.stall += 1
        self._pending = None
        if (self.restart_sigma is not None and self.sigma < self.restart_sigma * self.sigma0) \
                or (self.restart_stall is not None and self.stall >= self.restart_stall):
            self.restart()

    def restart(self, x0=None) -> None:
        """IPOP restart: a new search from ``x0`` (default the best point found) with the
        initial relative step size (rescaled to the point, see the class) and twice the
        population."""
        self.restarts += 1
        x0 = np.asarray(x0 if x0 is not None else self.best_x, float)
        if self.relative:
            self.scale = np.maximum(np.abs(x0), self.scale_floor)
        self.es = self._strategy(x0, self.seed + 1000 * self.restarts, 2 * self.popsize)
        self.stall = 0

    def spawn(self, x0, seed: int) -> "CMA":
        """A search at ``x0`` that keeps this one's step size, covariance and population (a warm
        start for a neighbouring problem, e.g. a structure one variation away), with its own
        random stream (``seed``) and no best point yet."""
        if self._pending is not None:
            raise RuntimeError("spawn only between tell() and ask()")
        child = copy.copy(self)
        child.es = pickle.loads(pickle.dumps(self.es))
        child.es.mean = np.asarray(x0, float) / child.scale
        child.es.opts["randn"].rng = np.random.default_rng(seed)
        child.seed, child.restarts = int(seed), 0
        child.best_value, child.best_x, child.stall = math.inf, None, 0
        return child

    _STATE = ("es", "scale", "scale_floor", "relative", "sigma0", "seed", "restart_sigma",
              "restart_stall", "restarts", "best_value", "best_x", "stall")

    def state(self) -> str:
        """The optimiser with its generator, scale and restart bookkeeping, pickled (base64)."""
        if self._pending is not None:
            raise RuntimeError("checkpoint only between tell() and ask()")
        return base64.b64encode(pickle.dumps({k: getattr(self, k) for k in self._STATE})) \
            .decode("ascii")

    def load_state(self, text: str) -> "CMA":
        """Restore a :meth:`state` (unpickled: load only checkpoints this program wrote)."""
        st = pickle.loads(base64.b64decode(text))
        if isinstance(st, tuple):                    # written before restarts lived here
            st = {"es": st[0], "scale": st[1]}
        for k, v in st.items():
            setattr(self, k, v)
        self._pending = None
        return self


class PolicySearch:
    """CMA-ES over the parameters q of a fixed law structure (ask/tell, checkpointable).

    Parameters
    ----------
    structure : NetworkOperator
        The law; its q is the start point.
    target : Target
    seed, sigma, scale, popsize, bounds, scale_floor :
        Options of :class:`CMA` (``sigma`` relative to the scale of each q).
    """

    def __init__(self, structure: NetworkOperator, target: Target, seed: int = 1,
                 sigma: float = 0.3, scale=None, popsize: int | None = None,
                 bounds: tuple | None = None, scale_floor: float = 0.1,
                 restart_sigma: float = IPOP_SIGMA, restart_stall: int = IPOP_STALL):
        self.structure = structure
        self.target = target
        self.cma = CMA(structure.q, sigma, seed, scale, popsize, bounds, scale_floor,
                       restart_sigma=restart_sigma, restart_stall=restart_stall)
        self.evaluations = 0
        self.generations = 0
        self.best_law, self.best_f = None, None          # best feasible law and its objectives
        self.history = []            # per generation: (evaluations, best feasible objective)
        self._pending = None

    @property
    def restarts(self) -> int:
        """IPOP restarts so far (:class:`CMA`)."""
        return self.cma.restarts

    @property
    def popsize(self) -> int:
        return self.cma.popsize

    @property
    def sigma(self) -> float:
        return self.cma.sigma

    def ask(self) -> list:
        """Candidate laws of the next CMA-ES generation."""
        if self._pending is None:
            self._pending = [self.structure.with_q([float(v) for v in x])
                             for x in self.cma.ask()]
        return list(self._pending)

    def tell(self, F) -> None:
        """Objective rows of the candidates of the last :meth:`ask`."""
        if self._pending is None:
            raise RuntimeError("tell() without a pending ask()")
        F = np.atleast_2d(np.asarray(F, float))
        if len(F) != len(self._pending) or not np.all(np.isfinite(F)):
            raise ValueError(f"expected {len(self._pending)} finite objective rows, got shape "
                             f"{F.shape}")
        self.cma.tell(self.target.scalar(F))
        k = self.target.best(F)
        obj = self.target.objective
        if k is not None and (self.best_f is None or F[k, obj] < self.best_f[obj]):
            self.best_law, self.best_f = self._pending[k], F[k].copy()
        self._pending = None
        self.evaluations += len(F)
        self.generations += 1
        self.history.append((self.evaluations, None if self.best_f is None
                             else float(self.best_f[obj])))

    def run(self, evaluate, evaluations: int, callback=None) -> "PolicySearch":
        """Generations until ``evaluations`` more candidates were evaluated (whole generations).

        ``evaluate(laws) -> F`` (rows); ``callback(search)`` after every generation.
        """
        stop = self.evaluations + evaluations
        while self.evaluations < stop:
            self.tell(evaluate(self.ask()))
            if callback is not None:
                callback(self)
        return self

    # -- checkpoint -----------------------------------------------------------------------
    def state(self) -> dict:
        """JSON-serialisable state (the pickled optimiser and its generator, base64)."""
        if self._pending is not None:
            raise RuntimeError("checkpoint only between tell() and ask()")
        return {"cma": self.cma.state(), "evaluations": self.evaluations,
                "generations": self.generations, "restarts": self.restarts,
                "best_law": None if self.best_law is None else self.best_law.to_dict(),
                "best_f": None if self.best_f is None else self.best_f.tolist(),
                "history": self.history}

    def load_state(self, st: dict) -> "PolicySearch":
        """Restore a :meth:`state` of a search with the same structure and options."""
        self.cma.load_state(st["cma"])
        if "best_scalar" in st:                  # restart bookkeeping of an older checkpoint
            c = self.cma
            c.restarts, c.best_value, c.best_x, c.stall = (st["restarts"], st["best_scalar"],
                                                           st["best_x"], st["stall"])
        self.evaluations, self.generations = st["evaluations"], st["generations"]
        self.best_law = (None if st["best_law"] is None
                         else NetworkOperator.from_dict(st["best_law"]))
        self.best_f = None if st["best_f"] is None else np.array(st["best_f"], float)
        self.history = [tuple(h) for h in st["history"]]
        self._pending = None
        return self


# -- law structures --------------------------------------------------------------------------
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
