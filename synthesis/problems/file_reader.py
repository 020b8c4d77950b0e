"""Reading a problem file: one-line errors naming the file, the key and what is wrong, and the
checks of the FMUs it names (:mod:`synthesis.problems.files` builds the problem)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["ProblemFileError", "Reader", "find_fmu", "model_description", "read_settings",
           "PlantInfo", "ControllerInfo"]


class ProblemFileError(ValueError):
    """A problem file is malformed; the message names the file, the key and the problem."""


#: What to write for a table a problem file lacks: its keys (the first ones required) and a
#: one-line example (the "missing" errors say both).
TABLE_HINTS = {
    "problem": ("name (description)", 'name = "hopper"'),
    "plant": ("fmu (parameters)", 'fmu = "Hopper.fmu"'),
    "controller": ("inputs, outputs (fmu, scaling)",
                   'inputs = [{ output = "h", scale = 0.1 }]  outputs = [{ input = "throttle", '
                   'min = 0.0, max = 1.0 }]'),
    "simulation": ("step, stop_time (stop, path)",
                   'step = 0.1  stop_time = 30.0  stop = { output = "h", op = "<=", '
                   'value = 0.0 }'),
    "initial_states": ("states, or box and samples (sampler, seed)",
                       'states = [{ h0 = 10.0, v0 = -1.0 }]'),
    "basic_law": ("gains, bias, size (a linear law); or file; or psi, q, outputs",
                  'gains = [[-1.5, -0.5]]  bias = [0.324]  size = 14'),
    "objectives": ("name, flight (over_states, unmet_stop_penalty, penalty); one [[objectives]] "
                   "table each", 'name = "miss"  flight = "abs(final(v))"  over_states = "max"'),
    "constraints": ("name, flight, sense, bound (over_states, scale); one [[constraints]] "
                    "table each",
                    'name = "peak"  flight = "max(abs(v))"  sense = "<="  bound = 2.0'),
}


def missing_table(key: str) -> str:
    """The message for a missing table ``key``: what to write, in one line."""
    hint = TABLE_HINTS.get(key)
    if hint is None:
        return "missing"
    keys, example = hint
    head = f"[[{key}]]" if key in ("objectives", "constraints") else f"[{key}]"
    return f"missing; add a {head} table with {keys}, e.g. {head} {example}"


class Reader:
    """Reads one file, raising ProblemFileError(file: key: problem)."""

    def __init__(self, path: Path):
        self.path = path

    def error(self, key: str, message: str):
        return ProblemFileError(f"{self.path}: {key}: {message}")

    def table(self, data, key: str, required: bool = True) -> dict:
        v = data.get(key.split(".")[-1]) if isinstance(data, dict) else None
        if v is None:
            if required:
                raise self.error(key, missing_table(key))
            return {}
        if not isinstance(v, dict):
            raise self.error(key, f"must be a table, got {type(v).__name__}")
        return v

    def items(self, d: dict, key: str, allowed: set, most: int = 64):
        """``(key[k], table)`` for every table of the non-empty list ``d[last part of key]``
        (at most ``most`` of them)."""
        v = d.get(key.split(".")[-1])
        if v is None and key in TABLE_HINTS:
            raise self.error(key, missing_table(key))
        if not isinstance(v, list) or not v:
            raise self.error(key, "must be a non-empty list of tables")
        if len(v) > most:
            raise self.error(key, f"{len(v)} tables; the documented maximum is {most}")
        for k, item in enumerate(v):
            kk = f"{key}[{k + 1}]"
            if not isinstance(item, dict):
                raise self.error(kk, f"must be a table with keys {', '.join(sorted(allowed))}")
            self.keys(item, kk, allowed)
            yield kk, item

    def keys(self, d: dict, key: str, allowed: set) -> None:
        for k in d:
            if k not in allowed:
                raise self.error(f"{key}.{k}", f"unknown key; allowed: {', '.join(sorted(allowed))}")

    def number(self, d: dict, key: str, name: str, default=None, positive=False,
               integer=False):
        if name not in d:
            if default is None:
                raise self.error(f"{key}.{name}", "missing")
            return default
        v = d[name]
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.error(f"{key}.{name}", f"must be a number, got {v!r}")
        if integer and not isinstance(v, int):
            raise self.error(f"{key}.{name}", f"must be an integer, got {v!r}")
        if not math.isfinite(v):
            raise self.error(f"{key}.{name}", f"must be finite, got {v!r}")
        if positive and v <= 0:
            raise self.error(f"{key}.{name}", f"must be > 0, got {v!r}")
        return v

    def string(self, d: dict, key: str, name: str, default=None) -> str:
        if name not in d:
            if default is None:
                raise self.error(f"{key}.{name}", "missing")
            return default
        v = d[name]
        if not isinstance(v, str) or not v:
            raise self.error(f"{key}.{name}", f"must be a non-empty string, got {v!r}")
        return v


def find_fmu(reader: Reader, key: str, name: str, fmu_dir) -> Path:
    p = Path(name)
    candidates = [p] if p.is_absolute() else [reader.path.parent / p] + (
        [Path(fmu_dir) / p] if fmu_dir is not None else [])
    for c in candidates:
        if c.is_file():
            return c.resolve()
    raise reader.error(key, f"FMU file not found: {name} (looked in "
                            f"{', '.join(str(c.parent) for c in candidates)}; build it first, e.g. "
                            f"python build_fmus.py for the package's FMUs)")


def model_description(reader: Reader, key: str, path: Path):
    import zipfile
    from xml.etree import ElementTree as ET

    from fmpy import read_model_description
    try:
        with zipfile.ZipFile(path) as z:
            root = ET.fromstring(z.read("modelDescription.xml"))
    except (OSError, KeyError, zipfile.BadZipFile, ET.ParseError) as exc:
        raise reader.error(key, f"{path} is not a readable FMU: {exc}") from None
    version = root.get("fmiVersion", "?")
    if version != "2.0":
        raise reader.error(key, f"{path.name} is an FMI {version} FMU; descent-fmus needs "
                                f"FMI 2.0")
    if root.find("CoSimulation") is None:
        raise reader.error(key, f"{path.name} is not a co-simulation FMU (model exchange "
                                f"only); export it for co-simulation")
    try:
        return read_model_description(str(path))
    except Exception as exc:  # fmpy's schema validation lists every problem on its own line
        lines = str(exc).splitlines()
        more = f" (+{len(lines) - 2} more)" if len(lines) > 2 else ""
        raise reader.error(key, f"{path.name}: invalid model description: "
                                f"{' '.join(x.strip() for x in lines[:2])}{more}") from None


def read_settings(reader: Reader, table: dict, key: str, current, extra=()):
    """The settings dataclass ``current`` with the values of ``table`` (keys named as its
    fields; ``extra`` keys are allowed and left to the caller), checked against each field's
    documented limits."""
    from descent_fmus.synthesis.methods.settings import (SettingError, replace_settings,
                                                         settings_of)
    infos = {s.name: s for s in settings_of(type(current))}
    reader.keys(table, key, set(infos) | set(extra))
    changes = {}
    for name, info in infos.items():
        if name not in table:
            continue
        if info.type is str:
            changes[name] = reader.string(table, key, name)
        else:
            changes[name] = reader.number(table, key, name, integer=info.type is int)
    try:
        return replace_settings(current, changes, f"{key}.")
    except SettingError as exc:
        raise reader.error(exc.key, str(exc).split(": ", 1)[1]) from None


@dataclass
class PlantInfo:
    """What the file's plant FMU offers (read from its model description)."""

    path: Path
    md: object
    vars: dict = field(default_factory=dict)

    @property
    def outputs(self) -> set:
        return {n for n, v in self.vars.items() if v.causality == "output"}

    @property
    def real_outputs(self) -> set:
        return {n for n in self.outputs if self.vars[n].type == "Real"}

    @property
    def inputs(self) -> set:
        return {n for n, v in self.vars.items() if v.causality == "input"}

    @property
    def settable(self) -> set:
        return {n for n, v in self.vars.items() if v.causality in ("parameter", "input")}


@dataclass
class ControllerInfo:
    """The law's inputs (plant outputs, scales, offsets) and outputs (plant inputs, bounds)."""

    path: Path
    inputs: list
    scale: list
    offset: list
    outputs: list
    bounds: list
    scaling: str = "given"

    @property
    def law_signals(self) -> dict:
        return {f"u{k + 1}": f"u[{k + 1}]" for k in range(len(self.outputs))}
