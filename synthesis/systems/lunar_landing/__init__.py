"""S3 -- vertical lunar soft landing: Pontryagin's principle solved by shooting, flown as FMUs.

Files of this system: ``models/lunar_landing.py`` (equations, closed-form arcs, switching curve,
exact optimum, the LunarLander FMU), ``models/controllers/lunar_landing_program.py`` (the
LandingProgram FMU: the optimal open-loop program), ``models/controllers/lunar_landing_switch.py``
(the LandingSwitch FMU: the optimal law as feedback), this package (``problems`` the Pontryagin
problems and the closed-loop wirings, ``solution`` the shooting solve and the paper's figures,
``study`` the closed loops through the FMUs, the dispersion study and its figures, ``cli`` its
commands), ``tests/test_lunar_landing_*.py``
(and ``tests/methods/test_shooting.py`` for the solver), ``benchmarks/lunar_landing.py`` and
``docs/make_lunar_landing_figures.py``.  The generic piece it uses: the shooting solver
``synthesis.methods.shooting``.

Importing this package computes nothing: the program closed loop's start values (the exact
optimum) are computed when its FMU is built (:func:`problems.program_defaults`).
"""
from descent_fmus.synthesis.registry import ClosedLoopSpec, System
from descent_fmus.synthesis.systems.lunar_landing import cli, problems


def _native_plants() -> dict:
    """The native plants of this system (C traced from its plant classes)."""
    from descent_fmus.synthesis.fmi.native.builders.plant_fmu import PlantSpec
    return {"LunarLander": PlantSpec("lunar_landing:LunarLander", "lander")}


SYSTEM = System(
    stem="lunar_landing",
    title="S3 vertical lunar soft landing: Pontryagin + shooting, program vs feedback law",
    fmus=("lunar_landing:LunarLander", "controllers.lunar_landing_program:LandingProgram",
          "controllers.lunar_landing_switch:LandingSwitch"),
    closed_loops=(
        ClosedLoopSpec(problems.PROGRAM_WIRING, parameters=problems.PROGRAM_LOOP_PARAMETERS,
                       controller_defaults=problems.program_defaults),
        ClosedLoopSpec(problems.FEEDBACK_WIRING, parameters=problems.FEEDBACK_LOOP_PARAMETERS),
    ),
    native_plants=_native_plants,
    add_commands=cli.add_commands,
)
