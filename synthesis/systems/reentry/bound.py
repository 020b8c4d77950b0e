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
enters through the event condition h = hf.  The flight runs in plain floats; the tangents of
its sub-steps are then composed for all sub-steps at once in NumPy, so one flight with all
sensitivities costs about five plain flights, where finite differences cost one flight per
segment.

The NLP holds only the load samples near the peak (:data:`NEAR_PEAK`, checked against every
sample at the solution), and :func:`reference_bounds` starts the zero-miss bound from the same
bound on coarser grids (:func:`coarse_start`): the same bounds as SLSQP from u = 0 with every
sample, several times faster (``benchmarks/bound.py`` prints both).

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
           "coarse_start", "segments", "replay_program", "plot_program", "T_SEG"]

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
    def from_dict(cls, d: dict) -> "Program":
        """The program of :meth:`to_dict`'s dictionary."""
        return cls(np.asarray(d["u"], float), float(d["t_seg"]), d.get("J1", math.nan),
                   d.get("miss", math.nan), d.get("t_land", math.nan), d.get("info", {}))

    @classmethod
    def load(cls, path) -> "Program":
        try:
            return cls.from_dict(json.loads(Path(path).read_text()))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{path} is not a program file: {exc}") from None


def fly_program(u, t_seg: float, p: ReentryParams = ReentryParams(), trace: bool = False):
    """Fly the program in-process (communication step = segment length; the plant's integrator)."""
    u = np.asarray(u, float)
    prog = lambda t, x: float(u[min(int(t / t_seg + 1e-9), len(u) - 1)])  # noqa: E731
    return simulate(p, prog, step=t_seg, t_plus=T_PLUS, trace=trace)


def _load_gradients(X, DX, FX, FU, p: ReentryParams):
    """Gradients of the load samples (``models.reentry.loads``) with respect to the state and
    the control: ``(gx (m, 4), gu (m,))`` at the states ``X`` (m, 4) with derivatives ``DX``,
    their Jacobians ``FX`` (m, 4, 4) and ``FU`` (m, 4) (:func:`models.reentry.rhs_jacobians`)."""
    x1, x3 = X[:, 0], X[:, 2]
    r2 = x1 * x1 + x3 * x3
    a = np.hypot(DX[:, 1], DX[:, 3])
    safe = np.where(a > 0.0, a, 1.0)
    c = 1.0 / (p.Rz * p.Rz * p.g0)
    ga = (DX[:, 1, None] * FX[:, 1] + DX[:, 3, None] * FX[:, 3]) / safe[:, None]
    zero = np.zeros_like(x1)
    gx = c * (r2[:, None] * ga + a[:, None] * np.stack([2.0 * x1, zero, 2.0 * x3, zero], 1))
    gu = c * r2 * (DX[:, 1] * FU[:, 1] + DX[:, 3] * FU[:, 3]) / safe
    gx[a == 0.0] = 0.0
    gu[a == 0.0] = 0.0
    return gx, gu


def _rk4_tangents(steps, c):
    """``(Phi (N, 4, 4), Gamma (N, 4))``: the derivatives of every RK4 sub-step ``(x, u, h)`` of
    ``steps`` with respect to its start state and to u (tangent-linear RK4).  The stage states
    and their Jacobians (:func:`models.reentry.rhs_jacobians`) are computed step by step, the
    chain rule through the four stages for all steps at once."""
    jac = []
    for x, u, h in steps:
        args = (u,) + c
        k1 = rhs(x, *args)
        x2 = tuple(xi + 0.5 * h * ki for xi, ki in zip(x, k1))
        k2 = rhs(x2, *args)
        x3 = tuple(xi + 0.5 * h * ki for xi, ki in zip(x, k2))
        k3 = rhs(x3, *args)
        x4 = tuple(xi + h * ki for xi, ki in zip(x, k3))
        jac.append(tuple(rhs_jacobians(xs, u, *c) for xs in (x, x2, x3, x4)))
    fx = np.array([[s[0] for s in j] for j in jac])            # (N, stage, 4, 4)
    fu = np.array([[s[1] for s in j] for j in jac])            # (N, stage, 4)
    h = np.array([s[2] for s in steps])
    eye = np.eye(4)
    kx, ku = fx[:, 0], fu[:, 0]
    sx, su = kx.copy(), ku.copy()
    for stage, w, a in ((1, 2.0, 0.5), (2, 2.0, 0.5), (3, 1.0, 1.0)):
        ah = a * h
        kx, ku = (fx[:, stage] @ (eye + ah[:, None, None] * kx),
                  np.einsum("nij,nj->ni", fx[:, stage], ah[:, None] * ku) + fu[:, stage])
        sx += w * kx
        su += w * ku
    return eye + (h / 6.0)[:, None, None] * sx, (h / 6.0)[:, None] * su


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
        samples, at, steps, seg = [], [], [], []    # at: (x, dx, u, segment, steps before)

        def sample(x, dx, u_k, k):
            samples.append(loads(x, dx, kd, p.lam, p.Rz, p.g0, u_k)[0])
            at.append((x, dx, u_k, k, len(steps)))

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
                sample(x, k1, uk, kk)
                xn = rk4_step_with_k1(rhs, x, k1, h, args)
                g1 = math.hypot(xn[0], xn[2]) - rz_hf
                if g1 <= 0.0:
                    g0 = math.hypot(x[0], x[2]) - rz_hf
                    s, xs = locate_crossing(rhs, x, k1, h, args,
                                            lambda y: math.hypot(y[0], y[2]) - rz_hf, g0, g1)
                    steps.append((x, uk, s * h))
                    seg.append(kk)
                    x, t, landed = xs, t + s * h, True
                    break
                steps.append((x, uk, h))
                seg.append(kk)
                x, t = xn, t + h
            sample(x, rhs(x, *args), uk, kk)   # the landing point, or the left-hand value
            if landed:                          # at the segment end
                break
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
        self.dloads = self.dmiss = None
        if sensitivities:
            land = (x, (u[seg[-1]],) + args0) if landed else None
            S = _propagate(steps, seg, n, args0, land)
            self.dloads = _sample_gradients(at, S, n, p, args0)
            self.dmiss = gmiss @ S[-1]

    @property
    def J1(self) -> float:
        return float(self.loads.max())


def _propagate(steps, seg, n: int, c, land):
    """The sensitivities of the state to the program, ``S[j]`` (4 x n) after ``j`` sub-steps
    (``S[0] = 0``); ``land = (x, args)`` when the last sub-step ends on h = hf: the landing
    time moves with u, dt_land = -(dG/dx dx) / (dG/dx f)."""
    phi, gam = _rk4_tangents(steps, c)
    S = np.zeros((len(steps) + 1, 4, n))
    for j, k in enumerate(seg):
        S[j + 1] = phi[j] @ S[j]
        S[j + 1, :, k] += gam[j]
    if land is not None:
        xs, args = land
        fs = np.asarray(rhs(xs, *args))
        r = math.hypot(xs[0], xs[2])
        dG = np.array([xs[0] / r, 0.0, xs[2] / r, 0.0])
        S[-1] -= np.outer(fs, (dG @ S[-1]) / (dG @ fs))
    return S


def _sample_gradients(at, S, n: int, p: ReentryParams, c):
    """d load / d u of every sample ``(x, dx, u, segment, sub-steps before)`` of ``at``."""
    X = np.array([a[0] for a in at])
    DX = np.array([a[1] for a in at])
    jac = [rhs_jacobians(a[0], a[2], *c) for a in at]
    gx, gu = _load_gradients(X, DX, np.array([j[0] for j in jac]),
                             np.array([j[1] for j in jac]), p)
    idx = np.array([a[4] for a in at])
    out = np.einsum("mi,mik->mk", gx, S[idx])
    out[np.arange(len(at)), [a[3] for a in at]] += gu
    return out


#: [choice] The NLP holds the load samples within this fraction below the peak (of the start
#: program, then of every solution): the others cannot be active at the optimum, and SLSQP's
#: subproblem grows with the number of constraints (all ~1 200 samples made it 70 % of the
#: bound's time).  A sample left out that comes within NEAR_PEAK / 2 of a solution's peak joins
#: and the NLP is solved again from there, so the result is a solution of the full problem.
NEAR_PEAK = 0.25
#: Most solves of the NLP before it holds every sample.
MAX_ROUNDS = 4


def _near_peak(loads, band: float) -> np.ndarray:
    """Indices of the samples within ``band`` (a fraction) below the peak."""
    return np.flatnonzero(loads >= (1.0 - band) * loads.max())


def optimize_open_loop(p: ReentryParams = ReentryParams(), t_seg: float = T_SEG,
                       miss_tol: float = 0.0, maxiter: int = 300, tol: float = 1e-10,
                       u0=None, progress=None, near_peak: float = NEAR_PEAK) -> Program:
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
        SLSQP limits (``maxiter`` per solve).
    u0 : array-like, optional
        Starting program (default u = 0).
    progress : callable, optional
        Called with (iteration, J1, |miss| violation) after every SLSQP iteration.
    near_peak : float
        The samples the NLP holds: those within this fraction below the peak
        (:data:`NEAR_PEAK`; 1 = every sample).

    Returns
    -------
    Program
        With ``J1`` (true-peak max load), ``miss`` |L(tf) - Lf| [m], ``t_land`` and solver
        ``info`` (``rounds``: solves of the NLP, ``samples``: the load samples it held).
    """
    if not t_seg > 0:
        raise ValueError(f"t_seg must be > 0, got {t_seg}")
    if not miss_tol >= 0:
        raise ValueError(f"miss_tol must be >= 0, got {miss_tol}")
    n = segments(t_seg)
    # upper bound on the samples of one flight: every sub-step start, two per segment end
    n_samples = int(math.ceil(T_PLUS / DT_INTEGRATION)) + 2 * n + 2

    def pad(a, fill=0.0):
        out = np.full((n_samples,) + a.shape[1:], fill)
        out[:len(a)] = a
        return out

    if not 0 < near_peak <= 1:
        raise ValueError(f"near_peak must be in (0, 1], got {near_peak}")
    u = np.clip(np.zeros(n) if u0 is None else np.asarray(u0, float), *U_BOUNDS)
    f = ProgramFlight(u, t_seg, p, sensitivities=False)
    rows = _near_peak(pad(f.loads), near_peak)
    info = {"iterations": 0, "seconds": 0.0}
    for rounds in range(1, MAX_ROUNDS + 1):
        if rounds == MAX_ROUNDS:
            rows = np.arange(n_samples)

        def fly(u, rows=rows):
            f = ProgramFlight(u, t_seg, p)
            return pad(f.loads)[rows], f.miss, pad(f.dloads)[rows], f.dmiss[None, :]

        # miss in units of 10 km keeps the constraint well scaled
        u, step = minimax_program(fly, n, U_BOUNDS, u0=u, eq_scale=1e-4, eq_tol=miss_tol,
                                  maxiter=maxiter, tol=tol, progress=progress,
                                  with_jacobian=True)
        info.update(step, iterations=info["iterations"] + step["iterations"],
                    seconds=info["seconds"] + step["seconds"])
        f = ProgramFlight(u, t_seg, p, sensitivities=False)
        join = np.setdiff1d(_near_peak(pad(f.loads), near_peak / 2), rows)
        if not len(join):
            break
        rows = np.union1d(rows, _near_peak(pad(f.loads), near_peak))
    info.update(segments=n, miss_tol=miss_tol, rounds=rounds, samples=len(rows))
    return Program(u, t_seg, J1=f.J1, miss=abs(f.miss) if f.landed else math.nan,
                   t_land=f.t_end if f.landed else math.nan, info=info)


#: [choice] The zero-miss bound starts from the same bound on grids 8, 4 and 2 times coarser,
#: each solved from the one before (the coarse problems' subproblems are small): SLSQP then needs
#: 18 iterations on the controller's grid instead of 94 from u = 0, and ends at the same
#: program (J1 within 1e-8 of the solve from u = 0 on the default and the second scenario).
COARSE_LEVELS = 3


def segments(t_seg: float) -> int:
    """Number of program values on a grid of ``t_seg`` [s]: ceil(t+ / t_seg)."""
    return int(math.ceil(T_PLUS / t_seg - 1e-9))


def coarse_start(p: ReentryParams = ReentryParams(), t_seg: float = T_SEG,
                 levels: int = COARSE_LEVELS) -> np.ndarray:
    """A start for the zero-miss bound on the grid ``t_seg``: the bound on the grid
    ``2**levels`` times coarser, refined by halving the segments down to ``2 t_seg``, each
    solved from the one before (:data:`COARSE_LEVELS`); u = 0 with ``levels = 0``."""
    u = None
    for i in range(levels, 0, -1):
        n = segments(t_seg * 2 ** i)
        u = optimize_open_loop(p, t_seg * 2 ** i, u0=None if u is None else
                               np.repeat(u, 2)[:n]).u
    return np.zeros(segments(t_seg)) if u is None else np.repeat(u, 2)[:segments(t_seg)]


def reference_bounds(miss_tol: float, p: ReentryParams = ReentryParams(),
                     t_seg: float = T_SEG) -> tuple[Program, Program]:
    """(zero-miss bound, bound at ``miss_tol``): the first from :func:`coarse_start`, the
    second from the first's program."""
    zero = optimize_open_loop(p, t_seg, u0=coarse_start(p, t_seg))
    tol = optimize_open_loop(p, t_seg, miss_tol=miss_tol, u0=zero.u)
    return zero, tol


def replay_program(prog: Program, fmu_dir, p: ReentryParams = ReentryParams(),
                   record=()) -> dict:
    """Fly a program blind through the Reentry FMU (fmpy): u[k] is set at every communication
    point k * t_seg whatever the state.  Returns the plant's final outputs (``load_max``,
    ``L``, ``status``, ...) and, for the outputs named in ``record``, their values at every
    communication point under ``"trace"`` (with ``"t"`` and ``"u"``)."""
    from descent_fmus.synthesis.fmi.slave import load_slave
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
