"""One way to open a closed loop: the :class:`Loop` protocol and :func:`open_loop`, the factory.

Five paths fly a plant and a controller FMU in closed loop, each a class with the same ``run``:

* ``"master"`` -- :class:`~synthesis.fmi.closed_loop.ClosedLoop`, the Python master over fmpy
  (the only one that records trajectories, other steps and schemes);
* ``"native-master"`` -- the same master on the native (C) twins;
* ``"container"`` -- :class:`~synthesis.fmi.container_loop.ContainerLoop`, the closed loop as
  one fmpy container FMU, one ``doStep`` per flight;
* ``"native-container"`` -- :class:`~synthesis.fmi.native_loop.NativeContainerLoop`, the twins
  in the container, called directly;
* ``"native-c"`` -- :class:`~synthesis.fmi.c_master_loop.CMasterLoop`, the twins under the C
  master, one call per flight.

:func:`choose_path` says which path a wiring takes (the twins where built, unless ``native`` is
False; the container if asked; the master when recording, or when outputs are asked for at
t = 0 that only the C master reads without a recording) and :func:`open_loop` opens it.
Every caller opens its loops here (``tests/fmi/test_closed_loop_factory.py`` checks that no other
module constructs one of the five classes).
"""
from __future__ import annotations

import warnings
from collections.abc import Mapping
from typing import Protocol, runtime_checkable

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop, ClosedLoopResult, Wiring
from descent_fmus.synthesis.fmi.native_loop import native_fmus
from descent_fmus.synthesis.paths import FMUNotFoundError

__all__ = ["Loop", "PATHS", "choose_path", "open_loop"]

#: The closed-loop paths, in one word each (what a run reports).
PATHS = ("master", "native-master", "container", "native-container", "native-c")


@runtime_checkable
class Loop(Protocol):
    """A plant and a controller FMU loaded once, flying one law from one initial state per
    :meth:`run`."""

    #: the path, one of :data:`PATHS`
    path: str
    wiring: Wiring

    def run(self, plant_values: Mapping | None = None,
            controller_values: Mapping | None = None, stop_time: float | None = None,
            record: bool = False) -> ClosedLoopResult:
        """One flight from t = 0: the plant's and the controller's start values (a mapping,
        :class:`~synthesis.fmi.start_values.StartValues` or a dict) -> its result."""

    def close(self) -> None:
        """Free the FMUs and delete their extracted files."""

    def remove_files(self) -> None:
        """Delete the extracted files only (no FMU call; safe in a signal handler)."""


_WARNED: list = []


def _native_path() -> str:
    """``"native-c"`` where the C master is built (or can be, once), else
    ``"native-container"`` (and a warning saying why, once per process)."""
    from descent_fmus.synthesis.fmi.c_master_loop import MasterUnavailable, master_library
    try:
        master_library()
        return "native-c"
    except MasterUnavailable as exc:
        if not _WARNED:
            _WARNED.append(1)
            warnings.warn(f"{exc}; the native flights run in fmpy's container FMU instead",
                          RuntimeWarning, stacklevel=4)
        return "native-container"


def choose_path(wiring: Wiring, plant_fmu, controller_fmu, native: bool | None = None,
                container: bool = False, record=(), initial=()) -> tuple:
    """``(path, (plant FMU, controller FMU))``: the path :func:`open_loop` takes and the FMUs
    it flies (the native twins on a native path).  ``native`` None takes the native path where
    the twins are built, True requires it (an error if they are missing), False never takes
    it; ``container`` asks for the container where no twins fly; ``record`` (plant outputs
    recorded) needs a master; ``initial`` (plant outputs read at t = 0 only) the C master,
    else a master that records them.

    Raises
    ------
    FMUNotFoundError
        ``native=True`` and the twins are not built.
    """
    twins = native_fmus(wiring, plant_fmu, controller_fmu) if native is not False else None
    if native and twins is None:
        raise FMUNotFoundError(
            f"the native path needs the native FMUs {wiring.plant}.fmu and "
            f"{wiring.controller}.fmu in the folder native/ beside {plant_fmu} (python "
            f"build_fmus.py builds them where a C compiler exists)")
    if twins is not None:
        path = "native-master" if record else _native_path()
        return ("native-master" if initial and path != "native-c" else path), twins
    return ("container" if container and not (record or initial) else "master"), \
        (plant_fmu, controller_fmu)


def open_loop(wiring: Wiring, plant_fmu, controller_fmu, path: str | None = None, *,
              native: bool | None = None, container: bool = False, record=(),
              initial=()) -> Loop:
    """The closed loop of ``wiring`` on these FMUs, loaded once: the path :func:`choose_path`
    takes, or ``path`` (one of :data:`PATHS`) on exactly the FMUs given (a benchmark comparing
    paths, the twins given as such).  ``record``: the plant outputs a master records;
    ``initial``: plant outputs wanted at t = 0 only (the C master reads them there, its
    results' ``initial``; a master records them)."""
    if path is None:
        path, (plant_fmu, controller_fmu) = choose_path(wiring, plant_fmu, controller_fmu,
                                                        native, container, record, initial)
    if path == "native-c":
        from descent_fmus.synthesis.fmi.c_master_loop import CMasterLoop
        return CMasterLoop(wiring, plant_fmu, controller_fmu, initial=initial)
    if path == "native-container":
        from descent_fmus.synthesis.fmi.native_loop import NativeContainerLoop
        return NativeContainerLoop(wiring, plant_fmu, controller_fmu)
    if path == "container":
        from descent_fmus.synthesis.fmi.container_loop import ContainerLoop
        return ContainerLoop(wiring, plant_fmu, controller_fmu)
    if path not in ("master", "native-master"):
        raise ValueError(f"unknown closed-loop path {path!r}; known: {', '.join(PATHS)}")
    loop = ClosedLoop(wiring, plant_fmu, controller_fmu,
                      record=list(record) + [n for n in initial if n not in record])
    loop.path = path
    return loop
