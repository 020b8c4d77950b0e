"""The problems of the benchmark suite: how each is loaded, its flight budget, its reference and
its goal (``benchmarks/suite/run.py`` runs them; docs/benchmarks/suite.md).

Every problem is a :class:`~synthesis.problems.contract.SynthesisProblem` the package's run loop
drives as it is -- problem files in this folder on plants written here once each, in the
package's model style (built at run time into ``build/`` by ``descent-fmus build-plant``, as a
user would: the pythonfmu FMU and its native twin, which the runs fly), the tutorial's hopper
file, and the
registered S5 problem.  The learning curve of a run follows the problem's target, else its
first objective (:func:`synthesis.methods.registry.cma_target`): the value tabulated.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from descent_fmus.synthesis.systems.lunar_descent.problems import LUNAR_DESCENT_RECIPE
from plant_flights import BUILD, SUITE, PlantFlyer, build_plants
from references import (AICARDI_GAINS, AICARDI_GAINS_BOX, LUNAR_DESCENT_CMA_J1, parking_reference,
                        stored)
from riccati import lq_reference

__all__ = ["Spec", "SPECS", "load", "reference", "ORDER", "PARKING", "MINTIME"]

#: the parking problems (the polar law their reference, parked starts their details)
PARKING = ("parking", "parking-polar", "parking-box")
#: the minimum-time problems (a target set, its stop condition: reached starts their details)
MINTIME = ("mintime-di", "mintime-osc")


@dataclass(frozen=True)
class Spec:
    """One problem of the suite.

    Attributes
    ----------
    name : str
    flights : int
        Flight budget of every method (laws flown, each from all the problem's starts).
    plants : tuple of str
        Plant FMUs it needs built (:data:`plant_flights.PLANT_SOURCES`).
    file : str or None
        Its problem file (None: a registered problem).
    goal : str
        What the network operator should reach, in words.
    goal_ratio : float or None
        The goal as a ratio to the reference (value / reference <= goal_ratio).
    goal_value : float or None
        The goal as a value (value <= goal_value), for problems whose reference is 0.
    goal_at : tuple
        Goals at other flight budgets than ``flights``, ``((budget, value), ...)``: the value
        (as ``goal_value``) a run of that budget should reach (the parking problems' <= 0.01
        at 20 000 flights).
    reference_label : str
    note : str
    """

    name: str
    flights: int
    plants: tuple = ()
    file: str | None = None
    registered: str | None = None
    goal: str = ""
    goal_ratio: float | None = None
    goal_value: float | None = None
    goal_at: tuple = ()
    reference_label: str = ""
    note: str = ""
    plot: str = "value"          # the figure: "value" of the objective, or its "excess" over
    ratio: bool = True           # the reference (value/ref - 1); ratio: a meaningful scale


SPECS = {s.name: s for s in (
    Spec("lq", 1200, ("LQPlant",), "lq.toml",
         goal="cost <= 1.02 x the sampled-data optimum", goal_ratio=1.02, plot="excess",
         reference_label="optimum of the sampled-data LQ problem (Riccati), mean x0'Px0"),
    Spec("cartpole", 2000, ("CartPole",), "cartpole.toml",
         goal="never fall from any start; cost as low as the best baseline",
         reference_label="best open-loop program per start (trajectory optimisation), mean"),
    Spec("parking", 8000, ("Unicycle",), "parking.toml",
         goal="mean park error <= 0.05, clearly better than every fixed structure",
         goal_value=0.05, goal_at=((20000, 0.01),), ratio=False,
         reference_label="Aicardi et al. (1995) polar law through the FMU"),
    Spec("reentry-second", 20000, (), "reentry-second.toml",
         goal="J1 <= 1.002 x the open-loop bound at miss <= 1 km", goal_ratio=1.002,
         plot="excess",
         reference_label="best 1 s program at miss <= 1 km (S1 bound, second scenario)"),
    Spec("lunar-descent", LUNAR_DESCENT_RECIPE["budget"].flights, (), None,
         registered="lunar-descent",
         goal="J1 <= 0.017 m (CMA-ES over the basic law's 8 gains), the whole front kept",
         goal_ratio=1.0,
         reference_label="best J1 of CMA-ES over the basic law's 8 gains (measured)"),
    Spec("hopper", 1500, ("Hopper",), str(BUILD / "hopper.toml"),
         goal="at least as good as the best baseline",
         reference_label="none (no known optimum)"),
    Spec("parking-polar", 3000, ("Unicycle",), "parking-polar.toml",
         goal="(a variant: the law is given the polar coordinates)", ratio=False,
         reference_label="Aicardi et al. (1995) polar law through the FMU"),
    Spec("mintime-di", 4000, ("DoubleIntegrator",), "mintime-di.toml",
         goal="mean time <= 1.05 x the closed-form optimum, every start reached",
         goal_ratio=1.05, plot="excess",
         reference_label="closed-form minimum time to the origin per start, mean"),
    Spec("mintime-osc", 4000, ("Oscillator",), "mintime-osc.toml",
         goal="mean time <= 1.05 x the reference, every start reached", goal_ratio=1.05,
         plot="excess",
         reference_label="least time of any program held over the step (reachability per "
                         "step count), mean"),
    Spec("parking-box", 8000, ("Unicycle",), "parking-box.toml",
         goal="mean park error <= 0.05", goal_value=0.05, goal_at=((20000, 0.01),),
         ratio=False,
         reference_label="Aicardi et al. (1995) polar law, turn rate clipped to +-1"),
)}

#: the order of the table and of the figure's panels
ORDER = tuple(SPECS)


def load(name: str, fmu_dir=None, build: bool = True):
    """The problem ``name`` as the suite runs it (its plants built first with ``build``)."""
    spec = SPECS[name]
    if build and spec.plants:
        build_plants(names=spec.plants)
    if spec.registered:
        from descent_fmus.synthesis.registry import get_problem
        problem = get_problem(spec.registered)
    else:
        from descent_fmus.synthesis.problems.files import load_problem_file
        problem = load_problem_file(SUITE / spec.file, fmu_dir)
    return problem


def reference(name: str, problem=None, fmu_dir=None) -> dict:
    """The reference of problem ``name``: ``{"value": ... (of the target objective, or None),
    "label": ..., "details": {...}}`` -- computed (lq, parking: seconds) or stored (cartpole,
    reentry-second: ``reference/*.json``)."""
    spec = SPECS[name]
    out = {"label": spec.reference_label, "value": None, "details": {}}
    if name == "lq":
        problem = problem or load(name, fmu_dir)
        with PlantFlyer(problem.fmu_paths(fmu_dir or BUILD)[0]) as fl:
            params = fl.defaults()
        d = lq_reference(problem, params)
        out.update(value=d["mean"], details=d)
    elif name == "cartpole":
        d = stored("cartpole")
        progs = [p["J"] for p in d["programs"]]
        out.update(value=sum(progs) / len(progs), details=d)
    elif name in PARKING:
        problem = problem or load(name, fmu_dir)
        gains = AICARDI_GAINS_BOX if name == "parking-box" else AICARDI_GAINS
        d = parking_reference(problem, fmu_dir, gains)
        out.update(value=d["park"], details=d)
    elif name == "reentry-second":
        d = stored("reentry-second")
        out.update(value=d["J1"], details={k: v for k, v in d.items()
                                           if k not in ("bound", "zero_miss")})
        out["details"]["J1_zero_miss"] = d["zero_miss"]["J1"]
    elif name == "lunar-descent":
        out.update(value=LUNAR_DESCENT_CMA_J1)
    elif name in MINTIME:
        import mintime
        problem = problem or load(name, fmu_dir)
        d = (mintime.mintime_di_reference if name == "mintime-di"
             else mintime.mintime_osc_reference)(problem)
        out.update(value=d["mean"], details=d)
    return out


#: a start counts as parked within 5 cm and 3 deg of the target
PARKED = (0.05, math.radians(3.0))


def law_details(name: str, problem, law, fmu_dir=None) -> str:
    """What a law does start by start, in words: the cart-pole starts it saves (the pole stays
    within the never-fall bound), the parking starts it parks (:data:`PARKED`); "" else."""
    if name == "cartpole":
        from plant_flights import fly_law
        bound = problem.constraints[0].bound
        finals = fly_law(problem, law, fmu_dir)
        saved = [s for s, f in zip(problem.initial_states, finals) if f["tilt_max"] <= bound]
        return (f"saves {len(saved)}/{len(finals)} starts"
                + ("" if len(saved) == len(finals) else ": theta0 = " + ", ".join(
                    f"{math.degrees(s['theta0']):+.0f}" for s in saved) + " deg"))
    if name in PARKING:
        from plant_flights import fly_law
        finals = fly_law(problem, law, fmu_dir)
        n = sum(f["rho"] < PARKED[0] and abs(f["theta"]) < PARKED[1] for f in finals)
        d = sum(f["rho"] for f in finals) / len(finals)
        a = sum(abs(f["theta"]) for f in finals) / len(finals)
        return (f"parks {n}/{len(finals)} starts (within 5 cm, 3 deg); mean final distance "
                f"{d:.3g} m, heading error {a:.3g} rad")
    if name in MINTIME:
        from plant_flights import fly_law
        stop = problem.wiring.stop
        finals = fly_law(problem, law, fmu_dir)
        n = sum(stop.holds(f[stop.output]) for f in finals)
        return f"reaches {n}/{len(finals)} starts"
    return ""


def best_law(problem, pareto: list):
    """The best law of a run's ``pareto.json`` by the problem's target (its first objective
    without one), among the laws meeting the constraints."""
    from descent_fmus.synthesis.methods.law import NetworkOperator
    from descent_fmus.synthesis.methods.registry import cma_target
    t = cma_target(problem)
    name = problem.objective_names[t.objective]
    rows = [r for r in pareto if r.get("feasible", True)]
    if t.constraint is not None:
        c = problem.objective_names[t.constraint]
        rows = [r for r in rows if r[c] < t.limit]
    if not rows:
        return None
    return NetworkOperator.from_dict(min(rows, key=lambda r: r[name])["law"])


def ratio(value, ref) -> float:
    if value is None or ref is None or not math.isfinite(value) or ref <= 0:
        return math.nan
    return value / ref
