"""S1 reentry: the guidance closed loops and the laws their FMUs carry.

* :data:`SENSED_WIRING` -- the Reentry plant with the ``SensedNetworkOperatorController`` (a
  network-operator law reading the drag-factor estimate y3 that the controller FMU computes from
  the sensed drag ``aero_load`` and the navigated state ``x1..x4``): u = phi(y1, y2, y3, q);
* :data:`NPC_WIRING` -- the Reentry plant with the ``ReentryNPC`` predictor-corrector guidance;
* :data:`GUIDED_WIRING` -- the Reentry plant with the ``GuidedNetworkOperatorController``: a law
  of y1, y2, y3 plus the on-board correction c;
* :func:`reads_estimate`, :func:`reads_correction` -- which of these wirings a law flies on;
* the committed laws (:data:`DEFAULT_LAW_FILE`, :data:`GUIDED_LAW_FILE`,
  :data:`NOMINAL_LAW_FILE`) and their loaders, read on demand only (the built closed-loop FMUs'
  defaults, the guided problem's basic solution).
"""
from __future__ import annotations

from pathlib import Path

from descent_fmus.models.reentry import T_PLUS
from descent_fmus.synthesis.fmi.closed_loop import STATUS_STOP, Wiring
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.systems.reentry.laws import as_guided, sensed_basic_law
from descent_fmus.synthesis.systems.reentry.wiring import STEP

__all__ = ["SENSED_WIRING", "NPC_WIRING", "GUIDED_WIRING", "SENSED_LOOP_PARAMETERS",
           "NPC_LOOP_PARAMETERS", "GUIDED_LOOP_PARAMETERS", "reads_estimate", "reads_correction",
           "DEFAULT_LAW_FILE", "GUIDED_LAW_FILE", "NOMINAL_LAW_FILE", "default_law",
           "default_law_values", "guided_basic_law", "default_guided_law",
           "default_guided_law_values"]

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
    step=STEP,
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
    step=STEP,
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
    step=STEP,
    stop_time=T_PLUS,
    stop=STATUS_STOP,
    exposed=_EXPOSED + (("u", "controller", "u[1]"), ("correction", "controller", "correction"),
                        ("predicted_miss", "controller", "predicted_miss")),
    description="S1 Earth reentry (Reentry plant) under a network-operator law reading the "
                "drag-factor estimate y3 and the on-board correction c (a predictor-corrector "
                "that predicts with the law itself): u = phi(y1, y2, y3, c, q)",
)

#: Parameters the closed-loop FMUs expose: the dispersed plant parameters and the sensing.
_PLANT_PARAMETERS = tuple((n, "plant", n) for n in ("V0", "h0", "beta0", "m", "rho0", "lam"))
_SENSING = tuple((n, "controller", n) for n in ("threshold", "noise", "bias", "noise_seed"))
SENSED_LOOP_PARAMETERS = _PLANT_PARAMETERS + _SENSING
_PROFILE = tuple((n, "controller", n) for n in ("accel_sigma", "scale_prior", "bias_prior"))
NPC_LOOP_PARAMETERS = _PLANT_PARAMETERS + _SENSING + _PROFILE + (("cycle", "controller",
                                                                   "cycle"),)
GUIDED_LOOP_PARAMETERS = NPC_LOOP_PARAMETERS + tuple(
    (n, "controller", n) for n in ("h0_line", "correction_gate", "replan", "replan_iterations",
                                   "replan_trust", "replan_effort"))


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
