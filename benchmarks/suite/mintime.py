"""The references of the suite's minimum-time problems, each computed by other means than the
synthesis (docs/benchmarks/suite.md).

* **mintime-di** -- the closed-form least time to the origin of the double integrator with
  |u| <= 1 from every start (:func:`time_to_go`, the plant's own definition,
  ``plants/double_integrator.py``), their mean.  The problem's value of a flight (the arrival
  in the target set tgo <= tau plus the tgo left there) is never below it: T*(x(t)) >= T*(x0) - t
  along any admissible trajectory (else T* would not be least).
* **mintime-osc** -- per start the least number of steps N after which SOME program held over
  the law's step (any sampled law's flight is one) puts the harmonic oscillator in the target
  box: a linear-programming feasibility test (the final state is linear in the program, the
  box and the bound are linear constraints) at N = 1, 2, ... (:func:`least_steps`: the
  separating-axis test of :func:`box_reachable` for every N, then the program by
  ``scipy.optimize.linprog``).  No law's flight arrives before N h from that start.

The same LP with the box shrunk to the origin and a fine step is the tests' independent check of
the closed form (:func:`min_time_lp`).  The exact zero-order-hold discretisation of both plants
is :func:`riccati.van_loan` (a matrix exponential), not the plants' own step formulas.
"""
from __future__ import annotations

import importlib.util

import numpy as np

from plant_flights import SUITE
from riccati import van_loan

__all__ = ["time_to_go", "plant_matrices", "discretise", "reach_program", "box_reachable",
           "least_steps",
           "min_time_lp", "mintime_di_reference", "mintime_osc_reference", "switching_law_di"]


def _plant_module(name: str):
    """The plant file ``plants/<name>.py`` as a module (its closed forms, one definition)."""
    spec = importlib.util.spec_from_file_location(f"suite_plant_{name}",
                                                  SUITE / "plants" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def time_to_go(x1: float, x2: float, u_max: float = 1.0) -> float:
    """The least time from (x1, x2) to the origin of the double integrator with |u| <= u_max
    (closed form, as the plant outputs it)."""
    return _plant_module("double_integrator").time_to_go(x1, x2, u_max)


#: (A, B) of the suite's second-order plants: x1' = x2, x2' = -k x1 + u
PLANTS = {"double-integrator": 0.0, "oscillator": 1.0}


def plant_matrices(kind: str) -> tuple:
    """(A, B) of ``kind`` (:data:`PLANTS`)."""
    A = np.array([[0.0, 1.0], [-PLANTS[kind], 0.0]])
    return A, np.array([[0.0], [1.0]])


def discretise(kind: str, h: float) -> tuple:
    """(Ad, Bd): x_{k+1} = Ad x_k + Bd u_k for u held over h (exact)."""
    A, B = plant_matrices(kind)
    Ad, Bd = van_loan(A, B, np.zeros((2, 2)), np.zeros((1, 1)), h)[:2]
    return Ad, Bd[:, 0]


def reach_program(Ad, Bd, x0, steps: int, eps: float = 0.0, u_max: float = 1.0):
    """A program u_0..u_{N-1} (|u_k| <= u_max) with max(|x_N|) <= eps, or None if there is
    none: x_N = Ad^N x0 + sum_k Ad^(N-1-k) Bd u_k is linear in u, so this is an LP
    feasibility problem (zero cost; equality constraints for eps = 0)."""
    from scipy.optimize import linprog
    cols, P = [], np.eye(len(x0))
    for _ in range(steps):
        cols.append(P @ Bd)
        P = Ad @ P
    M = np.array(cols[::-1]).T                 # column k multiplies u_k
    free = P @ np.asarray(x0, float)
    bounds = [(-u_max, u_max)] * steps
    if eps > 0.0:
        r = linprog(np.zeros(steps), A_ub=np.vstack([M, -M]),
                    b_ub=np.r_[eps - free, eps + free], bounds=bounds, method="highs")
    else:
        r = linprog(np.zeros(steps), A_eq=M, b_eq=-free, bounds=bounds, method="highs")
    return r.x if r.status == 0 else None


def box_reachable(Ad, Bd, x0, steps: int, eps: float, u_max: float = 1.0) -> bool:
    """Whether some program of ``steps`` steps puts a 2-state plant in the box max(|x|) <= eps:
    the states it can reach form a zonotope (centre Ad^N x0, generators u_max Ad^j Bd), and two
    convex polygons meet iff their projections on every edge normal of both overlap (the
    separating-axis theorem) -- exact, and fast enough to try every step count."""
    G = np.empty((steps, 2))
    g, c = np.asarray(Bd, float), np.asarray(x0, float)
    for j in range(steps):
        G[j], g, c = g, Ad @ g, Ad @ c
    axes = np.vstack([np.eye(2), G[:, ::-1] * np.array([1.0, -1.0])])
    reach = u_max * np.abs(axes @ G.T).sum(axis=1) + eps * np.abs(axes).sum(axis=1)
    return bool(np.all(np.abs(axes @ c) <= reach * (1 + 1e-12) + 1e-12))


def least_steps(Ad, Bd, x0, eps: float, n_max: int, u_max: float = 1.0) -> tuple:
    """The least N <= n_max with a program into the box max(|x|) <= eps after N steps (every N
    from 0 up by :func:`box_reachable`: reachability of a box need not be monotone in N), and
    such a program (:func:`reach_program`).  (None, None) if there is none."""
    x0 = np.asarray(x0, float)
    if np.max(np.abs(x0)) <= eps:
        return 0, np.zeros(0)
    for n in range(1, n_max + 1):
        if box_reachable(Ad, Bd, x0, n, eps, u_max):
            return n, reach_program(Ad, Bd, x0, n, eps * (1 + 1e-9), u_max)
    return None, None


def min_time_lp(kind: str, x0, h: float, u_max: float = 1.0, n_max: int = 4000) -> float:
    """The least N h with a program held over h that brings ``kind`` from x0 to the origin
    exactly (bisection: the origin is an equilibrium at u = 0, so reaching it is monotone in N).
    A sampled program is an admissible continuous one: T* <= N h, and N h -> T* as h -> 0."""
    Ad, Bd = discretise(kind, h)
    lo, hi = 0, 1
    while reach_program(Ad, Bd, x0, hi, 0.0, u_max) is None:
        lo, hi = hi, 2 * hi
        if hi > n_max:
            raise ValueError(f"{kind}: the origin is not reached from {list(x0)} in {n_max} "
                             f"steps of {h}")
    while hi - lo > 1:                              # reach(lo) false, reach(hi) true
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if reach_program(Ad, Bd, x0, mid, 0.0, u_max) is not None \
            else (mid, hi)
    return hi * h


def _starts(problem) -> np.ndarray:
    return np.array([[s["x10"], s["x20"]] for s in problem.initial_states])


def mintime_di_reference(problem) -> dict:
    """The closed-form optimal time per start of ``mintime-di`` and their mean (the reference
    of the ``time`` objective)."""
    u_max = problem.basic().bounds[0][1]
    per = [float(time_to_go(x1, x2, u_max)) for x1, x2 in _starts(problem)]
    return {"per_start": per, "mean": float(np.mean(per)), "max": float(max(per)),
            "tau": problem.wiring.stop.value}


def mintime_osc_reference(problem) -> dict:
    """Per start of ``mintime-osc`` the least time N h after which a program held over the
    law's step h can be in the target box (:func:`least_steps`), the programs, their mean."""
    h, eps = problem.wiring.step, problem.wiring.stop.value
    u_max = problem.basic().bounds[0][1]
    Ad, Bd = discretise("oscillator", h)
    n_max = int(round(problem.wiring.stop_time / h))
    rows = []
    for x0 in _starts(problem):
        n, u = least_steps(Ad, Bd, x0, eps, n_max, u_max)
        if n is None:
            raise ValueError(f"mintime-osc: no program reaches the box from {list(x0)} within "
                             f"the stop time")
        rows.append({"start": x0.tolist(), "steps": n, "time": n * h, "u": u.tolist()})
    times = [r["time"] for r in rows]
    return {"per_start": rows, "mean": float(np.mean(times)), "max": float(max(times)),
            "step": h, "eps": eps}


def switching_law_di(h: float, gain: float = 2.0, floor: float = 1e-3):
    """A sampled law of the double integrator near the time-optimal one (for checks, not a
    reference): drive s = x1 + x2 |x2| / 2 (zero on the switching curve) to zero at the rate
    s / (gain h), ds/dt = x2 + |x2| u, so u = -(x2 + s / (gain h)) / |x2|, clipped to +-1 by
    the plant -- the bang-bang law far from the curve, and no chattering along it."""
    def law(y: dict) -> tuple:
        x1, x2 = y["x1"], y["x2"]
        s = x1 + 0.5 * x2 * abs(x2)
        return (-(x2 + s / (gain * h)) / (abs(x2) + floor),)
    return law

