"""Small helpers shared by every pythonfmu slave of descent-fmus.

Each plant or controller FMU is a :class:`pythonfmu.Fmi2Slave` subclass that lives beside the
equations it wraps (``models/<system>.py``).  This module keeps the repetitive FMI variable
registration in one place so that the FMU classes read like a table of their interface:

* parameters (causality ``parameter``, variability ``fixed``) with their SI unit in the description
  (pythonfmu has no unit attribute);
* inputs (continuous Reals, start value required);
* outputs (``initial=exact`` so that ``fmpy validate`` accepts them; Integer outputs are
  ``discrete`` as FMI 2.0 requires).

Parameter checks run in ``exit_initialization_mode``; a failed check raises
:class:`ParameterError`, which pythonfmu reports through the FMU logger and turns into
``fmi2Error`` -- the host sees a message naming the parameter, never a NaN trajectory.
"""
from __future__ import annotations

import json
import math
import os

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Initial

__all__ = ["ParameterError", "SlaveBase", "require_finite", "require_positive"]


class ParameterError(ValueError):
    """A parameter of an FMU (or of an in-process model) is out of its valid range."""


def require_finite(name: str, value: float) -> float:
    """Return ``float(value)`` or raise :class:`ParameterError` if it is NaN or infinite."""
    value = float(value)
    if not math.isfinite(value):
        raise ParameterError(f"parameter {name} must be finite, got {value!r}")
    return value


def require_positive(name: str, value: float) -> float:
    """Return ``float(value)`` or raise :class:`ParameterError` unless it is finite and > 0."""
    value = require_finite(name, value)
    if value <= 0.0:
        raise ParameterError(f"parameter {name} must be > 0, got {value!r}")
    return value


class SlaveBase(Fmi2Slave):
    """Registration helpers; subclasses implement ``do_step`` and optionally ``check_parameters``.

    Values live in plain instance attributes (floats and lists of floats): the FMI getters and
    setters are closures over them, and ``do_step`` works on plain Python floats, which is
    several times faster than NumPy for state vectors of a handful of elements.
    """

    author = "descent-fmus developers"
    license = "MIT"

    # -- registration -----------------------------------------------------------------------
    def _register(self, var) -> None:
        self.register_variable(var)

    def parameter(self, name: str, start: float, description: str) -> None:
        """A Real parameter stored in attribute ``name`` (start value = current default)."""
        setattr(self, name, float(start))
        self._register(Real(name, causality=Fmi2Causality.parameter,
                            variability=Fmi2Variability.fixed, description=description,
                            getter=lambda n=name: getattr(self, n),
                            setter=lambda v, n=name: setattr(self, n, v)))

    def int_parameter(self, name: str, start: int, description: str) -> None:
        setattr(self, name, int(start))
        self._register(Integer(name, causality=Fmi2Causality.parameter,
                               variability=Fmi2Variability.fixed, description=description,
                               getter=lambda n=name: getattr(self, n),
                               setter=lambda v, n=name: setattr(self, n, int(v))))

    def input(self, name: str, start: float, description: str, setter=None) -> None:
        setattr(self, name, float(start))
        self._register(Real(name, causality=Fmi2Causality.input,
                            variability=Fmi2Variability.continuous, description=description,
                            getter=lambda n=name: getattr(self, n),
                            setter=setter or (lambda v, n=name: setattr(self, n, v))))

    def output(self, name: str, description: str, getter=None, start: float = 0.0) -> None:
        if getter is None:
            setattr(self, name, float(start))
            getter = lambda n=name: getattr(self, n)  # noqa: E731
        self._register(Real(name, causality=Fmi2Causality.output,
                            variability=Fmi2Variability.continuous, initial=Fmi2Initial.exact,
                            description=description, getter=getter))

    def int_output(self, name: str, description: str, getter=None, start: int = 0) -> None:
        if getter is None:
            setattr(self, name, int(start))
            getter = lambda n=name: getattr(self, n)  # noqa: E731
        self._register(Integer(name, causality=Fmi2Causality.output,
                               variability=Fmi2Variability.discrete, initial=Fmi2Initial.exact,
                               description=description, getter=getter))

    def real_array(self, name: str, values: list, causality: Fmi2Causality, description: str,
                   setter_hook=None) -> None:
        """Register ``name[1..n]`` over the list ``values`` (modified in place by setters).

        ``setter_hook`` (optional) is called after every set, e.g. to mark a cache dirty.
        """
        for k in range(len(values)):
            def setter(v, k=k):
                values[k] = v
                if setter_hook is not None:
                    setter_hook()
            kw = {}
            if causality == Fmi2Causality.parameter:
                kw["variability"] = Fmi2Variability.fixed
            elif causality == Fmi2Causality.input:
                kw["variability"] = Fmi2Variability.continuous
            self._register(Real(f"{name}[{k + 1}]", causality=causality, description=description,
                                getter=lambda k=k: values[k], setter=setter, **kw))

    # -- defaults carried by an exported FMU ------------------------------------------------
    DEFAULTS_FILE = "defaults.json"

    def apply_resource_defaults(self) -> None:
        """Apply ``resources/defaults.json`` ({variable name: value}) if the FMU carries one.

        ``synthesis.export`` writes it (and the same values as XML start values) when a law or a
        scenario is exported, so an exported FMU *is* the generic FMU with other defaults.
        """
        if not self.resources:
            return
        path = os.path.join(self.resources, self.DEFAULTS_FILE)
        if not os.path.exists(path):
            return
        with open(path, encoding="utf-8") as fh:
            values = json.load(fh)
        by_name = {v.name: v for v in self.vars.values()}
        for name, value in values.items():
            by_name[name].setter(value)

    # -- life cycle -------------------------------------------------------------------------
    def check_parameters(self) -> None:
        """Validate parameters; raise :class:`ParameterError` with an actionable message."""

    def prepare(self) -> None:
        """Derive run constants and the initial state from the (validated) parameters."""

    def exit_initialization_mode(self) -> None:
        try:
            self.check_parameters()
        except ParameterError as exc:
            self.log(f"{type(self).__name__}: {exc}", status=3, category="logStatusError")
            raise
        self.prepare()
