"""The direct (Newton-Kantorovich) method for two-point boundary problems with a control.

Problem: find a piecewise-linear control ``u(t)`` on a uniform grid such that the solution of

    dx/dt = f(x, u),   x(t0) = x0

hits ``x_i(tf) = xf_i`` for the chosen components ``i`` (to a tolerance ``tol`` on each of them),
with ``u(t0)`` and ``u(tf)`` kept at their initial-guess values (the thesis' u(t0) = u(tf) = 0).

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

``S`` is the *adaptive selection of independent end conditions* (Voronov 2009, ch. 2): first
integrals (quaternion norm, angular momentum) make the end conditions linearly dependent, so at
every iteration the numerical rank ``r`` of their sensitivity rows is found by SVD and, among the
subsets of ``r`` rows that are well conditioned, the one that leaves out the components with the
smallest miss is used (the thesis forms the independent sub-vector from the components with the
worst accuracy).  The end conditions left out are met through the first integrals.

References
----------
S.A. Voronov, PhD thesis (2009), ch. 1 (basic algorithm, Gram system), ch. 2 (basis
modification at the ends, reduced algorithm, adaptive choice of independent variables).
"""
from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field

import numpy as np

from descent_fmus.models.rk4_input import rk4_linear_input_step

__all__ = ["BoundaryProblem", "LinearModel", "DirectResult", "ConvergenceError",
           "SingularGramError", "solve", "simulate", "blend_window", "fd_jacobian"]


class ConvergenceError(RuntimeError):
    """The iterations did not reach the tolerance; ``.history`` holds the misses so far."""

    def __init__(self, message, history=None):
        super().__init__(message)
        self.history = history or []


class SingularGramError(ConvergenceError):
    """The Gram matrix of the selected end conditions is singular: the linearised system cannot
    steer them (e.g. a singular gyro state or a target outside the reachable set)."""


@dataclass(frozen=True)
class LinearModel:
    """The model the method linearises (the *reduced* algorithm when it differs from the plant).

    Attributes
    ----------
    jac : callable
        ``jac(X, U) -> (A, B)`` with ``X`` (n, nr), ``U`` (n, nu) -> (n, nr, nr), (n, nr, nu).
    project : callable or None
        Maps full states (n, nx) to the reduced states (n, nr) (a linear map, e.g. a slice);
        ``None`` = identity.  The target indices refer to the reduced state.
    """

    jac: object
    project: object = None


@dataclass(frozen=True)
class BoundaryProblem:
    """``dx/dt = f(x, u)``, ``x(t0) = x0``, ``x_i(tf) = xf_i`` for ``i`` in ``target_index``.

    Attributes
    ----------
    rhs : callable
        ``f(x, u)`` on tuples of floats.
    x0 : tuple of float
        Initial state.
    tf : float
        Final time [s] (``t0`` = 0 unless given).
    target_index, target_value : tuple
        End conditions.
    n_u : int
        Number of controls.
    intervals : int
        Control grid intervals (node values are the unknowns).
    substeps : int
        RK4 sub-steps per control interval (even: Simpson's rule on pairs of sub-steps).
    blend : float
        Fraction ``a`` of ``[t0, tf]`` at each end over which the correction is blended to 0.
    jac : callable or None
        Analytic Jacobian ``jac(X, U) -> (A, B)`` of ``rhs``; ``None`` = finite differences.
    """

    rhs: object
    x0: tuple
    tf: float
    target_index: tuple
    target_value: tuple
    n_u: int
    t0: float = 0.0
    intervals: int = 40
    substeps: int = 10
    blend: float = 0.1
    jac: object = None

    def validate(self):
        if not (self.tf > self.t0 and math.isfinite(self.tf)):
            raise ValueError(f"need tf > t0, got t0={self.t0}, tf={self.tf}")
        if self.intervals < 2 or self.substeps < 2 or self.substeps % 2:
            raise ValueError("need intervals >= 2 and an even number of substeps >= 2, got "
                             f"{self.intervals}, {self.substeps}")
        if not 0.0 < self.blend < 0.5:
            raise ValueError(f"blend must be in (0, 0.5), got {self.blend}")
        if len(self.target_index) != len(self.target_value) or not self.target_index:
            raise ValueError("target_index and target_value must be non-empty, equal lengths")
        return self

    @property
    def nodes(self) -> np.ndarray:
        return np.linspace(self.t0, self.tf, self.intervals + 1)


@dataclass
class DirectResult:
    """Outcome of :func:`solve`.

    Attributes
    ----------
    success : bool
        Every end condition within ``tol``.
    iterations : int
        Newton corrections applied.
    history : list of dict
        Per integration of the plant: ``iteration``, ``max_miss`` (max |x_i(tf) - xf_i|),
        ``miss`` (vector), ``selected`` (end conditions in the Gram system), ``step`` (1 = full).
    t_nodes, controls : ndarray
        Control grid [s] and node values (intervals+1, n_u); ``u`` is linear between nodes.
    t, states : ndarray
        Sub-step times [s] and states of the last integration.
    miss : ndarray
        Final ``x_i(tf) - xf_i``.
    seconds : float
        Wall time of the solve [s].
    """

    success: bool
    iterations: int
    history: list
    t_nodes: np.ndarray
    controls: np.ndarray
    t: np.ndarray
    states: np.ndarray
    miss: np.ndarray
    seconds: float
    target_index: tuple = field(default=())

    def control(self, t) -> np.ndarray:
        """u(t) by linear interpolation of the node values, shape (len(t), n_u)."""
        t = np.atleast_1d(np.asarray(t, float))
        return np.stack([np.interp(t, self.t_nodes, c) for c in self.controls.T], -1)

    @property
    def max_miss(self) -> float:
        return float(np.max(np.abs(self.miss)))


def blend_window(t, t0: float, tf: float, a: float) -> np.ndarray:
    """Cubic blending window: 0 at t0 and tf, 1 on [t0 + a T, tf - a T], C1 (smoothstep)."""
    t = np.asarray(t, float)
    span = a * (tf - t0)
    s = np.clip(np.minimum(t - t0, tf - t) / span, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def simulate(rhs, x0, t_nodes, controls, substeps: int):
    """Integrate with the piecewise-linear control; returns (t, X (n+1, nx), U (n+1, nu)).

    Sub-step ``j`` of interval ``i`` uses the control linear between its ends (the same formula
    as the telescope FMUs, ``models.rk4_input``).
    """
    P = [tuple(float(v) for v in row) for row in controls]
    x = tuple(float(v) for v in x0)
    xs = [x]
    m = substeps
    ts = [float(t_nodes[0])]
    us = [P[0]]
    for i in range(len(t_nodes) - 1):
        span = float(t_nodes[i + 1] - t_nodes[i])
        h = span / m
        p0, p1 = P[i], P[i + 1]
        ua = p0
        for j in range(1, m + 1):
            s = j / m
            ub = tuple(a + (b - a) * s for a, b in zip(p0, p1)) if j < m else p1
            x = rk4_linear_input_step(rhs, x, h, ua, ub)
            xs.append(x)
            us.append(ub)
            ts.append(float(t_nodes[i]) + j * h)
            ua = ub
    X = np.array(xs)
    if not np.all(np.isfinite(X)):
        raise ConvergenceError("the integration produced a non-finite state (the control "
                               "iterate is too large: the problem is far from solvable?)")
    return np.array(ts), X, np.array(us)


def fd_jacobian(rhs, eps: float = 1e-7):
    """A batch Jacobian ``jac(X, U)`` of ``rhs`` by central finite differences (fallback)."""
    def jac(X, U):
        n, nx = X.shape
        nu = U.shape[1]
        A = np.empty((n, nx, nx))
        B = np.empty((n, nx, nu))
        for k in range(n):
            x, u = X[k], U[k]
            for i in range(nx):
                d = np.zeros(nx)
                d[i] = eps * max(1.0, abs(x[i]))
                A[k, :, i] = (np.array(rhs(tuple(x + d), tuple(u)))
                              - np.array(rhs(tuple(x - d), tuple(u)))) / (2 * d[i])
            for i in range(nu):
                d = np.zeros(nu)
                d[i] = eps
                B[k, :, i] = (np.array(rhs(tuple(x), tuple(u + d)))
                              - np.array(rhs(tuple(x), tuple(u - d)))) / (2 * eps)
        return A, B
    return jac


def _transitions(A0, Am, A1, h):
    """RK4 transition matrices of dPhi/dt = A(t) Phi over steps of size h (batched)."""
    I = np.eye(A0.shape[-1])
    K1 = A0
    K2 = Am @ (I + 0.5 * h * K1)
    K3 = Am @ (I + 0.5 * h * K2)
    K4 = A1 @ (I + h * K3)
    return I + (h / 6.0) * (K1 + 2.0 * (K2 + K3) + K4)


def _select(rows: np.ndarray, miss: np.ndarray, rank_tol: float = 1e-7):
    """Indices of an independent, well-conditioned subset of ``rows`` leaving out small misses."""
    nrm = np.linalg.norm(rows, axis=1)
    ok = nrm > 0
    R = rows[ok] / nrm[ok, None]
    cand = np.flatnonzero(ok)
    sv = np.linalg.svd(R, compute_uv=False)
    r = int(np.sum(sv > rank_tol * sv[0]))
    if r == len(cand):
        return list(cand)
    subsets = list(itertools.combinations(range(len(cand)), r))
    if len(subsets) > 200:       # many candidates: pivoted QR ordered by miss
        from scipy.linalg import qr
        order = np.argsort(-np.abs(miss[cand]))
        _, _, piv = qr(R[order].T, pivoting=True, mode="economic")
        return sorted(int(cand[order[i]]) for i in piv[:r])
    conds = []
    for sub in subsets:
        s = np.linalg.svd(R[list(sub)], compute_uv=False)
        conds.append(s[0] / s[-1] if s[-1] > 0 else np.inf)
    best = min(conds)
    good = [sub for sub, c in zip(subsets, conds) if c <= 10.0 * best]
    left_out = lambda sub: sum(abs(miss[cand[i]]) for i in range(len(cand))  # noqa: E731
                               if i not in sub)
    sub = min(good, key=left_out)
    return [int(cand[i]) for i in sub]


def solve(problem: BoundaryProblem, controls=None, tol: float = 1e-7, max_iter: int = 20,
          linear: LinearModel | None = None, max_halvings: int = 6) -> DirectResult:
    """Solve the boundary problem by the direct method (see the module docstring).

    Parameters
    ----------
    problem : BoundaryProblem
    controls : array (intervals+1, n_u), optional
        Initial guess (default zero); its first and last rows are kept.
    tol : float
        Tolerance on every end condition (units of the state components).
    max_iter : int
        Maximum number of Newton corrections.
    linear : LinearModel, optional
        Model to linearise (default: ``problem.jac`` on the full state).  A reduced model gives
        the thesis' reduced algorithm: the miss is always that of the full ``problem.rhs``.

    Returns
    -------
    DirectResult

    Raises
    ------
    ConvergenceError
        ``max_iter`` reached, or the miss cannot be reduced along the Newton direction.
    SingularGramError
        The Gram system is singular.
    """
    t_start = time.perf_counter()
    pb = problem.validate()
    t_nodes = pb.nodes
    N, m, nu = pb.intervals, pb.substeps, pb.n_u
    P = np.zeros((N + 1, nu)) if controls is None else np.array(controls, float).copy()
    if P.shape != (N + 1, nu):
        raise ValueError(f"controls must have shape {(N + 1, nu)}, got {P.shape}")
    if linear is None:
        linear = LinearModel(pb.jac or fd_jacobian(pb.rhs))
    project = linear.project or (lambda X: X)
    idx = np.array(pb.target_index)
    xf = np.array(pb.target_value, float)
    h = (t_nodes[1] - t_nodes[0]) / m
    w_nodes = blend_window(t_nodes, pb.t0, pb.tf, pb.blend)
    simpson = np.ones(m + 1)
    simpson[1:-1:2], simpson[2:-1:2] = 4.0, 2.0
    simpson *= h / 3.0
    frac = np.arange(m + 1) / m

    t, X, U = simulate(pb.rhs, pb.x0, t_nodes, P, m)
    miss = xf - X[-1, idx]
    history = [dict(iteration=0, max_miss=float(np.max(np.abs(miss))), miss=(-miss).tolist(),
                    selected=[], step=0.0)]
    it = 0
    while history[-1]["max_miss"] >= tol:
        if it >= max_iter:
            raise ConvergenceError(f"no convergence to {tol:g} in {max_iter} iterations; misses "
                                   f"{['%.2e' % h_['max_miss'] for h_ in history]}", history)
        it += 1
        # -- linearise along (x^k, u^k) (reduced state if a reduced model is given) ----------
        F = np.array([pb.rhs(tuple(x), tuple(u)) for x, u in zip(X, U)])
        Xr, Fr = project(X), project(F)
        Xm = 0.5 * (Xr[:-1] + Xr[1:]) + (h / 8.0) * (Fr[:-1] - Fr[1:])   # Hermite midpoints
        Um = 0.5 * (U[:-1] + U[1:])
        A, B = linear.jac(Xr, U)
        Am, _ = linear.jac(Xm, Um)
        M = _transitions(A[:-1], Am, A[1:], h)
        # -- rows of Phi(tf, s) for the end conditions, backwards (adjoint) -------------------
        nr = Xr.shape[1]
        Psi = np.empty((len(t), len(idx), nr))
        Psi[-1] = np.eye(nr)[idx]
        for k in range(len(t) - 2, -1, -1):
            Psi[k] = Psi[k + 1] @ M[k]
        H = Psi @ B                                             # (n+1, r_c, nu) impulse response
        # -- sensitivities of x_S(tf) to the node values: integrals of H against hat functions --
        Hi = np.stack([H[i * m:(i + 1) * m + 1] for i in range(N)])      # (N, m+1, r_c, nu)
        S = np.zeros((N + 1,) + H.shape[1:])
        S[:-1] += np.einsum("j,ijrk->irk", simpson * (1.0 - frac), Hi)
        S[1:] += np.einsum("j,ijrk->irk", simpson * frac, Hi)
        rows = S.transpose(1, 0, 2).reshape(len(idx), -1)
        sel = _select(rows, miss)
        # -- Gram system for the end-blended impulse-response basis ----------------------------
        Hn = H[::m][:, sel, :] * w_nodes[:, None, None]                 # (N+1, r, nu)
        Q = np.einsum("nrk,nsk->rs", S[:, sel, :], Hn)
        scale = 1.0 / np.linalg.norm(Q, axis=1)
        Qs = Q * scale[:, None]
        cond = np.linalg.cond(Qs)
        if not np.isfinite(cond) or cond > 1e13:
            raise SingularGramError(f"Gram matrix singular at iteration {it} (condition "
                                    f"{cond:.2e}): the selected end conditions cannot be steered",
                                    history)
        c = np.linalg.solve(Qs, miss[sel] * scale)
        dP = np.einsum("nrk,r->nk", Hn, c)
        # -- nonlinear step (halved while the miss grows) --------------------------------------
        step = 1.0
        for _ in range(max_halvings + 1):
            Pn = P + step * dP
            try:
                tn, Xn, Un = simulate(pb.rhs, pb.x0, t_nodes, Pn, m)
                miss_n = xf - Xn[-1, idx]
                mm = float(np.max(np.abs(miss_n)))
            except ConvergenceError:
                mm = math.inf
            if mm < history[-1]["max_miss"]:
                break
            step *= 0.5
        else:
            raise ConvergenceError(f"iteration {it}: the miss {history[-1]['max_miss']:.3e} "
                                   "cannot be reduced along the Newton direction (the target "
                                   "may be unreachable from this initial guess)", history)
        P, t, X, U, miss = Pn, tn, Xn, Un, miss_n
        history.append(dict(iteration=it, max_miss=mm, miss=(-miss).tolist(),
                            selected=[int(pb.target_index[s]) for s in sel], step=step))
    return DirectResult(success=True, iterations=it, history=history, t_nodes=t_nodes,
                        controls=P, t=t, states=X, miss=-miss,
                        seconds=time.perf_counter() - t_start,
                        target_index=tuple(pb.target_index))
