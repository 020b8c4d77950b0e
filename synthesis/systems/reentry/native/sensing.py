"""S1's drag-factor estimator in C, traced from its one Python definition.

The estimator (:class:`models.controllers.drag_estimator.DragFactorEstimator`) is run here on
traced values by the plant generator's tracer (:mod:`.plant_trace`, :mod:`.plant_codegen`),
so its C computes what Python computes, operation for operation and branch for branch.  Five C
functions of ``<prefix>_sensing.c`` (``in``: values the C model passes, ``st``: the estimator's
state, ``r``/``iv``: the FMU's Reals and Integers):

* ``<prefix>_check(r, iv, msg)`` -- ``params().validate()``: the ParameterError's message;
* ``<prefix>_nominal(in, out)`` -- ``nominal_drag(x, u)`` (the reentry model's ``loads``): the
  nominal-model drag, or PC_ERROR where Python raises (the estimator then skips the sample);
* ``<prefix>_draw(r, iv, in, out)`` -- ``_draw()``: the accelerometer error of the next sample
  from the Gaussian draw ``in[0]`` (the C model draws it with CPython's generator,
  ``c/py_random.h``, only where Python does: ``noise > 0``);
* ``<prefix>_estimate(r, iv, st, in, out)`` -- the FMU's ``drag_factor_log`` and
  ``drag_factor`` (``estimate`` with the current sample);
* ``<prefix>_commit(r, iv, st, in)`` -- ``commit(a_drag, x, u_next)``: the new state;
* ``<prefix>_profile(r, iv, st, in, out)`` -- only for the density-profile fit
  (:class:`~models.controllers.density_profile.ProfileEstimator`): ``profile(a_drag, x)``'s
  ``kd``, ``lam`` and ``log_factor`` (what the guidance predicts with).

The profile fit's state adds its nine sums to the constant-factor estimator's (:func:`state_names`)
and its ``estimate`` also gives the FMU's outputs ``scale_height_error`` and ``drag_factor_sd``.

The nominal drag of a sample is computed first (``in``: ``fail``, ``a_nom``); inside the traced
``estimate`` and ``commit`` a failed nominal raises where ``nominal_drag`` would, and the
estimator's own ``try`` catches it, as in Python.
"""
from __future__ import annotations

from types import SimpleNamespace

from descent_fmus.models.controllers.drag_estimator import DragFactorEstimator
from descent_fmus.models.reentry import ReentryParams
from descent_fmus.synthesis.fmi.native.tracer.plant_calls import CALL_RENDERERS, Unit, using_unit
from descent_fmus.synthesis.fmi.native.tracer.plant_codegen import Scope, render_function
from descent_fmus.synthesis.fmi.native.tracer.plant_phases import _INTERCEPTORS, PlantCode
from descent_fmus.synthesis.fmi.native.tracer.plant_shims import patched
from descent_fmus.synthesis.fmi.native.tracer.plant_trace import (Source, Tracer, check_python,
                                                           explore, operand)

__all__ = ["ST_NAMES", "state_names", "SensingCode", "sensing_sources"]

#: The estimator's state ``st`` (doubles): the weighted sums, the control of the last step, the
#: accelerometer error of the next sample, the last navigated state (NaN: none yet).
ST_NAMES = ("sw", "swz", "u_prev", "err", "last_x1", "last_x2", "last_x3", "last_x4")
#: ... and the profile fit's sums (ProfileEstimator.s) after them
PROFILE_ST = tuple(f"s{k + 1}" for k in range(9))
#: outputs of ``estimate`` beyond drag_factor_log and drag_factor, where the FMU has them
PROFILE_OUTPUTS = ("scale_height_error", "drag_factor_sd")

#: ``in`` of estimate/commit: the nominal drag failed (1) or not (0), its value, the control of
#: the coming step (commit)
IN_FAIL, IN_ANOM, IN_UNEXT = 0, 1, 2


def state_names(estimator_class) -> tuple:
    """The names of the state ``st`` of the estimator class's C (the profile fit: its sums
    after the constant-factor estimator's state)."""
    return ST_NAMES + (PROFILE_ST if hasattr(estimator_class, "profile") else ())


def _writes(space: str):
    """Leaf: ``space[k] = value`` for the ``(k, value)`` pairs, then PC_OK."""
    def leaf(value, scope, ind):
        return [f"{ind}{space}[{k}] = {scope.value(operand(v))};" for k, v in value] + \
            [f"{ind}return PC_OK;"]
    return leaf


class SensingCode:
    """The estimator of the FMU class ``cls`` (DragEstimator or a controller that carries one)
    traced into C (see the module docstring)."""

    def __init__(self, cls, prefix: str):
        check_python()
        # the FMU instance, its parameters and inputs traced; the seed only seeds the C
        # model's generator (its check, finite, holds for every Integer)
        self.code = PlantCode(cls, prefix, structural={"noise_seed": 0})
        self.prefix, self.unit = prefix, self.code.unit
        self.ST, self.IN = Source("st"), Source("in")
        self.estimator_class = cls.estimator_class
        self.profiled = len(state_names(self.estimator_class)) > len(ST_NAMES)

    # -- the traced estimator ------------------------------------------------------------------
    def _estimator(self, tracer) -> DragFactorEstimator:
        """An estimator on the traced state ``st`` and the FMU's traced parameters, built as
        its constructor builds it (without the generator: the C model draws)."""
        est = object.__new__(self.estimator_class)
        est.params = self.code.inst.params()
        est.model = ReentryParams()
        est.kd = est.model.constants()[1]
        st = self.ST
        est.sw, est.swz, est.u_prev, est._err = (st.sym(k) for k in range(4))
        est._last_x = tuple(st.sym(4 + k) for k in range(4))
        est.samples = 0
        if self.profiled:
            est._weights()
            est.s = [st.sym(len(ST_NAMES) + k) for k in range(len(PROFILE_ST))]
        fail, a_nom = self.IN.sym(IN_FAIL), self.IN.sym(IN_ANOM)

        def nominal(x, u):          # computed before: raise where nominal_drag raised
            if fail:
                raise ArithmeticError("the nominal drag failed")
            return a_nom
        est.nominal_drag = nominal
        return est

    def _function(self, stem, signature, params, tracer, tree, leaf, sources) -> str:
        scope = Scope(tracer, sources=sources, allow_ctx=False)
        scope.call_renderers = CALL_RENDERERS          # advance_to, in the guidance's step
        name = f"{self.prefix}_{stem}"
        self.unit.functions.append((name, render_function(signature.replace("@NAME@", name),
                                                          tree, scope, leaf, params), False))
        return name

    def _fmu_sources(self) -> dict:
        return {self.code.R: "r", self.code.I: "iv", self.ST: "st", self.IN: "in"}

    # -- the functions -------------------------------------------------------------------------
    def trace_check(self) -> str:
        tracer = Tracer(f"{self.prefix} check")
        tree = explore(tracer, lambda: self.code.inst.params().validate() and [])
        return self._function("check", "int @NAME@(const double *r, const int *iv, char *msg)",
                              ("r", "iv", "msg"), tracer, tree, _writes("r"),
                              {self.code.R: "r", self.code.I: "iv"})

    def trace_nominal(self) -> str:
        tracer = Tracer(f"{self.prefix} nominal")
        est = object.__new__(DragFactorEstimator)
        est.model = ReentryParams()
        est.kd = est.model.constants()[1]
        x, u = tuple(self.IN.sym(k) for k in range(4)), self.IN.sym(4)
        tree = explore(tracer, lambda: [(0, est.nominal_drag(x, u))])
        return self._function("nominal", "int @NAME@(const double *in, double *out)",
                              ("in", "out"), tracer, tree, _writes("out"), {self.IN: "in"})

    def trace_draw(self) -> str:
        tracer = Tracer(f"{self.prefix} draw")

        def body():
            est = self._estimator(tracer)
            est._rng = SimpleNamespace(gauss=lambda mu, sigma: self.IN.sym(0))
            est._draw()
            return [(0, est._err)]
        tree = explore(tracer, body)
        return self._function("draw", "int @NAME@(const double *r, const int *iv, "
                              "const double *in, double *out)", ("r", "iv", "in", "out"),
                              tracer, tree, _writes("out"), self._fmu_sources())

    def trace_estimate(self) -> str:
        """The FMU's getters of ``drag_factor_log`` and ``drag_factor`` -> out[0], out[1]."""
        tracer = Tracer(f"{self.prefix} estimate")
        inst = self.code.inst
        getters = {v.name: v.getter for v in self.code.iface.of("output")}

        names = ("drag_factor_log", "drag_factor") + (PROFILE_OUTPUTS if self.profiled else ())

        def body():
            inst._estimator = self._estimator(tracer)
            return [(k, getters[name]()) for k, name in enumerate(names)]
        tree = explore(tracer, body)
        return self._function("estimate", "int @NAME@(const double *r, const int *iv, "
                              "const double *st, const double *in, double *out)",
                              ("r", "iv", "st", "in", "out"), tracer, tree, _writes("out"),
                              self._fmu_sources())

    def trace_commit(self) -> str:
        """``commit(a_drag, nav, u_next)`` of the FMU's estimator -> the new state in st (the
        next draw is the C model's)."""
        tracer = Tracer(f"{self.prefix} commit")
        inst = self.code.inst

        def body():
            est = inst._estimator = self._estimator(tracer)
            est._draw = lambda: None
            inst.commit_sample(self.IN.sym(IN_UNEXT))
            state = (est.sw, est.swz, est.u_prev, est._err) + tuple(est._last_x)
            return list(enumerate(state + (tuple(est.s) if self.profiled else ())))
        tree = explore(tracer, body)
        return self._function("commit", "int @NAME@(const double *r, const int *iv, double *st, "
                              "const double *in)", ("r", "iv", "st", "in"), tracer, tree,
                              _writes("st"), self._fmu_sources())

    def trace_profile(self) -> str:
        """``profile(a_drag, nav)`` of the FMU's estimator -> kd, lam, log_factor in out."""
        tracer = Tracer(f"{self.prefix} profile")
        inst = self.code.inst

        def body():
            prof = self._estimator(tracer).profile(inst.a_drag, inst.nav_state())
            return [(0, prof.kd), (1, prof.lam), (2, prof.log_factor)]
        tree = explore(tracer, body)
        return self._function("profile", "int @NAME@(const double *r, const int *iv, "
                              "const double *st, const double *in, double *out)",
                              ("r", "iv", "st", "in", "out"), tracer, tree, _writes("out"),
                              self._fmu_sources())

    def trace_all(self, more=()) -> "SensingCode":
        """Trace the estimator's functions, then the callables ``more`` (each given this
        object), in the same C unit."""
        traces = [self.trace_check, self.trace_nominal, self.trace_draw, self.trace_estimate,
                  self.trace_commit] + ([self.trace_profile] if self.profiled else [])
        with patched(_INTERCEPTORS), using_unit(self.unit):
            self.code._bind(self.code.inst)
            for trace in traces:
                trace()
            for trace in more:
                trace(self)
        return self


def sensing_sources(cls, prefix: str, more=()) -> dict:
    """``{"<prefix>_sensing.c": ..., "<prefix>_sensing.h": ...}`` of the estimator of the FMU
    class ``cls`` (its C names ``<prefix>_*``), with the functions the callables ``more``
    trace (each given the :class:`SensingCode`) in the same files."""
    code = SensingCode(cls, prefix).trace_all(more)
    code_names = state_names(code.estimator_class)
    P = prefix.upper()
    h = [f"/* {prefix}_sensing.h -- the drag-factor estimator of {cls.__name__}, generated by "
         f"descent-fmus from", " * models/controllers/drag_estimator.py "
         "(synthesis/systems/reentry/native/sensing.py); regenerate rather than edit. */",
         f"#ifndef DESCENT_SENSING_{P}_H", f"#define DESCENT_SENSING_{P}_H", "",
         f"#define {P}_N_ST {len(code_names)}  /* " + ", ".join(code_names) + " */", ""]
    h += [text.split("\n", 1)[0] + ";" for _, text, static in code.unit.functions
          if not static]
    c = [f"/* {prefix}_sensing.c -- generated by descent-fmus from the Python estimator; "
         f"regenerate rather than edit. */", "#include <math.h>", "#include <stdio.h>", "",
         '#include "plant_runtime.h"', f'#include "{prefix}_sensing.h"', ""]
    c += [text for _, text, _ in code.unit.functions]
    return {f"{prefix}_sensing.h": "\n".join(h + ["", "#endif", ""]),
            f"{prefix}_sensing.c": "\n".join(c)}
