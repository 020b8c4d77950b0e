"""S1 reentry: the objectives of a flight and of a law over several flights, with the penalties
of a flight that never reaches hf and the thresholds the targets and reports share.

* :func:`objectives` -- J1 (max load), J2 (miss at hf) of one flight from the plant's final
  outputs;
* :func:`nominal_objectives` -- (J1, J2) of the nominal flight (``reentry``, ``reentry-100m``);
* :func:`robust_objectives` -- worst J1 and mean J2 over :data:`ROBUST_CASES`
  (``reentry-robust``).

The set objectives of the sensed and guided problems: :mod:`.sample_set`.

References
----------
Diveev & Shmalko (reentry paper): criteria eqs. (7)-(8).
"""
from __future__ import annotations

import math

from descent_fmus.models.integrators import REACHED
from descent_fmus.models.reentry import ReentryParams

__all__ = ["objectives", "flight_objectives", "nominal_objectives", "robust_objectives",
           "NOT_LANDED_PENALTY", "DIVERGED_J1", "ON_TARGET", "TIGHT_MISS", "J1_LIMIT",
           "ROBUST_CASES"]

#: Miss assigned on top of the distance to go when a flight never reaches hf by t+ [m]: larger
#: than any miss of a flight that lands (half the Earth's circumference is 2.0e7 m), so a law
#: that does not land is never preferred to one that does.
NOT_LANDED_PENALTY = 2.0e7
#: J1 of a diverged integration (never a NaN in a result).
DIVERGED_J1 = 1.0e3
#: miss below which a law counts as landing on target [m]
ON_TARGET = 1000.0
#: miss of the "tight" laws the report also gives, against the zero-miss bound [m]
TIGHT_MISS = 100.0
#: Median-J1 limit of the single-objective target (CMA-ES) [choice]: the issue's target.
J1_LIMIT = 9.0


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
