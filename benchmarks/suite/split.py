"""The suite's held-out protocol as data: ``split.toml`` names the problems the default recipe
is tuned on and the problems it is never tuned on (docs/benchmarks/suite.md); run.py reports the
two halves apart.  :func:`read_split` reads and checks it."""
from __future__ import annotations

from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:              # Python 3.10
    import tomli as tomllib

__all__ = ["HALVES", "SPLIT", "SplitError", "read_split"]

SPLIT = Path(__file__).resolve().parent / "split.toml"
#: the two halves, in the order of the report: (TOML table, title)
HALVES = (("tuning", "tuning problems (the default recipe is chosen on these)"),
          ("held_out", "held-out problems (never used to tune the recipe)"))


class SplitError(ValueError):
    """The split file is malformed: the message names the file and the problem."""


def read_split(path=SPLIT, problems=None) -> dict:
    """``{"tuning": [...], "held_out": [...]}`` from ``path``.  With ``problems`` (the suite's
    names) every one must be named exactly once: an unknown name, a name given twice (in one
    half or in both) or a problem left out is a :class:`SplitError`."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise SplitError(f"{path}: {exc}") from None
    halves = {name for name, _ in HALVES}
    extra = sorted(set(data) - halves)
    if extra:
        raise SplitError(f"{path}: unknown table(s) {', '.join(extra)} (expected "
                         f"{', '.join(sorted(halves))})")
    out, seen = {}, {}
    for half, _ in HALVES:
        table = data.get(half)
        names = table.get("problems") if isinstance(table, dict) else None
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise SplitError(f"{path}: {half}.problems must be a list of problem names")
        if set(table) - {"problems"}:
            raise SplitError(f"{path}: {half}: unknown key(s) "
                             f"{', '.join(sorted(set(table) - {'problems'}))}")
        for n in names:
            if n in seen:
                raise SplitError(f"{path}: problem {n!r} named twice ({seen[n]} and {half})")
            if problems is not None and n not in problems:
                raise SplitError(f"{path}: {half}: unknown problem {n!r} (known: "
                                 f"{', '.join(problems)})")
            seen[n] = half
        out[half] = list(names)
    if problems is not None:
        missing = [n for n in problems if n not in seen]
        if missing:
            raise SplitError(f"{path}: problem(s) in neither half: {', '.join(missing)}")
    return out
