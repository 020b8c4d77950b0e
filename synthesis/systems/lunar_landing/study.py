"""S3 lunar soft landing: closed-loop flights through the FMUs and the dispersion study.

The shooting solve and the paper's figures 1-2 are
:mod:`synthesis.systems.lunar_landing.solution`.

* :func:`fly_feedback_in_process` -- the feedback law flown without FMUs (same functions);
* :class:`LandingLoops` -- the program and feedback closed loops (fmpy, FMUs loaded once);
* :func:`dispersion` / :func:`dispersion_table` / :func:`plot_dispersion` -- seeded dispersion
  of h0, V0 (+-10 %) and gL (+-2 %) (:func:`dispersion_box`): the feedback law lands softly, the
  open-loop program does not.

References
----------
T.Yu. Mozzhorina, 2017 (closing remark on synthesis).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from descent_fmus.models.controllers.lunar_landing_switch import SwitchLaw
from descent_fmus.models.integrators import REACHED
from descent_fmus.models.lunar_landing import (STEP, LanderIntegrator, LanderParams,
                                               optimal_landing)
from descent_fmus.synthesis.problems.dispersion import Box
from descent_fmus.synthesis.plotting import save_figure

__all__ = ["fly_feedback_in_process", "LandingLoops", "Touchdown", "dispersion_box",
           "dispersion", "dispersion_table", "plot_dispersion", "finite_or_none", "SOFT_SPEED",
           "DISPERSION", "LAWS"]

#: A touchdown is soft when |V| at h = 0 is below this [m/s] ([choice], models/README.md).
SOFT_SPEED = 0.05
#: Relative half-widths of the dispersion box: h0, V0 (+-10 %) and gL (+-2 %).
DISPERSION = dict(h0=0.10, V0=0.10, gL=0.02)
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
