"""S1 reentry: the registered network-operator synthesis problems and their recipes.

* :func:`nominal_problems` -- ``reentry`` (nominal flight), ``reentry-100m`` (the same, CMA-ES
  target a miss below 100 m) and ``reentry-robust`` (nominal + the rho0 and V0 extremes of the
  dispersion set);
* :func:`set_problems` -- ``reentry-sensed`` (law of y1, y2, y3), ``reentry-sensed-y12`` (the
  same objective, law of y1, y2 only: what the measurement buys) and ``reentry-guided`` (law
  of y1, y2, y3 plus the on-board correction c), judged over a fixed seeded set of dispersion
  samples (:mod:`.sample_set`);
* :func:`problems` -- all of them, in that order.

The pieces: wirings (:mod:`.wiring`, :mod:`.guidance`), objectives (:mod:`.objectives`,
:mod:`.sample_set`), basic solutions and baselines (:mod:`.laws`), reports (:mod:`.reports`).
Each set problem flies on the faster of the Python master and the closed-loop container FMU
(``synthesis.fmi.container_loop``; :data:`SENSED_CONTAINER`, :data:`PLAIN_CONTAINER`).
"""
from __future__ import annotations

from descent_fmus.models.reentry import ReentryParams
from descent_fmus.synthesis.methods.pareto import Target
from descent_fmus.synthesis.problems.contract import (LAB_SEARCH, ProblemOption,
                                                      SynthesisProblem, recipe)
from descent_fmus.synthesis.problems.runner import Race, Runner
from descent_fmus.synthesis.systems.reentry.guidance import (GUIDED_WIRING, SENSED_WIRING,
                                                             guided_basic_law)
from descent_fmus.synthesis.systems.reentry.laws import (baseline_structures, robust_basic_law,
                                                         sensed_baselines, sensed_basic_law,
                                                         sensed_y12_baselines,
                                                         synthesis_basic_law)
from descent_fmus.synthesis.systems.reentry.objectives import (DIVERGED_J1, J1_LIMIT,
                                                               NOT_LANDED_PENALTY, ON_TARGET,
                                                               ROBUST_CASES, TIGHT_MISS,
                                                               nominal_objectives,
                                                               robust_objectives)
from descent_fmus.synthesis.systems.reentry.reports import (GuidedReport, ReentryReport,
                                                            SensedReport)
from descent_fmus.synthesis.systems.reentry.sample_set import (ERRORS_OPTION, RACE_OFFSET,
                                                               RACE_SIZES, SAMPLES_OPTION,
                                                               STATISTIC_OPTION,
                                                               SYNTHESIS_SAMPLES, SYNTHESIS_SEED,
                                                               RobustObjectives, proceed,
                                                               synthesis_set)
from descent_fmus.synthesis.systems.reentry.wiring import WIRING, plant_values

__all__ = ["problems", "nominal_problems", "set_problems", "REENTRY_RECIPE", "ROBUST_RECIPE",
           "SENSED_RECIPE", "GUIDED_RECIPE", "TARGET", "TARGET_TIGHT", "Q_BITS", "SCALED_Q_BITS",
           "ROBUST_Q_BITS", "SENSED_CONTAINER", "PLAIN_CONTAINER"]

#: Default budget of `synthesize reentry` [choice] (models/README.md, "S1 synthesis"): CMA-ES
#: on the basic solution's parameters first (8000 flights: in the (10 y1, 2 y2) scaling the
#: cubic needed ~5000 uninterrupted ones to leave the J1 ~8.45 plateau, and without this
#: refinement seeds 1-3 ended at 1.002-1.07 x the bound), then the GA with CMA-ES refinement of the
#: best law's parameters (2000 evaluations, continued for a structure seen before) after every
#: epoch of 10 generations, stopped after 20 000 flights -- under 10 min with 2 workers on a
#: quiet 2-core machine; the basis refinement stops at its 8000 (``refine_basis_patience=0``: the
#: recipe was measured so, and its later CMA-ES per epoch continues the same search).  ``flights``
#: is the same budget for the fixed-structure CMA-ES
#: baselines (--method cma-*).
REENTRY_RECIPE = recipe(population=128, generations=200, crossovers=32, lchr=8, epoch=10,
                        seed=2, refine_evals=2000, refine_laws=1, refine_basis=8000,
                        refine_basis_patience=0, flights=20_000, basis_rule="target",
                        **LAB_SEARCH)
#: The robust variant costs 5 flights per law: smaller population, fewer generations.
#: (The GA alone, as measured: no flight budget, no CMA-ES refinement, the lab's basis rule.)
ROBUST_RECIPE = recipe(population=128, generations=150, crossovers=32, lchr=8, epoch=12, seed=1,
                       flights=0, refine_basis=0, refine_evals=0, basis_rule="compromise",
                       **LAB_SEARCH)
#: Default budget of the robust problems [choice]: about 20 min with 2 workers on a 2-core
#: machine (benchmarks/reentry_robust.py measures the evaluation rate); ``flights`` is the
#: evaluation budget of the CMA-ES baseline (--method cma-polynomial), about what the GA spends.
SENSED_RECIPE = recipe(population=48, generations=40, crossovers=12, lchr=8, epoch=10, seed=1,
                       refine_evals=150, refine_laws=1, flights=2600, refine_basis=0,
                       basis_rule="compromise", **LAB_SEARCH)
#: Default budget of ``reentry-guided`` [choice]: a law costs up to 16 flights of ~0.15 s (the
#: on-board predictions), so the run stops after 600 law evaluations (about 10 min with 2
#: workers); CMA-ES tunes the basic solution's parameters first (120 evaluations; its shape is
#: already a good nominal law), then the GA with 80 evaluations of refinement per epoch.
GUIDED_RECIPE = recipe(population=32, generations=60, crossovers=8, lchr=8, epoch=10, seed=1,
                       refine_evals=80, refine_laws=1, refine_basis=120,
                       refine_basis_patience=0, flights=600, basis_rule="target",
                       **LAB_SEARCH)

#: The single objective of CMA-ES: J1 subject to a miss below 1 km (``reentry``) or below
#: 100 m (``reentry-100m``).
TARGET = Target(objective=0, constraint=1, limit=ON_TARGET)
TARGET_TIGHT = Target(objective=0, constraint=1, limit=TIGHT_MISS)

#: Gray code of the parameters [choice]: 7 + 30 bits over [-64, 64) -- the window cubic's
#: coefficients stay below 1 in size (seeds 1-4), and near the bound J1 moves with their
#: 1e-7-th parts, so the grid is 9.3e-10 (a grid of 3.8e-6 stalled the search at 8.2705 /
#: 8.2708, seeds 1 / 2).
Q_BITS = (7, 30, -64.0, 64.0)
#: Gray code of laws in the (10 y1, 2 y2) scaling refined by CMA-ES (the sensed-drag
#: problems): 15 + 18 bits over [-16384, 16384), a range their coefficients never meet
#: (in that scaling a near-optimal cubic's reach thousands).
SCALED_Q_BITS = (15, 18, -16384.0, 16384.0)
#: The robust variant has no CMA-ES refinement: its parameters are searched by the Gray-coded
#: bit flips alone, which a narrow range keeps small (6 + 18 bits over [-64, 64)).
ROBUST_Q_BITS = (6, 18, -64.0, 64.0)
#: Gray code of the automatically scaled cubic [choice]: 15 + 33 bits over [-16384, 16384) --
#: the range of the (10 y1, 2 y2) scaling, whose near-optimal coefficients reach thousands, on
#: the fine grid (1.2e-10) the window runs needed.
AUTO_Q_BITS = (15, 33, -16384.0, 16384.0)

#: Which closed-loop path the robust problems fly [choice] (benchmarks/reentry_robust.py): the
#: container FMU costs about as much CPU as the Python master for the two-input law and more for
#: the sensed law, whose seven connections the container sets one FMI call each where the master
#: sets them in one call.
SENSED_CONTAINER = False
PLAIN_CONTAINER = True

_PENALTY = (DIVERGED_J1, 2 * NOT_LANDED_PENALTY)
_LABELS = ("J1 = max load (paper's eq. 7)", "J2 = miss at hf [m]")


def problems() -> tuple:
    """The registered S1 synthesis problems: the nominal ones, then those over the sample set."""
    return nominal_problems() + set_problems()


def nominal_problems() -> tuple:
    """``reentry``, ``reentry-100m`` and ``reentry-robust`` (see the module docstring)."""
    basic = synthesis_basic_law()
    return (
        SynthesisProblem(
            name="reentry", wiring=WIRING, initial_states=(plant_values(ReentryParams()),),
            objectives=nominal_objectives, objective_names=("J1", "J2"), penalty=_PENALTY,
            basic_law=robust_basic_law(), **REENTRY_RECIPE, objective_labels=_LABELS,
            q_bits=AUTO_Q_BITS, report=ReentryReport(), source="system reentry",
            target=TARGET, baselines=baseline_structures, input_scaling="auto",
            description="S1 Earth reentry: min max load (J1) and miss at hf (J2) [m]; the "
                        "inputs' coordinates derived from the flights"),
        SynthesisProblem(
            name="reentry-window", wiring=WIRING,
            initial_states=(plant_values(ReentryParams()),), objectives=nominal_objectives,
            objective_names=("J1", "J2"), penalty=_PENALTY, basic_law=basic, **REENTRY_RECIPE,
            objective_labels=_LABELS, q_bits=Q_BITS, report=ReentryReport(),
            source="system reentry", target=TARGET, baselines=baseline_structures,
            description="S1 Earth reentry in the hand-picked input window (the default before "
                        "automatic input scaling)"),
        SynthesisProblem(
            name="reentry-100m", wiring=WIRING, initial_states=(plant_values(ReentryParams()),),
            objectives=nominal_objectives, objective_names=("J1", "J2"), penalty=_PENALTY,
            basic_law=basic, **REENTRY_RECIPE, objective_labels=_LABELS,
            q_bits=Q_BITS, report=ReentryReport(), source="system reentry",
            target=TARGET_TIGHT, baselines=baseline_structures,
            description="S1 Earth reentry, tight miss: as reentry, CMA-ES target J1 subject to "
                        "a miss below 100 m"),
        SynthesisProblem(
            name="reentry-robust", wiring=WIRING,
            initial_states=tuple(plant_values(ReentryParams(**c)) for c in ROBUST_CASES),
            objectives=robust_objectives, objective_names=("J1", "J2"), penalty=_PENALTY,
            basic_law=robust_basic_law(), **ROBUST_RECIPE, objective_labels=_LABELS,
            q_bits=ROBUST_Q_BITS, source="system reentry",
            description="S1 reentry, robust: worst max load and mean miss over the nominal flight "
                        "and the rho0 +-15 %, V0 +-50 m/s extremes"),
    )


def with_replan(problem, value: str):
    """``problem`` with every flight re-planned on board (``value`` 1) or the single correction
    (0): the guided controller's ``replan`` (natively 15 ms a flight, against 2.5 ms)."""
    if value.strip() not in ("0", "1"):
        raise ValueError(f"replan must be 0 or 1, got {value!r}")
    flag = int(value)
    kept = tuple(p for p in problem.controller_values if p[0] != "replan")
    return problem.with_(controller_values=kept + ((("replan", flag),) if flag else ()),
                         source=f"{problem.source}, replan {flag}")


#: ``synthesize reentry-guided --option replan=1``: the laws searched with the re-planner in the
#: loop (every flight re-plans on board) instead of the single correction.
REPLAN_OPTION = ProblemOption("replan", "1: every flight re-plans the correction on board "
                              "(the guided controller's replan = 1); 0: one correction c",
                              with_replan)


def set_problems(statistic_name: str = "mean", samples: int = SYNTHESIS_SAMPLES,
                 seed: int = SYNTHESIS_SEED) -> tuple:
    """``reentry-sensed``, ``reentry-sensed-y12`` and ``reentry-guided`` over the synthesis set
    of ``samples`` flights (seed ``seed``), the sensed ones judged with the statistic
    ``statistic_name`` of the miss (see the module docstring)."""
    params = synthesis_set(samples, seed)
    states = tuple(plant_values(p) for p in params)
    objectives = RobustObjectives(statistic_name, samples)
    race = Race(RACE_SIZES, proceed)
    target = Target(objective=1, constraint=0, limit=J1_LIMIT)
    labels = ("J1 = median max load over the set", f"J2 = {statistic_name} miss over the set [m]")
    common = dict(initial_states=states, objectives=objectives, objective_names=("J1", "J2"),
                  penalty=(DIVERGED_J1, 4 * RACE_OFFSET), **SENSED_RECIPE,
                  objective_labels=labels, q_bits=SCALED_Q_BITS, report=SensedReport(),
                  source=f"system reentry (set: {samples} samples, seed {seed}, "
                         f"{statistic_name})",
                  target=target, options=(STATISTIC_OPTION, ERRORS_OPTION, SAMPLES_OPTION))
    return (
        SynthesisProblem(
            name="reentry-sensed", wiring=SENSED_WIRING, basic_law=sensed_basic_law(3),
            baselines=sensed_baselines, runner=Runner(container=SENSED_CONTAINER, race=race),
            description="S1 reentry, robust guidance with sensed drag: u = phi(y1, y2, y3) over "
                        f"a seeded set of {samples} dispersion samples (median J1, "
                        f"{statistic_name} miss)", **common),
        SynthesisProblem(
            name="reentry-sensed-y12", wiring=WIRING, basic_law=sensed_basic_law(2),
            baselines=sensed_y12_baselines, runner=Runner(container=PLAIN_CONTAINER, race=race),
            description="S1 reentry, the robust objective of reentry-sensed with a law of y1, y2 "
                        "only (no drag measurement)", **common),
        SynthesisProblem(
            name="reentry-guided", wiring=GUIDED_WIRING, basic_law=guided_basic_law,
            runner=Runner(container=SENSED_CONTAINER, race=race),
            **dict(common, objectives=RobustObjectives("median", samples),
                   objective_labels=(labels[0], "J2 = median miss over the set [m]"),
                   **GUIDED_RECIPE, report=GuidedReport(),
                   target=Target(objective=0, constraint=1, limit=ON_TARGET),
                   options=common["options"] + (REPLAN_OPTION,),
                   source=f"system reentry (set: {samples} samples, seed {seed}, median)"),
            description="S1 reentry, guided: a law u = phi(y1, y2, y3, c) plus the on-board "
                        "correction c (a predictor-corrector flying the law itself), min median "
                        f"J1 and median miss over the set of {samples} samples"),
    )
