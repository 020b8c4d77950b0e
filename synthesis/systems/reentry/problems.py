"""S1 reentry: the closed-loop wiring and the network-operator synthesis problems.

* :data:`WIRING` -- the Reentry plant with the generic NetworkOperatorController (y1, y2 -> u);
* :func:`objectives` -- J1 (max load), J2 (miss at hf) of one flight from the plant's final
  outputs, with the penalties of a flight that never reaches hf;
* :func:`problems` -- ``reentry`` (nominal flight) and ``reentry-robust`` (nominal + the rho0
  and V0 extremes of the dispersion set).

References
----------
Diveev & Shmalko (reentry paper): criteria eqs. (7)-(8), basic law eqs. (24)-(25).
"""
from __future__ import annotations

import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from descent_fmus.models.controllers.network_operator import PAPER_Q
from descent_fmus.models.integrators import REACHED
from descent_fmus.models.reentry import T_PLUS, ReentryParams
from descent_fmus.synthesis.fmi.closed_loop import STATUS_STOP, Wiring
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.pareto import Target
from descent_fmus.synthesis.problems.contract import Report, SynthesisProblem, recipe
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law, reentry_law

__all__ = ["WIRING", "STEP", "LOOP_PARAMETERS", "plant_values", "objectives", "problems",
           "synthesis_basic_law", "NOT_LANDED_PENALTY", "DIVERGED_J1", "ON_TARGET",
           "ROBUST_CASES", "REENTRY_RECIPE", "TARGET", "baseline_structures",
           "paper_basic_law_16", "bound_reference", "INPUT_SCALE", "TIGHT_MISS", "Q_BITS",
           "robust_basic_law", "WINDOW_CENTRE", "WINDOW_HALF", "SCALED_Q_BITS"]

#: Communication step of the reentry closed loop [s] (halving it changes J1 by < 0.5 %:
#: tests/test_cosim.py).
STEP = 1.0

WIRING = Wiring(
    name="ReentryClosedLoop",
    plant="Reentry",
    controller="NetworkOperatorController",
    to_controller=(("y1", "x[1]"), ("y2", "x[2]")),
    to_plant=(("u[1]", "u"),),
    step=STEP,
    stop_time=T_PLUS,
    stop=STATUS_STOP,
    exposed=(("h", "plant", "h"), ("L", "plant", "L"), ("load", "plant", "load"),
             ("aero_load", "plant", "aero_load"), ("load_max", "plant", "load_max"),
             ("y1", "plant", "y1"), ("y2", "plant", "y2"), ("u", "controller", "u[1]"),
             ("status", "plant", "status"), ("t_end", "plant", "t_end")),
    description="S1 Earth reentry (Reentry plant) under a network-operator law "
                "(default: the paper's basic law q1 = 2.259375, q2 = 1.953125)",
)

#: Parameters the closed-loop FMU exposes.
LOOP_PARAMETERS = (("V0", "plant", "V0"), ("h0", "plant", "h0"), ("beta0", "plant", "beta0"),
                   ("m", "plant", "m"), ("rho0", "plant", "rho0"),
                   ("q[1]", "controller", "q[1]"), ("q[2]", "controller", "q[2]"))

#: Miss assigned on top of the distance to go when a flight never reaches hf by t+ [m]: larger
#: than any miss of a flight that lands (half the Earth's circumference is 2.0e7 m), so a law
#: that does not land is never preferred to one that does.
NOT_LANDED_PENALTY = 2.0e7
#: J1 of a diverged integration (never a NaN in a result).
DIVERGED_J1 = 1.0e3
#: miss below which a law counts as landing on target [m]
ON_TARGET = 1000.0


def plant_values(params: ReentryParams) -> dict:
    """Start values of the Reentry FMU for a :class:`models.reentry.ReentryParams`."""
    return asdict(params)


def objectives(final: dict, params: ReentryParams) -> dict:
    """J1, J2 and reporting values from the plant's final outputs (``ClosedLoopResult.final``).

    J1 = max load (the paper's eq. 7, running max over all integration sub-steps);
    J2 = |L(tf) - Lf| if the flight reached hf, else the penalty ``NOT_LANDED_PENALTY`` plus the
    remaining range and altitude to go; a run with non-finite outputs gets J1 = DIVERGED_J1 too.
    """
    landed = final["status"] == REACHED
    L, h = final["L"], final["h"]
    j1, aero = final["load_max"], final["aero_load_max"]
    finite = all(math.isfinite(v) for v in (L, h, j1, aero))
    if not finite:
        return {"J1": DIVERGED_J1, "J2": NOT_LANDED_PENALTY * 2, "aero_load_max": DIVERGED_J1,
                "landed": False, "t_land": -1.0, "L_final": 0.0, "h_final": 0.0,
                "diverged": True}
    if landed:
        j2 = abs(L - params.Lf)
    else:
        j2 = NOT_LANDED_PENALTY + abs(params.Lf - L) + max(h - params.hf, 0.0)
    return {"J1": j1, "J2": j2, "aero_load_max": aero, "landed": landed,
            "t_land": final["t_end"], "L_final": L, "h_final": h, "diverged": False}


def paper_basic_law_16() -> NetworkOperator:
    """The paper's basic law q1*y1 + q2*y2 on a 16-node matrix (the GA's basic solution before
    the richer polynomial one; kept as the ``cma-basic`` baseline structure).

    Nodes: 1 y1, 2 y2, 3-6 q1..q4 (q3, q4 unused until a variation connects them),
    7 = q1*y1, 8 = q2*y2, 9 = 7 + 8, then identity nodes 10..16 (+) carrying z9 to the output
    node 16.
    """
    L = 16
    psi = np.zeros((L, L), dtype=int)
    for a, b, op in [(1, 7, 1), (3, 7, 1), (2, 8, 1), (4, 8, 1), (7, 9, 1), (8, 9, 1)]:
        psi[a - 1, b - 1] = op
    psi[6, 6], psi[7, 7], psi[8, 8] = 2, 2, 1
    for k in range(9, L):
        psi[k - 1, k] = 1
        psi[k, k] = 1
    return reentry_law(psi, list(PAPER_Q) + [1.0, 1.0], outputs=[L])


#: Input scaling of the baselines' laws [choice]: 10*y1 and 2*y2 are of order 1 along a flight
#: (y1 in [0, 0.2], y2 in [-1.1, -0.1] rad under the basic law).
INPUT_SCALE = (10.0, 2.0)
#: Input window of the GA's basic solution [choice] (models/README.md, "S1 synthesis"): its
#: inputs are w1 = (y1 - 0.19) / 0.01 and w2 = (y2 + 0.25) / 0.1, of order 1 where near-optimal
#: laws act (unclipped only between t ~ 125 s and 195 s, at y1 in [0.18, 0.20] near its
#: maximum and y2 in [-0.37, -0.15]).
WINDOW_CENTRE, WINDOW_HALF = (0.19, -0.25), (0.01, 0.1)


def _template(scale, offset=(0.0, 0.0)) -> NetworkOperator:
    return reentry_law(paper_basic_law_16().psi, list(PAPER_Q) + [1.0, 1.0], [16],
                       input_scale=list(scale), input_offset=list(offset))


def _paper_cubic(template: NetworkOperator, size: int | None = None) -> NetworkOperator:
    """A cubic polynomial in the template's inputs s_i = k_i (y_i - o_i) at the paper's basic
    law q1 y1 + q2 y2 = (q1 o1 + q2 o2) + (q1 / k1) s1 + (q2 / k2) s2 (the rest 0)."""
    from descent_fmus.synthesis.methods.structures import polynomial_law
    (k1, k2), (o1, o2) = template.input_scale, template.input_offset
    q = [PAPER_Q[0] * o1 + PAPER_Q[1] * o2, PAPER_Q[0] / k1, PAPER_Q[1] / k2] + [0.0] * 7
    return polynomial_law(template, 3, q, size=size)


def synthesis_basic_law() -> NetworkOperator:
    """The GA's first basic solution [choice]: a cubic polynomial in the window inputs
    (w1, w2) = ((y1 - 0.19) / 0.01, (y2 + 0.25) / 0.1) on 32 nodes, at the paper's basic law.

    Nodes: 1-2 the inputs, 3-12 the coefficients (constant first), 13-21 one product node per
    monomial, 22 their sum, 23-32 identity nodes (spare nodes on which the variations build
    structure).  The method leaves the basic solution to the designer; a richer one than the
    paper's linear law gives the parameter search (CMA-ES) more to work with, and inputs of
    order 1 where the law acts give it coefficients of order 1 that act nearly independently.
    """
    return _paper_cubic(_template([1.0 / h for h in WINDOW_HALF], WINDOW_CENTRE), size=32)


def robust_basic_law() -> NetworkOperator:
    """The robust variant's basic solution: the same cubic in the baselines' inputs
    (10 y1, 2 y2) on 32 nodes, at the paper's basic law (its Gray-coded bit flips search
    q in +-64, ``ROBUST_Q_BITS``)."""
    return _paper_cubic(_template(INPUT_SCALE), size=32)


def baseline_structures() -> dict:
    """The fixed structures of the CMA-ES baselines (``synthesize reentry --method cma-NAME``):
    ``basic`` the paper's basic law (its two gains), ``polynomial`` the basic solution's cubic
    polynomial (10 coefficients) in the inputs (10 y1, 2 y2), ``tanh`` a 2-3-1 tanh network (13 weights, seeded
    random start)."""
    from descent_fmus.synthesis.methods.structures import tanh_network_law
    return {"basic": paper_basic_law(),
            "polynomial": _paper_cubic(_template(INPUT_SCALE)),
            "tanh": tanh_network_law(_template(INPUT_SCALE), 3, seed=0)}


def flight_objectives(flight) -> dict:
    """:func:`objectives` of one flight, judged against the conditions it was flown from."""
    return objectives(flight.final, ReentryParams(**flight.start))


def nominal_objectives(results):
    """(J1, J2) and reported values of one flight (the problem's one initial state)."""
    o = flight_objectives(results[0])
    return (o["J1"], o["J2"]), {k: o[k] for k in ("aero_load_max", "landed", "t_land",
                                                  "L_final", "diverged")}


#: Initial states of the robust variant: the nominal flight and the extremes of the two
#: dispersion components that move the landing point most (rho0 +-15 %, V0 +-50 m/s).
ROBUST_CASES = ({}, {"rho0": 1.22 * 1.15}, {"rho0": 1.22 * 0.85}, {"V0": 7550.0}, {"V0": 7450.0})


def robust_objectives(results):
    """Robust variant: J1 = worst max load, J2 = mean miss over the flights (ROBUST_CASES)."""
    res = [flight_objectives(r) for r in results]
    j1 = max(r["J1"] for r in res)
    j2 = sum(r["J2"] for r in res) / len(res)
    return (j1, j2), {"miss_max": max(r["J2"] for r in res),
                      "landed_all": all(r["landed"] for r in res),
                      "J1_nominal": res[0]["J1"], "J2_nominal": res[0]["J2"]}


#: miss of the "tight" laws the report also gives, against the zero-miss bound [m]
TIGHT_MISS = 100.0


class ReentryReport(Report):
    """Best law with miss < 1 km (and < 100 m); ratios to the bound, the best open-loop program
    on the controller's 1 s grid at the same miss tolerance (cached in the run folder)."""

    def headline(self, front):
        ok = front[front[:, 1] < ON_TARGET]
        return {"J1@miss<1km": f"{ok[:, 0].min():.4f}" if len(ok) else "-"}

    def summary(self, rows, out, reference=True):
        result = {}
        for key, limit in (("best_miss_below_1km", ON_TARGET),
                           ("best_miss_below_100m", TIGHT_MISS)):
            ok = [r for r in rows if r["J2"] < limit]
            best = min(ok, key=lambda r: r["J1"]) if ok else None
            result[key] = best and {"k": best["k"], "J1": best["J1"], "J2": best["J2"],
                                    "readable": best.get("readable", best["formula"])}
        if reference:
            zero, tol = bound_reference(out)
            result["bound_J1"], result["bound_J1_zero_miss"] = tol, zero
            result["open_loop_J1"] = tol
            if result["best_miss_below_1km"]:
                result["ratio_to_bound"] = result["best_miss_below_1km"]["J1"] / tol
                result["ratio_to_open_loop"] = result["ratio_to_bound"]
            if result["best_miss_below_100m"]:
                result["ratio_100m_to_zero_miss_bound"] = \
                    result["best_miss_below_100m"]["J1"] / zero
            result["reference"] = {"value": tol, "label": "bound (miss <= 1 km)"}
        return result

    def lines(self, summary):
        return [f"  {key}: {summary[key]}" for key in (
            "best_miss_below_1km", "best_miss_below_100m", "bound_J1", "bound_J1_zero_miss",
            "ratio_to_bound", "ratio_100m_to_zero_miss_bound") if key in summary]


#: Files of the cached bounds in a run folder: zero miss, miss <= ON_TARGET.
BOUND_FILES = ("open_loop.json", "open_loop_1km.json")


def bound_reference(out_dir) -> tuple[float, float]:
    """J1 of the bound at zero miss and at miss <= 1 km (the best programs on the 1 s grid,
    true-peak load; ~30 s), cached as ``open_loop.json`` / ``open_loop_1km.json`` in the run."""
    from descent_fmus.synthesis.systems.reentry.bound import Program, reference_bounds
    paths = [Path(out_dir) / f for f in BOUND_FILES] if out_dir is not None else None
    if paths and all(pth.exists() for pth in paths):
        return tuple(Program.load(pth).J1 for pth in paths)
    progs = reference_bounds(ON_TARGET)
    if paths:
        for prog, pth in zip(progs, paths):
            prog.save(pth)
    return tuple(prog.J1 for prog in progs)


def open_loop_reference(out_dir) -> float:
    """J1 of the bound at miss <= 1 km (see :func:`bound_reference`)."""
    return bound_reference(out_dir)[1]


#: Default budget of `synthesize reentry` [choice] (models/README.md, "S1 synthesis"): CMA-ES
#: on the basic solution's parameters first (8000 flights: in the (10 y1, 2 y2) scaling the
#: cubic needed ~5000 uninterrupted ones to leave the J1 ~8.45 plateau, and without this
#: refinement seeds 1-3 ended at 1.002-1.07 x the bound), then the GA with CMA-ES refinement of the
#: best law's parameters (2000 evaluations, continued for a structure seen before) after every
#: epoch of 10 generations, stopped after 20 000 flights -- under 10 min with 2 workers on a
#: quiet 2-core machine.  ``flights`` is the same budget for the fixed-structure CMA-ES
#: baselines (--method cma-*).
REENTRY_RECIPE = recipe(population=128, generations=200, crossovers=32, lchr=8, epoch=10,
                        seed=2, refine_evals=2000, refine_laws=1, refine_basis=8000,
                        flights=20_000, basis_rule="target")
#: The robust variant costs 5 flights per law: smaller population, fewer generations.
ROBUST_RECIPE = recipe(population=128, generations=150, crossovers=32, lchr=8, epoch=12, seed=1)
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

_PENALTY = (DIVERGED_J1, 2 * NOT_LANDED_PENALTY)
_LABELS = ("J1 = max load (paper's eq. 7)", "J2 = miss at hf [m]")


def problems() -> tuple:
    """The registered S1 synthesis problems."""
    basic = synthesis_basic_law()
    return (
        SynthesisProblem(
            name="reentry", wiring=WIRING, initial_states=(plant_values(ReentryParams()),),
            objectives=nominal_objectives, objective_names=("J1", "J2"), penalty=_PENALTY,
            basic_law=basic, **REENTRY_RECIPE, objective_labels=_LABELS,
            q_bits=Q_BITS, report=ReentryReport(), source="system reentry", target=TARGET,
            baselines=baseline_structures,
            description="S1 Earth reentry: min max load (J1) and miss at hf (J2) [m]"),
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
