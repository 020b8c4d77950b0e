"""Fly the S2 Mars closed loops through the FMUs, summarise and plot them.

One :class:`~descent_fmus.synthesis.fmi.closed_loop.ClosedLoop` (plant FMU + MarsBellmanController FMU) is
loaded and reset per run: the controlled flight, the uncontrolled one (``u_max = 0``: the same
controller FMU outputs u = 0) and the paper's printed formula (``formula = 1``) are three runs
of the same two FMUs with other start values.

References
----------
Lyubimov & Kurkina, figs. 1-2 (alpha(t) without and with the control).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from descent_fmus.models.controllers.mars_bellman import CONSISTENT, PAPER
from descent_fmus.models.integrators import REACHED, STATUS_NAMES
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoopResult
from descent_fmus.synthesis.fmi.loop import Loop, open_loop
from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir
from descent_fmus.synthesis.plotting import save_figure
from descent_fmus.synthesis.systems.mars.wiring import WIRING

__all__ = ["MarsRun", "load_loop", "fly", "fly_set", "plot_alpha", "RECORD", "RECORD_6DOF",
           "FORMULAS", "ALPHA_TARGET"]

#: Plant outputs recorded besides the connected ones (averaged plant).
RECORD = ("h", "q", "omega_a", "theta_dot")
#: ... and for the rigid-body plant (``alpha`` is not connected when the law is fed mode 1).
RECORD_6DOF = RECORD + ("alpha", "alpha_m1", "alpha_m2")
#: CLI names of the controller's ``formula`` values.
FORMULAS = {"consistent": CONSISTENT, "paper": PAPER}
#: alpha at the end of the descent the law must reach [rad] (Lyubimov & Kurkina, fig. 2).
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
               "h_end": f["h"], "V_end": f["V"], "status": STATUS_NAMES[f["status"]],
               "reached_h_end": f["status"] == REACHED, "plant": dict(self.plant_values),
               "controller": dict(self.controller_values)}
        if self.result.outputs:
            u = self.result["ctrl.u"]
            out["max_abs_u"] = float(np.max(np.abs(u)))
            out["fraction_u_nonzero"] = float(np.mean(u != 0.0))
        for k in ("alpha_m1", "alpha_m2"):
            if k in f:
                out[k + "_end"] = f[k]
        return out


def load_loop(fmu_dir=None, wiring=WIRING, record=RECORD) -> Loop:
    """Load the plant FMU and the controller FMU of ``wiring`` once (reset per :func:`fly`).

    ``wiring`` defaults to the averaged plant's :data:`~.wiring.WIRING`; pass
    ``WIRING_6DOF`` or ``WIRING_6DOF_INSTANT`` (with ``record=RECORD_6DOF``) for the rigid-body
    plant.  ``fmu_dir`` defaults to :func:`descent_fmus.synthesis.paths.fmu_dir`.
    """
    d = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    return open_loop(wiring, d / f"{wiring.plant}.fmu", d / f"{wiring.controller}.fmu",
                     native=False, record=record)


def fly(loop: Loop, label: str, plant_values: dict | None = None,
        controller_values: dict | None = None, record: bool = True,
        step: float | None = None) -> MarsRun:
    """One flight through ``loop``'s FMUs (start values by FMU variable name)."""
    pv, cv = dict(plant_values or {}), dict(controller_values or {})
    if "theta1" in pv and "theta1" not in cv:
        cv["theta1"] = pv["theta1"]   # the law must know the plant's asymmetry phase
    res = loop.run(pv, cv, record=record, step=step)
    return MarsRun(label, pv, cv, res)


def fly_set(fmu_dir=None, control: bool = True, formulas=("consistent",),
            plant_values: dict | None = None, controller_values: dict | None = None,
            record: bool = True) -> list[MarsRun]:
    """The uncontrolled flight and (if ``control``) one controlled flight per formula."""
    runs = []
    with load_loop(fmu_dir) as loop:
        runs.append(fly(loop, "no control", plant_values,
                        dict(controller_values or {}, u_max=0.0), record))
        if control:
            for name in formulas:
                runs.append(fly(loop, f"law, {name} root", plant_values,
                                dict(controller_values or {}, formula=FORMULAS[name]), record))
    return runs


def plot_alpha(runs, path, title: str | None = None, log: bool = True) -> Path:
    """alpha(t) of several recorded runs on one figure (the paper's figs. 1-2 together)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(12, 4.2))
    for i, r in enumerate(runs):
        res = r.result
        ls = "--" if i >= 2 else "-"     # a third run may lie on the first (paper's root)
        ax[0].plot(res.time, res["alpha"], ls=ls,
                   label=f"{r.label}: alpha_end = {r.alpha_end:.2e} rad")
        ax[1].plot(res.time, res["ctrl.u"], ls=ls, lw=0.6, label=r.label)
    ax[0].axhline(ALPHA_TARGET, color="k", ls=":", lw=0.8, label=f"{ALPHA_TARGET} rad")
    if log:
        ax[0].set_yscale("log")
    ax[0].set(xlabel="t [s]", ylabel="spatial angle of attack alpha [rad]",
              title=title or "S2 Mars descent: alpha(t) through the FMUs")
    ax[0].legend(fontsize=8)
    ax[1].set(xlabel="t [s]", ylabel="u = m^A", title="control")
    ax[1].legend(fontsize=8)
    return save_figure(fig, path, ax, dpi=90)
