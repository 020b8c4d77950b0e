"""S4 route problem (Voronov 2009, ch. 3, Example 3): a telescope traces, within eps, the attitude
motion of another spacecraft, as a chain of two-point problems solved by the direct method.

* :data:`ROUTE_CRAFT`, :data:`TRACER` -- the two crafts of Example 3: the route is the solution
  of a two-point reorientation of a craft with inertia diag(11000, 20000, 20000) kg m^2 and four
  gyrodynes whose gimbal axes are normal to four pairwise non-parallel faces of a regular
  octahedron (T = 80 s); it is traced by a telescope-like craft with another inertia and six
  gyrodynes in a pyramid (20 deg between every gimbal axis and the pyramid's height);
* :func:`make_route` -- solves the route craft's reorientation by the direct method and returns
  its (lambda, omega)(t) as a :class:`~synthesis.methods.route_problem.RouteTable` (cubic Hermite between
  the RK4 sub-steps, with the rates from the equations);
* :func:`trace` -- traces the route with the tracer (:func:`synthesis.methods.route.trace_route`:
  halving as in the thesis, or the adaptive rule; optional gimbal-rate limits);
* :func:`replay_route` -- flies the traced program through the FMUs (ProgramController with the
  stages' node times + Telescope with the tracer's parameters) and measures the deviation from
  the route at every communication point;
* :func:`plot_route` -- one PNG: the gimbal rates with the stage joints, the deviation from the
  route against eps, the route itself.

References
----------
S.A. Voronov, PhD thesis (2009), ch. 3, Example 3.
"""
from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from descent_fmus.models.telescope import DT_INTEGRATION
from descent_fmus.models.telescope_cmg import octahedron_axes, pyramid_axes, quat_to_matrix
from descent_fmus.models.telescope_dynamics import (TelescopeParams, inertial_momentum,
                                                    make_rigid_rhs, rigid_jacobian,
                                                    singularity_measure)
from descent_fmus.synthesis.methods.direct_method import DirectResult, solve
from descent_fmus.synthesis.methods.route import trace_route
from descent_fmus.synthesis.methods.route_problem import (RouteProblem, RouteResult, RouteTable,
                                                          route_values)
from descent_fmus.synthesis.systems.telescope.reorientation import (GRID_STEP, STATE_NAMES,
                                                                    RateLimitTooSmallError,
                                                                    check_reachable,
                                                                    rigid_problem)

__all__ = ["ROUTE_CRAFT", "TRACER", "ROUTE_T", "ROUTE_X0", "ROUTE_LAM_END", "ROUTE_W_END",
           "TRACER_BETA0", "EPS", "PAPER_STAGES", "ROUTE_TOL", "INTERVALS", "Route",
           "RouteTrace", "make_route", "trace", "check_route_rate_limit", "replay_route",
           "replay_step", "plot_route"]


def _deg(v: float) -> float:
    return math.radians(v)


#: The craft whose reorientation is the route (Voronov 2009, Example 3): inertia
#: diag(11000, 20000, 20000) kg m^2 ([choice]: the scan prints "110000"), four gyrodynes
#: h = 250 N m s normal to four non-parallel octahedron faces, rotor axes tangential at beta = 0.
ROUTE_CRAFT = TelescopeParams(inertia=(11000.0, 0.0, 0.0, 0.0, 20000.0, 0.0, 0.0, 0.0, 20000.0),
                              h=250.0, rotor_ref="z", gimbal_axes=octahedron_axes())
#: The tracer (Voronov 2009, Example 3): six gyrodynes h = 250 N m s in a pyramid, 20 deg between
#: every gimbal axis and the height, azimuths 60 deg apart ([choice]), rotor axes tangential
#: (horizontal) at beta = 0 ([choice]).
TRACER = TelescopeParams(inertia=(21000.0, -100.0, -100.0, -100.0, 10500.0, 100.0, -100.0, 100.0,
                                  19000.0),
                         h=250.0, rotor_ref="z", gimbal_axes=pyramid_axes(6, _deg(20.0)))
#: Duration of the route [s] and the route craft's boundary conditions (Example 3): the start
#: (lambda, omega [rad/s], beta [rad]; beta4 = -70 deg, [choice]: the print is cut after "-70")
#: and the end (lambda, omega).
ROUTE_T = 80.0
ROUTE_X0 = (math.cos(_deg(15.0)), 0.0, math.sin(_deg(15.0)), 0.0, 0.0, _deg(0.25), 0.0,
            0.0, 0.0, 0.0, _deg(-70.0))
ROUTE_LAM_END = (1.0, 0.0, 0.0, 0.0)
ROUTE_W_END = (_deg(-0.15), 0.0, _deg(0.2))
#: The tracer's initial gimbal angles [rad] ([choice]: zero, the pyramid's symmetric state with
#: zero rotor momentum, det(C C^T)/h^6 = 4.93 of at most 8).
TRACER_BETA0 = (0.0,) * 6
#: Required accuracy of the route on lambda0..3 and omega (Example 3) and the thesis' stage count.
EPS = 5e-5
PAPER_STAGES = 32
#: End accuracy of the route craft's two-point problem (the route itself; as Example 1).
ROUTE_TOL = 1e-7
#: Control intervals per stage of the trace ([choice]; piecewise-linear gimbal rates).
INTERVALS = 8


@dataclass
class Route:
    """The route: the route craft's reorientation and its (lambda, omega)(t) as a table."""

    result: DirectResult
    table: RouteTable
    params: TelescopeParams

    @property
    def seconds(self) -> float:
        return self.result.seconds


@functools.lru_cache(maxsize=4)
def make_route(params: TelescopeParams = ROUTE_CRAFT, x0=ROUTE_X0, lam_f=ROUTE_LAM_END,
               w_f=ROUTE_W_END, T: float = ROUTE_T, tol: float = ROUTE_TOL) -> Route:
    """Solve the route craft's reorientation (u(0) = u(T) = 0, 1 s grid, RK4 sub-steps of
    0.025 s) and tabulate its quaternion and body rate with their rates (cubic Hermite).

    Deterministic, so the result is kept per arguments (tuples; the arrays are read-only): the
    commands and tests that trace the same route solve it once per process.
    """
    check_reachable(x0, lam_f, w_f, params)
    res = solve(rigid_problem(params, T, lam_f, w_f, x0=x0, grid_step=GRID_STEP), tol=tol)
    f = make_rigid_rhs(params)
    U = res.control(res.t)
    rates = np.array([f(tuple(x), tuple(u))[:7] for x, u in zip(res.states, U)])
    for a in (res.t, res.states, res.controls, res.t_nodes, rates):
        a.flags.writeable = False
    return Route(res, RouteTable(res.t, res.states[:, :7], rates), params)


@dataclass
class RouteTrace:
    """A traced route: the route, the trace (:class:`~synthesis.methods.route_problem.RouteResult`), the
    tracer's parameters and the options used."""

    route: Route
    result: RouteResult
    params: TelescopeParams
    x0: tuple
    options: dict = field(default_factory=dict)

    def summary(self) -> dict:
        r = self.result
        p = self.params
        n = p.n_gyros
        X = r.states
        sing = np.array([singularity_measure(x[7:7 + n], p) for x in X[::10]])
        K = np.array([inertial_momentum(x, p) for x in X[::10]])
        dev = r.max_deviation
        return dict(
            stages=r.n_stages, paper_stages=PAPER_STAGES, rule=r.rule,
            joints=self.options.get("joints"), eps=float(np.max(r.eps)),
            tau=r.tau, max_deviation=float(np.max(dev)),
            max_deviation_per_component=dict(zip(STATE_NAMES, map(float, dev))),
            max_relative_deviation=r.max_relative_deviation,
            deviation_checked_at=f"every RK4 sub-step and between them ({len(r.t)} sub-steps)",
            stage_solves=len(r.attempts),
            stage_iterations=[s.iterations for s in r.stages],
            seconds=r.seconds, route_seconds=self.route.seconds,
            route_iterations=self.route.result.iterations,
            u_max=self.options.get("u_max"), u_peak=float(np.max(np.abs(r.controls))),
            energy=r.energy, program_nodes=len(r.t_nodes),
            sing_min=float(np.min(sing)), momentum_drift=float(np.max(np.linalg.norm(K - K[0],
                                                                                    axis=1))))


def trace(eps=EPS, rule: str = "halving", joints: str = "continuous", u_max=None,
          intervals: int = INTERVALS, max_stages: int = 256, minimize_energy: bool = False,
          route: Route | None = None, params: TelescopeParams = TRACER,
          beta0=TRACER_BETA0, w0=None) -> RouteTrace:
    """Trace the route of Example 3 (made by :func:`make_route` unless given) with the tracer.

    The tracer starts on the route (its quaternion and body rate at t = 0) with gimbal angles
    ``beta0``; ``w0`` [rad/s] overrides its initial body rate (a start away from the route is
    refused).  See :class:`synthesis.methods.route_problem.RouteProblem` for the other options.

    Raises
    ------
    synthesis.methods.route_problem.RouteError
        Ill-posed: eps <= 0, a start away from the route, ...
    RateLimitTooSmallError
        ``u_max`` cannot follow the route (closed form, before tracing).
    synthesis.methods.route_problem.RouteNotTracedError
        No partition within ``max_stages`` keeps the trace within eps (e.g. a rate limit too
        small that the closed-form check lets through).
    """
    params.validate()
    if w0 is not None and route is None:       # refuse a start away from the route before
        RouteProblem(rhs=None, x0=ROUTE_X0[:4] + tuple(float(v) for v in w0),  # solving it
                     route=lambda t: np.tile(ROUTE_X0[:7], (np.size(t), 1)),
                     route_index=tuple(range(7)), t0=0.0, tf=ROUTE_T, eps=eps,
                     n_u=params.n_gyros).validate()
    route = route or make_route()
    start = route_values(route.table, [0.0])[0]
    w_start = tuple(start[4:7]) if w0 is None else tuple(float(v) for v in w0)
    x0 = tuple(start[:4]) + w_start + tuple(float(v) for v in beta0)
    if len(x0) != params.n_states:
        raise ValueError(f"beta0 needs {params.n_gyros} values, got {len(beta0)}")
    if u_max is not None:
        check_route_rate_limit(route, params, x0, u_max, eps)
    t_end = float(route.table.t[-1])
    pb = RouteProblem(rhs=make_rigid_rhs(params), x0=x0, route=route.table,
                      route_index=tuple(range(7)), t0=0.0, tf=t_end, eps=eps,
                      n_u=params.n_gyros, jac=rigid_jacobian(params), intervals=intervals,
                      dt=DT_INTEGRATION, joints=joints, rule=rule, max_stages=max_stages,
                      quantum=intervals * DT_INTEGRATION, u_max=u_max,
                      minimize_energy=minimize_energy)
    res = trace_route(pb)
    return RouteTrace(route, res, params, x0,
                      options=dict(eps=eps, rule=rule, joints=joints, u_max=u_max,
                                   intervals=intervals, minimize_energy=minimize_energy))


def check_route_rate_limit(route: Route, params: TelescopeParams, x0, u_max: float,
                           eps) -> dict:
    """Raise :class:`RateLimitTooSmallError` if ``|u_j| <= u_max`` cannot follow the route.

    A necessary condition in closed form (the route problem's analogue of
    :func:`~synthesis.systems.telescope.reorientation.check_rate_limit`): the inertial momentum
    ``K`` is conserved, so on the route the gyros must hold ``k(t) = R(lambda)^T K - I omega``;
    over a time ``L`` every rotor moves its momentum by at most the chord
    ``2 h sin(min(u_max L, pi) / 2)``, so ``|k(t + L) - k(t)|`` may exceed ``n`` such chords only
    by what the eps-neighbourhood allows (``2 eps (|I| + 4 |K|)``).  Checked for lags of 1/64 to
    1 of the route's duration.
    """
    if not (math.isfinite(u_max) and u_max > 0):
        raise ValueError(f"u_max must be > 0 [rad/s], got {u_max}")
    t = np.asarray(route.table.t)
    Y = np.asarray(route.table.values, float)
    K = inertial_momentum(x0, params)
    k = np.array([quat_to_matrix(y[:4]).T @ K for y in Y]) - Y[:, 4:7] @ params.I.T
    slack = 2.0 * float(np.max(eps)) * (float(np.linalg.norm(params.I, 2))
                                        + 4.0 * float(np.linalg.norm(K)))
    n = params.n_gyros
    span = t[-1] - t[0]
    worst = None
    for j in range(7):
        L = span / 2 ** j
        lag = max(1, int(round(L / (span / (len(t) - 1)))))
        dk = np.linalg.norm(k[lag:] - k[:-lag], axis=1)
        i = int(np.argmax(dk))
        reach = 2.0 * n * params.h * math.sin(min(u_max * (t[i + lag] - t[i]), math.pi) / 2.0)
        if dk[i] > reach + slack:
            worst = (float(t[i]), float(t[i + lag]), float(dk[i]), reach)
            break
    if worst is not None:
        a, b, need, reach = worst
        raise RateLimitTooSmallError(
            f"the gimbal-rate limit {u_max:g} rad/s is too small for the route: between t = "
            f"{a:.4g} s and {b:.4g} s the gyros must change their momentum by {need:.1f} N m s, "
            f"|u| <= {u_max:g} rad/s allows at most {reach:.1f} N m s")
    return dict(slack=slack)


def replay_step(t_nodes, largest: float = 0.1, fallback: float = DT_INTEGRATION) -> float:
    """The communication step of a replay: the largest ``<= largest`` that puts every node time
    on a communication point (then the first-order hold replays the program exactly), else
    ``fallback`` (nodes that fall inside a step then see the slope of the segment that step
    starts in)."""
    t = np.asarray(t_nodes, float)
    spacing = float(np.min(np.diff(t)))
    for k in range(max(1, math.ceil(spacing / largest - 1e-9)), 257):
        h = spacing / k
        q = (t - t[0]) / h
        if np.all(np.abs(q - np.round(q)) < 1e-6):
            return h
    return fallback


def replay_route(rt: RouteTrace, fmu_dir=None, step: float | None = None) -> dict:
    """Fly the traced program through the FMUs (ProgramController with the stages' node times,
    Telescope with the tracer's parameters and initial state) with fmpy; the deviation from the
    route at every communication point and the end error against the in-process trace."""
    from descent_fmus.models.controllers.program_table import program_values
    from descent_fmus.synthesis.fmi.loop import open_loop
    from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir
    from descent_fmus.synthesis.systems.telescope.wiring import plant_values, wiring

    fmu_dir = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    r = rt.result
    step = step or replay_step(r.t_nodes)
    names = list(STATE_NAMES)
    t_end = float(r.t_nodes[-1])
    with open_loop(wiring("Telescope"), fmu_dir / "Telescope.fmu",
                   fmu_dir / "ProgramController.fmu", native=False,
                   record=names + ["sing"]) as cl:
        t0 = time.perf_counter()
        out = cl.run(plant_values=plant_values(rt.params, dt=DT_INTEGRATION, state=rt.x0),
                     controller_values=program_values(t_end, r.controls, times=r.t_nodes),
                     stop_time=t_end, step=step, record=True)
        secs = time.perf_counter() - t0
    Y = np.stack([out[n] for n in names], -1)
    dev = np.abs(Y - route_values(rt.route.table, out.time))
    final = Y[-1]
    return dict(replay_max_deviation=float(np.max(dev)),
                replay_max_relative_deviation=float(np.max(dev / r.eps)),
                replay_points=len(out.time), replay_step=step,
                replay_error_vs_solver=float(np.max(np.abs(final - r.states[-1, :7]))),
                replay_sing_min=float(np.min(out["sing"])), replay_seconds=secs,
                replay_status=out.final["status"])


def plot_route(rt: RouteTrace, path) -> Path:
    """Write one PNG: gimbal rates with the stage joints, deviation from the route against eps,
    the route (lambda, omega); returns the path."""
    import matplotlib.pyplot as plt

    from descent_fmus.synthesis.plotting import save_figure

    r = rt.result
    fig, ax = plt.subplots(3, 1, figsize=(8, 8.5), sharex=True)
    for j in range(r.controls.shape[1]):
        ax[0].plot(r.t_nodes, np.degrees(r.controls[:, j]), label=f"u{j + 1}")
    if rt.options.get("u_max") is not None:
        for s in (1, -1):
            ax[0].axhline(s * math.degrees(rt.options["u_max"]), color="r", ls=":", lw=1)
    ax[0].set_ylabel("gimbal rate u [deg/s]")
    for a in ax[:2]:
        for tau in r.tau[1:-1]:
            a.axvline(tau, color="0.8", lw=0.6, zorder=0)
    for k, name in enumerate(STATE_NAMES):
        ax[1].semilogy(r.t, np.maximum(r.deviation[:, k], 1e-14), lw=0.8, label=name)
    ax[1].axhline(float(np.max(r.eps)), color="r", ls="--", label=f"eps {np.max(r.eps):g}")
    ax[1].set_ylabel("|x(t) - route(t)|")
    ax[1].set_ylim(1e-10, 5 * float(np.max(r.eps)))
    for k in range(4):
        ax[2].plot(r.t, r.states[:, k], label=f"lam{k}")
    a2 = ax[2].twinx()
    for k in range(3):
        a2.plot(r.t, np.degrees(r.states[:, 4 + k]), ls="--", label=f"w{k + 1}")
    a2.set_ylabel("body rate [deg/s] (dashed)")
    ax[2].set_ylabel("quaternion [1]")
    ax[2].set_xlabel("t [s]")
    for a in list(ax) + [a2]:
        if a.get_legend_handles_labels()[0]:
            a.legend(fontsize=7, ncol=8, loc="best")
    fig.suptitle(f"S4 route (Voronov 2009, Example 3): {r.n_stages} stages ({r.rule}), max "
                 f"deviation {np.max(r.deviation):.2e} (eps {np.max(r.eps):g})")
    return save_figure(fig, path, axes=list(ax), dpi=90)
