"""S1's native (C) code: what the reentry system builds natively, beside its Python.

* :mod:`.exports` -- S1's model functions exported with stable C names (the plant's C library
  for an on-board predictor);
* :mod:`.sensing` -- the drag-factor estimator traced to C;
* :mod:`.guidance` -- the on-board predictions of the guidance controllers traced to C;
* :mod:`.onboard_lp` -- the re-planner's C linear-programme solver, callable from Python;
* :mod:`.controllers` -- the twins of S1's sensed, guided and NPC controllers;
* ``c/`` -- S1's hand-written C (the controllers' models, the estimator, the guidance cycle,
  the re-planner and its simplex method).

:func:`native_plants` and :func:`native_controllers` are what S1's ``System`` record names
(nothing is imported until they are called).
"""
from __future__ import annotations

__all__ = ["native_plants", "native_controllers"]


def native_plants() -> dict:
    """S1's native plant: the Reentry plant, with its exported model functions."""
    from descent_fmus.synthesis.fmi.native.builders.plant_fmu import PlantSpec
    from descent_fmus.synthesis.systems.reentry.native.exports import REENTRY_EXPORTS
    return {"Reentry": PlantSpec("reentry:Reentry", "reentry", exports=REENTRY_EXPORTS)}


def native_controllers() -> dict:
    """The native twins S1 flies: the two generic controllers and its own four."""
    from descent_fmus.synthesis.fmi.native.builders.controllers import GENERIC_TWINS
    from descent_fmus.synthesis.systems.reentry.native.controllers import NATIVE_TWINS
    return {**GENERIC_TWINS, **NATIVE_TWINS}
