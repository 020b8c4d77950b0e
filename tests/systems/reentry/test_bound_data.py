"""The S1 bounds shipped with the package (synthesis/systems/reentry/bound_data.py).

Oracles: the old route's bounds (SLSQP from u = 0 with every load sample, commit 1642ab5; the
values of test_reentry_bound.py's OLD_ROUTE), the plant's own flight of the shipped programs, and
(slow) the bounds solved afresh by ``reference_bounds`` -- the route the shipped file was written
by (``python -m descent_fmus.synthesis.systems.reentry.bound_data``).
"""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.models.reentry import ReentryParams, downrange
from descent_fmus.synthesis.systems.reentry import bound_data, reports
from descent_fmus.synthesis.systems.reentry.bound import ProgramFlight, fly_program
from descent_fmus.synthesis.systems.reentry.objectives import ON_TARGET

#: (zero miss, miss <= 1 km) by the old route on the default scenario (test_reentry_bound.py)
OLD_ROUTE = (8.289492969721305, 8.269102108359542)


def test_the_shipped_bounds_are_current():
    # the file was solved under today's content key (plant, integrators, NLP, bound code, entry
    # conditions); a change to any of them needs the file written anew
    assert bound_data.shipped_key() == reports._bound_key(), (
        f"the shipped S1 bounds are stale: run {bound_data.REGENERATE}")


def test_the_shipped_bounds_are_the_old_routes_and_fly_as_stated():
    zero, tol = bound_data.shipped_bounds(reports._bound_key())
    assert len(zero.u) == len(tol.u) == 300 and zero.t_seg == tol.t_seg == 1.0
    # the same bounds as the old route, to 1e-6
    assert zero.J1 == pytest.approx(OLD_ROUTE[0], abs=1e-6)
    assert tol.J1 == pytest.approx(OLD_ROUTE[1], abs=1e-6)
    assert np.all(np.abs(zero.u) <= 0.2 + 1e-12) and np.all(np.abs(tol.u) <= 0.2 + 1e-12)
    # each program flown by the plant's own integrator gives its stated peak and miss
    p = ReentryParams()
    for prog, miss_tol in ((zero, 1.0), (tol, ON_TARGET + 1e-3)):
        fi = fly_program(prog.u, prog.t_seg)
        assert fi.load_max == pytest.approx(prog.J1, rel=1e-12)
        assert abs(downrange(fi.x, p.Rz) - p.Lf) <= miss_tol
        assert ProgramFlight(prog.u, sensitivities=False).J1 == pytest.approx(prog.J1, rel=1e-12)


def test_a_fresh_cache_reads_the_shipped_bounds_and_keeps_them(tmp_path, monkeypatch):
    # nothing is solved (the solver would raise) and the cache then holds the shipped programs
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path))

    def solve(*args, **kwargs):
        raise AssertionError("solved although the shipped bounds are current")
    monkeypatch.setattr("descent_fmus.synthesis.systems.reentry.bound.reference_bounds", solve)
    zero, tol, cached = reports.bound_programs()
    shipped = bound_data.shipped_bounds(reports._bound_key())
    assert (zero.J1, tol.J1) == (shipped[0].J1, shipped[1].J1)
    assert all(pth.is_file() for pth in cached)
    assert np.array_equal(reports.bound_programs()[0].u, shipped[0].u)


def test_another_content_key_solves_the_bounds(tmp_path, monkeypatch):
    # a changed model or scenario (another key): the shipped file is not used
    monkeypatch.setenv("DESCENT_FMUS_CACHE", str(tmp_path))
    monkeypatch.setattr(reports, "_bound_key", lambda: "another-content")
    solved = []

    def solve(miss_tol, *args, **kwargs):
        solved.append(miss_tol)
        return bound_data.shipped_bounds(bound_data.shipped_key())
    monkeypatch.setattr("descent_fmus.synthesis.systems.reentry.bound.reference_bounds", solve)
    assert bound_data.shipped_bounds("another-content") is None
    reports.bound_programs()
    assert solved == [ON_TARGET]


def test_a_damaged_file_is_not_read(tmp_path):
    bad = tmp_path / "b.json"
    bad.write_text("{not json")
    assert bound_data.shipped_bounds("k", bad) is None and bound_data.shipped_key(bad) is None


@pytest.mark.slow            # both bounds solved afresh (~12 s on a quiet core)
def test_the_shipped_bounds_equal_a_fresh_solve(tmp_path):
    # oracle: reference_bounds, the route that wrote the file, run now: the same values to 1e-6
    out = bound_data.write_shipped(tmp_path / "fresh.json")
    fresh = bound_data.shipped_bounds(reports._bound_key(), out)
    shipped = bound_data.shipped_bounds(reports._bound_key())
    for a, b in zip(fresh, shipped):
        assert a.J1 == pytest.approx(b.J1, abs=1e-6)
        assert np.max(np.abs(a.u - b.u)) < 1e-4
