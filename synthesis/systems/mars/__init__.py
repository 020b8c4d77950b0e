"""S2 -- Mars capsule: the Bellman/averaging angle-of-attack law of Lyubimov & Kurkina.

Files of this system: ``models/mars.py`` (the descent and averaged angle-of-attack equations,
MarsIntegrator, the MarsCapsule FMU), ``models/mars_6dof.py`` (the rigid-body check of the
averaging, the MarsCapsule6DOF FMU), ``models/controllers/mars_bellman.py`` (the law, the
MarsBellmanController FMU), this package (``wiring`` the closed loops, ``flight`` flights
through the FMUs and the alpha(t) plot, ``cli`` the ``descent-fmus mars fly`` command),
``tests/test_mars_*.py``, ``benchmarks/mars.py`` and ``docs/make_mars_figures.py``.
"""
from descent_fmus.synthesis.registry import ClosedLoopSpec, System
from descent_fmus.synthesis.systems.mars import cli, wiring


def _native_plants() -> dict:
    """The native plants of this system (C traced from its plant classes)."""
    from descent_fmus.synthesis.fmi.native.builders.plant_fmu import PlantSpec
    return {"MarsCapsule": PlantSpec("mars:MarsCapsule", "mars"),
            "MarsCapsule6DOF": PlantSpec("mars_6dof:MarsCapsule6DOF", "mars6dof")}


SYSTEM = System(
    stem="mars",
    title="S2 Mars capsule: Bellman/averaging angle-of-attack law (alpha with and without it)",
    fmus=("mars:MarsCapsule", "mars_6dof:MarsCapsule6DOF",
          "controllers.mars_bellman:MarsBellmanController"),
    closed_loops=(ClosedLoopSpec(wiring.WIRING, parameters=wiring.LOOP_PARAMETERS,
                                 controller_defaults=wiring.controller_defaults),),
    native_plants=_native_plants,
    add_commands=cli.add_commands,
)
