"""S1 -- Earth atmospheric descent: network-operator synthesis of a feedback law u = phi(y, q).

Files of this system: ``models/reentry.py`` (equations, the Reentry FMU), this package
(``problems`` wiring and synthesis problems, ``flight`` closed-loop flights and plots, ``bound``
the best open-loop program, ``robustness`` the dispersion study, ``sensed`` robust guidance with
sensed drag (wirings, robust problems), ``oracle`` the per-sample bound, ``cli`` its commands), and
``tests/test_reentry_*.py``.  The generic pieces it uses: the NetworkOperatorController and
ProgramController FMUs, ``synthesis.methods`` (network operator, GA, open loop).
"""
from descent_fmus.synthesis.registry import ClosedLoopSpec, System
from descent_fmus.synthesis.systems.reentry import cli, problems, sensed


def _problems() -> tuple:
    """The nominal problems and the robust guidance problems with sensed drag."""
    return problems.problems() + sensed.problems()


SYSTEM = System(
    stem="reentry",
    title="S1 Earth reentry: network-operator synthesis of a feedback law (min load, miss)",
    fmus=("reentry:Reentry", "controllers.network_operator:NetworkOperatorController",
          "controllers.program_table:ProgramController",
          "controllers.drag_estimator:DragEstimator",
          "controllers.drag_estimator:SensedNetworkOperatorController",
          "controllers.reentry_npc:ReentryNPC",
          "controllers.reentry_npc:GuidedNetworkOperatorController"),
    closed_loops=(ClosedLoopSpec(problems.WIRING, parameters=problems.LOOP_PARAMETERS),
                  ClosedLoopSpec(sensed.SENSED_WIRING, parameters=sensed.SENSED_LOOP_PARAMETERS,
                                 controller_defaults=sensed.default_law_values),
                  ClosedLoopSpec(sensed.NPC_WIRING, parameters=sensed.NPC_LOOP_PARAMETERS),
                  ClosedLoopSpec(sensed.GUIDED_WIRING,
                                 parameters=sensed.GUIDED_LOOP_PARAMETERS,
                                 controller_defaults=sensed.default_guided_law_values)),
    problems=_problems,
    add_commands=cli.add_commands,
)
