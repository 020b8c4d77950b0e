"""The documented maxima of what a problem may ask for, so that no input makes a run grow
without limit: initial states, communication steps per flight, the size of a problem file and
of its lists.  (The recipe's maxima live with their settings dataclasses; the workers' and the
memory check with the run: :mod:`synthesis.run.resources`.)"""
from __future__ import annotations

import math

__all__ = ["ResourceLimitError", "MAX_STATES", "MAX_STEPS", "MAX_FILE_BYTES",
           "MAX_OBJECTIVES", "MAX_CONSTRAINTS", "MAX_BASELINES", "check_steps"]


class ResourceLimitError(ValueError):
    """An input exceeds a documented maximum or the machine's available memory."""


#: Most initial states of a problem (every law flies each): listed, sampled, or box corners.
MAX_STATES = 100_000
#: Most communication steps of one flight (stop time / step).
MAX_STEPS = 10_000_000
#: Largest problem file [bytes] (many initial states are given as a box and a sampler).
MAX_FILE_BYTES = 1_048_576
#: Most objectives, constraints and baseline structures of a problem file.
MAX_OBJECTIVES, MAX_CONSTRAINTS, MAX_BASELINES = 16, 64, 16


def check_steps(stop_time: float, step: float, what: str) -> int:
    """The communication steps of one flight; ResourceLimitError beyond :data:`MAX_STEPS`."""
    n = math.ceil(stop_time / step - 1e-9)
    if n > MAX_STEPS:
        raise ResourceLimitError(f"{what}: {n} communication steps per flight; the documented "
                                 f"maximum is {MAX_STEPS}")
    return n
