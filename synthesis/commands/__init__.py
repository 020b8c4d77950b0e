"""Sub-commands of ``descent-fmus`` (one module per system) and their shared helpers."""
from __future__ import annotations

import json

__all__ = ["CliError", "emit"]


class CliError(Exception):
    """A user error: printed as one line, exit code 2, no traceback."""


def emit(args, summary: dict, text: str) -> None:
    """Print ``summary`` as JSON if ``--json`` was given, else the human-readable ``text``."""
    if getattr(args, "json", False):
        print(json.dumps(summary, indent=2, default=float))
    else:
        print(text)
