"""Helpers every ``descent-fmus`` command uses: user errors, ``--json``, common options.

Kept apart from :mod:`synthesis.cli.main` (the entry point) so that the systems' command modules
import it without importing the entry point (no import cycle).
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

__all__ = ["CliError", "emit", "json_safe", "OneLineParser", "add_common_options", "add_parameter_options",
           "parameter_overrides", "positive_int", "nonnegative_int", "int_at_least", "finite_float",
           "positive_float"]


class CliError(Exception):
    """A user error: printed as one line, exit code 2, no traceback."""


def emit(args, summary: dict, text: str) -> None:
    """Print ``summary`` as JSON if ``--json`` was given, else the human-readable ``text``.

    Non-finite numbers become ``null`` (JSON has no NaN), other objects their ``float`` or
    ``str``.
    """
    if getattr(args, "json", False):
        print(json.dumps(json_safe(summary), indent=2, allow_nan=False))
    else:
        print(text)


def json_safe(v):
    """``v`` with NaN/inf as None, tuples as lists, numpy scalars as Python numbers."""
    if isinstance(v, dict):
        return {str(k): json_safe(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [json_safe(x) for x in v]
    if isinstance(v, (bool, int, str)) or v is None:
        return v
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    if hasattr(v, "dtype") and getattr(v.dtype, "kind", "") in "iub":
        return int(v) if v.dtype.kind != "b" else bool(v)
    return f if math.isfinite(f) else None


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (``prog: error: ...``), exit 2."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


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
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return v


def positive_float(text: str) -> float:
    v = finite_float(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return v


def int_at_least(lo: int, hi: int | None = None):
    """An argparse type: an integer >= ``lo`` (and <= ``hi``, a documented maximum)."""
    def convert(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"must be >= {lo}, got {v}")
        if hi is not None and v > hi:
            raise argparse.ArgumentTypeError(f"must be <= {hi} (the documented maximum), "
                                             f"got {v}")
        return v
    convert.__name__ = f"integer >= {lo}" if hi is None else f"integer in {lo}..{hi}"
    return convert


positive_int = int_at_least(1)
nonnegative_int = int_at_least(0)
