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

References
----------
S.A. Voronov, PhD thesis (2009), ch. 1 (basic algorithm, Gram system), ch. 2 (basis
modification at the ends, reduced algorithm, adaptive choice of independent variables), ch. 3
(limits on the gimbal rates).  J. Nocedal, S.J. Wright, Numerical Optimization (2006), ch. 18
(SQP, l1 merit function, second-order correction).
"""
from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field

import numpy as np

from descent_fmus.models.rk4_input import rk4_linear_input_step

__all__ = ["BoundaryProblem", "LinearModel", "DirectResult", "ConvergenceError",
           "SingularGramError", "SaturatedError", "solve", "simulate", "blend_window",
           "fd_jacobian", "control_energy", "mass_matrix"]


class ConvergenceError(RuntimeError):
    """The iterations did not reach the tolerance; ``.history`` holds the misses so far."""

    def __init__(self, message, history=None):
        super().__init__(message)
        self.history = history or []


class SingularGramError(ConvergenceError):
    """The Gram matrix of the selected end conditions is singular: the linearised system cannot
    steer them (e.g. a singular gyro state or a target outside the reachable set)."""


class SaturatedError(SingularGramError):
    """With rate limits: every control node is held at its limit, none is left to steer the end
    conditions (the limit is too small for the target)."""


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
    free_end : bool
        ``u(tf)`` is free (only ``u(t0)`` is kept; the correction is blended at ``t0`` only).
    u_max : float, sequence of float or None
        Rate limits ``|u_j| <= u_max_j`` (one value for every control, or one per control).
    minimize_energy : bool
        Seek the control of least ``int |u|^2 dt`` among those meeting the end conditions.
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
    free_end: bool = False
    u_max: object = None
    minimize_energy: bool = False

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
        self.limits()
        return self

    def limits(self):
        """The rate limits as an array (n_u,), or None."""
        if self.u_max is None:
            return None
        lim = np.broadcast_to(np.asarray(self.u_max, float), (self.n_u,)).copy() \
            if np.ndim(self.u_max) == 0 or len(self.u_max) == self.n_u else None
        if lim is None:
            raise ValueError(f"u_max needs one value or {self.n_u} values, got {self.u_max!r}")
        if not np.all(np.isfinite(lim)) or np.any(lim <= 0):
            raise ValueError(f"u_max must be finite and > 0, got {self.u_max!r}")
        return lim

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
    u_max : ndarray or None
        The rate limits the solve respected.
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
    u_max: np.ndarray | None = None

    def control(self, t) -> np.ndarray:
        """u(t) by linear interpolation of the node values, shape (len(t), n_u)."""
        t = np.atleast_1d(np.asarray(t, float))
        return np.stack([np.interp(t, self.t_nodes, c) for c in self.controls.T], -1)

    @property
    def max_miss(self) -> float:
        return float(np.max(np.abs(self.miss)))

    @property
    def energy(self) -> float:
        """``int |u|^2 dt`` of the control (exact for the piecewise-linear class)."""
        return control_energy(self.t_nodes, self.controls)


def control_energy(t_nodes, controls) -> float:
    """``int |u(t)|^2 dt`` of the piecewise-linear control with node values ``controls``
    (nodes x channels) at the times ``t_nodes`` (any spacing): sum of dt (a^2 + a b + b^2) / 3."""
    P = np.asarray(controls, float)
    dt = np.diff(np.asarray(t_nodes, float))[:, None]
    a, b = P[:-1], P[1:]
    return float(np.sum(dt * (a * a + a * b + b * b)) / 3.0)


def mass_matrix(t_nodes) -> np.ndarray:
    """Mass matrix of the hat functions on ``t_nodes``: ``int u_j^2 dt = p^T M p``."""
    dt = np.diff(np.asarray(t_nodes, float))
    n = len(dt) + 1
    M = np.zeros((n, n))
    idx = np.arange(n - 1)
    M[idx, idx] += dt / 3.0
    M[idx + 1, idx + 1] += dt / 3.0
    M[idx, idx + 1] = M[idx + 1, idx] = dt / 6.0
    return M


def blend_window(t, t0: float, tf: float, a: float, at_end: bool = True) -> np.ndarray:
    """Cubic blending window: 0 at t0 and tf, 1 on [t0 + a T, tf - a T], C1 (smoothstep).

    ``at_end=False``: 0 at t0 only (1 from t0 + a T to tf).
    """
    t = np.asarray(t, float)
    span = a * (tf - t0)
    d = np.minimum(t - t0, tf - t) if at_end else t - t0
    s = np.clip(d / span, 0.0, 1.0)
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


def _gram_correction(S, Hn, b, it):
    """Voronov's correction in the impulse-response basis: ``du = Hn c`` with ``S . du = b``."""
    Q = np.einsum("nrk,nsk->rs", S, Hn)
    scale = 1.0 / np.linalg.norm(Q, axis=1)
    Qs = Q * scale[:, None]
    cond = np.linalg.cond(Qs)
    if not np.isfinite(cond) or cond > 1e13:
        raise SingularGramError(f"Gram matrix singular at iteration {it} (condition "
                                f"{cond:.2e}): the selected end conditions cannot be steered")
    c = np.linalg.solve(Qs, b * scale)
    return np.einsum("nrk,r->nk", Hn, c), None


def _energy_correction(P, S, b, free, Mk, B, it):
    """The minimum-energy step: ``min grad E(p)^T d + d^T B d / 2`` over the free entries of
    ``d`` subject to ``S . d = b`` (``E(p) = p^T Mk p``; ``B`` the Hessian of the Lagrangian,
    ``2 Mk`` or its quasi-Newton update).  Returns ``d`` and the multipliers ``nu`` of the end
    conditions (``grad E + B d = G^T nu`` on the free entries)."""
    r = S.shape[1]
    f = free.ravel()
    G = S.transpose(1, 0, 2).reshape(r, -1)[:, f]
    rn = np.linalg.norm(G, axis=1)
    if not np.all(rn > 0):
        raise SingularGramError(f"iteration {it}: an end condition depends on no free control "
                                "node (all held at their limits?)")
    Gs = G / rn[:, None]
    K = B[np.ix_(f, f)]
    g = 2.0 * (Mk @ P.ravel())[f]
    nf = int(f.sum())
    cond = np.linalg.cond(Gs @ np.linalg.solve(K, Gs.T))
    if not np.isfinite(cond) or cond > 1e13:
        raise SingularGramError(f"iteration {it}: the end conditions cannot be steered by the "
                                f"free control nodes (condition {cond:.2e})")
    kkt = np.zeros((nf + r, nf + r))
    kkt[:nf, :nf] = K
    kkt[:nf, nf:] = Gs.T
    kkt[nf:, :nf] = Gs
    sol = np.linalg.solve(kkt, np.concatenate([-g, b / rn]))
    d = np.zeros(P.size)
    d[f] = sol[:nf]
    return d.reshape(P.shape), -sol[nf:] / rn


def _step(P, S, Hn, b, fixed, lim, Mk, B, energy, it):
    """The correction of one iteration, every node kept within the limits ``lim``.

    Nodes that the unconstrained correction would push over a limit are moved onto it and held
    there (removed from the basis); the other nodes then meet the linearised end conditions.
    Repeated until no node crosses a limit (at most once per node).  Returns the step, the
    multipliers (energy mode), the number of nodes held at a limit and the mask of free nodes.
    """
    free = ~fixed
    base = np.zeros_like(P)
    held = 0
    while True:
        rhs = b - np.einsum("nrk,nk->r", S, base) if held else b
        try:
            if energy:
                d, mult = _energy_correction(P + base, S, rhs, free, Mk, B, it)
            else:
                d, mult = _gram_correction(S, Hn * free[:, None, :] if held or lim is not None
                                           else Hn, rhs, it)
        except SingularGramError as exc:
            if held:        # the nodes left free cannot steer the end conditions
                raise SaturatedError(f"iteration {it}: with {held} control nodes held at the "
                                     "rate limit the others cannot steer the end conditions: "
                                     "the limit u_max is too small for them") from exc
            raise
        D = base + d
        if lim is None:
            return D, mult, held, free
        Pn = P + D
        over = free & (np.abs(Pn) > lim * (1.0 + 1e-12))
        if not over.any():
            return D, mult, held, free
        base[over] = np.clip(Pn, -lim, lim)[over] - P[over]
        free &= ~over
        held += int(over.sum())
        if not free.any():
            raise SaturatedError(f"iteration {it}: every control node is held at its rate "
                                 "limit: the limit u_max is too small to reach the end "
                                 "conditions from here")


def _end_curvature(jac, Xr, U, B, M, psi, N, m, h, nu, eps=1e-5):
    """Hessian of ``nu . x_S(tf)`` with respect to the node values (the end conditions'
    curvature that the Lagrangian of the minimum-energy problem needs), by the second-order
    adjoint formula

        d2 (nu . x(tf)) / dp_a dp_b = int y_a(t)^T [d2 (psi^T f) / d(x, u)^2] y_b(t) dt,

    ``psi(t) = Phi(tf, t)^T nu`` (the adjoint), ``y_a = (dx/dp_a, du/dp_a)`` (forward
    sensitivities and hat functions).  The forward sensitivities are propagated with the
    sub-step transition matrices ``M`` (trapezoidal input term), the second derivatives of ``f``
    are central differences of the Jacobian ``jac``, and the integral is Simpson's rule on every
    control interval (nodes and midpoints).  ``psi`` (n+1, nr) on the sub-steps; returns a
    ((N+1) nu, (N+1) nu) matrix (node-major).
    """
    nr = Xr.shape[1]
    nP = (N + 1) * nu
    half = m // 2
    fr = np.tile(np.arange(m) / m, N)                       # fraction of sub-step k in its interval
    fn = np.tile(np.arange(1, m + 1) / m, N)                # ... and of its end
    MB = np.einsum("kab,kbc->kac", M, B[:-1])
    left = 0.5 * h * ((1.0 - fr)[:, None, None] * MB + (1.0 - fn)[:, None, None] * B[1:])
    right = 0.5 * h * (fr[:, None, None] * MB + fn[:, None, None] * B[1:])
    ks = sorted({i * m for i in range(N + 1)} | {i * m + half for i in range(N)})
    Zs = np.zeros((len(ks), nr, nP))
    Z = np.zeros((nr, nP))
    q = 0
    for k in range(N * m + 1):
        if k == ks[q]:
            Zs[q] = Z
            q += 1
            if k == N * m:
                break
        i = k // m
        c = (i + 2) * nu
        Z[:, :c] = M[k] @ Z[:, :c]
        Z[:, i * nu:(i + 1) * nu] += left[k]
        Z[:, (i + 1) * nu:c] += right[k]
    # second derivatives of psi . f at the samples: central differences of the Jacobian
    Xs, Us, Ps = Xr[ks], U[ks], psi[ks]
    nz = nr + nu
    Hf = np.zeros((len(ks), nz, nz))
    for c in range(nz):
        dx, du = np.zeros(nr), np.zeros(nu)
        if c < nr:
            dx[c] = eps
        else:
            du[c - nr] = eps
        Ap, Bp = jac(Xs + dx, Us + du)
        Am, Bm = jac(Xs - dx, Us - du)
        Hf[:, c, :nr] = np.einsum("sa,sab->sb", Ps, Ap - Am) / (2.0 * eps)
        Hf[:, c, nr:] = np.einsum("sa,sab->sb", Ps, Bp - Bm) / (2.0 * eps)
    Hf = 0.5 * (Hf + Hf.transpose(0, 2, 1))
    # y at the samples (state sensitivities, hat functions) and Simpson's weights
    Y = np.zeros((len(ks), nz, nP))
    Y[:, :nr] = Zs
    w = np.zeros(len(ks))
    dt = h * m
    eye = np.eye(nu)
    for q, k in enumerate(ks):
        i, j = divmod(k, m)
        if j == 0:
            Y[q, nr:, i * nu:(i + 1) * nu] = eye
            w[q] = dt / 6.0 * (1.0 if i in (0, N) else 2.0)
        else:
            Y[q, nr:, i * nu:(i + 2) * nu] = np.concatenate([0.5 * eye, 0.5 * eye], 1)
            w[q] = 4.0 * dt / 6.0
    T = np.einsum("qab,qbj->qaj", Hf, Y) * w[:, None, None]
    W = Y.reshape(-1, nP).T @ T.reshape(-1, nP)
    return 0.5 * (W + W.T)


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
    pb = problem.validate()
    t_nodes = pb.nodes
    N, m, nu = pb.intervals, pb.substeps, pb.n_u
    P = np.zeros((N + 1, nu)) if controls is None else np.array(controls, float).copy()
    if P.shape != (N + 1, nu):
        raise ValueError(f"controls must have shape {(N + 1, nu)}, got {P.shape}")
    fixed = np.zeros((N + 1, nu), bool)
    fixed[0] = True
    if not pb.free_end:
        fixed[-1] = True
    lim = pb.limits()
    if lim is not None:
        if np.any(np.abs(P[fixed]) > np.broadcast_to(lim, P.shape)[fixed]):
            raise ValueError("the kept end values of the control exceed the rate limit u_max")
        P = np.clip(P, -lim, lim)
    energy = bool(pb.minimize_energy)
    Mk = np.kron(mass_matrix(t_nodes), np.eye(nu)) if energy else None
    Bq = 2.0 * Mk if energy else None       # Hessian of the Lagrangian
    nu_full = np.zeros(len(pb.target_index))
    if linear is None:
        linear = LinearModel(pb.jac or fd_jacobian(pb.rhs))
    project = linear.project or (lambda X: X)
    idx = np.array(pb.target_index)
    xf = np.array(pb.target_value, float)
    h = (t_nodes[1] - t_nodes[0]) / m
    w_nodes = blend_window(t_nodes, pb.t0, pb.tf, pb.blend, at_end=not pb.free_end)
    simpson = np.ones(m + 1)
    simpson[1:-1:2], simpson[2:-1:2] = 4.0, 2.0
    simpson *= h / 3.0
    frac = np.arange(m + 1) / m

    t, X, U = simulate(pb.rhs, pb.x0, t_nodes, P, m)
    miss = xf - X[-1, idx]
    E = control_energy(t_nodes, P)
    history = [dict(iteration=0, max_miss=float(np.max(np.abs(miss))), miss=(-miss).tolist(),
                    selected=[], step=0.0, energy=E, held=0)]
    it = 0
    mu = 0.0                    # weight of the l1 merit function (energy mode)
    settled = False             # energy mode: E changed by < energy_rtol in the last iteration
    while history[-1]["max_miss"] >= tol or (energy and not settled):
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
        # -- the correction: end-blended impulse-response basis, or minimum energy -------------
        Hn = H[::m][:, sel, :] * w_nodes[:, None, None]                 # (N+1, r, nu)
        try:
            if energy and np.any(nu_full):     # Newton-KKT: the Lagrangian's exact Hessian
                psi = np.einsum("r,nra->na", nu_full, Psi)
                Bq = 2.0 * Mk - _end_curvature(linear.jac, Xr, U, B, M, psi, N, m, h, nu)
            aim = 1.0
            while True:
                # with rate limits the full correction may need more than the limits allow:
                # then aim at a fraction of the miss (the limits bind less on a shorter step)
                try:
                    dP, mult, held, free = _step(P, S[:, sel, :], Hn, aim * miss[sel], fixed,
                                                 lim, Mk, Bq, energy, it)
                    break
                except SaturatedError:
                    aim *= 0.5
                    if aim < 0.5 ** max_halvings:
                        raise
        except SingularGramError as exc:
            raise type(exc)(str(exc), history) from None
        if energy:
            mu = max(mu, 2.0 * float(np.max(np.abs(mult))))
            nu_full = np.zeros(len(idx))
            nu_full[sel] = mult
            merit0 = E + mu * float(np.sum(np.abs(miss)))
        # -- nonlinear step (halved while the miss, or the merit function, grows) --------------
        def trial(Pn):
            try:
                tn, Xn, Un = simulate(pb.rhs, pb.x0, t_nodes, Pn, m)
            except ConvergenceError:
                return None
            miss_n = xf - Xn[-1, idx]
            return tn, Xn, Un, miss_n, float(np.max(np.abs(miss_n)))

        def accepted(Pn, out):
            if out is None:
                return False
            if not energy:
                return out[4] < history[-1]["max_miss"]
            return (control_energy(t_nodes, Pn) + mu * float(np.sum(np.abs(out[3]))) < merit0
                    or out[4] < min(tol, history[-1]["max_miss"]))

        step = 1.0
        for _ in range(max_halvings + 1):
            Pn = P + step * dP
            if lim is not None:             # (a convex combination: only rounding can cross)
                Pn = np.clip(Pn, -lim, lim)
            out = trial(Pn)
            if accepted(Pn, out):
                break
            if energy and step == 1.0 and out is not None:
                # second-order correction: the end conditions' curvature made the full step
                # miss; restore them with the same linearisation (least-norm correction)
                try:
                    d2 = _energy_correction(np.zeros_like(P), S[:, sel, :], out[3][sel], free,
                                            np.zeros_like(Mk), 2.0 * Mk, it)[0]
                except SingularGramError:
                    d2 = None
                if d2 is not None:
                    Pc = Pn + d2 if lim is None else np.clip(Pn + d2, -lim, lim)
                    out_c = trial(Pc)
                    if accepted(Pc, out_c):
                        Pn, out = Pc, out_c
                        break
            step *= 0.5
        else:
            raise ConvergenceError(f"iteration {it}: the miss {history[-1]['max_miss']:.3e} "
                                   "cannot be reduced along the Newton direction (the target "
                                   "may be unreachable from this initial guess)", history)
        tn, Xn, Un, miss_n, mm = out
        En = control_energy(t_nodes, Pn)
        settled = abs(En - E) <= energy_rtol * max(En, 1e-300)
        E = En
        P, t, X, U, miss = Pn, tn, Xn, Un, miss_n
        history.append(dict(iteration=it, max_miss=mm, miss=(-miss).tolist(),
                            selected=[int(pb.target_index[s]) for s in sel], step=step,
                            energy=E, held=held))
    return DirectResult(success=True, iterations=it, history=history, t_nodes=t_nodes,
                        controls=P, t=t, states=X, miss=-miss,
                        seconds=time.perf_counter() - t_start,
                        target_index=tuple(pb.target_index), u_max=lim)
