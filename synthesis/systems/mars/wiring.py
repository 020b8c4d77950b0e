"""S2 Mars capsule: wiring of the MarsCapsule plants with the MarsBellmanController law."""
from __future__ import annotations

from descent_fmus.synthesis.cosim import Wiring
from descent_fmus.synthesis.scenarios import ClosedLoopSpec, register

#: Communication step [s]: over one step the held control sees the phase theta advance by
#: theta_dot * STEP <= 0.1 rad (theta_dot <= 1.95 rad/s).  Halving it changes alpha(150 s) by
#: 0.3 % and alpha_end by 0.9 %; doubling it (0.1 s) by 1.5 % and 4.6 % (models/README.md,
#: tests/test_mars.py).
STEP = 0.05
#: Time limit [s]; the default descent reaches h_end = 10 km at t = 660.5 s.
STOP_TIME = 1500.0

_TO_CONTROLLER = (("alpha", "alpha"), ("theta", "theta"), ("omega", "omega"),
                  ("omega_dot", "omega_dot"), ("omega_a", "omega_a"))

WIRING = Wiring(
    name="MarsClosedLoop",
    plant="MarsCapsule",
    controller="MarsBellmanController",
    to_controller=_TO_CONTROLLER,
    to_plant=(("u", "u"),),
    step=STEP,
    stop_time=STOP_TIME,
    stop_flag="done",
    exposed=(("alpha", "plant", "alpha"), ("theta", "plant", "theta"), ("q", "plant", "q"),
             ("omega", "plant", "omega"), ("omega_dot", "plant", "omega_dot"),
             ("h", "plant", "h"), ("V", "plant", "V"), ("u", "controller", "u"),
             ("A", "controller", "A"), ("done", "plant", "done"), ("t_end", "plant", "t_end")),
    description="S2 Mars capsule (averaged angle-of-attack equations) under the Bellman/"
                "averaging law u = A alpha cos(theta+theta1)/(2 c omega_a) of seed 001",
)

#: The rigid-body plant with the controller fed the amplitude and phase of the omega_1
#: precession mode (what the averaged model describes).
WIRING_6DOF = Wiring(
    name="Mars6DOFClosedLoop", plant="MarsCapsule6DOF", controller="MarsBellmanController",
    to_controller=(("alpha_m1", "alpha"), ("theta_m1", "theta")) + _TO_CONTROLLER[2:],
    to_plant=(("u", "u"),), step=STEP, stop_time=STOP_TIME, stop_flag="done")

#: The rigid-body plant with the controller fed the instantaneous spatial angle of attack and
#: aerodynamic roll phase: breaks down once the omega_1 mode is smaller than the omega_2 mode.
WIRING_6DOF_INSTANT = Wiring(
    name="Mars6DOFInstantClosedLoop", plant="MarsCapsule6DOF",
    controller="MarsBellmanController", to_controller=_TO_CONTROLLER, to_plant=(("u", "u"),),
    step=STEP, stop_time=STOP_TIME, stop_flag="done")


def _controller_defaults() -> dict:
    from descent_fmus.models.controllers.mars_bellman import B, C, CONSISTENT, THETA1, U_MAX
    return {"b": B, "c": C, "theta1": THETA1, "u_max": U_MAX, "formula": CONSISTENT}


register(
    slaves=["models/mars_capsule.py", "models/mars_capsule_6dof.py",
            "models/controllers/mars_bellman.py"],
    closed_loops=[ClosedLoopSpec(
        WIRING,
        controller_defaults=_controller_defaults(),
        parameters=(("alpha0", "plant", "alpha0"), ("omega_x", "plant", "omega_x"),
                    ("theta1", "plant", "theta1"), ("eps", "plant", "eps"),
                    ("V0", "plant", "V0"), ("h_end", "plant", "h_end"),
                    ("b", "controller", "b"), ("c", "controller", "c"),
                    ("u_max", "controller", "u_max"), ("formula", "controller", "formula"),
                    ("theta1_law", "controller", "theta1")))],
)
