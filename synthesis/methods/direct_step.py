"""One Newton-Kantorovich correction of the direct method: linearisation along the iterate,
the choice of independent end conditions, and the correction of the node values.

* :func:`linearise` -- transition matrices of the sub-steps, the adjoint rows ``Phi(tf, s)`` of
  the end conditions, the impulse response and the sensitivities of the end conditions to the
  node values (:class:`Linearisation`);
* :func:`select_conditions` -- the adaptive selection of independent end conditions;
* :func:`gram_correction`, :func:`energy_correction` -- the correction in the impulse-response
  basis (Gram system) and the minimum-energy (KKT) correction;
* :func:`limited_step`, :func:`aimed_step` -- the correction with nodes held at the rate limits,
  and at a fraction of the miss when the limits leave too few nodes;
* :func:`end_curvature` -- the end conditions' curvature for the Lagrangian's Hessian.

The method is described in :mod:`synthesis.methods.direct_method`, which iterates these steps.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from descent_fmus.synthesis.methods.direct_problem import (Discretisation, SaturatedError,
                                                           SingularGramError)

__all__ = ["Linearisation", "linearise", "transitions", "select_conditions", "gram_correction",
           "energy_correction", "limited_step", "aimed_step", "end_curvature"]


@dataclass(frozen=True)
class Linearisation:
    """The linearisation of the plant along one iterate (on the sub-steps of the control grid).

    Attributes
    ----------
    Xr : ndarray
        States of the linearised (possibly reduced) model (n+1, nr).
    U : ndarray
        Controls (n+1, n_u).
    B : ndarray
        ``df/du`` along the iterate (n+1, nr, n_u).
    M : ndarray
        RK4 transition matrices of the sub-steps (n, nr, nr).
    Psi : ndarray
        Rows of ``Phi(tf, s)`` for the end conditions (n+1, r_c, nr): the adjoint.
    H : ndarray
        Impulse response ``Psi B`` (n+1, r_c, n_u).
    S : ndarray
        Sensitivities ``d x_S(tf) / d(node values)`` (intervals+1, r_c, n_u): the integrals of
        ``H`` against the hat functions.
    """

    Xr: np.ndarray
    U: np.ndarray
    B: np.ndarray
    M: np.ndarray
    Psi: np.ndarray
    H: np.ndarray
    S: np.ndarray

    @property
    def rows(self) -> np.ndarray:
        """The sensitivity rows of the end conditions, one per condition (r_c, (N+1) n_u)."""
        return self.S.transpose(1, 0, 2).reshape(self.S.shape[1], -1)

    def curvature(self, grid: Discretisation, nu: np.ndarray) -> np.ndarray:
        """:func:`end_curvature` of ``nu . x_S(tf)`` (``nu``: a multiplier per end condition)."""
        psi = np.einsum("r,nra->na", nu, self.Psi)
        return end_curvature(grid.linear.jac, self.Xr, self.U, self.B, self.M, psi, grid.N,
                             grid.m, grid.h, grid.n_u)


def linearise(grid: Discretisation, X: np.ndarray, U: np.ndarray) -> Linearisation:
    """Linearise along the iterate ``(X, U)`` (full states and controls on the sub-steps).

    The Jacobian is taken at the sub-step ends and at Hermite midpoints of the states (RK4
    transition matrices); the rows of ``Phi(tf, s)`` for the end conditions are propagated
    backwards (the adjoint), and the sensitivities to the node values are their impulse
    responses integrated against the hat functions by Simpson's rule on the sub-steps (exact
    for the piecewise-linear control class).
    """
    pb, h, m, N = grid.problem, grid.h, grid.m, grid.N
    F = np.array([pb.rhs(tuple(x), tuple(u)) for x, u in zip(X, U)])
    Xr, Fr = grid.project(X), grid.project(F)
    Xm = 0.5 * (Xr[:-1] + Xr[1:]) + (h / 8.0) * (Fr[:-1] - Fr[1:])   # Hermite midpoints
    Um = 0.5 * (U[:-1] + U[1:])
    A, B = grid.linear.jac(Xr, U)
    Am, _ = grid.linear.jac(Xm, Um)
    M = transitions(A[:-1], Am, A[1:], h)
    # rows of Phi(tf, s) for the end conditions, backwards (adjoint)
    nr = Xr.shape[1]
    Psi = np.empty((len(X), len(grid.idx), nr))
    Psi[-1] = np.eye(nr)[grid.idx]
    for k in range(len(X) - 2, -1, -1):
        Psi[k] = Psi[k + 1] @ M[k]
    H = Psi @ B                                             # (n+1, r_c, nu) impulse response
    Hi = np.stack([H[i * m:(i + 1) * m + 1] for i in range(N)])      # (N, m+1, r_c, nu)
    S = np.zeros((N + 1,) + H.shape[1:])
    S[:-1] += np.einsum("j,ijrk->irk", grid.simpson * (1.0 - grid.frac), Hi)
    S[1:] += np.einsum("j,ijrk->irk", grid.simpson * grid.frac, Hi)
    return Linearisation(Xr, U, B, M, Psi, H, S)


def transitions(A0, Am, A1, h):
    """RK4 transition matrices of dPhi/dt = A(t) Phi over steps of size h (batched)."""
    I = np.eye(A0.shape[-1])
    K1 = A0
    K2 = Am @ (I + 0.5 * h * K1)
    K3 = Am @ (I + 0.5 * h * K2)
    K4 = A1 @ (I + h * K3)
    return I + (h / 6.0) * (K1 + 2.0 * (K2 + K3) + K4)


def select_conditions(rows: np.ndarray, miss: np.ndarray, rank_tol: float = 1e-7):
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


def gram_correction(S, Hn, b, it):
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


def energy_correction(P, S, b, free, Mk, B, it):
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


def limited_step(P, S, Hn, b, fixed, lim, Mk, B, energy, it):
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
                d, mult = energy_correction(P + base, S, rhs, free, Mk, B, it)
            else:
                d, mult = gram_correction(S, Hn * free[:, None, :] if held or lim is not None
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


def aimed_step(grid: Discretisation, lin: Linearisation, P, miss, sel, B, max_halvings: int,
               it: int):
    """The correction of iteration ``it`` for the selected end conditions ``sel``.

    The end-blended impulse-response basis (or, for ``minimize_energy``, the KKT step with the
    Lagrangian's Hessian ``B``), every node within the rate limits (:func:`limited_step`).  With
    rate limits the full correction may need more than the limits allow: then it aims at half
    the miss, a quarter, ... (the limits bind less on a shorter step), at most ``max_halvings``
    times.  Returns the step, the multipliers, the number of held nodes and the free-node mask.

    Raises
    ------
    SaturatedError
        Even the shortest aim leaves too few free nodes.
    SingularGramError
        The selected end conditions cannot be steered.
    """
    Hn = lin.H[::grid.m][:, sel, :] * grid.w_nodes[:, None, None]          # (N+1, r, nu)
    aim = 1.0
    while True:
        try:
            return limited_step(P, lin.S[:, sel, :], Hn, aim * miss[sel], grid.fixed, grid.lim,
                                grid.Mk, B, grid.energy, it)
        except SaturatedError:
            aim *= 0.5
            if aim < 0.5 ** max_halvings:
                raise


def end_curvature(jac, Xr, U, B, M, psi, N, m, h, nu, eps=1e-5):
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
