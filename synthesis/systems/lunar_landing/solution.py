"""S3 lunar soft landing: the paper's shooting problem solved and drawn.

* :func:`solve_landing` -- the paper's shooting problem solved by
  :mod:`synthesis.methods.shooting`, reported beside the exact solution
  (:func:`models.lunar_landing.optimal_landing`);
* :func:`plot_solution` -- the paper's figures 1-2 (V, h, m vs t; phase plane).

The closed loops through the FMUs and the dispersion study are
:mod:`synthesis.systems.lunar_landing.study`.

References
----------
T.Yu. Mozzhorina, 2017 (Tables 1-2, Figs. 1-2).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from descent_fmus.models.lunar_landing import (LanderParams, OptimalLanding, constant_flow_state,
                                               optimal_landing)
from descent_fmus.synthesis.methods.shooting import ShootingError, ShootingResult, solve
from descent_fmus.synthesis.plotting import save_figure

__all__ = ["LandingSolution", "solve_landing", "plot_solution", "DEFAULT_GUESS"]

#: The paper's guess I, (psi1(0), psi3(0), T) (Mozzhorina 2017, Table 1).
DEFAULT_GUESS = (-0.15, -0.7, 15.0)


@dataclass
class LandingSolution:
    """A shooting solve of S3 with the numbers of the paper's Table 2 and the exact values.

    Attributes
    ----------
    params : LanderParams
    result : ShootingResult
    t_switch, T : float
        Switch and final time [s].
    V_switch, h_switch : float
        Downward speed [m/s] and altitude [m] at the switch.
    fuel : float
        Fuel burnt [kg].
    psi1, psi3_0 : float
        psi1(0), psi3(0) found by the shooting.
    exact : OptimalLanding
        The closed-form optimum of the same data.
    """

    params: LanderParams
    result: ShootingResult
    t_switch: float
    T: float
    V_switch: float
    h_switch: float
    fuel: float
    psi1: float
    psi3_0: float
    exact: OptimalLanding

    def summary(self) -> dict:
        r = self.result
        ex = self.exact
        out = dict(t_switch=self.t_switch, T=self.T, V_switch=self.V_switch,
                   h_switch=self.h_switch, fuel=self.fuel, psi1=self.psi1, psi3_0=self.psi3_0,
                   iterations=r.iterations, residual_norm=r.residual_norm,
                   initial_residual_norm=r.initial_residual_norm, method=r.method,
                   evaluations=r.evaluations, switches=list(map(float, r.trajectory.switches)),
                   params=asdict(self.params))
        out["exact"] = asdict(ex)
        out["relative_error"] = {k: abs(out[k] - getattr(ex, k)) / abs(getattr(ex, k))
                                 for k in ("t_switch", "T", "fuel", "h_switch", "V_switch")}
        out["relative_error"]["psi1"] = abs(self.psi1 - ex.psi1) / abs(ex.psi1)
        out["relative_error"]["psi3_0"] = abs(self.psi3_0 - ex.psi3_0) / abs(ex.psi3_0)
        return out


def solve_landing(p: LanderParams = LanderParams(), guess=DEFAULT_GUESS,
                  method: str = "event", damped: bool = False, n_steps: int = 1000,
                  tol: float | None = None) -> LandingSolution:
    """Solve S3 by shooting from ``guess = (psi1(0), psi3(0), T)``.

    Parameters
    ----------
    p : LanderParams
    guess : tuple of 3 float
        ``(psi1(0), psi3(0), T [s])``; ``psi3(0)`` may be None: then it is set by the paper's
        eq. (8) for a switch at ``T/2``.
    method : {"event", "interpolate"}
        Switch handling of :func:`synthesis.methods.shooting.solve`.
    damped : bool
        Modified (damped) Newton instead of the classical one.
    n_steps : int
        RK4 steps of the ``interpolate`` method.
    tol : float, optional
        Max-norm of the residuals to stop at (default: the solver's, per method).

    Raises
    ------
    models.lunar_landing.InfeasibleLandingError
        ``umax`` too small to stop the lander (checked before shooting).
    synthesis.methods.shooting.ShootingError
        Singular Jacobian (no switch for this guess), integration failure, no convergence.
    """
    from descent_fmus.synthesis.systems.lunar_landing.problems import (landing_problem,
                                                                       paper_guess)

    p.require_stoppable()
    exact = optimal_landing(p)
    psi1, psi3, T = guess
    if psi3 is None:
        psi1, psi3, T = paper_guess(psi1, T, p)
    res = solve(landing_problem(p), (psi1, psi3, T), method=method, damped=damped,
                n_steps=n_steps, tol=tol)
    tr = res.trajectory
    if len(tr.switches) != 1:
        raise ShootingError(f"the converged trajectory switches {len(tr.switches)} times; the "
                            f"fuel-optimal landing switches once (coast, then full thrust)")
    ts = float(tr.switches[0])
    y_sw = constant_flow_state((p.h0, p.V0, p.m0), 0.0, ts, p.gL, p.beta)   # the coast: exact
    return LandingSolution(params=p, result=res, t_switch=ts, T=float(res.z[2]),
                           V_switch=y_sw[1], h_switch=y_sw[0], fuel=p.m0 - float(tr.y_T[2]),
                           psi1=float(res.z[0]), psi3_0=float(res.z[1]), exact=exact)


def plot_solution(sol: LandingSolution, path, extra_switches=(4.51, 4.91)) -> Path:
    """The paper's Figs. 1-2 as one PNG: V(t), h(t), m(t) and the phase plane V(h).

    Beside the optimum, free fall and full thrust switched on at ``extra_switches`` [s] (the
    paper shows 4.51 and 4.91 s) are drawn from the closed-form arcs.
    """
    import matplotlib.pyplot as plt

    p = sol.params
    tr = sol.result.trajectory

    def arc(t_on, t_end):
        ts = np.linspace(0.0, t_end, 600)
        rows = []
        for t in ts:
            if t_on is None or t <= t_on:
                x = constant_flow_state((p.h0, p.V0, p.m0), 0.0, t, p.gL, p.beta)
            else:
                xs = constant_flow_state((p.h0, p.V0, p.m0), 0.0, t_on, p.gL, p.beta)
                x = constant_flow_state(xs, p.umax, t - t_on, p.gL, p.beta)
            rows.append(x)
        rows = np.array(rows)
        keep = np.concatenate([[True], rows[:-1, 0] > 0.0])
        return ts[keep], rows[keep]

    fig, ax = plt.subplots(2, 2, figsize=(11, 8))
    curves = [("free fall", arc(None, 12.0), dict(color="0.5", ls=":"))]
    for t_on, ls in zip(extra_switches, ("--", "-.")):
        curves.append((f"engine on at {t_on:.2f} s", arc(t_on, sol.T * 1.15), dict(ls=ls)))
    for label, (t, x), kw in curves:
        ax[0, 0].plot(t, x[:, 1], label=label, **kw)
        ax[0, 1].plot(t, x[:, 0], label=label, **kw)
        ax[1, 0].plot(t, x[:, 2], label=label, **kw)
        ax[1, 1].plot(x[:, 0], x[:, 1], label=label, **kw)
    # the optimum: the shooting trajectory's points, joined by the arcs of its own switch time
    lab = f"optimum (shooting): engine on at {sol.t_switch:.4f} s"
    t, x = arc(sol.t_switch, sol.T)
    for a, (xs, ys, px, py) in zip(ax.flat, ((t, x[:, 1], tr.t, tr.y[:, 1]),
                                              (t, x[:, 0], tr.t, tr.y[:, 0]),
                                              (t, x[:, 2], tr.t, tr.y[:, 2]),
                                              (x[:, 0], x[:, 1], tr.y[:, 0], tr.y[:, 1]))):
        a.plot(xs, ys, "k", lw=1.6, label=lab)
        a.plot(px, py, "k.", ms=3)
    ax[0, 0].set(xlabel="t [s]", ylabel="V [m/s] (down)", title="Fig. 1a: speed")
    ax[0, 1].set(xlabel="t [s]", ylabel="h [m]", title="Fig. 1b: altitude")
    ax[1, 0].set(xlabel="t [s]", ylabel="m [kg]", title="Fig. 1c: mass")
    ax[1, 1].set(xlabel="h [m]", ylabel="V [m/s]", title="Fig. 2: phase trajectories")
    ax[0, 1].set_ylim(bottom=0.0)
    ax[1, 1].set_xlim(left=0.0)
    ax[0, 0].legend(fontsize=8)
    fig.suptitle(f"S3 lunar landing, umax = {p.umax} kg/s: T = {sol.T:.4f} s, "
                 f"fuel = {sol.fuel:.2f} kg ({sol.result.method}, {sol.result.iterations} "
                 f"Newton iterations)")
    return save_figure(fig, path, ax.flat, dpi=110)
