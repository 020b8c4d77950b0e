"""S5 -- descent from lunar orbit: network-operator synthesis of a feedback law with two controls
(thrust direction u1, thrust change u2) over a set of initial states.

Files of this system: ``models/lunar_descent.py`` (equations, the DescentIntegrator, the
LunarDescent FMU), this package (``problems`` wiring, criteria, basic law and the synthesis
problem ``lunar-descent``; ``study`` flights of a law on the initial set and on a seeded
dispersion, front comparison and the report figure; ``cli`` the ``report`` command),
``tests/test_lunar_descent_*.py``, ``tests/reference/lunar_descent_law*.json`` (a synthesised
law), ``benchmarks/lunar_descent.py`` and ``docs/make_lunar_descent_figures.py``.  The generic
pieces it uses: the NetworkOperatorController FMU and ``synthesis.methods`` (network operator,
GA).
"""
from descent_fmus.synthesis.registry import ClosedLoopSpec, System
from descent_fmus.synthesis.systems.lunar_descent import cli, problems


def _native_plants() -> dict:
    """The native plants of this system (C traced from its plant classes)."""
    from descent_fmus.synthesis.fmi.native.builders.plant_fmu import PlantSpec
    return {"LunarDescent": PlantSpec("lunar_descent:LunarDescent", "descent")}


def _native_controllers() -> dict:
    """The native twin of the generic controller this system flies."""
    from descent_fmus.synthesis.fmi.native.builders.controllers import GENERIC_TWINS
    return {"NetworkOperatorController": GENERIC_TWINS["NetworkOperatorController"]}


SYSTEM = System(
    stem="lunar_descent",
    title="S5 descent from lunar orbit: network-operator synthesis with two controls (h, V "
          "misses in the terminal box)",
    fmus=("lunar_descent:LunarDescent", "controllers.network_operator:NetworkOperatorController"),
    closed_loops=(ClosedLoopSpec(problems.WIRING, parameters=problems.LOOP_PARAMETERS,
                                 controller_defaults=problems.basic_law_start_values),),
    native_plants=_native_plants,
    native_controllers=_native_controllers,
    problems=problems.problems,
    add_commands=cli.add_commands,
)
