"""The discretised boundary problem of the direct method: its data, the piecewise-linear control
class and the integration of the plant under it.

* :class:`BoundaryProblem`, :class:`LinearModel` -- the problem and the model it is linearised on;
* :class:`DirectResult` -- what :func:`synthesis.methods.direct_method.solve` returns;
* :func:`simulate`, :func:`control_energy`, :func:`mass_matrix`, :func:`blend_window`,
  :func:`fd_jacobian` -- the control class (node values, linear in between), its energy, the
  end-blending window and the fallback Jacobian;
* :class:`Discretisation` -- the fixed quantities of one solve (grid, sub-steps, end conditions,
  kept nodes, rate limits, quadrature weights), computed once before the iterations.

The method itself is described in :mod:`synthesis.methods.direct_method` (the driver) and
:mod:`synthesis.methods.direct_step` (one Newton-Kantorovich correction).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from descent_fmus.models.rk4_input import rk4_linear_input_step

__all__ = ["BoundaryProblem", "LinearModel", "DirectResult", "ConvergenceError",
           "SingularGramError", "SaturatedError", "Discretisation", "simulate", "blend_window",
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


@dataclass(frozen=True)
class Discretisation:
    """The fixed quantities of one solve of a :class:`BoundaryProblem` (computed once, before
    the iterations, by :meth:`of`).

    Attributes
    ----------
    problem : BoundaryProblem
        The validated problem.
    linear : LinearModel
        The model the iterations linearise.
    t_nodes : ndarray
        Control grid [s] (intervals+1,).
    h : float
        RK4 sub-step [s] (``substeps`` per control interval).
    idx, xf : ndarray
        State components of the end conditions and their target values.
    fixed : ndarray of bool
        (intervals+1, n_u): the node values kept at the initial guess (``u(t0)``, and ``u(tf)``
        unless ``free_end``).
    lim : ndarray or None
        Rate limits (n_u,).
    w_nodes : ndarray
        The blending window at the nodes (the correction vanishes at the kept ends).
    simpson, frac : ndarray
        Simpson's weights of the sub-step ends of one control interval (m+1,), and the fraction
        of the interval at each: they integrate the impulse response against the hat functions.
    Mk : ndarray or None
        Mass matrix of the node values, node-major (``minimize_energy`` only).
    """

    problem: BoundaryProblem
    linear: LinearModel
    t_nodes: np.ndarray
    h: float
    idx: np.ndarray
    xf: np.ndarray
    fixed: np.ndarray
    lim: np.ndarray | None
    w_nodes: np.ndarray
    simpson: np.ndarray
    frac: np.ndarray
    Mk: np.ndarray | None

    @classmethod
    def of(cls, problem: BoundaryProblem, linear: LinearModel | None = None) -> "Discretisation":
        """Validate ``problem`` and discretise it; ``linear`` defaults to ``problem.jac`` (or
        finite differences of ``problem.rhs``) on the full state."""
        pb = problem.validate()
        t_nodes = pb.nodes
        m, nu = pb.substeps, pb.n_u
        fixed = np.zeros((pb.intervals + 1, nu), bool)
        fixed[0] = True
        if not pb.free_end:
            fixed[-1] = True
        if linear is None:
            linear = LinearModel(pb.jac or fd_jacobian(pb.rhs))
        h = (t_nodes[1] - t_nodes[0]) / m
        simpson = np.ones(m + 1)
        simpson[1:-1:2], simpson[2:-1:2] = 4.0, 2.0
        simpson *= h / 3.0
        return cls(problem=pb, linear=linear, t_nodes=t_nodes, h=h,
                   idx=np.array(pb.target_index), xf=np.array(pb.target_value, float),
                   fixed=fixed, lim=pb.limits(),
                   w_nodes=blend_window(t_nodes, pb.t0, pb.tf, pb.blend, at_end=not pb.free_end),
                   simpson=simpson, frac=np.arange(m + 1) / m,
                   Mk=np.kron(mass_matrix(t_nodes), np.eye(nu)) if pb.minimize_energy else None)

    @property
    def N(self) -> int:
        """Number of control intervals."""
        return self.problem.intervals

    @property
    def m(self) -> int:
        """RK4 sub-steps per control interval."""
        return self.problem.substeps

    @property
    def n_u(self) -> int:
        """Number of controls."""
        return self.problem.n_u

    @property
    def energy(self) -> bool:
        """The minimum-energy variant (``minimize_energy``)."""
        return bool(self.problem.minimize_energy)

    def project(self, X: np.ndarray) -> np.ndarray:
        """Full states (n, nx) -> the states of the linearised model (identity by default)."""
        return X if self.linear.project is None else self.linear.project(X)

    def simulate(self, P: np.ndarray):
        """Integrate the plant with the node values ``P``: ``(t, X, U)`` on the sub-steps."""
        pb = self.problem
        return simulate(pb.rhs, pb.x0, self.t_nodes, P, self.m)

    def miss(self, X: np.ndarray) -> np.ndarray:
        """``xf - x_S(tf)`` of the states ``X`` (the correction's right-hand side)."""
        return self.xf - X[-1, self.idx]

    def initial_controls(self, controls=None) -> np.ndarray:
        """The first iterate's node values: ``controls`` (default zero) within the rate limits.

        Raises
        ------
        ValueError
            ``controls`` of the wrong shape, or whose kept end values exceed the rate limits.
        """
        shape = (self.N + 1, self.n_u)
        P = np.zeros(shape) if controls is None else np.array(controls, float).copy()
        if P.shape != shape:
            raise ValueError(f"controls must have shape {shape}, got {P.shape}")
        lim = self.lim
        if lim is not None:
            if np.any(np.abs(P[self.fixed]) > np.broadcast_to(lim, P.shape)[self.fixed]):
                raise ValueError("the kept end values of the control exceed the rate limit "
                                 "u_max")
            P = np.clip(P, -lim, lim)
        return P
