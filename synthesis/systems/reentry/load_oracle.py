"""The physical limits of S1 guidance per sample, computed once and kept by content.

* the **oracle bound** (:mod:`.oracle`): the miss of the best constant control with the true
  parameters -- no law with |u| <= 0.2 misses less;
* the **load oracle**: the least peak load J1 of any program on the controller's 1 s grid that
  lands exactly (zero miss) with perfect knowledge of the sample -- the bound of
  :func:`.bound.optimize_open_loop` (true-peak minimax, exact sensitivities) with the sample's
  true parameters.  A solve from scratch costs minutes here; warm-started it costs seconds: the
  sample's program is first solved on a 2 s grid from the nominal 2 s program (cached), then
  on the 1 s grid from it (on a test sample: 3 SLSQP iterations, J1 equal to the cold 1 s
  solve to 1e-6).  A sample that no constant control lands has no zero-miss program: its load
  oracle is the J1 of the extreme constant control that misses least (the only way to reach
  the oracle's miss), marked ``exact = False``.

Both are kept in the cache folder (:func:`synthesis.paths.cache_dir`) per sample, under a key
of the code they depend on (plant, integrators, open-loop method, bound, the functions
computing them) and the sample's parameters, so every study and figure reuses them.
"""
from __future__ import annotations

import hashlib
import inspect
import json
from dataclasses import asdict
from functools import lru_cache

import numpy as np

from descent_fmus.models.reentry import U_BOUNDS, ReentryParams, simulate

__all__ = ["sample_limits", "set_limits", "load_oracle", "nominal_program", "COARSE_SEG"]

#: Segment of the warm start's first solve [s].
COARSE_SEG = 2.0


@lru_cache(maxsize=1)
def _code_key() -> str:
    from descent_fmus.models import integrators, reentry
    from descent_fmus.synthesis.methods import open_loop
    from descent_fmus.synthesis.systems.reentry import bound, oracle
    h = hashlib.sha256()
    for module in (reentry, integrators, open_loop, bound):
        h.update(inspect.getsource(module).encode())
    for function in (oracle.oracle_bound, oracle.constant_control_range, nominal_program,
                     load_oracle, sample_limits):
        h.update(inspect.getsource(function).encode())
    h.update(repr(COARSE_SEG).encode())
    return h.hexdigest()[:16]


def _folder():
    from descent_fmus.synthesis.paths import cache_dir
    return cache_dir() / f"reentry-limits-{_code_key()}"


def _sample_key(p: ReentryParams) -> str:
    return hashlib.sha256(repr(sorted(asdict(p).items())).encode()).hexdigest()[:20]


def _read(name: str):
    try:
        return json.loads((_folder() / name).read_text())
    except (OSError, ValueError):
        return None


def _write(name: str, value) -> None:
    path = _folder() / name
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(value))
        tmp.replace(path)
    except OSError:                   # a read-only cache: computed again next time
        pass


def nominal_program(base: ReentryParams = ReentryParams()) -> np.ndarray:
    """The zero-miss bound of the scenario ``base`` on the 2 s grid (the warm start; cached)."""
    from descent_fmus.synthesis.systems.reentry.bound import optimize_open_loop
    name = f"nominal-{_sample_key(base)}.json"
    cached = _read(name)
    if cached is not None:
        return np.asarray(cached["u"], float)
    u = optimize_open_loop(base, t_seg=COARSE_SEG).u
    _write(name, {"u": [float(v) for v in u]})
    return u


def load_oracle(p: ReentryParams, base: ReentryParams = ReentryParams()) -> float:
    """J1 of the zero-miss bound of the sample ``p`` on the 1 s grid (module docstring)."""
    from descent_fmus.synthesis.systems.reentry.bound import optimize_open_loop
    coarse = optimize_open_loop(p, t_seg=COARSE_SEG, u0=nominal_program(base), tol=1e-7,
                                maxiter=100)
    fine = optimize_open_loop(p, t_seg=1.0, u0=np.repeat(coarse.u, int(COARSE_SEG)),
                              tol=1e-7, maxiter=60)
    return float(fine.J1)


def sample_limits(p: ReentryParams, load: bool = True,
                  base: ReentryParams = ReentryParams()) -> dict:
    """``{"miss", "exact", "L_min", "L_max", "J1_load", "load_exact"}`` of the sample ``p``
    (``J1_load`` only with ``load``), from the cache where it is there."""
    from descent_fmus.synthesis.systems.reentry.oracle import oracle_bound
    name = f"{_sample_key(p)}.json"
    got = _read(name) or {}
    if "miss" not in got:
        b = oracle_bound(p)
        got.update(miss=b.miss, exact=b.exact, L_min=b.L_min, L_max=b.L_max)
        _write(name, got)
    if load and "J1_load" not in got:
        if got["exact"]:
            got.update(J1_load=load_oracle(p, base), load_exact=True)
        else:                              # the extreme that misses least
            u = U_BOUNDS[1] if got["L_min"] > p.Lf else U_BOUNDS[0]
            got.update(J1_load=float(simulate(p, lambda t, x: u).load_max), load_exact=False)
        _write(name, got)
    return got


def set_limits(params, load: bool = True, base: ReentryParams = ReentryParams(),
               progress=None) -> list:
    """:func:`sample_limits` of every sample (``progress(k, n)`` after each)."""
    out = []
    for k, p in enumerate(params):
        out.append(sample_limits(p, load, base))
        if progress is not None:
            progress(k + 1, len(params))
    return out
