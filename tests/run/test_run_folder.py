"""A run's folder refuses a different run and resumes the same one (synthesis/run/folder.py).

Oracle: the run identities written here by hand (run.json of an older version, without a
setting added since, is the same run when the setting is at its default)."""
from __future__ import annotations

import json

import pytest

from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.run.folder import (CHECKPOINT, RUN_FILE, RunDirError, RunFolder,
                                               recipe_defaults, run_spec)


def _old_run(tmp_path, spec, drop):
    """A folder holding ``spec``'s run as a version before ``ga.<drop>`` existed wrote it."""
    old = json.loads(json.dumps(spec))
    del old["ga"][drop]
    (tmp_path / RUN_FILE).write_text(json.dumps(old))
    (tmp_path / CHECKPOINT).write_text(json.dumps({"simulated": 0}))


def test_a_run_written_before_a_setting_existed_resumes_at_its_default(tmp_path):
    problem = get_problem("reentry")
    spec, defaults = run_spec(problem, "network-operator"), recipe_defaults(problem)
    assert set(defaults) == {"ga", "refine", "gp"}
    assert defaults["ga"]["weighted_arcs"] == 0.0          # the setting's default: off
    _old_run(tmp_path, spec, "weighted_arcs")
    assert RunFolder(tmp_path).open(spec, resume=True, defaults=defaults) == {"simulated": 0}
    # run.json now names the setting: the record is complete again
    assert json.loads((tmp_path / RUN_FILE).read_text())["ga"]["weighted_arcs"] == 0.0


def test_a_setting_added_since_and_set_otherwise_makes_another_run(tmp_path):
    problem = get_problem("reentry")
    spec, defaults = run_spec(problem, "network-operator"), recipe_defaults(problem)
    _old_run(tmp_path, spec, "weighted_arcs")
    other = {**spec, "ga": {**spec["ga"], "weighted_arcs": 0.25}}
    with pytest.raises(RunDirError, match="holds a different run"):
        RunFolder(tmp_path).open(other, resume=True, defaults=defaults)
    # without the defaults (an exact comparison) the old record is a different run too
    with pytest.raises(RunDirError, match="holds a different run"):
        RunFolder(tmp_path).open(spec, resume=True)
    # a setting the old run names with another value is never filled in
    changed = {**spec, "ga": {**spec["ga"], "population": spec["ga"]["population"] + 1}}
    with pytest.raises(RunDirError, match="holds a different run"):
        RunFolder(tmp_path).open(changed, resume=True, defaults=defaults)
