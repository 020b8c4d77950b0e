"""S3 optimal law as *feedback*: full thrust once the state reaches the switching curve.

The fuel-optimal landing is a coast, then full thrust to h = V = 0 (Mozzhorina 2017).  Its
feedback form: the engine is on when the lander is on or below the switching curve
``h = h_sw(V, m)`` (:func:`models.lunar_landing.switch_height`: the height from which full thrust
stops the lander exactly at the ground), off above it.  The law sees only the measured state, so
it absorbs errors in the start state that ruin the open-loop program.

Sampled-data realisation (the control is held over a communication step ``dt``):

* **one-step prediction** -- the control for ``[t_k, t_k + dt]`` is the smallest constant flow
  ``u in [0, umax]`` whose closed-form motion (:func:`models.lunar_landing.constant_flow_state`)
  ends the step *on or above* the curve: 0 while coasting keeps it above, ``umax`` once even full
  thrust cannot, and in between on the switching step (the averaged control of Mozzhorina's
  Fedorenko scheme, located by the law itself).  Without it the switch would be late by up to
  one step and the lander would touch down at ~1 m/s with dt = 0.01 s.
* **gravity estimate** (``estimate_g = 1``) -- while coasting ``dV/dt = gL`` exactly, so the
  difference quotient of two measured speeds over a coast step is the local gravity; the curve
  uses it from the second sample on (``g_nominal`` before).  With a +-2 % error in gL the curve
  computed from a wrong gL is ~2 m off at 93 m, a ~2 m/s touchdown; the estimate removes it.

References
----------
T.Yu. Mozzhorina, 2017 (the optimal control structure, the averaged control on the switching
step, and the closing remark that synthesis -- feedback -- needs another algorithm).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.lunar_landing import (STEP, InfeasibleLandingError, LanderParams,
                                               constant_flow_state, solve_increasing,
                                               switch_height)
from descent_fmus.models.params import ParameterError, Params, param

__all__ = ["SwitchParams", "SwitchLaw", "LandingSwitch", "G_GATE"]

#: A gravity estimate further than this fraction from ``g_nominal`` is rejected (the dispersion
#: of interest is +-2 %; a wrong speed sample gives errors of order 100 %).
G_GATE = 0.25


@dataclass(frozen=True)
class SwitchParams(Params):
    """Parameters of the feedback law (FMU :class:`LandingSwitch`); defaults from the plant's
    default scenario (:class:`models.lunar_landing.LanderParams`)."""

    umax: float = param(LanderParams.umax, "kg/s", "maximum fuel flow", positive=True)
    beta: float = param(LanderParams.beta, "m/s", "exhaust velocity", positive=True)
    g_nominal: float = param(LanderParams.gL, "m/s2", "gravity before an estimate exists",
                             positive=True)
    estimate_g: int = param(1, "1", "1: estimate gravity from coast steps, 0: use g_nominal "
                            "throughout")
    step: float = param(STEP, "s", "communication step assumed before the first doStep",
                        positive=True)

    def check(self) -> None:
        if self.estimate_g not in (0, 1):
            raise ParameterError(f"parameter estimate_g must be 0 or 1, got {self.estimate_g}")


_DEFAULT = SwitchParams()


class SwitchLaw:
    """The feedback law on plain floats (used by the FMU and by in-process code).

    Parameters
    ----------
    umax : float
        Maximum fuel flow [kg/s].
    beta : float
        Exhaust velocity [m/s].
    g_nominal : float
        Gravity used before an estimate exists (or always, if ``estimate_g`` is False) [m/s^2].
    estimate_g : bool
        Estimate the gravity from coast steps.
    dt : float
        Communication step used for the one-step prediction until :meth:`stepped` reports one [s].
    """

    def __init__(self, umax=_DEFAULT.umax, beta=_DEFAULT.beta, g_nominal=_DEFAULT.g_nominal,
                 estimate_g=True, dt=_DEFAULT.step):
        self.umax, self.beta, self.g_nominal = umax, beta, g_nominal
        self.estimate_g = bool(estimate_g)
        self.dt = dt
        self.g = g_nominal
        self._last = None          # (V, u, dt) of the last step taken
        self._fresh = False        # a step has been taken since the last estimate

    def curve(self, V, m, g=None):
        """Switching-curve height ``h_sw(V, m)`` [m] with the current gravity (estimate)."""
        try:
            return switch_height(V, m, self.umax, self.g if g is None else g, self.beta)
        except InfeasibleLandingError:
            return math.inf        # cannot stop any more: full thrust is the best there is

    def control(self, h, V, m):
        """Fuel flow [kg/s] for the coming step from the measured ``h`` [m], ``V`` [m/s], ``m``."""
        if self.estimate_g and self._fresh and self._last is not None:
            V_prev, u_prev, dt_prev = self._last
            if u_prev == 0.0 and dt_prev > 0.0 and V_prev is not None:
                g = (V - V_prev) / dt_prev
                # plausibility gate: a speed sample that is not a fresh measurement (e.g. an
                # input not yet updated by the master) must not become "gravity"
                if math.isfinite(g) and abs(g - self.g_nominal) <= G_GATE * self.g_nominal:
                    self.g = g
            self._fresh = False
        if not (math.isfinite(h) and math.isfinite(V) and math.isfinite(m) and m > 0.0):
            return 0.0
        if h <= 0.0:
            return 0.0
        g, b, dt, umax = self.g, self.beta, self.dt, self.umax

        def margin(u):            # height above the curve at the end of the step
            hn, Vn, mn = constant_flow_state((h, V, m), u, dt, g, b)
            return hn - self.curve(Vn, mn)

        f0 = margin(0.0)
        if f0 >= 0.0:
            return 0.0
        f1 = margin(umax)
        if not f1 > 0.0:
            return umax
        return solve_increasing(margin, 0.0, umax, f0, f1, xtol=1e-12 * umax)

    def stepped(self, V, u, dt):
        """Report the step just taken: speed at its start [m/s] (None if it was not measured
        for this step), control [kg/s], size [s]."""
        self._last = (V, u, dt)
        self._fresh = True
        if dt > 0.0:
            self.dt = dt


class LandingSwitch(SlaveBase):
    """Feedback controller FMU: inputs ``h, V, m``; output the fuel flow ``u`` [kg/s].

    Outputs are computed from the inputs when read (direct feed-through), like the
    network-operator controller.  Diagnostic outputs: ``h_sw`` (the switching-curve height at the
    current V, m) and ``g_est`` (the gravity the law uses).
    """

    params_class = SwitchParams

    description = ("S3 optimal landing law as feedback: full thrust once the state reaches the "
                   "switching curve h = h_sw(V, m) (closed-form powered arc); Mozzhorina 2017")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self._dirty = True
        self._measured = False
        self._u = 0.0
        p = LanderParams()
        for name, desc, start in (("h", "measured altitude [m]", p.h0),
                                  ("V", "measured downward speed [m/s]", p.V0),
                                  ("m", "measured mass [kg]", p.m0)):
            self.input(name, start, desc, setter=lambda v, n=name: self._set(n, v))
        self.output("u", "fuel flow for the coming communication step [kg/s]",
                    getter=self._output)
        self.output("h_sw", "switching-curve height at the current V and m [m]",
                    getter=lambda: self._law.curve(self.V, self.m))
        self.output("g_est", "gravity used by the law [m/s2]", getter=lambda: self._law.g)
        self.apply_resource_defaults()
        self.prepare()

    def _set(self, name, value):
        setattr(self, name, value)
        self._dirty = True
        self._measured = True

    def prepare(self) -> None:
        self._law = SwitchLaw(self.umax, self.beta, self.g_nominal, self.estimate_g, self.step)
        self._dirty = True

    def _output(self):
        if self._dirty:
            self._u = self._law.control(self.h, self.V, self.m)
            self._dirty = False
        return self._u

    def do_step(self, current_time: float, step_size: float) -> bool:
        # V counts as a measurement of this step only if the master set the inputs since the
        # last step (a container may step once before its first connection update)
        self._law.stepped(self.V if self._measured else None, self._output(), step_size)
        self._measured = False
        self._dirty = True
        return True
