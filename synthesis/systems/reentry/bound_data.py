"""The S1 bounds shipped with the package: ``bound_reference.json`` beside this module.

The two bounds every ``synthesize reentry`` report compares with (:func:`.reports.bound_programs`:
zero miss and miss <= 1 km on the controller's 1 s grid) cost about 12 s to solve
(:func:`.bound.reference_bounds`), the largest fixed cost of README line 1's main job on a fresh
machine.  They depend only on the content :func:`bound_key` hashes (the plant's and the
bound's code, the entry conditions, the tolerance), so the package ships them under that key:

* :func:`shipped_bounds` -- the two programs when the shipped key equals the current one, else
  None (a changed model, bound code or scenario: the bounds are solved again, as before);
* :func:`write_shipped` -- solves both bounds and writes the file (run it after such a change:
  ``python -m descent_fmus.synthesis.systems.reentry.bound_data``).

``tests/systems/reentry/test_bound_data.py`` checks that the shipped key is current (a fast test
that names this command when it is not) and, slow-marked, recomputes both bounds and compares them
with the shipped ones.
"""
from __future__ import annotations

import json
from pathlib import Path

__all__ = ["SHIPPED", "bound_key", "shipped_key", "shipped_bounds", "write_shipped", "REGENERATE"]

#: The shipped bounds (key, both programs).
SHIPPED = Path(__file__).with_name("bound_reference.json")
#: The command that writes :data:`SHIPPED` anew.
REGENERATE = "python -m descent_fmus.synthesis.systems.reentry.bound_data"


def bound_key() -> str:
    """What the bound depends on: the plant's and the bound's code, the entry conditions."""
    import hashlib
    import inspect
    from dataclasses import asdict

    from descent_fmus.models import integrators, reentry
    from descent_fmus.models.reentry import ReentryParams
    from descent_fmus.synthesis.methods import open_loop
    from descent_fmus.synthesis.systems.reentry import bound
    from descent_fmus.synthesis.systems.reentry.objectives import ON_TARGET
    h = hashlib.sha256()
    for module in (reentry, integrators, open_loop, bound):
        h.update(inspect.getsource(module).encode())
    h.update(repr((sorted(asdict(ReentryParams()).items()), ON_TARGET)).encode())
    return h.hexdigest()[:20]


def shipped_key(path: Path = SHIPPED) -> str | None:
    """The content key the shipped bounds were solved under (None: no readable file)."""
    try:
        return json.loads(Path(path).read_text())["key"]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def shipped_bounds(key: str, path: Path = SHIPPED):
    """``(zero-miss program, 1 km program)`` from the shipped file if it was solved under
    ``key`` (:func:`bound_key`), else None."""
    from descent_fmus.synthesis.systems.reentry.bound import Program
    try:
        d = json.loads(Path(path).read_text())
        if d["key"] != key:
            return None
        return tuple(Program.from_dict(p) for p in d["programs"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def write_shipped(path: Path = SHIPPED) -> Path:
    """Solve both bounds (:func:`.bound.reference_bounds`) and write them with the current key."""
    from descent_fmus.synthesis.systems.reentry.bound import reference_bounds
    from descent_fmus.synthesis.systems.reentry.objectives import ON_TARGET
    progs = reference_bounds(ON_TARGET)
    data = {"key": bound_key(), "written_by": REGENERATE,
            "programs": [p.to_dict() for p in progs]}
    path = Path(path)
    path.write_text(json.dumps(data, indent=1) + "\n")
    return path


if __name__ == "__main__":
    out = write_shipped()
    print(f"wrote {out} (key {shipped_key(out)})")
