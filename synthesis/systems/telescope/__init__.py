"""S4 orbital telescope with control-moment gyros: the reorientation and the route problem by the
direct (Newton-Kantorovich) method, flown through the FMUs as programs.

Files of this system: ``models/telescope_dynamics.py`` (rigid equations, Jacobian, invariants,
the data of Example 1), ``models/telescope_cmg.py`` (the gyro cluster's geometry, the attitude
kinematics), ``models/telescope.py`` (the ``AttitudeIntegrator`` and the Telescope FMU),
``models/telescope_flexible.py`` (two flexible
solar panels, the FlexibleTelescope FMU), ``models/rk4_input.py`` (RK4 with a first-order-hold
control, shared with the method), this package (``wiring`` the closed loops and their stored
programs ``programs.json``, ``reorientation`` the solves, replay and plot, ``route`` the route
problem of Example 3, ``cli`` its commands),
``tests/test_telescope_*.py``, ``benchmarks/telescope.py`` and ``docs/make_telescope_figures.py``.
The generic pieces it uses: the ProgramController FMU (``models/controllers/program_table.py``),
the direct method (``synthesis/methods/direct_method.py``, tested in
``tests/methods/test_direct_method.py``) and the route tracer (``synthesis/methods/route.py``,
``tests/methods/test_route.py``).

References
----------
S.A. Voronov, PhD thesis (2009), ch. 2, Examples 1-2; ch. 3, Example 3.
"""
from descent_fmus.synthesis.registry import ClosedLoopSpec, System
from descent_fmus.synthesis.systems.telescope import cli, wiring


def _native_plants() -> dict:
    """The native plants of this system (C traced from its plant classes)."""
    from descent_fmus.synthesis.fmi.native.builders.plant_fmu import PlantSpec
    gyros = (1, 2, 3, 4, 5, 6)          # the structural n_gyros, traced one by one
    return {"Telescope": PlantSpec("telescope:Telescope", "telescope", {"n_gyros": gyros}),
            "FlexibleTelescope": PlantSpec("telescope_flexible:FlexibleTelescope", "flexible",
                                           {"n_gyros": gyros})}


def _native_controllers() -> dict:
    """The native twin of the generic controller this system flies."""
    from descent_fmus.synthesis.fmi.native.builders.controllers import GENERIC_TWINS
    return {"ProgramController": GENERIC_TWINS["ProgramController"]}


SYSTEM = System(
    stem="telescope",
    title="S4 orbital telescope with CMGs: reorientation and route tracing by the direct "
          "method",
    fmus=("telescope:Telescope", "telescope_flexible:FlexibleTelescope",
          "controllers.program_table:ProgramController"),
    closed_loops=(ClosedLoopSpec(wiring.WIRING, controller_defaults=wiring.rigid_program),
                  ClosedLoopSpec(wiring.FLEXIBLE_WIRING,
                                 controller_defaults=wiring.flexible_program)),
    native_plants=_native_plants,
    native_controllers=_native_controllers,
    add_commands=cli.add_commands,
)
