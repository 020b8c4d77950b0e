"""RK4 with a control that is linear in time over the step (first-order hold), on tuples.

Used by the telescope plants (S4) inside their FMUs and by
:mod:`synthesis.methods.direct_method`, so that the solver and the FMU replay integrate the same
piecewise-linear control with the same formula (identical sub-steps give identical results to
rounding).

``f(x, u)`` returns the derivative tuple of the state tuple ``x`` for the control tuple ``u``.

References
----------
S.A. Voronov, PhD thesis (2009), ch. 2: the controls are sought in the class of piecewise-linear
functions of time.
"""
from __future__ import annotations

__all__ = ["rk4_linear_input_step", "propagate_linear_input"]


def rk4_linear_input_step(f, x, h, u0, u1):
    """One classical RK4 step of size ``h`` [s] with ``u`` linear from ``u0`` to ``u1``."""
    um = tuple(0.5 * (a + b) for a, b in zip(u0, u1))
    h2 = 0.5 * h
    k1 = f(x, u0)
    k2 = f(tuple(a + h2 * b for a, b in zip(x, k1)), um)
    k3 = f(tuple(a + h2 * b for a, b in zip(x, k2)), um)
    k4 = f(tuple(a + h * b for a, b in zip(x, k3)), u1)
    h6 = h / 6.0
    return tuple(a + h6 * (b1 + 2.0 * (b2 + b3) + b4)
                 for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4))


def propagate_linear_input(f, x, span, u0, du, n, out=None):
    """Advance ``x`` over ``span`` [s] in ``n`` RK4 steps with ``u(s) = u0 + du * s``.

    ``out`` (a list) receives the state after every sub-step if given.  Returns the final state.
    """
    h = span / n
    ua = tuple(u0)
    for i in range(1, n + 1):
        s = i * h
        ub = tuple(a + b * s for a, b in zip(u0, du))
        x = rk4_linear_input_step(f, x, h, ua, ub)
        if out is not None:
            out.append(x)
        ua = ub
    return x
