"""Helpers of the tests that run the command line and watch its processes (Linux: they read
the process table from ``/proc``)."""
from __future__ import annotations

import sys
import time
from pathlib import Path


def cli(*args) -> list:
    """The ``descent-fmus`` command line with ``args`` (this interpreter, the installed package)."""
    return [sys.executable, "-m", "descent_fmus.synthesis.cli.main", *map(str, args)]


def group(pgid: int) -> list:
    """Live (non-zombie) processes of process group ``pgid``."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        fields = text[text.rindex(")") + 2:].split()     # after "pid (comm) "
        if int(fields[2]) == pgid and fields[0] != "Z":
            out.append(int(stat.parent.name))
    return out


def wait_empty(pgid: int, seconds: float = 10.0) -> list:
    """The processes of group ``pgid`` still alive after at most ``seconds`` (``[]``: none)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        left = group(pgid)
        if not left:
            return []
        time.sleep(0.02)
    return group(pgid)
