"""Tables for the docs and ``descent-fmus info``: a system's FMUs, closed loops and parameters.

The parameter tables come from the parameter dataclasses (:mod:`models.params`), the one place
where each parameter's default, unit and description are written.
"""
from __future__ import annotations

import importlib

from descent_fmus.models.params import parameter_table

__all__ = ["system_info", "parameter_markdown"]


def _fmu_class(spec: str):
    module, cls = spec.split(":")
    return getattr(importlib.import_module(f"descent_fmus.models.{module}"), cls)


def parameter_markdown(params_class) -> str:
    """A Markdown table (name, default, unit, description) of a parameter dataclass."""
    lines = ["| parameter | default | unit | description |", "| --- | --- | --- | --- |"]
    for name, default, unit, desc in parameter_table(params_class):
        value = f"{default:g}" if isinstance(default, (int, float)) else str(default)
        cells = (f"`{name}`", value, unit, desc)
        lines.append("| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |")
    return "\n".join(lines)


def system_info(system) -> tuple[dict, str]:
    """(JSON-able dict, Markdown text) describing ``system``."""
    info = {"system": system.cli_name, "title": system.title, "fmus": [],
            "closed_loops": [c.wiring.name for c in system.closed_loops]}
    text = [f"# {system.title}", ""]
    for spec in system.fmus:
        cls = _fmu_class(spec)
        entry = {"fmu": cls.__name__, "description": getattr(cls, "description", "")}
        text += [f"## {cls.__name__}.fmu", "", entry["description"], ""]
        pc = getattr(cls, "params_class", None)
        if pc is not None:
            entry["parameters"] = [dict(zip(("name", "default", "unit", "description"), row))
                                   for row in parameter_table(pc)]
            text += [parameter_markdown(pc), ""]
        info["fmus"].append(entry)
    if info["closed_loops"]:
        text += ["closed loops: " + ", ".join(f"{n}.fmu" for n in info["closed_loops"])]
    return info, "\n".join(text)
