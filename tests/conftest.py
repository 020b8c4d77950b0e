"""Shared fixtures: the built FMUs.

``fmu_dir`` is ``$DESCENT_FMUS_DIR`` if set, else ``fmus/`` of the checkout; the FMUs are built
there once per session if any registered one is missing (CI builds them before pytest).
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _expected_fmus():
    from synthesis import scenarios
    scenarios.load_all()
    return [f"{name}.fmu" for name in scenarios.CLOSED_LOOPS]


@pytest.fixture(scope="session")
def fmu_dir() -> Path:
    d = Path(os.environ.get("DESCENT_FMUS_DIR", ROOT / "fmus"))
    if not all((d / f).is_file() for f in _expected_fmus()):
        subprocess.run([sys.executable, str(ROOT / "build_fmus.py"), "--out", str(d)], check=True)
    return d


@pytest.fixture(scope="session")
def open_loop_program():
    """The best open-loop S1 program, N = 120 (synthesis.open_loop; ~20 s, computed once)."""
    from synthesis.open_loop import optimize_open_loop
    return optimize_open_loop(segments=120)
