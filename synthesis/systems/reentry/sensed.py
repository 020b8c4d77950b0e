"""S1 robust guidance with sensed drag: wirings, the robust synthesis problems, the NPC loop.

* :data:`SENSED_WIRING` -- the Reentry plant with the ``SensedNetworkOperatorController`` (a
  network-operator law reading the drag-factor estimate y3 that the controller FMU computes from
  the sensed drag ``aero_load`` and the navigated state ``x1..x4``): u = phi(y1, y2, y3, q);
* :data:`NPC_WIRING` -- the Reentry plant with the ``ReentryNPC`` predictor-corrector guidance;
* :func:`problems` -- ``reentry-sensed`` (law of y1, y2, y3) and ``reentry-sensed-y12`` (the same
  objective, law of y1, y2 only: what the measurement buys), judged over a fixed seeded set of
  dispersion samples (:func:`synthesis_set`).

Objectives over the set [choice] (models/README.md, "S1 robust guidance"): J1 = the median over
the set of the max load, J2 = a statistic of the miss (default the mean; each flight's miss capped
at :data:`MISS_CAP`, so a flight that does not land counts as a large but finite miss).  Racing:
a law flies the nominal flight first, then the first :data:`RACE_SIZES` samples, and flies on
only if it passes :func:`proceed`; a law stopped early gets ``RACE_OFFSET`` per skipped stage
added to its J2, which ranks it behind every law that flew the whole set.  Each problem flies
on the faster of the Python master and the closed-loop container FMU (``synthesis.fmi.container_loop``;
:data:`SENSED_CONTAINER`, :data:`PLAIN_CONTAINER`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from descent_fmus.models.reentry import T_PLUS, ReentryParams
from descent_fmus.synthesis.fmi.closed_loop import STATUS_STOP, Wiring
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.pareto import Target
from descent_fmus.synthesis.problems.contract import (ProblemOption, Report, SynthesisProblem,
                                                     recipe)
from descent_fmus.synthesis.problems.runner import Race, Runner
from descent_fmus.synthesis.systems.reentry import problems as spec

__all__ = ["SENSED_WIRING", "NPC_WIRING", "SENSED_LOOP_PARAMETERS", "NPC_LOOP_PARAMETERS",
           "STATISTICS", "statistic", "synthesis_set", "RobustObjectives", "proceed",
           "sensed_basic_law", "sensed_baselines", "GUIDED_WIRING", "GUIDED_LOOP_PARAMETERS",
           "reads_correction", "as_guided", "default_guided_law", "best_guided_row", "problems", "SENSED_RECIPE", "SYNTHESIS_SEED",
           "SYNTHESIS_SAMPLES", "MISS_CAP", "reads_estimate", "J1_LIMIT", "best_row"]

_NAV = (("x1", "nav_x1"), ("x2", "nav_x2"), ("x3", "nav_x3"), ("x4", "nav_x4"))
_EXPOSED = (("h", "plant", "h"), ("L", "plant", "L"), ("load", "plant", "load"),
            ("aero_load", "plant", "aero_load"), ("load_max", "plant", "load_max"),
            ("aero_load_max", "plant", "aero_load_max"),
            ("y1", "plant", "y1"), ("y2", "plant", "y2"), ("status", "plant", "status"),
            ("t_end", "plant", "t_end"), ("drag_factor_log", "controller", "drag_factor_log"))

SENSED_WIRING = Wiring(
    name="ReentrySensedClosedLoop",
    plant="Reentry",
    controller="SensedNetworkOperatorController",
    to_controller=(("y1", "x[1]"), ("y2", "x[2]"), ("aero_load", "a_drag")) + _NAV,
    to_plant=(("u[1]", "u"),),
    step=spec.STEP,
    stop_time=T_PLUS,
    stop=STATUS_STOP,
    exposed=_EXPOSED + (("u", "controller", "u[1]"),),
    description="S1 Earth reentry (Reentry plant) under a network-operator law reading the "
                "drag-factor estimate y3 (sensed drag / nominal model, estimated in the "
                "controller FMU): u = phi(y1, y2, y3, q)",
)

NPC_WIRING = Wiring(
    name="ReentryNPCClosedLoop",
    plant="Reentry",
    controller="ReentryNPC",
    to_controller=(("aero_load", "a_drag"),) + _NAV,
    to_plant=(("u", "u"),),
    step=spec.STEP,
    stop_time=T_PLUS,
    stop=STATUS_STOP,
    exposed=_EXPOSED + (("u", "controller", "u"),
                        ("predicted_miss", "controller", "predicted_miss")),
    description="S1 Earth reentry (Reentry plant) under numerical predictor-corrector guidance "
                "(nominal model with the estimated drag factor, constant u nulling the "
                "predicted miss every cycle)",
)

GUIDED_WIRING = Wiring(
    name="ReentryGuidedClosedLoop",
    plant="Reentry",
    controller="GuidedNetworkOperatorController",
    to_controller=(("y1", "x[1]"), ("y2", "x[2]"), ("aero_load", "a_drag")) + _NAV,
    to_plant=(("u[1]", "u"),),
    step=spec.STEP,
    stop_time=T_PLUS,
    stop=STATUS_STOP,
    exposed=_EXPOSED + (("u", "controller", "u[1]"), ("correction", "controller", "correction"),
                        ("predicted_miss", "controller", "predicted_miss")),
    description="S1 Earth reentry (Reentry plant) under a network-operator law reading the "
                "drag-factor estimate y3 and the on-board correction c (a predictor-corrector "
                "that predicts with the law itself): u = phi(y1, y2, y3, c, q)",
)

#: Parameters the closed-loop FMUs expose: the dispersed plant parameters and the sensing.
_PLANT_PARAMETERS = tuple((n, "plant", n) for n in ("V0", "h0", "beta0", "m", "rho0"))
_SENSING = tuple((n, "controller", n) for n in ("threshold", "noise", "bias", "noise_seed"))
SENSED_LOOP_PARAMETERS = _PLANT_PARAMETERS + _SENSING
NPC_LOOP_PARAMETERS = _PLANT_PARAMETERS + _SENSING + (("cycle", "controller", "cycle"),)
GUIDED_LOOP_PARAMETERS = NPC_LOOP_PARAMETERS + (("h0_line", "controller", "h0_line"),
                                                 ("correction_gate", "controller",
                                                  "correction_gate"))

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
#: Median-J1 limit of the single-objective target (CMA-ES) [choice]: the issue's target.
J1_LIMIT = 9.0


def _percentile(q):
    def f(x):
        return float(np.percentile(x, q))
    f.__name__ = f"p{q}"
    return f


#: Statistics of the miss over the set, by name (``problems(statistic_name=...)``).
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
    rows = [spec.flight_objectives(r) for r in results]
    if len(rows) == 1:
        return bool(rows[0]["landed"]) and rows[0]["J2"] <= RACE_NOMINAL_MISS
    return float(np.mean([min(r["J2"], MISS_CAP) for r in rows])) <= RACE_STAGE_MISS


@dataclass(frozen=True)
class RobustObjectives:
    """(J1, J2) of a law over the synthesis set: median max load, ``statistic`` of the capped
    miss; raced-out laws (fewer flights than the set) get RACE_OFFSET per skipped stage."""

    statistic: str = "mean"
    samples: int = SYNTHESIS_SAMPLES

    def __post_init__(self):
        statistic(self.statistic)

    def __call__(self, results):
        rows = [spec.flight_objectives(r) for r in results]
        miss = np.array([min(r["J2"], MISS_CAP) for r in rows])
        j1 = np.array([min(r["J1"], spec.DIVERGED_J1) for r in rows])
        f1 = float(np.median(j1))
        f2 = statistic(self.statistic)(miss)
        skipped = sum(1 for s in RACE_SIZES + (self.samples,) if s > len(rows))
        extras = {"flights": len(rows), "miss_nominal": rows[0]["J2"], "J1_nominal": rows[0]["J1"],
                  "miss_median": float(np.median(miss)),
                  "within_1km": float(np.mean(miss < spec.ON_TARGET)),
                  "landed_all": all(r["landed"] for r in rows)}
        if skipped:
            f2 += RACE_OFFSET * skipped
            extras["raced_out"] = True
        return (f1, f2), extras


#: Input scaling of the sensed laws [choice]: 10 y1, 2 y2 as the nominal problem, 5 y3
#: (y3 lies in [-0.21, 0.19] over the dispersion set).
SENSED_INPUT_SCALE = tuple(spec.INPUT_SCALE) + (5.0,)


def _template(nx: int) -> NetworkOperator:
    from descent_fmus.synthesis.systems.reentry.laws import reentry_law
    psi = np.zeros((nx + 2, nx + 2), dtype=int)
    return reentry_law(psi, [0.0], [nx + 2], nx=nx, input_scale=list(SENSED_INPUT_SCALE[:nx]))


def _start_coefficients(nx: int, degree: int) -> list:
    """The paper's basic law (gains q1/10, q2/2 on the scaled inputs) and, with y3, the
    first-order compensation of the drag factor: u = -y3 (coefficient -1/5 on 5 y3)."""
    from descent_fmus.models.controllers.network_operator import PAPER_Q
    from descent_fmus.synthesis.methods.structures import monomials
    gains = {0: PAPER_Q[0] / SENSED_INPUT_SCALE[0], 1: PAPER_Q[1] / SENSED_INPUT_SCALE[1],
             2: -1.0 / SENSED_INPUT_SCALE[2]}
    q = [0.0]
    for m in monomials(nx, degree):
        q.append(gains[m.index(1)] if sum(m) == 1 else 0.0)
    return q


def sensed_basic_law(nx: int = 3) -> NetworkOperator:
    """The GA's first basic solution [choice]: a quadratic polynomial in the scaled inputs on 32
    nodes (a cubic in three inputs needs 20 parameters, more than the controller FMU holds), the
    paper's basic law plus u = -y3 as its start; identity nodes up to 32 for the variations.
    With ``nx = 2`` (y1, y2 only) the same construction without y3 (degree 3 fits)."""
    from descent_fmus.synthesis.methods.structures import polynomial_law
    degree = 2 if nx == 3 else 3
    return polynomial_law(_template(nx), degree, _start_coefficients(nx, degree), size=32)


def sensed_baselines() -> dict:
    """Fixed structures of the CMA-ES baseline (``--method cma-polynomial``): the basic
    solution's polynomial, only its coefficients tuned."""
    from descent_fmus.synthesis.methods.structures import polynomial_law
    return {"polynomial": polynomial_law(_template(3), 2, _start_coefficients(3, 2))}


def sensed_y12_baselines() -> dict:
    from descent_fmus.synthesis.methods.structures import polynomial_law
    return {"polynomial": polynomial_law(_template(2), 3, _start_coefficients(2, 3))}


def reads_estimate(law: NetworkOperator) -> bool:
    """Whether a law reads the drag-factor estimate (its third input is y3): it then flies on
    :data:`SENSED_WIRING`, else on the plain network-operator wiring."""
    names = list(law.input_names or [])
    return law.nx >= 3 and (len(names) < 3 or names[2] == "y3")


def reads_correction(law: NetworkOperator) -> bool:
    """Whether a law reads the on-board correction c (its fourth input is c): it then flies on
    :data:`GUIDED_WIRING`."""
    names = list(law.input_names or [])
    return law.nx >= 4 and len(names) >= 4 and names[3] == "c"


#: Names and scales of the guided laws' inputs [choice]: y1, y2, y3 as the sensed laws, and
#: the correction c unscaled (|c| <= 0.4).
GUIDED_INPUTS = (("y1", spec.INPUT_SCALE[0]), ("y2", spec.INPUT_SCALE[1]),
                 ("y3", SENSED_INPUT_SCALE[2]), ("c", 1.0))


def as_guided(law: NetworkOperator) -> NetworkOperator:
    """``law`` with the inputs of a guided law (y1, y2, y3, c): a law of (y1, y2) or (y1, y2,
    y3) gets the missing inputs as unused source nodes (the controller adds c to its output
    all the same; a variation may connect them).  Identity nodes at the end of the law make
    room within the controller's node count."""
    from descent_fmus.models.controllers.network_operator import L_MAX
    if reads_correction(law):
        return law
    names = list(law.input_names or [])
    want = [n for n, _ in GUIDED_INPUTS]
    if not 2 <= law.nx <= 3 or names != want[:law.nx] or len(law.outputs) != 1:
        raise ValueError(f"a guided law needs the inputs {', '.join(want[:3])} (the first two "
                         f"at least) and one output; got inputs {names}")
    add = len(want) - law.nx
    psi, out = law.psi.copy(), law.outputs[0] - 1
    while psi.shape[0] + add > L_MAX:
        if out < psi.shape[0] - 1:                   # nodes after the output: unused
            psi = psi[:-1, :-1]
            continue
        src = np.flatnonzero(psi[:out, out])
        if len(src) != 1 or psi[src[0], out] != 1 or psi[out, out] not in (1, 2):
            raise ValueError(f"the law needs {add} free nodes for the guided inputs and its "
                             f"output node is not an identity node that can be dropped")
        psi, out = psi[:-1, :-1], int(src[0])        # an identity node: its source is the output
    n, nx = psi.shape[0], law.nx
    keep = [k if k < nx else k + add for k in range(n)]
    new = np.zeros((n + add, n + add), dtype=int)
    new[np.ix_(keep, keep)] = psi
    scale = list(law.input_scale) + [v for _, v in GUIDED_INPUTS[nx:]]
    offset = list(law.input_offset) + [0.0] * add
    return NetworkOperator(new, len(want), list(law.q), [keep[out] + 1], bounds=list(law.bounds),
                           input_names=want, input_scale=scale, input_offset=offset)


def best_row(rows):
    """The robust law of a run [choice]: the lowest J2 among the laws that flew the whole set
    with median J1 below J1_LIMIT and the nominal flight within 1 km (the issue's targets);
    without such a law, the lowest J2 with median J1 below J1_LIMIT; None if there is none."""
    ok = [r for r in rows if r["J1"] < J1_LIMIT and not r.get("raced_out")]
    nominal = [r for r in ok if r.get("miss_nominal", math.inf) < spec.ON_TARGET]
    pool = nominal or ok
    return min(pool, key=lambda r: r["J2"]) if pool else None


class SensedReport(Report):
    """The robust law by :func:`best_row`."""

    def headline(self, front):
        ok = front[front[:, 0] < J1_LIMIT]
        return {f"J2@J1<{J1_LIMIT:g}": f"{ok[:, 1].min():.0f}" if len(ok) else "-"}

    def summary(self, rows, out, reference=True):
        best = best_row(rows)
        return {"robust_law": best and {k: best[k] for k in (
            "k", "J1", "J2", "miss_nominal", "miss_median", "within_1km", "formula") if k in best}}

    def lines(self, summary):
        return [f"  robust_law: {summary.get('robust_law')}"]


#: Default budget of the robust problems [choice]: about 20 min with 2 workers on a 2-core
#: machine (benchmarks/reentry_robust.py measures the evaluation rate); ``flights`` is the
#: evaluation budget of the CMA-ES baseline (--method cma-polynomial), about what the GA spends.
SENSED_RECIPE = recipe(population=48, generations=40, crossovers=12, lchr=8, epoch=10, seed=1,
                       refine_evals=150, refine_laws=1, flights=2600)
#: Which closed-loop path the robust problems fly [choice] (benchmarks/reentry_robust.py): the
#: container FMU costs about as much CPU as the Python master for the two-input law and more for
#: the sensed law, whose seven connections the container sets one FMI call each where the master
#: sets them in one call.
SENSED_CONTAINER = False
PLAIN_CONTAINER = True


#: Default budget of ``reentry-guided`` [choice]: a law costs up to 16 flights of ~0.15 s (the
#: on-board predictions), so the run stops after 600 law evaluations (about 10 min with 2
#: workers); CMA-ES tunes the basic solution's parameters first (120 evaluations; its shape is
#: already a good nominal law), then the GA with 80 evaluations of refinement per epoch.
GUIDED_RECIPE = recipe(population=32, generations=60, crossovers=8, lchr=8, epoch=10, seed=1,
                       refine_evals=80, refine_laws=1, refine_basis=120, flights=600,
                       basis_rule="target")


def best_guided_row(rows):
    """The guided law of a run [choice]: the lowest median J1 among the laws that flew the whole
    set with a median miss below 1 km and the nominal flight within 1 km; None if there is none."""
    ok = [r for r in rows if r["J2"] < spec.ON_TARGET and not r.get("raced_out")
          and r.get("miss_nominal", math.inf) < spec.ON_TARGET]
    return min(ok, key=lambda r: r["J1"]) if ok else None


class GuidedReport(Report):
    """The guided law by :func:`best_guided_row`."""

    def headline(self, front):
        ok = front[front[:, 1] < spec.ON_TARGET]
        return {"J1@miss<1km": f"{ok[:, 0].min():.4f}" if len(ok) else "-"}

    def summary(self, rows, out, reference=True):
        best = best_guided_row(rows)
        return {"guided_law": best and {k: best[k] for k in (
            "k", "J1", "J2", "miss_nominal", "J1_nominal", "within_1km", "formula")
            if k in best}}

    def lines(self, summary):
        return [f"  guided_law: {summary.get('guided_law')}"]


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


def problems(statistic_name: str = "mean", samples: int = SYNTHESIS_SAMPLES,
             seed: int = SYNTHESIS_SEED) -> tuple:
    """The robust problems over the synthesis set (see the module docstring)."""
    params = synthesis_set(samples, seed)
    states = tuple(spec.plant_values(p) for p in params)
    objectives = RobustObjectives(statistic_name, samples)
    race = Race(RACE_SIZES, proceed)
    target = Target(objective=1, constraint=0, limit=J1_LIMIT)
    labels = ("J1 = median max load over the set", f"J2 = {statistic_name} miss over the set [m]")
    common = dict(initial_states=states, objectives=objectives, objective_names=("J1", "J2"),
                  penalty=(spec.DIVERGED_J1, 4 * RACE_OFFSET), **SENSED_RECIPE,
                  objective_labels=labels, q_bits=spec.SCALED_Q_BITS, report=SensedReport(),
                  source=f"system reentry (set: {samples} samples, seed {seed}, "
                         f"{statistic_name})",
                  target=target, options=(STATISTIC_OPTION,))
    return (
        SynthesisProblem(
            name="reentry-sensed", wiring=SENSED_WIRING, basic_law=sensed_basic_law(3),
            baselines=sensed_baselines, runner=Runner(container=SENSED_CONTAINER, race=race),
            description="S1 reentry, robust guidance with sensed drag: u = phi(y1, y2, y3) over "
                        f"a seeded set of {samples} dispersion samples (median J1, "
                        f"{statistic_name} miss)", **common),
        SynthesisProblem(
            name="reentry-sensed-y12", wiring=spec.WIRING, basic_law=sensed_basic_law(2),
            baselines=sensed_y12_baselines, runner=Runner(container=PLAIN_CONTAINER, race=race),
            description="S1 reentry, the robust objective of reentry-sensed with a law of y1, y2 "
                        "only (no drag measurement)", **common),
        SynthesisProblem(
            name="reentry-guided", wiring=GUIDED_WIRING, basic_law=guided_basic_law,
            runner=Runner(container=SENSED_CONTAINER, race=race),
            **dict(common, objectives=RobustObjectives("median", samples),
                   objective_labels=(labels[0], "J2 = median miss over the set [m]"),
                   **GUIDED_RECIPE, report=GuidedReport(),
                   target=Target(objective=0, constraint=1, limit=spec.ON_TARGET),
                   source=f"system reentry (set: {samples} samples, seed {seed}, median)"),
            description="S1 reentry, guided: a law u = phi(y1, y2, y3, c) plus the on-board "
                        "correction c (a predictor-corrector flying the law itself), min median "
                        f"J1 and median miss over the set of {samples} samples"),
    )



#: The robust law the built ``ReentrySensedClosedLoop.fmu`` carries (from the default
#: ``synthesize reentry-sensed`` run; docs/make_reentry_robust_figures.py writes it).
DEFAULT_LAW_FILE = Path(__file__).with_name("sensed_law.json")


def default_law() -> NetworkOperator:
    """The law of ``ReentrySensedClosedLoop.fmu``: the committed robust law, or the basic
    solution if none is committed."""
    if DEFAULT_LAW_FILE.exists():
        return NetworkOperator.load(DEFAULT_LAW_FILE)
    return sensed_basic_law(3)


def default_law_values() -> dict:
    return default_law().start_values()


#: The law the built ``ReentryGuidedClosedLoop.fmu`` carries [choice]: the committed result of
#: the default ``synthesize reentry-guided`` run if there is one, else its basic solution.
GUIDED_LAW_FILE = Path(__file__).with_name("guided_law.json")


#: The nominal law the guided synthesis starts from [choice]: the best law with miss < 1 km of
#: the default ``synthesize reentry`` run.
NOMINAL_LAW_FILE = Path(__file__).with_name("nominal_law.json")


def guided_basic_law() -> NetworkOperator:
    """The guided problem's basic solution: the nominal law with the inputs y3, c added."""
    return as_guided(NetworkOperator.load(NOMINAL_LAW_FILE))


def default_guided_law() -> NetworkOperator:
    if GUIDED_LAW_FILE.exists():
        return NetworkOperator.load(GUIDED_LAW_FILE)
    return guided_basic_law()


def default_guided_law_values() -> dict:
    return default_guided_law().start_values()
