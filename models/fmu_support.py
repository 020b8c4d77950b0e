"""Small helpers shared by every pythonfmu slave of descent-fmus.

Each plant or controller FMU is a :class:`pythonfmu.Fmi2Slave` subclass that lives beside the
equations it wraps (``models/<system>.py``).  This module keeps the repetitive FMI variable
registration in one place so that the FMU classes read like a table of their interface:

* parameters (causality ``parameter``, variability ``fixed``) taken from the model's parameter
  dataclass (:mod:`models.params`: default, unit and description written once), the unit in
  brackets in the description (pythonfmu has no unit attribute; the build adds the attribute);
* inputs (continuous Reals, start value required);
* outputs (``initial=exact`` so that ``fmpy validate`` accepts them; Integer outputs are
  ``discrete`` as FMI 2.0 requires);
* the plant status convention: every plant publishes the Integer ``status``
  (:data:`models.integrators.STATUS_DESCRIPTION`) and the Real ``t_end``
  (:meth:`SlaveBase.status_outputs`);
* sampled controllers: every controller (``models/controllers/``) has the parameter
  ``sample_period``; with a value > 0 it acts once per period and holds its outputs in between,
  so that a master may step finer than the controller samples (``_sampling_step``).

Parameter checks run in ``exit_initialization_mode``; a failed check raises
:class:`ParameterError` with a message naming the parameter (never a NaN trajectory).  pythonfmu
0.7 logs it with status fmi2Error and returns fmi2Fatal (its C++ layer turns every Python
exception into fmi2Fatal and forwards log messages only when the host instantiated the FMU with
``loggingOn``: ``fmpy simulate --debug-logging`` shows the message); the build's status wrapper
(``synthesis.fmi.compose.add_status_wrapper``) makes that fmi2Error.  A container FMU reports a
failing component as fmi2Error.
"""
from __future__ import annotations

import json
import os
from collections import OrderedDict
from dataclasses import fields

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Initial

from descent_fmus.models.integrators import STATUS_DESCRIPTION, T_END_DESCRIPTION
from descent_fmus.models.params import (ParameterError, description_of, require_finite,
                                        require_positive)
from descent_fmus.models.pythonfmu_compat import GUARDED_METHODS, keep_refs_on_error

__all__ = ["ParameterError", "SlaveBase", "require_finite", "require_positive",
           "SAMPLE_PERIOD_DESCRIPTION"]

_CONTROLLERS = "descent_fmus.models.controllers."
SAMPLE_PERIOD_DESCRIPTION = ("sample period of the controller: it reads its inputs and updates "
                             "its outputs once per period and holds them in between; 0 = at "
                             "every communication point [s]")


def _sampling_step(do_step):
    """``do_step`` of a sampled controller (:attr:`SlaveBase.sampled`).

    With ``sample_period = Ts > 0`` the controller acts at most once per ``Ts``: a communication
    step that ends less than ``Ts`` after the last sample holds the outputs and ignores the
    inputs; the first one that ends ``Ts`` or more after it runs the controller's own step over
    the whole interval since the last sample, and the controller is live again (it reads its
    inputs and computes its outputs).  A master stepping at ``Ts`` sees exactly the unsampled
    controller; one stepping at ``Ts / n`` sees the same controller sampled every ``n`` steps.
    """
    import functools

    @functools.wraps(do_step)
    def step(self, current_time: float, step_size: float) -> bool:
        if self._held is None:                 # sample_period = 0: every communication point
            return do_step(self, current_time, step_size)
        if self._sample_t is None:
            self._sample_t = current_time
        if not self._holding:                  # leaving a sample: hold the outputs
            self._hold()
        t1 = current_time + step_size
        elapsed = t1 - self._sample_t
        if elapsed < self.sample_period * (1.0 - 1e-9):
            return True
        if self._sample_t == current_time:     # one communication step: exactly as given
            ok = do_step(self, current_time, step_size)
        else:
            ok = do_step(self, self._sample_t, elapsed)
        self._sample_t = t1
        self._holding = False
        return ok

    return step


def _template(var) -> dict:
    return {k: v for k, v in var.__dict__.items() if k not in ("getter", "setter")}


def _clone(cls, template, getter, setter):
    var = cls.__new__(cls)
    d = dict(template)
    d["getter"], d["setter"] = getter, setter
    var.__dict__ = d
    return var


class _LazyVars(OrderedDict):
    """pythonfmu's variable table (value reference -> variable) with lazily built ranges."""

    def __init__(self):
        super().__init__()
        self.size = 0            # number of value references handed out
        self.ranges = []         # (first vr, count, make(k) -> variable)

    def add(self, vr, var):
        self[vr] = var
        self.size += 1

    def add_range(self, vr0, count, make):
        self.ranges.append((vr0, count, make))
        self.size += count

    def __missing__(self, vr):
        for vr0, count, make in self.ranges:
            if vr0 <= vr < vr0 + count:
                var = self[vr] = make(vr - vr0)
                return var
        raise KeyError(vr)

    def materialise(self):
        """Build every lazy variable (needed before iterating over all variables)."""
        for vr0, count, _ in self.ranges:
            for vr in range(vr0, vr0 + count):
                if vr not in self:
                    self.__missing__(vr)
        self.ranges = []
        for vr in sorted(self):   # restore value-reference order for iteration
            self.move_to_end(vr)


class SlaveBase(Fmi2Slave):
    """Registration helpers; subclasses implement ``do_step`` and optionally ``check_parameters``.

    Values live in plain instance attributes (floats and lists of floats): the FMI getters and
    setters are closures over them, and ``do_step`` works on plain Python floats, which is
    several times faster than NumPy for state vectors of a handful of elements.
    """

    author = "descent-fmus developers"
    license = "MIT"

    # -- registration -----------------------------------------------------------------------
    # pythonfmu re-creates the slave object on every fmi2Reset, so registration cost is paid
    # per closed-loop run.  The first instance of a class in a process builds every variable
    # with pythonfmu's constructors (that instance also writes modelDescription.xml at build
    # time); later instances clone the recorded attribute dictionaries and bind new closures,
    # and large blocks (var_block) are materialised only when a value reference is touched.
    _prototypes: dict = {}

    #: A sampled controller gets the parameter ``sample_period`` (see :meth:`_sampling_step`).
    #: None = decided by the module: every FMU class under ``models/controllers/`` is sampled.
    sampled: bool | None = None

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.vars = _LazyVars()
        self._io = []               # (variable, causality, getter, setter) of inputs and outputs
        self._held = None           # output values held between samples (None: unsampled)
        self._holding = False       # between two samples
        self._sample_t = None       # time of the last sample [s]
        if self.sampled:
            self.parameter("sample_period", 0.0, SAMPLE_PERIOD_DESCRIPTION)

    def _var(self, cls, name, getter, setter=None, **kw) -> None:
        if self.sampled and kw.get("causality") in (Fmi2Causality.input, Fmi2Causality.output):
            self._io.append((name, kw["causality"], getter, setter))
        proto = SlaveBase._prototypes.get((type(self), name))
        vr = self.vars.size
        if proto is not None and proto[1] == vr:
            self.vars.add(vr, _clone(cls, proto[0], getter, setter))
            return
        self.vars.materialise()
        var = cls(name, getter=getter, setter=setter, **kw)
        self.register_variable(var)
        self.vars.size += 1
        SlaveBase._prototypes[(type(self), name)] = (_template(var), vr)

    def var_block(self, cls, names, getter_of, setter_of, **kw) -> None:
        """Register ``names[k]`` with ``getter_of(k)`` / ``setter_of(k)`` (closures made lazily).

        For blocks of hundreds of parameters (the network operator's matrix) of which a run
        touches only a few.
        """
        key = (type(self), "block", names[0], len(names))
        proto = SlaveBase._prototypes.get(key)
        vr0 = self.vars.size
        if proto is not None and proto[1] == vr0:
            templates = proto[0]
            self.vars.add_range(vr0, len(names), lambda k: _clone(cls, templates[k], getter_of(k),
                                                                   setter_of(k)))
            return
        for k, name in enumerate(names):
            self._var(cls, name, getter_of(k), setter_of(k), **kw)
        SlaveBase._prototypes[key] = ([SlaveBase._prototypes[(type(self), n)][0] for n in names],
                                      vr0)

    def parameter(self, name: str, start: float, description: str) -> None:
        """A Real parameter stored in attribute ``name`` (start value = current default)."""
        setattr(self, name, float(start))
        self._var(Real, name, lambda n=name: getattr(self, n),
                  lambda v, n=name: setattr(self, n, v), causality=Fmi2Causality.parameter,
                  variability=Fmi2Variability.fixed, description=description)

    def parameters(self, names=None) -> None:
        """Parameters from the fields of :attr:`params_class` (all, or ``names``): Integer for
        int fields, Real otherwise.

        Default, unit and description come from the dataclass (:func:`models.params.param`).
        """
        cls = self.params_class
        defaults = cls()
        for name in names or [f.name for f in fields(cls)]:
            value = getattr(defaults, name)
            if isinstance(value, int) and not isinstance(value, bool):
                self.int_parameter(name, value, description_of(cls, name))
            else:
                self.parameter(name, value, description_of(cls, name))

    def status_outputs(self, status, t_end) -> None:
        """The plant status convention: Integer ``status`` and Real ``t_end`` (getters)."""
        self.int_output("status", STATUS_DESCRIPTION, getter=status)
        self.output("t_end", T_END_DESCRIPTION, getter=t_end)

    def int_parameter(self, name: str, start: int, description: str, getter=None,
                      setter=None) -> None:
        """An Integer parameter (attribute ``name`` unless a getter/setter pair is given)."""
        if getter is None:
            setattr(self, name, int(start))
            getter = lambda n=name: getattr(self, n)  # noqa: E731
            setter = lambda v, n=name: setattr(self, n, int(v))  # noqa: E731
        self._var(Integer, name, getter, setter, causality=Fmi2Causality.parameter,
                  variability=Fmi2Variability.fixed, description=description)

    def input(self, name: str, start: float, description: str, setter=None) -> None:
        setattr(self, name, float(start))
        self._var(Real, name, lambda n=name: getattr(self, n),
                  setter or (lambda v, n=name: setattr(self, n, v)),
                  causality=Fmi2Causality.input, variability=Fmi2Variability.continuous,
                  description=description)

    def output(self, name: str, description: str, getter=None, start: float = 0.0) -> None:
        if getter is None:
            setattr(self, name, float(start))
            getter = lambda n=name: getattr(self, n)  # noqa: E731
        self._var(Real, name, getter, causality=Fmi2Causality.output,
                  variability=Fmi2Variability.continuous, initial=Fmi2Initial.exact,
                  description=description)

    def int_output(self, name: str, description: str, getter=None, start: int = 0) -> None:
        if getter is None:
            setattr(self, name, int(start))
            getter = lambda n=name: getattr(self, n)  # noqa: E731
        self._var(Integer, name, getter, causality=Fmi2Causality.output,
                  variability=Fmi2Variability.discrete, initial=Fmi2Initial.exact,
                  description=description)

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
            self._var(Real, f"{name}[{k + 1}]", lambda k=k: values[k], setter,
                      causality=causality, description=description, **kw)

    # -- defaults carried by an exported FMU ------------------------------------------------
    DEFAULTS_FILE = "defaults.json"

    def apply_resource_defaults(self) -> None:
        """Apply ``resources/defaults.json`` ({variable name: value}) if the FMU carries one.

        ``synthesis.fmi.compose`` writes it (and the same values as XML start values) when a law or a
        scenario is exported, so an exported FMU *is* the generic FMU with other defaults.
        """
        if not self.resources:
            return
        path = os.path.join(self.resources, self.DEFAULTS_FILE)
        if not os.path.exists(path):
            return
        with open(path, encoding="utf-8") as fh:
            values = json.load(fh)
        self.vars.materialise()
        by_name = {v.name: v for v in self.vars.values()}
        for name, value in values.items():
            by_name[name].setter(value)

    def __init_subclass__(cls, **kwargs):
        # pythonfmu 0.7 crashes the host after a callback raised unless the references are
        # balanced (models/pythonfmu_compat.py): guard every callback of every FMU class.
        super().__init_subclass__(**kwargs)
        if "sampled" not in cls.__dict__ and cls.sampled is None:
            cls.sampled = cls.__module__.startswith(_CONTROLLERS)
        if cls.sampled and "do_step" in cls.__dict__:
            cls.do_step = _sampling_step(cls.__dict__["do_step"])
        for name in GUARDED_METHODS:
            if name in cls.__dict__:
                setattr(cls, name, keep_refs_on_error(cls.__dict__[name]))

    # -- life cycle -------------------------------------------------------------------------
    #: dataclass of the model's parameters (stored in attributes of the same names), if any;
    #: it must have a ``validate()`` method raising ParameterError
    params_class = None

    def params(self):
        """The current parameter values as an instance of :attr:`params_class`."""
        return self.params_class(**{f.name: getattr(self, f.name)
                                    for f in fields(self.params_class)})

    def check_parameters(self) -> None:
        """Validate parameters; raise :class:`ParameterError` with an actionable message.

        Default: ``params().validate()`` and a positive integration step ``dt`` if the FMU has
        one; subclasses add their own checks after calling this.
        """
        if self.params_class is not None:
            self.params().validate()
        if hasattr(self, "dt"):
            require_positive("dt", self.dt)

    def enter_initialization_mode(self) -> None:
        # The start values are set by now: prepare with them so that outputs read during
        # initialisation (a container FMU propagates its connections then) already show them.
        # Invalid values are reported at exit_initialization_mode.
        try:
            self.check_parameters()
        except ParameterError:
            return
        self.prepare()

    def prepare(self) -> None:
        """Derive run constants and the initial state from the (validated) parameters."""

    @keep_refs_on_error
    def exit_initialization_mode(self) -> None:
        try:
            self.check_parameters()
            if self.sampled:
                self._start_sampling()
        except ParameterError as exc:
            self.log(f"{type(self).__name__}: {exc}", status=3, category="logStatusError")
            raise
        self.prepare()

    # -- sampled controllers ----------------------------------------------------------------
    def _start_sampling(self) -> None:
        """With ``sample_period > 0``: hold outputs and ignore inputs between samples."""
        period = require_finite("sample_period", self.sample_period)
        if period < 0.0:
            raise ParameterError(f"parameter sample_period must be >= 0, got {period!r}")
        if period == 0.0 or self._held is not None:
            return
        self._held = held = {}
        by_name = {v.name: v for v in self.vars.values()}
        for name, causality, getter, setter in self._io:
            var = by_name[name]
            if causality == Fmi2Causality.output:
                var.getter = lambda n=name, g=getter: held[n] if self._holding else g()
            elif setter is not None:
                var.setter = lambda v, s=setter: None if self._holding else s(v)

    def _hold(self) -> None:
        """Freeze the outputs at their values now (the last sample) until the next sample."""
        for name, causality, getter, _ in self._io:
            if causality == Fmi2Causality.output:
                self._held[name] = getter()
        self._holding = True
