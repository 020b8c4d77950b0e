"""The bound for S1 feedback laws: the best open-loop program u(t) (min max load at a given miss).

No feedback law can beat the best open-loop program on the nominal flight, so its J1 is the limit
the network-operator synthesis approaches.  :func:`optimize_open_loop` solves

    minimise max_t load(t; u)   subject to  |L(tf; u) - Lf| <= miss_tol,   -0.2 <= u_k <= 0.2,

over u_k held on segments of ``t_seg`` -- by default the controller's own sample period (the
closed loop's 1 s communication step, so every feedback law is such a program) -- with
:func:`synthesis.methods.open_loop.minimax_program`.  ``load(t)`` is the plant's true peak: the
samples at every RK4 sub-step and both one-sided values at every control change, exactly what the
Reentry FMU measures (:class:`ProgramFlight` runs the same functions on the same sub-steps).

Gradients are exact derivatives of the discrete flight: the RK4 sub-steps propagate the
sensitivities of the state to every u_k (tangent-linear RK4 with the hand-differentiated
right-hand side :func:`models.reentry.rhs_jacobians`), the landing time's dependence on u
enters through the event condition h = hf.  One flight with all sensitivities costs about as
much as three plain flights, where finite differences cost one flight per segment.

References
----------
Diveev & Shmalko (the paper compares its feedback law with the optimal program of its refs.).
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from descent_fmus.models.integrators import locate_crossing, rk4_step_with_k1
from descent_fmus.models.reentry import (DT_INTEGRATION, T_PLUS, U_BOUNDS, ReentryParams,
                                         downrange, initial_state, loads, rhs, rhs_jacobians,
                                         simulate)
from descent_fmus.synthesis.methods.open_loop import minimax_program

__all__ = ["Program", "ProgramFlight", "fly_program", "optimize_open_loop", "reference_bounds",
           "replay_program", "plot_program", "T_SEG"]

#: Default segment length [s]: the controller's sample period (the closed loop's step).
T_SEG = 1.0


@dataclass
class Program:
    """A piecewise-constant control program u(t) = u[k] for k*t_seg <= t < (k+1)*t_seg."""

    u: np.ndarray
    t_seg: float
    J1: float = math.nan
    miss: float = math.nan
    t_land: float = math.nan
    info: dict = field(default_factory=dict)

    def __call__(self, t: float) -> float:
        k = min(int(t / self.t_seg + 1e-9), len(self.u) - 1)
        return float(self.u[k])

    def to_dict(self) -> dict:
        return {"u": [float(v) for v in self.u], "t_seg": self.t_seg, "J1": self.J1,
                "miss": self.miss, "t_land": self.t_land, "info": self.info}

    def save(self, path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1))
        return path

    @classmethod
    def load(cls, path) -> "Program":
        try:
            d = json.loads(Path(path).read_text())
            return cls(np.asarray(d["u"], float), float(d["t_seg"]), d.get("J1", math.nan),
                       d.get("miss", math.nan), d.get("t_land", math.nan), d.get("info", {}))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{path} is not a program file: {exc}") from None


def fly_program(u, t_seg: float, p: ReentryParams = ReentryParams(), trace: bool = False):
    """Fly the program in-process (communication step = segment length; the plant's integrator)."""
    u = np.asarray(u, float)
    prog = lambda t, x: float(u[min(int(t / t_seg + 1e-9), len(u) - 1)])  # noqa: E731
    return simulate(p, prog, step=t_seg, t_plus=T_PLUS, trace=trace)


def _load_and_gradient(x, dx, fx, fu, u, p: ReentryParams, kd: float):
    """The load at (x, u) and its gradients with respect to x (4,) and u."""
    load = loads(x, dx, kd, p.lam, p.Rz, p.g0, u)[0]
    x1, _, x3, _ = x
    r2 = x1 * x1 + x3 * x3
    a = math.hypot(dx[1], dx[3])
    c = 1.0 / (p.Rz * p.Rz * p.g0)
    if a == 0.0:
        return load, np.zeros(4), 0.0
    ga = (dx[1] * np.asarray(fx[1]) + dx[3] * np.asarray(fx[3])) / a
    gx = c * (r2 * ga + a * np.array([2.0 * x1, 0.0, 2.0 * x3, 0.0]))
    gu = c * r2 * (dx[1] * fu[1] + dx[3] * fu[3]) / a
    return load, gx, gu


def _rk4_tangent(x, u, h, args):
    """(Phi, Gamma): derivatives of one RK4 step of size ``h`` from ``x`` (control ``u`` held)
    with respect to the start state and to u."""
    c = args[1:]
    eye = np.eye(4)
    fx, fu = rhs_jacobians(x, u, *c)
    k1 = rhs(x, *args)
    Kx, Ku = np.asarray(fx), np.asarray(fu)
    sx, su = Kx.copy(), Ku.copy()
    ks = k1
    for w, a in ((2.0, 0.5), (2.0, 0.5), (1.0, 1.0)):
        xs = tuple(xi + a * h * ki for xi, ki in zip(x, ks))
        fx, fu = rhs_jacobians(xs, u, *c)
        fx = np.asarray(fx)
        Kx, Ku = fx @ (eye + a * h * Kx), fx @ (a * h * Ku) + np.asarray(fu)
        sx += w * Kx
        su += w * Ku
        ks = rhs(xs, *args)
    return eye + h / 6.0 * sx, h / 6.0 * su


class ProgramFlight:
    """One in-process flight of a program on the plant's own sub-steps, with sensitivities.

    ``loads`` are the samples the Reentry FMU takes (every sub-step start, both one-sided values at
    each segment end, the landing point), so ``max(loads)`` equals the FMU's ``load_max`` of the
    same program.  With ``sensitivities`` the flight also gives ``dloads`` (samples x segments) and
    ``dmiss`` (segments,), exact derivatives of the discrete flight.

    ``miss`` is L(tf) - Lf [m] (signed); a flight that never reaches hf by t+ gets
    -|L - Lf| - (h - hf), so that "reaching the target" stays a smooth constraint.
    """

    def __init__(self, u, t_seg: float = T_SEG, p: ReentryParams = ReentryParams(),
                 dt: float = DT_INTEGRATION, sensitivities: bool = True):
        u = np.clip(np.asarray(u, float), *U_BOUNDS)
        n = len(u)
        args0 = p.constants()
        kd = args0[1]
        rz_hf = p.Rz + p.hf
        x = initial_state(p)
        S = np.zeros((4, n)) if sensitivities else None
        samples, grads = [], []

        def sample(x, dx, u_k, k, S):
            if S is None:
                samples.append(loads(x, dx, kd, p.lam, p.Rz, p.g0, u_k)[0])
                return
            fx, fu = rhs_jacobians(x, u_k, *args0)
            val, gx, gu = _load_and_gradient(x, dx, fx, fu, u_k, p, kd)
            row = gx @ S
            row[k] += gu
            samples.append(val)
            grads.append(row)

        t, landed, n_steps = 0.0, False, int(math.ceil(T_PLUS / t_seg - 1e-9))
        for k in range(n_steps):
            uk = float(u[min(k, n - 1)])
            kk = min(k, n - 1)
            args = (uk,) + args0
            t_end = min((k + 1) * t_seg, T_PLUS)
            m = max(1, math.ceil((t_end - t) / dt - 1e-9))
            h = (t_end - t) / m
            for _ in range(m):
                k1 = rhs(x, *args)
                sample(x, k1, uk, kk, S)
                xn = rk4_step_with_k1(rhs, x, k1, h, args)
                g1 = math.hypot(xn[0], xn[2]) - rz_hf
                if g1 <= 0.0:
                    g0 = math.hypot(x[0], x[2]) - rz_hf
                    s, xs = locate_crossing(rhs, x, k1, h, args,
                                            lambda y: math.hypot(y[0], y[2]) - rz_hf, g0, g1)
                    if S is not None:
                        phi, gam = _rk4_tangent(x, uk, s * h, args)
                        S = phi @ S
                        S[:, kk] += gam
                        # the landing time moves with u: dt_land = -(dG/dx dx)/(dG/dx f)
                        fs = rhs(xs, *args)
                        r = math.hypot(xs[0], xs[2])
                        dG = np.array([xs[0] / r, 0.0, xs[2] / r, 0.0])
                        S = S - np.outer(fs, (dG @ S) / (dG @ np.asarray(fs)))
                    x, t, landed = xs, t + s * h, True
                    break
                if S is not None:
                    phi, gam = _rk4_tangent(x, uk, h, args)
                    S = phi @ S
                    S[:, kk] += gam
                x, t = xn, t + h
            if landed:
                sample(x, rhs(x, *args), uk, kk, S)
                break
            sample(x, rhs(x, *args), uk, kk, S)       # left-hand value at the segment end
        r = math.hypot(x[0], x[2])
        L = downrange(x, p.Rz)
        dL = p.Rz * np.array([x[2], 0.0, -x[0], 0.0]) / (r * r)
        if landed:
            miss, gmiss = L - p.Lf, dL
        else:
            sgn = 1.0 if L >= p.Lf else -1.0
            miss = -abs(L - p.Lf) - (r - rz_hf)
            gmiss = -sgn * dL - np.array([x[0] / r, 0.0, x[2] / r, 0.0])
        self.u, self.t_seg = u, t_seg
        self.loads = np.array(samples)
        self.landed, self.t_end, self.x = landed, t, x
        self.miss = miss
        self.dloads = np.array(grads) if S is not None else None
        self.dmiss = gmiss @ S if S is not None else None

    @property
    def J1(self) -> float:
        return float(self.loads.max())


def optimize_open_loop(p: ReentryParams = ReentryParams(), t_seg: float = T_SEG,
                       miss_tol: float = 0.0, maxiter: int = 300, tol: float = 1e-10,
                       u0=None, progress=None) -> Program:
    """Best piecewise-constant program (SLSQP on the epigraph form, exact gradients).

    Parameters
    ----------
    p : ReentryParams
        Scenario.
    t_seg : float
        Segment length [s] (default: the controller's sample period, 1 s); the program has
        ceil(t+ / t_seg) values.
    miss_tol : float
        Allowed |L(tf) - Lf| [m] (0: hit Lf exactly).
    maxiter, tol : int, float
        SLSQP limits.
    u0 : array-like, optional
        Starting program (default u = 0).
    progress : callable, optional
        Called with (iteration, J1, |miss| violation) after every SLSQP iteration.

    Returns
    -------
    Program
        With ``J1`` (true-peak max load), ``miss`` |L(tf) - Lf| [m], ``t_land`` and solver
        ``info``.
    """
    if not t_seg > 0:
        raise ValueError(f"t_seg must be > 0, got {t_seg}")
    if not miss_tol >= 0:
        raise ValueError(f"miss_tol must be >= 0, got {miss_tol}")
    n = int(math.ceil(T_PLUS / t_seg - 1e-9))
    # upper bound on the samples of one flight: every sub-step start, two per segment end
    n_samples = int(math.ceil(T_PLUS / DT_INTEGRATION)) + 2 * n + 2

    def pad(a, fill):
        out = np.full((n_samples,) + a.shape[1:], fill)
        out[:len(a)] = a
        return out

    def fly(u):
        f = ProgramFlight(u, t_seg, p)
        return (pad(f.loads, 0.0), f.miss, pad(f.dloads, 0.0), f.dmiss[None, :])

    # miss in units of 10 km keeps the constraint well scaled
    u, info = minimax_program(fly, n, U_BOUNDS, u0=u0, eq_scale=1e-4, eq_tol=miss_tol,
                              maxiter=maxiter, tol=tol, progress=progress, with_jacobian=True)
    f = ProgramFlight(u, t_seg, p, sensitivities=False)
    info.update(segments=n, miss_tol=miss_tol)
    return Program(u, t_seg, J1=f.J1, miss=abs(f.miss) if f.landed else math.nan,
                   t_land=f.t_end if f.landed else math.nan, info=info)


def reference_bounds(miss_tol: float, p: ReentryParams = ReentryParams(),
                     t_seg: float = T_SEG) -> tuple[Program, Program]:
    """(zero-miss bound, bound at ``miss_tol``): the second starts from the first's program."""
    zero = optimize_open_loop(p, t_seg)
    tol = optimize_open_loop(p, t_seg, miss_tol=miss_tol, u0=zero.u)
    return zero, tol


def replay_program(prog: Program, fmu_dir, p: ReentryParams = ReentryParams(),
                   record=()) -> dict:
    """Fly a program blind through the Reentry FMU (fmpy): u[k] is set at every communication
    point k * t_seg whatever the state.  Returns the plant's final outputs (``load_max``,
    ``L``, ``status``, ...) and, for the outputs named in ``record``, their values at every
    communication point under ``"trace"`` (with ``"t"`` and ``"u"``)."""
    from descent_fmus.synthesis.fmi.closed_loop import load_slave
    from descent_fmus.synthesis.paths import require_fmu
    fmu = load_slave(require_fmu(Path(fmu_dir) / "Reentry.fmu"), "plant")
    md = fmu.model
    vr = {v.name: v.valueReference for v in md.modelVariables}
    trace = {name: [] for name in ("t", "u") + tuple(record)}
    try:
        start = asdict(p)          # the plant's parameters are the dataclass fields
        fmu.setReal([vr[k] for k in start], [float(v) for v in start.values()])
        fmu.setupExperiment(startTime=0.0, stopTime=T_PLUS)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        n = int(math.ceil(T_PLUS / prog.t_seg - 1e-9))
        rec = [vr[name] for name in record]
        for k in range(n + 1):
            t = k * prog.t_seg
            u = prog(t)
            if record:
                trace["t"].append(t)
                trace["u"].append(u)
                for name, v in zip(record, fmu.getReal(rec)):
                    trace[name].append(v)
            if k == n or fmu.getInteger([vr["status"]])[0] != 0:
                break
            fmu.setReal([vr["u"]], [u])
            fmu.doStep(t, min(prog.t_seg, T_PLUS - t))
        out = {v.name: (int(fmu.getInteger([v.valueReference])[0]) if v.type == "Integer"
                        else float(fmu.getReal([v.valueReference])[0]))
               for v in md.modelVariables if v.causality == "output"}
    finally:
        fmu.free()
    if record:
        out["trace"] = {k: np.asarray(v) for k, v in trace.items()}
    return out


def plot_program(prog: Program, path, label: str = "") -> Path:
    """PNG: the program u(t) and the load along its flight."""
    import matplotlib.pyplot as plt

    from descent_fmus.synthesis.plotting import save_figure
    f = ProgramFlight(prog.u, prog.t_seg, sensitivities=False)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    t = np.arange(len(prog.u)) * prog.t_seg
    ax[0].step(t, prog.u, where="post")
    ax[0].set(xlabel="t [s]", ylabel="u", xlim=(0, f.t_end),
              title=f"best program, {prog.t_seg:g} s segments {label}")
    ax[1].plot(np.linspace(0, f.t_end, len(f.loads)), f.loads)
    ax[1].set(xlabel="t [s] (samples)", ylabel="load",
              title=f"J1 = {prog.J1:.4f}, miss = {prog.miss:.3g} m")
    return save_figure(fig, path, ax, dpi=110)
