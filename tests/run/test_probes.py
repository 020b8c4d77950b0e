"""The equivalence keys through the controller twin's C interpreter (synthesis.run.probes) are
the Python interpreter's keys, bit for bit (the oracle: ``NetworkOperator.raw_points``, i.e.
``models.controllers.law_interpreter``, which the pythonfmu controller runs)."""
from __future__ import annotations

import numpy as np

from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.run.evaluation import _behaviour_key, _probes
from descent_fmus.synthesis.run.probes import native_prober

from tests.methods.test_interpreter_batch import _random_law


def test_native_keys_are_the_python_keys(fmu_dir):
    problem = get_problem("reentry")
    fmus = tuple(str(f) for f in problem.fmu_paths(fmu_dir))
    prober = native_prober(problem, fmus)
    assert prober is not None, "the reentry problem flies native twins: a prober is built"
    prober.checked = 10 ** 9                 # no cross-check inside: this test is the check
    rng = np.random.default_rng(11)
    points = _probes(problem)
    wide = np.vstack([points, rng.normal(0, 1e5, (8, 2)), np.zeros((1, 2))])
    laws = [problem.basic()] + [_random_law(rng, L=30, nx=2) for _ in range(80)]
    for law in laws:
        for pts in (points, wide):
            got = prober.values(law, pts)
            want = [float(v) for row in law.raw_points(pts) for v in row]
            assert [v.hex() for v in got] == [v.hex() for v in want]      # bit for bit
        assert _behaviour_key(law, points, prober) == _behaviour_key(law, points)
    big = _random_law(rng, L=40, nx=2)                  # larger than the twin: Python route
    assert prober.values(big, points) is None
    assert _behaviour_key(big, points, prober) == _behaviour_key(big, points)


def test_a_difference_sends_the_run_to_python(fmu_dir):
    problem = get_problem("reentry")
    prober = native_prober(problem, tuple(str(f) for f in problem.fmu_paths(fmu_dir)))
    law, points = problem.basic(), _probes(problem)
    right = prober.values(law, points)
    prober._eval = lambda *a: (a[-1].fill(0.5), 0)[1]       # a twin that answers wrongly
    assert prober.values(law, points) == right and not prober.trusted
    assert prober.values(law, points) is None                # from now on: Python


def test_no_twin_no_prober(tmp_path):
    problem = get_problem("reentry")
    assert native_prober(problem, (str(tmp_path / "a.fmu"), str(tmp_path / "b.fmu"))) is None
