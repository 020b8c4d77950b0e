"""Synthesis problems from a TOML file, for any FMI 2.0 co-simulation plant FMU (in progress)."""
from __future__ import annotations

__all__ = ["ProblemFileError", "load_problem_file"]


class ProblemFileError(ValueError):
    """A problem file is malformed; the message names the file, the key and the problem."""


def load_problem_file(path, fmu_dir=None):
    raise ProblemFileError(f"{path}: problem files are not supported yet")
