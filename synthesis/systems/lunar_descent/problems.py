"""S5 descent from lunar orbit: the closed-loop wiring and the network-operator synthesis problem.

* :data:`WIRING` -- the LunarDescent plant with the generic NetworkOperatorController (two
  outputs: u1 thrust direction, u2 thrust change);
* :func:`per_state` -- J1, J2 contributions of one flight from the plant's final outputs, with
  the penalties of a crash and of a flight that never enters the box;
* :func:`problems` -- ``lunar-descent``: the criteria summed over a set of initial states (robust
  by construction).

References
----------
A.I. Diveev et al., Vestnik MGTU im. Baumana, ser. Priborostroenie, 2013, no. 4 (problem
statement, criteria J1 = |hf - h(tf)| + s, J2 = |Vf - V(tf)| over a set of initial points); the
scenario numbers are our [choice] (models/README.md).
"""
from __future__ import annotations

import math

import numpy as np

from descent_fmus.models.integrators import CRASHED, REACHED
from descent_fmus.models.lunar_descent import T_PLUS, U1_BOUNDS, U2_BOUNDS, DescentParams
from descent_fmus.synthesis.fmi.closed_loop import STATUS_STOP, Wiring
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.problems.contract import (LAB_SEARCH, Report, SynthesisProblem,
                                                      recipe)

__all__ = ["WIRING", "STEP", "LOOP_PARAMETERS", "INITIAL_SET", "initial_states", "per_state",
           "totals", "objectives", "synthesis_basic_law", "basic_law_start_values", "problems",
           "LunarDescentReport", "U_BOUNDS", "HF", "VF", "CRASH_S", "NOT_IN_BOX_H",
           "NOT_IN_BOX_V", "LUNAR_DESCENT_RECIPE"]

#: Communication step [s] (the law's sample-and-hold period): halving it to 0.5 s moves h(tf)
#: of the basic law by < 2.5 m per state (of a 500 m half box); the RK4 sub-step (1 s) is
#: converged to 0.01 m (tests/systems/lunar_descent/test_lunar_descent_model.py).
STEP = 1.0

#: Controller output bounds: u1 in [pi, 2 pi] rad, u2 in [-40, 40] kgf (the plant's clipping).
U_BOUNDS = (U1_BOUNDS, U2_BOUNDS)

WIRING = Wiring(
    name="LunarDescentClosedLoop",
    plant="LunarDescent",
    controller="NetworkOperatorController",
    to_controller=(("y1", "x[1]"), ("y2", "x[2]"), ("y3", "x[3]"), ("y4", "x[4]")),
    to_plant=(("u[1]", "u1"), ("u[2]", "u2")),
    step=STEP,
    stop_time=T_PLUS,
    stop=STATUS_STOP,
    exposed=(("V", "plant", "V"), ("theta", "plant", "theta"), ("h", "plant", "h"),
             ("m", "plant", "m"), ("fuel", "plant", "fuel"), ("h_min", "plant", "h_min"),
             ("status", "plant", "status"), ("t_end", "plant", "t_end"),
             ("u1", "controller", "u[1]"), ("u2", "controller", "u[2]")),
    description="S5 descent from lunar orbit (LunarDescent plant) under a two-output "
                "network-operator law (u1 thrust direction, u2 thrust change)",
)

#: Parameters the closed-loop FMU exposes (the initial state and the dispersion parameters).
LOOP_PARAMETERS = (("theta0", "plant", "theta0"), ("h0", "plant", "h0"), ("m0", "plant", "m0"),
                   ("k_P", "plant", "k_P"), ("P_ud", "plant", "P_ud"))

#: The initial-state set of the robust synthesis [choice]: the corners and the centre of
#: theta0 in [89, 91] deg x h0 in [17.5, 18.5] km, m0 = 1400 kg, V0 = 1690 m/s.
INITIAL_SET = tuple((math.radians(a), h) for a, h in
                    ((89.0, 17_500.0), (89.0, 18_500.0), (91.0, 17_500.0), (91.0, 18_500.0),
                     (90.0, 18_000.0)))

#: Targets of J1 [m] and J2 [m/s]: the centre of the default terminal box.
HF, VF = DescentParams().hf, DescentParams().Vf
#: s of J1 when h reached 0 (Diveev et al. 2013) [m].
CRASH_S = 100.0
#: Added to J1 [m] and J2 [m/s] of an initial state whose flight never entered the box
#: (ended at t+ or left the model's domain) [choice]: a law that reaches the box from a state
#: is always preferred for that state.
NOT_IN_BOX_H, NOT_IN_BOX_V = 1000.0, 100.0


def initial_states(states=INITIAL_SET, **extra) -> tuple:
    """Plant start values (theta0 [rad], h0 [m] and ``extra`` parameters) for each initial
    state."""
    return tuple(dict(theta0=th, h0=h, **extra) for th, h in states)


def per_state(final: dict, hf: float = HF, Vf: float = VF,
              h_lo: float = DescentParams().h_lo) -> dict:
    """J1, J2 contributions and report values of one flight from its plant final outputs.

    j1 = |hf - h(tf)| + s (s = 100 m at a crash) + max(0, hf- - h_min) + [not in box] 1000 m;
    j2 = |Vf - V(tf)| + [not in box] 100 m/s.  The floor term [choice] keeps the braking phase
    above the box until it enters it: the box is where the next phase (vertical landing) starts.

    Parameters
    ----------
    final : dict
        Plant outputs at the end of the flight (``ClosedLoopResult.final``): ``status``, ``V``
        [m/s], ``h`` [m], ``h_min`` [m], ``fuel`` [kg], ``t_end`` [s].
    hf, Vf, h_lo : float
        Target altitude [m], target speed [m/s], box floor [m].
    """
    V, h, h_min = final["V"], final["h"], final["h_min"]
    if not all(math.isfinite(v) for v in (V, h, h_min, final["fuel"])):
        return {"j1": 2 * (hf + CRASH_S + NOT_IN_BOX_H), "j2": 2 * (Vf + NOT_IN_BOX_V),
                "in_box": False, "crashed": False, "h": 0.0, "V": 0.0, "h_min": 0.0,
                "fuel": 0.0, "t_end": -1.0}
    status = int(final["status"])
    in_box, crashed = status == REACHED, status == CRASHED
    j1 = abs(hf - h) + (CRASH_S if crashed else 0.0) + max(0.0, h_lo - h_min)
    j2 = abs(Vf - V)
    if not in_box:
        j1 += NOT_IN_BOX_H
        j2 += NOT_IN_BOX_V
    return {"j1": j1, "j2": j2, "in_box": in_box, "crashed": crashed, "h": h, "V": V,
            "h_min": h_min, "fuel": final["fuel"], "t_end": final["t_end"]}


def totals(rows) -> tuple:
    """(J1 [m], J2 [m/s]) summed over the :func:`per_state` rows, and the reported values."""
    j1 = sum(r["j1"] for r in rows)
    j2 = sum(r["j2"] for r in rows)
    extras = {"in_box": sum(r["in_box"] for r in rows), "crashed": sum(r["crashed"] for r in rows),
              "h_min": min(r["h_min"] for r in rows),
              "dh_max": max(abs(r["h"] - HF) for r in rows),
              "dV_max": max(abs(r["V"] - VF) for r in rows),
              "fuel_max": max(r["fuel"] for r in rows),
              "fuel_mean": sum(r["fuel"] for r in rows) / len(rows)}
    return (j1, j2), extras


def objectives(results) -> tuple:
    """The objective function: (J1, J2) over the flights (one ``ClosedLoopResult`` per initial
    state) and the reported values."""
    return totals([per_state(r.final) for r in results])


#: Gains of the designer's basic law (rounded from a short Nelder-Mead fit of the linear law on
#: the initial set, in-process): u1 = theta + q1 + q2 y2 + q3 y3 + q4 y4,
#: u2 = q8 (q5 + q6 y2 + q7 y4).
BASIC_Q = (3.25, -3.5, 0.5, -2.0, 0.25, -1.5, -0.25, 16.0)


def synthesis_basic_law(q=BASIC_Q) -> NetworkOperator:
    """The GA's first basic solution: a linear feedback law on a 32-node matrix.

    Nodes: 1 y1 = theta, 2 y2, 3 y3, 4 y4, 5-12 q1..q8; 13 = q2 y2, 14 = q3 y3, 15 = q4 y4,
    16 = y1 + q1 + z13 + z14 + z15; 17 = q6 y2, 18 = q7 y4, 19 = q5 + z17 + z18, 20 = q8 z19;
    21-26 identity nodes carrying z16 to the output u1 (node 26), 27-32 carrying z20 to the
    output u2 (node 32): spare nodes on which the variations build structure.
    """
    L = 32
    psi = np.zeros((L, L), dtype=int)
    arcs = [(6, 13), (2, 13), (7, 14), (3, 14), (8, 15), (4, 15), (1, 16), (5, 16), (13, 16),
            (14, 16), (15, 16), (10, 17), (2, 17), (11, 18), (4, 18), (9, 19), (17, 19),
            (18, 19), (12, 20), (19, 20), (16, 21), (20, 27)]
    arcs += [(k, k + 1) for k in range(21, 26)] + [(k, k + 1) for k in range(27, 32)]
    for a, b in arcs:
        psi[a - 1, b - 1] = 1
    for node, op in [(13, 2), (14, 2), (15, 2), (16, 1), (17, 2), (18, 2), (19, 1), (20, 2)]:
        psi[node - 1, node - 1] = op
    for node in range(21, 33):
        psi[node - 1, node - 1] = 1
    return NetworkOperator(psi, nx=4, q=list(q), outputs=[26, 32], bounds=list(U_BOUNDS),
                           input_names=["theta", "y2", "y3", "y4"])


def basic_law_start_values() -> dict:
    """Controller start values of the basic law (the defaults of LunarDescentClosedLoop.fmu)."""
    return synthesis_basic_law().start_values()


#: Sum of |hf - h(tf)| over the set below which a law counts as hitting the box centre [m].
ON_TARGET_J1 = 100.0


class LunarDescentReport(Report):
    """Best J2 near the box centre (progress bar); the laws that bring every state into the box
    and the one of them closest to the box centre in h (summary)."""

    def headline(self, front):
        """Best J2 among front members with J1 < 100 m (all in the box)."""
        ok = front[front[:, 0] < ON_TARGET_J1]
        return {"J2@J1<100": f"{ok[:, 1].min():.3f}" if len(ok) else "-"}

    def summary(self, rows, out, reference=True):
        n = len(INITIAL_SET)
        ok = [r for r in rows if r.get("in_box") == n]
        result = {"laws_all_in_box": len(ok)}
        if ok:
            best = min(ok, key=lambda r: (r["J1"], r["J2"]))
            result["best_all_in_box"] = {k: best[k] for k in ("k", "J1", "J2", "h_min",
                                                              "fuel_max", "formula")
                                         if k in best}
        return result

    def lines(self, summary):
        out = [f"  laws with every initial state in the box: {summary['laws_all_in_box']}"]
        b = summary.get("best_all_in_box")
        if b:
            out.append(f"  the best of them: k = {b['k']}, J1 = {b['J1']:.3f} m, J2 = "
                       f"{b['J2']:.3f} m/s, h_min = {b['h_min']:.0f} m, fuel max = "
                       f"{b['fuel_max']:.1f} kg: {b['formula']}")
        return out


#: Default budget of ``descent-fmus synthesize lunar-descent`` [choice]: six independent CMA-ES
#: searches of 8 000 laws on the basic law's gains (``refine_starts``: one search settles in
#: one basin of a multimodal J1 within its first few thousand laws; over 12 seeds one search
#: ends at or below 0.1 m on 4 of them, so six reach such a basin on ~9 runs in 10), then the
#: structure search with 500 CMA-ES laws per epoch on promising forms.  54 000 laws take about
#: 2 min on the native twins (measured runs: docs/systems/lunar_descent.md).
LUNAR_DESCENT_RECIPE = recipe(population=128, generations=1000, crossovers=32, lchr=8, epoch=10,
                              seed=1, flights=54_000, refine_basis=8000, refine_starts=6,
                              refine_evals=500, refine_basis_patience=0, **LAB_SEARCH)
#: Gray code of the parameters [choice]: 11 + 31 bits over [-1024, 1024) -- the basic law's
#: gain q8 = 16 sat on the edge of the former [-16, 16) and the refined gains reach hundreds,
#: and the former grid of 2^-11 held the CMA-ES refinement to J1 ~ 1.8 m where a continuous
#: CMA-ES over the same gains reaches 0.017 m; the grid is now 4.7e-10.
Q_BITS = (11, 31, -1024.0, 1024.0)

#: Objectives of a law whose evaluation failed: twice the worst per-state penalty.
_PENALTY = (2 * len(INITIAL_SET) * (HF + CRASH_S + NOT_IN_BOX_H + DescentParams().h_lo),
            2 * len(INITIAL_SET) * (DescentParams().V0 + NOT_IN_BOX_V))


def problems() -> tuple:
    """The registered S5 synthesis problem."""
    return (
        SynthesisProblem(
            name="lunar-descent", wiring=WIRING, initial_states=initial_states(),
            objectives=objectives, objective_names=("J1", "J2"), penalty=_PENALTY,
            basic_law=synthesis_basic_law(), **LUNAR_DESCENT_RECIPE,
            objective_labels=("J1 = sum |hf - h(tf)| + penalties [m]",
                              "J2 = sum |Vf - V(tf)| + penalties [m/s]"),
            q_bits=Q_BITS, report=LunarDescentReport(),
            source="system lunar_descent",
            description="S5 descent from lunar orbit: sum over 5 initial states of |hf - h(tf)| "
                        "+ penalties (J1) [m] and |Vf - V(tf)| + penalties (J2) [m/s]"),
    )
