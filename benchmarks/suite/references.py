"""The references of the benchmark suite, each computed by other means than the synthesis.

* **lq** -- the exact optimum of the sampled-data LQ problem: the plant and its continuous
  quadratic cost discretised exactly for the zero-order hold of the communication step (Van
  Loan's block matrix exponential), then the discrete Riccati equation with the cross term
  (``scipy.linalg.solve_discrete_are(..., s=N)``); the optimum from x0 is x0' P x0, the
  optimal law u = -K x.  :func:`lq_reference`.
* **cartpole** -- the LQR law of the linearisation at the upright (the same sampled-data
  Riccati solution with the cart-pole's cost weights), flown through the FMU: which starts it
  saves; and per start the best open-loop program found by trajectory optimisation (L-BFGS-B,
  in-process RK4 identical to the plant's), replayed through the plant FMU.
  :func:`cartpole_lqr`, :func:`cartpole_programs`.
* **parking** -- the polar-coordinate law of Aicardi et al. (1995), flown through the same
  Unicycle FMU from the same starts: :func:`aicardi_law`, :func:`parking_reference`.
* **reentry-second** -- the best open-loop program of S1's second scenario at miss <= 1 km
  (:func:`synthesis.systems.reentry.bound.reference_bounds`): :func:`reentry_second_bound`.
* **lunar-descent** -- the best J1 of CMA-ES over the 8 gains of the basic law (measured,
  docs/systems/lunar_descent.md): :data:`LUNAR_DESCENT_CMA_J1`.

Expensive references (the cart-pole programs, the S1 bound) are computed once and stored in
``benchmarks/suite/reference/*.json``; ``python benchmarks/suite/references.py`` recomputes
them.  Plants are flown through their FMUs with :class:`PlantFlyer` (fmpy, the master's order:
read the outputs at t_k, compute u_k, step) or, for network-operator laws, through the
package's closed loop.
"""
from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

SUITE = Path(__file__).resolve().parent
ROOT = SUITE.parent.parent
BUILD = SUITE / "build"
STORED = SUITE / "reference"
TUTORIAL = ROOT / "docs" / "tutorials"

#: plant FMUs the suite builds at run time: model identifier -> the plant file
PLANT_SOURCES = {"LQPlant": SUITE / "plants" / "lq.py",
                 "CartPole": SUITE / "plants" / "cartpole.py",
                 "Unicycle": SUITE / "plants" / "unicycle.py",
                 "DoubleIntegrator": SUITE / "plants" / "double_integrator.py",
                 "Oscillator": SUITE / "plants" / "oscillator.py",
                 "Hopper": TUTORIAL / "hopper.py"}

#: S5: best J1 [m] of CMA-ES over the basic law's 8 gains (benchmarks/lunar_descent_search.py
#: --flights 8664 --seed 1; docs/systems/lunar_descent.md, "Against a generic policy search")
LUNAR_DESCENT_CMA_J1 = 0.017


# -- building the plants -------------------------------------------------------------------------
def build_plants(dest: Path = BUILD, names=None, force: bool = False) -> dict:
    """Build the suite's plants into ``dest`` with ``descent-fmus build-plant`` (as a user
    would: each plant file gives its pythonfmu FMU and, beside it in ``native/``, its native C
    twin checked bit for bit, which the problems then fly), each only if missing or older than
    its source; copy the tutorial's ``hopper.toml`` beside its FMU.  Returns {identifier: FMU
    path}."""
    from concurrent.futures import ThreadPoolExecutor

    from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    native = find_compiler() is not None
    out, todo = {}, []
    for name, src in PLANT_SOURCES.items():
        if names is not None and name not in names:
            continue
        fmu = dest / f"{name}.fmu"
        out[name] = fmu
        if force or not fmu.is_file() or fmu.stat().st_mtime < src.stat().st_mtime or (
                native and not (dest / "native" / fmu.name).is_file()):
            todo.append(src)

    def build(src):
        r = subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main",
                            "build-plant", str(src), "-d", str(dest)], capture_output=True,
                           text=True)
        if r.returncode != 0:
            raise RuntimeError(f"build-plant {src.name}: "
                               f"{(r.stderr or r.stdout).strip().splitlines()[-1:]}")
    with ThreadPoolExecutor(max_workers=2) as pool:
        list(pool.map(build, todo))
    if names is None or "Hopper" in names:
        shutil.copyfile(TUTORIAL / "hopper.toml", dest / "hopper.toml")
    return out


# -- flying a plant FMU with a Python law ------------------------------------------------------
class PlantFlyer:
    """A plant FMU loaded once (fmpy), flown from start values under a Python law or an
    open-loop program, in the closed loop's order: at t_k read the outputs, compute u_k (clipped
    to the bounds, as the controller FMU clips), set it, step to t_k+1."""

    def __init__(self, fmu):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave
        self.path = Path(fmu)
        self.md = read_model_description(str(self.path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.outputs = [v.name for v in self.md.modelVariables if v.causality == "output"
                        and v.type == "Real"]
        self._dir = extract(str(self.path))
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self._dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName="plant")
        self.fmu.instantiate()
        self._fresh = True

    def defaults(self) -> dict:
        """The plant's declared start values of its Real parameters."""
        return {v.name: float(v.start) for v in self.md.modelVariables
                if v.causality == "parameter" and v.type == "Real"}

    def fly(self, start: dict, law, inputs, step: float, stop_time: float, bounds=None,
            record: bool = False) -> dict:
        """One flight.  ``law(outputs: dict) -> sequence`` of the values of ``inputs`` (or a
        sequence of such vectors, one per step: an open-loop program); ``bounds`` [(lo, hi)]
        clip them.  Returns the final outputs (and ``trace``: outputs per communication point
        with ``t`` and the applied ``u``, with ``record``)."""
        f = self.fmu
        if not self._fresh:
            f.reset()
        self._fresh = False
        f.setReal([self.vr[k] for k in start], [float(v) for v in start.values()])
        f.setupExperiment(startTime=0.0, stopTime=stop_time)
        f.enterInitializationMode()
        f.exitInitializationMode()
        out_vr = [self.vr[n] for n in self.outputs]
        in_vr = [self.vr[n] for n in inputs]
        n = int(round(stop_time / step))
        trace = {"t": [], "u": [], **{k: [] for k in self.outputs}}
        for k in range(n + 1):
            y = dict(zip(self.outputs, f.getReal(out_vr)))
            if record:
                trace["t"].append(k * step)
                for name in self.outputs:
                    trace[name].append(y[name])
            if k == n:
                break
            u = law[k] if not callable(law) else law(y)
            u = [float(v) for v in np.atleast_1d(u)]
            if bounds is not None:
                u = [min(max(v, lo), hi) for v, (lo, hi) in zip(u, bounds)]
            if record:
                trace["u"].append(u)
            f.setReal(in_vr, u)
            f.doStep(currentCommunicationPoint=k * step, communicationStepSize=step)
        out = dict(zip(self.outputs, f.getReal(out_vr)))
        if record:
            out["trace"] = {k: np.asarray(v) for k, v in trace.items()}
        return out

    def close(self) -> None:
        try:
            self.fmu.terminate()
            self.fmu.freeInstance()
        finally:
            shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def fly_law(problem, law, fmu_dir=None) -> list:
    """The final plant outputs of a network-operator ``law`` flown from every initial state of
    ``problem`` through its closed loop (plant FMU and the controller FMU), one dict per
    start."""
    from descent_fmus.synthesis.fmi.loop import open_loop
    from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir
    plant, ctrl = problem.fmu_paths(fmu_dir or default_fmu_dir())
    loop = open_loop(problem.wiring, plant, ctrl, native=False)
    try:
        return [loop.run(plant_values=s, controller_values=law.start_values()).final
                for s in problem.initial_states]
    finally:
        loop.close()


def objective_of(problem, law, fmu_dir=None) -> tuple:
    """The objectives and total constraint violation of ``law`` on ``problem``, through the
    package's evaluator (the numbers a synthesis run sees)."""
    from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir
    from descent_fmus.synthesis.run.evaluation import Evaluator
    ev = Evaluator(problem, fmu_dir or default_fmu_dir())
    try:
        r = ev.evaluate([law])
        return tuple(float(v) for v in r.F[0]), float(r.cv[0])
    finally:
        ev.close()


# -- lq: the sampled-data Riccati solution ---------------------------------------------------
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


# -- cartpole --------------------------------------------------------------------------------
def cartpole_rhs(p: dict):
    """The cart-pole's right-hand side (``plants/cartpole.py``) on arrays: f(s, F) with s of
    shape (..., 5) = (x, xdot, theta, thetadot, J)."""
    mc, mp, l, g = p["m_c"], p["m_p"], p["l"], p["g"]
    w = (p["w_x"], p["w_xdot"], p["w_theta"], p["w_thetadot"], p["w_F"])

    def f(s, F):
        x, xd, th, thd = s[..., 0], s[..., 1], s[..., 2], s[..., 3]
        st, ct = np.sin(th), np.cos(th)
        M = mc + mp
        tmp = (F + mp * l * thd * thd * st) / M
        thdd = (g * st - ct * tmp) / (l * (4.0 / 3.0 - mp * ct * ct / M))
        xdd = tmp - mp * l * thdd * ct / M
        c = w[0] * x * x + w[1] * xd * xd + w[2] * th * th + w[3] * thd * thd + w[4] * F * F
        return np.stack([xd, xdd, thd, thdd, c], -1)
    return f


def cartpole_lqr(p: dict, h: float) -> dict:
    """The LQR law of the cart-pole linearised at the upright, for the law sampled every h
    (:func:`sampled_lqr` with the plant's cost weights): u = -K (x, xdot, theta, thetadot)."""
    f = cartpole_rhs(p)
    s0, e = np.zeros(5), 1e-6
    A = np.zeros((4, 4))
    for i in range(4):
        d = np.zeros(5)
        d[i] = e
        A[:, i] = (f(s0 + d, 0.0)[:4] - f(s0 - d, 0.0)[:4]) / (2 * e)
    B = ((f(s0, e)[:4] - f(s0, -e)[:4]) / (2 * e)).reshape(4, 1)
    Q = np.diag([p["w_x"], p["w_xdot"], p["w_theta"], p["w_thetadot"]])
    R = np.array([[p["w_F"]]])
    d = sampled_lqr(A, B, Q, R, h)
    return {"A": A.tolist(), "B": B.ravel().tolist(), "K": d["K"].ravel().tolist()}


def _cartpole_fly(f, p, s0, V, K, h, n_sub, Fmax):
    """Flights of the programs u_k = Fmax tanh((v_k - K x_k) / Fmax) (rows of V) from s0: a
    feedback-parametrised open-loop program (any program within the bounds is one, and the
    parametrisation keeps the unstable pendulum's sensitivities bounded); (J, programs)."""
    V = np.atleast_2d(V)
    s = np.zeros((V.shape[0], 5))
    s[:, :4] = s0
    dt = h / n_sub
    U = np.empty_like(V)
    for k in range(V.shape[1]):
        F = Fmax * np.tanh((V[:, k] - s[:, :4] @ K) / Fmax)
        U[:, k] = F
        for _ in range(n_sub):
            k1 = f(s, F)
            k2 = f(s + 0.5 * dt * k1, F)
            k3 = f(s + 0.5 * dt * k2, F)
            k4 = f(s + dt * k3, F)
            s = s + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return s[:, 4], U


def cartpole_program(p: dict, s0, K, h: float, steps: int, v0=None,
                     maxiter: int = 3000) -> dict:
    """A locally optimal open-loop program from one start: L-BFGS-B over the feedforward v of
    :func:`_cartpole_fly` (forward-difference gradients, all perturbed flights in one batch),
    from ``v0`` (default 0: the smoothly saturated law -K x).  Any law's flight is a program, so
    no law does better from this start than the global optimum of this problem; L-BFGS-B finds
    a local one."""
    from scipy.optimize import minimize
    f = cartpole_rhs(p)
    K = np.asarray(K, float)
    n_sub, Fmax = int(p["n_sub"] + 0.5), p["F_max"]

    def fun(v):
        eps = 1e-7
        J, _ = _cartpole_fly(f, p, s0, np.vstack([v, v + eps * np.eye(steps)]), K, h, n_sub,
                             Fmax)
        return J[0], (J[1:] - J[0]) / eps

    start = np.zeros(steps) if v0 is None else np.asarray(v0, float)
    r = minimize(fun, start, jac=True, method="L-BFGS-B", options={"maxiter": maxiter})
    J, U = _cartpole_fly(f, p, s0, r.x, K, h, n_sub, Fmax)
    return {"J": float(J[0]), "u": U[0].tolist(), "v": r.x.tolist(), "iterations": int(r.nit),
            "message": str(r.message)}


def cartpole_start(state: dict) -> np.ndarray:
    return np.array([state.get("x0", 0.0), state.get("xdot0", 0.0), state.get("theta0", 0.0),
                     state.get("thetadot0", 0.0)])


#: gains of the programs' parametrisation, as multiples of the LQR gains: the optimum is the
#: same program problem for each, the local optimum L-BFGS-B reaches is not
CARTPOLE_PARAMETRISATIONS = (1.0, 1.5)


def cartpole_programs(problem, p: dict, K) -> list:
    """The best of several local optima per initial state of ``problem``: each parametrisation
    of :data:`CARTPOLE_PARAMETRISATIONS`, started from v = 0 and (continuation) from the best
    program of the next smaller angle of the same sign; starts in order of |theta0|."""
    h, T = problem.wiring.step, problem.wiring.stop_time
    steps = int(round(T / h))
    states = sorted(problem.initial_states, key=lambda s: abs(s.get("theta0", 0.0)))
    best, prev = {}, {}
    for s in states:
        s0 = cartpole_start(s)
        sign = math.copysign(1.0, s0[2])
        tries = []
        for m in CARTPOLE_PARAMETRISATIONS:
            Km = m * np.asarray(K, float)
            guesses = [None] + ([prev[sign][1]] if sign in prev and prev[sign][0] == m else [])
            for v0 in guesses:
                tries.append(dict(cartpole_program(p, s0, Km, h, steps, v0), gain_multiple=m,
                                  continued=v0 is not None))
        b = min(tries, key=lambda r: r["J"])
        prev[sign] = (b["gain_multiple"], b["v"])
        b = {k: v for k, v in b.items() if k != "v"}
        b["tries"] = [round(r["J"], 6) for r in tries]
        best[id(s)] = dict(b, start=s)
    # the cart-pole is odd-symmetric (sin, the force and every state change sign together, the
    # cost is even), so the negated program of the mirrored start is a program of this start
    # with the same cost, bit for bit: keep the better of the two
    out = []
    for s in problem.initial_states:
        b = best[id(s)]
        m = next((best[id(t)] for t in problem.initial_states
                  if all(t.get(k, 0.0) == -s.get(k, 0.0) for k in set(s) | set(t))), None)
        if m is not None and m["J"] < b["J"]:
            b = dict(m, u=[-v for v in m["u"]], start=s, mirrored=True)
        out.append(b)
    return out


# -- parking -----------------------------------------------------------------------------------
#: gains of the polar law [our choice]: gamma, k, h > 0 (any positive values converge)
AICARDI_GAINS = (3.0, 6.0, 1.0)
#: its gains for parking-box [our choice]: with the turn rate clipped to +-1 the gains above
#: saturate it and leave headings off by up to pi; the best of a grid over gamma in {0.2 .. 1},
#: k in {0.5 .. 3}, h in {0.5 .. 3} on the problem's starts parks all 12 to 3e-6 in 16 s
AICARDI_GAINS_BOX = (1.0, 3.0, 3.0)


def aicardi_law(gamma: float = AICARDI_GAINS[0], k: float = AICARDI_GAINS[1],
                h: float = AICARDI_GAINS[2]):
    """The law of Aicardi, Casalino, Bicchi & Balestrino (1995) on the plant's polar outputs
    (rho = distance, phi = direction to the target, alpha = phi - heading):

        v = gamma rho cos(alpha),  omega = k alpha + gamma cos(alpha) sin(alpha) (alpha + h phi) / alpha

    With V = (rho^2 + alpha^2 + h phi^2) / 2, dV/dt = -gamma cos^2(alpha) rho^2 - k alpha^2
    <= 0: rho, alpha, phi -> 0 from every start (the heading -> phi - alpha = 0)."""
    def law(y: dict) -> tuple:
        rho, a, phi = y["rho"], y["alpha"], y["phi"]
        sinc = math.sin(a) / a if abs(a) > 1e-12 else 1.0
        return (gamma * rho * math.cos(a),
                k * a + gamma * math.cos(a) * sinc * (a + h * phi))
    return law


def parking_reference(problem, fmu_dir=None, gains=AICARDI_GAINS) -> dict:
    """The polar law with ``gains`` flown through the problem's Unicycle FMU from every start:
    final distance and |heading| per start, their means, and the ``park`` objective (mean of
    their sum)."""
    plant, _ = problem.fmu_paths(fmu_dir or BUILD)
    law = aicardi_law(*gains)
    bounds = list(problem.basic().bounds)
    rows = []
    with PlantFlyer(plant) as fl:
        for s in problem.initial_states:
            out = fl.fly(s, law, ["v", "omega"], problem.wiring.step, problem.wiring.stop_time,
                         bounds)
            rows.append({"start": s, "distance": out["rho"], "heading": abs(out["theta"])})
    d = [r["distance"] for r in rows]
    a = [r["heading"] for r in rows]
    return {"per_start": rows, "mean_distance": float(np.mean(d)),
            "mean_heading": float(np.mean(a)), "park": float(np.mean(np.add(d, a))),
            "worst": float(max(np.add(d, a))), "gains": list(gains)}


# -- reentry-second --------------------------------------------------------------------------
def reentry_second_bound(miss_tol: float = 1000.0) -> dict:
    """S1's second scenario: the best program on the 1 s grid at zero miss and at miss <=
    ``miss_tol`` (SLSQP with exact sensitivities; ~1 min)."""
    from descent_fmus.models.reentry import SECOND_SCENARIO
    from descent_fmus.synthesis.systems.reentry.bound import reference_bounds
    zero, tol = reference_bounds(miss_tol, SECOND_SCENARIO)
    return {"zero_miss": zero.to_dict(), "miss_tol": miss_tol, "bound": tol.to_dict(),
            "J1": tol.J1}


# -- stored references ------------------------------------------------------------------------
def stored(name: str) -> dict:
    """A stored reference (``reference/<name>.json``)."""
    return json.loads((STORED / f"{name}.json").read_text())


def compute_stored(names=("cartpole", "reentry-second")) -> None:
    """Recompute the expensive references and store them."""
    from descent_fmus.synthesis.problems.files import load_problem_file
    STORED.mkdir(exist_ok=True)
    build_plants(names=("CartPole",))
    if "cartpole" in names:
        prob = load_problem_file(SUITE / "cartpole.toml")
        with PlantFlyer(BUILD / "CartPole.fmu") as fl:
            p = fl.defaults()
        lqr = cartpole_lqr(p, prob.wiring.step)
        progs = cartpole_programs(prob, p, lqr["K"])
        (STORED / "cartpole.json").write_text(json.dumps(
            {"lqr": lqr, "programs": progs, "step": prob.wiring.step,
             "stop_time": prob.wiring.stop_time}, indent=1))
    if "reentry-second" in names:
        (STORED / "reentry-second.json").write_text(json.dumps(reentry_second_bound(),
                                                               indent=1))


if __name__ == "__main__":
    compute_stored(tuple(sys.argv[1:]) or ("cartpole", "reentry-second"))
