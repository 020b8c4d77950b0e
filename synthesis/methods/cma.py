"""CMA-ES (pycma) on a real vector: seeded, checkpointable, with IPOP restarts.

One class serves the fixed-structure baselines (:mod:`synthesis.methods.policy_search`) and the
parameter refinement inside the network-operator search (:mod:`synthesis.methods.refinement`).
Values to minimise are floats, or ``(violation, value)`` pairs for problems with constraints
(a smaller violation is always better; CMA-ES itself only needs the order of a generation).

Determinism: the sampling uses a :class:`numpy.random.Generator` owned by the search (pycma's
``randn`` option), and :meth:`CMA.state` is the pickled optimiser with that generator, so a
restored search continues exactly as an uninterrupted one.

References
----------
N. Hansen, "The CMA Evolution Strategy: A Tutorial", arXiv:1604.00772; pycma (github.com/CMA-ES);
A. Auger, N. Hansen, "A restart CMA evolution strategy with increasing population size", CEC 2005.
"""
from __future__ import annotations

import base64
import copy
import math
import pickle

import numpy as np

__all__ = ["CMA", "NormalSource", "IPOP_SIGMA", "IPOP_STALL"]


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
        self.restarts, self.best_key, self.best_x, self.stall = 0, (math.inf, math.inf), None, 0
        self.stall_mark = self.best_key   # the best key when the stall count last ended
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

    def ask_rows(self) -> np.ndarray:
        """:meth:`ask` as one array, a candidate a row: the same values, the scale, the bounds
        and ``x_map`` applied to the whole generation at once (``x_map`` must take rows, as
        :meth:`GrayCodec.grid <synthesis.methods.encoding.GrayCodec.grid>` does: elementwise)."""
        if self._pending is None:
            self._pending = self.es.ask()
        return np.asarray(self.x(self._pending), float)      # x() is elementwise: rows too

    def tell(self, values, stall_gain: float = 0.0) -> None:
        """Values to minimise of the candidates of the last :meth:`ask`, same order: floats, or
        ``(violation, value)`` pairs (compared as tuples).  ``stall_gain``: this generation
        ends the stall count (``restart_stall``) only if its best beats the best at the last
        end of a stall by more than this share (a lower violation always does); 0: any better
        value does."""
        if self._pending is None:
            raise RuntimeError("tell() without a pending ask()")
        keys = [(float(v[0]), float(v[1])) if isinstance(v, tuple) else (0.0, float(v))
                for v in values]
        if len(keys) != len(self._pending) or not all(map(math.isfinite,
                                                          (x for k in keys for x in k))):
            raise ValueError(f"expected {len(self._pending)} finite values, got {values}")
        if any(k[0] for k in keys):         # constraints: CMA-ES needs only the order
            order = sorted(range(len(keys)), key=keys.__getitem__)
            fitness = [0.0] * len(keys)
            for rank, i in enumerate(order):
                fitness[i] = float(rank)
        else:
            fitness = [k[1] for k in keys]
        self.es.tell(self._pending, fitness)
        i = min(range(len(keys)), key=keys.__getitem__)
        if keys[i] < self.best_key:
            self.best_key, self.best_x = keys[i], [float(v) for v in self.x(self._pending[i])]
        mark = self.stall_mark
        if stall_gain:                 # a better value by more than the share `stall_gain`
            mark = (mark[0], mark[1] - stall_gain * abs(mark[1]))
        if keys[i] < mark:
            self.stall, self.stall_mark = 0, self.best_key
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
        child.best_key, child.best_x, child.stall = (math.inf, math.inf), None, 0
        child.stall_mark = child.best_key
        return child

    _STATE = ("es", "scale", "scale_floor", "relative", "sigma0", "seed", "restart_sigma",
              "restart_stall", "restarts", "best_key", "best_x", "stall", "stall_mark")

    def state(self) -> str:
        """The optimiser with its generator, scale and restart bookkeeping, pickled (base64)."""
        if self._pending is not None:
            raise RuntimeError("checkpoint only between tell() and ask()")
        return base64.b64encode(pickle.dumps({k: getattr(self, k) for k in self._STATE})) \
            .decode("ascii")

    def load_state(self, text: str) -> "CMA":
        """Restore a :meth:`state` (unpickled: load only checkpoints this program wrote)."""
        st = pickle.loads(base64.b64decode(text))
        st.setdefault("stall_mark", st.get("best_key", self.best_key))  # older checkpoints
        for k, v in st.items():
            setattr(self, k, v)
        self._pending = None
        return self
