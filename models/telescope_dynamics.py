"""S4 -- the rigid gyrostat's equations: a telescope with n control-moment gyros (gyrodynes; six).

State ``x = (lam0, lam1, lam2, lam3, w1, w2, w3, beta1, ..., beta_n)`` (7 + n): the quaternion
``lam`` [1] (body -> inertial, scalar first), the body rate ``w`` [rad/s] in the body axes and the
gimbal angles ``beta`` [rad]; control ``u`` (n): the gimbal rates [rad/s].

    I dw/dt + w x (I w + k) + dk/dt = 0,    dlam/dt = 1/2 A(w) lam,    dbeta/dt = u
    k     = h sum_j (a_j cos beta_j + b_j sin beta_j)                  [N m s]
    dk/dt = h sum_j (-a_j sin beta_j + b_j cos beta_j) u_j = C(beta) u [N m]

By default (Voronov 2009, Example 1) six gimbal axes ``g_j`` along the six non-parallel face
normals of a regular dodecahedron, ``a_j = normalize(g_j x e_y)`` (rotor axis at beta_j = 0,
[choice], models/README.md) and ``b_j = g_j x a_j``.  The gimbal axes (hence the number of
gyrodynes) and the reference direction of the rotor axes are parameters
(:class:`TelescopeParams`); ``models/telescope_cmg.py`` has the cluster's geometry and the
attitude kinematics on plain floats (gimbal axes, the other clusters of the thesis, rotor axes,
``k`` and ``dk/dt``, the quaternion rate).  First integrals: ``|lam| = 1`` and the inertial
angular momentum ``K = R(lam) (I w + k)`` (:func:`inertial_momentum`); the CMG singularity
measure, envelope and the momentum an end state needs are here too.

This module holds the only definition of these equations (:func:`make_rigid_rhs`); the
:class:`~models.telescope.Telescope` FMU (``models/telescope.py``), the flexible model
(``models/telescope_flexible.py``) and the reorientation by the direct method
(``synthesis/systems/telescope/reorientation.py``) all call it.  :func:`rigid_jacobian` is its
analytic linearisation (checked against finite differences in
``tests/systems/telescope/test_telescope_model.py``).  The data of Example 1 (the initial state,
the target, the time T) are here as well.

References
----------
S.A. Voronov, PhD thesis (2009), ch. 2, Example 1, eqs. (8)-(9); ch. 3, Example 3.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from descent_fmus.models.params import ParameterError, Params, param
from descent_fmus.models.telescope_cmg import (AXES, GIMBAL_AXES, axes_of, gimbal_vectors,
                                               gyro_sums, normalize, quat_to_matrix,
                                               quaternion_rate)

__all__ = ["TelescopeParams", "make_rigid_rhs", "rigid_jacobian", "body_momentum",
           "inertial_momentum", "gyro_momentum", "singularity_measure", "envelope_radius",
           "required_gyro_momentum", "INITIAL_STATE", "TARGET_LAM", "TARGET_W", "T_DEFAULT",
           "deg"]

#: Reorientation time T of Voronov (2009), Example 1 [s].
T_DEFAULT = 40.0


def deg(x: float) -> float:
    """Degrees -> radians."""
    return math.radians(x)


_C15, _S15 = math.cos(deg(15.0)), math.sin(deg(15.0))
_C10, _S10 = math.cos(deg(10.0)), math.sin(deg(10.0))
#: Initial state of the reorientation, Voronov (2009) Example 1 (lam, w [rad/s], beta [rad]).
INITIAL_STATE = (_C15, 0.0, _S15, 0.0, 0.0, deg(0.4), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -math.pi)
#: Target quaternion and body rate [rad/s] at t = T, Voronov (2009) Example 1.
TARGET_LAM = (_C10, _S10 / math.sqrt(2.0), 0.0, _S10 / math.sqrt(2.0))
TARGET_W = (deg(-0.3), 0.0, deg(-0.3))


@dataclass(frozen=True)
class TelescopeParams(Params):
    """Parameters of the rigid S4 gyrostat (SI units); defaults = Voronov (2009), Example 1.

    ``rotor_ref`` may also be given as a body axis name (``"x"``, ``"y"``, ``"z"``); it is
    stored as the 3-vector.  ``gimbal_axes`` holds 3 entries per gyrodyne (their number is
    :attr:`n_gyros`); they need not be unit vectors.
    """

    inertia: tuple = param((25000.0, -100.0, -100.0, -100.0, 10000.0, 100.0, -100.0, 100.0,
                            18000.0), "kg.m2", "inertia tensor I (row-major 3x3)")
    h: float = param(250.0, "N.m.s", "rotor angular momentum of each gyrodyne", positive=True)
    rotor_ref: tuple = param(AXES["y"], "1", "reference direction e_ref of the rotor axes at "
                             "beta = 0, a_j = normalize(g_j x e_ref), body axes [choice]")
    gimbal_axes: tuple = param(tuple(v for g in GIMBAL_AXES for v in g), "1",
                               "gimbal axes g_j in body axes, 3 entries per gyrodyne (default: "
                               "normals of six non-parallel faces of a regular dodecahedron)")

    def __post_init__(self):
        if isinstance(self.rotor_ref, str) and self.rotor_ref in AXES:
            object.__setattr__(self, "rotor_ref", AXES[self.rotor_ref])

    def check(self) -> None:
        if len(self.inertia) != 9:
            raise ParameterError("parameter inertia needs 9 entries (row-major 3x3) [kg m2]")
        I = np.array(self.inertia, float).reshape(3, 3)
        if not np.allclose(I, I.T):
            raise ParameterError("inertia tensor must be symmetric")
        ev = np.linalg.eigvalsh(I)
        if ev[0] <= 0.0:
            raise ParameterError(f"inertia tensor must be positive definite, eigenvalues {ev}")
        e = sorted(ev)
        if e[0] + e[1] < e[2] * (1 - 1e-12):
            raise ParameterError(f"inertia tensor violates the triangle inequality: {ev}")
        n3 = len(self.gimbal_axes)
        if n3 < 3 or n3 % 3:
            raise ParameterError(f"parameter gimbal_axes needs 3 entries per gyrodyne (at least "
                                 f"one), got {n3}")
        for j, g in enumerate(axes_of(self.gimbal_axes)):
            if math.sqrt(g[0] ** 2 + g[1] ** 2 + g[2] ** 2) <= 1e-12:
                raise ParameterError(f"gimbal axis {j + 1} (gimbal_axes[{3 * j + 1}..{3 * j + 3}])"
                                     " is zero")
        if len(self.rotor_ref) != 3:
            raise ParameterError(f"parameter rotor_ref needs 3 entries (a direction in body "
                                 f"axes) or an axis name 'x', 'y', 'z', got {self.rotor_ref!r}")
        e_ref = np.array(self.rotor_ref, float)
        n = float(np.linalg.norm(e_ref))
        if n == 0.0 or any(np.linalg.norm(np.cross(normalize(g), e_ref)) <= 1e-9 * n
                           for g in axes_of(self.gimbal_axes)):
            raise ParameterError(f"parameter rotor_ref {self.rotor_ref} is zero or along a "
                                 "gimbal axis: it defines no rotor direction")

    @property
    def I(self) -> np.ndarray:  # noqa: E743
        return np.array(self.inertia, dtype=float).reshape(3, 3)

    @property
    def n_gyros(self) -> int:
        """Number of gyrodynes (controls)."""
        return len(self.gimbal_axes) // 3

    @property
    def n_states(self) -> int:
        """Rigid state size 7 + n_gyros."""
        return 7 + self.n_gyros

    def gyro_matrices(self):
        """(h a_j, h b_j) as (n, 3) arrays [N m s]."""
        _, a, b = gimbal_vectors(self.rotor_ref, self.gimbal_axes)
        return self.h * np.array(a), self.h * np.array(b)



def make_rigid_rhs(p: TelescopeParams):
    """Return ``f(x, u)``: the S4 rigid gyrostat right-hand side on tuples (7 + n states, n
    controls; ``u`` may be longer: the first n entries are used).

    The returned closure works on plain floats (several times faster than NumPy for a
    13-element state, ``models/integrators.py``).
    """
    p.validate()
    Ii = np.linalg.inv(p.I)
    i11, i12, i13, i21, i22, i23, i31, i32, i33 = p.inertia
    j11, j12, j13, j21, j22, j23, j31, j32, j33 = (float(v) for v in Ii.ravel())
    ha, hb = p.gyro_matrices()
    HA = [tuple(float(v) for v in r) for r in ha]
    HB = [tuple(float(v) for v in r) for r in hb]
    gy = list(zip(HA, HB))
    n = len(gy)

    def rhs(x, u):
        l0, l1, l2, l3, w1, w2, w3 = x[0], x[1], x[2], x[3], x[4], x[5], x[6]
        k1, k2, k3, d1, d2, d3 = gyro_sums(x, u, gy)
        L1 = i11 * w1 + i12 * w2 + i13 * w3 + k1
        L2 = i21 * w1 + i22 * w2 + i23 * w3 + k2
        L3 = i31 * w1 + i32 * w2 + i33 * w3 + k3
        r1 = -(w2 * L3 - w3 * L2) - d1
        r2 = -(w3 * L1 - w1 * L3) - d2
        r3 = -(w1 * L2 - w2 * L1) - d3
        return quaternion_rate(l0, l1, l2, l3, w1, w2, w3) + (
                j11 * r1 + j12 * r2 + j13 * r3,
                j21 * r1 + j22 * r2 + j23 * r3,
                j31 * r1 + j32 * r2 + j33 * r3) + tuple(u[:n])
    return rhs


def _skew(v):
    """Batch of cross-product matrices [v]x, v of shape (n, 3) -> (n, 3, 3)."""
    n = v.shape[0]
    S = np.zeros((n, 3, 3))
    S[:, 0, 1], S[:, 0, 2] = -v[:, 2], v[:, 1]
    S[:, 1, 0], S[:, 1, 2] = v[:, 2], -v[:, 0]
    S[:, 2, 0], S[:, 2, 1] = -v[:, 1], v[:, 0]
    return S


def rigid_jacobian(p: TelescopeParams):
    """Return ``jac(X, U) -> (A, B)``: df/dx (n, 7+m, 7+m) and df/du (n, 7+m, m) of the rigid
    model with m gyrodynes (13 and 6 by default).

    ``X`` (n, 7+m) and ``U`` (n, m) are batches of states and controls (vectorised over time).
    """
    p.validate()
    I = p.I
    Ii = np.linalg.inv(I)
    ha, hb = p.gyro_matrices()
    m = p.n_gyros
    nx = 7 + m

    def jac(X, U):
        X = np.atleast_2d(np.asarray(X, float))
        U = np.atleast_2d(np.asarray(U, float))[:, :m]
        n = X.shape[0]
        lam, w, beta = X[:, :4], X[:, 4:7], X[:, 7:nx]
        c, s = np.cos(beta)[..., None], np.sin(beta)[..., None]
        Cj = -s * ha + c * hb          # (n, 6, 3) dk/dbeta_j
        kj = c * ha + s * hb           # (n, 6, 3) h (a_j cos + b_j sin)
        k = kj.sum(axis=1)
        L = w @ I.T + k
        A = np.zeros((n, nx, nx))
        w1, w2, w3 = w[:, 0], w[:, 1], w[:, 2]
        Aw = np.zeros((n, 4, 4))
        Aw[:, 0, 1], Aw[:, 0, 2], Aw[:, 0, 3] = -w1, -w2, -w3
        Aw[:, 1, 0], Aw[:, 1, 2], Aw[:, 1, 3] = w1, w3, -w2
        Aw[:, 2, 0], Aw[:, 2, 1], Aw[:, 2, 3] = w2, -w3, w1
        Aw[:, 3, 0], Aw[:, 3, 1], Aw[:, 3, 2] = w3, w2, -w1
        A[:, :4, :4] = 0.5 * Aw
        l0, l1, l2, l3 = lam[:, 0], lam[:, 1], lam[:, 2], lam[:, 3]
        Xi = np.stack([np.stack([-l1, -l2, -l3], -1), np.stack([l0, -l3, l2], -1),
                       np.stack([l3, l0, -l1], -1), np.stack([-l2, l1, l0], -1)], 1)
        A[:, :4, 4:7] = 0.5 * Xi
        A[:, 4:7, 4:7] = np.einsum("ab,nbc->nac", Ii, _skew(L) - _skew(w) @ I)
        dbeta = -np.cross(w[:, None, :], Cj) + kj * U[..., None]      # (n, m, 3)
        A[:, 4:7, 7:nx] = np.einsum("ab,njb->naj", Ii, dbeta)
        B = np.zeros((n, nx, m))
        B[:, 4:7, :] = np.einsum("ab,njb->naj", Ii, -Cj)
        B[:, 7:nx, :] = np.eye(m)
        return A, B
    return jac




def gyro_momentum(beta, p: TelescopeParams) -> np.ndarray:
    """k(beta) [N m s] in body axes."""
    ha, hb = p.gyro_matrices()
    beta = np.asarray(beta, float)
    return np.cos(beta) @ ha + np.sin(beta) @ hb


def body_momentum(x, p: TelescopeParams) -> np.ndarray:
    """Angular momentum of the rigid gyrostat in body axes, I w + k [N m s]."""
    x = np.asarray(x, float)
    return p.I @ x[4:7] + gyro_momentum(x[7:7 + p.n_gyros], p)


def inertial_momentum(x, p: TelescopeParams) -> np.ndarray:
    """First integral K = R(lam) (I w + k) [N m s] (inertial axes)."""
    return quat_to_matrix(x) @ body_momentum(x, p)


def singularity_measure(beta, p: TelescopeParams) -> float:
    """det(C C^T) / h^6 [1] of the 3 x n gyro Jacobian C = dk/dbeta (0 = singular state).

    Normalised by h^6: the maximum over beta is :func:`sing_max` (8 for six gyrodynes:
    C C^T = 2 h^2 I, trace = 6 h^2).
    """
    ha, hb = p.gyro_matrices()
    beta = np.asarray(beta, float)[:, None]
    C = (-np.sin(beta) * ha + np.cos(beta) * hb).T / p.h
    return float(np.linalg.det(C @ C.T))


def envelope_radius(direction, p: TelescopeParams) -> float:
    """Largest gyro momentum |k| [N m s] reachable along ``direction`` (the CMG envelope).

    Each gyro's rotor sweeps the plane normal to its gimbal axis, so its largest contribution
    along a unit vector e is h sqrt(1 - (e.g_j)^2).
    """
    e = np.asarray(direction, float)
    e = e / np.linalg.norm(e)
    g, _, _ = gimbal_vectors(p.rotor_ref, p.gimbal_axes)
    return float(p.h * sum(math.sqrt(max(0.0, 1.0 - float(np.dot(e, gj)) ** 2)) for gj in g))


def required_gyro_momentum(x0, lam_f, w_f, p: TelescopeParams) -> np.ndarray:
    """Gyro momentum k(T) [N m s] the end state needs: R(lam_f)^T K(x0) - I w_f."""
    K = inertial_momentum(x0, p)
    lam_f = np.asarray(lam_f, float)
    lam_f = lam_f / np.linalg.norm(lam_f)
    return quat_to_matrix(lam_f).T @ K - p.I @ np.asarray(w_f, float)
