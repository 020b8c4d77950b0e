"""S1 reentry: the nominal closed loop -- the Reentry plant under the generic
NetworkOperatorController (y1, y2 -> u), and the plant's start values.

References
----------
Diveev & Shmalko (reentry paper): the basic law eqs. (24)-(25) (the loop's default law).
"""
from __future__ import annotations

from dataclasses import asdict

from descent_fmus.models.reentry import T_PLUS, ReentryParams
from descent_fmus.synthesis.fmi.closed_loop import STATUS_STOP, Wiring

__all__ = ["WIRING", "STEP", "LOOP_PARAMETERS", "plant_values"]

#: Communication step of the reentry closed loop [s] (halving it changes J1 by < 0.5 %:
#: tests/fmi/test_cosim.py).
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


def plant_values(params: ReentryParams) -> dict:
    """Start values of the Reentry FMU for a :class:`models.reentry.ReentryParams`."""
    return asdict(params)
