"""Registered systems: their closed-loop wiring and the FMUs that ``build_fmus.py`` builds.

Each system module registers :class:`ClosedLoopSpec` entries in :data:`CLOSED_LOOPS` and the
pythonfmu sources of its FMUs in :data:`SLAVES`; ``build_fmus.py`` builds them all.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from synthesis.cosim import Wiring

__all__ = ["ClosedLoopSpec", "CLOSED_LOOPS", "SLAVES", "register"]


@dataclass(frozen=True)
class ClosedLoopSpec:
    """A closed-loop FMU to build: wiring, controller start values, exposed parameters."""

    wiring: Wiring
    controller_defaults: dict = field(default_factory=dict)
    parameters: tuple = ()          # (container name, role, component variable)
    controller_fmu: str | None = None  # name of the controller FMU file if not wiring.controller


#: pythonfmu sources (paths relative to the project root), in build order.
SLAVES: list[str] = []
#: closed-loop FMUs by name.
CLOSED_LOOPS: dict[str, ClosedLoopSpec] = {}


def register(slaves=(), closed_loops=()):
    for s in slaves:
        if s not in SLAVES:
            SLAVES.append(s)
    for spec in closed_loops:
        CLOSED_LOOPS[spec.wiring.name] = spec


def load_all():
    """Import every system module so that it registers itself."""
    from synthesis.scenarios import reentry  # noqa: F401
    from synthesis.scenarios import telescope  # noqa: F401
    from synthesis.scenarios import mars  # noqa: F401
    from synthesis.scenarios import lunar_landing  # noqa: F401
    from synthesis.scenarios import lunar_descent  # noqa: F401
