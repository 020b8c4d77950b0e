"""The best open-loop program for S1: piecewise-constant u(t) minimising the max load at zero miss.

No feedback law can beat the best open-loop program on the nominal flight (SPEC S1), so its J1 is
the limit the network-operator synthesis approaches.  Epigraph form, solved with SciPy's SLSQP:

    minimise s  over (u_1..u_N, s)
    subject to  load(t_i; u) <= s at every integration sample t_i,
                L(tf; u) - Lf = 0,   -0.2 <= u_k <= 0.2,

with u_k held on segments of equal length ``t_seg`` (default 300 s / 120).  Gradients by forward
differences of in-process flights (models.reentry, the same functions the FMU runs).

References
----------
Seed 000 (the paper compares its feedback law with the optimal program of refs. [1, 2] there).
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from models.reentry import (T_PLUS, U_BOUNDS, ReentryParams, downrange, simulate)

__all__ = ["Program", "fly_program", "optimize_open_loop"]


@dataclass
class Program:
    """A piecewise-constant control program u(t) = u[k] for k*t_seg <= t < (k+1)*t_seg."""

    u: np.ndarray
    t_seg: float
    J1: float = math.nan
    miss: float = math.nan
    t_land: float = math.nan
    info: dict = field(default_factory=dict)

    def __call__(self, t: float) -> float:
        k = min(int(t / self.t_seg + 1e-9), len(self.u) - 1)
        return float(self.u[k])

    def to_dict(self) -> dict:
        return {"u": [float(v) for v in self.u], "t_seg": self.t_seg, "J1": self.J1,
                "miss": self.miss, "t_land": self.t_land, "info": self.info}

    def save(self, path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1))
        return path

    @classmethod
    def load(cls, path) -> "Program":
        try:
            d = json.loads(Path(path).read_text())
            return cls(np.asarray(d["u"], float), float(d["t_seg"]), d.get("J1", math.nan),
                       d.get("miss", math.nan), d.get("t_land", math.nan), d.get("info", {}))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{path} is not a program file: {exc}") from None


def fly_program(u, t_seg: float, p: ReentryParams = ReentryParams(), trace: bool = False):
    """Fly the program in-process (communication step = segment length)."""
    u = np.asarray(u, float)
    prog = lambda t, x: float(u[min(int(t / t_seg + 1e-9), len(u) - 1)])  # noqa: E731
    return simulate(p, prog, step=t_seg, t_plus=T_PLUS, trace=trace)


def optimize_open_loop(p: ReentryParams = ReentryParams(), segments: int = 120,
                       t_total: float = T_PLUS, maxiter: int = 200, tol: float = 1e-9,
                       u0=None, progress=None) -> Program:
    """Best piecewise-constant program (SLSQP on the epigraph form; see the module docstring).

    Parameters
    ----------
    p : ReentryParams
        Scenario.
    segments : int
        Number N of constant pieces over ``t_total`` [s].
    maxiter, tol : int, float
        SLSQP limits.
    u0 : array-like, optional
        Starting program (default u = 0).
    progress : callable, optional
        Called with (iteration, J1, miss) after every SLSQP iteration.

    Returns
    -------
    Program
        With ``J1`` (max load), ``miss`` |L(tf) - Lf| [m], ``t_land`` and solver ``info``.
    """
    if segments < 1:
        raise ValueError(f"segments must be >= 1, got {segments}")
    t_seg = t_total / segments
    n_samples = int(round(T_PLUS / 0.5)) + segments + 8   # upper bound on load samples

    def run(u):
        fi = fly_program(u, t_seg, p, trace=True)
        loads = np.zeros(n_samples)
        tr = np.asarray(fi.trace[:n_samples])
        loads[:len(tr)] = tr
        miss = downrange(fi.x, p.Rz) - p.Lf
        if not fi.landed:   # did not reach hf: count the altitude still to go as miss
            miss = -abs(miss) - (fi.x and (math.hypot(fi.x[0], fi.x[2]) - p.Rz - p.hf))
        return loads, miss

    cache = {}

    def eval_with_jac(z):
        key = z.tobytes()
        if key in cache:
            return cache[key]
        u = z[:-1]
        loads0, miss0 = run(u)
        eps = 1e-6
        jl = np.zeros((n_samples, segments))
        jm = np.zeros(segments)
        for k in range(segments):
            du = u.copy()
            du[k] += eps if du[k] + eps <= U_BOUNDS[1] else -eps
            h = du[k] - u[k]
            lk, mk = run(du)
            jl[:, k] = (lk - loads0) / h
            jm[k] = (mk - miss0) / h
        cache.clear()
        cache[key] = (loads0, miss0, jl, jm)
        return cache[key]

    scale_m = 1e-4   # miss in units of 10 km keeps the constraint well scaled

    cons = [
        {"type": "ineq", "fun": lambda z: z[-1] - eval_with_jac(z)[0],
         "jac": lambda z: np.hstack([-eval_with_jac(z)[2], np.ones((n_samples, 1))])},
        {"type": "eq", "fun": lambda z: np.array([eval_with_jac(z)[1] * scale_m]),
         "jac": lambda z: np.hstack([eval_with_jac(z)[3] * scale_m, [0.0]])[None, :]},
    ]
    u_start = np.zeros(segments) if u0 is None else np.clip(np.asarray(u0, float), *U_BOUNDS)
    z0 = np.append(u_start, run(u_start)[0].max())
    bounds = [U_BOUNDS] * segments + [(0.0, None)]
    it = [0]

    def callback(z):
        it[0] += 1
        if progress is not None:
            loads, miss = run(z[:-1])
            progress(it[0], float(loads.max()), float(abs(miss)))

    t0 = time.perf_counter()
    res = minimize(lambda z: z[-1], z0, jac=lambda z: np.append(np.zeros(segments), 1.0),
                   method="SLSQP", bounds=bounds, constraints=cons, callback=callback,
                   options={"maxiter": maxiter, "ftol": tol})
    u = np.clip(res.x[:-1], *U_BOUNDS)
    fi = fly_program(u, t_seg, p)
    return Program(u, t_seg, J1=fi.load_max, miss=abs(downrange(fi.x, p.Rz) - p.Lf),
                   t_land=fi.t_land if fi.landed else math.nan,
                   info={"success": bool(res.success), "message": str(res.message),
                         "iterations": int(res.nit), "seconds": time.perf_counter() - t0,
                         "segments": segments})
