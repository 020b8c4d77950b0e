"""S1 guidance options over a held-out dispersion set, every flight through the FMUs.

:func:`robust_study` flies, on the same seeded samples of the dispersion set (rho0 +-15 %,
m +-5 %, V0 +-50 m/s, beta0 +-0.03 deg; uniform, a seed other than the synthesis set's and
without the nominal point, so the two sets are disjoint), for each scenario (the default one
and the second: V0 = 8000 m/s, h0 = 80 km, beta0 = -1.6 deg):

* the network-operator laws given (a law reading y3 flies Reentry + SensedNetworkOperator-
  Controller, the estimator inside; a law of y1, y2 flies Reentry + NetworkOperatorController);
* the paper's basic law;
* the NPC guidance (Reentry + ReentryNPC);
* the open-loop program flown blind (Reentry alone, the program replayed whatever the state);
* the oracle bound per sample (:mod:`synthesis.systems.reentry.oracle`, in-process).

:func:`table_lines` prints median / p90 / p95 / max miss, the shares within 1 km and 5 km,
median / max J1 and the landed share; :func:`plot_robust_study` the miss CDFs against the oracle
and the J1 boxplots.
"""
from __future__ import annotations

import math
import textwrap
from dataclasses import asdict
from pathlib import Path

import numpy as np

from descent_fmus.models.reentry import SECOND_SCENARIO, ReentryParams
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.systems.reentry.error_families import Sample
from descent_fmus.synthesis.systems.reentry.guidance import (GUIDED_WIRING, NPC_WIRING,
                                                             SENSED_WIRING,
                                                             reads_correction,
                                                             reads_estimate)
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law
from descent_fmus.synthesis.systems.reentry.objectives import objectives
from descent_fmus.synthesis.systems.reentry.sample_set import (SYNTHESIS_SAMPLES,
                                                               SYNTHESIS_SEED,
                                                               synthesis_set)
from descent_fmus.synthesis.systems.reentry.wiring import WIRING, plant_values

__all__ = ["SCENARIOS", "held_out_samples", "robust_study", "stats", "table_lines",
           "plot_robust_study", "NPC", "PROGRAM", "ORACLE", "BASIC", "HELD_OUT_SEED"]

#: Scenarios of the study.
SCENARIOS = {"default": ReentryParams(), "second": SECOND_SCENARIO}
#: Names of the built-in guidance options.
NPC, PROGRAM, ORACLE, BASIC = ("NPC guidance", "open-loop program (blind)", "oracle bound",
                               "basic law (paper q)")
#: Default seed of the held-out set (the synthesis set uses sample_set.SYNTHESIS_SEED).
HELD_OUT_SEED = 7


def held_out_samples(n: int, seed: int = HELD_OUT_SEED, base: ReentryParams = ReentryParams()
                     ) -> list:
    """``n`` uniform samples of the dispersion set around ``base`` (seeded; the nominal point
    is not among them)."""
    from descent_fmus.synthesis.systems.reentry.robustness import dispersion_box
    if n < 1:
        raise ValueError(f"the number of samples must be >= 1, got {n}")
    return [base.with_(**s) for s in dispersion_box(base).sample(n, seed)]


def _key(p: ReentryParams) -> tuple:
    return (p.rho0, p.m, p.V0, p.beta0)


def disjoint_from_synthesis(params) -> bool:
    """No sample of ``params`` is a point of the synthesis set (sample_set.synthesis_set)."""
    used = {_key(p) for p in synthesis_set()}
    return not any(_key(p) in used for p in params)


def stats(rows) -> dict:
    """The table's statistics of one guidance option's flights."""
    miss = np.array([r["J2"] for r in rows], float)
    j1 = np.array([r["J1"] for r in rows], float)
    landed = np.array([r["landed"] for r in rows], bool)
    return {"miss_median": float(np.median(miss)), "miss_p90": float(np.percentile(miss, 90)),
            "miss_p95": float(np.percentile(miss, 95)), "miss_max": float(miss.max()),
            "within_1km": float(np.mean(miss < 1000.0)),
            "within_5km": float(np.mean(miss < 5000.0)),
            "J1_median": float(np.median(j1)), "J1_max": float(j1.max()),
            "landed": float(landed.mean())}


def _sensing(noise: float, bias: float, k: int, seed: int) -> dict:
    if noise == 0.0 and bias == 0.0:
        return {}
    return {"noise": noise, "bias": bias, "noise_seed": 1000 * seed + k}


def _fly_loop(wiring, fmu_dir, plant, ctrl_fmu, params, controller_values, noise, bias, seed,
              per_sample=None):
    from tqdm import tqdm

    from descent_fmus.synthesis.fmi.loop import open_loop
    rows = []
    sensed = wiring is not WIRING
    # the native twins where they are built (the same flights, ~40x faster; re-planned
    # flights the same to the rounding of the re-planner's linear programmes, ~30x faster)
    loop = open_loop(wiring, fmu_dir / plant, fmu_dir / ctrl_fmu)
    try:
        # a progress bar on a terminal only (a re-planned flight costs ~1 s in Python)
        for k, p in enumerate(tqdm(params, desc=f"{wiring.name} flights ({loop.path})",
                                   unit="flight", leave=False, disable=None)):
            cv = dict(controller_values)
            cv.update(_sensing(noise, bias, k, seed))
            p, errors = (p.plant, p.sensing) if isinstance(p, Sample) else (p, {})
            if sensed:
                cv.update(errors)           # the sample's accelerometer errors
            if per_sample is not None:
                cv.update(per_sample(p))
            rows.append(objectives(loop.run(plant_values(p), cv).final, p))
    finally:
        loop.close()
    return rows


def fly_law(law: NetworkOperator, params, fmu_dir, noise: float = 0.0, bias: float = 0.0,
            seed: int = 0, guidance: dict | None = None) -> list:
    """Objectives of ``law`` on every sample (a ReentryParams, or a
    :class:`~.error_families.Sample` whose sensing errors the estimator simulates; the guided
    wiring if the law reads the on-board correction c, with the controller parameters
    ``guidance`` (e.g. ``correction_gate``) over the law's own; the sensed wiring if it reads
    y3)."""
    fmu_dir = Path(fmu_dir)
    if reads_correction(law):
        return _fly_loop(GUIDED_WIRING, fmu_dir, "Reentry.fmu",
                         "GuidedNetworkOperatorController.fmu", params,
                         {**law.start_values(), **(guidance or {})}, noise, bias, seed,
                         per_sample=lambda p: {"h0_line": p.h0})
    if guidance:
        raise ValueError(f"guidance parameters {sorted(guidance)} need a law that reads the "
                         f"correction c")
    if reads_estimate(law):
        return _fly_loop(SENSED_WIRING, fmu_dir, "Reentry.fmu",
                         "SensedNetworkOperatorController.fmu", params, law.start_values(),
                         noise, bias, seed)
    return _fly_loop(WIRING, fmu_dir, "Reentry.fmu", "NetworkOperatorController.fmu",
                     params, law.start_values(), 0.0, 0.0, seed)


def fly_npc(params, fmu_dir, noise: float = 0.0, bias: float = 0.0, seed: int = 0,
            controller_values: dict | None = None) -> list:
    """Objectives of the NPC guidance on every sample."""
    return _fly_loop(NPC_WIRING, Path(fmu_dir), "Reentry.fmu", "ReentryNPC.fmu", params,
                     controller_values or {}, noise, bias, seed)


def _with_guidance(option):
    """``(law, guidance parameters)`` of a guidance option: a law, or a pair of both."""
    return option if isinstance(option, tuple) else (option, None)


def robust_study(laws: dict, samples: int, seed: int, fmu_dir, scenarios=("default",),
                 programs: dict | None = None, npc: bool = True, oracle: bool = True,
                 noise: float = 0.0, bias: float = 0.0) -> dict:
    """Fly every guidance option over the held-out set of each scenario (see the module
    docstring).  ``laws`` maps a name to a law, or to a pair (law, guidance parameters of its
    controller, e.g. ``{"correction_gate": 12.0}``).  ``programs`` maps a scenario to its
    open-loop program (flown blind) or None.

    Returns ``{"samples", "seed", "disjoint", "scenarios": {name: {"params", "results",
    "nominal", "stats", "oracle"}}}``; ``nominal`` holds each option's nominal flight."""
    from descent_fmus.synthesis.systems.reentry.bound import replay_program
    from descent_fmus.synthesis.systems.reentry.oracle import oracle_bound
    if noise < 0.0:
        raise ValueError(f"accelerometer noise must be >= 0 m/s2, got {noise}")
    for s in scenarios:
        if s not in SCENARIOS:
            raise ValueError(f"unknown scenario {s!r}; known: {', '.join(SCENARIOS)}")
    fmu_dir = Path(fmu_dir)
    options = dict(laws)
    options.setdefault(BASIC, paper_basic_law())
    out = {"samples": samples, "seed": seed, "scenarios": {},
           "synthesis_set": {"samples": SYNTHESIS_SAMPLES, "seed": SYNTHESIS_SEED,
                             "design": "nominal + uniform"},
           "held_out_set": {"samples": samples, "seed": seed, "design": "uniform"},
           "noise": noise, "bias": bias}
    disjoint = True
    for name in scenarios:
        base = SCENARIOS[name]
        params = held_out_samples(samples, seed, base)
        disjoint &= disjoint_from_synthesis(params)
        every = [base] + params                     # the nominal flight first, reported apart
        results = {}
        for n, option in options.items():
            law, guidance = _with_guidance(option)
            results[n] = fly_law(law, every, fmu_dir, noise, bias, seed, guidance)
        if npc:
            results[NPC] = fly_npc(every, fmu_dir, noise, bias, seed)
        prog = (programs or {}).get(name)
        if prog is not None:
            results[PROGRAM] = [objectives(replay_program(prog, fmu_dir, p), p)
                                for p in every]
        sc = {"params": [asdict(p) for p in params],
              "nominal": {n: rows[0] for n, rows in results.items()},
              "results": {n: rows[1:] for n, rows in results.items()}}
        sc["stats"] = {n: dict(stats(rows), miss_nominal=sc["nominal"][n]["J2"],
                               J1_nominal=sc["nominal"][n]["J1"])
                       for n, rows in sc["results"].items()}
        if oracle:
            bounds = [oracle_bound(p) for p in params]
            sc["oracle"] = [b.miss for b in bounds]
            miss = np.array(sc["oracle"])
            sc["stats"][ORACLE] = {
                "miss_median": float(np.median(miss)),
                "miss_p90": float(np.percentile(miss, 90)),
                "miss_p95": float(np.percentile(miss, 95)), "miss_max": float(miss.max()),
                "within_1km": float(np.mean(miss < 1000.0)),
                "within_5km": float(np.mean(miss < 5000.0)),
                "exact": float(np.mean([b.exact for b in bounds]))}
        out["scenarios"][name] = sc
    out["disjoint"] = bool(disjoint)
    return out


def _fmt(v, unit_km=False, pct=False):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if pct:
        return f"{100 * v:.0f} %"
    return f"{v / 1e3:.2f}" if unit_km else f"{v:.3f}"


def table_lines(study: dict) -> list:
    """The printed table(s): one per scenario."""
    if "families" in study:
        lines = [f"held-out sets: {study['samples']} Latin-hypercube samples of each error "
                 f"family, seed {study['seed']}"]
        lines += [f"  {n}: {d}" for n, d in study["families"].items()]
    else:
        lines = [f"held-out set: {study['samples']} uniform samples of the dispersion set, "
                 f"seed {study['seed']}; synthesis set: {study['synthesis_set']['samples']} "
                 f"points (nominal + uniform), seed {study['synthesis_set']['seed']} -- "
                 + ("disjoint" if study["disjoint"] else "NOT disjoint")]
    if study.get("noise") or study.get("bias"):
        lines.append(f"accelerometer noise {study['noise']} m/s2, bias {study['bias']} m/s2")
    head = (f"{'guidance':34s} {'med':>7s} {'p90':>7s} {'p95':>7s} {'max':>7s} {'<1km':>5s} "
            f"{'<5km':>5s} {'J1 med':>7s} {'J1 max':>7s} {'landed':>6s} {'nominal':>8s}")
    for name, sc in study["scenarios"].items():
        lines += ["", f"scenario {name} (miss in km)", head]
        for g, s in sc["stats"].items():
            lines.append(
                f"{g[:34]:34s} {_fmt(s.get('miss_median'), True):>7s} "
                f"{_fmt(s.get('miss_p90'), True):>7s} {_fmt(s.get('miss_p95'), True):>7s} "
                f"{_fmt(s.get('miss_max'), True):>7s} {_fmt(s.get('within_1km'), pct=True):>5s} "
                f"{_fmt(s.get('within_5km'), pct=True):>5s} {_fmt(s.get('J1_median')):>7s} "
                f"{_fmt(s.get('J1_max')):>7s} {_fmt(s.get('landed'), pct=True):>6s} "
                f"{_fmt(s.get('miss_nominal'), True):>8s}")
    return lines


def plot_robust_study(study: dict, path) -> Path:
    """Miss CDFs of every guidance option against the oracle bound, and J1 boxplots (one row
    of two panels per scenario)."""
    import matplotlib.pyplot as plt

    from descent_fmus.synthesis.plotting import save_figure
    scen = list(study["scenarios"])
    fig, axes = plt.subplots(len(scen), 2, figsize=(15, 5.2 * len(scen)), squeeze=False)
    for row, name in zip(axes, scen):
        sc = study["scenarios"][name]
        ax = row[0]
        curves = {g: [r["J2"] for r in rows] for g, rows in sc["results"].items()}
        if "oracle" in sc:
            curves[ORACLE] = sc["oracle"]
        for g, miss in curves.items():
            m = np.sort(np.asarray(miss, float)) / 1e3
            y = np.arange(1, len(m) + 1) / len(m)
            style = dict(color="k", lw=2.2, ls="--") if g == ORACLE else dict(lw=1.6)
            ax.step(m, y, where="post", label=g[:52], **style)
        ax.set_xscale("symlog", linthresh=0.1)
        what = "errors" if "families" in study else "scenario"
        ax.set(xlabel="miss |L(tf) - Lf| [km]", ylabel="share of samples",
               title=f"{name} {what}: miss CDF ({len(sc['params'])} held-out samples)")
        ax.axvline(1.0, color="0.6", lw=0.8)
        ax.legend(fontsize=7, loc="lower right")
        names = list(sc["results"])
        j1 = [np.array([r["J1"] for r in sc["results"][g]]) for g in names]
        load = [r["J1_load"] for r in sc.get("limits", ()) if "J1_load" in r]
        if load:                            # the physical limit beside the options
            names.append("load oracle (min J1 at zero miss)"
                         + ("" if len(load) == len(sc["params"]) else f", {len(load)} samples"))
            j1.append(np.array(load))
        row[1].boxplot(j1, tick_labels=[textwrap.fill(g, 14) for g in names])
        row[1].set(ylabel="J1 (max load)", title=f"{name} {what}: J1")
        row[1].tick_params(axis="x", labelsize=7)
    return save_figure(fig, path, list(axes.ravel()), dpi=100)
