"""S1 on-board re-planning of where the capsule brakes: a shaped correction of a feedback law.

The guided law adds a correction to a synthesised law's clipped output.  A single number c for
the rest of the flight moves the range but also brakes at the load peak; the best programs per
sample instead *move* the braking to where the load has slack.  The shaped correction is a
bank of hat functions of the altitude (a partition of unity on :data:`PLAN_KNOTS`),

    u = clip(clip(phi(y)) + sum_j c_j b_j(h)),

and every guidance cycle :func:`replan` re-solves its weights c on board from the navigated
state with the estimated density profile:

1. one sequential linear-programming step (``iterations`` of them): the prediction and its
   finite-difference derivatives in each c_j (``K + 1`` predictions) give the linearised
   minimax problem -- minimise s + effort sum |c_j| subject to every predicted load sample
   <= s, s >= the peak already flown, predicted miss = 0, |c_j| <= c_max, a trust region --
   solved by SciPy's HiGHS (where the miss cannot be nulled, the least |miss| instead);
2. a uniform offset of all weights (the partition of unity makes it the plain correction)
   solved by the predictor-corrector's root search nulls the predicted miss whatever the
   linearisation missed.

The plan carries over from cycle to cycle (warm start), so the linearisation is repeated on
the flight's own time scale.

References
----------
Lu, "Entry guidance: a unified method", J. Guidance, Control, and Dynamics 37(3), 2014
(predictor-corrector guidance that re-solves a parametrised profile every cycle).
"""
from __future__ import annotations

import numpy as np

__all__ = ["PLAN_KNOTS", "plan_weights", "plan_value", "replan", "lp_step", "lp_problems"]

#: Altitudes [m] of the hat functions' peaks [choice]: above the first knot the first weight
#: acts alone, below the last the last; between them the two neighbours interpolate.  The
#: nominal flight's load peaks between 40 and 60 km (t = 125-195 s), where the knots are
#: closest.  Nine knots: on four reachable samples of the scale-height family's tuning set
#: (seed 11) J1 was 1.4-6.6 % above the load oracle against 2.6-7.7 % with five (80, 62, 50,
#: 38, 22 km); thirteen were no better (one sample better, one worse) at 15 % more time.
PLAN_KNOTS = (85_000.0, 72_000.0, 62_000.0, 55_000.0, 48_000.0, 42_000.0, 36_000.0, 30_000.0,
              22_000.0)
#: Finite-difference step of the weights.
FD_STEP = 0.02
#: Scale of the miss in the linear programme [m] (keeps its rows of the size of the loads').
MISS_SCALE = 1.0e4


def plan_weights(h: float, knots=PLAN_KNOTS) -> list:
    """The hat functions b_j at the altitude ``h`` (they sum to 1)."""
    k = len(knots)
    w = [0.0] * k
    if h >= knots[0]:
        w[0] = 1.0
        return w
    if h <= knots[-1]:
        w[-1] = 1.0
        return w
    for j in range(k - 1):
        if h >= knots[j + 1]:
            f = (h - knots[j + 1]) / (knots[j] - knots[j + 1])
            w[j], w[j + 1] = f, 1.0 - f
            return w
    return w


def plan_value(c, h: float, knots=PLAN_KNOTS) -> float:
    """The correction sum_j c_j b_j(h)."""
    return sum(cj * wj for cj, wj in zip(c, plan_weights(h, knots)))


def _columns(evaluate, c, c_max):
    """The prediction at ``c`` and the finite-difference derivatives of its miss and loads."""
    m0, l0 = evaluate(c)
    cols, dm = [], []
    for j in range(len(c)):
        step = FD_STEP if c[j] + FD_STEP <= c_max else -FD_STEP
        cj = list(c)
        cj[j] += step
        mj, lj = evaluate(cj)
        cols.append((lj, step))
        dm.append((mj - m0) / step)
    n = min([len(l0)] + [len(lj) for lj, _ in cols])
    l0a = np.asarray(l0[:n], float)
    G = np.column_stack([(np.asarray(lj[:n], float) - l0a) / s for lj, s in cols])
    return m0, l0a, np.asarray(dm), G


def lp_problems(m0, l0, dm, G, c, c_max, trust, effort, floor) -> tuple:
    """The two linear programmes of :func:`lp_step` as :func:`scipy.optimize.linprog`'s
    keyword arguments: the minimax step (variables Delta_1..k, s, t_1..k: minimise
    s + effort sum t subject to G Delta - s <= -l0, s >= floor, t_j >= |c_j + Delta_j|, the
    linearised miss dm Delta + m0 = 0, the trust region and |c + Delta| <= c_max), and the
    least |miss| within the same box (variables Delta, e)."""
    k, n = len(c), len(l0)
    c = np.asarray(c, float)
    dm = np.asarray(dm, float)
    lo = np.maximum(-trust, -c_max - c)
    hi = np.minimum(trust, c_max - c)
    cost = np.concatenate([np.zeros(k), [1.0], np.full(k, effort)])
    a_ub = np.zeros((n + 1 + 2 * k, 2 * k + 1))
    a_ub[:n, :k], a_ub[:n, k] = G, -1.0
    a_ub[n, k] = -1.0
    eye = np.eye(k)
    a_ub[n + 1:n + 1 + k, :k], a_ub[n + 1:n + 1 + k, k + 1:] = eye, -eye
    a_ub[n + 1 + k:, :k], a_ub[n + 1 + k:, k + 1:] = -eye, -eye
    b_ub = np.concatenate([-np.asarray(l0, float), [-floor], -c, c])
    bounds = [(a, b) for a, b in zip(lo, hi)] + [(None, None)] + [(0.0, None)] * k
    minimax = dict(c=cost, A_ub=a_ub, b_ub=b_ub,
                   A_eq=(np.concatenate([dm, np.zeros(k + 1)]) / MISS_SCALE)[None, :],
                   b_eq=[-m0 / MISS_SCALE], bounds=bounds)
    row = np.concatenate([dm / MISS_SCALE, [-1.0]])
    least = dict(c=np.concatenate([np.zeros(k), [1.0]]),
                 A_ub=np.vstack([row, np.concatenate([-dm / MISS_SCALE, [-1.0]])]),
                 b_ub=[-m0 / MISS_SCALE, m0 / MISS_SCALE],
                 bounds=[(a, b) for a, b in zip(lo, hi)] + [(0.0, None)])
    return minimax, least


def lp_step(m0, l0, dm, G, c, c_max, trust, effort, floor):
    """The linearised minimax step Delta of the weights (see the module docstring): the
    minimax programme of :func:`lp_problems`, where it has no solution the least |miss|, where
    that has none either no step."""
    from scipy.optimize import linprog
    k = len(c)
    minimax, least = lp_problems(m0, l0, dm, G, c, c_max, trust, effort, floor)
    res = linprog(**minimax, method="highs")
    if res.status == 0:
        return res.x[:k]
    res = linprog(**least, method="highs")
    return res.x[:k] if res.status == 0 else np.zeros(k)


def replan(evaluate, c, c_max: float, trust: float, effort: float, floor: float,
           iterations: int, solve_offset):
    """One guidance cycle's plan (module docstring).  ``evaluate(c) -> (miss, loads)`` is the
    prediction under the weights c; ``solve_offset(miss_of_offset)`` the root search of the
    uniform offset (``(offset, miss, evaluations)``).  Returns ``(c, miss, predictions)``."""
    c = [min(max(v, -c_max), c_max) for v in c]
    n = 0
    for _ in range(iterations):
        m0, l0, dm, G = _columns(evaluate, c, c_max)
        n += len(c) + 1
        delta = lp_step(m0, l0, dm, G, c, c_max, trust, effort, floor)
        c = [min(max(v + d, -c_max), c_max) for v, d in zip(c, delta)]

    def shifted(offset):
        return [min(max(v + offset, -c_max), c_max) for v in c]
    offset, miss, k = solve_offset(lambda o: evaluate(shifted(o))[0])
    return shifted(offset), miss, n + k
