"""Settings dataclasses whose every field carries its help text and its limits.

The budget of a run, the variational GA's sizes and the CMA-ES refinement are each one frozen
dataclass (:class:`~synthesis.problems.contract.Budget`, :class:`~synthesis.methods.ga_config.GAConfig`,
:class:`~synthesis.methods.refinement.RefineConfig`).  Their fields are declared with
:func:`setting`, and everything else is derived from that one declaration: the command-line
options of ``descent-fmus synthesize``, the keys of a problem file's tables, the checks and
their one-line errors, and the documented maximum of every size a user can give (no input can
make a run grow without limit).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

__all__ = ["setting", "SettingError", "SettingInfo", "settings_of", "check_settings",
           "replace_settings"]


class SettingError(ValueError):
    """A setting is out of its range; ``key`` names it."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}")
        self.key = key


def setting(default, help: str, minimum=None, maximum=None, choices=None):
    """A dataclass field with its help text and limits (inclusive; None = no limit)."""
    return field(default=default, metadata={"help": help, "min": minimum, "max": maximum,
                                            "choices": choices})


@dataclass(frozen=True)
class SettingInfo:
    """One field of a settings dataclass, as :func:`settings_of` lists it."""

    name: str
    type: type
    default: object
    help: str
    minimum: object = None
    maximum: object = None
    choices: tuple | None = None

    @property
    def limits(self) -> str:
        """The range as text, e.g. ``1..100000`` or ``>= 0``."""
        if self.choices:
            return " | ".join(map(str, self.choices))
        lo, hi = self.minimum, self.maximum
        if lo is not None and hi is not None:
            return f"{lo}..{hi}"
        if lo is not None:
            return f">= {lo}"
        return f"<= {hi}" if hi is not None else ""


def settings_of(cls) -> list[SettingInfo]:
    """The fields of a settings dataclass declared with :func:`setting`."""
    out = []
    for f in dataclasses.fields(cls):
        md = f.metadata
        if "help" not in md:
            continue
        out.append(SettingInfo(f.name, type(f.default), f.default, md["help"], md["min"],
                               md["max"], md["choices"]))
    return out


def check_settings(obj, prefix: str = "") -> None:
    """Raise :class:`SettingError` for the first field of ``obj`` outside its limits (type,
    range, choices); ``prefix`` is put before the key in the message (e.g. ``"ga."``)."""
    for s in settings_of(type(obj)):
        v = getattr(obj, s.name)
        key = prefix + s.name
        if s.choices is not None:
            if v not in s.choices:
                raise SettingError(key, f"must be one of {', '.join(map(str, s.choices))}, "
                                        f"got {v!r}")
            continue
        if s.type is int and (isinstance(v, bool) or not isinstance(v, int)):
            raise SettingError(key, f"must be an integer, got {v!r}")
        if s.type is float:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise SettingError(key, f"must be a finite number, got {v!r}")
        if s.minimum is not None and v < s.minimum:
            raise SettingError(key, f"must be >= {s.minimum}, got {v}")
        if s.maximum is not None and v > s.maximum:
            raise SettingError(key, f"must be <= {s.maximum} (the documented maximum), "
                                    f"got {v}")


def replace_settings(obj, changes: dict, prefix: str = ""):
    """A copy of ``obj`` with ``changes`` (None values ignored), checked; unknown keys raise
    :class:`SettingError` naming the allowed ones."""
    names = {s.name for s in settings_of(type(obj))}
    for k in changes:
        if k not in names:
            raise SettingError(prefix + k, f"unknown key; allowed: {', '.join(sorted(names))}")
    new = dataclasses.replace(obj, **{k: v for k, v in changes.items() if v is not None})
    check_settings(new, prefix)
    return new
