"""The documentation builds and stays readable.  Oracle: MkDocs' own strict build (``mkdocs build
--strict`` with link, anchor and nav validation set to warn in mkdocs.yml, so a broken link, a
missing anchor, a page left out of the nav or a link outside docs/ fails the build), and the
README's own text (its length and its first lines)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SYSTEM_PAGES = ("reentry", "mars", "lunar_landing", "telescope", "lunar_descent")


def test_docs_site_builds_strictly_with_generated_parameter_tables(tmp_path):
    site = tmp_path / "site"
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, f"mkdocs build --strict failed:\n{res.stdout}\n{res.stderr}"
    for stem in SYSTEM_PAGES:
        assert (site / "systems" / stem / "index.html").is_file(), stem
    reentry = (site / "systems" / "reentry" / "index.html").read_text()
    # a row of the parameter table generated from ReentryParams by docs/hooks.py (the marker
    # line is replaced, so it never reaches the page)
    assert "<td><code>V0</code></td>" in reentry
    assert "parameters: reentry" not in reentry
    cli = (site / "reference" / "cli" / "index.html").read_text()
    assert "<code>--resume</code>" in cli          # an option table generated from the parser


def test_readme_is_short_and_starts_with_the_two_commands():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 250, len(lines)
    head = "\n".join(lines[:8])
    assert '.venv/bin/pip install -e ".[test]" && .venv/bin/python build_fmus.py' in head
    assert "pytest" in head


def test_ci_runs_readme_line_2_and_then_the_slow_tests():
    # oracle: the README's own second command (the tests not marked slow) and .ci/run's lines:
    # CI runs README line 2 as written and the same command with -m slow, so every test runs
    block = (ROOT / "README.md").read_text().split("```bash\n", 1)[1].split("```", 1)[0]
    line2 = block.splitlines()[1].strip()
    assert line2.endswith('-m "not slow"'), line2
    ci = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    assert line2 in ci, "the README's test command is not a line of .ci/run"
    slow = line2.replace('-m "not slow"', "-m slow")
    assert slow in ci and ci.index(slow) > ci.index(line2), "the slow tests do not run in CI"
