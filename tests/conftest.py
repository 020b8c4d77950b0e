"""Shared fixtures of every folder of tests: the built FMUs, the tutorial's hopper plant, the S1
open-loop program.

``fmu_dir`` is ``$DESCENT_FMUS_DIR`` if set, else ``fmus/`` of the checkout; the FMUs are built
there once per session if any registered one is missing (CI builds them before pytest).

The session-scoped work is done once per test session even when pytest-xdist runs the tests in
several worker processes (``-n 2``): :func:`once` does it under a file lock in the session's
temporary folder, which every worker shares; the first worker to ask does the work, the others
wait for it and reuse its result.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def shared_tmp(tmp_path_factory) -> Path:
    """The session's temporary folder, the same for every xdist worker (each worker's own
    ``tmp_path_factory`` folder is a sub-folder of it)."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def once(tmp_path_factory, name: str, make) -> Path:
    """The folder ``name`` of :func:`shared_tmp`, filled by ``make(folder)`` once per test
    session across the xdist workers (under a file lock; a failed ``make`` is retried by the
    next worker that asks, in an empty folder)."""
    import shutil

    from filelock import FileLock
    base = shared_tmp(tmp_path_factory)
    folder, done = base / name, base / f"{name}.done"
    with FileLock(str(base / f"{name}.lock")):
        if not done.exists():
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir()
            make(folder)
            done.touch()
    return folder


def _expected_fmus():
    from descent_fmus.synthesis.registry import closed_loop_specs, fmu_classes
    return ([f"{c.split(':')[1]}.fmu" for c in fmu_classes()]
            + [f"{s.wiring.name}.fmu" for s in closed_loop_specs()])


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory) -> Path:
    d = Path(os.environ.get("DESCENT_FMUS_DIR", ROOT / "fmus"))
    if os.environ.get("DESCENT_FMUS_NO_AUTOBUILD"):      # the caller built what it needs
        return d
    from filelock import FileLock
    with FileLock(str(shared_tmp(tmp_path_factory) / "fmus.lock")):    # one build, not one
        if not all((d / f).is_file() for f in _expected_fmus()):       # per xdist worker
            subprocess.run([sys.executable, str(ROOT / "build_fmus.py"), "--out", str(d)],
                           check=True)
    return d


@pytest.fixture(scope="session")
def native_twin(tmp_path_factory):
    """``native_twin(name)``: the path of the native twin ``name`` of the registry's controllers
    (``registry.native_controllers()``: the generic ones and S1's), built from this checkout's
    C once per test session, shared by the xdist workers and by every test file that flies it
    (a twin such as the guided controller takes ~10 s of the compiler)."""
    from descent_fmus.synthesis.registry import native_controllers
    builders = native_controllers()

    def twin(name: str) -> Path:
        folder = once(tmp_path_factory, f"native_twin_{name}",
                      lambda d: builders[name](d / f"{name}.fmu"))
        return folder / f"{name}.fmu"
    return twin


@pytest.fixture(scope="session")
def hopper_dir(tmp_path_factory) -> Path:
    """The tutorial's plant (``docs/tutorials/hopper.py``) built as the tutorial builds it
    (``descent-fmus build-plant``: ``Hopper.fmu`` and its native twin ``native/Hopper.fmu``),
    beside a copy of its problem file ``hopper.toml`` -- once per session, shared by the xdist
    workers (tests write their variants elsewhere or under names of their own; a copy of
    ``Hopper.fmu`` alone flies pythonfmu)."""
    import shutil
    tutorial = ROOT / "docs" / "tutorials"

    def build(d):
        subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main", "build-plant",
                        str(tutorial / "hopper.py"), "-d", str(d)], check=True,
                       capture_output=True)
        shutil.copy(tutorial / "hopper.toml", d / "hopper.toml")
    return once(tmp_path_factory, "hopper", build)


@pytest.fixture(scope="session")
def open_loop_program(tmp_path_factory):
    """The best open-loop S1 program on the controller's 1 s grid at zero miss (the reentry
    bound, true-peak load; ~25 s, computed once per session: the other xdist workers read the
    program file the first one wrote, exact to the bit)."""
    from descent_fmus.synthesis.systems.reentry.bound import Program, optimize_open_loop
    made = []

    def compute(d):
        made.append(optimize_open_loop())
        made[0].save(d / "program.json")
    folder = once(tmp_path_factory, "open_loop_program", compute)
    return made[0] if made else Program.load(folder / "program.json")


def pytest_sessionfinish(session, exitstatus):
    session.config._descent_exit = int(exitstatus)


def pytest_unconfigure(config):
    # after the summary is printed: end as the descent-fmus program does, without the
    # interpreter's teardown (pythonfmu FMUs loaded in this process were seen, rarely, to make
    # it abort in glibc's heap checks after every test had passed)
    if hasattr(config, "_descent_exit") and not hasattr(config, "workerinput"):
        from descent_fmus.synthesis.cli.main import exit_without_teardown
        exit_without_teardown(config._descent_exit)

