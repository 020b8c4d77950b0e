"""Helpers every ``descent-fmus`` command uses: user errors, ``--json``, common options.

Kept apart from :mod:`synthesis.cli` (the entry point) so that the systems' command modules
import it without importing the entry point (no import cycle).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

__all__ = ["CliError", "emit", "add_common_options", "add_parameter_options",
           "parameter_overrides", "positive_int", "nonnegative_int", "finite_float",
           "positive_float"]


class CliError(Exception):
    """A user error: printed as one line, exit code 2, no traceback."""


def emit(args, summary: dict, text: str) -> None:
    """Print ``summary`` as JSON if ``--json`` was given, else the human-readable ``text``."""
    if getattr(args, "json", False):
        print(json.dumps(summary, indent=2, default=_json_default, allow_nan=False))
    else:
        print(text)


def _json_default(v):
    try:
        v = float(v)
    except (TypeError, ValueError):
        return str(v)
    return v if math.isfinite(v) else None


def add_common_options(p, fmus: bool = True, plot: str | None = None) -> None:
    """``--json``, ``--fmus DIR`` (default: the package's FMU folder) and ``--plot FILE``."""
    if fmus:
        p.add_argument("--fmus", type=Path, default=None, metavar="DIR",
                       help="folder of the built FMUs (default: fmus/ of the checkout, or "
                            "$DESCENT_FMUS_DIR)")
    if plot:
        p.add_argument("--plot", type=Path, default=None, metavar="FILE.png", help=plot)
    p.add_argument("--json", action="store_true", help="print a JSON summary")


def fmu_folder(args) -> Path:
    """The ``--fmus`` folder, or the default one."""
    from descent_fmus.synthesis.paths import fmu_dir
    return args.fmus if getattr(args, "fmus", None) is not None else fmu_dir()


def add_parameter_options(p, params_class, names, dest_prefix: str = "") -> None:
    """``--NAME`` options for fields of a parameter dataclass, help and default from it.

    The default shown is the dataclass's; the option's own default is None (= not given), so
    :func:`parameter_overrides` returns only what the user set.
    """
    from descent_fmus.models.params import description_of
    defaults = params_class()
    for name in names:
        p.add_argument(f"--{name.replace('_', '-')}", dest=dest_prefix + name, type=finite_float,
                       default=None, metavar="X",
                       help=f"{description_of(params_class, name)} "
                            f"(default {getattr(defaults, name):g})")


def parameter_overrides(args, names, dest_prefix: str = "") -> dict:
    """``{name: value}`` of the parameter options the user gave."""
    return {n: getattr(args, dest_prefix + n) for n in names
            if getattr(args, dest_prefix + n, None) is not None}


def finite_float(text: str) -> float:
    import argparse
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return v


def positive_float(text: str) -> float:
    import argparse
    v = finite_float(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return v


def positive_int(text: str) -> int:
    import argparse
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {v}")
    return v


def nonnegative_int(text: str) -> int:
    import argparse
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {v}")
    return v
