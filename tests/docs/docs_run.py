"""Running the documentation: the command blocks of a Markdown file, as written, in a scratch copy
of the repository, and the figures the text quotes beside what the commands printed.

* :func:`command_lines` -- every command of the ```` ```bash ```` blocks of a page, in order
  (a line ending in ``\\`` continues on the next);
* :func:`scratch_copy` -- the tracked files of the checkout (as they are in the working tree) in a
  new folder, with the substitutions of :data:`SUBSTITUTED` (the venv and the built FMUs);
* :func:`run_page` -- a page's commands run there by ``bash`` one by one, each with its result;
* :func:`quoted_figures` -- the numbers the text marks as checked: ``8.2705<!-- check: KEY -->``
  (a figure of a run) or ``48 s<!-- time: KEY -->`` (a duration, never asserted: the tests
  do not time anything; it must name a phase the run reports), the marker right after the
  figure (and its unit) on the same line; HTML comments, so neither GitHub nor MkDocs shows them.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: [choice] The few places where a test does not run a documented command as written, and why.
#: The key is the exact command (one part of an ``a && b`` line); every key must still occur in
#: the docs (tests/docs/test_docs_executed.py checks), so that a substitution cannot outlive its
#: text.
SUBSTITUTED = {
    "python3 -m venv .venv": "the scratch copy's .venv is a link to the venv running the tests",
    '.venv/bin/pip install -e ".[test]"': "already installed in that venv (a reinstall only "
                                          "costs minutes)",
    ".venv/bin/python build_fmus.py": "the FMUs the session built (conftest's fmu_dir, in CI "
                                      "built by .ci/run) are linked into the copy's fmus/",
    '.venv/bin/python -m pytest -q -n auto -m "not slow"': "the README's test command is this "
                                                           "very run (CI runs it)",
    ".venv/bin/mkdocs build --strict": "tests/docs/test_docs.py builds the site with --strict",
}

NUMBER = r"[−-]?\d{1,3}(?:[  ]\d{3})+(?:\.\d+)?|[−-]?\d+(?:\.\d+)?(?:e[−-]?\d+)?"
MARKER = re.compile(rf"(?P<num>{NUMBER})(?P<unit>[^\d<>]{{0,12}}?)\s*"
                    rf"<!--\s*(?P<kind>check|time):\s*(?P<key>[\w.-]+)\s*-->")


def command_lines(page: Path) -> list[str]:
    """The commands of the bash blocks of ``page``, in order (comment lines dropped)."""
    out, block, pending = [], None, ""
    for line in page.read_text().splitlines():
        if line.startswith("```"):
            block = line[3:].strip() if block is None else None
            continue
        if block not in ("bash", "sh") or not line.strip() or line.lstrip().startswith("#"):
            continue
        if line.endswith("\\"):
            pending += line[:-1]
            continue
        out.append((pending + line).strip())
        pending = ""
    return out


def parts(command: str) -> list[str]:
    """``a && b && c  # note`` -> the commands a, b, c (the comment removed)."""
    quote = None
    for i, ch in enumerate(command):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or command[i - 1].isspace()):
            command = command[:i]
            break
    return [p.strip() for p in command.split(" && ")]


@dataclass
class Ran:
    command: str
    returncode: int
    stdout: str
    stderr: str
    seconds: float


def scratch_copy(dest: Path, fmu_dir: Path) -> Path:
    """The tracked files of the checkout (working-tree contents) under ``dest``; ``.venv`` a link
    to the running venv, ``fmus/`` holding links to the built FMUs (:data:`SUBSTITUTED`)."""
    import sys
    files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True,
                           text=True).stdout.split("\0")
    for name in filter(None, files):
        src = ROOT / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)
    (dest / ".venv").symlink_to(Path(sys.executable).parent.parent)
    (dest / "fmus").mkdir(exist_ok=True)
    for item in Path(fmu_dir).iterdir():
        if not (dest / "fmus" / item.name).exists():
            (dest / "fmus" / item.name).symlink_to(item.resolve())
    return dest


def run_page(page: Path, where: Path, env: dict, timeout: float = 3600) -> dict[str, Ran]:
    """Every command of ``page`` run in ``where`` by bash, in order, as written except the parts
    :data:`SUBSTITUTED`; {command part: Ran}.  A failing command does not stop the others."""
    results = {}
    for line in command_lines(page):
        for part in parts(line):
            if part in SUBSTITUTED:
                continue
            t0 = time.perf_counter()
            res = subprocess.run(["bash", "-c", part], cwd=where, env=env, capture_output=True,
                                 text=True, timeout=timeout)
            results[part] = Ran(part, res.returncode, res.stdout, res.stderr,
                                time.perf_counter() - t0)
    return results


def run_env(cache: Path) -> dict:
    """The environment of the documented commands: a fresh cache folder, no display."""
    env = dict(os.environ, DESCENT_FMUS_CACHE=str(cache), MPLBACKEND="Agg")
    env.pop("DESCENT_FMUS_DIR", None)
    return env


@dataclass
class Figure:
    kind: str            # "check" or "time"
    key: str
    text: str            # the figure as quoted
    value: float
    decimals: int
    unit: str
    line: int

    def matches(self, measured: float) -> bool:
        """The quoted figure is the measured value rounded to the digits quoted."""
        return abs(measured - self.value) <= 0.5 * 10.0 ** -self.decimals * (1 + 1e-9)


def quoted_figures(page: Path) -> list[Figure]:
    out = []
    for i, line in enumerate(page.read_text().splitlines(), 1):
        for m in MARKER.finditer(line):
            text = m["num"]
            plain = text.replace("−", "-").replace(" ", "").replace(" ", "")
            mant = plain.split("e")[0]
            decimals = len(mant.split(".")[1]) if "." in mant else 0
            if "e" in plain:
                decimals -= int(plain.split("e")[1])
            out.append(Figure(m["kind"], m["key"], text, float(plain), decimals,
                              m["unit"].strip(), i))
    return out


def left_behind(where: Path) -> list[str]:
    """Files in ``where`` that are neither tracked nor under ``runs/`` nor ignored by the
    checkout's .gitignore (``git check-ignore``): what the commands left in a user's tree."""
    tracked = set(subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True,
                                 check=True, text=True).stdout.split("\0"))
    new = []
    for folder, dirs, files in os.walk(where):          # does not enter the linked .venv
        rel = Path(folder).relative_to(where)
        dirs[:] = [d for d in dirs if not (rel == Path(".") and d == "runs")
                   and d != "__pycache__"]
        new += [str(rel / f) for f in files if str(rel / f) not in tracked
                and not (Path(folder) / f).is_symlink()]
    if not new:
        return []
    res = subprocess.run(["git", "check-ignore", "--no-index", "--verbose", "--non-matching",
                          "--stdin"], cwd=ROOT, input="\n".join(new), capture_output=True,
                         text=True)
    return [line.split("\t")[-1] for line in res.stdout.splitlines() if line.startswith("::")]
