"""The direct (Newton-Kantorovich) method for two-point boundary problems with a control.

Problem: find a piecewise-linear control ``u(t)`` on a uniform grid such that the solution of

    dx/dt = f(x, u),   x(t0) = x0

hits ``x_i(tf) = xf_i`` for the chosen components ``i`` (to a tolerance ``tol`` on each of them),
with ``u(t0)`` and ``u(tf)`` kept at their initial-guess values (the thesis' u(t0) = u(tf) = 0;
``free_end`` leaves ``u(tf)`` free, as the stages of a route need).  Options of the problem:

* ``u_max`` -- rate limits ``|u_j(t)| <= u_max_j``, enforced at the nodes (hence everywhere: ``u``
  is linear between them).  Every correction is computed with the nodes it would push over a
  limit held *at* the limit (they leave the basis; the end conditions are met by the others),
  so every iterate respects the limits.  When the held nodes leave too few to steer the end
  conditions, the iteration aims at half the miss (then a quarter, ...); when even that fails it
  stops with :class:`SaturatedError` (the limit is too small);
* ``minimize_energy`` -- among the controls meeting the end conditions, the one with the least
  ``E = int |u|^2 dt`` (exact for the piecewise-linear class: ``E = sum_j p_j^T M p_j`` with the
  mass matrix ``M`` of the hat functions).  Each iteration is a Newton step on the optimality
  (KKT) conditions ``grad E = G^T nu``, ``x_S(tf) = xf_S``: the quadratic programme
  ``min grad E . dp + dp^T W dp / 2`` subject to the linearised end conditions, with ``W`` the
  Hessian of the Lagrangian -- ``2 M`` minus the end conditions' curvature
  ``d2 (nu . x_S(tf)) / dp2``, computed by the second-order adjoint formula (forward
  sensitivities, the adjoint, second derivatives of ``f`` by differences of the Jacobian).  An
  l1 merit function ``E + mu |miss|_1`` decides the step length (with one second-order
  correction of the end conditions before halving); it stops when the end conditions hold and
  ``E`` changes by less than ``energy_rtol`` (relative) in an iteration.  Without the curvature
  term (Gauss-Newton) the iteration converges only linearly on Example 1 (24 iterations instead
  of 10).

Iteration ``k`` (Voronov 2009, ch. 1-2):

1. integrate the nonlinear system with ``u^k`` (RK4, sub-steps aligned with the control grid;
   the control is linear over every sub-step) -> ``x^k(t)`` and the miss ``dx_f = xf - x^k(tf)``;
2. linearise along ``(x^k, u^k)``: ``A(t) = df/dx``, ``B(t) = df/du`` (analytic Jacobian of the
   model, or of a *reduced* model on a projection of the state -- the thesis' reduced algorithm);
3. the fundamental matrix gives the impulse response ``H(tf, s) = Phi(tf, s) B(s)``; its rows
   for the end conditions are propagated backwards (``Psi(s) = Phi(tf, s)``, the adjoint form);
4. the correction is sought in the basis of impulse responses modified at the ends,
   ``du(t) = w(t) H_S(tf, t)^T c`` with a cubic blending window ``w`` (0 at t0 and tf, 1 in
   ``[t0 + a (tf-t0), tf - a (tf-t0)]``) so that ``du(t0) = du(tf) = 0``;
5. the Gram system ``Q c = dx_f,S`` with ``Q = d x_S(tf) / d(node values) . [w H_S^T]`` (exact
   for the piecewise-linear control class: the sensitivities of the node values are the
   integrals of ``H`` against the hat functions, by Simpson's rule on the sub-steps);
6. ``u^{k+1} = u^k + du`` (halved if the miss would grow; a loop that cannot reduce the miss
   stops with :class:`ConvergenceError`).

With ``minimize_energy`` steps 4-5 are replaced by the minimum-energy step above (the first
step from ``u = 0``, where ``nu = 0``, is a minimum-norm correction).

``S`` is the *adaptive selection of independent end conditions* (Voronov 2009, ch. 2): first
integrals (quaternion norm, angular momentum) make the end conditions linearly dependent, so at
every iteration the numerical rank ``r`` of their sensitivity rows is found by SVD and, among the
subsets of ``r`` rows that are well conditioned, the one that leaves out the components with the
smallest miss is used (the thesis forms the independent sub-vector from the components with the
worst accuracy).  The end conditions left out are met through the first integrals.

The code: the discretised problem and its data types in :mod:`synthesis.methods.direct_problem`,
one correction (steps 2-5, the selection of ``S``, the minimum-energy step) in
:mod:`synthesis.methods.direct_step`, the iteration (steps 1 and 6, the merit function, the
second-order correction) here.  Every public name is importable from this module.

References
----------
S.A. Voronov, PhD thesis (2009), ch. 1 (basic algorithm, Gram system), ch. 2 (basis
modification at the ends, reduced algorithm, adaptive choice of independent variables), ch. 3
(limits on the gimbal rates).  J. Nocedal, S.J. Wright, Numerical Optimization (2006), ch. 18
(SQP, l1 merit function, second-order correction).
"""
from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np

from descent_fmus.synthesis.methods.direct_problem import (BoundaryProblem, ConvergenceError,
                                                           DirectResult, Discretisation,
                                                           LinearModel, SaturatedError,
                                                           SingularGramError, blend_window,
                                                           control_energy, fd_jacobian,
                                                           mass_matrix, simulate)
from descent_fmus.synthesis.methods.direct_step import (aimed_step, energy_correction,
                                                        linearise, select_conditions)

__all__ = ["BoundaryProblem", "LinearModel", "DirectResult", "ConvergenceError",
           "SingularGramError", "SaturatedError", "solve", "simulate", "blend_window",
           "fd_jacobian", "control_energy", "mass_matrix"]


@dataclass
class _Iterate:
    """The current iterate of :func:`solve` and what one iteration hands to the next.

    Attributes
    ----------
    P : ndarray
        Node values (intervals+1, n_u).
    t, X, U : ndarray
        Sub-step times, states and controls of its integration.
    miss : ndarray
        ``xf - x_S(tf)``.
    E : float
        Its control energy.
    mu : float
        Weight of the l1 merit function (energy mode; never decreases).
    nu : ndarray
        Multipliers of the end conditions from the last correction (energy mode).
    B : ndarray or None
        Hessian of the Lagrangian (energy mode): ``2 M`` until the multipliers are nonzero,
        then with the end conditions' curvature of the latest nonzero multipliers.
    settled : bool
        Energy mode: ``E`` changed by less than ``energy_rtol`` in the last iteration.
    """

    P: np.ndarray
    t: np.ndarray
    X: np.ndarray
    U: np.ndarray
    miss: np.ndarray
    E: float
    mu: float
    nu: np.ndarray
    B: np.ndarray | None
    settled: bool = False

    @classmethod
    def first(cls, grid: Discretisation, P: np.ndarray) -> "_Iterate":
        """The iterate of the initial node values ``P`` (integrated once)."""
        t, X, U = grid.simulate(P)
        return cls(P=P, t=t, X=X, U=U, miss=grid.miss(X), E=control_energy(grid.t_nodes, P),
                   mu=0.0, nu=np.zeros(len(grid.idx)),
                   B=2.0 * grid.Mk if grid.energy else None)


def _history_entry(iteration: int, miss, selected, step: float, energy: float,
                   held: int) -> dict:
    """One row of :attr:`DirectResult.history` (``miss`` is ``xf - x_S(tf)``)."""
    return dict(iteration=iteration, max_miss=float(np.max(np.abs(miss))), miss=(-miss).tolist(),
                selected=selected, step=step, energy=energy, held=held)


def _trial(grid: Discretisation, Pn):
    """Integrate the node values ``Pn``: ``(t, X, U, miss, max |miss|)``, or None if the
    integration diverges."""
    try:
        tn, Xn, Un = grid.simulate(Pn)
    except ConvergenceError:
        return None
    miss_n = grid.miss(Xn)
    return tn, Xn, Un, miss_n, float(np.max(np.abs(miss_n)))


def _accepted(Pn, out, *, grid: Discretisation, last: float, tol: float, mu: float,
              merit0: float | None) -> bool:
    """Whether the trial ``out`` of ``Pn`` (:func:`_trial`) is accepted: its miss is below the
    last one ``last``; in energy mode, the l1 merit function ``E + mu |miss|_1`` decreased from
    ``merit0``, or every end condition is met and the miss did not grow."""
    if out is None:
        return False
    if not grid.energy:
        return out[4] < last
    return (control_energy(grid.t_nodes, Pn) + mu * float(np.sum(np.abs(out[3]))) < merit0
            or out[4] < min(tol, last))


def _second_order_correction(grid: Discretisation, S, sel, free, Pn, out, it: int):
    """Restore the end conditions that the full step ``Pn`` (trial ``out``) missed through
    their curvature, with the same linearisation: the least-norm correction on the free nodes
    ``free`` (``S`` the sensitivities of the selected end conditions ``sel``).  Returns
    ``(Pc, trial of Pc)``, or None if the correction is singular."""
    try:
        d2 = energy_correction(np.zeros_like(Pn), S, out[3][sel], free, np.zeros_like(grid.Mk),
                               2.0 * grid.Mk, it)[0]
    except SingularGramError:
        return None
    lim = grid.lim
    Pc = Pn + d2 if lim is None else np.clip(Pn + d2, -lim, lim)
    return Pc, _trial(grid, Pc)


def _line_search(grid: Discretisation, S, sel, free, P, dP, accept, max_halvings: int,
                 it: int):
    """The nonlinear step from ``P`` along ``dP``, halved while ``accept`` refuses it.

    In energy mode a refused full step first gets one second-order correction
    (:func:`_second_order_correction`): the end conditions' curvature, not the merit
    function's slope, is then what made it fail.  Returns ``(Pn, trial of Pn, step)``, or None
    when ``max_halvings`` halvings do not help.
    """
    lim = grid.lim
    step = 1.0
    for _ in range(max_halvings + 1):
        Pn = P + step * dP
        if lim is not None:             # (a convex combination: only rounding can cross)
            Pn = np.clip(Pn, -lim, lim)
        out = _trial(grid, Pn)
        if accept(Pn, out):
            return Pn, out, step
        if grid.energy and step == 1.0 and out is not None:
            corrected = _second_order_correction(grid, S, sel, free, Pn, out, it)
            if corrected is not None and accept(*corrected):
                return corrected + (step,)
        step *= 0.5
    return None


def _iteration(grid: Discretisation, cur: _Iterate, it: int, history: list, tol: float,
               max_halvings: int, energy_rtol: float) -> dict:
    """Iteration ``it``: linearise along ``cur``, correct, step; updates ``cur`` in place and
    returns the row of the history.

    Raises
    ------
    ConvergenceError
        The miss (or the merit function) cannot be reduced along the correction.
    SingularGramError
        The selected end conditions cannot be steered (``SaturatedError``: within the limits).
    """
    lin = linearise(grid, cur.X, cur.U)
    sel = select_conditions(lin.rows, cur.miss)
    if grid.energy and np.any(cur.nu):     # Newton-KKT: the Lagrangian's exact Hessian
        cur.B = 2.0 * grid.Mk - lin.curvature(grid, cur.nu)
    try:
        dP, mult, held, free = aimed_step(grid, lin, cur.P, cur.miss, sel, cur.B, max_halvings,
                                          it)
    except SingularGramError as exc:
        raise type(exc)(str(exc), history) from None
    merit0 = None
    if grid.energy:
        cur.mu = max(cur.mu, 2.0 * float(np.max(np.abs(mult))))
        cur.nu = np.zeros(len(grid.idx))
        cur.nu[sel] = mult
        merit0 = cur.E + cur.mu * float(np.sum(np.abs(cur.miss)))
    accept = functools.partial(_accepted, grid=grid, last=history[-1]["max_miss"], tol=tol,
                               mu=cur.mu, merit0=merit0)
    found = _line_search(grid, lin.S[:, sel, :], sel, free, cur.P, dP, accept, max_halvings, it)
    if found is None:
        raise ConvergenceError(f"iteration {it}: the miss {history[-1]['max_miss']:.3e} "
                               "cannot be reduced along the Newton direction (the target "
                               "may be unreachable from this initial guess)", history)
    Pn, (cur.t, cur.X, cur.U, cur.miss, _), step = found
    En = control_energy(grid.t_nodes, Pn)
    cur.settled = abs(En - cur.E) <= energy_rtol * max(En, 1e-300)
    cur.P, cur.E = Pn, En
    return _history_entry(it, cur.miss, [int(grid.problem.target_index[s]) for s in sel], step,
                          cur.E, held)


def solve(problem: BoundaryProblem, controls=None, tol: float = 1e-7, max_iter: int = 20,
          linear: LinearModel | None = None, max_halvings: int = 6,
          energy_rtol: float = 1e-6) -> DirectResult:
    """Solve the boundary problem by the direct method (see the module docstring).

    Parameters
    ----------
    problem : BoundaryProblem
    controls : array (intervals+1, n_u), optional
        Initial guess (default zero); its first row (and last, unless ``free_end``) is kept.
    tol : float
        Tolerance on every end condition (units of the state components).
    max_iter : int
        Maximum number of Newton corrections.
    linear : LinearModel, optional
        Model to linearise (default: ``problem.jac`` on the full state).  A reduced model gives
        the thesis' reduced algorithm: the miss is always that of the full ``problem.rhs``.
    max_halvings : int
        Step halvings per iteration before giving up.
    energy_rtol : float
        ``minimize_energy``: stop when the energy changes by less than this (relative) in an
        iteration that ends with every end condition within ``tol``.

    Returns
    -------
    DirectResult

    Raises
    ------
    ConvergenceError
        ``max_iter`` reached, or the miss cannot be reduced along the Newton direction.
    SingularGramError
        The Gram system is singular (with rate limits: too many nodes held at the limits).
    ValueError
        An initial guess of the wrong shape, or whose kept end values exceed the rate limits.
    """
    t_start = time.perf_counter()
    grid = Discretisation.of(problem, linear)
    cur = _Iterate.first(grid, grid.initial_controls(controls))
    history = [_history_entry(0, cur.miss, [], 0.0, cur.E, 0)]
    it = 0
    while history[-1]["max_miss"] >= tol or (grid.energy and not cur.settled):
        if it >= max_iter:
            raise ConvergenceError(f"no convergence to {tol:g} in {max_iter} iterations; misses "
                                   f"{['%.2e' % h_['max_miss'] for h_ in history]}", history)
        it += 1
        history.append(_iteration(grid, cur, it, history, tol, max_halvings, energy_rtol))
    return DirectResult(success=True, iterations=it, history=history, t_nodes=grid.t_nodes,
                        controls=cur.P, t=cur.t, states=cur.X, miss=-cur.miss,
                        seconds=time.perf_counter() - t_start,
                        target_index=tuple(grid.problem.target_index), u_max=grid.lim)
