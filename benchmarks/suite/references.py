"""The references of the benchmark suite, each computed by other means than the synthesis.

* **lq** -- the exact optimum of the sampled-data LQ problem: the plant and its continuous
  quadratic cost discretised exactly for the zero-order hold of the communication step (Van
  Loan's block matrix exponential), then the discrete Riccati equation with the cross term
  (``scipy.linalg.solve_discrete_are(..., s=N)``); the optimum from x0 is x0' P x0, the
  optimal law u = -K x.  ``riccati.lq_reference``.
* **cartpole** -- the LQR law of the linearisation at the upright (the same sampled-data
  Riccati solution with the cart-pole's cost weights), flown through the FMU: which starts it
  saves; and per start the best open-loop program found by trajectory optimisation (L-BFGS-B,
  in-process RK4 identical to the plant's), replayed through the plant FMU.
  ``cartpole_reference.cartpole_lqr``, ``cartpole_reference.cartpole_programs``.
* **parking** -- the polar-coordinate law of Aicardi et al. (1995), flown through the same
  Unicycle FMU from the same starts: :func:`aicardi_law`, :func:`parking_reference`.
* **reentry-second** -- the best open-loop program of S1's second scenario at miss <= 1 km
  (:func:`synthesis.systems.reentry.bound.reference_bounds`): :func:`reentry_second_bound`.
* **lunar-descent** -- the best J1 of CMA-ES over the 8 gains of the basic law (measured,
  docs/systems/lunar_descent.md): :data:`LUNAR_DESCENT_CMA_J1`.

The computations live beside this file by job: the plants built and flown
(``plant_flights.py``), the sampled-data LQ solution (``riccati.py``), the cart-pole's programs
(``cartpole_reference.py``); this module has the parking and S1 references and the store.
Expensive references (the cart-pole programs, the S1 bound) are computed once and stored in
``benchmarks/suite/reference/*.json``; ``python benchmarks/suite/references.py`` recomputes
them.  Plants are flown through their FMUs with ``plant_flights.PlantFlyer`` (fmpy, the
master's order: read the outputs at t_k, compute u_k, step) or, for network-operator laws,
through the package's closed loop.
"""
from __future__ import annotations

import json
import math
import sys

import numpy as np

from cartpole_reference import cartpole_lqr, cartpole_programs
from plant_flights import BUILD, SUITE, PlantFlyer, build_plants

__all__ = ["STORED", "LUNAR_DESCENT_CMA_J1", "AICARDI_GAINS", "AICARDI_GAINS_BOX", "aicardi_law",
           "parking_reference", "reentry_second_bound", "stored", "compute_stored"]

STORED = SUITE / "reference"

#: S5: best J1 [m] of CMA-ES over the basic law's 8 gains (benchmarks/lunar_descent_search.py
#: --flights 8664 --seed 1; docs/systems/lunar_descent.md, "Against a generic policy search")
LUNAR_DESCENT_CMA_J1 = 0.017


# -- parking -----------------------------------------------------------------------------------
#: gains of the polar law [our choice]: gamma, k, h > 0 (any positive values converge)
AICARDI_GAINS = (3.0, 6.0, 1.0)
#: its gains for parking-box [our choice]: with the turn rate clipped to +-1 the gains above
#: saturate it and leave headings off by up to pi; the best of a grid over gamma in {0.2 .. 1},
#: k in {0.5 .. 3}, h in {0.5 .. 3} on the problem's starts parks all 12 to 3e-6 in 16 s
AICARDI_GAINS_BOX = (1.0, 3.0, 3.0)


def aicardi_law(gamma: float = AICARDI_GAINS[0], k: float = AICARDI_GAINS[1],
                h: float = AICARDI_GAINS[2]):
    """The law of Aicardi, Casalino, Bicchi & Balestrino (1995) on the plant's polar outputs
    (rho = distance, phi = direction to the target, alpha = phi - heading):

        v = gamma rho cos(alpha),  omega = k alpha + gamma cos(alpha) sin(alpha) (alpha + h phi) / alpha

    With V = (rho^2 + alpha^2 + h phi^2) / 2, dV/dt = -gamma cos^2(alpha) rho^2 - k alpha^2
    <= 0: rho, alpha, phi -> 0 from every start (the heading -> phi - alpha = 0)."""
    def law(y: dict) -> tuple:
        rho, a, phi = y["rho"], y["alpha"], y["phi"]
        sinc = math.sin(a) / a if abs(a) > 1e-12 else 1.0
        return (gamma * rho * math.cos(a),
                k * a + gamma * math.cos(a) * sinc * (a + h * phi))
    return law


def parking_reference(problem, fmu_dir=None, gains=AICARDI_GAINS) -> dict:
    """The polar law with ``gains`` flown through the problem's Unicycle FMU from every start:
    final distance and |heading| per start, their means, and the ``park`` objective (mean of
    their sum)."""
    plant, _ = problem.fmu_paths(fmu_dir or BUILD)
    law = aicardi_law(*gains)
    bounds = list(problem.basic().bounds)
    rows = []
    with PlantFlyer(plant) as fl:
        for s in problem.initial_states:
            out = fl.fly(s, law, ["v", "omega"], problem.wiring.step, problem.wiring.stop_time,
                         bounds)
            rows.append({"start": s, "distance": out["rho"], "heading": abs(out["theta"])})
    d = [r["distance"] for r in rows]
    a = [r["heading"] for r in rows]
    return {"per_start": rows, "mean_distance": float(np.mean(d)),
            "mean_heading": float(np.mean(a)), "park": float(np.mean(np.add(d, a))),
            "worst": float(max(np.add(d, a))), "gains": list(gains)}


# -- reentry-second --------------------------------------------------------------------------
def reentry_second_bound(miss_tol: float = 1000.0) -> dict:
    """S1's second scenario: the best program on the 1 s grid at zero miss and at miss <=
    ``miss_tol`` (SLSQP with exact sensitivities; ~1 min)."""
    from descent_fmus.models.reentry import SECOND_SCENARIO
    from descent_fmus.synthesis.systems.reentry.bound import reference_bounds
    zero, tol = reference_bounds(miss_tol, SECOND_SCENARIO)
    return {"zero_miss": zero.to_dict(), "miss_tol": miss_tol, "bound": tol.to_dict(),
            "J1": tol.J1}


# -- stored references ------------------------------------------------------------------------
def stored(name: str) -> dict:
    """A stored reference (``reference/<name>.json``)."""
    return json.loads((STORED / f"{name}.json").read_text())


def compute_stored(names=("cartpole", "reentry-second")) -> None:
    """Recompute the expensive references and store them."""
    from descent_fmus.synthesis.problems.files import load_problem_file
    STORED.mkdir(exist_ok=True)
    build_plants(names=("CartPole",))
    if "cartpole" in names:
        prob = load_problem_file(SUITE / "cartpole.toml")
        with PlantFlyer(BUILD / "CartPole.fmu") as fl:
            p = fl.defaults()
        lqr = cartpole_lqr(p, prob.wiring.step)
        progs = cartpole_programs(prob, p, lqr["K"])
        (STORED / "cartpole.json").write_text(json.dumps(
            {"lqr": lqr, "programs": progs, "step": prob.wiring.step,
             "stop_time": prob.wiring.stop_time}, indent=1))
    if "reentry-second" in names:
        (STORED / "reentry-second.json").write_text(json.dumps(reentry_second_bound(),
                                                               indent=1))


if __name__ == "__main__":
    compute_stored(tuple(sys.argv[1:]) or ("cartpole", "reentry-second"))
