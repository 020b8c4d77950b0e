"""S1 sensing: an on-board estimate of the drag-model factor from the sensed drag acceleration.

The accelerometers of a capsule measure its non-gravitational acceleration, here the drag
``a = (1+u) S rho0/m v^2 exp(-lam h)`` (the Reentry plant publishes it as ``aero_load``, in g).
The guidance knows the nominal model (:class:`models.reentry.ReentryParams` defaults), its own
control ``u`` and the navigated state; the ratio of the sensed drag to the nominal model's drag at
that state and control is exactly the factor ``(rho0/m) / (rho0/m)_nominal`` that a density or
mass error changes -- from the first samples of sensible drag on.  The estimate is its logarithm

    y3 = sum_k w_k ln(a_sensed,k / a_nominal,k) / sum_k w_k,    w_k = a_nominal,k^2,

over the samples whose nominal drag exceeds ``threshold`` (in g); 0 (the nominal model) before
the first one.  The weights make it the minimum-variance mean under additive accelerometer noise
(the log-ratio's noise is about sigma / a); the factor is constant in this model, so every
sample is kept.  Optional seeded accelerometer errors (``noise``: white noise of that standard
deviation, ``bias``: a constant offset, both in m/s2; default off) show how it degrades.

The estimator never reads the plant's true parameters.  Three FMUs use this one class:

* :class:`DragEstimator` -- the estimator alone (inputs ``a_drag``, ``nav_x1..nav_x4``, ``u``;
  output ``drag_factor_log`` = y3), for other guidance and tests;
* :class:`SensedNetworkOperatorController` -- the generic network-operator law whose input
  ``x[estimate_input]`` (default 3) is the estimate: ``u = phi(y1, y2, y3, q)`` in one FMU;
* ``models.controllers.reentry_npc.ReentryNPC`` -- the numerical predictor-corrector guidance.

Timing convention (the closed loops of this project, Gauss-Seidel): at the communication point
t_k the plant's ``aero_load`` is the value at the end of the step just taken, i.e. with the
control ``u_{k-1}`` applied over that step (``u = 0`` at t = 0).  The sample at t_k therefore
divides by the nominal drag with ``u_{k-1}``; it is committed when the step from t_k starts
(``commit(u_k)``), and the estimate read at t_k already includes it.
"""
from __future__ import annotations

import math
import random
from dataclasses import dataclass

from descent_fmus.models.controllers.network_operator import NX_MAX, NetworkOperatorController
from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.params import ParameterError, Params, param
from descent_fmus.models.reentry import ReentryParams, loads

__all__ = ["DragEstimatorParams", "DragFactorEstimator", "DragEstimator",
           "SensedNetworkOperatorController", "NAV_INPUTS"]

#: Names of the navigated-state inputs (the plant's x1..x4) of the FMUs using the estimator.
NAV_INPUTS = ("nav_x1", "nav_x2", "nav_x3", "nav_x4")


@dataclass(frozen=True)
class DragEstimatorParams(Params):
    """Parameters of the drag-factor estimator (the sensing block)."""

    threshold: float = param(0.005, "1", "nominal-model drag [g] above which a sample enters "
                             "the estimate", positive=True)
    noise: float = param(0.0, "m/s2", "standard deviation of the simulated accelerometer "
                         "white noise (0 = off)", nonnegative=True)
    bias: float = param(0.0, "m/s2", "simulated accelerometer bias (0 = off)")
    noise_seed: int = param(0, "1", "seed of the accelerometer noise")


class DragFactorEstimator:
    """The estimate y3 = filtered ln(sensed drag / nominal-model drag); see the module docstring.

    Parameters
    ----------
    params : DragEstimatorParams
    model : ReentryParams
        The nominal model the guidance believes (default: the default scenario's values).
    """

    def __init__(self, params: DragEstimatorParams = DragEstimatorParams(),
                 model: ReentryParams = ReentryParams()):
        self.params = params.validate()
        self.model = model
        self.kd = model.constants()[1]           # S rho0 / m of the nominal model
        self._rng = random.Random(params.noise_seed)
        self.u_prev = 0.0                        # control applied over the step just taken
        self.sw = self.swz = 0.0
        self.samples = 0
        self._last_x = None
        self._draw()

    def _draw(self) -> None:
        p = self.params
        self._err = p.bias + (self._rng.gauss(0.0, p.noise) if p.noise > 0.0 else 0.0)

    def nominal_drag(self, x, u: float) -> float:
        """Drag acceleration [m/s2] of the nominal model at state ``x`` with control ``u``."""
        m = self.model
        return loads(x, (0.0,) * 4, self.kd, m.lam, m.Rz, m.g0, u)[1] * m.g0

    def _sample(self, a_drag_g: float, x):
        """``(weight, log-ratio)`` of the current sample, or None if it does not count."""
        if x == self._last_x:                # the plant froze (landed): nothing new
            return None
        try:
            a_nom = self.nominal_drag(x, self.u_prev)
        except (ArithmeticError, ValueError):        # not a state of the flight (e.g. zeros)
            return None
        if not a_nom >= self.params.threshold * self.model.g0:
            return None
        a_meas = a_drag_g * self.model.g0 + self._err
        if not (a_meas > 0.0 and math.isfinite(a_meas)):
            return None
        return a_nom * a_nom, math.log(a_meas / a_nom)

    def estimate(self, a_drag_g: float, x) -> float:
        """y3 including the current sample (``a_drag_g`` [g], navigated state ``x``); no state
        change -- the value read at a communication point."""
        s = self._sample(a_drag_g, tuple(x))
        sw, swz = self.sw, self.swz
        if s is not None:
            sw, swz = sw + s[0], swz + s[0] * s[1]
        return swz / sw if sw > 0.0 else 0.0

    def commit(self, a_drag_g: float, x, u_next: float) -> None:
        """Add the current sample for good; ``u_next`` is the control applied over the coming
        step (the next sample divides by the nominal drag with it)."""
        x = tuple(x)
        s = self._sample(a_drag_g, x)
        if s is not None:
            self.sw += s[0]
            self.swz += s[0] * s[1]
            self.samples += 1
        self._last_x = x
        self.u_prev = u_next
        self._draw()


class _EstimatorInputs:
    """The FMU interface shared by the FMUs that carry a :class:`DragFactorEstimator`: the
    sensing parameters, the inputs ``a_drag`` and ``nav_x1..nav_x4``, the output
    ``drag_factor_log``."""

    #: the estimator the FMU carries (a subclass of DragFactorEstimator)
    estimator_class = DragFactorEstimator

    def register_estimator(self, on_input=None) -> None:
        self.parameters()                                    # DragEstimatorParams fields
        self.input("a_drag", 0.0, "sensed drag acceleration / g0 (the plant's aero_load) [1]",
                   setter=self._setter("a_drag", on_input))
        for k, name in enumerate(NAV_INPUTS):
            self.input(name, 0.0, f"navigated state x{k + 1} (the plant's x{k + 1}) "
                       f"[{'m' if k % 2 == 0 else 'm/s'}]", setter=self._setter(name, on_input))
        self.output("drag_factor_log", "estimate y3 = ln(drag factor / nominal) [1]",
                    getter=self.current_estimate)
        self.output("drag_factor", "estimated drag factor (rho0/m) / nominal [1]",
                    getter=lambda: math.exp(self.current_estimate()))
        if hasattr(self.estimator_class, "profile"):          # the density-profile fit
            self.output("scale_height_error", "estimated relative error of the model's density "
                        "scale height, lam_nominal / lam_estimated - 1 [1]",
                        getter=lambda: self.estimator().model.lam / self._profile().lam - 1.0)
            self.output("drag_factor_sd", "standard deviation of drag_factor_log [1]",
                        getter=lambda: self._profile().log_factor_sd)
        self._estimator = None

    def _setter(self, name, hook):
        def set_(v):
            setattr(self, name, v)
            if hook is not None:
                hook()
        return set_

    def estimator(self) -> DragFactorEstimator:
        if self._estimator is None:
            self._estimator = self.estimator_class(self.params())
        return self._estimator

    def nav_state(self) -> tuple:
        return (self.nav_x1, self.nav_x2, self.nav_x3, self.nav_x4)

    def _profile(self):
        return self.estimator().profile(self.a_drag, self.nav_state())

    def current_estimate(self) -> float:
        return self.estimator().estimate(self.a_drag, self.nav_state())

    def commit_sample(self, u_next: float) -> None:
        self.estimator().commit(self.a_drag, self.nav_state(), u_next)


class DragEstimator(_EstimatorInputs, SlaveBase):
    """FMU of the drag-factor estimator alone.

    Inputs: ``a_drag`` (sensed drag / g0), the navigated state ``nav_x1..nav_x4`` and ``u``, the
    control applied over the coming step; output ``drag_factor_log`` (y3) and ``drag_factor``.
    """

    params_class = DragEstimatorParams
    description = ("S1 sensing: estimate of the drag-model factor ln((rho0/m)/nominal) from the "
                   "sensed drag acceleration and the nominal model")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.register_estimator()
        self.input("u", 0.0, "control applied over the coming step [1]")
        self.apply_resource_defaults()

    def prepare(self) -> None:
        self._estimator = self.estimator_class(self.params())

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.commit_sample(self.u)
        return True


class SensedNetworkOperatorController(_EstimatorInputs, NetworkOperatorController):
    """The generic network-operator law reading the drag-factor estimate: one controller FMU
    that contains the estimate.

    Everything of :class:`NetworkOperatorController` (matrix, q, bounds, scaling), plus the
    estimator's inputs and parameters: the law's input ``x[estimate_input]`` (default 3; 0 = none)
    is not read from outside but set to y3 before the law is evaluated, so a law
    ``u = phi(y1, y2, y3, q)`` is wired as plant ``y1 -> x[1]``, ``y2 -> x[2]``,
    ``aero_load -> a_drag``, ``x1..x4 -> nav_x1..nav_x4``.  Output ``u[1]`` is the control the
    estimator divides by (``out[1]`` is the applied control).
    """

    params_class = DragEstimatorParams
    description = ("Network-operator control law reading the drag-factor estimate y3 "
                   "(estimator inside): u = phi(y1, y2, y3, q)")

    def __init__(self, **kwargs):
        self._registered = False
        super().__init__(**kwargs)       # the law's variables (its defaults wait, see below)
        self.register_estimator(on_input=self._touch)
        self.int_parameter("estimate_input", 3, "law input receiving the estimate y3 "
                           "(0 = none) [1]")
        self._registered = True
        self.apply_resource_defaults()
        self.check_parameters()
        self.prepare()

    def apply_resource_defaults(self) -> None:
        # the generic controller applies an exported FMU's defaults at the end of its own
        # registration; here they may name the estimator's variables too: apply them once all
        # variables exist
        if self._registered:
            super().apply_resource_defaults()

    def check_parameters(self) -> None:
        super().check_parameters()
        if self._registered:
            self.params().validate()
            if not 0 <= self.estimate_input <= NX_MAX:
                raise ParameterError(f"estimate_input = {self.estimate_input} outside "
                                     f"0..{NX_MAX}")

    def prepare(self) -> None:
        super().prepare()
        if self._registered:
            self._estimator = self.estimator_class(self.params())

    def _outputs(self):
        if self._dirty and self._registered and self.estimate_input:
            self.x[self.estimate_input - 1] = self.current_estimate()
        return super()._outputs()

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.commit_sample(self._outputs()[0])
        return super().do_step(current_time, step_size)

