"""S1 on-board prediction: the flight to hf on the nominal model, and the corrector's root search.

The predictor-corrector guidance of :mod:`models.controllers.reentry_npc` (the NPC and the
guided network-operator law) predicts the flight on board: it integrates the nominal model
(:func:`models.reentry.rhs`, the one definition of the equations) with an estimated drag factor
and scale height from a navigated state to the altitude hf, with the plant's RK4 scheme
(:func:`models.integrators.advance_to`) on a coarser step, locating h = hf inside the step as the
plant does (:func:`predict_step`, :func:`predict_range`, :func:`predict_flight`), and solves for
the control whose predicted down-range is Lf (:func:`solve_control`: Brent's method, scipy, on
the bracket a guess and a bound give).  The native twins trace these functions to C
(``synthesis/systems/reentry/native/guidance.py``).

References
----------
Predictor-corrector entry guidance (e.g. Lu, "Entry guidance: a unified method", J. Guidance,
Control, and Dynamics 37(3), 2014): predict the terminal condition by integrating the model
on board, correct the control parameter by a root search.
"""
from __future__ import annotations

import math

from descent_fmus.models.integrators import EVENT, OK, advance_to
from descent_fmus.models.reentry import (T_PLUS, U_BOUNDS, ReentryParams, altitude, deviations,
                                         downrange, loads, rhs)

__all__ = ["HORIZON", "NOT_REACHED", "gate_weight", "predict_range", "predict_flight",
           "predict_step", "predicted_inputs", "predicted_load", "solve_control"]

#: Prediction horizon beyond the current time [s] (a flight that has not reached hf by then
#: counts as flying too far).
HORIZON = 2.0 * T_PLUS
#: Predicted range of a flight that does not reach hf within the horizon [m].
NOT_REACHED = 1.0e9


def gate_weight(x, c: float, gate: float, kd: float, model: ReentryParams) -> float:
    """Weight of the correction ``c`` at the state ``x``: 1 without a gate (``gate`` = 0) or for
    c <= 0 (less drag); for a braking c > 0, ``(1 - n/gate)^2`` while the drag load n is below
    ``gate`` [g] and 0 above it, n = kd v^2 exp(-lam h) / g0 the drag load of the model with the
    drag factor ``kd`` [1/m] at u = 0.  Braking thus goes where the load has slack (high up
    before the peak, low down after it) instead of raising the peak."""
    if gate <= 0.0 or c <= 0.0:
        return 1.0
    n = kd * (x[1] * x[1] + x[3] * x[3]) \
        * math.exp(-model.lam * (math.hypot(x[0], x[2]) - model.Rz)) / model.g0
    return (1.0 - n / gate) ** 2 if n < gate else 0.0


def predict_flight(x, control, kd: float, model: ReentryParams = ReentryParams(),
                   dt: float = 2.0, lam: float | None = None, record: bool = True):
    """The on-board prediction under a feedback ``control(x)`` evaluated and held every ``dt``:
    ``(range at hf [m] or NOT_REACHED, loads)`` with the drag factor ``kd`` = S rho0 / m [1/m]
    and the inverse scale height ``lam`` (default the model's); ``loads`` are the paper's load
    (models.reentry.loads) at both ends of every step under that step's control (both
    one-sided values of every control change, as the plant samples them) and at the landing
    (an empty list without ``record``)."""
    lam = model.lam if lam is None else lam
    rz = model.constants()[3]
    x, t, samples = tuple(x), 0.0, []
    while t < HORIZON - 1e-9:
        u = control(x)
        if record:
            samples.append(predicted_load(x, u, kd, lam, model))
        x, outcome = predict_step(x, u, kd, lam, model, dt)
        if outcome == EVENT:
            if record:
                samples.append(predicted_load(x, u, kd, lam, model))
            return downrange(x, rz), samples
        if outcome != OK:
            break
        if record:       # the left-hand value at the step's end: the load jumps with u there
            samples.append(predicted_load(x, u, kd, lam, model))
        t += dt
    return NOT_REACHED, samples


def predicted_load(x, u: float, kd: float, lam: float, model: ReentryParams) -> float:
    """The paper's load (:func:`models.reentry.loads`) at the state ``x`` under the control
    ``u`` with the drag factor ``kd`` [1/m] and the inverse scale height ``lam`` [1/m] of an
    estimated profile (``model``'s other constants)."""
    gm, _, _, rz = model.constants()
    return loads(x, rhs(x, u, gm, kd, lam, rz), kd, lam, rz, model.g0, u)[0]


def predicted_inputs(xp, line: ReentryParams, rz: float, log_factor: float, dlam: float,
                     h_now: float):
    """The guided law's inputs at a predicted state ``xp``: y1, y2 (the deviations from
    ``line``'s straight line) and y3, the log factor the fitted profile gives at the altitude of
    ``xp`` (``log_factor`` at ``h_now``, its slope ``dlam`` the profile's lam minus the
    model's)."""
    y1, y2 = deviations(xp, line)
    return y1, y2, log_factor - dlam * (altitude(xp, rz) - h_now)


def predict_step(x, u: float, kd: float, lam: float, model: ReentryParams, dt: float):
    """One step ``dt`` of the on-board prediction (:func:`predict_flight`) under the held
    control ``u``: ``(x, outcome)``, the state after it -- at h = hf if the step reaches it
    (outcome EVENT) -- and :func:`models.integrators.advance_to`'s outcome."""
    gm, _, _, rz = model.constants()
    rz_hf = rz + model.hf
    x, _, outcome = advance_to(rhs, x, 0.0, dt, dt, (u, gm, kd, lam, rz),
                               event=lambda y: math.hypot(y[0], y[2]) - rz_hf)
    return x, outcome


def predict_range(x, u, kd: float, model: ReentryParams = ReentryParams(),
                  dt: float = 2.0, lam: float | None = None) -> float:
    """Predicted down-range [m] at h = hf from state ``x`` with the drag factor ``kd`` =
    S rho0 / m [1/m], the inverse scale height ``lam`` (default the model's) and the control
    ``u``: a number held over the whole prediction, or a function ``u(x)`` of the predicted
    state, evaluated and held every ``dt`` (:func:`predict_flight`); :data:`NOT_REACHED` if hf
    is not reached within the horizon (a flight that goes on counts as far too long)."""
    if callable(u):
        return predict_flight(x, u, kd, model, dt, lam, record=False)[0]
    gm, _, lam_m, rz = model.constants()
    rz_hf = rz + model.hf
    xe, _, outcome = advance_to(rhs, tuple(x), 0.0, HORIZON, dt,
                                (u, gm, kd, lam_m if lam is None else lam, rz),
                                event=lambda y: math.hypot(y[0], y[2]) - rz_hf)
    return downrange(xe, rz) if outcome == EVENT else NOT_REACHED


def solve_control(miss, u0: float, tol: float, max_iter: int, bounds=U_BOUNDS):
    """The u in ``bounds`` with ``miss(u) = 0`` (``miss`` decreasing in u), from the guess u0.

    The guess and one bound bracket the root (if even the bound cannot null the miss, that
    bound is the answer); Brent's method (scipy) then finds it to ``tol`` metres of miss.
    Returns ``(u, miss(u), evaluations)``.
    """
    from scipy.optimize import brentq
    lo, hi = bounds
    u0 = min(max(u0, lo), hi)
    f0 = miss(u0)
    if abs(f0) <= tol:
        return u0, f0, 1
    end = hi if f0 > 0.0 else lo                  # too far: more drag; too short: less
    fe = miss(end)
    if (fe >= 0.0) == (f0 > 0.0):
        return end, fe, 2
    calls = [2]

    def counted(u):
        calls[0] += 1
        return miss(u)
    slope = abs(fe - f0) / abs(end - u0)          # m of miss per unit of u over the bracket
    u = brentq(counted, min(u0, end), max(u0, end), xtol=tol / slope, maxiter=max_iter,
               disp=False)
    return u, miss(u), calls[0] + 1
