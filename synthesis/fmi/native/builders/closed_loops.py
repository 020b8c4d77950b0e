"""Closed-loop FMUs and SSP files of native components, for external tools.

For every registered closed loop (``synthesis.registry.ClosedLoopSpec``) whose plant and
controller both have native twins in ``fmus/native/``, :func:`build_native_closed_loops` writes
``fmus/native/<Name>ClosedLoop.fmu`` -- the closed-loop FMU of the two native FMUs
(``synthesis.fmi.containers.closed_loop_fmu``: the package's closed-loop engine), the same
connections, exposed variables and parameters as the pythonfmu closed loop -- and its
``.ssp`` beside it.  No Python runs in them: any FMI 2.0 host (``fmpy simulate``, a C host)
runs them, at any output interval (the controller samples at its own period).

A loop whose controller carries other start values (``controller_defaults``: a stored program,
a law) gets its own native controller, ``<Name>ClosedLoopController.fmu``: the twin rebuilt with
those start values (a native FMU's defaults are compiled in; there is no defaults file to swap).
"""
from __future__ import annotations

import time
from pathlib import Path

from descent_fmus.synthesis.fmi.native.builders.controllers import build_native_controllers

__all__ = ["build_native_closed_loops", "build_native_fmus"]


def build_native_closed_loops(specs, native_dir, controllers, say=print) -> list[Path]:
    """The native closed loops of ``specs`` whose twins are in ``native_dir`` (see the module
    docstring; ``controllers``: the twin builders by model identifier, for a loop's own
    controller); the paths of the FMUs written (closed loops and their own controllers)."""
    native_dir, built = Path(native_dir), []
    for spec in specs:
        w = spec.wiring
        plant, ctrl = native_dir / f"{w.plant}.fmu", native_dir / f"{w.controller}.fmu"
        if not (plant.is_file() and ctrl.is_file()):
            continue
        t0 = time.perf_counter()
        if spec.controller_defaults is not None:
            if w.controller not in controllers:
                say(f"native/{w.name}.fmu skipped: no native builder for {w.controller} with "
                    f"other start values")
                continue
            ctrl = controllers[w.controller](native_dir / f"{w.name}Controller.fmu",
                                             defaults=spec.controller_defaults())
            built.append(ctrl)
        fmu, ssp = spec.write(plant, ctrl, native_dir)
        built.append(fmu)
        say(f"built native/{fmu.name} and native/{ssp.name} ({time.perf_counter() - t0:.1f} s)")
    return built


def build_native_fmus(native_dir, controllers, specs, say=print) -> list[Path]:
    """What ``build_fmus.py`` builds into ``fmus/native/`` after the plants: the native twins
    ``controllers`` (model identifier -> builder), then the closed loops of ``specs`` whose
    plant and controller have twins there.  Without a C compiler: one line, nothing built."""
    built = build_native_controllers(native_dir, controllers, say=say)
    if built:
        built += build_native_closed_loops(specs, native_dir, controllers, say)
    return built
