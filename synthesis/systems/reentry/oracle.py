"""The physical bound of S1 guidance under dispersion: the oracle that knows the true parameters.

For one sample of the dispersion set (true rho0, m, V0, beta0), a guidance that knew them could
hold any constant control u in [-0.2, 0.2] from entry.  The range at hf is continuous and
decreasing in u (more drag, shorter flight), so the reachable ranges of constant controls form
the interval [L(u = +0.2), L(u = -0.2)]; the oracle's miss is the distance from Lf to that
interval -- 0 when some constant u lands exactly.  Feedback with imperfect knowledge cannot do
better with constant controls; a sample outside the interval is missed by every law that keeps
|u| <= 0.2 (up to what a varying control adds at the ends, which the study measures).

The flights use the plant's own integrator (:func:`models.reentry.simulate`: the code the
Reentry FMU runs, RK4 sub-steps of 0.5 s, the landing located inside the step).
"""
from __future__ import annotations

from dataclasses import dataclass

from descent_fmus.models.integrators import REACHED
from descent_fmus.models.reentry import U_BOUNDS, ReentryParams, downrange, simulate

__all__ = ["OracleBound", "oracle_bound", "constant_control_range"]


def constant_control_range(p: ReentryParams, u: float) -> float:
    """Range at hf [m] of the flight with the constant control ``u`` (``inf`` if hf is never
    reached within t+)."""
    fi = simulate(p, lambda t, x: u)
    return downrange(fi.x, p.Rz) if fi.status == REACHED else float("inf")


@dataclass(frozen=True)
class OracleBound:
    """The reachable interval of constant controls for one sample and the oracle's miss."""

    L_min: float     #: range at hf with u = +0.2 (most drag) [m]
    L_max: float     #: range at hf with u = -0.2 (least drag) [m]
    miss: float      #: distance from Lf to [L_min, L_max] [m]
    exact: bool      #: Lf inside the interval (some constant u lands exactly)


def oracle_bound(p: ReentryParams) -> OracleBound:
    """The oracle bound of one sample (two flights)."""
    lo = constant_control_range(p, U_BOUNDS[1])
    hi = constant_control_range(p, U_BOUNDS[0])
    if lo <= p.Lf <= hi:
        return OracleBound(lo, hi, 0.0, True)
    return OracleBound(lo, hi, min(abs(p.Lf - lo), abs(p.Lf - hi)), False)
