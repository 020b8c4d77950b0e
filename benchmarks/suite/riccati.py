"""The sampled-data LQ solution: the exact optimum of the suite's lq problem and the LQR laws.

The plant and its continuous quadratic cost are discretised exactly for the zero-order hold of
the communication step (Van Loan's block matrix exponential, :func:`van_loan`), then the
discrete Riccati equation with the cross term (``scipy.linalg.solve_discrete_are(..., s=N)``,
:func:`sampled_lqr`); the optimum from x0 is x0' P x0, the optimal law u = -K x
(:func:`lq_reference`).  The cart-pole's LQR law (``cartpole_reference.py``) and the
minimum-time references (``mintime.py``) use the same discretisation.
"""
from __future__ import annotations

import numpy as np

__all__ = ["van_loan", "sampled_lqr", "law_cost_matrix", "finite_horizon_bound", "lq_matrices",
           "lq_reference"]


def van_loan(A, B, Q, R, h: float) -> tuple:
    """Exact zero-order-hold discretisation of dx/dt = A x + B u and of the cost
    integral(x'Qx + u'Ru) over one step h: (Ad, Bd, Qd, Nd, Rd) with
    x_{k+1} = Ad x_k + Bd u_k and the step's cost x'Qd x + 2 x'Nd u + u'Rd u (Van Loan 1978:
    one matrix exponential of the block matrix [[-F', W], [0, F]] h, F = [[A, B], [0, 0]])."""
    from scipy.linalg import block_diag, expm
    A, B = np.atleast_2d(A).astype(float), np.atleast_2d(B).astype(float)
    n, m = B.shape
    F = np.zeros((n + m, n + m))
    F[:n, :n], F[:n, n:] = A, B
    W = block_diag(np.atleast_2d(Q), np.atleast_2d(R))
    C = np.zeros((2 * (n + m),) * 2)
    C[:n + m, :n + m], C[:n + m, n + m:], C[n + m:, n + m:] = -F.T, W, F
    E = expm(C * h)
    Phi = E[n + m:, n + m:]
    M = Phi.T @ E[:n + m, n + m:]
    M = 0.5 * (M + M.T)
    return Phi[:n, :n], Phi[:n, n:], M[:n, :n], M[:n, n:], M[n:, n:]


def sampled_lqr(A, B, Q, R, h: float) -> dict:
    """The optimal sampled-data law u_k = -K x_k (u held over h) and the cost matrix P of the
    infinite-horizon continuous cost: ``solve_discrete_are`` with the cross term of
    :func:`van_loan`."""
    from scipy.linalg import solve_discrete_are
    Ad, Bd, Qd, Nd, Rd = van_loan(A, B, Q, R, h)
    P = solve_discrete_are(Ad, Bd, Qd, Rd, s=Nd)
    K = np.linalg.solve(Rd + Bd.T @ P @ Bd, Bd.T @ P @ Ad + Nd.T)
    return {"K": K, "P": P, "Ad": Ad, "Bd": Bd, "Qd": Qd, "Nd": Nd, "Rd": Rd}


def law_cost_matrix(d: dict, K) -> np.ndarray:
    """P_K with x0' P_K x0 the infinite-horizon cost of the sampled law u = -K x (a discrete
    Lyapunov equation; inf if the loop is unstable)."""
    from scipy.linalg import solve_discrete_lyapunov
    K = np.atleast_2d(K)
    Acl = d["Ad"] - d["Bd"] @ K
    if max(abs(np.linalg.eigvals(Acl))) >= 1.0:
        return np.full(Acl.shape, np.inf)
    W = d["Qd"] - d["Nd"] @ K - K.T @ d["Nd"].T + K.T @ d["Rd"] @ K
    return solve_discrete_lyapunov(Acl.T, W)


def finite_horizon_bound(d: dict, steps: int) -> np.ndarray:
    """P_N of the N-step problem without terminal cost (backward Riccati recursion): x0' P_N x0
    is the least cost of ANY control sequence (time-varying, nonlinear) over N steps."""
    Ad, Bd, Qd, Nd, Rd = (d[k] for k in ("Ad", "Bd", "Qd", "Nd", "Rd"))
    P = np.zeros_like(Qd)
    for _ in range(steps):
        G = Rd + Bd.T @ P @ Bd
        H = Bd.T @ P @ Ad + Nd.T
        P = Qd + Ad.T @ P @ Ad - H.T @ np.linalg.solve(G, H)
        P = 0.5 * (P + P.T)
    return P


def lq_matrices(params: dict) -> tuple:
    """(A, B, Q, R) of the LQ plant from its parameters (``plants/lq.py``)."""
    A = np.array([[0.0, 1.0], [params["a21"], params["a22"]]])
    B = np.array([[0.0], [params["b"]]])
    return A, B, np.diag([params["q1"], params["q2"]]), np.array([[params["r"]]])


def lq_reference(problem, params: dict) -> dict:
    """The optimum of the lq problem: per start x0' P x0, their mean (the reference of the
    ``cost`` objective, a mean over the starts), the optimal gains, the finite-horizon lower
    bound at the problem's horizon, the basic law's exact cost and the continuous-time LQR for
    comparison.  ``params`` are the plant's parameter values (its defaults)."""
    from scipy.linalg import solve_continuous_are
    A, B, Q, R = lq_matrices(params)
    h, T = problem.wiring.step, problem.wiring.stop_time
    d = sampled_lqr(A, B, Q, R, h)
    X0 = np.array([[s["x10"], s["x20"]] for s in problem.initial_states])
    per = [float(x @ d["P"] @ x) for x in X0]
    PN = finite_horizon_bound(d, int(round(T / h)))
    basic = problem.basic()
    Kb = -np.array(basic.q[:2])[None, :]
    Pb = law_cost_matrix(d, Kb)
    Pc = solve_continuous_are(A, B, Q, R)
    return {"K": d["K"].ravel().tolist(), "P": d["P"].tolist(), "per_start": per,
            "mean": float(np.mean(per)),
            "finite_horizon_mean": float(np.mean([x @ PN @ x for x in X0])),
            "basic_law_mean": float(np.mean([x @ Pb @ x for x in X0])),
            "K_continuous": np.linalg.solve(R, B.T @ Pc).ravel().tolist(),
            "continuous_mean": float(np.mean([x @ Pc @ x for x in X0])),
            "closed_loop_poles": np.linalg.eigvals(d["Ad"] - d["Bd"] @ d["K"]).tolist()}
