"""The S1 bound (the best open-loop program) and the robustness study (the program flown blind
vs feedback laws, through the FMUs)."""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.models.reentry import ReentryParams, downrange
from descent_fmus.synthesis.methods.network_operator import NetworkOperator
from descent_fmus.synthesis.systems.reentry.bound import Program, fly_program
from descent_fmus.synthesis.systems.reentry.robustness import dispersion_samples, dispersion_study, plot_study


@pytest.fixture(scope="module")
def program(open_loop_program):
    return open_loop_program


def test_open_loop_optimum_matches_spec(program):
    # the best piecewise-constant program (120 segments, zero miss) reaches J1 ~ 8.33;
    # refinement suggests 8.2-8.3 for continuous u.  Ours: 8.306 (tolerance: 8.2 .. 8.35).
    assert 8.2 <= program.J1 <= 8.35
    assert program.miss < 1.0                       # zero miss (equality constraint) [m]
    assert np.all(np.abs(program.u) <= 0.2 + 1e-12)
    # independent check of the reported numbers: fly the program again in-process
    fi = fly_program(program.u, program.t_seg)
    assert fi.load_max == pytest.approx(program.J1, rel=1e-12)
    assert abs(downrange(fi.x, ReentryParams().Rz) - ReentryParams().Lf) < 1.0


def test_program_file_round_trip(program, tmp_path):
    back = Program.load(program.save(tmp_path / "p.json"))
    assert np.array_equal(back.u, program.u) and back.J1 == program.J1
    (tmp_path / "bad.json").write_text('{"t_seg": 2.5}')
    with pytest.raises(ValueError, match="not a program file"):
        Program.load(tmp_path / "bad.json")


def test_the_blind_program_misses_under_dispersion(program, fmu_dir, tmp_path):
    # the model is not exactly known, so the optimal program flown blind misses: on the
    # dispersion set (rho0 +-15 %, m +-5 %, V0 +-50 m/s, beta0 +-0.03 deg) its median miss is
    # many km although its nominal replay through the FMUs (ProgramController, step = segment)
    # reproduces the optimised flight exactly.
    study = dispersion_study({"basic": NetworkOperator.basic_law()}, program, samples=12,
                             seed=7, fmu_dir=fmu_dir)
    assert plot_study(study, tmp_path / "robust.png").stat().st_size > 10_000
    prog = study["stats"]["open-loop program (blind)"]
    assert prog["J1_nominal"] == pytest.approx(program.J1, rel=1e-12)
    assert prog["miss_nominal"] < 1.0
    assert prog["miss_median"] > 5_000.0
    assert study["stats"]["basic"]["landed_fraction"] == 1.0
    # every row is a flight through the FMUs: the nominal basic-law row equals fly()
    from descent_fmus.synthesis.systems.reentry.flight import fly
    assert study["results"]["basic"][0]["J2"] == \
        fly(NetworkOperator.basic_law(), fmu_dir=fmu_dir).objectives["J2"]


def test_dispersion_samples_are_seeded_and_in_range():
    a, b = dispersion_samples(50, 3), dispersion_samples(50, 3)
    assert a == b and a[0] == ReentryParams()
    p0 = ReentryParams()
    for p in a:
        assert abs(p.rho0 / p0.rho0 - 1) <= 0.15 and abs(p.m / p0.m - 1) <= 0.05
        assert abs(p.V0 - p0.V0) <= 50 and abs(np.degrees(p.beta0 - p0.beta0)) <= 0.03 + 1e-12
