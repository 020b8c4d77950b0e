"""S1 numerical predictor-corrector (NPC) guidance: the industry anchor for the synthesised laws.

Every guidance cycle the controller integrates the nominal model (:func:`models.reentry.rhs`,
the one definition of the equations) with the estimated drag factor (the
:class:`~models.controllers.drag_estimator.DragFactorEstimator` inside this FMU) from the
navigated state to the altitude hf, and solves for the constant control u in [-0.2, 0.2] whose
predicted down-range at hf is Lf (Brent's method, scipy, on the bracket the previous solution
and a bound give); if even a bound cannot null the predicted miss, u is that bound.
The control is held until the next cycle.

The prediction uses the plant's RK4 scheme (:func:`models.integrators.advance_to`) on a coarser
step ``dt_pred`` and locates h = hf inside the step, as the plant does.

References
----------
Predictor-corrector entry guidance (e.g. Lu, "Entry guidance: a unified method", J. Guidance,
Control, and Dynamics 37(3), 2014): predict the terminal condition by integrating the model
on board, correct the control parameter by a root search.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from descent_fmus.models.controllers.density_profile import ProfileEstimator, ProfileParams
from descent_fmus.models.controllers.drag_estimator import (SensedNetworkOperatorController,
                                                            _EstimatorInputs)
from descent_fmus.models.controllers.reentry_prediction import (gate_weight, predict_flight,
                                                                predict_range, predicted_inputs,
                                                                predicted_load, solve_control)
from descent_fmus.models.controllers.reentry_replan import PLAN_KNOTS, plan_value, replan
from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.controllers.network_operator import NX_MAX
from descent_fmus.models.params import ParameterError, param
from descent_fmus.models.reentry import ReentryParams, altitude

__all__ = ["NPCParams", "GuidedParams", "ReentryNPC", "GuidedNetworkOperatorController"]


@dataclass(frozen=True)
class NPCParams(ProfileParams):
    """Parameters of the NPC guidance (plus the density-profile estimator's)."""

    cycle: float = param(10.0, "s", "guidance period: the predicted miss is nulled every cycle",
                         positive=True)
    dt_pred: float = param(2.0, "s", "RK4 step of the on-board prediction", positive=True)
    tol: float = param(20.0, "m", "predicted-miss tolerance of the root search", positive=True)
    max_iter: int = param(20, "1", "iterations of the root search per cycle at most",
                          positive=True)


@dataclass(frozen=True)
class GuidedParams(NPCParams):
    """Parameters of the guided network-operator law (plus the NPC's and the estimator's)."""

    correction_max: float = param(0.4, "1", "bound of the on-board correction c: |c| <= this",
                                  positive=True)
    correction_gain: float = param(1.0, "1", "gain g of the correction added to the law's "
                                   "clipped output: u = clip(phi + g c)")
    h0_line: float = param(100_000.0, "m", "entry altitude of the straight line y1, y2 refer "
                           "to (the plant's h0)", positive=True)
    correction_gate: float = param(0.0, "1", "load gate G [g] of a braking correction: c > 0 "
                                   "enters with the weight (1 - n/G)^2 below the drag load n = G "
                                   "and not above it (0 = no gate)")
    replan: int = param(0, "1", "1: the correction is a plan over altitude re-solved every cycle "
                        "for the least predicted peak load at zero predicted miss; 0: one "
                        "number c")
    replan_iterations: int = param(1, "1", "linear-programming steps of the plan per cycle")
    replan_trust: float = param(0.1, "1", "trust region of a plan step: |change of a weight| "
                                "<= this", positive=True)
    replan_effort: float = param(0.02, "1", "cost of the plan's weights in the plan's objective "
                                 "[g per unit weight]")

    def check(self) -> None:
        super().check()
        if self.correction_gate < 0.0:
            raise ParameterError(f"parameter correction_gate must be >= 0 g (0 = no gate), got "
                                 f"{self.correction_gate}")
        if self.replan not in (0, 1):
            raise ParameterError(f"parameter replan must be 0 or 1, got {self.replan}")
        if self.replan_iterations < 0:
            raise ParameterError(f"parameter replan_iterations must be >= 0, got "
                                 f"{self.replan_iterations}")
        if self.replan_effort < 0.0:
            raise ParameterError(f"parameter replan_effort must be >= 0, got "
                                 f"{self.replan_effort}")


class _GuidanceCycle:
    """The guidance cycle of the NPC and the guided law: at a communication point t >= the next
    correction time, above hf, ``_correct(x)`` runs and the next time moves on by whole cycles.
    Needs ``_t``, ``_next``, ``_model`` and ``_correct``."""

    def _maybe_correct(self, x, cycle: float) -> None:
        if self._t >= self._next - 1e-9 and altitude(x, self._model.Rz) > self._model.hf:
            self._correct(x)
            self._next += cycle * max(1, math.ceil((self._t - self._next) / cycle + 1e-9))


class ReentryNPC(_EstimatorInputs, _GuidanceCycle, SlaveBase):
    """FMU of the NPC guidance.

    Inputs ``a_drag`` (the plant's aero_load) and the navigated state ``nav_x1..nav_x4``;
    outputs ``u`` (in [-0.2, 0.2], held over a cycle), ``predicted_miss`` [m] (predicted
    L(hf) - Lf at the last correction), ``drag_factor_log`` (the estimate y3), ``drag_factor``
    and ``predictions`` (predictions so far).  The nominal model is the default scenario's
    :class:`models.reentry.ReentryParams` (target hf, Lf).
    """

    params_class = NPCParams
    estimator_class = ProfileEstimator
    description = ("S1 numerical predictor-corrector guidance: every cycle, the constant u that "
                   "nulls the miss predicted with the nominal model and the estimated density "
                   "profile (factor and scale height)")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.register_estimator(on_input=self._touch)
        self.output("u", "control: relative change of drag, in [-0.2, 0.2] [1]",
                    getter=lambda: self._command()[0])
        self.output("predicted_miss", "predicted L(hf) - Lf at the last correction [m]",
                    getter=lambda: self._command()[1])
        self.int_output("predictions", "on-board predictions so far [1]",
                        getter=lambda: self._n_pred)
        self.apply_resource_defaults()
        self.prepare()

    def prepare(self) -> None:
        p = self.params()
        self._estimator = None
        self._model = ReentryParams()
        self._kd = self._model.constants()[1]
        self._t = 0.0
        self._next = 0.0
        self._u = 0.0
        self._miss = 0.0
        self._n_pred = 0
        self._fresh = False          # the command of this communication point is computed
        self._cycle = p.cycle

    def _touch(self):
        self._fresh = False

    def _command(self):
        if not self._fresh:
            self._fresh = True
            self._maybe_correct(self.nav_state(), self._cycle)
        return self._u, self._miss

    def _correct(self, x) -> None:
        prof = self.estimator().profile(self.a_drag, x)
        lf, dt = self._model.Lf, self.dt_pred

        def miss(u):
            return predict_range(x, u, prof.kd, self._model, dt, prof.lam) - lf

        self._u, self._miss, n = solve_control(miss, self._u, self.tol, self.max_iter)
        self._n_pred += n

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.commit_sample(self._command()[0])
        self._t = current_time + step_size
        self._fresh = False
        return True


class GuidedNetworkOperatorController(_GuidanceCycle, SensedNetworkOperatorController):
    """A network-operator law with an on-board predictor-corrector:
    ``u = clip(phi(y1, y2, y3, c, q) + g c)``.

    Everything of :class:`~models.controllers.drag_estimator.SensedNetworkOperatorController`
    (the law reads the drag-factor estimate y3 at ``x[estimate_input]``), plus the correction c:
    added with gain ``correction_gain`` g to the law's clipped output (then clipped again to the
    same bounds), and read by the law at ``x[correction_input]`` (default 4; 0, or an input the
    law does not have: not read).  With a load gate ``correction_gate`` G > 0 a braking c > 0
    enters with the weight of :func:`gate_weight` (none at drag loads above G), in the flight
    and in the prediction alike.  Every ``cycle`` seconds the controller predicts the flight to
    hf with the nominal model, the estimated drag factor and *this guidance itself* (y1, y2 of
    the predicted state, y3 held, c constant; RK4 steps of ``dt_pred``, the control held over
    each) and solves for the c in [-correction_max, correction_max] whose predicted down-range
    is Lf (:func:`solve_control`).  A synthesised law keeps its shape (what lowers the load)
    while c absorbs the range error the dispersion causes -- the predictor-corrector idea
    applied to a feedback law instead of a constant control.  The law's inputs 1 and 2 are y1
    and y2 (the plant's outputs; the prediction computes them with
    :func:`models.reentry.deviations` on the line from ``h0_line`` to the nominal hf, Lf).
    Outputs: ``correction`` (c), ``predicted_miss`` [m] and ``predictions``.
    """

    params_class = GuidedParams
    estimator_class = ProfileEstimator
    description = ("Network-operator law reading the drag-factor estimate y3 and an on-board "
                   "predictor-corrector correction c: u = phi(y1, y2, y3, c, q)")

    def __init__(self, **kwargs):
        self._guided = False
        self._c, self._miss, self._n_pred = 0.0, 0.0, 0
        super().__init__(**kwargs)
        self.int_parameter("correction_input", 4, "law input receiving the correction c "
                           "(0 = none) [1]")
        self.output("correction", "on-board correction c of the last cycle [1]",
                    getter=lambda: self._c)
        self.output("predicted_miss", "predicted L(hf) - Lf at the last correction [m]",
                    getter=lambda: self._miss)
        self.int_output("predictions", "on-board predictions so far [1]",
                        getter=lambda: self._n_pred)
        self._guided = True
        self.apply_resource_defaults()
        self.check_parameters()
        self.prepare()

    def apply_resource_defaults(self) -> None:
        if self._guided:
            super().apply_resource_defaults()

    def check_parameters(self) -> None:
        super().check_parameters()
        if self._guided:
            if not 0 <= self.correction_input <= NX_MAX:
                raise ParameterError(f"correction_input = {self.correction_input} outside "
                                     f"0..{NX_MAX}")
            if self.correction_input and self.correction_input == self.estimate_input:
                raise ParameterError("correction_input and estimate_input must differ")

    def prepare(self) -> None:
        super().prepare()
        if self._guided:
            self._model = ReentryParams()
            self._line = ReentryParams(h0=self.h0_line)
            self._kd = self._model.constants()[1]
            self._t, self._next = 0.0, 0.0
            self._c, self._miss, self._n_pred = 0.0, 0.0, 0
            self._plan, self._peak = [0.0] * len(PLAN_KNOTS), 0.0

    def _correction_at(self, x) -> float:
        """The correction now: c, or the plan's value at the altitude of ``x``."""
        if not self.replan:
            return self._c
        return plan_value(self._plan, altitude(x, self._model.Rz))

    def _outputs(self):
        if self._dirty and self._guided and self._active():
            x = self.nav_state()
            self._maybe_correct(x, self.cycle)
            c = self._c = self._correction_at(x) if self.replan else self._c
            if self._reads_c():
                self.x[self.correction_input - 1] = c
            u = super()._outputs()
            if self.correction_gain:
                if self.correction_gate and c > 0.0:     # the gate needs the state
                    u[0] = self._corrected(u[0], c, x,
                                           self._kd * math.exp(self.current_estimate()),
                                           self._model)
                else:
                    u[0] = self._corrected(u[0], c)
            return u
        return super()._outputs()

    def _reads_c(self) -> bool:
        return 0 < self.correction_input <= self.nx

    def _active(self) -> bool:
        return self._reads_c() or self.correction_gain != 0.0

    def _corrected(self, u: float, c: float, x=None, kd: float = 0.0, model=None) -> float:
        """The law's clipped output plus g w c (w: :func:`gate_weight` at the state ``x`` with
        the drag factor ``kd`` and ``model``'s scale height; 1 without a gate or for c <= 0,
        where ``x`` is not needed), clipped to the same bounds."""
        w = gate_weight(x, c, self.correction_gate, kd, model) \
            if self.correction_gate and c > 0.0 else 1.0
        v = u + self.correction_gain * w * c
        return self.u_lo[0] if v < self.u_lo[0] else (self.u_hi[0] if v > self.u_hi[0] else v)

    def _predictor(self, x, prof):
        """``control(correction)``: the guidance as the prediction flies it -- the law on the
        predicted state (y1, y2 on the line, y3 the fitted profile's log factor at the predicted
        altitude) plus the correction ``correction(xp)``."""
        inputs = list(self.x[:self.nx])
        k_e = self.estimate_input - 1 if 0 < self.estimate_input <= self.nx else -1
        k_c, line, law, rz = self.correction_input - 1, self._line, self.law, self._model.Rz
        reads, gain, corrected = self._reads_c(), self.correction_gain, self._corrected
        kd, dlam, h_now = prof.kd, prof.lam - self._model.lam, altitude(x, rz)
        model = self._model if dlam == 0.0 else self._model.with_(lam=prof.lam)

        def control_for(correction):
            def control(xp):
                inputs[0], inputs[1], y3 = predicted_inputs(xp, line, rz, prof.log_factor, dlam,
                                                            h_now)
                if k_e >= 0:
                    inputs[k_e] = y3
                c = correction(xp)
                if reads:
                    inputs[k_c] = c
                u = law(inputs)[0]
                return corrected(u, c, xp, kd, model) if gain else u
            return control
        return control_for

    def _correct(self, x) -> None:
        prof = self.estimator().profile(self.a_drag, x)
        control_for = self._predictor(x, prof)
        lf, dt, model, rz = self._model.Lf, self.dt_pred, self._model, self._model.Rz
        bound = self.correction_max

        def solve(miss):
            return solve_control(miss, 0.0, self.tol, self.max_iter, (-bound, bound))

        if self.replan:
            def evaluate(c):
                rng, samples = predict_flight(
                    x, control_for(lambda xp: plan_value(c, altitude(xp, rz))), prof.kd, model,
                    dt, prof.lam)
                return rng - lf, samples
            self._plan, self._miss, n = replan(evaluate, self._plan, bound, self.replan_trust,
                                               self.replan_effort, self._peak,
                                               self.replan_iterations, solve)
        else:
            def miss(c):
                return predict_range(x, control_for(lambda xp: c), prof.kd, model, dt,
                                     prof.lam) - lf
            self._c, self._miss, n = solve_control(miss, self._c, self.tol, self.max_iter,
                                                   (-bound, bound))
        self._n_pred += n

    def _track_peak(self, u: float) -> None:
        """The running peak of the model's load at the navigated states (the plan's floor)."""
        x = self.nav_state()
        try:
            prof = self.estimator().profile(self.a_drag, x)
            n = predicted_load(x, u, prof.kd, prof.lam, self._model)
        except (ArithmeticError, ValueError):
            return
        if n > self._peak:
            self._peak = n

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self.replan:
            self._track_peak(self._outputs()[0])
        ok = super().do_step(current_time, step_size)
        self._t = current_time + step_size
        return ok
