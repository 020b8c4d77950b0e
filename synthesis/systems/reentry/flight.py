"""Fly the S1 reentry closed loop through the FMUs and report/plot it."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from descent_fmus.models.reentry import SECOND_SCENARIO, ReentryParams
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoopResult
from descent_fmus.synthesis.fmi.loop import Loop, open_loop
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir
from descent_fmus.synthesis.plotting import save_figure
from descent_fmus.synthesis.systems.reentry.objectives import objectives
from descent_fmus.synthesis.systems.reentry.wiring import WIRING, plant_values

__all__ = ["SCENARIOS", "scenario_params", "ReentryFlight", "load_loop", "fly", "plot_flight"]

#: Entry conditions by name: the default scenario and the second one ([choice]).
SCENARIOS = {"default": ReentryParams(), "second": SECOND_SCENARIO}
RECORD = ("h", "L", "load", "aero_load")


def scenario_params(name: str) -> ReentryParams:
    try:
        return SCENARIOS[name]
    except KeyError:
        raise KeyError(f"unknown reentry scenario {name!r}; known: {', '.join(SCENARIOS)}") \
            from None


@dataclass
class ReentryFlight:
    """One closed-loop flight: the law, the entry conditions, the FMU result, J1/J2."""

    law: NetworkOperator
    params: ReentryParams
    result: ClosedLoopResult
    objectives: dict

    def summary(self) -> dict:
        return dict(self.objectives, law=self.law.to_dict())


def load_loop(fmu_dir=None, record=RECORD) -> Loop:
    """The Reentry + NetworkOperatorController closed loop, loaded once (reset per flight)."""
    d = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    return open_loop(WIRING, d / "Reentry.fmu", d / "NetworkOperatorController.fmu",
                     native=False, record=record)


def fly(law: NetworkOperator, scenario: str = "default", params: ReentryParams | None = None,
        fmu_dir=None, record: bool = False, loop: Loop | None = None,
        step: float | None = None) -> ReentryFlight:
    """One closed-loop flight of ``law`` through the Reentry and NetworkOperatorController FMUs."""
    p = params or scenario_params(scenario)
    own = loop is None
    loop = loop or load_loop(fmu_dir)
    try:
        res = loop.run(plant_values(p), law.start_values(), record=record, step=step)
    finally:
        if own:
            loop.close()
    return ReentryFlight(law, p, res, objectives(res.final, p))


def plot_flight(flight: ReentryFlight, path, label: str | None = None) -> Path:
    """PNG with h(L), load(t) and u(t) of a recorded flight."""
    import matplotlib.pyplot as plt

    r = flight.result
    fig, ax = plt.subplots(1, 3, figsize=(14, 4))
    ax[0].plot(r["L"] / 1e3, r["h"] / 1e3, label=label or "closed loop")
    p = flight.params
    ax[0].plot([0, p.Lf / 1e3], [p.h0 / 1e3, p.hf / 1e3], "k--", lw=0.8, label="reference line")
    ax[0].set(xlabel="down-range L [km]", ylabel="altitude h [km]", title="trajectory")
    ax[0].legend()
    ax[1].plot(r.time, r["load"], label="load (J1 integrand)")
    ax[1].plot(r.time, r["aero_load"], label="aerodynamic load")
    ax[1].set(xlabel="t [s]", ylabel="load [g]",
              title=f"J1 = {flight.objectives['J1']:.3f}")
    ax[1].legend()
    ax[2].step(r.time, r["ctrl.u[1]"], where="post")
    ax[2].set(xlabel="t [s]", ylabel="u [-]",
              title=f"control; miss = {flight.objectives['J2'] / 1e3:.2f} km")
    return save_figure(fig, path, ax, dpi=110)
