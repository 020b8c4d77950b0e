"""The density-profile estimator (factor and scale height) of S1's guidance.

Oracles: the closed form of the sensed drag, a = (1 + u) S rho0/m v^2 exp(-lam h), at the states
of a flight integrated here by scipy's DOP853 with a plant whose rho0, m and lam (the inverse
scale height) are off the model's; its fit must return the true S rho0/m and lam.  Under seeded
accelerometer noise the estimates over many seeds must centre on the truth (unbiased) with the
spread the fit reports.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from descent_fmus.models.controllers.density_profile import ProfileEstimator, ProfileParams
from descent_fmus.models.params import ParameterError
from descent_fmus.models.reentry import ReentryParams

P0 = ReentryParams()
TRUE = P0.with_(rho0=P0.rho0 * 1.10, m=P0.m * 0.98, lam=P0.lam * 1.04)
KD_TRUE = TRUE.S * TRUE.rho0 / TRUE.m
U = 0.05


def _flight(t_end=250.0):
    """(a_drag [g], state) every 1 s of the true plant (DOP853), u = U from t = 1 s on."""
    mu = P0.g0 * P0.Rz ** 2

    def f(t, x):
        r = math.hypot(x[0], x[2])
        d = (1 + U) * KD_TRUE * math.hypot(x[1], x[3]) * math.exp(-TRUE.lam * (r - P0.Rz))
        return [x[1], -mu * x[0] / r ** 3 - d * x[1], x[3], -mu * x[2] / r ** 3 - d * x[3]]

    x0 = [0.0, P0.V0 * math.cos(P0.beta0), P0.Rz + P0.h0, P0.V0 * math.sin(P0.beta0)]
    t = np.arange(0.0, t_end + 0.5, 1.0)
    sol = solve_ivp(f, (0.0, t_end), x0, method="DOP853", t_eval=t, rtol=1e-11, atol=1e-6)
    out = []
    for k, x in enumerate(sol.y.T):
        u = U if k else 0.0      # the plant's sample at t = 0 is taken before any control
        h = math.hypot(x[0], x[2]) - P0.Rz
        a = (1 + u) * KD_TRUE * (x[1] ** 2 + x[3] ** 2) * math.exp(-TRUE.lam * h) / P0.g0
        out.append((a, tuple(x)))
    return out


FLIGHT = _flight()


def _run(params: ProfileParams, upto=None):
    est = ProfileEstimator(params)
    rows = []
    for a, x in FLIGHT[:upto]:
        rows.append((math.hypot(x[0], x[2]) - P0.Rz, est.profile(a, x)))
        est.commit(a, x, U)
    return rows


def test_noise_free_fit_recovers_factor_and_scale_height_exactly():
    # nearly flat priors: the weighted least-squares fit of exact data is the truth (closed
    # form); what is left early is the priors' weight against few samples over a short arc
    rows = _run(ProfileParams(scale_prior=1e6, bias_prior=1e6))
    for h, prof in rows[80:]:                      # below 76 km
        assert prof.kd == pytest.approx(KD_TRUE, rel=1e-8)
        assert prof.lam == pytest.approx(TRUE.lam, rel=1e-9)
        # the log factor at the current altitude is the true density over the model's there
        true_log = math.log(KD_TRUE / (P0.S * P0.rho0 / P0.m)) - (TRUE.lam - P0.lam) * h
        assert prof.log_factor == pytest.approx(true_log, abs=1e-7)
        assert abs(prof.bias) < 1e-6


def test_default_priors_converge_on_the_truth_before_the_load_peak():
    # the prior keeps the early slope near the model's; by 60 km the data decide
    rows = _run(ProfileParams())
    late = [(h, p) for h, p in rows if h < 60_000.0]
    assert late
    for h, prof in late:
        assert prof.lam == pytest.approx(TRUE.lam, rel=2e-3)
        assert prof.log_factor_sd < 0.01
    h, prof = rows[-1]
    assert prof.lam == pytest.approx(TRUE.lam, rel=1e-5)
    assert prof.kd == pytest.approx(KD_TRUE, rel=1e-4)


def test_scale_prior_zero_is_the_constant_factor_estimate():
    from descent_fmus.models.controllers.drag_estimator import DragFactorEstimator
    est = ProfileEstimator(ProfileParams(scale_prior=0.0, bias_prior=0.0))
    const = DragFactorEstimator(ProfileParams())
    for a, x in FLIGHT[:120]:
        # the same mean but for the intercept's nearly flat prior (precision 1e-6)
        assert est.estimate(a, x) == pytest.approx(const.estimate(a, x), abs=1e-6)
        assert est.profile(a, x).lam == pytest.approx(P0.lam, rel=1e-12)
        est.commit(a, x, U)
        const.commit(a, x, U)


def test_unbiased_under_seeded_noise_with_the_spread_it_reports():
    # 0.03 m/s2 white noise, 40 seeds: the mean error of lam and of the log factor at the end
    # is within 3 standard errors of zero, and the reported sd matches the seeds' spread
    sigma = 0.03
    lam_err, log_err, sd_lam = [], [], []
    for seed in range(40):
        h, prof = _run(ProfileParams(noise=sigma, noise_seed=seed, accel_sigma=sigma,
                                     bias_prior=0.0), upto=220)[-1]
        true_log = math.log(KD_TRUE / (P0.S * P0.rho0 / P0.m)) - (TRUE.lam - P0.lam) * h
        lam_err.append(prof.lam / TRUE.lam - 1.0)
        log_err.append(prof.log_factor - true_log)
        sd_lam.append(prof.lam_sd / TRUE.lam)
    lam_err, log_err = np.array(lam_err), np.array(log_err)
    assert abs(lam_err.mean()) < 3 * lam_err.std(ddof=1) / math.sqrt(len(lam_err)) + 1e-6
    assert abs(log_err.mean()) < 3 * log_err.std(ddof=1) / math.sqrt(len(log_err)) + 1e-6
    assert 0.5 < lam_err.std(ddof=1) / np.mean(sd_lam) < 2.0
    assert np.abs(lam_err).max() < 0.01            # well within the 4 % error it estimates


def test_bias_is_absorbed():
    # a 0.015 m/s2 bias: the fit's bias term takes it, so the scale height stays right
    h, prof = _run(ProfileParams(bias=0.015), upto=220)[-1]
    assert prof.lam == pytest.approx(TRUE.lam, rel=2e-3)
    h0, plain = _run(ProfileParams(bias=0.015, bias_prior=0.0), upto=220)[-1]
    assert abs(prof.lam / TRUE.lam - 1) < abs(plain.lam / TRUE.lam - 1)


@pytest.mark.parametrize("name", ["scale_prior", "bias_prior"])
def test_negative_priors_are_rejected(name):
    with pytest.raises(ParameterError, match=f"{name} must be >= 0"):
        ProfileParams(**{name: -0.1}).validate()
