"""S5 descent from lunar orbit: wiring of the LunarDescent plant with the generic
network-operator controller (two outputs: u1 thrust direction, u2 thrust change), and the
robust synthesis problem ``lunar-descent`` (criteria summed over a set of initial states).

References
----------
Seed 004: A.I. Diveev et al., Vestnik MGTU im. Baumana, ser. Priborostroenie, 2013, no. 4
(problem statement, criteria J1 = |hf - h(tf)| + s, J2 = |Vf - V(tf)| over initial points);
the scenario numbers are SPEC S5's [choice] (models/README.md).
"""
from __future__ import annotations

import math

from descent_fmus.synthesis.cosim import Wiring
from descent_fmus.synthesis.scenarios import ClosedLoopSpec, register

__all__ = ["WIRING", "STEP", "INITIAL_SET", "initial_states", "per_state", "objectives",
           "synthesis_basic_law", "U_BOUNDS", "CRASH_S", "NOT_IN_BOX_H", "NOT_IN_BOX_V"]

#: Communication step [s] (the law's sample-and-hold period): halving it to 0.5 s moves h(tf)
#: of the basic law by < 2.5 m per state (of a 500 m half box); the RK4 sub-step (1 s) is
#: converged to 0.01 m (tests/test_lunar_descent.py).
STEP = 1.0

#: Controller output bounds: u1 in [pi, 2 pi] rad, u2 in [-40, 40] kgf (SPEC S5).
U_BOUNDS = ((math.pi, 2.0 * math.pi), (-40.0, 40.0))

WIRING = Wiring(
    name="LunarDescentClosedLoop",
    plant="LunarDescent",
    controller="NetworkOperatorController",
    to_controller=(("y1", "x[1]"), ("y2", "x[2]"), ("y3", "x[3]"), ("y4", "x[4]")),
    to_plant=(("u[1]", "u1"), ("u[2]", "u2")),
    step=STEP,
    stop_time=600.0,
    stop_flag="stop",
    exposed=(("V", "plant", "V"), ("theta", "plant", "theta"), ("h", "plant", "h"),
             ("m", "plant", "m"), ("fuel", "plant", "fuel"), ("h_min", "plant", "h_min"),
             ("t_end", "plant", "t_end"), ("stop", "plant", "stop"),
             ("u1", "controller", "u[1]"), ("u2", "controller", "u[2]")),
    description="S5 descent from lunar orbit (LunarDescent plant) under a two-output "
                "network-operator law (u1 thrust direction, u2 thrust change)",
)

#: The initial-state set of the robust synthesis [choice]: the corners and the centre of
#: theta0 in [89, 91] deg x h0 in [17.5, 18.5] km (SPEC S5), m0 = 1400 kg, V0 = 1690 m/s.
INITIAL_SET = tuple((math.radians(a), h) for a, h in
                    ((89.0, 17_500.0), (89.0, 18_500.0), (91.0, 17_500.0), (91.0, 18_500.0),
                     (90.0, 18_000.0)))

#: s of J1 when h reached 0 (SPEC S5) [m].
CRASH_S = 100.0
#: Added to J1 [m] and J2 [m/s] of an initial state whose flight never entered the box
#: (ended at t+ or left the model's domain) [choice]: a law that reaches the box from a state
#: is always preferred for that state.
NOT_IN_BOX_H, NOT_IN_BOX_V = 1000.0, 100.0


def initial_states(states=INITIAL_SET, **extra) -> tuple:
    """Plant start values (theta0, h0 and ``extra`` parameters) for each initial state."""
    return tuple(dict(theta0=th, h0=h, **extra) for th, h in states)


def per_state(final: dict, hf: float = 2000.0, Vf: float = 50.0, h_lo: float = 1500.0) -> dict:
    """J1, J2 contributions and report values of one flight from its plant final outputs.

    j1 = |hf - h(tf)| + s (s = 100 m at a crash) + max(0, hf- - h_min) + [not in box] 1000 m;
    j2 = |Vf - V(tf)| + [not in box] 100 m/s.  The floor term [choice] keeps the braking phase
    above the box until it enters it: the box is where the next phase (vertical landing) starts.
    """
    end = int(round(final["end"]))
    V, h, h_min = final["V"], final["h"], final["h_min"]
    if not all(math.isfinite(v) for v in (V, h, h_min, final["fuel"])):
        return {"j1": 2 * (hf + CRASH_S + NOT_IN_BOX_H), "j2": 2 * (Vf + NOT_IN_BOX_V),
                "in_box": False, "crashed": False, "h": 0.0, "V": 0.0, "h_min": 0.0,
                "fuel": 0.0, "t_end": -1.0}
    in_box, crashed = end == 1, end == 2
    j1 = abs(hf - h) + (CRASH_S if crashed else 0.0) + max(0.0, h_lo - h_min)
    j2 = abs(Vf - V)
    if not in_box:
        j1 += NOT_IN_BOX_H
        j2 += NOT_IN_BOX_V
    return {"j1": j1, "j2": j2, "in_box": in_box, "crashed": crashed, "h": h, "V": V,
            "h_min": h_min, "fuel": final["fuel"], "t_end": final["t_end"]}


def objectives(finals) -> tuple:
    """(J1, J2) summed over the initial states, and the reported values."""
    rows = [per_state(f) for f in finals]
    j1 = sum(r["j1"] for r in rows)
    j2 = sum(r["j2"] for r in rows)
    extras = {"in_box": sum(r["in_box"] for r in rows), "crashed": sum(r["crashed"] for r in rows),
              "h_min": min(r["h_min"] for r in rows),
              "dh_max": max(abs(r["h"] - 2000.0) for r in rows),
              "dV_max": max(abs(r["V"] - 50.0) for r in rows),
              "fuel_max": max(r["fuel"] for r in rows),
              "fuel_mean": sum(r["fuel"] for r in rows) / len(rows)}
    return (j1, j2), extras


#: Gains of the designer's basic law (rounded from a short Nelder-Mead fit of the linear law on
#: the initial set, in-process): u1 = theta + q1 + q2 y2 + q3 y3 + q4 y4,
#: u2 = q8 (q5 + q6 y2 + q7 y4).
BASIC_Q = (3.25, -3.5, 0.5, -2.0, 0.25, -1.5, -0.25, 16.0)


def synthesis_basic_law(q=BASIC_Q):
    """The GA's first basic solution: a linear feedback law on a 32-node matrix.

    Nodes: 1 y1 = theta, 2 y2, 3 y3, 4 y4, 5-12 q1..q8; 13 = q2 y2, 14 = q3 y3, 15 = q4 y4,
    16 = y1 + q1 + z13 + z14 + z15; 17 = q6 y2, 18 = q7 y4, 19 = q5 + z17 + z18, 20 = q8 z19;
    21-26 identity nodes carrying z16 to the output u1 (node 26), 27-32 carrying z20 to the
    output u2 (node 32): spare nodes on which the variations build structure.
    """
    import numpy as np

    from descent_fmus.synthesis.methods.network_operator import NetworkOperator
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


#: Default budget of ``descent-fmus synthesize lunar-descent`` [choice]: a flight costs about
#: 15 ms through the FMUs and a law 5 flights, so this is ~12 000 evaluations, well under 15 min
#: on 2 cores (measured run: models/README.md).
GA_BUDGET = {"population": 128, "generations": 120, "crossovers": 32, "lchr": 8, "epoch": 10}

#: Sum of |hf - h(tf)| over the set below which a law counts as hitting the box centre [m].
ON_TARGET_J1 = 100.0


def headline(front):
    """Progress-bar field: best J2 among front members with J1 < 100 m (all in the box)."""
    ok = front[front[:, 0] < ON_TARGET_J1]
    return {"J2@J1<100": f"{ok[:, 1].min():.3f}" if len(ok) else "-"}


def summary(rows, reference_j1=None):
    """Report fields of a finished run: the law closest to the box centre in h with every state
    in the box, and how many front laws bring every state into the box."""
    n = len(INITIAL_SET)
    ok = [r for r in rows if r.get("in_box") == n]
    out = {"laws_all_in_box": len(ok)}
    if ok:
        best = min(ok, key=lambda r: (r["J1"], r["J2"]))
        out["best_all_in_box"] = {k: best[k] for k in ("k", "J1", "J2", "h_min", "fuel_max",
                                                       "formula") if k in best}
    return out


def fly_in_process(law, theta0: float, h0: float, step: float = STEP, dt: float | None = None,
                   trace: list | None = None, **params):
    """Fly a law in-process (models.lunar_descent.simulate, same equations as the FMU) -- for
    tests and quick scans; the synthesis itself evaluates through the FMUs."""
    from descent_fmus.models import lunar_descent as ld
    p = ld.DescentParams(theta0=theta0, h0=h0, **params)
    return ld.simulate(p, lambda t, x: law(ld.controller_inputs(x, p)), step=step,
                       dt=ld.DT_INTEGRATION if dt is None else dt, trace=trace)


def _register_problem():
    from descent_fmus.synthesis.evaluator import SynthesisProblem, register_problem
    register_problem(SynthesisProblem(
        name="lunar-descent", wiring=WIRING, initial_states=initial_states(),
        objectives=objectives, objective_names=("J1", "J2"),
        penalty=(2 * len(INITIAL_SET) * (2000.0 + CRASH_S + NOT_IN_BOX_H + 1500.0),
                 2 * len(INITIAL_SET) * (1690.0 + NOT_IN_BOX_V)),
        basic_law=synthesis_basic_law, q_bits=(5, 11, -16.0, 16.0),
        description="S5 descent from lunar orbit: sum over 5 initial states of |hf - h(tf)| + "
                    "penalties (J1) [m] and |Vf - V(tf)| + penalties (J2) [m/s]",
        defaults={"headline": headline, "summary": summary, "ga": GA_BUDGET}))


register(
    slaves=["models/lunar_descent.py", "models/controllers/network_operator.py"],
    closed_loops=[ClosedLoopSpec(
        WIRING, controller_defaults=synthesis_basic_law().start_values(),
        parameters=(("theta0", "plant", "theta0"), ("h0", "plant", "h0"), ("m0", "plant", "m0"),
                    ("k_P", "plant", "k_P"), ("P_ud", "plant", "P_ud")))],
)

_register_problem()
