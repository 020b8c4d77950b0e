"""S2 Mars capsule: wiring of the MarsCapsule plants with the MarsBellmanController law.

* :data:`WIRING` -- the averaged plant under the law (the ``MarsClosedLoop`` FMU);
* :data:`WIRING_6DOF` -- the rigid-body plant, the law fed its omega_1 precession mode;
* :data:`WIRING_6DOF_INSTANT` -- the rigid-body plant, the law fed its instantaneous angles.

Every flight ends when the plant's ``status`` becomes non-zero (h = h_end reached) or at
:data:`~descent_fmus.models.mars.T_MAX`; the communication step is
:data:`~descent_fmus.models.mars.STEP` (its accuracy: models/README.md).
"""
from __future__ import annotations

from dataclasses import asdict

from descent_fmus.models.controllers.mars_bellman import MarsBellmanParams
from descent_fmus.models.mars import STEP, T_MAX
from descent_fmus.synthesis.fmi.closed_loop import STATUS_STOP, Wiring

__all__ = ["WIRING", "WIRING_6DOF", "WIRING_6DOF_INSTANT", "LOOP_PARAMETERS",
           "controller_defaults"]

_TO_CONTROLLER = (("alpha", "alpha"), ("theta", "theta"), ("omega", "omega"),
                  ("omega_dot", "omega_dot"), ("omega_a", "omega_a"))

WIRING = Wiring(
    name="MarsClosedLoop",
    plant="MarsCapsule",
    controller="MarsBellmanController",
    to_controller=_TO_CONTROLLER,
    to_plant=(("u", "u"),),
    step=STEP,
    stop_time=T_MAX,
    stop=STATUS_STOP,
    exposed=(("alpha", "plant", "alpha"), ("theta", "plant", "theta"), ("q", "plant", "q"),
             ("omega", "plant", "omega"), ("omega_dot", "plant", "omega_dot"),
             ("h", "plant", "h"), ("V", "plant", "V"), ("u", "controller", "u"),
             ("A", "controller", "A"), ("status", "plant", "status"),
             ("t_end", "plant", "t_end")),
    description="S2 Mars capsule (averaged angle-of-attack equations) under the Bellman/"
                "averaging law u = A alpha cos(theta+theta1)/(2 c omega_a) of Lyubimov & Kurkina",
)

#: Parameters the ``MarsClosedLoop`` FMU exposes.
LOOP_PARAMETERS = (("alpha0", "plant", "alpha0"), ("omega_x", "plant", "omega_x"),
                   ("theta1", "plant", "theta1"), ("eps", "plant", "eps"),
                   ("V0", "plant", "V0"), ("h_end", "plant", "h_end"),
                   ("b", "controller", "b"), ("c", "controller", "c"),
                   ("u_max", "controller", "u_max"), ("formula", "controller", "formula"),
                   ("theta1_law", "controller", "theta1"))

#: The rigid-body plant with the controller fed the amplitude and phase of the omega_1
#: precession mode (what the averaged model describes).
WIRING_6DOF = Wiring(
    name="Mars6DOFClosedLoop", plant="MarsCapsule6DOF", controller="MarsBellmanController",
    to_controller=(("alpha_m1", "alpha"), ("theta_m1", "theta")) + _TO_CONTROLLER[2:],
    to_plant=(("u", "u"),), step=STEP, stop_time=T_MAX, stop=STATUS_STOP)

#: The rigid-body plant with the controller fed the instantaneous spatial angle of attack and
#: aerodynamic roll phase: breaks down once the omega_1 mode is smaller than the omega_2 mode.
WIRING_6DOF_INSTANT = Wiring(
    name="Mars6DOFInstantClosedLoop", plant="MarsCapsule6DOF",
    controller="MarsBellmanController", to_controller=_TO_CONTROLLER, to_plant=(("u", "u"),),
    step=STEP, stop_time=T_MAX, stop=STATUS_STOP)


def controller_defaults() -> dict:
    """Start values the controller FMU of ``MarsClosedLoop`` carries: the law's defaults."""
    return asdict(MarsBellmanParams())
