"""Newton's method on the shooting method's unknowns: classical or damped, the Jacobian by
forward finite differences, a singular Jacobian reported with its reason; and the errors of the
shooting method (:mod:`.shooting`)."""
from __future__ import annotations

import numpy as np

__all__ = ["ShootingError", "SingularJacobianError", "NoConvergenceError", "newton"]


class ShootingError(RuntimeError):
    """The shooting method could not produce a solution; the message says why."""


class SingularJacobianError(ShootingError):
    """The Jacobian of the residuals is singular at the current unknowns."""


class NoConvergenceError(ShootingError):
    """Newton did not reach the tolerance within the allowed iterations."""


def newton(fun, z0, tol: float = 1e-5, max_iter: int = 50, damped: bool = False,
           fd_step: float = 1e-7, domain=None, on_singular=None, cond_max: float = 1e8):
    """Solve ``fun(z) = 0`` by Newton's method with a forward-difference Jacobian.

    Parameters
    ----------
    fun : callable ``z -> ndarray``
        Residuals (as many as unknowns).
    z0 : sequence of float
        Starting guess.
    tol : float
        Stop when ``max |fun(z)| < tol`` (the paper: 1e-5).
    damped : bool
        Modified Newton: halve the step until the residual's 2-norm decreases (the step never
        exceeds the classical Newton step).  Classical Newton takes the full step (halved only
        when it leaves the domain).
    fd_step : float
        Relative finite-difference step: ``dz_i = fd_step * max(|z_i|, 1)``.
    domain : callable ``z -> str or None``, optional
        Reason why ``z`` is invalid (e.g. ``T <= 0``); a step into it is halved.
    on_singular : callable ``(z, singular values) -> str``, optional
        Builds the message of :class:`SingularJacobianError`.
    cond_max : float
        Condition number (ratio of extreme singular values) above which the Jacobian counts as
        singular.  A structurally zero column computed by finite differences of an adaptive
        integration is not exactly zero but ~1e-9 of the others (integrator noise / fd step);
        a regular Jacobian of S3 has a condition number of ~2e3.

    Returns
    -------
    dict
        ``z``, ``r`` (residuals), ``iterations``, ``history`` [(z, max-norm)], ``evaluations``,
        ``success``, ``message``.
    """
    z = np.array(z0, dtype=float)
    n = z.size
    evals = 0

    def F(zz):
        nonlocal evals
        evals += 1
        r = np.asarray(fun(zz), dtype=float)
        if r.shape != (n,):
            raise ShootingError(f"residual vector has shape {r.shape}, expected ({n},)")
        return r

    r = F(z)
    history = [(z.copy(), float(np.max(np.abs(r))))]
    it = 0
    while np.max(np.abs(r)) >= tol:
        if it >= max_iter:
            return dict(z=z, r=r, iterations=it, history=history, evaluations=evals,
                        success=False, message=f"no convergence in {max_iter} Newton "
                        f"iterations (max |residual| = {np.max(np.abs(r)):.3g})")
        J = _fd_jacobian(F, z, r, fd_step, domain)
        _require_regular(J, z, cond_max, on_singular)
        z, r = _backtrack(F, z, r, -np.linalg.solve(J, r), damped, domain)
        it += 1
        history.append((z.copy(), float(np.max(np.abs(r)))))
    return dict(z=z, r=r, iterations=it, history=history, evaluations=evals, success=True,
                message="converged")


def _fd_jacobian(F, z, r, fd_step: float, domain) -> np.ndarray:
    """Forward-difference Jacobian of ``F`` at ``z`` (``F(z) = r``), step ``fd_step * max(|z_i|,
    1)``; a step that would leave the domain is taken backwards."""
    n = z.size
    J = np.empty((n, n))
    for i in range(n):
        dz = fd_step * max(abs(z[i]), 1.0)
        zi = z.copy()
        zi[i] += dz
        if domain is not None and domain(zi):
            zi[i] = z[i] - dz
            dz = -dz
        J[:, i] = (F(zi) - r) / dz
    return J


def _require_regular(J, z, cond_max: float, on_singular) -> None:
    """Raise :class:`SingularJacobianError` if ``J`` is singular: a non-finite or zero singular
    value, or a condition number above ``cond_max`` (message by ``on_singular`` if given)."""
    sv = np.linalg.svd(J, compute_uv=False)
    if not np.all(np.isfinite(sv)) or sv[-1] <= sv[0] / cond_max or sv[0] == 0.0:
        raise SingularJacobianError(on_singular(z, sv) if on_singular else
                                    f"singular Jacobian at z = {z} (singular values {sv})")


def _backtrack(F, z, r, step, damped: bool, domain):
    """The Newton step from ``z`` (residuals ``r``), halved until it stays in the domain with
    finite residuals (and, ``damped``, decreases the residual's 2-norm by the Armijo factor
    ``1 - 1e-4 lam``).  Returns the new ``(z, F(z))``.

    Raises
    ------
    ShootingError
        No step down to ``2^-30`` of the Newton step qualifies.
    """
    lam = 1.0
    norm0 = float(np.linalg.norm(r))
    while True:
        zt = z + lam * step
        bad = domain(zt) if domain is not None else None
        if not bad:
            try:
                rt = F(zt)
            except ShootingError:
                rt = None
            if rt is not None and np.all(np.isfinite(rt)) and (
                    not damped or np.linalg.norm(rt) < (1.0 - 1e-4 * lam) * norm0):
                return zt, rt
        lam *= 0.5
        if lam < 2.0 ** -30:
            raise ShootingError(f"Newton step from z = {z} cannot be shortened into the "
                                f"domain or to a smaller residual"
                                + (f" ({bad})" if bad else ""))
