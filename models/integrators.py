"""Fixed-step integrators on plain tuples of floats, shared by every plant FMU.

The plants advance inside ``do_step`` with the classical 4th-order Runge-Kutta method on
sub-steps of a documented size.  States are tuples of Python floats: for the 4-17 element states
of descent-fmus this is several times faster than NumPy arrays (measured: a 4-element RK4 step
costs about 4 us on tuples, 15 us on arrays).

``f(x, *args)`` returns the derivative tuple of the state tuple ``x``.

Every plant's integrator derives from :class:`Integrator` (time, state, sub-step, the status
convention) and advances with :func:`advance_to`, the one stepping loop of the project.
"""
from __future__ import annotations

import math

from descent_fmus.models.params import require_positive

__all__ = ["rk4_step", "rk4_step_with_k1", "locate_crossing", "advance_to", "OK", "EVENT",
           "DIVERGED", "Integrator", "RUNNING", "REACHED", "CRASHED", "LEFT_DOMAIN",
           "STATUS_NAMES", "STATUS_DESCRIPTION", "T_END_DESCRIPTION"]

#: outcomes of :func:`advance_to`
OK, EVENT, DIVERGED = "ok", "event", "diverged"

#: The plant status convention: every plant FMU publishes one Integer ``status`` with these
#: values (and the Real ``t_end``); once it is non-zero the plant's state is frozen.
RUNNING, REACHED, CRASHED, LEFT_DOMAIN = 0, 1, 2, 3
STATUS_NAMES = {RUNNING: "running", REACHED: "reached", CRASHED: "crashed",
                LEFT_DOMAIN: "diverged"}
STATUS_DESCRIPTION = ("0 running, 1 reached its terminal condition, 2 crashed, 3 diverged or "
                      "left the model's domain; the state is frozen once non-zero [1]")
T_END_DESCRIPTION = "time the flight ended (status became non-zero), -1 before [s]"


class Integrator:
    """Time, state, RK4 sub-step and status of one plant integration (the base of every plant's
    integrator).

    Subclasses define :meth:`initial_state`, may extend :meth:`reset`, and advance with
    :func:`advance_to`, ending the flight with :meth:`end`.

    Parameters
    ----------
    dt : float or None
        RK4 sub-step [s] (> 0); None for a plant that chooses its own steps in ``advance``
        (a number of sub-steps per communication step, or an exact step in closed form).
    """

    def __init__(self, dt: float | None):
        self.dt = None if dt is None else require_positive("dt", dt)
        self.reset()

    def initial_state(self) -> tuple:
        raise NotImplementedError

    def reset(self) -> None:
        """Back to t = 0 at the initial state, running."""
        self.t = 0.0
        self.x = self.initial_state()
        self.status = RUNNING
        self.t_end = math.nan

    @property
    def running(self) -> bool:
        return self.status == RUNNING

    def end(self, status: int, t: float) -> None:
        """End the flight at time ``t`` [s] with a non-zero ``status``."""
        self.status = status
        self.t_end = t

    @property
    def t_end_output(self) -> float:
        """``t_end`` as the FMUs publish it: -1 while running."""
        return self.t_end if self.status else -1.0


def rk4_step_with_k1(f, x, k1, h, args):
    """One RK4 step of size ``h`` from ``x`` whose derivative ``k1 = f(x, *args)`` is known."""
    h2 = 0.5 * h
    k2 = f(tuple(a + h2 * b for a, b in zip(x, k1)), *args)
    k3 = f(tuple(a + h2 * b for a, b in zip(x, k2)), *args)
    k4 = f(tuple(a + h * b for a, b in zip(x, k3)), *args)
    h6 = h / 6.0
    return tuple(a + h6 * (b1 + 2.0 * (b2 + b3) + b4)
                 for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4))


def rk4_step(f, x, h, args):
    """One classical RK4 step of size ``h`` from the state tuple ``x``."""
    return rk4_step_with_k1(f, x, f(x, *args), h, args)


def locate_crossing(f, x0, k0, h, args, g, g0, g1, tol=1e-9, max_iter=30):
    """Find where the scalar event function ``g(x)`` crosses zero inside one RK4 step.

    ``x0`` is the state at the start of the step (``g(x0) = g0 > 0``), ``g1 = g(x(h)) <= 0`` at
    its end.  The fraction ``s`` of the step is found by the Illinois variant of regula falsi on
    ``s -> g(rk4(x0, s*h))``: every trial is one RK4 step of size ``s*h`` from ``x0``, as
    accurate as the regular step, so the crossing state has the integrator's own accuracy.

    Returns ``(s, x_s)``.
    """
    a, ga = 0.0, g0
    b, gb = 1.0, g1
    xs = None
    side = 0
    for _ in range(max_iter):
        s = (a * gb - b * ga) / (gb - ga)
        xs = rk4_step_with_k1(f, x0, k0, s * h, args)
        gs = g(xs)
        if abs(gs) <= tol or (b - a) < 1e-15:
            return s, xs
        if gs > 0.0:
            a, ga = s, gs
            if side == 1:
                gb *= 0.5
            side = 1
        else:
            b, gb = s, gs
            if side == -1:
                ga *= 0.5
            side = -1
    return s, xs


def advance_to(f, x, t0: float, t_end: float, dt: float, args, event=None, on_step=None,
               tol: float = 1e-9):
    """Integrate ``x' = f(x, *args)`` from ``(t0, x)`` to ``t_end`` on RK4 sub-steps <= ``dt``.

    The sub-steps divide ``[t0, t_end]`` evenly.  If ``event(x)`` (positive before the event)
    reaches 0 inside a sub-step, the crossing is located with :func:`locate_crossing` and the
    integration stops there.  ``on_step(x, k1)`` is called at the start of every sub-step with
    the derivative ``k1 = f(x, *args)`` (e.g. to sample loads).  A non-finite state, or an
    arithmetic error in ``f``, stops the integration at the last finite state.

    This is the one stepping loop of every plant FMU of the project.

    Returns
    -------
    (x, t, outcome) : tuple
        The state and time reached; ``outcome`` is :data:`OK` (reached ``t_end``),
        :data:`EVENT` (stopped at the event, ``t`` is its time) or :data:`DIVERGED`.
    """
    span = t_end - t0
    if span <= 0.0:
        return x, t0, OK
    n = max(1, math.ceil(span / dt - 1e-9))
    h = span / n
    isfinite = math.isfinite
    for i in range(n):
        try:
            k1 = f(x, *args)
            if on_step is not None:
                on_step(x, k1)
            xn = rk4_step_with_k1(f, x, k1, h, args)
        except (ArithmeticError, ValueError):
            return x, t0 + i * h, DIVERGED
        if not all(map(isfinite, xn)):
            return x, t0 + i * h, DIVERGED
        if event is not None:
            g1 = event(xn)
            if g1 <= 0.0:
                s, xs = locate_crossing(f, x, k1, h, args, event, event(x), g1, tol=tol)
                return xs, t0 + (i + s) * h, EVENT
        x = xn
    return x, t_end, OK
