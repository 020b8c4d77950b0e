"""S1's controllers as native FMUs: twins of the sensed, guided and NPC pythonfmu controllers.

The twins are built by the generic twin builder
(:func:`synthesis.fmi.native.builders.controllers.build_twin`: the variables read from the
Python class) from S1's hand-written C models (``c/``: the drag-factor estimator's model, the
sensed and guided network-operator controllers, the NPC; the guidance cycle, the re-planner and
its linear programmes) and the C traced from S1's Python (:mod:`.sensing`: the estimator,
:mod:`.guidance`: the on-board predictions).  :data:`NATIVE_TWINS` names them by model
identifier (S1's ``System`` record lists them with the generic twins it flies).
"""
from __future__ import annotations

from pathlib import Path

from descent_fmus.synthesis.fmi.native.builders.ccode import interpreter_operations_h
from descent_fmus.synthesis.fmi.native.builders.controllers import (NO_FILES, NO_NAMES,
                                                                    build_twin, layout_config,
                                                                    no_capacity)

__all__ = ["C_DIR", "SENSING_FILES", "SENSED_FILES", "GUIDANCE_FILES", "REPLAN_FILES",
           "build_drag_estimator", "build_sensed_controller", "build_guided_controller",
           "build_npc_controller", "NATIVE_TWINS"]

#: S1's hand-written C files (package data).
C_DIR = Path(__file__).resolve().parent / "c"
#: Hand-written C files every twin that carries S1's drag-factor estimator ships (its C
#: generated, :mod:`.sensing`)
SENSING_FILES = (C_DIR / "estimator.h", "py_random.h", "plant_runtime.c", "plant_runtime.h")
#: ... and every twin of a law reading the estimate (the sensed and the guided controller)
SENSED_FILES = NO_FILES + SENSING_FILES + (C_DIR / "sensed_controller.h",)
#: ... and every twin of S1's guidance (the cycle and the root search)
GUIDANCE_FILES = (C_DIR / "guidance_cycle.h", "brent.h")
#: ... and the guided law's re-planner (its loop and its linear programmes)
REPLAN_FILES = (C_DIR / "replan.h", C_DIR / "lp.h")


def _sensing_config(prefix: str, names: dict, constants: dict | None = None):
    """``model_config(variables)`` of a twin carrying the estimator: the value references the
    C reads and the generated functions' names (``SENSING_*``)."""
    def config(variables) -> str:
        text = layout_config(variables, {
            "VR_SAMPLE": "sample_period", "VR_NOISE": "noise", "VR_NAV": "nav_x1",
            "VR_Y3": "drag_factor_log", "VR_FACTOR": "drag_factor", "IX_SEED": "noise_seed",
            **names}, constants)
        return (text + f'#include "{prefix}_sensing.h"\n'
                f"#define SENSING_N_ST {prefix.upper()}_N_ST\n"
                + "".join(f"#define SENSING_{f.upper()} {prefix}_{f}\n"
                          for f in ("check", "nominal", "draw", "estimate", "commit")))
    return config


def build_drag_estimator(dest, compiler: str | None = None,
                         defaults: dict | None = None) -> Path:
    """The native ``DragEstimator`` (``c/drag_model.c``; the estimator's C generated from the
    Python estimator, :mod:`.sensing`)."""
    from descent_fmus.models.controllers.drag_estimator import DragEstimator
    from descent_fmus.synthesis.systems.reentry.native.sensing import sensing_sources
    return build_twin(DragEstimator, dest, C_DIR / "drag_model.c",
                      _sensing_config("drag", {"VR_UIN": "u"}), SENSING_FILES,
                      sensing_sources(DragEstimator, "drag"), compiler, defaults)


def build_sensed_controller(dest, compiler: str | None = None,
                            defaults: dict | None = None) -> Path:
    """The native ``SensedNetworkOperatorController``: the generic controller's interpreter and
    the estimator (``c/sensed_model.c``)."""
    from descent_fmus.models.controllers.drag_estimator import SensedNetworkOperatorController
    from descent_fmus.synthesis.systems.reentry.native.sensing import sensing_sources
    cls = SensedNetworkOperatorController
    names = dict(NO_NAMES, IX_ESTIMATE="estimate_input")
    constants = no_capacity()
    generated = dict(sensing_sources(cls, "sensed"),
                     **{"no_operations.h": interpreter_operations_h()})
    return build_twin(cls, dest, C_DIR / "sensed_model.c",
                      _sensing_config("sensed", names, constants),
                      SENSED_FILES, generated, compiler, defaults)


def build_guided_controller(dest, compiler: str | None = None,
                            defaults: dict | None = None) -> Path:
    """The native ``GuidedNetworkOperatorController``: the correction c one number per cycle,
    or (``replan = 1``) the plan over altitude re-solved every cycle (``c/guided_model.c``,
    ``c/replan.h``, ``c/lp.h``; the estimator's and the prediction's C generated from the
    Python, :mod:`.sensing`, :mod:`.guidance`)."""
    from descent_fmus.models.controllers.reentry_npc import GuidedNetworkOperatorController
    from descent_fmus.synthesis.systems.reentry.native.guidance import (guidance_constants,
                                                                       trace_guidance)
    from descent_fmus.synthesis.systems.reentry.native.sensing import sensing_sources
    cls = GuidedNetworkOperatorController
    names = dict(NO_NAMES, IX_ESTIMATE="estimate_input", IX_CORRECTION="correction_input",
                 VR_GAIN="correction_gain", VR_GATE="correction_gate", VR_CMAX="correction_max",
                 VR_TOL="tol", VR_DTPRED="dt_pred", VR_CYCLE="cycle", VR_CORR="correction",
                 VR_MISS="predicted_miss", VR_SHE="scale_height_error",
                 VR_FACTOR_SD="drag_factor_sd", IX_REPLAN="replan", IX_MAXITER="max_iter",
                 IX_NPRED="predictions", IX_RITER="replan_iterations",
                 VR_TRUST="replan_trust", VR_EFFORT="replan_effort")
    constants = dict(no_capacity(), SENSING_PROFILE="guided_profile",
                     **guidance_constants("guided"))
    generated = dict(sensing_sources(cls, "guided", [trace_guidance]),
                     **{"no_operations.h": interpreter_operations_h()})
    return build_twin(cls, dest, C_DIR / "guided_model.c",
                      _sensing_config("guided", names, constants),
                      SENSED_FILES + GUIDANCE_FILES + REPLAN_FILES, generated, compiler,
                      defaults)


def build_npc_controller(dest, compiler: str | None = None,
                         defaults: dict | None = None) -> Path:
    """The native ``ReentryNPC`` (``c/npc_model.c``; the estimator's and the prediction's C
    generated from the Python, :mod:`.sensing`, :mod:`.guidance`)."""
    from descent_fmus.models.controllers.reentry_npc import ReentryNPC
    from descent_fmus.synthesis.systems.reentry.native.guidance import (guidance_constants,
                                                                       trace_npc)
    from descent_fmus.synthesis.systems.reentry.native.sensing import sensing_sources
    names = {"VR_TOL": "tol", "VR_DTPRED": "dt_pred", "VR_CYCLE": "cycle", "VR_UOUT": "u",
             "VR_MISS": "predicted_miss", "VR_SHE": "scale_height_error",
             "VR_FACTOR_SD": "drag_factor_sd", "IX_MAXITER": "max_iter",
             "IX_NPRED": "predictions"}
    constants = dict(SENSING_PROFILE="npc_profile", **guidance_constants("npc"))
    return build_twin(ReentryNPC, dest, C_DIR / "npc_model.c",
                      _sensing_config("npc", names, constants), SENSING_FILES + GUIDANCE_FILES,
                      sensing_sources(ReentryNPC, "npc", [trace_npc]), compiler, defaults)


#: S1's own native twins by model identifier.
NATIVE_TWINS = {"DragEstimator": build_drag_estimator,
                "SensedNetworkOperatorController": build_sensed_controller,
                "GuidedNetworkOperatorController": build_guided_controller,
                "ReentryNPC": build_npc_controller}
