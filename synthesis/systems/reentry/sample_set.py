"""S1 reentry: judging a law over a fixed seeded set of dispersion samples (the sensed and
guided problems).

* :func:`synthesis_set` -- the set: the nominal flight and seeded uniform samples of the
  dispersion set;
* :class:`RobustObjectives` -- (J1, J2) over the set, :data:`STATISTICS` of the miss;
* :func:`proceed` -- racing: whether a law flies on after the first stages;
* :data:`STATISTIC_OPTION` -- ``synthesize --option statistic=NAME`` (:func:`with_statistic`).

Objectives over the set [choice] (models/README.md, "S1 robust guidance"): J1 = the median over
the set of the max load, J2 = a statistic of the miss (default the mean; each flight's miss capped
at :data:`MISS_CAP`, so a flight that does not land counts as a large but finite miss).  Racing:
a law flies the nominal flight first, then the first :data:`RACE_SIZES` samples, and flies on
only if it passes :func:`proceed`; a law stopped early gets ``RACE_OFFSET`` per skipped stage
added to its J2, which ranks it behind every law that flew the whole set.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from descent_fmus.models.reentry import ReentryParams
from descent_fmus.synthesis.problems.contract import ProblemOption
from descent_fmus.synthesis.systems.reentry.objectives import (DIVERGED_J1, ON_TARGET,
                                                               flight_objectives)

__all__ = ["SYNTHESIS_SAMPLES", "SYNTHESIS_SEED", "RACE_SIZES", "RACE_NOMINAL_MISS",
           "RACE_STAGE_MISS", "MISS_CAP", "RACE_OFFSET", "STATISTICS", "statistic",
           "synthesis_set", "family_set", "proceed", "RobustObjectives", "with_statistic",
           "STATISTIC_OPTION", "ERRORS_OPTION", "SAMPLES_OPTION"]

#: The synthesis set [choice]: the nominal flight + 15 uniform samples of the dispersion set,
#: seed 1 (the held-out study draws other uniform samples, seed 7, without the nominal point).
#: Uniform rather than Latin hypercube: the registry builds the problems on import and the
#: hypercube would import scipy there.
SYNTHESIS_SAMPLES = 16
SYNTHESIS_SEED = 1
#: Racing [choice]: stage sizes (flights flown before a check) and what passes.
RACE_SIZES = (1, 6)
RACE_NOMINAL_MISS = 10_000.0      # m: the nominal flight must land within this
RACE_STAGE_MISS = 15_000.0        # m: mean capped miss of the first 6 flights
#: Miss cap per flight inside the statistic [m] (a flight that does not land counts this much).
MISS_CAP = 200_000.0
#: Added to J2 per stage a raced-out law skipped [m] (larger than any capped statistic).
RACE_OFFSET = 1.0e6


def _percentile(q):
    def f(x):
        return float(np.percentile(x, q))
    f.__name__ = f"p{q}"
    return f


#: Statistics of the miss over the set, by name (``problems.set_problems(statistic_name=...)``).
STATISTICS = {"mean": lambda x: float(np.mean(x)), "median": lambda x: float(np.median(x)),
              "p75": _percentile(75), "p90": _percentile(90), "max": lambda x: float(np.max(x))}


def statistic(name: str):
    """The statistic ``name`` (:data:`STATISTICS`); ValueError with the choices otherwise."""
    try:
        return STATISTICS[name]
    except KeyError:
        raise ValueError(f"unknown statistic {name!r}; choose from "
                         f"{', '.join(STATISTICS)}") from None


def synthesis_set(samples: int = SYNTHESIS_SAMPLES, seed: int = SYNTHESIS_SEED,
                  base: ReentryParams = ReentryParams()) -> list:
    """The fixed set the robust problems judge a law on: the nominal flight first, then
    ``samples - 1`` uniform samples of the dispersion set (seeded)."""
    from descent_fmus.synthesis.systems.reentry.robustness import dispersion_box
    if samples < 1:
        raise ValueError(f"the number of samples must be >= 1, got {samples}")
    return [base.with_(**s) for s in
            dispersion_box(base).sample(samples, seed, nominal_first=True)]


def proceed(results) -> bool:
    """Racing: does a law that flew ``results`` fly on?  After the nominal flight: it landed
    within RACE_NOMINAL_MISS; after the first stage: the mean capped miss is within
    RACE_STAGE_MISS."""
    rows = [flight_objectives(r) for r in results]
    if len(rows) == 1:
        return bool(rows[0]["landed"]) and rows[0]["J2"] <= RACE_NOMINAL_MISS
    return float(np.mean([min(r["J2"], MISS_CAP) for r in rows])) <= RACE_STAGE_MISS


@dataclass(frozen=True)
class RobustObjectives:
    """(J1, J2) of a law over the synthesis set: median max load, ``statistic`` of the capped
    miss; raced-out laws (fewer flights than the set) get RACE_OFFSET per skipped stage."""

    statistic: str = "mean"
    samples: int = SYNTHESIS_SAMPLES
    #: model-error families of the set (empty: the uniform dispersion set of synthesis_set)
    errors: tuple = ()

    def __post_init__(self):
        statistic(self.statistic)

    def __call__(self, results):
        rows = [flight_objectives(r) for r in results]
        miss = np.array([min(r["J2"], MISS_CAP) for r in rows])
        j1 = np.array([min(r["J1"], DIVERGED_J1) for r in rows])
        f1 = float(np.median(j1))
        f2 = statistic(self.statistic)(miss)
        skipped = sum(1 for s in RACE_SIZES + (self.samples,) if s > len(rows))
        extras = {"flights": len(rows), "miss_nominal": rows[0]["J2"], "J1_nominal": rows[0]["J1"],
                  "miss_median": float(np.median(miss)),
                  "within_1km": float(np.mean(miss < ON_TARGET)),
                  "landed_all": all(r["landed"] for r in rows)}
        if skipped:
            f2 += RACE_OFFSET * skipped
            extras["raced_out"] = True
        return (f1, f2), extras


def with_statistic(problem, name: str):
    """``problem`` judged with the set statistic ``name`` of the miss (ValueError if unknown)."""
    from dataclasses import replace
    objectives = replace(problem.objectives, statistic=name)
    labels = problem.labels[:1] + (f"J2 = {name} miss over the set [m]",) + problem.labels[2:]
    return problem.with_(objectives=objectives, objective_labels=labels,
                         source=f"{problem.source}, statistic {name}")


#: ``synthesize --option statistic=NAME`` (or ``--statistic NAME``) of the robust problems.
STATISTIC_OPTION = ProblemOption("statistic", "statistic of the miss over the sample set: "
                                 + ", ".join(STATISTICS), with_statistic)


def family_set(families, samples: int, seed: int = SYNTHESIS_SEED,
               base: ReentryParams = ReentryParams()) -> list:
    """The nominal flight, then ``samples - 1`` stratified samples shared out over the
    model-error ``families`` (a Latin hypercube of each, seeded; the plant's parameters only:
    the sensing errors of a family stay with the held-out study)."""
    from descent_fmus.synthesis.systems.reentry.error_families import family_samples
    if samples < 2:
        raise ValueError(f"a set of error families needs >= 2 samples, got {samples}")
    rest, out = samples - 1, [base]
    for k, name in enumerate(families):
        n = rest // len(families) + (1 if k < rest % len(families) else 0)
        if n:
            out += [s.plant for s in family_samples(name, n, seed, base)]
    return out


def _with_set(problem, objectives):
    """``problem`` judged on the set its ``objectives`` name (errors, samples)."""
    from descent_fmus.synthesis.systems.reentry.wiring import plant_values
    if objectives.errors:
        params = family_set(objectives.errors, objectives.samples)
        what = f"{objectives.samples} samples of {'+'.join(objectives.errors)}"
    else:
        params = synthesis_set(objectives.samples)
        what = f"{objectives.samples} samples"
    states = tuple(plant_values(p) for p in params)
    return problem.with_(objectives=objectives, initial_states=states,
                         source=f"{problem.source}, set {what}")


def with_errors(problem, value: str):
    """``problem`` judged on stratified samples of the model-error families ``value``
    (comma-separated names of error_families.FAMILIES)."""
    from dataclasses import replace

    from descent_fmus.synthesis.systems.reentry.error_families import family
    names = tuple(v.strip() for v in value.split(",") if v.strip())
    if not names:
        raise ValueError("errors needs at least one family name")
    for n in names:
        family(n)                      # ValueError naming the choices
    return _with_set(problem, replace(problem.objectives, errors=names))


def with_samples(problem, value: str):
    """``problem`` judged on a set of ``value`` flights (the nominal one included)."""
    from dataclasses import replace
    try:
        n = int(value)
    except ValueError:
        raise ValueError(f"samples must be an integer, got {value!r}") from None
    if n < max(RACE_SIZES) + 1:
        raise ValueError(f"samples must be >= {max(RACE_SIZES) + 1}, got {n}")
    return _with_set(problem, replace(problem.objectives, samples=n))


#: ``synthesize --option errors=FAMILY[,FAMILY]`` and ``--option samples=N`` of the set
#: problems: the set drawn from the model-error families, its size.
ERRORS_OPTION = ProblemOption("errors", "model-error families of the sample set (comma-"
                              "separated: spec, scale-height, entry, all; stratified)",
                              with_errors)
SAMPLES_OPTION = ProblemOption("samples", "flights of the sample set, the nominal one included",
                               with_samples)
