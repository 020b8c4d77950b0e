"""S4 -- the rigid telescope's FMU and the one integrator of the telescope plants.

:class:`Telescope` is the FMU of the rigid gyrostat with up to :data:`N_GYROS_MAX` gyrodynes
(six; the equations, their parameters and the data of Voronov's Example 1 are in
``models/telescope_dynamics.py``, the cluster's geometry in ``models/telescope_cmg.py``).
:class:`AttitudeIntegrator` is the one integrator of the telescope plants, rigid and flexible
(first-order hold of the gimbal rates, ``models/rk4_input.py``).

References
----------
S.A. Voronov, PhD thesis (2009), ch. 2, Example 1, eqs. (8)-(9); ch. 3, Example 3.
"""
from __future__ import annotations

import math

from pythonfmu import Fmi2Causality

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import LEFT_DOMAIN, Integrator
from descent_fmus.models.params import ParameterError, description_of, require_finite, unit_of
from descent_fmus.models.rk4_input import propagate_linear_input
from descent_fmus.models.telescope_dynamics import (INITIAL_STATE, TelescopeParams,
                                                    inertial_momentum, make_rigid_rhs,
                                                    singularity_measure)
from descent_fmus.models.traceable import where

__all__ = ["N_GYROS_MAX", "DT_INTEGRATION", "AttitudeIntegrator", "Telescope", "INERTIA_NAMES"]

#: Gyrodynes an FMU can carry (its inputs u[1..6], outputs beta1..beta6).
N_GYROS_MAX = 6
#: Default RK4 sub-step inside the FMU [s]; the direct method uses the same sub-steps.
DT_INTEGRATION = 0.025


class AttitudeIntegrator(Integrator):
    """Advance ``x`` under a piecewise-linear control with RK4 sub-steps of at most ``dt`` [s].

    The one integrator of the telescope plants (rigid and flexible: ``rhs`` decides), owned by
    their FMUs.  The reorientation has no terminal condition, so ``status`` stays ``RUNNING``
    up to the stop time; it becomes ``LEFT_DOMAIN`` if the integration diverges (a non-finite
    state or an arithmetic error), and the state stays the last finite one, at ``t_end``.

    Parameters
    ----------
    rhs : callable
        ``f(x, u)`` on tuples of floats (:func:`make_rigid_rhs`, or the flexible model's).
    x0 : sequence of float
        Initial state.
    dt : float
        Largest RK4 sub-step [s] (> 0).
    """

    def __init__(self, rhs, x0, dt: float = DT_INTEGRATION):
        self.rhs = rhs
        self.x0 = tuple(float(v) for v in x0)
        super().__init__(dt)

    def initial_state(self) -> tuple:
        return self.x0

    def advance(self, t_end: float, u, du) -> None:
        """Integrate to ``t_end`` with ``u(t) = u + du (t - self.t)`` (first-order hold)."""
        span = t_end - self.t
        if span <= 0.0 or self.status:
            return
        n = max(1, math.ceil(span / self.dt - 1e-9))
        try:
            x = propagate_linear_input(self.rhs, self.x, span, u, du, n)
        except (ArithmeticError, ValueError):
            x = None
        if x is None or not all(math.isfinite(v) for v in x):
            self.end(LEFT_DOMAIN, self.t)
            return
        self.x, self.t = x, t_end


#: Names of the FMU parameters holding the inertia tensor, row-major.
INERTIA_NAMES = ("I11", "I12", "I13", "I21", "I22", "I23", "I31", "I32", "I33")


class Telescope(SlaveBase):
    """FMU of the rigid S4 telescope: inputs gimbal rates and their slopes; outputs the state,
    inertial angular momentum, the CMG singularity measure and the status.

    Up to :data:`N_GYROS_MAX` gyrodynes: ``n_gyros`` (Integer) of them with the gimbal axes
    ``gimbal_axes[1..3 n_gyros]``; the inputs and outputs of the others are ignored / 0.

    The control over a communication step ``[t, t + H]`` is ``u + du (s - t)``: with ``du`` = 0 a
    zero-order hold, with the ProgramController's slopes an exact replay of a piecewise-linear
    program (first-order hold).  ``status`` (:mod:`models.integrators`) stays 0 (running) up to
    the stop time -- the reorientation has no terminal condition -- and becomes 3 if the
    integration diverges.
    """

    params_class = TelescopeParams

    description = ("S4 orbital telescope, rigid gyrostat with up to six gyrodynes (gimbal axes "
                   "as parameters; default the dodecahedron cluster); Voronov 2009")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        inertia = TelescopeParams().inertia
        what = description_of(TelescopeParams, "inertia", with_unit=False)
        unit = unit_of(TelescopeParams, "inertia")
        for name, value in zip(INERTIA_NAMES, inertia):
            self.parameter(name, value, f"{what}, entry {name} [{unit}]")
        self.parameters(["h"])
        self.rotor_ref = list(TelescopeParams().rotor_ref)
        self.real_array("rotor_ref", self.rotor_ref, Fmi2Causality.parameter,
                        description_of(TelescopeParams, "rotor_ref"))
        self.int_parameter("n_gyros", N_GYROS_MAX, f"number of gyrodynes in use (1..{N_GYROS_MAX});"
                           " gimbal axes gimbal_axes[1..3 n_gyros] [1]")
        self.gimbal_axes = list(TelescopeParams().gimbal_axes)
        self.real_array("gimbal_axes", self.gimbal_axes, Fmi2Causality.parameter,
                        description_of(TelescopeParams, "gimbal_axes"))
        self.parameter("dt", DT_INTEGRATION, "RK4 sub-step of the internal integration [s]")
        self.lam_init = list(INITIAL_STATE[:4])
        self.w_init = list(INITIAL_STATE[4:7])
        self.beta_init = list(INITIAL_STATE[7:13])
        self.real_array("lam_init", self.lam_init, Fmi2Causality.parameter,
                        "initial quaternion (scalar first), body -> inertial [1]")
        self.real_array("w_init", self.w_init, Fmi2Causality.parameter,
                        "initial body rate [rad/s]")
        self.real_array("beta_init", self.beta_init, Fmi2Causality.parameter,
                        "initial gimbal angles [rad]")
        self.u = [0.0] * 6
        self.du = [0.0] * 6
        self.real_array("u", self.u, Fmi2Causality.input, "gimbal rate at the step start [rad/s]")
        self.real_array("du", self.du, Fmi2Causality.input,
                        "gimbal rate slope over the step (0 = zero-order hold) [rad/s2]")
        self._register_extra_parameters()
        x = lambda: self._ig.x  # noqa: E731
        for k in range(4):
            self.output(f"lam{k}", f"quaternion component lambda{k} [1]",
                        getter=lambda k=k: x()[k])
        for k in range(3):
            self.output(f"w{k + 1}", f"body rate omega{k + 1} [rad/s]",
                        getter=lambda k=k: x()[4 + k])
        for k in range(N_GYROS_MAX):
            self.output(f"beta{k + 1}", f"gimbal angle beta{k + 1} (0 if k > n_gyros) [rad]",
                        getter=lambda k=k: x()[7 + k] if k < self._n else 0.0)
        for k in range(3):
            self.output(f"K{k + 1}", f"inertial angular momentum K{k + 1} (first integral) "
                        "[N m s]", getter=lambda k=k: float(self._momentum()[k]))
        self.output("sing", "CMG singularity measure det(C C^T)/h^6, 0 = singular [1]",
                    getter=lambda: singularity_measure(x()[7:7 + self._n], self._params))
        self.output("lam_norm", "quaternion norm |lambda| (first integral, = 1) [1]",
                    getter=lambda: math.sqrt(sum(v * v for v in x()[:4])))
        self._register_extra_outputs()
        self.status_outputs(lambda: self._ig.status, lambda: self._ig.t_end_output)
        self.apply_resource_defaults()
        self.prepare()

    # hooks for the flexible variant
    def _register_extra_parameters(self):
        pass

    def _register_extra_outputs(self):
        pass

    def _momentum(self):
        return inertial_momentum(self._ig.x, self._params)

    def params(self) -> TelescopeParams:
        """The current parameter values (the inertia from ``I11..I33``, the first ``n_gyros``
        gimbal axes)."""
        return TelescopeParams(inertia=tuple(getattr(self, n) for n in INERTIA_NAMES), h=self.h,
                               rotor_ref=tuple(self.rotor_ref),
                               gimbal_axes=tuple(self.gimbal_axes[:3 * self.n_gyros]))

    def _initial_state(self):
        return (tuple(self.lam_init) + tuple(self.w_init)
                + tuple(self.beta_init[:self.n_gyros]))

    def _make_rhs(self):
        return make_rigid_rhs(self._params)

    def check_parameters(self) -> None:
        if not 1 <= self.n_gyros <= N_GYROS_MAX:
            raise ParameterError(f"parameter n_gyros must be in 1..{N_GYROS_MAX}, got "
                                 f"{self.n_gyros}")
        super().check_parameters()
        for n, v in zip(("lam_init",) * 4 + ("w_init",) * 3 + ("beta_init",) * N_GYROS_MAX,
                        self._initial_state()):
            require_finite(n, v)
        nrm = math.sqrt(sum(v * v for v in self.lam_init))
        if abs(nrm - 1.0) > 1e-6:
            raise ParameterError(f"lam_init must be a unit quaternion, |lam_init| = {nrm}")

    def prepare(self) -> None:
        self._params = self.params()
        self._n = self._params.n_gyros
        self._ig = AttitudeIntegrator(self._make_rhs(), self._initial_state(), self.dt)

    def do_step(self, current_time: float, step_size: float) -> bool:
        # a non-finite input is 0 (models.traceable.where: one C conditional each natively)
        u = tuple(where(math.isfinite(v), v, 0.0) for v in self.u)
        du = tuple(where(math.isfinite(v), v, 0.0) for v in self.du)
        self._ig.advance(current_time + step_size, u, du)
        return True
