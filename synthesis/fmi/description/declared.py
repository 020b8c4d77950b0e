"""What a model description declares, as the closed loops read it."""
from __future__ import annotations

__all__ = ["declared_starts"]


def declared_starts(md) -> dict:
    """The numeric start values of a model's parameters and inputs by name (after a reset)."""
    out = {}
    for v in (v for v in md.modelVariables if v.start is not None
              and v.causality in ("parameter", "input")):
        try:
            out[v.name] = int(v.start) if v.type == "Integer" else float(v.start)
        except (TypeError, ValueError):
            pass
    return out
