"""Parameters of the models: one place for each parameter's default, unit and description.

Every model keeps its parameters in a frozen dataclass whose fields are declared with
:func:`param`::

    @dataclass(frozen=True)
    class ReentryParams(Params):
        m: float = param(5000.0, "kg", "capsule mass")

The unit and the description are written there once and read by everything that shows them:
the FMU variables (:meth:`models.fmu_support.SlaveBase.parameters`), the command-line help
(``synthesis.cli.common.add_parameter_options``) and the parameter tables of the docs
(``descent-fmus info``).  Units use the FMI spelling (``m/s2``, ``kg.m2``, ``1`` for
dimensionless).

This module needs nothing but the standard library: the integrators and the in-process code use
it without pythonfmu.
"""
from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field, fields, replace

__all__ = ["ParameterError", "require_finite", "require_positive", "require_nonnegative",
           "param", "Params",
           "unit_of", "description_of", "parameter_table"]


class ParameterError(ValueError):
    """A parameter of an FMU (or of an in-process model) is out of its valid range."""


def require_finite(name: str, value: float) -> float:
    """Return ``float(value)`` or raise :class:`ParameterError` if it is NaN or infinite."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"parameter {name} must be a number, got {value!r}") from None
    if not math.isfinite(value):
        raise ParameterError(f"parameter {name} must be finite, got {value!r}")
    return value


def require_positive(name: str, value: float) -> float:
    """Return ``float(value)`` or raise :class:`ParameterError` unless it is finite and > 0."""
    value = require_finite(name, value)
    if value <= 0.0:
        raise ParameterError(f"parameter {name} must be > 0, got {value!r}")
    return value


def require_nonnegative(name: str, value: float, unit: str = "") -> float:
    """Return ``float(value)`` or raise :class:`ParameterError` unless it is finite and >= 0
    (the message names the unit, if one other than ``"1"`` is given)."""
    value = require_finite(name, value)
    if value < 0.0:
        unit = f" {unit}" if unit and unit != "1" else ""
        raise ParameterError(f"parameter {name} must be >= 0{unit}, got {value!r}")
    return value


def param(default, unit: str, description: str, *, positive: bool = False,
          nonnegative: bool = False):
    """A dataclass field with its unit and description (and, optionally, a > 0 or >= 0 check).

    Parameters
    ----------
    default : float
        Default value (the default scenario).
    unit : str
        Unit in FMI spelling (``"m/s2"``, ``"1"`` for dimensionless).
    description : str
        What the parameter is, without the unit (it is appended in brackets where shown).
    positive : bool
        :meth:`Params.validate` requires the value to be > 0.
    nonnegative : bool
        :meth:`Params.validate` requires the value to be >= 0.
    """
    return field(default=default, metadata={"unit": unit, "description": description,
                                            "positive": positive, "nonnegative": nonnegative})


def unit_of(cls, name: str) -> str:
    """Unit of field ``name`` of the parameter dataclass ``cls``."""
    return _field(cls, name).metadata.get("unit", "")


def description_of(cls, name: str, with_unit: bool = True) -> str:
    """Description of field ``name`` of ``cls`` (``"capsule mass [kg]"`` with the unit)."""
    f = _field(cls, name)
    text = f.metadata.get("description", name)
    unit = f.metadata.get("unit")
    return f"{text} [{unit}]" if with_unit and unit else text


def _field(cls, name):
    for f in fields(cls):
        if f.name == name:
            return f
    raise KeyError(f"{cls.__name__} has no parameter {name!r}")


def parameter_table(cls) -> list[tuple[str, object, str, str]]:
    """``(name, default, unit, description)`` of every field of ``cls`` (for docs and help)."""
    out = []
    for f in fields(cls):
        default = f.default if f.default is not MISSING else None
        out.append((f.name, default, f.metadata.get("unit", ""),
                    f.metadata.get("description", "")))
    return out


@dataclass(frozen=True)
class Params:
    """Base of the parameter dataclasses: finite values, the ``positive`` fields > 0, the
    ``nonnegative`` fields >= 0.

    Subclasses add their own checks in :meth:`check` (called by :meth:`validate` after the
    generic ones) and raise :class:`ParameterError` naming the parameter.
    """

    def validate(self):
        """Raise :class:`ParameterError` naming the first invalid parameter; return self."""
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, (tuple, list)):
                for k, v in enumerate(value):
                    require_finite(f"{f.name}[{k + 1}]", v)
            else:
                require_finite(f.name, value)
            if f.metadata.get("positive"):
                require_positive(f.name, value)
            if f.metadata.get("nonnegative"):
                require_nonnegative(f.name, value, f.metadata.get("unit", ""))
        self.check()
        return self

    def check(self) -> None:
        """Model-specific checks (override)."""

    def with_(self, **changes):
        """A copy with some parameters changed."""
        return replace(self, **changes)
