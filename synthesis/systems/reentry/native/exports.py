"""S1's model functions exported with stable C names: the Reentry plant's C library for C code
of its own (an on-board predictor: right-hand side, event, range, loads).

Each entry is ``name -> ("module:qualname", {argument: 1 | n values | a Params class's
name})`` (:mod:`synthesis.fmi.native.tracer.plant_library` renders them beside the plant).
"""
from __future__ import annotations

__all__ = ["REENTRY_EXPORTS"]

#: S1's model functions for C code of its own (an on-board predictor: rhs, event, range)
REENTRY_EXPORTS = {
    "rhs": ("reentry:rhs", {"x": 4, "u": 1, "gm": 1, "kd": 1, "lam": 1, "rz": 1}),
    "altitude": ("reentry:altitude", {"x": 4, "rz": 1}),
    "downrange": ("reentry:downrange", {"x": 4, "rz": 1}),
    "deviations": ("reentry:deviations", {"x": 4, "p": "ReentryParams"}),
    "loads": ("reentry:loads", {"x": 4, "dx": 4, "kd": 1, "lam": 1, "rz": 1, "g0": 1, "u": 1}),
    "initial_state": ("reentry:initial_state", {"p": "ReentryParams"}),
    "constants": ("reentry:ReentryParams.constants", {"self": "ReentryParams"}),
}
