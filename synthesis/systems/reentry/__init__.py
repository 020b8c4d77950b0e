"""S1 -- Earth atmospheric descent: network-operator synthesis of a feedback law u = phi(y, q).

Files of this system: ``models/reentry.py`` (equations, the Reentry FMU), this package --
``wiring`` the nominal closed loop, ``guidance`` the guidance closed loops (sensed drag, NPC,
guided) and the committed laws their FMUs carry, ``laws`` the paper's laws, basic solutions and
baseline structures, ``objectives`` the objectives of a flight, ``sample_set`` the objectives
over the seeded sample set (statistics, racing), ``reports`` the run reports and the cached
bound, ``problems`` the recipes and the registered synthesis problems; the studies: ``flight``
closed-loop flights and plots, ``bound`` the best open-loop program, ``robustness`` the
dispersion study, ``robust_study`` the held-out study of guidance laws, ``oracle`` the
per-sample bound, ``cli`` its commands, ``native/`` its native (C) code: the estimator, the
on-board guidance and re-planner, the twins of its controllers -- and
``tests/test_reentry_*.py``.  The generic pieces it uses: the NetworkOperatorController and
ProgramController FMUs, ``synthesis.methods`` (network operator, GA, open loop).
"""
from descent_fmus.synthesis.registry import ClosedLoopSpec, System
from descent_fmus.synthesis.systems.reentry import cli, guidance, native, problems, wiring

SYSTEM = System(
    stem="reentry",
    title="S1 Earth reentry: network-operator synthesis of a feedback law (min load, miss)",
    fmus=("reentry:Reentry", "controllers.network_operator:NetworkOperatorController",
          "controllers.program_table:ProgramController",
          "controllers.drag_estimator:DragEstimator",
          "controllers.drag_estimator:SensedNetworkOperatorController",
          "controllers.reentry_npc:ReentryNPC",
          "controllers.reentry_npc:GuidedNetworkOperatorController"),
    closed_loops=(ClosedLoopSpec(wiring.WIRING, parameters=wiring.LOOP_PARAMETERS),
                  ClosedLoopSpec(guidance.SENSED_WIRING,
                                 parameters=guidance.SENSED_LOOP_PARAMETERS,
                                 controller_defaults=guidance.default_law_values),
                  ClosedLoopSpec(guidance.NPC_WIRING, parameters=guidance.NPC_LOOP_PARAMETERS),
                  ClosedLoopSpec(guidance.GUIDED_WIRING,
                                 parameters=guidance.GUIDED_LOOP_PARAMETERS,
                                 controller_defaults=guidance.default_guided_law_values)),
    native_plants=native.native_plants,
    native_controllers=native.native_controllers,
    problems=problems.problems,
    add_commands=cli.add_commands,
)
