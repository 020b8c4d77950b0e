"""The systems of descent-fmus: one typed record per system, found through one table.

Each system lives in ``synthesis/systems/<stem>/`` and describes itself with a :class:`System`
record named ``SYSTEM`` in its package: the FMU classes it contributes (built by
``build_fmus.py``), the native (C) plants and controller twins it builds, the closed-loop FMUs
composed from them, its synthesis problems and its command-line sub-commands.  This is the one
registry of what a system builds: the generic builders (``synthesis/fmi/``) take it as
arguments and know no system.  :data:`SYSTEMS` lists the stems; adding a system is one line here.

Nothing is imported or computed until asked for (``python -X importtime -c 'import
descent_fmus.synthesis.registry'`` imports no system): a system package is imported by
:func:`get_system`, and its records hold callables for anything that costs time (for instance
the start values a closed-loop FMU carries, computed when the FMU is built).
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping


__all__ = ["SYSTEMS", "System", "ClosedLoopSpec", "get_system", "all_systems", "get_problem",
           "problem_names", "fmu_classes", "closed_loop_specs", "native_plants",
           "native_controllers", "UnknownProblemError"]

#: Stems of the systems, in the order the docs present them (one line per system).
SYSTEMS = (
    "reentry",          # S1 Earth reentry, network-operator synthesis
    "mars",             # S2 Mars capsule, Bellman/averaging angle-of-attack law
    "lunar_landing",    # S3 vertical lunar landing, Pontryagin + shooting
    "telescope",        # S4 orbital telescope with CMGs, direct method
    "lunar_descent",    # S5 descent from lunar orbit, network-operator synthesis (2 controls)
)


class UnknownProblemError(KeyError):
    """No registered synthesis problem has that name."""

    def __str__(self):
        return self.args[0]


@dataclass(frozen=True)
class ClosedLoopSpec:
    """A closed-loop container FMU (and SSP file) that ``build_fmus.py`` composes.

    Attributes
    ----------
    wiring : Wiring
        Plant, controller, connections, step, stop time, exposed outputs.
    parameters : tuple of (str, str, str)
        ``(container name, "plant" | "controller", component variable)`` exposed as parameters.
    controller_defaults : callable or None
        ``() -> {variable: value}``: start values the controller FMU carries in this loop
        (called at build time; e.g. the computed optimal program).
    """

    wiring: object
    parameters: tuple = ()
    controller_defaults: Callable[[], Mapping] | None = None

    def write(self, plant_fmu: Path, controller_fmu: Path, folder: Path) -> tuple:
        """``(closed-loop FMU, SSP file)`` around these plant and controller FMUs, written into
        ``folder`` as ``<Name>.fmu`` and ``<Name>.ssp``."""
        from descent_fmus.synthesis.fmi.containers import closed_loop_fmu, write_ssp
        w, folder = self.wiring, Path(folder)
        return (closed_loop_fmu(w, plant_fmu, controller_fmu, folder / f"{w.name}.fmu",
                                parameters=self.parameters),
                write_ssp(w, plant_fmu, controller_fmu, folder / f"{w.name}.ssp"))


@dataclass(frozen=True)
class System:
    """Everything one system adds to descent-fmus.

    Attributes
    ----------
    stem : str
        Name used in every layer (``models/<stem>.py``, ``synthesis/systems/<stem>/``,
        ``tests/test_<stem>_*.py``); the command line spells it with hyphens.
    title : str
        One line for listings.
    fmus : tuple of str
        pythonfmu FMU classes as ``"module:Class"`` (module relative to ``descent_fmus.models``,
        e.g. ``"reentry:Reentry"``, ``"controllers.network_operator:NetworkOperatorController"``).
    closed_loops : tuple of ClosedLoopSpec
    native_plants : callable or None
        ``() -> {model identifier: PlantSpec}``: the native plants it builds
        (:class:`synthesis.fmi.native.builders.plant_fmu.PlantSpec`: C traced from the plant).
    native_controllers : callable or None
        ``() -> {model identifier: builder}``: the native controller twins it flies, generic
        (``synthesis.fmi.native.builders.controllers.GENERIC_TWINS``) or its own; a builder is
        ``builder(dest, compiler=None, defaults=None) -> Path``.
    problems : callable or None
        ``() -> tuple of SynthesisProblem`` (network-operator synthesis problems).
    add_commands : callable or None
        ``add_commands(subparsers)``: the ``descent-fmus <system> <action>`` sub-commands.
    """

    stem: str
    title: str
    fmus: tuple = ()
    closed_loops: tuple = ()
    native_plants: Callable[[], Mapping] | None = None
    native_controllers: Callable[[], Mapping] | None = None
    problems: Callable[[], tuple] | None = None
    add_commands: Callable | None = None

    @property
    def cli_name(self) -> str:
        return self.stem.replace("_", "-")


def get_system(stem: str) -> System:
    """The :class:`System` record of ``stem`` (imports its package)."""
    stem = stem.replace("-", "_")
    if stem not in SYSTEMS:
        raise KeyError(f"unknown system {stem!r}; known: {', '.join(SYSTEMS)}")
    return importlib.import_module(f"descent_fmus.synthesis.systems.{stem}").SYSTEM


def all_systems() -> list[System]:
    return [get_system(s) for s in SYSTEMS]


def _problems() -> dict:
    out = {}
    for system in all_systems():
        for problem in (system.problems() if system.problems else ()):
            out[problem.name] = problem
    return out


def problem_names() -> list[str]:
    return list(_problems())


def get_problem(name: str):
    """A registered :class:`~synthesis.problems.contract.SynthesisProblem` by name."""
    problems = _problems()
    try:
        return problems[name]
    except KeyError:
        raise UnknownProblemError(f"unknown synthesis problem {name!r}; registered: "
                                  f"{', '.join(problems) or 'none'} (or give a problem file: "
                                  f"--problem FILE.toml)") from None


def fmu_classes() -> list[str]:
    """Every ``"module:Class"`` to build, each once, in system order."""
    out = []
    for system in all_systems():
        out += [f for f in system.fmus if f not in out]
    return out


def closed_loop_specs() -> list[ClosedLoopSpec]:
    return [spec for system in all_systems() for spec in system.closed_loops]


def _merged(systems, field: str) -> dict:
    out = {}
    for system in systems:
        declared = getattr(system, field)
        out.update((k, v) for k, v in (declared() if declared else {}).items() if k not in out)
    return out


def native_plants(systems=None) -> dict:
    """The native plants of ``systems`` (default: all), each model identifier once."""
    return _merged(all_systems() if systems is None else systems, "native_plants")


def native_controllers(systems=None) -> dict:
    """The native controller twins of ``systems`` (default: all), each model identifier once."""
    return _merged(all_systems() if systems is None else systems, "native_controllers")
