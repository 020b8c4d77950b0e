"""S1 reentry: wiring of the Reentry plant with the network-operator controller."""
from __future__ import annotations

from synthesis.cosim import Wiring
from synthesis.scenarios import ClosedLoopSpec, register

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
    stop_time=300.0,
    stop_flag="landed",
    exposed=(("h", "plant", "h"), ("L", "plant", "L"), ("load", "plant", "load"),
             ("aero_load", "plant", "aero_load"), ("load_max", "plant", "load_max"),
             ("y1", "plant", "y1"), ("y2", "plant", "y2"), ("u", "controller", "u[1]"),
             ("landed", "plant", "landed"), ("t_land", "plant", "t_land")),
    description="S1 Earth reentry (Reentry plant) under a network-operator law "
                "(default: the paper's basic law q1 = 2.259375, q2 = 1.953125)",
)

register(
    slaves=["models/reentry.py", "models/controllers/network_operator.py"],
    closed_loops=[ClosedLoopSpec(
        WIRING,
        parameters=(("V0", "plant", "V0"), ("h0", "plant", "h0"), ("beta0", "plant", "beta0"),
                    ("m", "plant", "m"), ("rho0", "plant", "rho0"),
                    ("q[1]", "controller", "q[1]"), ("q[2]", "controller", "q[2]")))],
)

#: Miss assigned on top of the distance to go when a flight never reaches hf by t+ [m]: larger
#: than any miss of a flight that lands (half the Earth's circumference is 2.0e7 m), so a law
#: that does not land is never preferred to one that does (SPEC S1).
NOT_LANDED_PENALTY = 2.0e7
#: J1 of a diverged integration (never a NaN in a result).
DIVERGED_J1 = 1.0e3


def plant_values(params) -> dict:
    """Start values of the Reentry FMU for a :class:`models.reentry.ReentryParams`."""
    from dataclasses import asdict
    return asdict(params)


def objectives(final: dict, params) -> dict:
    """J1, J2 and reporting values from the plant's final outputs (``ClosedLoopResult.final``).

    J1 = max load (the paper's eq. 7, running max over all integration sub-steps);
    J2 = |L(tf) - Lf| if the flight reached hf, else the penalty ``NOT_LANDED_PENALTY`` plus the
    remaining range and altitude to go; a diverged run gets J1 = DIVERGED_J1 as well.
    """
    import math
    landed = final.get("t_land", -1.0) >= 0.0
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
            "t_land": final["t_land"], "L_final": L, "h_final": h, "diverged": False}
