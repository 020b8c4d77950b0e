"""Where the built FMUs are: one definition for the whole package.

``fmu_dir()`` is ``$DESCENT_FMUS_DIR`` if set, else ``fmus/`` of the checkout the package runs
from (``python build_fmus.py`` writes there), else ``./fmus``.
"""
from __future__ import annotations

import os
from pathlib import Path

__all__ = ["fmu_dir", "require_fmu", "FMUNotFoundError", "CHECKOUT", "cache_dir"]

#: The repository root when the package runs from a checkout (editable install), else None.
CHECKOUT = Path(__file__).resolve().parent.parent
if not (CHECKOUT / "build_fmus.py").is_file():
    CHECKOUT = None


class FMUNotFoundError(FileNotFoundError):
    """An FMU file the co-simulation needs does not exist (run ``python build_fmus.py``)."""


def fmu_dir() -> Path:
    """The folder of the built FMUs (see the module docstring)."""
    env = os.environ.get("DESCENT_FMUS_DIR")
    if env:
        return Path(env)
    if CHECKOUT is not None:
        return CHECKOUT / "fmus"
    return Path("fmus")


def cache_dir() -> Path:
    """Where references computed once are kept for every later run (by the content they depend
    on): ``$DESCENT_FMUS_CACHE`` if set, else ``$XDG_CACHE_HOME/descent-fmus``, else
    ``~/.cache/descent-fmus``."""
    env = os.environ.get("DESCENT_FMUS_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "descent-fmus"


def require_fmu(path) -> Path:
    """``path`` as a Path, or :class:`FMUNotFoundError` with what to do if it is missing."""
    path = Path(path)
    if not path.is_file():
        raise FMUNotFoundError(f"FMU not found: {path} -- build the FMUs first with "
                               f"'python build_fmus.py' (or point --fmus / DESCENT_FMUS_DIR at "
                               f"the folder that holds them)")
    return path
