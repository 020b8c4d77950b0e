"""Fly the S2 Mars closed loops through the FMUs, summarise and plot them.

One :class:`~synthesis.cosim.ClosedLoop` (plant FMU + MarsBellmanController FMU) is loaded and
reset per run: the controlled flight, the uncontrolled one (``u_max = 0``: the same controller
FMU outputs u = 0) and the paper's printed formula (``formula = 1``) are three runs of the same
two FMUs with other start values.

References
----------
Seed 001 (Lyubimov & Kurkina), figs. 1-2 (alpha(t) without and with the control).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from descent_fmus.models.controllers.mars_bellman import CONSISTENT, PAPER
from descent_fmus.synthesis.cosim import ClosedLoop, ClosedLoopResult
from descent_fmus.synthesis.scenarios import mars as spec
from descent_fmus.synthesis.plotting import save_figure

__all__ = ["FMU_DIR", "MarsRun", "open_loop", "fly", "fly_set", "plot_alpha", "RECORD",
           "RECORD_6DOF", "FORMULAS"]

FMU_DIR = Path(os.environ.get("DESCENT_FMUS_DIR",
                              Path(__file__).resolve().parent.parent / "fmus"))
RECORD = ("h", "q", "omega_a", "theta_dot")
RECORD_6DOF = RECORD + ("alpha_m1", "alpha_m2")
#: CLI names of the controller's ``formula`` values.
FORMULAS = {"consistent": CONSISTENT, "paper": PAPER}
#: Acceptance of SPEC S2 [rad]: alpha at the end of the descent with the law.
ALPHA_TARGET = 0.01


@dataclass
class MarsRun:
    """One flight: its label, start values and the closed-loop result."""

    label: str
    plant_values: dict
    controller_values: dict
    result: ClosedLoopResult

    @property
    def alpha_end(self) -> float:
        return float(self.result.final["alpha"])

    def summary(self) -> dict:
        f = self.result.final
        out = {"label": self.label, "alpha_end": self.alpha_end,
               "alpha_end_deg": math.degrees(self.alpha_end), "t_end": f["t_end"],
               "h_end": f["h"], "V_end": f["V"], "reached_h_end": bool(self.result.stopped),
               "controller": dict(self.controller_values)}
        if self.result.outputs:
            u = self.result["ctrl.u"]
            out["max_abs_u"] = float(np.max(np.abs(u)))
            out["fraction_u_nonzero"] = float(np.mean(u != 0.0))
        for k in ("alpha_m1", "alpha_m2"):
            if k in f:
                out[k + "_end"] = f[k]
        return out


def open_loop(fmu_dir=FMU_DIR, wiring=None, record=RECORD) -> ClosedLoop:
    """Load the plant FMU and the controller FMU of ``wiring`` once (reset per :func:`fly`).

    ``wiring`` defaults to the averaged plant's :data:`synthesis.systems.mars.wiring.WIRING`; pass
    ``WIRING_6DOF`` (with ``record=RECORD_6DOF``) for the rigid-body plant.
    """
    fmu_dir = Path(fmu_dir)
    w = wiring or spec.WIRING
    return ClosedLoop(w, fmu_dir / f"{w.plant}.fmu", fmu_dir / f"{w.controller}.fmu",
                      record=record)


def fly(loop: ClosedLoop, label: str, plant_values: dict | None = None,
        controller_values: dict | None = None, record: bool = True,
        step: float | None = None) -> MarsRun:
    """One flight through ``loop``'s FMUs (start values by FMU variable name)."""
    pv, cv = dict(plant_values or {}), dict(controller_values or {})
    if "theta1" in pv and "theta1" not in cv:
        cv["theta1"] = pv["theta1"]   # the law must know the plant's asymmetry phase
    res = loop.run(pv, cv, record=record, step=step)
    return MarsRun(label, pv, cv, res)


def fly_set(fmu_dir=FMU_DIR, control: bool = True, formulas=("consistent",),
            plant_values: dict | None = None, controller_values: dict | None = None,
            record: bool = True) -> list[MarsRun]:
    """The uncontrolled flight and (if ``control``) one controlled flight per formula."""
    runs = []
    with open_loop(fmu_dir) as loop:
        runs.append(fly(loop, "no control", plant_values,
                        dict(controller_values or {}, u_max=0.0), record))
        if control:
            for name in formulas:
                runs.append(fly(loop, f"law, {name} root", plant_values,
                                dict(controller_values or {}, formula=FORMULAS[name]), record))
    return runs


def plot_alpha(runs, path, title: str | None = None, log: bool = True) -> Path:
    """alpha(t) of several recorded runs on one figure (the paper's figs. 1-2 together)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(12, 4.2))
    for i, r in enumerate(runs):
        res = r.result
        ls = "--" if i >= 2 else "-"     # a third run may lie on the first (paper's root)
        ax[0].plot(res.time, res["alpha"], ls=ls,
                   label=f"{r.label}: alpha_end = {r.alpha_end:.2e} rad")
        ax[1].plot(res.time, res["ctrl.u"], ls=ls, lw=0.6, label=r.label)
    ax[0].axhline(ALPHA_TARGET, color="k", ls=":", lw=0.8, label="0.01 rad")
    if log:
        ax[0].set_yscale("log")
    ax[0].set(xlabel="t [s]", ylabel="spatial angle of attack alpha [rad]",
              title=title or "S2 Mars descent: alpha(t) through the FMUs")
    ax[0].legend(fontsize=8)
    ax[1].set(xlabel="t [s]", ylabel="u = m^A", title="control")
    ax[1].legend(fontsize=8)
    return save_figure(fig, path, ax, dpi=90)
