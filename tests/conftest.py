"""Shared fixtures: the built FMUs, the tutorial's hopper plant.

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
    from descent_fmus.synthesis.registry import closed_loop_specs, fmu_classes
    return ([f"{c.split(':')[1]}.fmu" for c in fmu_classes()]
            + [f"{s.wiring.name}.fmu" for s in closed_loop_specs()])


@pytest.fixture(scope="session")
def fmu_dir() -> Path:
    d = Path(os.environ.get("DESCENT_FMUS_DIR", ROOT / "fmus"))
    if os.environ.get("DESCENT_FMUS_NO_AUTOBUILD"):      # the caller built what it needs
        return d
    if not all((d / f).is_file() for f in _expected_fmus()):
        subprocess.run([sys.executable, str(ROOT / "build_fmus.py"), "--out", str(d)], check=True)
    return d


@pytest.fixture(scope="session")
def hopper_dir(tmp_path_factory) -> Path:
    """The tutorial's plant (``docs/tutorials/hopper.py``) built as the tutorial builds it
    (``descent-fmus build-plant``: ``Hopper.fmu`` and its native twin ``native/Hopper.fmu``),
    beside a copy of its problem file ``hopper.toml`` -- once per session (tests write their
    variants elsewhere or under other names; a copy of ``Hopper.fmu`` alone flies pythonfmu)."""
    import shutil
    tutorial = ROOT / "docs" / "tutorials"
    d = tmp_path_factory.mktemp("hopper")
    subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main", "build-plant",
                    str(tutorial / "hopper.py"), "-d", str(d)], check=True, capture_output=True)
    shutil.copy(tutorial / "hopper.toml", d / "hopper.toml")
    return d


@pytest.fixture(scope="session")
def open_loop_program():
    """The best open-loop S1 program on the controller's 1 s grid at zero miss (the reentry
    bound, true-peak load; ~25 s, computed once)."""
    from descent_fmus.synthesis.systems.reentry.bound import optimize_open_loop
    return optimize_open_loop()


def pytest_sessionfinish(session, exitstatus):
    session.config._descent_exit = int(exitstatus)


def pytest_unconfigure(config):
    # after the summary is printed: end as the descent-fmus program does, without the
    # interpreter's teardown (pythonfmu FMUs loaded in this process were seen, rarely, to make
    # it abort in glibc's heap checks after every test had passed)
    if hasattr(config, "_descent_exit") and not hasattr(config, "workerinput"):
        from descent_fmus.synthesis.cli.main import exit_without_teardown
        exit_without_teardown(config._descent_exit)

