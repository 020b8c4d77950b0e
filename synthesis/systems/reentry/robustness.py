"""Robustness of S1 laws: Monte-Carlo over the dispersion set, through the FMUs.

Dispersion: rho0 +-15 %, m +-5 %, V0 +-50 m/s, beta0 +-0.03 deg, uniform, seeded (the first
sample is the nominal flight).
Every feedback law flies Reentry + NetworkOperatorController; the open-loop program is flown blind
through the Reentry FMU (``bound.replay_program``: the nominal program replayed whatever the actual
state, one value per communication step of its segment length), so that the nominal replay is
the optimised flight.
"""
from __future__ import annotations

import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from descent_fmus.models.reentry import ReentryParams
from descent_fmus.synthesis.fmi.loop import open_loop
from descent_fmus.synthesis.problems.dispersion import Box
from descent_fmus.synthesis.systems.reentry.objectives import objectives
from descent_fmus.synthesis.systems.reentry.wiring import WIRING, plant_values

__all__ = ["dispersion_box", "dispersion_samples", "dispersion_study", "plot_study"]

#: Dispersion half-widths: rho0 and m relative, V0 [m/s] and beta0 [rad] absolute.
RELATIVE = {"rho0": 0.15, "m": 0.05}
ABSOLUTE = {"V0": 50.0, "beta0": math.radians(0.03)}


def dispersion_box(base: ReentryParams = ReentryParams()) -> Box:
    """The dispersion set around ``base`` as a :class:`~synthesis.problems.dispersion.Box`."""
    return Box.around(asdict(base), relative=RELATIVE, absolute=ABSOLUTE)


def dispersion_samples(n: int, seed: int, base: ReentryParams = ReentryParams()) -> list:
    """``n`` seeded ReentryParams drawn uniformly from the dispersion set (first = nominal)."""
    return [base.with_(**s) for s in dispersion_box(base).sample(n, seed, nominal_first=True)]


def _stats(rows) -> dict:
    miss = np.array([r["J2"] for r in rows])
    j1 = np.array([r["J1"] for r in rows])
    landed = np.array([r["landed"] for r in rows])
    return {"miss_median": float(np.median(miss)), "miss_p95": float(np.percentile(miss, 95)),
            "miss_max": float(miss.max()), "miss_nominal": float(miss[0]),
            "J1_median": float(np.median(j1)), "J1_max": float(j1.max()),
            "J1_nominal": float(j1[0]), "landed_fraction": float(landed.mean())}


def dispersion_study(laws: dict, program, samples: int, seed: int, fmu_dir) -> dict:
    """Fly every law (and the program, if given) over the same seeded dispersion samples."""
    fmu_dir = Path(fmu_dir)
    params = dispersion_samples(samples, seed)
    results = {}
    with open_loop(WIRING, fmu_dir / "Reentry.fmu", fmu_dir / "NetworkOperatorController.fmu",
                   native=False) as loop:
        for name, law in laws.items():
            sv = law.start_values()
            results[name] = [objectives(loop.run(plant_values(p), sv).final, p)
                             for p in params]
    if program is not None:
        from descent_fmus.synthesis.systems.reentry.bound import replay_program
        results["open-loop program (blind)"] = [
            objectives(replay_program(program, fmu_dir, p), p) for p in params]
    return {"params": [asdict(p) for p in params], "results": results,
            "stats": {k: _stats(v) for k, v in results.items()}}


def plot_study(study: dict, path) -> Path:
    """Boxplots of the miss and of J1 per law."""
    import matplotlib.pyplot as plt
    names = list(study["results"])
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    miss = [np.array([r["J2"] for r in study["results"][n]]) / 1e3 for n in names]
    j1 = [np.array([r["J1"] for r in study["results"][n]]) for n in names]
    ax[0].boxplot(miss, tick_labels=[n[:28] for n in names])
    ax[0].set_ylabel("miss |L(tf) - Lf| [km]")
    ax[1].boxplot(j1, tick_labels=[n[:28] for n in names])
    ax[1].set_ylabel("J1 (max load)")
    for a in ax:
        a.tick_params(axis="x", labelrotation=20)
        a.grid(alpha=0.3)
    fig.suptitle(f"dispersion study, {len(study['params'])} seeded samples "
                 "(rho0 +-15 %, m +-5 %, V0 +-50 m/s, beta0 +-0.03 deg)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
