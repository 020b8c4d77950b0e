"""Fly the S1 reentry closed loop through the FMUs and report/plot it."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from models.reentry import SECOND_SCENARIO, ReentryParams
from synthesis.cosim import ClosedLoop, ClosedLoopResult
from synthesis.network_operator import NetworkOperator
from synthesis.scenarios import reentry as spec
from synthesis.plotting import save_figure

FMU_DIR = Path(__file__).resolve().parent.parent / "fmus"
SCENARIOS = {"default": ReentryParams(), "second": SECOND_SCENARIO}
RECORD = ("h", "L", "load", "aero_load")


def scenario_params(name: str) -> ReentryParams:
    try:
        return SCENARIOS[name]
    except KeyError:
        raise KeyError(f"unknown reentry scenario {name!r}; known: {', '.join(SCENARIOS)}") \
            from None


@dataclass
class Flight:
    law: NetworkOperator
    params: ReentryParams
    result: ClosedLoopResult
    objectives: dict

    def summary(self) -> dict:
        return dict(self.objectives, law=self.law.to_dict())


def open_loop(fmu_dir=FMU_DIR, record=RECORD) -> ClosedLoop:
    fmu_dir = Path(fmu_dir)
    return ClosedLoop(spec.WIRING, fmu_dir / "Reentry.fmu",
                      fmu_dir / "NetworkOperatorController.fmu", record=record)


def fly(law: NetworkOperator, scenario: str = "default", params: ReentryParams | None = None,
        fmu_dir=FMU_DIR, record: bool = False, loop: ClosedLoop | None = None,
        step: float | None = None) -> Flight:
    """One closed-loop flight of ``law`` through the Reentry and NetworkOperatorController FMUs."""
    p = params or scenario_params(scenario)
    own = loop is None
    loop = loop or open_loop(fmu_dir)
    try:
        res = loop.run(spec.plant_values(p), law.start_values(), record=record, step=step)
    finally:
        if own:
            loop.close()
    return Flight(law, p, res, spec.objectives(res.final, p))


def plot_flight(flight: Flight, path, label: str | None = None) -> Path:
    """PNG with h(L), load(t) and u(t) of a recorded flight."""
    import matplotlib
    matplotlib.use("Agg")
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
