"""Units of FMU variables: from the one place they are written to FMI ``unit`` attributes.

A parameter's unit is written once, in :func:`descent_fmus.models.params.param`; every FMU
variable shows it at the end of its description in brackets (``"capsule mass [kg]"``, the
outputs and inputs likewise: ``"altitude r - Rz [m]"``).  pythonfmu writes no ``unit``
attribute, so the build reads the bracket back (:func:`unit_of_description`) and adds

* ``unit="..."`` to every Real variable (FMI 2.0 has no unit attribute on Integer or Boolean
  variables), and
* ``<UnitDefinitions>`` with each unit's SI base-unit exponents (:func:`base_unit`), so that FMI
  tools can check and convert units (and SSP tools can check connections).

Unit names use the FMI/Modelica spelling: factors joined by ``.``, an exponent after the symbol,
one ``/`` (``kg.m2``, ``m/s2``, ``1/rad``); ``1`` is dimensionless.  A spelling with blanks
(``N m s``) is normalised to dots (``N.m.s``).  A unit whose exponents are not integers
(``sqrt(kg).m``, the modal coordinates of a flexible structure) is declared without a base unit:
FMI 2.0 base-unit exponents are integers.
"""
from __future__ import annotations

import math
import re
from fractions import Fraction
from xml.etree import ElementTree as ET

__all__ = ["BASE", "unit_of_description", "normalise", "base_unit", "UnitError",
           "units_into_model_description", "unit_definitions"]

#: FMI 2.0 base-unit attributes (exponents), in schema order.
BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")

# symbol -> (factor to SI, {base: exponent})
_SYMBOLS = {
    "kg": (1.0, {"kg": 1}), "g": (1e-3, {"kg": 1}), "t": (1e3, {"kg": 1}),
    "m": (1.0, {"m": 1}), "km": (1e3, {"m": 1}),
    "s": (1.0, {"s": 1}), "min": (60.0, {"s": 1}), "h": (3600.0, {"s": 1}),
    "A": (1.0, {"A": 1}), "K": (1.0, {"K": 1}), "mol": (1.0, {"mol": 1}),
    "cd": (1.0, {"cd": 1}),
    "rad": (1.0, {"rad": 1}), "deg": (math.pi / 180.0, {"rad": 1}),
    "Hz": (1.0, {"s": -1}),
    "N": (1.0, {"kg": 1, "m": 1, "s": -2}),
    "kgf": (9.80665, {"kg": 1, "m": 1, "s": -2}),
    "Pa": (1.0, {"kg": 1, "m": -1, "s": -2}),
    "J": (1.0, {"kg": 1, "m": 2, "s": -2}),
    "W": (1.0, {"kg": 1, "m": 2, "s": -3}),
}

_BRACKET = re.compile(r"\[([^\[\]]+)\]\s*$")
_FACTOR = re.compile(r"^(sqrt\(([A-Za-z]+)\)|[A-Za-z]+)(-?\d+)?$")


class UnitError(ValueError):
    """A unit spelling this module cannot read."""


def normalise(unit: str) -> str:
    """``unit`` in the dotted spelling (blanks between factors become ``.``)."""
    return re.sub(r"\s*\.\s*|\s+", ".", unit.strip())


def unit_of_description(description: str | None, strict: bool = False) -> str | None:
    """The unit in brackets at the end of a variable's description (normalised), or None.

    A bracket that does not read as a unit (``"force, clipped to [-2, 2]"``) is text, not a
    unit: None, or with ``strict`` a :class:`UnitError` naming it (the package's own FMUs are
    checked that way, so a misspelt unit of theirs cannot pass as text)."""
    if not description:
        return None
    m = _BRACKET.search(description)
    if m is None:
        return None
    unit = normalise(m.group(1))
    try:
        base_unit(unit)
    except UnitError as exc:
        if strict:
            raise UnitError(f"description {description!r}: {exc}") from None
        return None
    return unit


def _factors(part: str):
    if part in ("", "1"):
        return
    for token in part.split("."):
        m = _FACTOR.match(token)
        if m is None:
            raise UnitError(f"cannot read unit factor {token!r}")
        root = m.group(2)
        symbol = root or m.group(1)
        if symbol not in _SYMBOLS:
            raise UnitError(f"unknown unit symbol {symbol!r}")
        power = Fraction(int(m.group(3) or 1), 2 if root else 1)
        yield symbol, power


def base_unit(unit: str) -> tuple[dict, float] | None:
    """SI exponents and factor of ``unit``: ``({"kg": 1, "m": 2}, 1.0)``.

    ``({}, 1.0)`` for the dimensionless ``"1"``; None if an exponent is not an integer (FMI 2.0
    cannot state it).  Raises :class:`UnitError` for a spelling it cannot read.
    """
    unit = normalise(unit)
    num, _, den = unit.partition("/")
    if "/" in den:
        raise UnitError(f"unit {unit!r}: at most one '/'")
    exps: dict = {}
    factor = 1.0
    for sign, part in ((1, num), (-1, den)):
        for symbol, power in _factors(part):
            f, dims = _SYMBOLS[symbol]
            factor *= f ** float(sign * power)
            for b, e in dims.items():
                exps[b] = exps.get(b, 0) + sign * power * e
    exps = {b: e for b, e in exps.items() if e != 0}
    if any(e.denominator != 1 for e in exps.values()):
        return None
    return {b: int(exps[b]) for b in BASE if b in exps}, factor


def unit_definitions(units) -> ET.Element:
    """``<UnitDefinitions>`` of the unit names ``units`` (SI exponents: :func:`base_unit`)."""
    defs = ET.Element("UnitDefinitions")
    for name in sorted(units):
        unit = ET.SubElement(defs, "Unit", {"name": name})
        base = base_unit(name)
        if base is not None:
            exps, factor = base
            attrs_ = {b: str(e) for b, e in exps.items()}
            if factor != 1.0:
                attrs_["factor"] = repr(factor)
            ET.SubElement(unit, "BaseUnit", attrs_)
    return defs


def units_into_model_description(root: ET.Element) -> set:
    """Give every Real variable the unit its description ends with (``"... [m/s]"``) and
    declare the units in ``<UnitDefinitions>``; return the unit names.

    The bracket is where the one definition of a unit (``models.params.param`` for parameters,
    the FMU class for inputs and outputs) reaches the model description; pythonfmu has no unit
    attribute.  FMI 2.0 gives only Real variables a ``unit``.
    """
    units = set()
    for sv in root.iter("ScalarVariable"):
        unit = unit_of_description(sv.get("description"))
        kind = sv[0]
        if unit is not None and kind.tag == "Real":
            kind.set("unit", unit)
            units.add(unit)
    old = root.find("UnitDefinitions")
    if old is not None:
        root.remove(old)
    if units:
        children = list(root)
        at = max((k + 1 for k, c in enumerate(children)
                  if c.tag in ("ModelExchange", "CoSimulation")), default=0)
        root.insert(at, unit_definitions(units))
    return units
