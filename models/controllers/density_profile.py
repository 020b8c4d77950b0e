"""S1 sensing: an on-board fit of the density profile (factor and scale height) to the sensed drag.

:class:`~models.controllers.drag_estimator.DragFactorEstimator` estimates one constant factor
``(rho0/m) / (rho0/m)_nominal``.  A density profile whose *shape* differs from the model's -- a
scale height off by a few per cent -- is a factor that changes with altitude, which no constant
describes: the sensed drag at 70 km then tells the guidance the wrong density at 30 km.  This
estimator fits the log-ratio of the sensed to the nominal drag over altitude,

    z_k = ln(a_sensed,k / a_nominal,k) = alpha + beta d_k + gamma e_k + noise,
    d_k = (h_k - H_REF) / H_UNIT,   e_k = 1 / a_nominal,k  [s2/m],

a regularised weighted least-squares fit (the information form of a Kalman filter of a constant
state ``theta = (alpha, beta, gamma)``): ``alpha`` is the log factor at ``H_REF``, ``beta`` the
change of the log density per ``H_UNIT`` of altitude that the model's scale height misses
(``lam_true = lam_nominal - beta / H_UNIT``), ``gamma`` [m/s2] the first-order effect of an
accelerometer bias (``ln(1 + b/a) ~ b/a``).  Weights ``w_k = a_nominal,k^2 / accel_sigma^2`` (the
log-ratio's noise is about sigma / a); prior: ``beta ~ N(0, (scale_prior lam H_UNIT)^2)``,
``gamma ~ N(0, bias_prior^2)``, ``alpha`` nearly flat.  The posterior covariance is the inverse
of the information matrix, so the fit carries its own uncertainty.

What runs per sample is arithmetic on a few sums and one 3 x 3 solve written out (cofactors),
so the native generator's tracer can follow it as it follows the constant-factor estimator.
The estimator never reads the plant's true parameters.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from descent_fmus.models.controllers.drag_estimator import DragEstimatorParams, DragFactorEstimator
from descent_fmus.models.params import param
from descent_fmus.models.traceable import where
from descent_fmus.models.reentry import ReentryParams

__all__ = ["ProfileParams", "ProfileEstimator", "Profile", "H_REF", "H_UNIT"]

#: Reference altitude of the fit's intercept [m] and the unit of its slope [m].
H_REF = 60_000.0
H_UNIT = 10_000.0
#: Prior precision of the intercept alpha (sd 1000: flat over any factor there is).
ALPHA_PRECISION = 1.0e-6
#: Precision standing for a term switched off (its prior sd 0).
OFF_PRECISION = 1.0e30


@dataclass(frozen=True)
class ProfileParams(DragEstimatorParams):
    """Parameters of the density-profile fit (plus the constant-factor estimator's)."""

    accel_sigma: float = param(0.05, "m/s2", "accelerometer noise the profile fit assumes "
                               "(its weights and its uncertainty)", positive=True)
    scale_prior: float = param(0.05, "1", "prior standard deviation of the relative error of "
                               "the density scale height (0 = a constant factor only)",
                               nonnegative=True)
    bias_prior: float = param(0.02, "m/s2", "prior standard deviation of the accelerometer bias "
                              "(0 = no bias term)", nonnegative=True)


@dataclass(frozen=True)
class Profile:
    """The fitted profile: ``kd`` = S rho0/m and ``lam`` of the model to predict with, the log
    factor at the altitude asked for, its standard deviation and that of ``lam``."""

    kd: float
    lam: float
    log_factor: float
    log_factor_sd: float
    lam_sd: float
    bias: float


def _solve3(a11, a12, a13, a22, a23, a33, b1, b2, b3):
    """The solution of the symmetric 3 x 3 system and the inverse's entries (cofactors)."""
    c11 = a22 * a33 - a23 * a23
    c12 = a13 * a23 - a12 * a33
    c13 = a12 * a23 - a13 * a22
    c22 = a11 * a33 - a13 * a13
    c23 = a12 * a13 - a11 * a23
    c33 = a11 * a22 - a12 * a12
    det = a11 * c11 + a12 * c12 + a13 * c13
    t1 = (c11 * b1 + c12 * b2 + c13 * b3) / det
    t2 = (c12 * b1 + c22 * b2 + c23 * b3) / det
    t3 = (c13 * b1 + c23 * b2 + c33 * b3) / det
    return (t1, t2, t3), (c11 / det, c12 / det, c22 / det)


class ProfileEstimator(DragFactorEstimator):
    """The constant-factor estimator plus the profile fit (see the module docstring): the same
    samples, timing and accelerometer errors; ``estimate`` is the log factor of the fitted
    profile at the current altitude (what the laws read as y3), :meth:`profile` the model the
    guidance predicts with."""

    def __init__(self, params: ProfileParams = ProfileParams(),
                 model: ReentryParams = ReentryParams()):
        super().__init__(params, model)
        self._weights()
        # sums of w phi phi^T (upper triangle) and w phi z, phi = (1, d, e)
        self.s = [0.0] * 9

    def _weights(self) -> None:
        """The prior precisions of (alpha, beta, gamma) and the samples' weight per unit
        a_nominal^2, from the parameters and the model."""
        p = self.params
        sb = p.scale_prior * self.model.lam * H_UNIT
        self.prior = (ALPHA_PRECISION, where(sb > 0.0, lambda: 1.0 / (sb * sb), OFF_PRECISION),
                      where(p.bias_prior > 0.0, lambda: 1.0 / (p.bias_prior * p.bias_prior),
                            OFF_PRECISION))
        self.iw = 1.0 / (p.accel_sigma * p.accel_sigma)

    def _terms(self, a_drag_g: float, x):
        """The sample's ``(w, z, d, e)``, or None where the constant-factor sample is None."""
        s = self._sample(a_drag_g, x)
        if s is None:
            return None
        a_nom = math.sqrt(s[0])
        h = math.hypot(x[0], x[2]) - self.model.Rz
        return s[0] * self.iw, s[1], (h - H_REF) / H_UNIT, 1.0 / a_nom

    def _sums(self, a_drag_g: float, x) -> list:
        s = list(self.s)
        t = self._terms(a_drag_g, tuple(x))
        if t is not None:
            w, z, d, e = t
            s[0] += w
            s[1] += w * d
            s[2] += w * e
            s[3] += w * d * d
            s[4] += w * d * e
            s[5] += w * e * e
            s[6] += w * z
            s[7] += w * d * z
            s[8] += w * e * z
        return s

    def _fit(self, s):
        pa, pb, pg = self.prior
        return _solve3(s[0] + pa, s[1], s[2], s[3] + pb, s[4], s[5] + pg, s[6], s[7], s[8])

    def profile(self, a_drag_g: float, x, h=None) -> Profile:
        """The fitted profile including the current sample; ``log_factor`` at the altitude ``h``
        (default: the state's)."""
        x = tuple(x)
        (alpha, beta, gamma), (v11, v12, v22) = self._fit(self._sums(a_drag_g, x))
        if h is None:
            h = math.hypot(x[0], x[2]) - self.model.Rz
        d = (h - H_REF) / H_UNIT
        m = self.model
        var = v11 + 2.0 * d * v12 + d * d * v22
        return Profile(kd=self.kd * math.exp(alpha - beta * H_REF / H_UNIT),
                       lam=m.lam - beta / H_UNIT, log_factor=alpha + beta * d,
                       log_factor_sd=math.sqrt(where(var > 0.0, var, 0.0)),
                       lam_sd=math.sqrt(where(v22 > 0.0, v22, 0.0)) / H_UNIT, bias=gamma)

    def estimate(self, a_drag_g: float, x) -> float:
        """The log factor of the fitted profile at the current altitude (0 before any sample)."""
        return self.profile(a_drag_g, x).log_factor

    def commit(self, a_drag_g: float, x, u_next: float) -> None:
        self.s = self._sums(a_drag_g, tuple(x))
        super().commit(a_drag_g, x, u_next)
