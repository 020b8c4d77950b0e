"""The numerical predictor-corrector guidance (ReentryNPC FMU) and its on-board prediction.

Oracles: the issue's acceptance (the nominal flight lands within 100 m); the reachable interval
of constant controls (a dispersed sample inside it must be landed as well); a closed-form miss
function for the root search.  The on-board prediction against an independent DOP853
integration: tests/systems/reentry/test_reentry_robust.py (beside the oracle bound, the same
integration).
"""
from __future__ import annotations

import pytest

from descent_fmus.models.controllers.reentry_prediction import solve_control
from descent_fmus.models.reentry import ReentryParams
from descent_fmus.synthesis.systems.reentry.oracle import oracle_bound
from descent_fmus.synthesis.systems.reentry.robust_study import fly_npc

P0 = ReentryParams()


def test_npc_lands_the_nominal_flight_within_100_m(fmu_dir):
    (row,) = fly_npc([P0], fmu_dir)
    assert row["landed"]
    assert row["J2"] < 100.0                   # issue acceptance: within 100 m


def test_npc_lands_a_dispersed_reachable_sample(fmu_dir):
    # rho0 - 10 %, V0 + 20 m/s: inside the reachable interval of constant controls (the
    # oracle lands it exactly), so the NPC, which estimates rho0/m, must land it too
    p = P0.with_(rho0=P0.rho0 * 0.90, V0=P0.V0 + 20.0)
    assert oracle_bound(p).exact
    (row,) = fly_npc([p], fmu_dir)
    assert row["landed"] and row["J2"] < 100.0


def test_solve_control_nulls_a_monotone_miss_or_returns_the_bound():
    # miss(u) = 1e5 (0.05 - u): root 0.05; a root outside [-0.2, 0.2] gives the bound
    u, f, n = solve_control(lambda u: 1e5 * (0.05 - u), 0.0, tol=1.0, max_iter=10)
    assert u == pytest.approx(0.05, abs=1e-5) and abs(f) <= 1.0
    u, f, n = solve_control(lambda u: 1e5 * (0.5 - u), 0.0, tol=1.0, max_iter=10)
    assert u == 0.2 and n == 2
    u, f, n = solve_control(lambda u: 1e5 * (-0.3 - u), 0.1, tol=1.0, max_iter=10)
    assert u == -0.2 and n == 2
