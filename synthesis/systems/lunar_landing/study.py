"""S3 lunar soft landing: shooting solve, closed-loop flights through the FMUs, dispersion study.

* :func:`solve_landing` -- the paper's shooting problem solved by
  :mod:`synthesis.methods.shooting`, reported beside the exact solution
  (:func:`models.lunar_landing.optimal_landing`);
* :func:`plot_solution` -- the paper's figures 1-2 (V, h, m vs t; phase plane);
* :func:`fly_feedback_in_process` -- the feedback law flown without FMUs (same functions);
* :class:`LandingLoops` -- the program and feedback closed loops (fmpy, FMUs loaded once);
* :func:`dispersion` / :func:`dispersion_table` / :func:`plot_dispersion` -- seeded dispersion
  of h0, V0 (+-10 %) and gL (+-2 %) (:func:`dispersion_box`): the feedback law lands softly, the
  open-loop program does not.

References
----------
T.Yu. Mozzhorina, 2017 (Tables 1-2, Figs. 1-2, closing remark on synthesis).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from descent_fmus.models.controllers.lunar_landing_switch import SwitchLaw
from descent_fmus.models.integrators import REACHED
from descent_fmus.models.lunar_landing import (STEP, LanderIntegrator, LanderParams,
                                               OptimalLanding, constant_flow_state,
                                               optimal_landing)
from descent_fmus.synthesis.problems.dispersion import Box
from descent_fmus.synthesis.methods.shooting import ShootingError, ShootingResult, solve
from descent_fmus.synthesis.plotting import save_figure

__all__ = ["LandingSolution", "solve_landing", "plot_solution", "fly_feedback_in_process",
           "LandingLoops", "Touchdown", "dispersion_box", "dispersion", "dispersion_table",
           "plot_dispersion", "finite_or_none", "SOFT_SPEED", "DISPERSION", "DEFAULT_GUESS",
           "LAWS"]

#: A touchdown is soft when |V| at h = 0 is below this [m/s] ([choice], models/README.md).
SOFT_SPEED = 0.05
#: Relative half-widths of the dispersion box: h0, V0 (+-10 %) and gL (+-2 %).
DISPERSION = dict(h0=0.10, V0=0.10, gL=0.02)
#: The paper's guess I, (psi1(0), psi3(0), T) (Mozzhorina 2017, Table 1).
DEFAULT_GUESS = (-0.15, -0.7, 15.0)
#: The two closed loops: the open-loop optimal program and the optimal law as feedback.
LAWS = ("program", "feedback")


def fly_feedback_in_process(p: LanderParams = LanderParams(), dt: float = STEP,
                            max_steps: int = 4000):
    """The feedback law flown without FMUs: the same SwitchLaw and LanderIntegrator the FMUs
    run, the same master order (read state, law, step).

    Parameters
    ----------
    p : LanderParams
    dt : float
        Communication step [s].
    max_steps : int
        Steps after which the flight is abandoned.

    Returns
    -------
    (LanderIntegrator, int)
        The integrator after the flight (``status``, ``t_end``, ``V_touchdown``, ``x``) and the
        number of steps taken.
    """
    fi, law = LanderIntegrator(p), SwitchLaw(dt=dt)
    k = 0
    while fi.running and k < max_steps:
        u = law.control(*fi.x)
        V = fi.x[1]
        fi.advance((k + 1) * dt, u)
        law.stepped(V, u, dt)
        k += 1
    return fi, k


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


# --------------------------------------------------------------------------- closed loops
@dataclass
class Touchdown:
    """Outcome of one closed-loop landing through the FMUs.

    Attributes
    ----------
    law : {"program", "feedback"}
    h0, V0, gL : float
        Start altitude [m], downward speed [m/s] and gravity [m/s2] of the flight.
    status : int
        The plant's final ``status`` (1 REACHED = touched down; 0 still flying at t+).
    V_touchdown : float
        Downward speed at touchdown [m/s] (NaN if it never touched down).
    t_touchdown : float
        Time of touchdown [s], the plant's ``t_end`` (NaN if it never touched down).
    fuel : float
        Fuel burnt [kg].
    """

    law: str
    h0: float
    V0: float
    gL: float
    status: int
    V_touchdown: float
    t_touchdown: float
    fuel: float

    @property
    def touched_down(self) -> bool:
        return self.status == REACHED

    @property
    def soft(self) -> bool:
        return self.touched_down and abs(self.V_touchdown) < SOFT_SPEED

    def summary(self) -> dict:
        """JSON-ready: NaN (no touchdown) becomes None."""
        return dict(status=self.status, touched_down=self.touched_down,
                    V_touchdown=finite_or_none(self.V_touchdown),
                    t_touchdown=finite_or_none(self.t_touchdown), fuel=self.fuel,
                    soft=self.soft)


def finite_or_none(value):
    """``value`` for JSON: every non-finite float in it (no touchdown) becomes None."""
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class LandingLoops:
    """The program and the feedback closed loops, each loaded once and reset per run.

    Parameters
    ----------
    fmu_dir : path-like, optional
        Folder of the built FMUs (``LunarLander.fmu``, ``LandingProgram.fmu``,
        ``LandingSwitch.fmu``); default :func:`synthesis.paths.fmu_dir`.
    nominal : LanderParams
        The conditions the program is computed for (its t_switch, t_off) and the feedback law's
        nominal umax, beta, gL.
    """

    RECORD = ("h", "V", "m", "fuel")

    def __init__(self, fmu_dir=None, nominal: LanderParams = LanderParams()):
        from descent_fmus.synthesis.fmi.loop import open_loop
        from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir
        from descent_fmus.synthesis.systems.lunar_landing.problems import (FEEDBACK_WIRING,
                                                                           PROGRAM_WIRING,
                                                                           program_defaults)

        d = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
        self.nominal = nominal
        self.program_values = program_defaults(nominal)
        self.feedback_values = {"umax": nominal.umax, "beta": nominal.beta,
                                "g_nominal": nominal.gL}
        self.loops = {}
        try:
            self.loops["program"] = open_loop(PROGRAM_WIRING, d / "LunarLander.fmu",
                                              d / "LandingProgram.fmu", native=False,
                                              record=self.RECORD)
            self.loops["feedback"] = open_loop(FEEDBACK_WIRING, d / "LunarLander.fmu",
                                               d / "LandingSwitch.fmu", native=False,
                                               record=self.RECORD)
        except Exception:
            self.close()
            raise

    def close(self):
        for loop in self.loops.values():
            loop.close()
        self.loops = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def fly(self, law: str, h0=None, V0=None, gL=None, estimate_g: bool = True,
            record: bool = False):
        """One landing of ``law`` ("program" | "feedback") from (h0, V0) in gravity gL.

        Parameters
        ----------
        law : {"program", "feedback"}
        h0, V0, gL : float, optional
            Start altitude [m], downward speed [m/s], gravity [m/s2]; default the nominal ones.
        estimate_g : bool
            The feedback law estimates the gravity from coast steps.
        record : bool
            Record the trajectories (h, V, m, fuel, u).

        Returns
        -------
        (Touchdown, ClosedLoopResult)
        """
        if law not in self.loops:
            raise ValueError(f"unknown law {law!r}; choose program or feedback")
        n = self.nominal
        plant = {"h0": n.h0 if h0 is None else h0, "V0": n.V0 if V0 is None else V0,
                 "gL": n.gL if gL is None else gL, "m0": n.m0, "umax": n.umax,
                 "beta": n.beta}
        ctrl = dict(self.program_values if law == "program" else self.feedback_values)
        if law == "feedback":
            ctrl["estimate_g"] = int(bool(estimate_g))
        res = self.loops[law].run(plant, ctrl, record=record)
        f = res.final
        down = f["status"] == REACHED
        td = Touchdown(law=law, h0=plant["h0"], V0=plant["V0"], gL=plant["gL"],
                       status=f["status"], V_touchdown=f["V_touchdown"] if down else math.nan,
                       t_touchdown=f["t_end"] if down else math.nan, fuel=f["fuel"])
        return td, res


def dispersion_box(nominal: LanderParams = LanderParams()) -> Box:
    """The dispersion set around ``nominal``: h0, V0 +-10 %, gL +-2 % (relative, uniform)."""
    return Box.around(asdict(nominal), relative=DISPERSION)


def dispersion(loops: LandingLoops, n: int = 40, seed: int = 2017, corners: bool = True,
               laws=LAWS) -> list:
    """Seeded dispersion: ``n`` uniform samples of :func:`dispersion_box` (+ its 8 corners).

    Parameters
    ----------
    loops : LandingLoops
        The closed loops (their nominal conditions are the centre of the box).
    n : int
        Uniform samples (0: only the corners).
    seed : int
    corners : bool
        Append the 2^3 corners of the box.
    laws : sequence of str

    Returns
    -------
    list of dict
        One per start: ``h0, V0, gL``, ``fuel_opt`` (the exact optimum of that start [kg]) and
        a :class:`Touchdown` per law.
    """
    box = dispersion_box(loops.nominal)
    if n > 0:
        starts = box.sample(n, seed, corners=corners)
    else:
        starts = box.sample(1, seed, method="corners") if corners else []
    rows = []
    for s in starts:
        h0, V0, gL = s["h0"], s["V0"], s["gL"]
        row = dict(h0=h0, V0=V0, gL=gL,
                   fuel_opt=optimal_landing(loops.nominal.with_(h0=h0, V0=V0, gL=gL)).fuel)
        for law in laws:
            row[law] = loops.fly(law, h0, V0, gL)[0]
        rows.append(row)
    return rows


def dispersion_table(rows, laws=LAWS) -> tuple:
    """(text table, summary dict) of a :func:`dispersion` result.

    The summary holds, per law: runs, soft landings, the worst and median touchdown speed
    [m/s] (inf for a start that never touches down) with the worst start, and the largest fuel
    burnt above each start's optimum [kg].
    """
    head = f"{'h0 [m]':>8} {'V0 [m/s]':>9} {'gL [m/s2]':>10} {'opt. fuel':>9}" + "".join(
        f" {law + ' |V_td| [m/s]':>24} {'fuel [kg]':>9}" for law in laws)
    lines = [head]
    for r in rows:
        s = f"{r['h0']:8.2f} {r['V0']:9.3f} {r['gL']:10.4f} {r['fuel_opt']:9.2f}"
        for law in laws:
            td = r[law]
            v = f"{abs(td.V_touchdown):.4f}" if td.touched_down else "no touchdown"
            s += f" {v:>24} {td.fuel:9.2f}"
        lines.append(s)
    summary = {}
    for law in laws:
        speeds = [abs(r[law].V_touchdown) if r[law].touched_down else math.inf for r in rows]
        k = int(np.argmax(speeds))
        summary[law] = dict(runs=len(rows), soft=sum(r[law].soft for r in rows),
                            worst_speed=speeds[k], worst_case=dict(h0=rows[k]["h0"],
                                                                   V0=rows[k]["V0"],
                                                                   gL=rows[k]["gL"]),
                            median_speed=float(np.median(speeds)),
                            max_fuel_excess=max(r[law].fuel - r["fuel_opt"] for r in rows))
    for law in laws:
        s = summary[law]
        lines.append(f"{law}: {s['soft']}/{s['runs']} soft (|V| < {SOFT_SPEED} m/s), worst "
                     f"|V_td| = {s['worst_speed']:.4f} m/s at h0 = {s['worst_case']['h0']:.2f} m,"
                     f" V0 = {s['worst_case']['V0']:.3f} m/s, gL = {s['worst_case']['gL']:.4f}")
    return "\n".join(lines), summary


def plot_dispersion(loops: LandingLoops, rows, path, n_traj: int = 12) -> Path:
    """PNG: touchdown speed of each dispersed start (program vs feedback) and phase trajectories
    of the first ``n_traj`` starts and of the nominal one (flown again, recorded)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
    idx = np.arange(len(rows))
    for law, mk in (("program", "o"), ("feedback", "s")):
        sp = [abs(r[law].V_touchdown) if r[law].touched_down else np.nan for r in rows]
        ax[0].semilogy(idx, np.maximum(sp, 1e-5), mk, label=law, ms=5)
    ax[0].axhline(SOFT_SPEED, color="r", lw=0.8, ls="--", label=f"soft: {SOFT_SPEED} m/s")
    ax[0].set(xlabel="dispersed start #", ylabel="|V| at touchdown [m/s]",
              title="h0, V0 ±10 %, gL ±2 %")
    ax[0].legend()
    for k, law in ((1, "program"), (2, "feedback")):
        for r in rows[:n_traj]:
            _, res = loops.fly(law, r["h0"], r["V0"], r["gL"], record=True)
            ax[k].plot(res["h"], res["V"], lw=0.8)
        _, res = loops.fly(law, record=True)
        ax[k].plot(res["h"], res["V"], "k", lw=1.8, label="nominal")
        ax[k].set(xlabel="h [m]", ylabel="V [m/s] (down)",
                  title=f"{law} (FMUs): phase trajectories")
        ax[k].set_xlim(left=0.0)
        ax[k].legend()
    return save_figure(fig, path, ax, dpi=110)
