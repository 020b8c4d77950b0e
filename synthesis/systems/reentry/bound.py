"""The bound for S1 feedback laws: the best open-loop program u(t) (min max load at zero miss).

No feedback law can beat the best open-loop program on the nominal flight, so its J1 is the limit
the network-operator synthesis approaches.  :func:`optimize_open_loop` solves

    minimise max_i load(t_i; u)   subject to  L(tf; u) - Lf = 0,   -0.2 <= u_k <= 0.2,

over u_k held on segments of equal length ``t_seg`` (default 300 s / 120), with
:func:`synthesis.methods.open_loop.minimax_program` on in-process flights (models.reentry, the same
functions the FMU runs).

References
----------
Diveev & Shmalko (the paper compares its feedback law with the optimal program of its refs.).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from descent_fmus.models.integrators import REACHED
from descent_fmus.models.reentry import T_PLUS, U_BOUNDS, ReentryParams, downrange, simulate
from descent_fmus.synthesis.methods.open_loop import minimax_program

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
        if fi.status != REACHED:   # did not reach hf: count the altitude still to go as miss
            miss = -abs(miss) - (math.hypot(fi.x[0], fi.x[2]) - p.Rz - p.hf)
        return loads, miss

    # miss in units of 10 km keeps the equality constraint well scaled
    u, info = minimax_program(run, segments, U_BOUNDS, u0=u0, eq_scale=1e-4, maxiter=maxiter,
                              tol=tol, progress=progress)
    fi = fly_program(u, t_seg, p)
    info["segments"] = segments
    return Program(u, t_seg, J1=fi.load_max, miss=abs(downrange(fi.x, p.Rz) - p.Lf),
                   t_land=fi.t_end if fi.status == REACHED else math.nan, info=info)


def plot_program(prog: Program, path) -> Path:
    """PNG: the program u(t) and the load along its flight."""
    import matplotlib.pyplot as plt

    from descent_fmus.synthesis.plotting import save_figure
    fi = fly_program(prog.u, prog.t_seg, trace=True)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    t = np.arange(len(prog.u)) * prog.t_seg
    ax[0].step(t, prog.u, where="post")
    ax[0].set(xlabel="t [s]", ylabel="u", title=f"best program, N = {len(prog.u)}")
    ax[1].plot(np.linspace(0, fi.t, len(fi.trace)), fi.trace)
    ax[1].set(xlabel="t [s] (samples)", ylabel="load", title=f"J1 = {prog.J1:.4f}")
    return save_figure(fig, path, ax, dpi=110)
